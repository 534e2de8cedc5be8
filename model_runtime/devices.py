"""Which torch device a command runs on (`--device auto|cpu|cuda|cuda:N`), and its name for reports."""
from __future__ import annotations

import os

import torch

from .errors import RemogenError


def resolve_device(name: str) -> torch.device:
    """auto: a CUDA GPU when this PyTorch sees one, else the CPU. Plain "cuda" under torchrun takes the GPU
    LOCAL_RANK. A one-line RemogenError names what is wrong with any other name."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    try:
        device = torch.device(name)
    except RuntimeError:
        raise RemogenError(f"--device {name!r} is not a device; use auto, cpu, cuda or cuda:N") from None
    if device.type not in ("cpu", "cuda"):
        raise RemogenError(f"--device {name!r}: this runs on cpu or cuda; use auto, cpu, cuda or cuda:N")
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise RemogenError(f"--device {name}: this PyTorch sees no CUDA GPU; use --device cpu (or auto)")
        if device.index is None:
            device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
        if device.index >= torch.cuda.device_count():
            raise RemogenError(f"--device {device}: only {torch.cuda.device_count()} GPU(s) are visible")
        torch.cuda.set_device(device)
    return device


def device_name(device: torch.device) -> str:
    """'cpu', or the GPU's name as the driver reports it."""
    return torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu"
