"""Held-out evaluation of a model: motion quality, the prior against a baseline, and interaction scenarios.

    python -m model_runtime.evaluate --data ../shared/data --json [--model PATH] [--library runs/clips.npz]
                                     [--plots runs/eval]

Runs only on the clip library's held-out split (ClipLibrary.split("val")), never on training clips, and
prints one JSON object:
    vae_reconstruction_mm       encode GT history + future, decode the mean latent, FK, mean joint error
    next_segment_mm             the prior from real history and the clip's caption (guidance 5) against
                                a constant-velocity extrapolation of each joint; both on the F future frames
    foot_skating_cm_per_frame   horizontal speed of foot joints whose sole is within 5 cm of the floor,
                                on prior rollouts, with the held-out clips themselves as reference
    peak_jerk_m_s3              max over joints and time of |third difference| * fps^3, same two sources
    interaction                 ReactionSession scenarios with alpha = 1 and alpha = 0 (prior only):
        facing_error_deg        partner walks from 4 m toward the ego and stops at 1 m (the ego starts
                                turned away); angle between the ego's hip facing and the partner, last frame
        min_clearance_m         smallest ego-joint to partner-joint distance in that scenario
        collision_percent       a box on the straight path to a goal: % of frames with an ego joint below
                                1.5 m inside an occupied voxel
        goal_distance_m         how far the ego ends from that goal (does it stop there)
        goal_closest_m          how close its pelvis comes to the goal at any frame (does it get there)
Plots (PNG, matplotlib Agg): training curves from runs/train/*.log.jsonl when present, and a stick-figure
strip (top and side views) of the generated reaction in the partner scenario.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch

from .data.pairs import facing_xy as hip_facing
from .data.pairs import min_clearance as min_body_clearance
from .errors import RemogenError
from .features import canonicalize, feature_joints, features_to_pose, to_world
from .skeleton import JOINT_INDEX, PARENTS, SOLE_BELOW_FOOT_JOINT, forward_kinematics, quat_to_matrix

FPS = 10
FEET = (JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"])
GROUND_CONTACT = 0.05     # m: a sole this close to the floor counts as grounded
COLLISION_HEIGHT = 1.5    # m: ego joints above this are ignored for scene collisions (arms raised over a box)
# The partner scenario's text says nothing about turning, so a turn toward the partner is the HHI module's
# work and alpha = 0 is a fair contrast. (Measured: "a person turns to face ..." made the hashed n-gram encoder
# match "walks and turns right" captions, and the prior alone turned right whichever side the partner was on.)
PARTNER_TEXT = "a person stands"
BOX_TEXT = "a person walks forward"
ALPHA_ON = {"hhi": 1.0, "hsi": 1.0}
ALPHA_OFF = {"hhi": 0.0, "hsi": 0.0}


# ----------------------------------------------------------------------------- metrics (NumPy, unit-tested)
def joint_error_mm(pred: np.ndarray, gt: np.ndarray) -> float:
    """Mean Euclidean joint position error in millimetres over all leading axes: (..., 22, 3) each."""
    return float(np.linalg.norm(np.asarray(pred, np.float64) - np.asarray(gt, np.float64), axis=-1).mean() * 1000)


def constant_velocity(history: np.ndarray, frames: int) -> np.ndarray:
    """Extrapolate each joint with its last history velocity: (..., H >= 2, J, 3) -> (..., frames, J, 3)."""
    h = np.asarray(history, np.float64)
    if h.shape[-3] < 2:
        raise ValueError("constant_velocity needs at least 2 history frames")
    last, vel = h[..., -1:, :, :], h[..., -1:, :, :] - h[..., -2:-1, :, :]
    k = np.arange(1, frames + 1, dtype=np.float64).reshape((frames, 1, 1))
    return last + k * vel


def grounded_foot_speeds(joints: np.ndarray, floor: float = 0.0, contact: float = GROUND_CONTACT) -> np.ndarray:
    """Horizontal foot-joint displacement (cm per frame) over every frame step where that foot's sole is
    within `contact` of the floor at both ends. joints (T, 22, 3), Z up; the sole is SOLE_BELOW_FOOT_JOINT
    below the foot joint. Pooled over feet; concatenate sequences' outputs to average several."""
    j = np.asarray(joints, np.float64)[:, list(FEET), :]
    sole = j[..., 2] - SOLE_BELOW_FOOT_JOINT - floor
    down = sole < contact
    both = down[1:] & down[:-1]
    step = np.linalg.norm(j[1:, :, :2] - j[:-1, :, :2], axis=-1) * 100.0
    return step[both]


