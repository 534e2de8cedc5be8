"""Fixtures for the extension tests, run under the PyPI `bpy` module (skipped cleanly without it).

    .venv-bpy45/bin/python -m pytest tests/blender

Exit guard: with Python objects still registered, the bpy 4.2 module segfaults and 4.5
hangs at interpreter exit. After pytest has written its summary we flush and os._exit with its status.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HAVE_BPY = importlib.util.find_spec("bpy") is not None
_exit_status: list[int] = []

if not HAVE_BPY:
    collect_ignore_glob = ["test_*.py"]   # the plain test run has no bpy: nothing here to collect

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_sessionfinish(session, exitstatus):
    _exit_status.append(int(exitstatus))


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    if "bpy" in sys.modules and _exit_status:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_exit_status[-1])


@pytest.fixture(scope="session")
def bpy_mod():
    import bpy
    return bpy


@pytest.fixture(scope="session")
def tiny_model_file(tmp_path_factory):
    """A small random-weights model saved as a file; the add-on finds it through $REMOGEN_MODEL_FILE."""
    from model_runtime import load_model, save_model
    path = tmp_path_factory.mktemp("model") / "tiny.pt"
    save_model(load_model(config="tiny", seed=0), path)
    old = os.environ.get("REMOGEN_MODEL_FILE")
    os.environ["REMOGEN_MODEL_FILE"] = str(path)
    yield path
    if old is None:
        os.environ.pop("REMOGEN_MODEL_FILE", None)
    else:
        os.environ["REMOGEN_MODEL_FILE"] = old


@pytest.fixture(scope="session")
def addon(bpy_mod, tiny_model_file):
    """The add-on registered from the source tree (the zip install is tested separately)."""
    import remogen_blender
    remogen_blender.register()
    yield remogen_blender
    from remogen_blender import live
    live.stop("tests done")
    remogen_blender.unregister()


@pytest.fixture
def fresh(addon, bpy_mod):
    """An empty file; live stopped before and after."""
    from remogen_blender import _runtime, live
    live.stop("test start")
    bpy_mod.ops.wm.read_factory_settings(use_empty=True)
    _runtime.clear_model_cache()
    yield bpy_mod.context
    live.stop("test end")
