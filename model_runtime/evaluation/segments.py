"""Next-segment errors on held-out windows: VAE reconstruction, the prior from real history and caption,
and a constant-velocity extrapolation as the baseline, all on the same windows."""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from ..errors import DEFAULT_GUIDANCE, RemogenError
from ..features import canonicalize, feature_joints, features_to_pose, to_world
from ..skeleton import forward_kinematics
from .metrics import constant_velocity, joint_error_mm
from .rollouts import ALPHA_OFF

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
def evaluate_segments(model, lib, clip_ids: Sequence[int], *, guidance: float = DEFAULT_GUIDANCE, seed: int = 0,
                      limit: int | None = 512, batch: int = 256) -> dict:
    """VAE reconstruction, prior next-segment error and the constant-velocity baseline on the same windows."""
    h, f = model.cfg.history, model.cfg.future
    windows = segment_windows(lib, clip_ids, h + f, f, limit)
    if not windows:
        raise RemogenError(f"no held-out clip is long enough for a {h + f + 1}-frame segment; add longer clips")
    gen = torch.Generator().manual_seed(seed)
    from ..model import Contexts
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
