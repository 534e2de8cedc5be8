"""Checks of the values a caller hands the online runtime: each bad value raises a one-line InputError."""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from .errors import (DEFAULT_FINAL_GUIDANCE_MIN_SPEED, DEFAULT_FINAL_GUIDANCE_SHARE, DEFAULT_GUIDANCE, MAX_COORD,
                     MAX_GUIDANCE, InputError)
from .config import MODULE_NAMES
from .skeleton import JOINT_NAMES, NUM_JOINTS


def check_partner(partner: Any) -> np.ndarray | None:
    if partner is None:
        return None
    try:
        p = np.asarray(partner, dtype=np.float32)
    except (TypeError, ValueError):
        raise InputError("partner must be a (22, 3) array of world joint positions or None") from None
    if p.shape != (NUM_JOINTS, 3):
        raise InputError(f"partner joints must have shape (22, 3) (SMPL-X joint order, metres), got {p.shape}")
    # Blender stores inf as float32 max, so "finite" alone is not enough: bound the magnitude too
    bad = ~(np.isfinite(p) & (np.abs(p) < MAX_COORD)).all(axis=1)
    if bad.any():
        names = ", ".join(JOINT_NAMES[i] for i in np.flatnonzero(bad)[:4])
        raise InputError(f"partner joints contain NaN, inf or values beyond {MAX_COORD:.0e} m ({names}); "
                         "fix the partner's transforms or pass None")
    extent = float(np.ptp(p, axis=0).max())
    if extent > 5.0:
        raise InputError(f"partner skeleton spans {extent:.1f} m; it looks like centimetres: scale it by 0.01")
    return p


def check_point(name: str, v: Any) -> np.ndarray | None:
    if v is None:
        return None
    try:
        p = np.asarray(v, dtype=np.float32).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an (x, y, z) point in metres or None") from None
    if p.shape != (3,):
        shape = np.shape(v)
        raise InputError(f"{name} must be one (x, y, z) point in metres or None, got {p.size} values (shape {shape}); "
                         "pass a single point")
    if not (np.isfinite(p) & (np.abs(p) < MAX_COORD)).all():
        raise InputError(f"{name} must be a finite (x, y, z) point within {MAX_COORD:.0e} m, or None; "
                         f"got ({', '.join(f'{x:g}' for x in p)})")
    return p


def _is_real(value: Any) -> bool:
    """An int or float (NumPy's too), not a bool (an int in Python, but never a meant number)."""
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


def check_seed(seed: Any) -> int:
    # bool is an int in Python but never a meant seed; floats would be truncated silently
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2 ** 64:
        raise InputError(f"seed must be an integer in 0..2**64-1, got {seed!r}; pass e.g. seed=0")
    return int(seed)


def check_alpha(alpha: Any) -> dict[str, float]:
    if alpha is None:
        return {k: 1.0 for k in MODULE_NAMES}
    if not isinstance(alpha, dict):
        raise InputError("alpha must be a dict like {'hhi': 1.0, 'hsi': 0.5}")
    unknown = sorted(map(repr, set(alpha) - set(MODULE_NAMES)))
    if unknown:
        raise InputError(f"unknown alpha key(s) {', '.join(unknown)}; use {list(MODULE_NAMES)}")
    out = {}
    for k in MODULE_NAMES:
        v = alpha.get(k, 0.0)
        if not _is_real(v) or not (math.isfinite(v) and v >= 0):
            raise InputError(f"alpha[{k!r}] must be a finite number >= 0, got {v!r}; e.g. {{'{k}': 1.0}}")
        out[k] = float(v)
    return out


def check_guidance(value: Any) -> float:
    if not _is_real(value) or not 0.0 <= float(value) <= MAX_GUIDANCE:
        raise InputError(f"guidance must be a number in 0..{MAX_GUIDANCE:g} (default {DEFAULT_GUIDANCE:g}), "
                         f"got {value!r}")
    return float(value)


def check_final_guidance_share(value: Any) -> float:
    if not _is_real(value) or not 0.0 <= float(value) <= 1.0:
        raise InputError(f"final guidance share must be a number in 0..1 (default {DEFAULT_FINAL_GUIDANCE_SHARE:g}), "
                         f"got {value!r}")
    return float(value)


def check_final_guidance_min_speed(value: Any) -> float:
    if not _is_real(value) or not math.isfinite(float(value)) or float(value) < 0.0:
        raise InputError(f"final guidance min speed must be a finite number of m/s >= 0 "
                         f"(default {DEFAULT_FINAL_GUIDANCE_MIN_SPEED:g}), got {value!r}")
    return float(value)


def check_text(value: Any) -> str:
    if not isinstance(value, str):
        raise InputError(f"text must be a string, got {type(value).__name__}")
    return value


def check_scene(value: Any) -> Any:
    if value is not None and not hasattr(value, "sample_ego"):
        raise InputError("scene must be an OccupancyGrid (model_runtime.OccupancyGrid) or None")
    return value


def check_control_config(value: Any) -> Any:
    from .control import ControlConfig
    if not isinstance(value, ControlConfig):
        raise InputError("control_config must be a model_runtime.ControlConfig")
    return value


class Checked:
    """An attribute whose every assignment goes through `check` (which raises a one-line InputError for bad
    input and returns the value to keep), stored as `_<name>` on the instance."""

    def __init__(self, check: Callable[[Any], Any], doc: str | None = None) -> None:
        self.check = check
        self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        return self if obj is None else getattr(obj, self.slot)

    def __set__(self, obj: Any, value: Any) -> None:
        setattr(obj, self.slot, self.check(value))
