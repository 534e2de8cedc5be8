"""Headless batch with only the `bpy` module (no Blender install):

    python -m remogen_blender.batch bake --blend scene.blend --partner Partner --frames 1 240 --output out.blend

Same arguments and exit statuses as `blender -b -c remogen ...` (0 done, 1 error, 2 bad arguments, 130 / 143
stopped by Ctrl-C / SIGTERM with no output written). Ends with os._exit: with Python objects still
registered, the bpy 4.2 module segfaults and 4.5 hangs at interpreter exit.

    python -m remogen_blender.batch bake-many shots.csv --jobs 4

bakes every row of a CSV shot list, each in its own process (see `bake-many --help` for the columns).
"""
from __future__ import annotations

import os
import sys
from typing import Sequence


def main(argv: Sequence[str]) -> int:
    import bpy  # noqa: F401  - must come before the add-on's modules
    del bpy
    if list(argv[:1]) == ["bake-many"]:   # only starts bakes: the add-on stays unregistered here
        from .bake_many import main as bake_many
        return bake_many(argv[1:])
    from . import register, unregister
    from .cli import cli_main
    register()
    try:
        return cli_main(argv)
    finally:
        unregister()


if __name__ == "__main__":
    rc = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(rc)
