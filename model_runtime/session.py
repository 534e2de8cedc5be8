"""ReactionSession: the online rollout of one ego, one 10 fps model frame per `step()`.

A session is a ReactionGroup (group.py) of one ego, with the settings of that ego on the session itself;
group.py describes the scheduling. The same seed and inputs give the same frames, and a step that fails
(bad input or a non-finite pose) leaves the session exactly as it was before it.
"""
from __future__ import annotations

from typing import Any, Sequence

import torch

from .errors import DEFAULT_GUIDANCE
from .control import ControlConfig
from .ego import EgoFrame, EgoSettings
from .group import ReactionGroup
from .model import ReMoGenModel
from .schedule import BOUNDARY_COST, STEERED_STEP_COST, steps_per_frame

__all__ = ["ReactionSession", "EgoFrame", "STEERED_STEP_COST", "BOUNDARY_COST", "steps_per_frame"]


class _Through:
    """A property that reads (and writes) the attribute of the same name on an inner object."""

    def __init__(self, inner: str, doc: str = "", read_only: bool = False) -> None:
        self.inner, self.read_only, self.__doc__ = inner, read_only, doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        return self if obj is None else getattr(getattr(obj, self.inner), self.name)

    def __set__(self, obj: Any, value: Any) -> None:
        if self.read_only:
            raise AttributeError(f"{self.name} is read-only")
        setattr(getattr(obj, self.inner), self.name, value)


class ReactionSession:
    """Online reaction generation for one ego. See group.py for the scheduling."""

    def __init__(self, model: ReMoGenModel, text: str = "", seed: int = 0, alpha: dict | None = None,
                 guidance: float = DEFAULT_GUIDANCE, fwsr: bool = True, scene: Any = None, slide: bool = False,
                 cleanup: bool = True, control: bool = True, control_config: ControlConfig | None = None,
                 pipeline: bool = False) -> None:
        settings = EgoSettings(text=text, seed=seed, alpha=alpha, guidance=guidance, fwsr=fwsr, cleanup=cleanup)
        self._group = ReactionGroup(model, [settings], scene=scene, slide=slide, control=control,
                                    control_config=control_config, pipeline=pipeline)
        self._ego = self._group.egos[0]

    @property
    def model(self) -> ReMoGenModel:
        return self._group.model

    @property
    def cfg(self):
        return self._group.cfg

    # Settings of the one ego and of the rollout, read and written straight through (the ego and the group
    # check the values and keep the state; a session only gives them the single-ego API).
    seed = _Through("_ego", "The noise seed; used from the next reset().")
    text = _Through("_ego")
    text_warning = _Through("_ego", "One line when the text encoder cannot read the prompt, else None.",
                            read_only=True)
    alpha = _Through("_ego")
    guidance = _Through("_ego")
    fwsr = _Through("_ego")
    cleanup = _Through("_ego", "Planted-foot cleanup of the output (leg IK); contacts are reported either way.")
    control = _Through("_group", "Test-time control (control.py): steer each segment with cost gradients. "
                                 "From the next segment on.")
    control_config = _Through("_group")
    pipeline = _Through("_group", "Run each segment's diffusion in a helper process (job_worker.py): the same "
                                  "frames, less work per step here.")
    scene = _Through("_group")
    slide = _Through("_group", read_only=True)

    def helper_ready(self, timeout: float = 0.0) -> bool:
        """Whether pipelined jobs now run in the helper process, waiting up to `timeout` s (ReactionGroup)."""
        return self._group.helper_ready(timeout)

    # ------------------------------------------------------------------ rollout
    def reset(self, root_position: Sequence[float] = (0.0, 0.0, 0.0), yaw: float = 0.0,
              frame: EgoFrame | Sequence[EgoFrame] | None = None) -> None:
        """Start over standing at rest on the floor point `root_position` facing `yaw`, or from a frame, or moving
        on from a list of frames (the body's latest frames at 10 fps, oldest first: a walking body keeps its pace).

        yaw is in radians about +Z; yaw = 0 faces -Y (the SMPL-X rest facing, Blender's front view).
        """
        self._group.reset([root_position], [yaw], [frame])

    def step(self, partner: Any = None, goal: Any = None) -> EgoFrame:
        """Advance one model frame (0.1 s). partner: (22, 3) world joints or None; goal: (x, y, z) or None.

        Raises InputError for bad inputs and ModelOutputError for a non-finite pose; either way the
        session is left exactly as before the call.
        """
        return self._group.step(partner, [goal])[0]

    # ------------------------------------------------------------------ introspection
    @property
    def frame_index(self) -> int:
        return self._group.frame_index

    @property
    def reads_scene_next(self) -> bool:
        """Whether the next step reads `scene` (it starts a segment): see ReactionGroup.reads_scene_next."""
        return self._group.reads_scene_next

    def history_world_features(self) -> torch.Tensor:
        """(H, 276) the latest emitted frames as world-frame features (for tools and tests)."""
        return self._ego.hist_world.clone()