def foot_skating_cm(joints: np.ndarray, floor: float = 0.0, contact: float = GROUND_CONTACT) -> float:
    """Mean grounded foot speed, cm/frame (NaN when no foot is ever grounded). A still foot scores 0."""
    s = grounded_foot_speeds(joints, floor, contact)
    return float(s.mean()) if s.size else float("nan")


def peak_jerk(joints: np.ndarray, fps: float = FPS) -> float:
    """Max over joints and time of the third finite difference of positions, in m/s^3. (T >= 4, J, 3)."""
    j = np.asarray(joints, np.float64)
    if j.shape[0] < 4:
        return float("nan")
    d3 = j[3:] - 3 * j[2:-1] + 3 * j[1:-2] - j[:-3]
    return float(np.linalg.norm(d3, axis=-1).max() * fps ** 3)


def facing_error_deg(ego: np.ndarray, target_xy: np.ndarray) -> np.ndarray | float:
    """Angle (degrees, 0..180) between the ego's hip facing and the horizontal direction from its pelvis
    to target_xy. ego (..., 22, 3), target_xy (..., 2) or (..., 3)."""
    e = np.asarray(ego, np.float64)
    to = np.asarray(target_xy, np.float64)[..., :2] - e[..., 0, :2]
    f = hip_facing(e)   # +Z x (right hip - left hip): the rest body faces -Y
    cross = f[..., 0] * to[..., 1] - f[..., 1] * to[..., 0]
    ang = np.degrees(np.abs(np.arctan2(cross, (f * to).sum(-1))))
    return float(ang) if np.ndim(ang) == 0 else ang


def collision_frames(joints: np.ndarray, grid: Any, height: float = COLLISION_HEIGHT) -> np.ndarray:
    """(T,) bool: any ego joint below `height` inside an occupied voxel of `grid` (an OccupancyGrid)."""
    j = np.asarray(joints, np.float64)
    hit = np.asarray(grid.occupied(j), bool) & (j[..., 2] < height)
    return hit.any(axis=-1)


def collision_percent(joints: np.ndarray, grid: Any, height: float = COLLISION_HEIGHT) -> float:
    """Percent of frames in collision (see collision_frames)."""
    c = collision_frames(joints, grid, height)
    return float(100.0 * c.mean()) if c.size else float("nan")


# ----------------------------------------------------------------------------- segments (VAE, prior, CV)
def segment_windows(lib, clip_ids: Sequence[int], span: int, stride: int, limit: int | None = None
                    ) -> list[tuple[int, int]]:
    """(clip, start) of non-overlapping-future windows of `span` feature frames, evenly thinned to `limit`."""
    out = []
    for c in clip_ids:
        n = lib.frames(c) - 1            # features: one row fewer than frames
        out.extend((c, s) for s in range(0, n - span + 1, stride))
    if limit is not None and len(out) > limit:
        keep = np.linspace(0, len(out) - 1, limit).round().astype(int)
        out = [out[i] for i in keep]
    return out


def _future_joints_world(model, fut_n: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor) -> np.ndarray:
    """Normalised canonical future features (B, F, D) -> FK world joints (B, F, 22, 3)."""
    feat = to_world(model.stats.denormalize(fut_n.float()), rot, trans)
    local, pelvis = features_to_pose(feat)
    return forward_kinematics(local, pelvis)[0].numpy()


