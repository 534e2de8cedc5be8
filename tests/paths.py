"""Locations the tests read (a plain module: test files must not import conftest, which is not unique).

Some tests also read public motion data and reference files from an optional folder named `shared` beside
the repository (or the folder the REMOGEN_TEST_SHARED environment variable names): `data/` with the CMU
and Bandai Namco clips and their index.csv files, `reference/` with the SMPL-X skeleton. They only read
it, and skip with a reason when a file they need is absent.

Real two-person takes (CMU trials of subjects 18-23, 33-34) are not part of that data; tests read them from the
folder the REMOGEN_TWO_PERSON_DIR environment variable names (laid out for model_runtime.data.two_person) and
skip without it.
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


def two_person_dir() -> Path:
    """The folder of real two-person takes (REMOGEN_TWO_PERSON_DIR), or skip the calling test."""
    folder = os.environ.get("REMOGEN_TWO_PERSON_DIR")
    if not folder:
        pytest.skip("REMOGEN_TWO_PERSON_DIR is not set (a folder of real two-person BVH takes)")
    if not Path(folder).is_dir():
        pytest.skip(f"REMOGEN_TWO_PERSON_DIR={folder} is not a folder")
    return Path(folder)
