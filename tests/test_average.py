"""Averaging the priors of model files (model_runtime.training.average)."""
import copy

import pytest
import torch

from model_runtime.checkpoint import load_model, save_model
from model_runtime.errors import RemogenError
from model_runtime.training.average import average_stage, main, parse_source


def _pair():
    a = load_model(config="tiny", seed=0)
    b = copy.deepcopy(a)
    with torch.no_grad():
        for p in b.denoiser.parameters():
            p.add_(1.0)
    return a, b


def test_the_prior_is_the_weighted_mean_and_the_rest_is_kept():
    a, b = _pair()
    before = {k: v.clone() for k, v in a.denoiser.state_dict().items()}
    hhi = {k: v.clone() for k, v in a.mims.state_dict().items()}
    out = average_stage([a, b], [3.0, 1.0])      # normalised: 0.75 and 0.25
    for k, v in out.denoiser.state_dict().items():
        assert torch.allclose(v, before[k] + 0.25, atol=1e-6), k
    assert all(torch.equal(v, hhi[k]) for k, v in out.mims.state_dict().items())


def test_files_that_differ_outside_the_prior_are_refused():
    a, b = _pair()
    with torch.no_grad():
        next(b.mims.parameters()).add_(0.1)
    with pytest.raises(RemogenError, match="mims"):
        average_stage([a, b], [1.0, 1.0])
    with pytest.raises(RemogenError, match="at least two"):
        average_stage([a], [1.0])


def test_sources_are_read_with_their_weights():
    assert parse_source("runs/x/model.pt") == ("runs/x/model.pt", 1.0)
    assert parse_source("runs/x/model.pt:0.35") == ("runs/x/model.pt", 0.35)
    assert parse_source("C:/models/a.pt") == ("C:/models/a.pt", 1.0)
    with pytest.raises(RemogenError, match="positive"):
        parse_source("model.pt:0")


def test_the_command_writes_the_average_and_records_its_sources(tmp_path, capsys):
    a, b = _pair()
    save_model(a, tmp_path / "a.pt")
    save_model(b, tmp_path / "b.pt")
    out = tmp_path / "avg.pt"
    assert main([str(tmp_path / "a.pt"), f"{tmp_path / 'b.pt'}:1", "--out", str(out)]) == 0
    avg = load_model(out, warn_untrained=False)
    ref = a.denoiser.state_dict()
    assert all(torch.allclose(v, ref[k] + 0.5, atol=1e-6) for k, v in avg.denoiser.state_dict().items())
    record = avg.meta["stages"]["prior"]["averaged_from"]
    assert [(r["file"], r["weight"]) for r in record] == [("a.pt", 0.5), ("b.pt", 0.5)]
    assert "averaged_from" not in record[0]
    # an average of an average keeps the first one's record inside its source's
    again = tmp_path / "again.pt"
    assert main([str(out), f"{tmp_path / 'b.pt'}:3", "--out", str(again)]) == 0
    chained = load_model(again, warn_untrained=False).meta["stages"]["prior"]["averaged_from"]
    assert [(r["file"], r["weight"]) for r in chained] == [("avg.pt", 0.25), ("b.pt", 0.75)]
    assert chained[0]["averaged_from"] == record and "averaged_from" not in chained[1]
    # a bad weight: one line, nothing written
    bad = tmp_path / "bad.pt"
    assert main([str(tmp_path / "a.pt"), f"{tmp_path / 'b.pt'}:-1", "--out", str(bad)]) == 2
    assert not bad.exists() and "positive" in capsys.readouterr().err


def test_the_decoder_alone_can_be_averaged_and_the_encoder_must_match():
    a = load_model(config="tiny", seed=0)
    b = copy.deepcopy(a)
    decoder = b.vae.decoder_parts()
    with torch.no_grad():
        for p in decoder.parameters():
            p.add_(1.0)
    encoder_before = {k: v.clone() for k, v in a.vae.in_proj.state_dict().items()}
    ref = {k: v.clone() for k, v in a.vae.decoder_parts().state_dict().items()}
    out = average_stage([a, b], [1.0, 1.0], "decoder")
    for k, v in out.vae.decoder_parts().state_dict().items():
        assert torch.allclose(v, ref[k] + 0.5, atol=1e-6), k
    assert all(torch.equal(v, encoder_before[k]) for k, v in out.vae.in_proj.state_dict().items())
    c = copy.deepcopy(a)
    with torch.no_grad():
        next(c.vae.in_proj.parameters()).add_(0.1)
    with pytest.raises(RemogenError, match="outside the decoder"):
        average_stage([a, c], [1.0, 1.0], "decoder")
    with pytest.raises(RemogenError, match="unknown stage"):
        average_stage([a, b], [1.0, 1.0], "encoder")
