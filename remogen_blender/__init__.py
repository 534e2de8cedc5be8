"""ReMoGen for Blender: a live reactive SMPL-X character (the ego) driven by model_runtime.

Registration only: importing torch and model_runtime waits until an operator needs them, so the add-on
registers (and the panel explains what is missing) on a Blender without PyTorch.
"""
from __future__ import annotations

import bpy

from . import _runtime, operators, panels, preferences, properties

_MODULES = (properties, preferences, operators, panels)
_cli_handle = None


def _cli(argv: list[str]) -> int:
    from .cli import cli_main
    return cli_main(argv)


def register() -> None:
    global _cli_handle
    _runtime.add_private_site_packages()
    for m in _MODULES:
        m.register()
    if hasattr(bpy.utils, "register_cli_command"):
        _cli_handle = bpy.utils.register_cli_command("remogen", _cli)


def unregister() -> None:
    global _cli_handle
    if _cli_handle is not None:
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
    for m in reversed(_MODULES):
        m.unregister()
