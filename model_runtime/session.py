"""ReactionSession: the online rollout of one ego, one 10 fps model frame per `step()`.

A session is a ReactionGroup (group.py) of one ego, with the settings of that ego on the session itself;
group.py describes the scheduling. The same seed and inputs give the same frames, and a step that fails
(bad input or a non-finite pose) leaves the session exactly as it was before it.
"""
from __future__ import annotations

from typing import Any, Sequence

import torch

from .checks import check_control_config
from .control import ControlConfig
from .ego import EgoFrame, EgoSettings
from .group import ReactionGroup
from .model import ReMoGenModel
from .schedule import BOUNDARY_COST, STEERED_STEP_COST, steps_per_frame

__all__ = ["ReactionSession", "EgoFrame", "STEERED_STEP_COST", "BOUNDARY_COST", "steps_per_frame"]


class ReactionSession:
    """Online reaction generation for one ego. See group.py for the scheduling."""

    def __init__(self, model: ReMoGenModel, text: str = "", seed: int = 0, alpha: dict | None = None,
                 guidance: float = 5.0, fwsr: bool = True, scene: Any = None, slide: bool = False,
                 cleanup: bool = True, control: bool = True, control_config: ControlConfig | None = None) -> None:
        settings = EgoSettings(text=text, seed=seed, alpha=alpha, guidance=guidance, fwsr=fwsr, cleanup=cleanup)
        self._group = ReactionGroup(model, [settings], scene=scene, slide=slide, control=control,
                                    control_config=control_config)
        self._ego = self._group.egos[0]

    @property
    def model(self) -> ReMoGenModel:
        return self._group.model

    @property
    def cfg(self):
        return self._group.cfg

    # ------------------------------------------------------------------ live settings of the ego
    @property
    def seed(self) -> int:
        """The noise seed; used from the next reset()."""
        return self._ego.seed

    @seed.setter
    def seed(self, value: int) -> None:
        self._ego.seed = value

    @property
    def text(self) -> str:
        return self._ego.text

    @text.setter
    def text(self, value: str) -> None:
        self._ego.text = value

    @property
    def text_warning(self) -> str | None:
        """One line when the text encoder cannot read the current text (another script, only emoji or symbols),
        else None."""
        return self._ego.text_warning

    @property
    def alpha(self) -> dict[str, float]:
        return self._ego.alpha

    @alpha.setter
    def alpha(self, value: dict | None) -> None:
        self._ego.alpha = value

    @property
    def guidance(self) -> float:
        return self._ego.guidance

    @guidance.setter
    def guidance(self, value: float) -> None:
        self._ego.guidance = value

    @property
    def fwsr(self) -> bool:
        return self._ego.fwsr

    @fwsr.setter
    def fwsr(self, value: bool) -> None:
        self._ego.fwsr = value

    @property
    def cleanup(self) -> bool:
        """Planted-foot cleanup of the output (leg IK); contacts are reported either way. Next frame on."""
        return self._ego.cleanup

    @cleanup.setter
    def cleanup(self, value: bool) -> None:
        self._ego.cleanup = value

    # ------------------------------------------------------------------ settings of the rollout
    @property
    def control(self) -> bool:
        """Test-time control (control.py): steer each segment with cost gradients. From the next segment on."""
        return self._group.control

    @control.setter
    def control(self, value: bool) -> None:
        self._group.control = value

    @property
    def control_config(self) -> ControlConfig:
        return self._group.control_config

    @control_config.setter
    def control_config(self, value: ControlConfig) -> None:
        self._group.control_config = check_control_config(value)

    @property
    def scene(self) -> Any:
        return self._group.scene

    @scene.setter
    def scene(self, value: Any) -> None:
        self._group.scene = value

    @property
    def slide(self) -> bool:
        return self._group.slide

    # ------------------------------------------------------------------ rollout
    def reset(self, root_position: Sequence[float] = (0.0, 0.0, 0.0), yaw: float = 0.0,
              frame: EgoFrame | None = None) -> None:
        """Start over standing at rest on the floor point `root_position` facing `yaw`, or from a frame.

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

    def history_world_features(self) -> torch.Tensor:
        """(H, 276) the latest emitted frames as world-frame features (for tools and tests)."""
        return self._ego.hist_world.clone()
