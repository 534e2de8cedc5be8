"""Environments for subprocesses that must run under the same Blender module (bpy) as the tests.

A second Blender version can be tested by putting its bpy first on PYTHONPATH (`PYTHONPATH=.bpy5`);
subprocesses that set their own PYTHONPATH keep that folder, made absolute (they run in other folders).
"""
from __future__ import annotations

import os
from pathlib import Path

BPY_FOLDERS = [str(Path(p).resolve()) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
               if p and (Path(p) / "bpy").is_dir()]


def subprocess_env(*paths: str | Path, drop: tuple[str, ...] = ()) -> dict[str, str]:
    """os.environ without the variables in `drop`, with PYTHONPATH = the tests' bpy folder + `paths`."""
    env = {k: v for k, v in os.environ.items() if k not in drop and k != "PYTHONPATH"}
    entries = BPY_FOLDERS + [str(p) for p in paths]
    if entries:
        env["PYTHONPATH"] = os.pathsep.join(entries)
    return env
