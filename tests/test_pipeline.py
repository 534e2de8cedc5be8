"""Pipelining: each segment's diffusion runs in a helper process while the caller plays frames. The frames
must be exactly those of a rollout without it, also when the helper fails, and the helper must take the jobs."""
from __future__ import annotations

import sys
import time
import warnings

import numpy as np
import pytest

from model_runtime import EgoSettings, ReactionGroup, ReactionSession
from model_runtime.fixtures import BOX_GOAL, approaching_partner, box_scene
from model_runtime.group import AHEAD_SLACK
from model_runtime.job_worker import JobWorker, RemoteJob



def frames_of(outs) -> np.ndarray:
    """Every output of a list of EgoFrames, flat per frame, to compare bit for bit."""
    return np.stack([np.concatenate([f.joints.ravel(), f.root.ravel(), f.local_rotations.ravel(),
                                     f.contacts.astype(np.float32)]) for f in outs])

FRAMES = 36


def _ready(worker: JobWorker) -> JobWorker:
    assert worker.ready.wait(60), f"the helper process did not start: {worker.problem}"
    return worker


def _rollout(group: ReactionGroup, frames: int = FRAMES, kill_at: int | None = None,
             helper_ahead: bool = False) -> tuple[np.ndarray, int]:
    """Frames of a rollout with a partner walking up, a box scene and goals; and how many jobs ran remotely.
    helper_ahead: before each step, wait until the helper has finished its job (a viewport at real time)."""
    partner, remote = approaching_partner(frames), []
    group.reset(root_positions=[(0.6 * i, 0.0, 0.0) for i in range(len(group.egos))])
    out = []
    for i in range(frames):
        if kill_at == i:
            group._worker._proc.kill()
        if helper_ahead and isinstance(group._job, RemoteJob):
            deadline = time.monotonic() + 60.0
            while not group._worker.has_result(group._job.job_id) and time.monotonic() < deadline:
                time.sleep(0.001)
            time.sleep(AHEAD_SLACK)
        out.extend(group.step(partner=None if i % 7 == 6 else partner[i], goals=[BOX_GOAL] * len(group.egos)))
        if isinstance(group._job, RemoteJob) and not any(group._job is r for r in remote):
            remote.append(group._job)
    return frames_of(out), len(remote)


def _group(model, n: int, pipeline: bool, worker: JobWorker | None = None, **kw) -> ReactionGroup:
    egos = [EgoSettings(text="walk to the person and wave", seed=3 + i, alpha={"hhi": 1.0, "hsi": 1.0}, **kw)
            for i in range(n)]
    g = ReactionGroup(model, egos, scene=box_scene())
    if pipeline:
        g._worker = worker
        g.pipeline = True
    return g


@pytest.fixture(scope="module")
def worker():
    w = _ready(JobWorker())
    yield w
    w.close()


@pytest.mark.parametrize("egos", [1, 2])
def test_pipelined_frames_equal_the_unpipelined_ones_bit_for_bit(tiny_model, worker, egos):
    plain, none_remote = _rollout(_group(tiny_model, egos, pipeline=False))
    piped, remote = _rollout(_group(tiny_model, egos, pipeline=True, worker=worker))
    assert none_remote == 0
    assert remote >= FRAMES // tiny_model.cfg.future - 2, "the helper process took (almost) no jobs"
    assert np.array_equal(plain, piped)


@pytest.mark.parametrize("egos", [1, 2])
def test_jobs_sent_a_step_late_when_the_helper_is_ahead_give_the_same_frames(tiny_model, worker, egos):
    plain, _ = _rollout(_group(tiny_model, egos, pipeline=False))
    group = _group(tiny_model, egos, pipeline=True, worker=worker)
    deferred = []
    build = group._build_pending

    def counted() -> None:
        deferred.append(group.frame_index)
        build()

    group._build_pending = counted
    piped, remote = _rollout(group, helper_ahead=True)
    assert np.array_equal(plain, piped)
    # every segment start after the second one (the first job runs here, the second is asked for at once)
    assert len(deferred) >= FRAMES // tiny_model.cfg.future - 2 and remote >= len(deferred)
    assert all(i % tiny_model.cfg.future == 1 for i in deferred), deferred


