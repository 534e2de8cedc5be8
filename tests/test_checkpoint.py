import copy
import warnings

import pytest
import torch

from model_runtime import InputError, ModelConfig, ModelFileError, load_model, save_model
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
    with pytest.warns(UserWarning, match="untrained"):     # random weights
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


def saved_payload(tmp_path, model, **meta):
    return torch.load(save_model(model, tmp_path / "m.pt", meta=meta or None), weights_only=True)


def load_payload(tmp_path, payload):
    torch.save(payload, tmp_path / "edited.pt")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                     # random weights: only the error matters here
        return load_model(tmp_path / "edited.pt")


@pytest.mark.parametrize("key", ["config", "state_dict"])
def test_a_file_without_config_or_weights_is_one_line(tmp_path, tiny_model, key):
    payload = saved_payload(tmp_path, tiny_model)
    del payload[key]
    with pytest.raises(ModelFileError) as err:
        load_payload(tmp_path, payload)
    assert f"no '{key}'" in one_line(err)


@pytest.mark.parametrize("version", [0, -1, True, "1", None])
def test_only_supported_format_versions_load(tmp_path, tiny_model, version):
    payload = saved_payload(tmp_path, tiny_model)
    payload["format_version"] = version
    with pytest.raises(ModelFileError) as err:
        load_payload(tmp_path, payload)
    assert "format version" in one_line(err)


@pytest.mark.parametrize("field, value, words", [
    ("future", 1000, "future = 1000 must be an integer in 1..64"),
    ("history", 0, "history = 0"),
    ("den_heads", 3, "multiple of den_heads"),
    ("inject_layers", [7], "inject_layers"),
    ("text", {"name": "hashed_ngram", "dim": 32, "buckets": -1, "seed": 1}, "text['buckets']"),
    ("dropout", "x", "dropout"),
    ("feature_dim", 10, "feature_dim"),
])
def test_out_of_range_config_in_a_file_is_one_line(tmp_path, tiny_model, field, value, words):
    payload = saved_payload(tmp_path, tiny_model)
    payload["config"][field] = value
    with pytest.raises(ModelFileError) as err:
        load_payload(tmp_path, payload)
    assert words in one_line(err) and "re-train or re-download" in str(err.value)


@pytest.mark.parametrize("kwargs, words", [
    ({"future": 10 ** 9}, "future = 1000000000 must be an integer in 1..64"),   # would allocate 512 GB
    ({"latent_dim": 2.5}, "latent_dim"),
    ({"scene_bounds": ((1.0, -1.0), (0.0, 1.0), (0.0, 1.0))}, "scene_bounds"),
    ({"partner_window": 1}, "partner_window"),
    ({"voxel_patch": 5}, "voxel_patch"),
])
def test_config_fields_are_checked_on_construction(kwargs, words):
    with pytest.raises(InputError) as err:
        ModelConfig(**kwargs)
    assert words in one_line(err)


def test_the_presets_are_valid_configs():
    for preset in ("tiny", "default", "paper"):
        assert load_model(config=preset).cfg.preset == preset


def test_nan_weights_are_refused_on_load_and_on_save(tmp_path, tiny_model):
    payload = saved_payload(tmp_path, tiny_model)
    payload["state_dict"]["vae.out.bias"][0] = float("nan")
    with pytest.raises(ModelFileError) as err:
        load_payload(tmp_path, payload)
    assert "NaN or inf" in one_line(err) and "vae.out.bias" in str(err.value)
    broken = copy.deepcopy(tiny_model)
    with torch.no_grad():
        broken.denoiser.out.weight[0, 0] = float("inf")
    with pytest.raises(ModelFileError) as err:
        save_model(broken, tmp_path / "broken.pt")
    assert "denoiser.out.weight" in one_line(err)
    assert not (tmp_path / "broken.pt").exists()


def stage_record(steps):
    return {"steps": steps, "wall_s": 1.0, "val_loss": 0.1}


def test_a_partly_trained_file_warns_naming_the_untrained_stages(tmp_path, tiny_model):
    path = save_model(tiny_model, tmp_path / "vae_only.pt",
                      meta={"trained": True, "stages": {"vae": stage_record(100), "prior": stage_record(0)}})
    with pytest.warns(UserWarning, match=r"only partly trained \(untrained: prior, hhi, hsi, fwsr\)") as rec:
        load_model(path)
    assert len(rec) == 1 and "\n" not in str(rec[0].message)


def test_a_fully_trained_or_unrecorded_file_loads_silently(tmp_path, tiny_model):
    full = {s: stage_record(10) for s in ("vae", "prior", "hhi", "hsi", "fwsr")}
    done = save_model(tiny_model, tmp_path / "full.pt", meta={"trained": True, "stages": full})
    old = tmp_path / "old.pt"
    payload = torch.load(done, weights_only=True)
    payload["meta"] = {"note": "a file from before stages were recorded"}
    torch.save(payload, old)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_model(done)
        load_model(old)


def test_damping_cli_writes_a_new_file_with_only_the_fwsr_beta_changed(tmp_path, tiny_model, capsys):
    from model_runtime.damping import main
    src = save_model(tiny_model, tmp_path / "in.pt")
    out = tmp_path / "out.pt"
    assert main([str(src), "--fwsr-beta", "4", "--out", str(out)]) == 0
    damped = load_model(out)
    assert damped.cfg.fwsr_beta == 4.0 and damped.meta["fwsr_beta_from"] == tiny_model.cfg.fwsr_beta
    original = load_model(src)
    assert original.cfg.fwsr_beta == tiny_model.cfg.fwsr_beta          # the input is unchanged
    assert all(torch.equal(a, b) for a, b in zip(damped.state_dict().values(), original.state_dict().values()))
    # an existing output or a bad value: one line, nothing written
    assert main([str(src), "--fwsr-beta", "2", "--out", str(out)]) == 2
    assert load_model(out).cfg.fwsr_beta == 4.0
    assert main([str(src), "--fwsr-beta", "-1", "--out", str(tmp_path / "bad.pt")]) == 2
    assert not (tmp_path / "bad.pt").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("error: ") for line in err)
