"""Training batches drawn by background worker processes.

A batch is assembled in Python clip by clip (about 1 ms per window on one core), which is slower than a
training step of the default model on a GPU: a GPU fed from the main process alone would wait on it.
Worker processes each draw batches with their own seeded sampler; the DataLoader hands them over in a
fixed worker order, so a run is repeatable for a given number of workers. With no workers the main
process draws every batch from the sampler it was given, exactly as before.
"""
from __future__ import annotations

from typing import Iterator

import torch
from torch.utils.data import DataLoader, IterableDataset, get_worker_info

from .samples import Batch, SegmentSampler


class _SampledBatches(IterableDataset):
    """An endless stream of batches; each worker reseeds its copy of the sampler."""

    def __init__(self, sampler: SegmentSampler, batch: int, fwsr: bool, seed: int) -> None:
        super().__init__()
        self.sampler, self.batch, self.fwsr, self.seed = sampler, batch, fwsr, seed

    def __iter__(self) -> Iterator[Batch]:
        info = get_worker_info()
        if info is not None:   # a forked copy: give it its own stream (worker id and run offset both count)
            self.sampler.gen.manual_seed(self.seed * 1009 + info.id)
        while True:
            yield self.sampler.sample(self.batch, fwsr=self.fwsr)


def _one_thread(_: int) -> None:
    torch.set_num_threads(1)   # many workers with a thread pool each would fight over the cores


def batch_stream(sampler: SegmentSampler, batch: int, *, fwsr: bool, workers: int, seed: int,
                 device: torch.device) -> Iterator[Batch]:
    """Endless batches on `device`. `seed` should differ between a run and its resumption (the step count is a
    good one), or a resumed run would replay the batches it began with."""
    if workers <= 0:
        while True:
            yield sampler.sample(batch, fwsr=fwsr).to(device)
    loader = DataLoader(_SampledBatches(sampler, batch, fwsr, seed), batch_size=None, num_workers=workers,
                        pin_memory=device.type == "cuda", prefetch_factor=4, worker_init_fn=_one_thread)
    for b in loader:
        yield b.to(device, non_blocking=True)