@torch.no_grad()
def evaluate_segments(model, lib, clip_ids: Sequence[int], *, guidance: float = 5.0, seed: int = 0,
                      limit: int | None = 512, batch: int = 256) -> dict:
    """VAE reconstruction, prior next-segment error and the constant-velocity baseline on the same windows."""
    h, f = model.cfg.history, model.cfg.future
    windows = segment_windows(lib, clip_ids, h + f, f, limit)
    if not windows:
        raise RemogenError(f"no held-out clip is long enough for a {h + f + 1}-frame segment; add longer clips")
    gen = torch.Generator().manual_seed(seed)
    from .model import Contexts
    sums = {"vae": 0.0, "prior": 0.0, "cv": 0.0}
    count = 0
    for a in range(0, len(windows), batch):
        chunk = windows[a:a + batch]
        segs, rots, transs, texts = [], [], [], []
        for c, s in chunk:
            seg_world = lib.features(c)[s:s + h + f]
            can, rot, trans = canonicalize(seg_world)
            segs.append((can, seg_world))
            rots.append(rot)
            transs.append(trans)
            texts.append(lib.captions[c])
        can = model.stats.normalize(torch.stack([x[0] for x in segs]))
        world = torch.stack([x[1] for x in segs])
        rot, trans = torch.stack(rots), torch.stack(transs)
        hist, fut = can[:, :h], can[:, h:]
        gt = feature_joints(world[:, h:]).numpy()            # FK joints of the GT future, world
        gt_hist = feature_joints(world[:, :h]).numpy()
        mu, _ = model.vae.encode(hist, fut)
        rec = _future_joints_world(model, model.vae.decode(hist, mu), rot, trans)
        text_emb = model.text_encoder.encode(texts)
        z = model.sample_latent(hist, text_emb, Contexts({}), dict(ALPHA_OFF), guidance, gen)
        pri = _future_joints_world(model, model.decode(hist, z), rot, trans)
        cv = constant_velocity(gt_hist, f)
        n = len(chunk)
        sums["vae"] += joint_error_mm(rec, gt) * n
        sums["prior"] += joint_error_mm(pri, gt) * n
        sums["cv"] += joint_error_mm(cv, gt) * n
        count += n
    return {"windows": count, "vae_mm": sums["vae"] / count, "prior_mm": sums["prior"] / count,
            "cv_mm": sums["cv"] / count}


# ----------------------------------------------------------------------------- rollouts and scenarios
def clip_start_frame(lib, clip: int):
    """The clip's first frame as an EgoFrame (to start a session from real motion)."""
    from .session import EgoFrame
    a = int(lib.offsets[clip])
    q = np.asarray(lib.rotations[a], np.float32)
    pel = np.asarray(lib.pelvis[a], np.float32)
    rot = quat_to_matrix(torch.from_numpy(q))
    joints = forward_kinematics(rot, torch.from_numpy(pel))[0].numpy()
    root = np.eye(4, dtype=np.float32)
    root[:3, :3], root[:3, 3] = rot[0].numpy(), pel
    return EgoFrame(0, joints.astype(np.float32), root, q)


def rollout(model, frames: int, *, text: str = "", seed: int = 0, alpha: dict | None = None,
            start=None, root_position: Sequence[float] = (0.0, 0.0, 0.0), yaw: float = 0.0,
            partner: np.ndarray | None = None, goal: Sequence[float] | None = None, scene=None,
            guidance: float = 5.0) -> np.ndarray:
    """(frames, 22, 3) world joints generated by a ReactionSession (FWSR on, as shipped)."""
    from .session import ReactionSession
    s = ReactionSession(model, text=text, seed=seed, alpha=alpha, guidance=guidance, fwsr=True, scene=scene)
    if start is not None:
        s.reset(frame=start)
    else:
        s.reset(root_position=root_position, yaw=yaw)
    out = np.empty((frames, 22, 3), np.float32)
    for i in range(frames):
        out[i] = s.step(partner=None if partner is None else partner[i], goal=goal).joints
    return out


def evaluate_rollouts(model, lib, clip_ids: Sequence[int], frames: int, seed: int = 0,
                      guidance: float = 5.0) -> dict:
    """Foot skating and peak jerk of prior rollouts started from held-out clips (their captions as text),
    with the same numbers on those clips' real motion as the reference."""
    speeds, jerks, gt_speeds, gt_jerks = [], [], [], []
    for k, c in enumerate(clip_ids):
        j = rollout(model, frames, text=lib.captions[c], seed=seed + k, alpha=dict(ALPHA_OFF),
                    start=clip_start_frame(lib, c), guidance=guidance)
        speeds.append(grounded_foot_speeds(j))
        jerks.append(peak_jerk(j))
        rot, pel = lib.pose(c)
        gt = forward_kinematics(rot, pel)[0].numpy()
        gt_speeds.append(grounded_foot_speeds(gt))
        gt_jerks.append(peak_jerk(gt))

    def mean(xs: list[np.ndarray]) -> float:
        x = np.concatenate(xs) if xs else np.zeros(0)
        return float(x.mean()) if x.size else float("nan")

    def mean_finite(xs: list[float]) -> float:
        x = np.asarray([v for v in xs if math.isfinite(v)])
        return float(x.mean()) if x.size else float("nan")

    return {"rollouts": len(clip_ids), "frames": frames,
            "skating_rollout": mean(speeds), "skating_gt": mean(gt_speeds),
            "jerk_rollout": mean_finite(jerks), "jerk_gt": mean_finite(gt_jerks)}


