"""Joining HHI and HSI trained side by side from one prior file (model_runtime.training.merge)."""
from __future__ import annotations

import copy

import pytest
import torch

from model_runtime.checkpoint import load_model, save_model
from model_runtime.errors import RemogenError
from model_runtime.training.merge import main, merge_stages


def _trained(model, stage: str, value: float):
    m = copy.deepcopy(model)
    for p in m.mims[stage].parameters():
        p.data.fill_(value)
    m.meta = dict(m.meta, stages={**m.meta.get("stages", {}), stage: {"steps": 7}})
    return m


@pytest.mark.filterwarnings("ignore:.*partly trained")
def test_merge_takes_the_other_files_module_and_its_record(tiny_model, tmp_path):
    hhi = _trained(tiny_model, "hhi", 0.25)
    hsi = _trained(tiny_model, "hsi", 0.5)
    save_model(hhi, tmp_path / "hhi.pt")
    save_model(hsi, tmp_path / "hsi.pt")
    assert main([str(tmp_path / "hhi.pt"), str(tmp_path / "hsi.pt"), "--take", "hsi",
                 "--out", str(tmp_path / "both.pt")]) == 0
    both = load_model(tmp_path / "both.pt")
    assert all(torch.all(p == 0.25) for p in both.mims["hhi"].parameters())
    assert all(torch.all(p == 0.5) for p in both.mims["hsi"].parameters())
    assert both.meta["stages"]["hhi"] == {"steps": 7} and both.meta["stages"]["hsi"] == {"steps": 7}


def test_merge_refuses_modules_of_another_prior(tiny_model):
    other = _trained(tiny_model, "hsi", 0.5)
    next(other.denoiser.parameters()).data.add_(1.0)
    with pytest.raises(RemogenError, match="different denoiser"):
        merge_stages(copy.deepcopy(tiny_model), other, ("hsi",))
    with pytest.raises(RemogenError, match="no trained hhi"):
        merge_stages(copy.deepcopy(tiny_model), _trained(tiny_model, "hsi", 0.5), ("hhi",))


def _decoder_trained(model, value: float):
    m = copy.deepcopy(model)
    for p in m.vae.decoder_parts().parameters():
        p.data.fill_(value)
    m.meta = dict(m.meta, stages={**m.meta.get("stages", {}), "decoder": {"steps": 5}})
    return m


def test_merge_joins_a_decoder_trained_beside_the_prior(tiny_model):
    prior = copy.deepcopy(tiny_model)
    next(prior.denoiser.parameters()).data.add_(1.0)       # the prior trained on in its own folder
    decoder = _decoder_trained(tiny_model, 0.75)
    merged = merge_stages(copy.deepcopy(prior), decoder, ("decoder",))
    assert all(torch.all(p == 0.75) for p in merged.vae.decoder_parts().parameters())
    assert torch.equal(merged.vae.in_proj.weight, tiny_model.vae.in_proj.weight)   # the encoder kept
    assert all(torch.equal(a, b) for a, b in zip(merged.denoiser.parameters(), prior.denoiser.parameters()))
    assert merged.meta["stages"]["decoder"] == {"steps": 5}


def test_merge_refuses_a_decoder_of_another_encoder_or_beside_a_module(tiny_model):
    other = _decoder_trained(tiny_model, 0.75)
    other.vae.in_proj.weight.data.add_(1.0)
    with pytest.raises(RemogenError, match="different encoder"):
        merge_stages(copy.deepcopy(tiny_model), other, ("decoder",))
    both = _trained(_decoder_trained(tiny_model, 0.75), "hsi", 0.5)
    with pytest.raises(RemogenError, match="on its own"):
        merge_stages(copy.deepcopy(tiny_model), both, ("decoder", "hsi"))
    with_fwsr = copy.deepcopy(tiny_model)
    with_fwsr.meta = dict(with_fwsr.meta, stages={**with_fwsr.meta.get("stages", {}), "fwsr": {"steps": 3}})
    with pytest.raises(RemogenError, match="FWSR"):
        merge_stages(with_fwsr, _decoder_trained(tiny_model, 0.75), ("decoder",))
