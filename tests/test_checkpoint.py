import pytest
import torch

from model_runtime import ModelFileError, load_model, save_model
from model_runtime.checkpoint import DEFAULT_WEIGHTS
from model_runtime.model import Contexts


def x0(model):
    cfg = model.cfg
    g = torch.Generator().manual_seed(0)
    z = torch.randn(1, cfg.latent_tokens, cfg.latent_dim, generator=g)
    hist = torch.randn(1, cfg.history, cfg.feature_dim, generator=g)
    with torch.inference_mode():
        return model.predict_x0(z, 3, hist, model.encode_text("wave"), Contexts({}), {}, 3.0)


def test_save_load_round_trip(tmp_path, tiny_model):
    path = save_model(tiny_model, tmp_path / "m.pt", meta={"note": "test"})
    loaded = load_model(path)
    assert loaded.cfg == tiny_model.cfg
    assert loaded.meta["note"] == "test"
    assert torch.equal(x0(loaded), x0(tiny_model))
    assert torch.equal(loaded.fwsr.sensitivity, tiny_model.fwsr.sensitivity)


def test_random_models_are_seeded():
    assert torch.equal(x0(load_model(config="tiny", seed=3)), x0(load_model(config="tiny", seed=3)))
    assert not torch.equal(x0(load_model(config="tiny", seed=3)), x0(load_model(config="tiny", seed=4)))


def one_line(err):
    assert "\n" not in str(err.value)
    return str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(ModelFileError) as err:
        load_model(tmp_path / "nope.pt")
    assert "not found" in one_line(err)


def test_truncated_file(tmp_path, tiny_model):
    path = save_model(tiny_model, tmp_path / "m.pt")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelFileError) as err:
        load_model(path)
    assert "truncated" in one_line(err)


def test_foreign_files(tmp_path):
    p = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, p)
    with pytest.raises(ModelFileError) as err:
        load_model(p)
    assert "not a ReMoGen model file" in one_line(err)
    txt = tmp_path / "notes.pt"
    txt.write_text("hello")
    with pytest.raises(ModelFileError):
        load_model(txt)


class Payload:  # pickled code must never run on load
    def __reduce__(self):
        return (print, ("code executed",))


def test_pickled_code_is_refused(tmp_path, capsys):
    p = tmp_path / "evil.pt"
    torch.save({"format": "remogen", "x": Payload()}, p)
    with pytest.raises(ModelFileError) as err:
        load_model(p)
    assert "cannot be loaded safely" in one_line(err)
    assert "code executed" not in capsys.readouterr().out


def test_mismatched_state_and_newer_version(tmp_path, tiny_model):
    payload = torch.load(save_model(tiny_model, tmp_path / "m.pt"), weights_only=True)
    payload["state_dict"]["vae.out.weight"] = torch.zeros(5, 5)
    torch.save(payload, tmp_path / "bad.pt")
    with pytest.raises(ModelFileError) as err:
        load_model(tmp_path / "bad.pt")
    assert "does not match" in one_line(err)
    payload["format_version"] = 99
    torch.save(payload, tmp_path / "new.pt")
    with pytest.raises(ModelFileError, match="version 99"):
        load_model(tmp_path / "new.pt")


def test_default_weights_or_a_clear_message():
    if DEFAULT_WEIGHTS.exists():
        assert load_model().cfg.preset
    else:
        with pytest.raises(ModelFileError, match="no shipped weights"):
            load_model()


def test_unknown_config():
    with pytest.raises(ValueError, match="unknown model config"):
        load_model(config="huge")


@pytest.mark.parametrize("precision", ["bf16", "int8"])
def test_reduced_precisions_step_and_stay_close(precision):
    """bf16 / int8 diffusion networks: a session runs, and the first segment stays near the fp32 one (the
    VAE decoder and FWSR stay float32). int8 swaps the denoiser's linear layers for quantised ones."""
    import numpy as np
    from model_runtime import ReactionSession

    def frames(model):
        s = ReactionSession(model, text="walk", seed=0, guidance=1.0)
        s.reset()
        return np.stack([s.step().joints for _ in range(8)])

    ref = frames(load_model(config="tiny"))
    low_model = load_model(config="tiny", precision=precision)
    low = frames(low_model)
    assert np.isfinite(low).all() and low.shape == ref.shape
    assert np.abs(low - ref).max() < 0.1                       # metres, over the first segment
    if precision == "int8":
        assert not any(isinstance(m, torch.nn.Linear) and type(m) is torch.nn.Linear
                       for m in low_model.denoiser.modules())
        with pytest.raises(Exception, match="already int8"):
            low_model.set_precision("fp32")


def test_unknown_precision_names_the_choices():
    with pytest.raises(Exception, match="'fp32', 'bf16' or 'int8'"):
        load_model(config="tiny", precision="fp16")
