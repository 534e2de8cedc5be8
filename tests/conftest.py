import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


@pytest.fixture(scope="session")
def tiny_model():
    from model_runtime import load_model
    return load_model(config="tiny", seed=0)


@pytest.fixture(autouse=True)
def _single_thread():
    torch.set_num_threads(1)
    yield