def test_a_session_pipelines_through_its_group(tiny_model, worker):
    kw = dict(text="a person walks forward", seed=5, alpha={"hhi": 0.0, "hsi": 1.0})
    a = ReactionSession(tiny_model, scene=box_scene(), **kw)
    b = ReactionSession(tiny_model, scene=box_scene(), **kw)
    b._group._worker = worker
    b.pipeline = True
    assert b.pipeline and not a.pipeline
    fa = [a.step(goal=BOX_GOAL) for _ in range(20)]
    fb = [b.step(goal=BOX_GOAL) for _ in range(20)]
    assert np.array_equal(frames_of(fa), frames_of(fb))


def test_when_the_helper_dies_the_jobs_run_here_with_the_same_frames(tiny_model):
    plain, _ = _rollout(_group(tiny_model, 1, pipeline=False))
    dying = _ready(JobWorker())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        piped, _ = _rollout(_group(tiny_model, 1, pipeline=True, worker=dying), kill_at=13)
    assert np.array_equal(plain, piped)
    assert dying.gone.is_set()
    assert any("helper process failed" in str(w.message) for w in caught)


def test_a_helper_that_cannot_start_leaves_the_jobs_here(tiny_model, monkeypatch):
    monkeypatch.setattr(sys, "executable", "")
    w = JobWorker()
    assert w.gone.is_set() and not w.usable and "Python" in w.problem
    plain, _ = _rollout(_group(tiny_model, 1, pipeline=False), frames=20)
    piped, remote = _rollout(_group(tiny_model, 1, pipeline=True, worker=w), frames=20)
    assert remote == 0 and np.array_equal(plain, piped)


def test_models_the_helper_cannot_run_stay_here(tiny_model):
    from model_runtime.job_worker import pipelinable
    from model_runtime import load_model
    assert pipelinable(tiny_model)
    assert not pipelinable(load_model(config="tiny", precision="bf16"))


def test_the_caller_keeps_nothing_of_finished_or_discarded_jobs(tiny_model, worker):
    group = _group(tiny_model, 1, pipeline=True, worker=worker)
    _rollout(group, frames=20)
    group.reset()                      # the job in flight is discarded
    deadline = time.monotonic() + 30.0
    while worker._dropped and time.monotonic() < deadline:
        time.sleep(0.01)
    import gc
    gc.collect()
    with worker._done:
        assert not worker._results and not worker._dropped



def test_weights_changed_in_place_reach_the_helper(tiny_model, worker):
    """The helper keeps a copy of the model; a weight changed in place (as fine-tuning does) is sent again, so
    pipelined frames stay those of the changed model."""
    import copy

    import torch
    model = copy.deepcopy(tiny_model)
    piped = _group(model, 1, pipeline=True, worker=worker)
    _rollout(piped, frames=12)
    with torch.no_grad():
        for p in model.denoiser.parameters():
            p.mul_(1.01)
    got, remote = _rollout(piped)
    want, _ = _rollout(_group(model, 1, pipeline=False))
    before, _ = _rollout(_group(tiny_model, 1, pipeline=False))
    assert remote > 0
    np.testing.assert_array_equal(got, want)
    assert not np.array_equal(got, before)      # the change mattered


def test_an_eased_last_step_reaches_the_helper(tiny_model, worker):
    """The model's final guidance settings travel with each job: the helper's frames are the caller's, and differ
    from those at full guidance."""
    before = tiny_model.final_guidance_share, tiny_model.final_guidance_min_speed
    try:
        tiny_model.final_guidance_min_speed = 0.0
        tiny_model.final_guidance_share = 0.3
        plain, _ = _rollout(_group(tiny_model, 1, pipeline=False))
        piped, remote = _rollout(_group(tiny_model, 1, pipeline=True, worker=worker))
        tiny_model.final_guidance_share = 1.0
        full, _ = _rollout(_group(tiny_model, 1, pipeline=False))
    finally:
        tiny_model.final_guidance_share, tiny_model.final_guidance_min_speed = before
    assert remote > 0
    assert np.array_equal(plain, piped)
    assert not np.array_equal(plain, full)
