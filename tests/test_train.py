import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from model_runtime import load_model
from model_runtime.train import train_stage
from model_runtime.text_blend import PROMPT_BLEND_KEEP
from model_runtime.training.recipe import TEXT_DROP
from model_runtime.training.samples import SegmentSampler
from synthetic import synthetic_library
from paths import ROOT


@pytest.fixture()
def lib():
    return synthetic_library(20, 40)  # clips 18 and 19 fall in the held-out split


def test_library_split_and_round_trip(tmp_path, lib):
    from model_runtime.data.library import ClipLibrary
    path = lib.save(tmp_path / "clips.npz")
    again = ClipLibrary.load(path)
    assert again.names == lib.names and again.frames(3) == 40
    assert torch.equal(again.features(2), lib.features(2))
    assert again.split("val") == [18, 19]
    assert set(again.split("train")) | set(again.split("val")) == set(range(20))
    assert again.subset({"cmu"}).sources == ["cmu"] * 10


def test_segment_sampler_canonicalises(lib):
    model = load_model(config="tiny")
    s = SegmentSampler(lib, list(range(8)), model.cfg, model.stats, seed=0)
    b = s.sample(5, fwsr=True)
    assert b.hist.shape == (5, 2, 276) and b.fut.shape == (5, 8, 276) and b.recent.shape == (5, 2, 276)
    # first history frame: pelvis above the canonical origin (stats are identity in a fresh model)
    assert torch.allclose(b.hist[:, 0, :2], torch.zeros(5, 2), atol=1e-5)
    assert ((b.frame >= 1) & (b.frame < 8)).all()


def read_log(path):
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_vae_and_prior_stages_train_resume_and_save(tmp_path, lib):
    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=2, batch=8, val_every=2, val_batches=1, progress=False)
    train_stage("vae", out, lib, config="tiny", steps=4, batch=8, val_every=2, val_batches=1, progress=False)
    steps = [r["step"] for r in read_log(out / "vae.log.jsonl")]
    assert steps == [1, 2, 3, 4]                      # resumed, not restarted
    train_stage("prior", out, lib, config="tiny", steps=3, batch=8, val_every=3, val_batches=1, progress=False)
    model = load_model(out / "model.pt")
    assert model.meta["trained"] and set(model.meta["stages"]) == {"vae", "prior"}
    assert model.meta["non_commercial"] is True       # the synthetic library mixes in 'bandai' clips
    assert model.meta["stages"]["prior"]["val_loss"] is not None
    # the caption dropout classifier-free guidance relies on is saved with the stage that trained with it
    assert model.meta["stages"]["prior"]["text_drop"] == TEXT_DROP and "text_drop" not in model.meta["stages"]["vae"]
    assert not torch.equal(model.stats.std, torch.ones(276))  # stats were fitted in the vae stage
    # the prior's training captions go with it, for the runtime's reading of prompts (text_blend.py)
    assert model.meta["prompt_blend"]["captions"] == sorted({lib.captions[i] for i in lib.split("train")})
    assert model.prompt_blend is not None and model.prompt_blend.keep == PROMPT_BLEND_KEEP


def test_a_prior_trained_again_continues_from_its_weights_and_records_them(tmp_path, lib):
    import shutil
    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=2, batch=8, val_every=2, val_batches=1, progress=False)
    train_stage("prior", out, lib, config="tiny", steps=3, batch=8, val_every=3, val_batches=1, progress=False)
    first = load_model(out / "model.pt")
    again = tmp_path / "again"
    again.mkdir()
    shutil.copy(out / "model.pt", again / "model.pt")     # a fine-tune: a trained file, no state of the stage
    train_stage("prior", again, lib, config="tiny", steps=2, batch=8, val_every=2, val_batches=1, progress=False,
                lr=1e-9)
    tuned = load_model(again / "model.pt")
    record = tuned.meta["stages"]["prior"]
    assert record["steps"] == 2 and record["started_from"]["steps"] == 3
    # it started from the trained weights (a learning rate of 1e-9 barely moves them), not from fresh ones
    for a, b in zip(first.denoiser.parameters(), tuned.denoiser.parameters()):
        assert torch.allclose(a, b, atol=1e-5)


