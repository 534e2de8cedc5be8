"""The test-time control costs of control.py with their gradients written out, in NumPy.

control.py defines each cost in torch; a steering step needs a cost and its gradient on one decoded segment of
8 frames, where autograd's bookkeeping over ~100 tiny ops cost more than the decoder's own backward (measured:
costs forward and backward 2.2-2.9 ms of a 4-5 ms step). Here the same sums and their derivatives run on small
NumPy arrays in float64, and only the decoder goes through autograd. tests/test_control_grad.py checks every
cost and gradient against the torch definitions, which stay the reference.
"""
from __future__ import annotations

import numpy as np

from .joints import LEFT_HIP, RIGHT_HIP, SOLE_BELOW_FOOT_JOINT

FPS = 10.0
SMOOTH_EPS = 0.05      # control._smooth_norm's rounded bottom
NORMALIZE_EPS = 1e-6   # torch.nn.functional.normalize's eps in control.py
NORM_EPS = 1e-12       # control.NORM_EPS


# ---------------------------------------------------------------------------------------------- helpers
def _normalize(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """v / max(|v|, eps) over the last axis, and that norm (for the backward)."""
    n = np.maximum(np.sqrt((v * v).sum(-1, keepdims=True)), NORMALIZE_EPS)
    return v / n, n


def _normalize_back(y: np.ndarray, n: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Gradient through y = v / |v| (|v| = n > eps): (g - y (y . g)) / n."""
    return (g - y * (y * g).sum(-1, keepdims=True)) / n


def facing(joints: np.ndarray, target_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """control.facing_cost and its gradient on joints (R, T, 22, 3); target_xy (R, 2)."""
    last = joints[:, -1]
    to, to_n = _normalize(target_xy - last[:, 0, :2])
    across = last[:, RIGHT_HIP, :2] - last[:, LEFT_HIP, :2]
    fwd, fwd_n = _normalize(np.stack((-across[:, 1], across[:, 0]), -1))
    cost = 1.0 - (fwd * to).sum(-1)
    g_fwd = _normalize_back(fwd, fwd_n, -to)
    g_to = _normalize_back(to, to_n, -fwd)
    grad = np.zeros_like(joints)
    g_across = np.stack((g_fwd[:, 1], -g_fwd[:, 0]), -1)
    grad[:, -1, RIGHT_HIP, :2] += g_across
    grad[:, -1, LEFT_HIP, :2] -= g_across
    grad[:, -1, 0, :2] -= g_to
    return cost, grad


def foot(joints: np.ndarray, before: np.ndarray, toes: tuple[int, int], skate_weight: float,
         floor_weight: float, body_share: float) -> tuple[np.ndarray, np.ndarray]:
    """control.foot_cost and its gradient. joints (B, T, 22, 3); before (B, 22, 3)."""
    t_idx = list(toes)
    tt = np.concatenate((before[:, None, t_idx], joints[:, :, t_idx]), 1)          # (B, T + 1, 2, 3)
    sole = tt[..., 2] - SOLE_BELOW_FOOT_JOINT
    near = 1.0 / (1.0 + np.exp(np.clip((sole - 0.04) / 0.01, -60.0, 60.0)))        # a weight, not differentiated
    step = tt[:, 1:, :, :2] - tt[:, :-1, :, :2]
    w = near[:, 1:] * near[:, :-1]
    skate = (w * (step * step).sum(-1)).sum((1, 2))
    under = np.maximum(-sole, 0.0)
    low = np.maximum(-joints[..., 2], 0.0)
    below = (under * under).sum((1, 2)) + (low * low).sum((1, 2))
    cost = skate_weight * skate + floor_weight * below
    g_tt = np.zeros_like(tt)
    g_step = skate_weight * 2.0 * w[..., None] * step
    g_tt[:, 1:, :, :2] += g_step
    g_tt[:, :-1, :, :2] -= g_step
    g_tt[..., 2] += floor_weight * -2.0 * under
    grad = np.zeros_like(joints)
    grad[..., 2] += floor_weight * -2.0 * low
    grad[:, :, t_idx] += g_tt[:, 1:]
    # the toes' slide moves the legs against the pelvis: the pelvis takes all but body_share of it back
    grad[:, :, 0, :2] -= (1.0 - body_share) * g_tt[:, 1:, :, :2].sum(2)
    return cost, grad


def seam(joints: np.ndarray, before: np.ndarray, earlier: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """control.seam_cost and its gradient."""
    at_history = joints[:, 0] - 2.0 * before + earlier
    at_first = joints[:, 1] - 2.0 * joints[:, 0] + before
    cost = (at_history ** 2).sum((1, 2)) + (at_first ** 2).sum((1, 2))
    grad = np.zeros_like(joints)
    grad[:, 0] += 2.0 * at_history - 4.0 * at_first
    grad[:, 1] += 2.0 * at_first
    return cost, grad


def glide(pelvis_xy: np.ndarray, history_xy: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """control.glide_cost and its gradient with respect to pelvis_xy (R, T, 2); history_xy (R, H, 2)."""
    h = history_xy.shape[1]
    path = np.concatenate((history_xy, pelvis_xy), 1)
    acc = path[:, 2:] - 2.0 * path[:, 1:-1] + path[:, :-2]
    size = np.sqrt((acc * acc).sum(-1) + NORM_EPS)
    excess = np.maximum(size - limit, 0.0)
    g_acc = (2.0 * excess / size)[..., None] * acc
    g_path = np.zeros_like(path)
    g_path[:, 2:] += g_acc
    g_path[:, 1:-1] -= 2.0 * g_acc
    g_path[:, :-2] += g_acc
    return (excess * excess).sum(-1), g_path[:, h:]


def partner(joints: np.ndarray, future: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """control.partner_cost and its gradient. joints (R, T, 22, 3); future (R, T + L, 22, 3).

    Only the joint pairs within `margin` count, and they are few: all pairs' squared distances come from one
    product (|a|^2 + |b|^2 - 2 a.b, with slack for its rounding), then the close pairs are taken exactly."""
    r, t = joints.shape[:2]
    ego = np.concatenate((joints, np.repeat(joints[:, -1:], future.shape[1] - t, 1)), 1)
    d2 = ((ego * ego).sum(-1)[..., :, None] + (future * future).sum(-1)[..., None, :]
          - 2.0 * np.matmul(ego, np.swapaxes(future, -1, -2)))
    cost, g_ego = np.zeros(r), np.zeros_like(ego)
    rr, tt, ii, kk = np.nonzero(d2 < (margin + 1e-3) ** 2)
    if len(rr):
        diff = ego[rr, tt, ii] - future[rr, tt, kk]
        d = np.sqrt((diff * diff).sum(-1))
        short = np.maximum(margin - d, 0.0)
        np.add.at(cost, rr, short * short)
        with np.errstate(divide="ignore", invalid="ignore"):
            unit = np.where(d[:, None] > 0.0, diff / d[:, None], 0.0)
        np.add.at(g_ego, (rr, tt, ii), -2.0 * short[:, None] * unit)
    grad = g_ego[:, :t].copy()
    grad[:, -1] += g_ego[:, t:].sum(1)
    return cost, grad


def passing(ego_xy: np.ndarray, partner_xy: np.ndarray, away: np.ndarray, clearance: float,
            length: float) -> tuple[np.ndarray, np.ndarray]:
    """control.passing_cost and its gradient on ego_xy (R, N, 2)."""
    rel = ego_xy - partner_xy
    along = np.stack((away[:, 1], -away[:, 0]), -1)
    lon = (rel * along[:, None]).sum(-1)
    lat = (rel * away[:, None]).sum(-1)
    near = np.maximum(1.0 - np.abs(lon) / length, 0.0)
    short = np.maximum(clearance - lat, 0.0)
    cost = (near * short * short).sum(-1)
    grad = (near * -2.0 * short)[..., None] * away[:, None]
    return cost, grad


def smooth_norm(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """control._smooth_norm and its gradient."""
    r = np.sqrt((v * v).sum(-1) + SMOOTH_EPS * SMOOTH_EPS)
    return r - SMOOTH_EPS, v / r[..., None]


def goal(pelvis: np.ndarray, start_xy: np.ndarray, goal_xy: np.ndarray, cfg, far_walk: np.ndarray | None,
         walk_end) -> tuple[np.ndarray, np.ndarray]:
    """control.goal_cost and its gradient on pelvis (R, T, 3). With walking distances: `far_walk` (R,) at the
    starts and `walk_end(xy (R, 2)) -> (values (R,), gradients (R, 2))`."""
    frames = pelvis.shape[1]
    start = np.sqrt(((goal_xy - start_xy) ** 2).sum(-1))
    if walk_end is None:
        far = start
        end, g_end_xy = smooth_norm(pelvis[:, -1, :2] - goal_xy)
    else:
        far = far_walk
        end, g_end_xy = walk_end(pelvis[:, -1, :2])
    wanted = np.maximum(far - cfg.pace * frames / FPS, 0.0)
    cost = cfg.goal_weight * np.maximum(end - wanted, 0.0)
    g_end = cfg.goal_weight * (end - wanted > 0.0)
    grad = np.zeros_like(pelvis)
    rest = start < cfg.rest_radius
    if rest.any():
        path = np.concatenate((start_xy[:, None], pelvis[:, :, :2]), 1)
        steps = path[:, 1:] - path[:, :-1]
        cost = cost + np.where(rest, cfg.rest_weight * ((steps ** 2).sum((1, 2)) + end ** 2), 0.0)
        g_end = g_end + np.where(rest, cfg.rest_weight * 2.0 * end, 0.0)
        g_steps = np.where(rest[:, None, None], cfg.rest_weight * 2.0 * steps, 0.0)
        grad[:, :, :2] += g_steps
        grad[:, :-1, :2] -= g_steps[:, 1:]
    grad[:, -1, :2] += g_end[:, None] * g_end_xy
    return cost, grad


# ---------------------------------------------------------------------------------------------- scene maps
def field_value_and_grad(field, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DistanceField(points) and its gradient in NumPy: trilinear on the cell-centre grid, `reach` with no
    gradient outside it (as its torch __call__). points (..., 3)."""
    shape = points.shape[:-1]
    p = points.reshape(-1, 3)
    reach = field.reach
    if field.empty:
        return np.full(shape, reach), np.zeros(shape + (3,))
    vol = field._volume_np
    n = np.asarray(vol.shape)
    c = (p - field._origin_np) / field.voxel_size - 0.5
    inside = ((c > 0.0) & (c < n - 1)).all(-1)
    i0 = np.clip(np.floor(c).astype(np.int64), 0, n - 2)
    t = np.clip(c - i0, 0.0, 1.0)
    x0, y0, z0 = i0[:, 0], i0[:, 1], i0[:, 2]
    c000, c100 = vol[x0, y0, z0], vol[x0 + 1, y0, z0]
    c010, c110 = vol[x0, y0 + 1, z0], vol[x0 + 1, y0 + 1, z0]
    c001, c101 = vol[x0, y0, z0 + 1], vol[x0 + 1, y0, z0 + 1]
    c011, c111 = vol[x0, y0 + 1, z0 + 1], vol[x0 + 1, y0 + 1, z0 + 1]
    tx, ty, tz = t[:, 0], t[:, 1], t[:, 2]
    c00, c10 = c000 + (c100 - c000) * tx, c010 + (c110 - c010) * tx
    c01, c11 = c001 + (c101 - c001) * tx, c011 + (c111 - c011) * tx
    c0, c1 = c00 + (c10 - c00) * ty, c01 + (c11 - c01) * ty
    val = c0 + (c1 - c0) * tz
    gx = ((1 - ty) * (1 - tz) * (c100 - c000) + ty * (1 - tz) * (c110 - c010)
          + (1 - ty) * tz * (c101 - c001) + ty * tz * (c111 - c011))
    gy = (1 - tz) * (c10 - c00) + tz * (c11 - c01)
    gz = c1 - c0
    grad = np.stack((gx, gy, gz), -1) / field.voxel_size
    val = np.where(inside, val, reach)
    grad = np.where(inside[:, None], grad, 0.0)
    return val.reshape(shape), grad.reshape(shape + (3,))


def nav_value_and_grad(nav, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """NavigationField(xy) and its gradient in NumPy: bilinear on the map's cells, plus the straight distance
    beyond its edge (as its torch __call__). xy (N, 2)."""
    u = nav._u
    n = np.asarray(u.shape)
    lo = nav.origin + 0.5 * nav.cell
    hi = nav.origin + (n - 0.5) * nav.cell
    inside = np.minimum(np.maximum(xy, lo), hi)
    off = xy - inside
    beyond = np.sqrt((off * off).sum(-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        g_beyond = np.where(beyond[:, None] > 0.0, off / beyond[:, None], 0.0)
    c = (inside - lo) / nav.cell
    i0 = np.clip(np.floor(c).astype(np.int64), 0, n - 2)
    t = np.clip(c - i0, 0.0, 1.0)
    x0, y0 = i0[:, 0], i0[:, 1]
    c00, c10, c01, c11 = u[x0, y0], u[x0 + 1, y0], u[x0, y0 + 1], u[x0 + 1, y0 + 1]
    tx, ty = t[:, 0], t[:, 1]
    val = (1 - tx) * (1 - ty) * c00 + tx * (1 - ty) * c10 + (1 - tx) * ty * c01 + tx * ty * c11
    gx = ((1 - ty) * (c10 - c00) + ty * (c11 - c01)) / nav.cell
    gy = ((1 - tx) * (c01 - c00) + tx * (c11 - c10)) / nav.cell
    free = (xy > lo) & (xy < hi)          # a clamped axis has no gradient through the map
    grad = np.stack((gx, gy), -1) * free + g_beyond
    return val + beyond, grad
