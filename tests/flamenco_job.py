"""The Flamenco job type under Node: compile_job(settings) runs farm/flamenco/remogen_bake.js through
flamenco_harness.js (a stand-in for the Flamenco Manager's job compiler API) and returns what it produced.

Skips the calling test when Node.js is not installed.
"""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
JOB_SCRIPT = ROOT / "farm" / "flamenco" / "remogen_bake.js"
HARNESS = Path(__file__).resolve().parent / "flamenco_harness.js"


class CompileError(Exception):
    """compileJob() refused the settings; str() is its message."""


def node() -> str:
    exe = shutil.which("node")
    if exe is None:
        pytest.skip("Node.js is not installed (the 'node' command is not on PATH): the Flamenco job type, "
                    "a JavaScript job compiler, cannot be run")
    return exe


def compile_job(settings: dict) -> dict:
    """{'label', 'settings', 'tasks': [{'name', 'type', 'commands': [{'name', 'parameters'}], ...}]}."""
    r = subprocess.run([node(), str(HARNESS), str(JOB_SCRIPT)], input=json.dumps({"settings": settings}),
                       capture_output=True, text=True, timeout=60)
    try:
        out = json.loads(r.stdout)
    except json.JSONDecodeError:
        raise AssertionError(f"the job script failed under Node (exit {r.returncode}): {r.stderr[-2000:]}")
    if "error" in out:
        raise CompileError(out["error"])
    assert r.returncode == 0, r.stderr[-2000:]
    return out
