import json

import torch

from model_runtime.diffusion import CosineSchedule
from model_runtime.text import HashedNgramEncoder


def test_cosine_schedule_shape():
    s = CosineSchedule(10)
    assert s.sqrt_abar.shape == (10,)
    assert (s.sqrt_abar[1:] < s.sqrt_abar[:-1]).all()
    assert s.sqrt_abar[0] > 0.95 and s.sqrt_abar[-1] < 0.05


def test_reverse_process_with_a_perfect_x0_returns_x0():
    s = CosineSchedule(10)
    x0 = torch.randn(4, 1, 8)
    g = torch.Generator().manual_seed(0)
    z = torch.randn(x0.shape, generator=g)
    for t in range(9, -1, -1):
        z = s.step(z, t, x0, torch.randn(x0.shape, generator=g))
    assert torch.equal(z, x0)


def test_q_sample_interpolates():
    s = CosineSchedule(10)
    x0, noise = torch.ones(2, 3), torch.zeros(2, 3)
    assert torch.allclose(s.q_sample(x0, torch.tensor([0, 9]), noise)[:, 0], s.sqrt_abar[[0, 9]])


def test_text_encoder_is_deterministic_and_semantic_enough():
    a, b = HashedNgramEncoder(), HashedNgramEncoder()
    v = a.encode(["walk to the left", "a person walks left", "sit down", ""])
    assert torch.equal(v, b.encode(["walk to the left", "a person walks left", "sit down", ""]))
    assert float(v[0] @ v[1]) > 0.5             # unseen inflection shares subwords
    assert abs(float(v[0] @ v[2])) < 0.3         # unrelated prompt stays apart
    assert torch.equal(v[3], torch.zeros(a.dim))


def test_text_cache_stays_bounded_and_keeps_recent_prompts():
    from model_runtime.text import CACHE_SIZE
    enc = HashedNgramEncoder(dim=8, buckets=64)
    first = enc.encode_one("prompt 0").clone()
    for i in range(1, 3 * CACHE_SIZE):
        enc.encode_one(f"prompt {i}")
        enc.encode_one("walk")                       # used all along: never dropped
    assert len(enc._cache) == CACHE_SIZE
    assert "walk" in enc._cache and "prompt 0" not in enc._cache
    assert torch.equal(enc.encode_one("prompt 0"), first)   # a dropped prompt encodes the same again


def test_bench_prints_all_rows(capsys):
    from model_runtime import bench
    assert bench.main(["--json", "--configs", "tiny", "--frames", "3", "--slide-frames", "2", "--warmup", "2"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["mode"] for r in rows] == ["segment", "fwsr", "fwsr-nocontrol", "fwsr-raw", "slide", "group8", "separate8"]
    for r in rows:
        assert {"config", "mode", "p50_ms", "p99_ms", "frames"} <= set(r) and r["p99_ms"] >= r["p50_ms"] > 0


def test_bench_pipelined_and_paced_rows_say_so(capsys):
    import time
    from model_runtime import bench
    t0 = time.perf_counter()
    assert bench.main(["--json", "--configs", "tiny", "--modes", "fwsr,group2", "--frames", "4", "--warmup", "2",
                       "--precisions", "fp32", "--pipeline", "--pace", "0.05"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines() if line.startswith("{")]
    assert [r["mode"] for r in rows] == ["fwsr", "group2", "separate2"]
    assert all(r["pipeline"] and r["pace_s"] == 0.05 and r["helper_process"] for r in rows)
    assert time.perf_counter() - t0 >= 2 * 6 * 0.05       # paced: 6 ticks of each case at 0.05 s


def test_bench_model_mode_times_the_networks_and_refuses_session_modes_on_a_gpu(capsys):
    import json
    from model_runtime import bench
    assert bench.main(["--json", "--configs", "tiny", "--modes", "model", "--frames", "10", "--warmup", "2",
                       "--precisions", "fp32"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert row["mode"] == "model" and row["frames"] == 10 and row["device"] == "cpu" and row["p50_ms"] > 0
    import pytest
    with pytest.raises(SystemExit, match="only the model mode"):
        bench.main(["--device", "meta", "--configs", "tiny", "--modes", "fwsr"])
