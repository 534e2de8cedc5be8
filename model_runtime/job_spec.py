"""A segment's reverse diffusion as plain data: everything it needs, fixed when it starts.

A ReactionGroup starts the diffusion of the next segment one segment ahead (group.py). Its inputs are fixed
then (histories, cues, text, alphas, guidance, the control's targets) and its noise is drawn then too
(`NoiseDraws`), so the job is a pure function of a `JobSpec`: built here it is spread over the frames of the
running segment; sent to a helper process (job_worker.py) it runs there while this one plays the frames, with
the very same result.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from .control import ControlConfig, ControlTargets, LatentSteer, SegmentCosts
from .model import DiffusionJob, NoiseDraws, ReMoGenModel


@dataclass
class JobSpec:
    """The inputs of one job, one row per ego (see DiffusionJob and ReMoGenModel.encode_contexts)."""
    hist_n: torch.Tensor                    # (B, H, D) normalised canonical histories
    text_emb: torch.Tensor                  # (B, text_dim)
    partner: torch.Tensor                   # (B, W, 22, 3) canonical cue frames
    present: torch.Tensor                   # (B, W) which cue frames are there
    occupancy: torch.Tensor | None          # (B, R, R, R) ego-local occupancy, None without a scene
    goal: torch.Tensor | None               # (B, 3) canonical goals, None without any
    has_goal: torch.Tensor | None           # (B,) which rows' goals are real, None when all are
    alpha: list[dict]
    guidance: list[float]
    noise: NoiseDraws
    targets: list[ControlTargets] | None    # test-time control of each row, None with control off
    control: ControlConfig | None
    final_guidance_share: float | None = None      # the model's when the job was fixed (None: the runner's)
    final_guidance_min_speed: float | None = None  # likewise

    def __getstate__(self) -> dict:
        """Pickled to the helper process: occupancy (0/1 cells) as bytes-sized booleans, a quarter of the bytes
        to copy through the pipe, read back exactly."""
        state = dict(self.__dict__)
        occ = state["occupancy"]
        if occ is not None and occ.dtype == torch.float32 and bool(((occ == 0) | (occ == 1)).all()):
            state["occupancy"] = occ.to(torch.bool)
        return state

    def __setstate__(self, state: dict) -> None:
        occ = state["occupancy"]
        if occ is not None and occ.dtype == torch.bool:
            state["occupancy"] = occ.to(torch.float32)
        self.__dict__.update(state)


def build_job(model: ReMoGenModel, spec: JobSpec) -> DiffusionJob:
    """The DiffusionJob of a spec: its contexts encoded, its steering set up, no step taken yet."""
    contexts = model.encode_contexts(spec.partner, spec.present, spec.occupancy, spec.goal, spec.alpha,
                                     spec.has_goal)
    steer, cc = None, spec.control
    if spec.targets is not None and cc is not None:
        steer = LatentSteer(model, spec.hist_n, SegmentCosts(model.stats, spec.hist_n, spec.targets, cc), cc)
    return DiffusionJob(model, spec.hist_n, spec.text_emb, contexts, spec.alpha, spec.guidance, spec.noise,
                        steer=steer, steered_steps=cc.steered_steps if cc else 0,
                        final_steers=cc.final_steers if cc else 0,
                        final_guidance_share=spec.final_guidance_share,
                        final_guidance_min_speed=spec.final_guidance_min_speed)


def run_job(model: ReMoGenModel, spec: JobSpec) -> torch.Tensor:
    """A spec's finished latent (B, L, latent_dim), all of its steps at once."""
    job = build_job(model, spec)
    job.advance(job.total_steps)
    return job.result