def test_an_adapter_stage_starts_over_unless_told_to_keep_its_module(tmp_path, lib):
    import shutil
    from model_runtime.errors import RemogenError
    out = tmp_path / "run"
    for stage in ("vae", "prior"):
        train_stage(stage, out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    base = tmp_path / "base"
    shutil.copytree(out, base)
    with pytest.raises(RemogenError, match="no trained hhi module to continue from"):
        train_stage("hhi", base, lib, config="tiny", steps=1, progress=False, keep_module=True)
    train_stage("hhi", out, lib, config="tiny", steps=3, batch=8, val_every=3, val_batches=1, progress=False)
    first = load_model(out / "model.pt", warn_untrained=False)
    runs = {}
    for keep in (True, False):
        again = tmp_path / f"again_{keep}"
        again.mkdir()
        shutil.copy(out / "model.pt", again / "model.pt")     # a trained file, no state of the stage
        train_stage("hhi", again, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False,
                    lr=1e-9, keep_module=keep)
        runs[keep] = load_model(again / "model.pt", warn_untrained=False)
    kept = list(zip(first.mims["hhi"].parameters(), runs[True].mims["hhi"].parameters()))
    assert all(torch.allclose(a, b, atol=1e-5) for a, b in kept)        # continued from the trained module
    assert runs[True].meta["stages"]["hhi"]["started_from"]["steps"] == 3
    fresh = zip(first.mims["hhi"].parameters(), runs[False].mims["hhi"].parameters())
    assert not all(torch.allclose(a, b, atol=1e-5) for a, b in fresh)    # started over


def test_an_hhi_stage_can_start_over_with_the_partner_line_cues(tmp_path, lib):
    from model_runtime.errors import RemogenError
    out = tmp_path / "run"
    for stage in ("vae", "prior"):
        train_stage(stage, out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    before = load_model(out / "model.pt", warn_untrained=False)
    with pytest.raises(RemogenError, match="cannot be kept"):
        train_stage("hhi", out, lib, config="tiny", steps=1, progress=False, keep_module=True, partner_line_cues=True)
    train_stage("hhi", out, lib, config="tiny", steps=2, batch=8, val_every=2, val_batches=1, progress=False,
                partner_line_cues=True)
    after = load_model(out / "model.pt", warn_untrained=False)
    assert after.cfg.partner_line_cues and not before.cfg.partner_line_cues
    for a, b in zip(before.denoiser.parameters(), after.denoiser.parameters()):
        assert torch.equal(a, b)                                   # the prior is the one it started from


def test_later_stage_without_earlier_says_so(tmp_path, lib):
    from model_runtime.errors import RemogenError
    with pytest.raises(RemogenError, match="train the stages before"):
        train_stage("prior", tmp_path / "empty", lib, config="tiny", steps=1, progress=False)


def _rank_report(res: subprocess.CompletedProcess, logs: Path) -> str:
    """On a failed DDP run: the launcher's tail and each rank's own stderr (torchrun --redirects wrote them per
    rank), so an intermittent abort shows which rank died and why instead of a truncated interleaving."""
    parts = [f"torchrun exit {res.returncode}:\n{res.stderr[-3000:]}"]
    for log in sorted(logs.rglob("stderr.log")):
        parts.append(f"--- {log.relative_to(logs)}:\n{log.read_text(errors='replace')[-4000:]}")
    return "\n".join(parts)


def _run_ddp(tmp_path, lib, *args: str):
    lib.save(tmp_path / "clips.npz")
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    logs = tmp_path / "rank_logs"
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
           "--log-dir", str(logs), "--redirects", "3",
           "-m", "model_runtime.train", "vae", "--library", str(tmp_path / "clips.npz"), "--out",
           str(tmp_path / "ddp"), "--config", "tiny", "--batch", "4", "--no-progress", *args]
    res = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, _rank_report(res, logs)
    return load_model(tmp_path / "ddp" / "model.pt").meta["stages"]["vae"]


def test_two_process_ddp_with_gloo(tmp_path, lib):
    stage = _run_ddp(tmp_path, lib, "--steps", "3")
    assert stage["world_size"] == 2 and stage["steps"] == 3


def test_ddp_time_limit_stops_every_rank_together(tmp_path, lib):
    """--minutes under DDP: rank 0's clock decides for all, so no rank is left waiting in an all-reduce."""
    stage = _run_ddp(tmp_path, lib, "--steps", "1000000", "--minutes", "0.05")
    assert 0 < stage["steps"] < 1000000
    state = torch.load(tmp_path / "ddp" / "vae.state.pt", weights_only=True)
    assert state["step"] == stage["steps"]


def test_all_six_stages_run_in_order_and_the_decoder_stage_trains_the_decoder_alone(tmp_path, lib):
    out = tmp_path / "all"
    for stage in ("vae", "prior", "hhi", "hsi", "fwsr"):
        train_stage(stage, out, lib, config="tiny", steps=2, batch=4, val_every=2, val_batches=1, progress=False)
    before = load_model(out / "model.pt")
    assert float(before.fwsr.sensitivity.mean()) == pytest.approx(1.0, rel=1e-4)   # computed, normalised
    train_stage("decoder", out, lib, config="tiny", steps=3, batch=4, val_every=3, val_batches=1, progress=False)
    model = load_model(out / "model.pt")
    assert list(model.meta["stages"]) == ["vae", "prior", "hhi", "hsi", "fwsr", "decoder"]
    old, new = before.state_dict(), model.state_dict()
    decoder = {f"vae.{n}" for n, _ in model.vae.decoder_parts().named_parameters()} | \
        {f"vae.{n}" for n, _ in model.vae.named_parameters() if n.startswith(("z_proj", "dec_", "decoder.", "out."))}
    changed = {k for k in old if not torch.equal(old[k], new[k])}
    assert changed and changed <= decoder | {"fwsr.sensitivity"}, changed - decoder
    assert any(k.startswith("vae.decoder.") for k in changed)
    assert "fwsr.sensitivity" in changed          # measured again for the new decoder
    assert float(model.fwsr.sensitivity.mean()) == pytest.approx(1.0, rel=1e-4)
    log = read_log(out / "decoder.log.jsonl")
    assert all(r["first_m"] >= 0 and r["shown_m"] >= 0 for r in log)


def test_shown_joint_error_is_the_kinematic_distance_per_frame():
    from model_runtime.training.stages import shown_joint_error
    model = load_model(config="tiny")
    real = torch.randn(2, model.cfg.future, model.cfg.feature_dim) * 0.1
    assert torch.allclose(shown_joint_error(model.stats, real, real), torch.zeros(model.cfg.future))
    moved = model.stats.denormalize(real).clone()
    from model_runtime.features import ROOT_T
    moved[:, 3, ROOT_T] += torch.tensor([0.3, 0.0, 0.4])        # the whole body 0.5 m away in frame 3
    err = shown_joint_error(model.stats, model.stats.normalize(moved), real)
    assert err[3] == pytest.approx(0.5, abs=1e-4)
    assert torch.allclose(err[torch.arange(model.cfg.future) != 3], torch.zeros(model.cfg.future - 1), atol=1e-5)


def test_ema_warms_up_so_short_stages_do_not_ship_their_initialisation():
    from model_runtime.train import EMA
    p = torch.nn.Parameter(torch.zeros(3))
    ema = EMA([p], decay=0.999)
    assert ema.current_decay() == pytest.approx(0.1)      # (1 + 0) / (10 + 0)
    with torch.no_grad():
        p.fill_(1.0)
    for _ in range(200):
        ema.update()
    # 200 updates toward a constant 1: the average is essentially there (without the warm-up, 0.18)
    assert float(ema.shadow[0].min()) > 0.9
    assert ema.current_decay() == pytest.approx(201 / 210)
    for _ in range(20000):
        ema.update()
    assert ema.current_decay() == 0.999


def _assert_drawn_share(s: SegmentSampler, rows: int, close: list[int], share: float) -> None:
    """`share` of the windows of item 0 drawn among `close`, the rest uniform (landing there len(close)/all)."""
    import numpy as np
    starts = [s._window_start(0, rows) for _ in range(400)]
    drawn = np.mean([st in close for st in starts])
    uniform = len(close) / (rows - s.span + 1)
    assert abs(drawn - (share + (1 - share) * uniform)) < 0.1


def test_hhi_windows_favour_the_frames_where_the_partner_is_near(lib):
    import numpy as np
    from model_runtime.data.pairs import HHIPair
    from model_runtime.training import samples
    model = load_model(config="tiny")
    clip = 0
    n = lib.frames(clip)
    a = int(lib.offsets[clip])
    partner = np.zeros((n, 22, 3), np.float32)
    partner[:, :, :2] = lib.pelvis[a:a + n, None, :2] + 100.0     # far away ...
    near = n - 5
    partner[near:, :, :2] = lib.pelvis[a + near:a + n, None, :2] + 1.0  # ... until the last 5 frames
    s = SegmentSampler(lib, [clip], model.cfg, model.stats, seed=0, pairs=[HHIPair(clip, partner, "approach_face")])
    span, h = model.cfg.history + model.cfg.future, model.cfg.history
    close = s._close_starts[0].tolist()
    assert close and all(st + span > near for st in close) and all(st + h <= n for st in close)
    _assert_drawn_share(s, lib.features(clip).shape[0], close, samples.INTERACTION_SHARE)


def test_the_hhi_loss_can_be_taken_on_the_prediction_guided_as_the_runtime_guides_it(lib):
    import numpy as np
    from model_runtime.data.pairs import HHIPair
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.stages import StageLoss
    model = load_model(config="tiny")
    torch.manual_seed(0)
    with torch.no_grad():       # a module and a null text token that do something, so the passes differ
        for p in list(model.mims["hhi"].parameters()) + [model.denoiser.null_text]:
            p.add_(0.05 * torch.randn_like(p))
    n = lib.frames(0)
    a = int(lib.offsets[0])
    partner = np.zeros((n, 22, 3), np.float32)
    partner[:, :, :2] = lib.pelvis[a:a + n, None, :2] + 1.0
    b = SegmentSampler(lib, [0], model.cfg, model.stats, seed=0, pairs=[HHIPair(0, partner, "approach_face")]).sample(4)
    scale = WINDOW_RECIPES["setoffs_guided"].hhi_guidance
    loss = StageLoss(model, "hhi", hhi_guidance=scale)
    ctx, alpha = loss.contexts(b)
    inject = model.injector(ctx, alpha)
    with torch.no_grad():
        z, _ = model.vae.encode(b.hist, b.fut)
        t = torch.full((4,), model.cfg.diffusion_steps - 1)
        emb = model.text_encoder.encode(b.text)
        cond = model.denoiser(z, t, b.hist, model.denoiser.text_tokens(emb, torch.zeros(4, dtype=torch.bool)), inject)
        uncond = model.denoiser(z, t, b.hist, model.denoiser.text_tokens(emb, torch.ones(4, dtype=torch.bool)), inject)
        guided = loss._guided(b, z, t, inject)
    assert scale == 6.0 and not torch.allclose(cond, uncond)
    assert torch.allclose(guided, uncond + scale * (cond - uncond), atol=1e-5)
    # the loss itself trains through both passes; without a scale (every shipped recipe) it is the usual one
    value, parts = loss(b, torch.Generator().manual_seed(0))
    value.backward()
    assert torch.isfinite(value) and any(p.grad is not None for p in model.mims["hhi"].parameters())
    assert StageLoss(model, "hhi").hhi_guidance == 0.0


def _pair_batch(lib, model, offset: float, n_rows: int = 4):
    """HHI windows of clip 0 with a partner that copies the ego's own joints, moved `offset` m sideways."""
    import numpy as np
    from model_runtime.data.pairs import HHIPair
    from model_runtime.training.samples import world_joints
    partner = world_joints(lib, 0).numpy().astype(np.float32).copy()
    partner[:, :, 0] += offset
    s = SegmentSampler(lib, [0], model.cfg, model.stats, seed=0, pairs=[HHIPair(0, partner, "approach_face")])
    return s.sample(n_rows)


def test_the_partner_future_is_where_the_partner_is_while_the_segment_plays(lib):
    from model_runtime.features import features_to_pose
    from model_runtime.skeleton import forward_kinematics
    from model_runtime.training.recipe import ROLLOUT_LOOK_AHEAD
    model = load_model(config="tiny")
    b = _pair_batch(lib, model, 0.0)
    f = model.cfg.future
    assert b.partner_future.shape == (4, f + ROLLOUT_LOOK_AHEAD, 22, 3)
    assert b.future_present.shape == (4, f + ROLLOUT_LOOK_AHEAD) and bool(b.future_present[:, :f].all())
    # the partner copies the ego, so over the segment's frames it is exactly the real future's body
    real = forward_kinematics(*features_to_pose(model.stats.denormalize(b.fut)))[0]
    assert torch.allclose(real, b.partner_future[:, :f], atol=2e-3)
    moved = _pair_batch(lib, model, 1.5)
    assert torch.allclose((moved.partner_future[:, :f] - b.partner_future[:, :f]).norm(dim=-1),
                          torch.full((4, f, 22), 1.5), atol=2e-3)


def test_the_clearance_charge_counts_each_frame_by_its_nearest_joints():
    from model_runtime.training.recipe import ROLLOUT_MARGIN
    from model_runtime.training.stages import clearance_charge
    ego = torch.zeros(1, 2, 22, 3)
    ego[0, 1, :, 0] = 1.0                                   # frame 0 at x = 0, frame 1 (the last) at x = 1
    partner = torch.full((1, 4, 22, 3), 50.0)               # far away ...
    present = torch.ones(1, 4, dtype=torch.bool)
    assert float(clearance_charge(ego, partner, present)) == 0.0
    partner[0, 0, 3] = torch.tensor([0.1, 0.0, 0.0])        # ... but one joint 0.1 m from the ego in frame 0
    partner[0, 3, 7] = torch.tensor([1.0, 0.2, 0.0])        # and one 0.2 m from the last pose, held past the segment
    want = ((ROLLOUT_MARGIN - 0.1) ** 2 + (ROLLOUT_MARGIN - 0.2) ** 2) / 4
    assert abs(float(clearance_charge(ego, partner, present)) - want) < 1e-6
    present[0, 3] = False                                   # a frame where the partner is not there is not charged
    assert abs(float(clearance_charge(ego, partner, present)) - (ROLLOUT_MARGIN - 0.1) ** 2 / 3) < 1e-6


def test_the_clearance_charge_can_leave_the_forearms_free():
    """Without the arms (WindowRecipe.rollout_arms off) a wrist or elbow reaching toward a partner costs nothing; the
    rest of the body still does; the recipe that says so gives the loss that joint list."""
    from model_runtime.joints import JOINT_INDEX
    from model_runtime.training.recipe import ROLLOUT_MARGIN, ROLLOUT_REACHING_JOINTS, WINDOW_RECIPES
    from model_runtime.training.stages import StageLoss, clearance_charge
    model = load_model(config="tiny")
    trunk = StageLoss(model, "hhi", hhi_rollout=1.0, rollout_arms=WINDOW_RECIPES["setoffs_rollout_trunk"].rollout_arms)
    assert sorted(trunk.clearance_joints) == sorted(i for n, i in JOINT_INDEX.items() if n not in ROLLOUT_REACHING_JOINTS)
    assert StageLoss(model, "hhi", hhi_rollout=1.0).clearance_joints is None
    ego = torch.zeros(1, 1, 22, 3)
    partner = torch.full((1, 1, 22, 3), 50.0)
    present = torch.ones(1, 1, dtype=torch.bool)
    ego[0, 0, JOINT_INDEX["right_wrist"]] = torch.tensor([49.8, 50.0, 50.0])    # a hand 0.2 m from the partner
    assert abs(float(clearance_charge(ego, partner, present)) - (ROLLOUT_MARGIN - 0.2) ** 2) < 1e-5
    assert float(clearance_charge(ego, partner, present, trunk.clearance_joints)) == 0.0
    ego[0, 0, JOINT_INDEX["head"]] = torch.tensor([49.9, 50.0, 50.0])           # the head 0.1 m from it
    assert abs(float(clearance_charge(ego, partner, present, trunk.clearance_joints))
               - (ROLLOUT_MARGIN - 0.1) ** 2) < 1e-5


def test_the_rollout_loss_trains_the_module_through_the_sampled_segment(lib):
    import copy
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.stages import StageLoss, freeze_for, rollout_joints
    model = load_model(config="tiny")
    params = freeze_for(model, "hhi")
    model.mims["hhi"].eval()       # no dropout: the same noise gives the same segment twice
    weight = WINDOW_RECIPES["setoffs_rollout"].hhi_rollout
    start = copy.deepcopy(model)
    loss = StageLoss(model, "hhi", hhi_guidance=6.0, hhi_rollout=weight, anchor=start, anchor_weight=1.0)
    b = _pair_batch(lib, model, 0.0)
    with torch.no_grad():
        ego = rollout_joints(model, b, slice(0, 4), torch.Generator().manual_seed(0))
    b.partner_future[:, :ego.shape[1]] = ego + torch.tensor([0.1, 0.0, 0.0])   # the partner beside the sampled body
    gen = torch.Generator().manual_seed(0)
    rolled = loss._rollout_loss(b, gen)
    assert set(rolled) == {"clear", "seam", "skate", "glide", "kept"}
    assert float(rolled["clear"].detach()) > 0.0 and float(rolled["seam"].detach()) > 0.0
    # the starting module sampled from the same noise: nothing has moved yet, and the noise drawn after is the same
    assert float(rolled["kept"].detach()) < 1e-10
    assert torch.equal(gen.get_state(), _drawn_once(model, b))
    (rolled["clear"] + rolled["seam"]).backward()
    assert any(p.grad is not None and bool(p.grad.abs().sum() > 0) for p in params)
    assert all(p.grad is None for p in model.denoiser.parameters())
    value, parts = loss(b, torch.Generator().manual_seed(0))
    assert {"clear", "seam", "skate", "glide", "kept"} <= set(parts) and torch.isfinite(value)
    assert "clear" not in StageLoss(model, "hhi")(b, torch.Generator().manual_seed(0))[1]
    with torch.no_grad():          # a moved module is held to the segments the starting one samples
        next(model.mims["hhi"].parameters()).add_(0.5)
    assert float(loss._rollout_loss(b, torch.Generator().manual_seed(0))["kept"]) > 0.0
    with pytest.raises(ValueError, match="hhi_rollout"):
        StageLoss(model, "hhi", anchor=start, anchor_weight=1.0)


def _drawn_once(model, b) -> torch.Tensor:
    """The generator's state after one segment sampled for the first 4 windows (from seed 0)."""
    from model_runtime.training.stages import rollout_joints
    gen = torch.Generator().manual_seed(0)
    with torch.no_grad():
        rollout_joints(model, b, slice(0, 4), gen)
    return gen.get_state()


def test_detour_scenes_are_drawn_more_often(lib):
    import numpy as np
    from model_runtime.data.pairs import HSIScene
    from model_runtime.training import samples
    model = load_model(config="tiny")
    empty = (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    scenes = [HSIScene(i, *empty, np.zeros(3, np.float32), kind) for i, kind in ((0, "detour"), (1, "beside_path"))]
    s = SegmentSampler(lib, [0, 1], model.cfg, model.stats, seed=0, scenes=scenes)
    w = s.weights.numpy()
    frames = np.array([lib.frames(0), lib.frames(1)], np.float64) - s.span
    expect = frames * np.array([samples.SCENE_KIND_WEIGHT["detour"], 1.0])
    assert np.allclose(w, expect / expect.sum())


def test_hsi_windows_favour_the_frames_that_reach_the_goal(lib):
    import numpy as np
    from model_runtime.data.pairs import HSIScene
    from model_runtime.training import samples
    model = load_model(config="tiny")
    clip = 0
    n = lib.frames(clip)
    a = int(lib.offsets[clip])
    goal = np.zeros(3, np.float32)
    goal[:2] = lib.pelvis[a + n - 1, :2]            # where the clip ends
    empty = (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    s = SegmentSampler(lib, [clip], model.cfg, model.stats, seed=0, scenes=[HSIScene(clip, *empty, goal, "static")])
    span, h = model.cfg.history + model.cfg.future, model.cfg.history
    dist = np.linalg.norm(np.asarray(lib.pelvis[a:a + n, :2]) - goal[:2], axis=1)
    expect = [st for st in range(n - span) if (dist[st + h:st + span] < samples.GOAL_RANGE).any()]
    close = s._close_starts[0].tolist()
    assert close == expect and 0 < len(close) < n - span    # some windows reach the goal, not all
    _assert_drawn_share(s, lib.features(clip).shape[0], close, samples.GOAL_SHARE)


def test_init_vae_copies_the_vae_and_trains_the_stages_after_it(tmp_path, lib):
    from model_runtime.train import main
    path = lib.save(tmp_path / "clips.npz")
    train_stage("vae", tmp_path / "a", lib, config="tiny", steps=2, batch=8, val_every=2, val_batches=1,
                progress=False)
    source = load_model(tmp_path / "a" / "model.pt")
    common = ["--library", str(path), "--config", "tiny", "--steps", "2", "--batch", "8", "--no-progress"]
    assert main(["vae", "--out", str(tmp_path / "b"), "--init-vae", str(tmp_path / "a" / "model.pt"), *common]) == 2
    assert not (tmp_path / "b").exists()                 # refused before anything was written
    assert main(["prior", "--out", str(tmp_path / "b"), "--init-vae", str(tmp_path / "a" / "model.pt"), *common]) == 0
    model = load_model(tmp_path / "b" / "model.pt")
    for part in ("stats", "vae"):
        mine, theirs = getattr(model, part).state_dict(), getattr(source, part).state_dict()
        assert all(torch.equal(mine[k], theirs[k]) for k in theirs)
    assert set(model.meta["stages"]) == {"vae", "prior"}
    assert model.meta["stages"]["vae"]["copied_from"] == str(tmp_path / "a" / "model.pt")
    assert model.meta["non_commercial"] is True


def test_init_vae_from_another_preset_is_refused(tmp_path, lib):
    from model_runtime.train import main
    from model_runtime.checkpoint import save_model
    path = lib.save(tmp_path / "clips.npz")
    save_model(load_model(config="default"), tmp_path / "big.pt")
    code = main(["prior", "--library", str(path), "--out", str(tmp_path / "b"), "--config", "tiny",
                 "--init-vae", str(tmp_path / "big.pt"), "--steps", "1", "--no-progress"])
    assert code == 2 and not (tmp_path / "b" / "model.pt").exists()


def test_still_windows_sometimes_train_as_standing():
    from model_runtime.features import features_from_pose
    from model_runtime.training.recipe import STILL_CAPTION, STILL_SHARE
    from model_runtime.training.samples import is_still
    from model_runtime.skeleton import quat_to_matrix
    rest = quat_to_matrix(torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(12, 22, 1))
    pel = torch.zeros(12, 3)
    still = features_from_pose(rest, pel)
    walking = features_from_pose(rest, pel + torch.tensor([0.0, 0.12, 0.0]) * torch.arange(12.0).view(-1, 1))
    assert is_still(still) and not is_still(walking)
    model = load_model(config="tiny")
    lib = synthetic_library(4, 40)
    s = SegmentSampler(lib, [0], model.cfg, model.stats, seed=0)
    counts = {"still": 0, "other": 0}
    for _ in range(400):
        caption = s._caption(still, 0)
        counts["still" if caption == STILL_CAPTION else "other"] += 1
        assert s._caption(walking, 0) == lib.captions[0]
    assert abs(counts["still"] / 400 - STILL_SHARE) < 0.1
    off = SegmentSampler(lib, [0], model.cfg, model.stats, seed=0, still_share=0.0)
    assert off._caption(still, 0) == lib.captions[0]


def test_background_workers_draw_batches_and_the_stage_records_its_device(tmp_path, lib):
    from model_runtime.training.prefetch import batch_stream
    model = load_model(config="tiny")
    s = SegmentSampler(lib, list(range(8)), model.cfg, model.stats, seed=0)
    stream = batch_stream(s, 4, fwsr=True, workers=2, seed=5, device=torch.device("cpu"))
    a, b = next(stream), next(stream)
    assert a.hist.shape == (4, 2, 276) and a.frame.shape == (4,) and len(a.text) == 4
    assert not torch.equal(a.hist, b.hist)            # two workers, two different streams
    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=3, batch=8, val_every=3, val_batches=1, progress=False,
                workers=2)
    stage = load_model(out / "model.pt").meta["stages"]["vae"]
    assert stage["steps"] == 3 and stage["device"] == "cpu" and stage["workers"] == 2


def test_batch_moves_every_tensor_and_keeps_the_captions(lib):
    model = load_model(config="tiny")
    b = SegmentSampler(lib, list(range(8)), model.cfg, model.stats, seed=0).sample(3)
    moved = b.to(torch.device("cpu"), non_blocking=True).to("cpu")
    assert moved.text == b.text and torch.equal(moved.fut, b.fut) and moved.partner is None


def test_training_device_names_what_is_wrong(monkeypatch):
    from model_runtime.errors import RemogenError
    from model_runtime.train import training_device
    assert training_device("cpu").type == "cpu"
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert training_device("auto").type == "cpu"      # no GPU: auto trains on the CPU
    with pytest.raises(RemogenError, match="sees no CUDA GPU"):
        training_device("cuda")
    with pytest.raises(RemogenError, match="not a device"):
        training_device("gpu0")
    with pytest.raises(RemogenError, match="cpu or cuda"):
        training_device("meta")


def test_fwsr_rows_read_the_generators_own_frames_in_the_real_frames_place(lib, monkeypatch):
    import model_runtime.training.stages as stages
    model = load_model(config="tiny")
    b = SegmentSampler(lib, list(range(8)), model.cfg, model.stats, seed=0).sample(6, fwsr=True)

    class Decoded:     # a decoder that returns the real future: the windows must then be the real recent frames
        class vae:
            @staticmethod
            def decode(hist, z):
                return b.fut
    monkeypatch.setattr(stages, "FWSR_OWN_SHARE", 1.0)
    own = stages.own_recent_frames(Decoded, b, torch.zeros(6, 2, 4), torch.Generator().manual_seed(0))
    assert torch.allclose(own, b.recent, atol=1e-5)
    monkeypatch.setattr(stages, "FWSR_OWN_SHARE", 0.0)
    assert stages.own_recent_frames(model, b, torch.zeros(6, 2, 4), torch.Generator()) is b.recent


def test_the_end_summary_points_to_the_next_required_stage_only(tmp_path):
    from model_runtime.training.report import StageRun, summary
    from model_runtime.training.stages import REQUIRED_STAGES

    def run(stage: str) -> StageRun:
        return StageRun(stage, tmp_path / "model.pt", tmp_path / f"{stage}.state.pt", tmp_path / "none.jsonl", 5, 5, 1.0)

    argv = ["hsi", "--out", str(tmp_path)]
    assert "next stage: python -m model_runtime.train fwsr --out" in summary([run("hsi")], REQUIRED_STAGES, argv, 1)
    after_fwsr = summary([run("fwsr")], REQUIRED_STAGES, ["fwsr", "--out", str(tmp_path)], 1)
    assert "next stage" not in after_fwsr and "decoder" not in after_fwsr     # the optional stage is not the next one
    after_decoder = summary([run("decoder")], REQUIRED_STAGES, ["decoder", "--out", str(tmp_path)], 1)
    assert "next stage" not in after_decoder and "saved:" in after_decoder


def test_snapshots_hold_the_ema_model_at_their_step(tmp_path, lib):
    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    train_stage("prior", out, lib, config="tiny", steps=4, batch=8, val_every=2, val_batches=1, progress=False,
                snapshot_every=2)
    snaps = sorted(p.name for p in (out / "snapshots").iterdir())
    assert snaps == ["prior_000002.pt"]               # the last step is the model file itself, not a snapshot
    snap, final = load_model(out / "snapshots" / snaps[0]), load_model(out / "model.pt")
    assert snap.meta["stages"]["prior"]["steps"] == 2 and final.meta["stages"]["prior"]["steps"] == 4
    assert snap.meta["stages"]["prior"]["val_loss"] is not None   # read from the log at that step
    # the snapshot holds EMA weights of step 2, neither the initial nor the final ones
    sd, fd = snap.denoiser.state_dict(), final.denoiser.state_dict()
    assert any(not torch.equal(sd[k], fd[k]) for k in sd)
    vs, vf = snap.vae.state_dict(), final.vae.state_dict()
    assert all(torch.equal(vs[k], vf[k]) for k in vs)   # frozen stages are untouched


def test_a_decoder_snapshot_carries_its_own_decoder_sensitivity(tmp_path, lib):
    """FWSR's damping reads the decoder's sensitivity: a decoder-stage snapshot measures its own decoder's, as the
    stage's final model file does, instead of keeping the starting file's."""
    import copy
    from model_runtime.training.setup import decoder_sensitivity
    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    start = load_model(out / "model.pt", warn_untrained=False).fwsr.sensitivity.clone()
    train_stage("decoder", out, lib, config="tiny", steps=4, batch=8, val_every=2, val_batches=1, progress=False,
                snapshot_every=2, lr=1e-2)
    snap = load_model(out / "snapshots" / "decoder_000002.pt", warn_untrained=False)
    again = copy.deepcopy(snap)
    decoder_sensitivity(again, lib, 0)
    assert torch.allclose(snap.fwsr.sensitivity, again.fwsr.sensitivity)
    assert not torch.allclose(snap.fwsr.sensitivity, start)


def test_the_window_recipe_reaches_the_samplers_and_is_recorded(tmp_path, lib):
    import numpy as np
    from model_runtime.data.library import derived_kind
    from model_runtime.errors import RemogenError
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    from synthetic import library_of, rigid_clip, walking_clip
    stand = np.tile([[4.0, 1.0]], (40, 1)) + np.random.default_rng(0).normal(0, 0.003, (40, 2))
    sets_off = library_of([("run", "a person runs forward", "bandai", walking_clip(40, 2.5, 0.0, yaw0=0.7)),
                           ("stand", "a person stands", "cmu", rigid_clip(stand, 1.0)),
                           ("wave", "a person waves", "bandai", rigid_clip(np.tile([[-3.0, 0.0]], (40, 1)), -1.0))])
    model = load_model(config="tiny")
    balanced, captured = WINDOW_RECIPES["balanced"], WINDOW_RECIPES["captured"]
    tr, va = build_samplers("prior", model, sets_off, seed=0, rank=0, windows=balanced)
    assert (tr.still_share, tr.slow_walk_share) == (balanced.still_share, balanced.slow_walk_share)
    if va is not None:     # the held-out windows stay as captured, so held-out losses compare across recipes
        assert (va.still_share, va.slow_walk_share) == (captured.still_share, captured.slow_walk_share)
    assert "startup" in {derived_kind(n) for n in tr.lib.names}
    plain = build_samplers("prior", model, sets_off, seed=0, rank=0, windows=captured)[0]
    assert "startup" not in {derived_kind(n) for n in plain.lib.names}
    assert (plain.path_tail_share, tr.path_tail_share) == (0.0, 0.0)
    tails = WINDOW_RECIPES["kicks_slowed_light_tails"]
    tailed, tailed_va = build_samplers("prior", model, sets_off, seed=0, rank=0, windows=tails)
    assert tailed.path_tail_share == tails.path_tail_share > 0.0
    assert tailed_va is None or tailed_va.path_tail_share == 0.0
    assert (plain.still_share, plain.slow_walk_share) == (captured.still_share, captured.slow_walk_share)

    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    train_stage("prior", out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False,
                windows="balanced")
    record = load_model(out / "model.pt", warn_untrained=False).meta["stages"]["prior"]["windows"]
    assert record == {"name": "balanced", "still_share": 0.75, "slow_walk_share": 0.5, "caption_balance": 0.5,
                      "startup_stages": ["prior"], "reversal_stages": [], "turn_arrival_stages": [],
                      "step_aside_rule": "ahead", "face_arrivals": False, "walk_aside": False,
                      "head_shares": [], "head_share_stages": [], "decoder_shown_weight": 1.0,
                      "hhi_copy_stages": [], "wider_phrasings": False, "path_tail_share": 0.0, "slowed_walk_stages": [],
                      "slowed_walk_weight": 0.5,
                      "setoff_share": 0.0, "hhi_guidance": 0.0, "anchor": 0.0,
                      "hhi_rollout": 0.0, "rollout_seam": 1.0, "rollout_skate": 10.0, "rollout_glide": 100.0,
                      "rollout_arms": True, "text_jitter_cos": 1.0}
    with pytest.raises(RemogenError, match="unknown window recipe 'odd'; use one of captured, balanced, reversed"):
        train_stage("prior", out, lib, config="tiny", steps=1, progress=False, windows="odd")


def test_the_kicks_hhi_recipe_shows_the_decoder_the_hhi_copies(lib):
    """`hhi_copy_stages`: the decoder stage also draws the HHI stage's copies (stepping aside, avoiding, ...), so
    it learns to render the motion the HHI module asks for; the plain kicks recipe does not."""
    from model_runtime.data.library import derived_kind
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    model = load_model(config="tiny")
    with_copies = build_samplers("decoder", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["kicks_hhi"])[0]
    without = build_samplers("decoder", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["kicks"])[0]
    added = {derived_kind(n) for n in with_copies.lib.names} - {derived_kind(n) for n in without.lib.names}
    assert added and len(with_copies.lib) > len(without.lib)


def test_the_kicks_recipe_trains_the_decoder_on_reconstruction_alone_with_kicks_drawn_more_often(lib):
    from model_runtime.training.recipe import KICK_HEAD_SHARES, WINDOW_RECIPES
    from model_runtime.training.stages import StageLoss
    kicks = WINDOW_RECIPES["kicks"]
    assert "decoder" in kicks.head_share_stages and kicks.head_shares == KICK_HEAD_SHARES
    assert kicks.decoder_shown_weight == 0.0
    model = load_model(config="tiny")
    b = SegmentSampler(lib, lib.split("train"), model.cfg, model.stats, seed=0).sample(4)
    plain = StageLoss(model, "decoder", shown_weight=0.0)(b, torch.Generator().manual_seed(1))
    shown = StageLoss(model, "decoder", shown_weight=1.0)(b, torch.Generator().manual_seed(1))
    assert float(plain[0].detach()) == pytest.approx(plain[1]["rec"], rel=1e-6)     # the VAE's own reconstruction loss
    assert float(shown[0].detach()) > shown[1]["rec"] > 0          # plus the error of the motion as shown


def test_an_anchored_fine_tune_holds_the_windows_it_knew_to_the_starting_output(lib):
    """WindowRecipe.anchor: the prior's and the decoder's output on the anchored windows (real clips and their
    mirrors) is held to the starting file's; the derived copies being taught learn freely."""
    import copy
    from model_runtime.data.library import derived_kind
    from model_runtime.training.recipe import ANCHORED_KINDS, WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    from model_runtime.training.stages import StageLoss
    model = load_model(config="tiny")
    tr = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["slow_back_anchored"])[0]
    kinds = {derived_kind(tr.lib.names[i]) for i, _ in tr.items}
    assert {"", "mirror"} <= kinds and kinds - set(ANCHORED_KINDS)     # some windows are taught, not anchored
    for anchored in (True, False):
        ids = [i for i, _ in tr.items if (derived_kind(tr.lib.names[i]) in ANCHORED_KINDS) == anchored]
        b = SegmentSampler(tr.lib, ids, model.cfg, model.stats, seed=0).sample(6)
        assert b.anchored.tolist() == [anchored] * 6
    b = SegmentSampler(lib, lib.split("train"), model.cfg, model.stats, seed=0).sample(6)
    start = copy.deepcopy(model)
    for stage in ("prior", "decoder"):
        model.eval()              # no dropout: an unchanged module gives exactly the starting output
        same = StageLoss(model, stage, anchor=start, anchor_weight=2.0)(b, torch.Generator().manual_seed(1))
        assert same[1]["anchor"] == 0.0
        moved = copy.deepcopy(model)
        with torch.no_grad():
            for p in (moved.denoiser if stage == "prior" else moved.vae).parameters():
                p.add_(0.05 * torch.randn_like(p))
        plain = StageLoss(moved, stage)(b, torch.Generator().manual_seed(1))
        held = StageLoss(moved, stage, anchor=start, anchor_weight=2.0)(b, torch.Generator().manual_seed(1))
        total, plain_total = float(held[0].detach()), float(plain[0].detach())
        assert held[1]["anchor"] > 0 and total == pytest.approx(plain_total + 2.0 * held[1]["anchor"], rel=1e-5)
        b.anchored = torch.zeros(6, dtype=torch.bool)    # only taught windows: nothing to hold
        free = StageLoss(moved, stage, anchor=start, anchor_weight=2.0)(b, torch.Generator().manual_seed(1))
        assert free[1]["anchor"] == 0.0 and float(free[0].detach()) == pytest.approx(plain_total, rel=1e-6)
        b.anchored = None
    with pytest.raises(ValueError, match="needs the starting model"):
        StageLoss(model, "hsi", anchor=start, anchor_weight=2.0)
    with pytest.raises(ValueError, match="hhi_rollout"):      # the HHI stage holds only its sampled segments
        StageLoss(model, "hhi", anchor=start, anchor_weight=2.0)


def test_an_anchored_recipe_needs_a_trained_stage_to_hold_to(tmp_path, lib):
    import shutil
    from model_runtime.errors import RemogenError
    out = tmp_path / "run"
    train_stage("vae", out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    with pytest.raises(RemogenError, match="has no trained prior: train it first"):
        train_stage("prior", out, lib, config="tiny", steps=1, batch=8, progress=False, windows="slow_back_anchored")
    with pytest.raises(RemogenError, match="hhi stage holds the segments its rollout loss samples"):
        train_stage("hhi", out, lib, config="tiny", steps=1, batch=8, progress=False, anchor=1.0)
    train_stage("prior", out, lib, config="tiny", steps=1, batch=8, val_every=1, val_batches=1, progress=False)
    again = tmp_path / "again"
    again.mkdir()
    shutil.copy(out / "model.pt", again / "model.pt")
    train_stage("prior", again, lib, config="tiny", steps=2, batch=8, val_every=2, val_batches=1, progress=False,
                windows="slow_back_anchored")
    assert all("anchor" in row for row in read_log(again / "prior.log.jsonl"))
    assert all("anchor" not in row for row in read_log(out / "prior.log.jsonl"))
    meta = load_model(again / "model.pt", warn_untrained=False).meta["stages"]["prior"]
    assert meta["windows"]["anchor"] > 0 and meta["started_from"]["steps"] == 1
    # resumed past its end, the run holds to the prior it first started from, not to the model.pt it wrote
    first = load_model(out / "model.pt", warn_untrained=False).denoiser.state_dict()
    kept = torch.load(again / "prior.state.pt", weights_only=True)["anchor_start"]
    assert all(torch.equal(first[k], kept[k]) for k in first)
    train_stage("prior", again, lib, config="tiny", steps=3, batch=8, val_every=3, val_batches=1, progress=False,
                windows="slow_back_anchored", anchor=0.5)
    assert load_model(again / "model.pt", warn_untrained=False).meta["stages"]["prior"]["windows"]["anchor"] == 0.5
    kept = torch.load(again / "prior.state.pt", weights_only=True)["anchor_start"]
    assert all(torch.equal(first[k], kept[k]) for k in first)
    with pytest.raises(RemogenError, match="began without an anchor"):
        train_stage("prior", out, lib, config="tiny", steps=2, batch=8, progress=False, windows="slow_back_anchored")
    with pytest.raises(RemogenError, match="--anchor -1.0: the weight must be a number >= 0"):
        train_stage("prior", again, lib, config="tiny", steps=4, progress=False, anchor=-1.0)
