"""Locations the tests read (a plain module: test files must not import conftest, which is not unique).

Some tests also read public motion data and reference files from an optional folder named `shared` beside
the repository (or the folder the REMOGEN_TEST_SHARED environment variable names): `data/` with the CMU
and Bandai Namco clips and their index.csv files, `reference/` with the SMPL-X skeleton. They only read
it, and skip with a reason when a file they need is absent.
"""
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("REMOGEN_TEST_SHARED") or ROOT.parent / "shared")
DATA = SHARED / "data"


def shared_file(rel: str) -> Path:
    """SHARED / rel, or skip the calling test when it is absent."""
    path = SHARED / rel
    if not path.exists():
        pytest.skip(f"test data {rel} not present beside the repository")
    return path


def data_file(rel: str) -> Path:
    """A file of the public motion data (DATA / rel), or skip the calling test when it is absent."""
    return shared_file(f"data/{rel}")