def partner_scenario(model, frames: int, alpha: dict, seeds: Sequence[int], yaws: Sequence[float],
                     guidance: float = 5.0) -> tuple[dict, list[tuple[np.ndarray, np.ndarray]]]:
    """Partner walks from 4 m toward the ego (at the origin) and stops at 1 m; the ego starts turned by
    each of `yaws` away from it. Returns metrics and the (ego, partner) trajectories."""
    from .bench import approaching_partner
    partner = approaching_partner(frames)
    errs, clear, runs = [], [], []
    for seed in seeds:
        for yaw in yaws:
            ego = rollout(model, frames, text=PARTNER_TEXT, seed=seed, alpha=alpha, yaw=yaw, partner=partner,
                          guidance=guidance)
            errs.append(facing_error_deg(ego[-1], partner[-1, 0]))
            clear.append(min_body_clearance(ego, partner))
            runs.append((ego, partner))
    return {"facing_error_deg": float(np.mean(errs)), "min_clearance_m": float(np.min(clear))}, runs


def box_scenario(model, frames: int, alpha: dict, seeds: Sequence[int], guidance: float = 5.0) -> dict:
    """A 0.8 m box 1.1-1.9 m ahead on the straight line to a goal 3 m ahead (model_runtime.bench.box_scene)."""
    from .bench import box_scene
    grid = box_scene()
    goal = (0.0, -3.0, 0.0)
    hits, dist, closest = [], [], []
    for seed in seeds:
        ego = rollout(model, frames, text=BOX_TEXT, seed=seed, alpha=alpha, goal=goal, scene=grid,
                      guidance=guidance)
        hits.append(collision_frames(ego, grid))
        to_goal = np.linalg.norm(ego[:, 0, :2] - np.asarray(goal[:2]), axis=-1)
        dist.append(float(to_goal[-1]))
        closest.append(float(to_goal.min()))
    return {"collision_percent": float(100.0 * np.concatenate(hits).mean()), "goal_distance_m": float(np.mean(dist)),
            "goal_closest_m": float(np.mean(closest))}


# ----------------------------------------------------------------------------- plots
def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def read_training_logs(log_dir: str | Path) -> dict[str, dict[str, np.ndarray]]:
    """{stage: {"step", "loss", "val_step", "val_loss"}} from every *.log.jsonl in log_dir (bad lines skipped)."""
    out: dict[str, dict[str, list]] = {}
    for path in sorted(Path(log_dir).glob("*.log.jsonl")):
        for line in path.read_text().splitlines():
            try:
                row = json.loads(line)
                stage, step, loss = str(row.get("stage", path.name.split(".")[0])), int(row["step"]), float(row["loss"])
            except (ValueError, KeyError, TypeError):
                continue
            d = out.setdefault(stage, {"step": [], "loss": [], "val_step": [], "val_loss": []})
            d["step"].append(step)
            d["loss"].append(loss)
            if row.get("val_loss") is not None:
                d["val_step"].append(step)
                d["val_loss"].append(float(row["val_loss"]))
    return {k: {kk: np.asarray(vv, np.float64) for kk, vv in v.items()} for k, v in out.items()}


