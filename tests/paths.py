"""Locations the tests read (a plain module: test files must not import conftest, which is not unique)."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