def plot_training_curves(log_dir: str | Path, out_png: str | Path) -> Path | None:
    """One panel per stage: training loss (raw and smoothed) and validation loss. None when no logs."""
    logs = read_training_logs(log_dir)
    if not logs:
        return None
    plt = _pyplot()
    n = len(logs)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.4), squeeze=False)
    for ax, (stage, d) in zip(axes[0], logs.items()):
        order = np.argsort(d["step"], kind="stable")
        step, loss = d["step"][order], d["loss"][order]
        ax.plot(step, loss, color="0.75", lw=0.6, label="train")
        k = max(1, len(loss) // 50)
        if k > 1:
            sm = np.convolve(loss, np.ones(k) / k, mode="valid")
            ax.plot(step[k - 1:], sm, color="tab:blue", lw=1.4, label=f"train (mean of {k})")
        if d["val_loss"].size:
            ax.plot(d["val_step"], d["val_loss"], "o-", color="tab:orange", ms=3, label="validation")
        if (loss > 0).all():
            ax.set_yscale("log")
        ax.set_title(stage)
        ax.set_xlabel("step")
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("loss")
    fig.tight_layout()
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return out_png


def _bones(ax, joints: np.ndarray, dims: tuple[int, int], color: str, alpha: float = 1.0) -> None:
    for i, p in enumerate(PARENTS):
        if p >= 0:
            ax.plot(joints[[p, i], dims[0]], joints[[p, i], dims[1]], color=color, lw=1.2, alpha=alpha)


def plot_reaction_strip(ego: np.ndarray, partner: np.ndarray | None, out_png: str | Path, n: int = 6,
                        title: str = "") -> Path:
    """Stick figures at n evenly spaced frames: top view (x-y) above, side view (along the longer horizontal
    extent, against z) below; ego blue, partner red. ego, partner (T, 22, 3)."""
    plt = _pyplot()
    t = ego.shape[0]
    idx = np.linspace(0, t - 1, min(n, t)).round().astype(int)
    pts = ego if partner is None else np.concatenate((ego, partner), 1)
    lo, hi = pts.min((0, 1)) - 0.3, pts.max((0, 1)) + 0.3
    side = 1 if hi[1] - lo[1] > hi[0] - lo[0] else 0   # side view across the longer horizontal extent
    fig, axes = plt.subplots(2, len(idx), figsize=(2.4 * len(idx), 5.2), squeeze=False)
    for c, f in enumerate(idx):
        for r, dims in enumerate(((0, 1), (side, 2))):
            ax = axes[r][c]
            if partner is not None:
                _bones(ax, partner[f], dims, "tab:red")
            _bones(ax, ego[f], dims, "tab:blue")
            if r == 0:   # the ego's path so far, for orientation
                ax.plot(ego[:f + 1, 0, 0], ego[:f + 1, 0, 1], color="tab:blue", lw=0.6, alpha=0.4)
            ax.set_xlim(lo[dims[0]], hi[dims[0]])
            ax.set_ylim(min(lo[dims[1]], 0.0) if r else lo[dims[1]], hi[dims[1]])
            ax.set_aspect("equal")
            ax.tick_params(labelsize=6)
            if r == 0:
                ax.set_title(f"t = {f / FPS:.1f} s", fontsize=8)
        axes[0][c].set_xlabel("x (top view)", fontsize=7)
        axes[1][c].set_xlabel(f"{'xy'[side]} (side view)", fontsize=7)
    axes[0][0].set_ylabel("y", fontsize=7)
    axes[1][0].set_ylabel("z", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return out_png


# ----------------------------------------------------------------------------- main
def load_library(data: str | None, library: str | None):
    """The clip cache if it exists, else built from the data folder (and saved to `library` if given)."""
    from .data.library import ClipLibrary
    if library and Path(library).exists():
        return ClipLibrary.load(library)
    if not data:
        raise RemogenError(f"clip library {library} not found and no --data folder given; pass --data DIR")
    try:
        from .data.prepare import build_library
    except ImportError:
        raise RemogenError("model_runtime.data.prepare.build_library is missing; build a cache with "
                           "python -m model_runtime.data.prepare and pass --library runs/clips.npz") from None
    if not Path(data).is_dir():
        raise RemogenError(f"data folder {data} not found; pass --data pointing at the motion data")
    try:
        lib = build_library(data)
    except FileNotFoundError as exc:
        raise RemogenError(f"{str(exc).splitlines()[0]}; pass --data pointing at the motion data") from None
    if library:
        lib.save(library)
    return lib


def _finite(x: Any) -> Any:
    """JSON-safe: NaN/inf become null, floats rounded."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return round(float(x), 4) if math.isfinite(float(x)) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def evaluate(model, lib, *, clips: int | None = None, windows: int | None = 512, rollouts: int = 8,
             rollout_frames: int = 60, scenario_frames: int = 60, seeds: Sequence[int] = (0, 1),
             yaws: Sequence[float] = (math.pi / 2, -math.pi / 2, math.pi), guidance: float = 5.0,
             plots: str | Path | None = None, log_dir: str | Path = "runs/train") -> dict:
    """All metrics as one dict (see the module docstring); writes plots into `plots` when given."""
    h, f = model.cfg.history, model.cfg.future
    val = lib.split("val", min_frames=h + f + 1)
    if not val:
        raise RemogenError(f"the clip library has no held-out clip with at least {h + f + 1} frames; "
                           "add clips or rebuild it with python -m model_runtime.data.prepare")
    if clips is not None:
        val = val[:clips]
    t0 = time.time()
    seg = evaluate_segments(model, lib, val, guidance=guidance, seed=seeds[0] if seeds else 0, limit=windows)
    roll_ids = [val[i] for i in np.linspace(0, len(val) - 1, min(rollouts, len(val))).round().astype(int)] \
        if rollouts > 0 else []
    roll = evaluate_rollouts(model, lib, roll_ids, rollout_frames, guidance=guidance) if roll_ids else {}
    inter: dict[str, dict[str, float]] = {"facing_error_deg": {}, "min_clearance_m": {},
                                           "collision_percent": {}, "goal_distance_m": {}, "goal_closest_m": {}}
    strip = None
    for name, alpha in (("alpha1", ALPHA_ON), ("alpha0", ALPHA_OFF)):
        p, runs = partner_scenario(model, scenario_frames, alpha, seeds, yaws, guidance)
        b = box_scenario(model, scenario_frames, alpha, seeds, guidance)
        for k, v in {**p, **b}.items():
            inter[k][name] = v
        if name == "alpha1" and runs:
            strip = runs[0]
    written = []
    if plots:
        out = Path(plots)
        tc = plot_training_curves(log_dir, out / "training_curves.png")
        if tc is not None:
            written.append(str(tc))
        if strip is not None:
            written.append(str(plot_reaction_strip(strip[0], strip[1], out / "reaction_strip.png",
                                                   title="partner walks in from 4 m and stops at 1 m (alpha = 1)")))
    result = {
        "model": model.meta.get("path", "default"),
        "trained": bool(model.meta.get("trained", False)),
        "held_out_clips": len(val),
        "windows": seg["windows"],
        "vae_reconstruction_mm": seg["vae_mm"],
        "next_segment_mm": {"prior": seg["prior_mm"], "constant_velocity": seg["cv_mm"],
                            "prior_beats_constant_velocity": seg["prior_mm"] < seg["cv_mm"]},
        "foot_skating_cm_per_frame": {"rollout": roll.get("skating_rollout"), "ground_truth": roll.get("skating_gt")},
        "peak_jerk_m_s3": {"rollout": roll.get("jerk_rollout"), "ground_truth": roll.get("jerk_gt")},
        "rollouts": {"count": roll.get("rollouts", 0), "frames": rollout_frames},
        "interaction": {**inter, "scenario_frames": scenario_frames, "runs_per_alpha": len(seeds) * len(yaws)},
        "plots": written,
        "wall_s": time.time() - t0,
    }
    return _finite(result)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.evaluate", description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="../shared/data", help="data folder (used when no --library cache exists)")
    ap.add_argument("--library", default=None, help="clip cache .npz (built from --data and saved here if missing)")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--json", action="store_true", help="print one JSON line only")
    ap.add_argument("--plots", default="runs/eval", help="folder for PNG plots ('' = none)")
    ap.add_argument("--logs", default="runs/train", help="folder with training *.log.jsonl files")
    ap.add_argument("--clips", type=int, default=None, help="use at most this many held-out clips")
    ap.add_argument("--windows", type=int, default=512, help="at most this many segments for the VAE/prior errors")
    ap.add_argument("--rollouts", type=int, default=8)
    ap.add_argument("--rollout-frames", type=int, default=60)
    ap.add_argument("--scenario-frames", type=int, default=60)
    ap.add_argument("--seeds", default="0,1", help="comma-separated seeds for the scenarios")
    ap.add_argument("--guidance", type=float, default=5.0)
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads (1: batch-1 session steps are fastest single-threaded, as in bench)")
    args = ap.parse_args(argv)
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    from .checkpoint import load_model
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
        if not seeds:
            raise ValueError
    except ValueError:
        print(f"error: --seeds must be comma-separated integers, got {args.seeds!r}", file=sys.stderr)
        return 2
    if args.scenario_frames < 4 or args.rollout_frames < 4:
        print("error: --scenario-frames and --rollout-frames must be at least 4", file=sys.stderr)
        return 2
    try:
        lib = load_library(args.data, args.library)
        model = load_model(args.model)
        model.meta.setdefault("path", str(args.model) if args.model else "default")
        res = evaluate(model, lib, clips=args.clips, windows=args.windows, rollouts=args.rollouts,
                       rollout_frames=args.rollout_frames, scenario_frames=args.scenario_frames, seeds=seeds,
                       guidance=args.guidance, plots=args.plots or None, log_dir=args.logs)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(res))
    else:
        print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
