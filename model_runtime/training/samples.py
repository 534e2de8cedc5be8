"""Training batches: canonicalised history/future segments plus their interaction cues.

A sample is a window of H + F frames of a clip, canonicalised on its first frame (exactly what the
session does online). HHI samples add the partner's recent joints in that frame, with a random lag of
up to one segment because online the diffusion runs ahead on stale partner frames; HSI samples add the
ego-local occupancy and the goal. For HHI pairs half the windows are drawn among those whose future
brings the partner within INTERACTION_RANGE of the ego: uniform windows are mostly mid-walk, where the
partner changes nothing, and a module trained on them learns a partner-independent bias instead of the
reaction (measured: shuffling partners across a batch cost only 0.003 of its 0.145 loss). HSI scenes do the
same with the goal: half the windows are drawn among those whose future brings the ego within GOAL_RANGE of its
goal, where slowing down and standing at it happen (uniform windows are mostly "keep walking toward a far goal";
measured: the module walked through the box test's goal at 1-1.8 m/s and kept going). FWSR samples add, for a
random frame f of the future, the latest H real frames and partner frames as the session sees them at frame f.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..config import ModelConfig
from ..data.library import ClipLibrary, derived_kind
from ..data.phrasings import pick_phrasing
from ..data.stretches import split_style
from ..features import JOINT_DELTA, ROOT_T, FeatureStats, canonicalize, to_canonical, world_points_to_canonical
from ..skeleton import NUM_JOINTS, forward_kinematics
from .recipe import (ANCHORED_KINDS, CONTROLLED_COPY_WEIGHT, REVERSAL_WEIGHT, ROLLOUT_LOOK_AHEAD, SLOWED_WALK_WEIGHT,
                     SLOW_WALK_CAPTION, SLOW_WALK_HEADS, SLOW_WALK_SHARE, SLOW_WALK_SPEED, STARTUP_WEIGHT,
                     STILL_CAPTION, STILL_SHARE, STILL_SPEED, STILL_TRAVEL, TURN_ARRIVAL_WEIGHT, TWO_PERSON_WEIGHT)

FPS = 10.0


def is_still(window: torch.Tensor) -> bool:
    """Whether a window of world features (T, 276) keeps still: its pelvis ends within STILL_TRAVEL m of where it
    started (floor plane) and its joints move slower than STILL_SPEED m/s on average."""
    travel = float(torch.linalg.vector_norm(window[-1, ROOT_T][:2] - window[0, ROOT_T][:2]))
    steps = window[:, JOINT_DELTA].reshape(window.shape[0], NUM_JOINTS, 3)
    return travel < STILL_TRAVEL and float(torch.linalg.vector_norm(steps, dim=-1).mean()) * FPS < STILL_SPEED


def caption_head(caption: str) -> str:
    """The caption without its style: 'a person walks forward, tired' -> 'a person walks forward'."""
    return split_style(caption)[0]


def caption_balance(lib: ClipLibrary, clips: list[int], power: float) -> np.ndarray:
    """(len(clips),) factors: each clip's caption head's frame count (over `clips`) to the power -`power`, scaled
    to a mean of 1 (all ones for power 0). recipe.CAPTION_BALANCE says why."""
    if power == 0.0 or not clips:
        return np.ones(len(clips))
    heads = [caption_head(lib.captions[i]) for i in clips]
    frames: dict[str, int] = {}
    for i, h in zip(clips, heads):
        frames[h] = frames.get(h, 0) + lib.frames(i)
    f = np.array([float(frames[h]) ** -power for h in heads])
    return f / f.mean()


def with_head_shares(weights: np.ndarray, heads: list[str], shares: tuple[tuple[str, float], ...]) -> np.ndarray:
    """Draw weights (one per clip, with its caption head) rescaled so that the clips whose head starts with a prefix
    of `shares` make that share of the draws (the first prefix that matches; the others keep their proportions in
    what is left). A prefix no clip has changes nothing. recipe.KICK_HEAD_SHARES says why."""
    w = np.asarray(weights, np.float64).copy()
    total = w.sum()
    taken = np.zeros(len(w), bool)
    kept = 1.0     # the share left to the clips no prefix names
    for prefix, share in shares:
        group = np.array([h.startswith(prefix) for h in heads], bool) & ~taken
        if w[group].sum() == 0:
            continue
        w[group] *= share * total / w[group].sum()
        taken |= group
        kept -= share
    rest = ~taken
    if taken.any() and w[rest].sum() > 0:
        w[rest] *= kept * total / w[rest].sum()
    return w


def window_speed(window: torch.Tensor) -> float:
    """m/s of a window's pelvis from its first to its last frame (floor plane)."""
    travel = float(torch.linalg.vector_norm(window[-1, ROOT_T][:2] - window[0, ROOT_T][:2]))
    return travel * FPS / max(1, window.shape[0] - 1)


def slow_walk_caption(caption: str) -> str | None:
    """SLOW_WALK_CAPTION with the caption's style ('a person walks forward, tired' -> 'a person walks slowly,
    tired'), or None when the caption is not a plain walk (SLOW_WALK_HEADS)."""
    head, style = split_style(caption)
    return SLOW_WALK_CAPTION + (f", {style}" if style else "") if head in SLOW_WALK_HEADS else None

INTERACTION_RANGE = 2.5   # m between the pelvises: the partner is close enough to shape the next segment
INTERACTION_SHARE = 0.5   # share of HHI windows drawn among those in range
# A set-off window: the pelvis travels less than SETOFF_STILL over the history and more than SETOFF_MOVE over the
# future (a standing body starting to move; recipe.WindowRecipe.setoff_share)
SETOFF_STILL = 0.05       # m
SETOFF_MOVE = 0.15        # m
GOAL_RANGE = 1.0          # m from the pelvis to the goal (floor plane): the goal decides how the segment ends
GOAL_SHARE = 0.5          # share of HSI windows drawn among those that reach it
# Detour scenes (data/detours.py) are the only ones whose box stands on the path to the goal, about 1 in 10
# windows by frame count; drawn 3x as often so that walking around something is not a rare event.
SCENE_KIND_WEIGHT = {"detour": 3.0}
# Derived clips drawn more or less often than their frame count (library.derived_kind -> factor).
CLIP_KIND_WEIGHT = {"startup": STARTUP_WEIGHT, "reversed": REVERSAL_WEIGHT, "turnarrive": TURN_ARRIVAL_WEIGHT,
                    "slowed": SLOWED_WALK_WEIGHT, "ctlavoid": CONTROLLED_COPY_WEIGHT,
                    "ctlgreeted": CONTROLLED_COPY_WEIGHT, "twoperson": TWO_PERSON_WEIGHT}


@dataclass
class Batch:
    hist: torch.Tensor                  # (B, H, D) normalised canonical
    fut: torch.Tensor                   # (B, F, D)
    text: list[str]
    partner: torch.Tensor | None = None  # (B, W, 22, 3) canonical
    present: torch.Tensor | None = None  # (B, W) bool
    occupancy: torch.Tensor | None = None  # (B, R, R, R)
    goal: torch.Tensor | None = None     # (B, 3) canonical
    frame: torch.Tensor | None = None    # (B,) FWSR frame index f
    recent: torch.Tensor | None = None   # (B, H, D) normalised latest real frames before f
    recent_partner: torch.Tensor | None = None  # (B, H, 22, 3)
    recent_present: torch.Tensor | None = None  # (B, H)
    anchored: torch.Tensor | None = None  # (B,) bool: a real clip's window or its mirror's (recipe.ANCHORED_KINDS)
    partner_future: torch.Tensor | None = None   # (B, F + L, 22, 3) canonical: the partner over the segment's
    future_present: torch.Tensor | None = None   # (B, F + L) bool        frames and ROLLOUT_LOOK_AHEAD after

    def to(self, device: torch.device | str, non_blocking: bool = False) -> "Batch":
        """The same batch with every tensor on `device` (the captions stay strings)."""
        return Batch(**{k: v.to(device, non_blocking=non_blocking) if torch.is_tensor(v) else v
                        for k, v in self.__dict__.items()})

    def pin_memory(self) -> "Batch":
        """Page-locked copies, so the copy to a GPU can overlap its work (DataLoader calls this)."""
        return Batch(**{k: v.pin_memory() if torch.is_tensor(v) else v for k, v in self.__dict__.items()})


class SegmentSampler:
    """Random segments from a set of clips (optionally with HHI pairs or HSI scenes)."""

    def __init__(self, lib: ClipLibrary, clip_ids: list[int], cfg: ModelConfig, stats: FeatureStats,
                 seed: int = 0, pairs: list | None = None, scenes: list | None = None,
                 still_share: float = STILL_SHARE, slow_walk_share: float = SLOW_WALK_SHARE,
                 caption_balance_power: float = 0.0,
                 head_shares: tuple[tuple[str, float], ...] = (), wider_phrasings: bool = False,
                 setoff_share: float = 0.0, kind_weights: dict[str, float] | None = None,
                 path_tail_share: float = 0.0) -> None:
        self.lib, self.cfg, self.stats = lib, cfg, stats
        kind_weight = {**CLIP_KIND_WEIGHT, **(kind_weights or {})}
        self.wider_phrasings, self.path_tail_share = wider_phrasings, path_tail_share
        self.still_share, self.slow_walk_share = still_share, slow_walk_share
        self.pairs, self.scenes = pairs, scenes
        self.span = cfg.history + cfg.future
        if pairs is not None:
            items = [(p.ego, k) for k, p in enumerate(pairs)]
        elif scenes is not None:
            items = [(sc.ego, k) for k, sc in enumerate(scenes)]
        else:
            items = [(i, -1) for i in clip_ids]
        # features have frames - 1 rows; keep clips that hold at least one whole segment
        self.items = [(i, k) for i, k in items if lib.frames(i) - 1 >= self.span]
        if not self.items:
            raise ValueError(f"no clip is long enough for a {self.span}-frame segment")
        weights = np.array([lib.frames(i) - self.span for i, _ in self.items], np.float64)
        weights *= np.array([kind_weight.get(derived_kind(lib.names[i]), 1.0) for i, _ in self.items])
        if scenes is not None:
            weights *= np.array([SCENE_KIND_WEIGHT.get(scenes[k].kind, 1.0) for _, k in self.items])
        else:
            weights *= caption_balance(lib, [i for i, _ in self.items], caption_balance_power)
            weights = with_head_shares(weights, [caption_head(lib.captions[i]) for i, _ in self.items], head_shares)
        self.weights = torch.from_numpy(weights / weights.sum())
        self.gen = torch.Generator().manual_seed(seed)
        self._partner_cache: dict[int, torch.Tensor] = {}
        # window starts where the cue matters (partner in range / goal reached), and the share drawn among them
        self._close_starts: list[torch.Tensor] | None = None
        self._close_share = 0.0
        if pairs is not None:
            self._close_starts = [self._interaction_starts(i, k) for i, k in self.items]
            self._close_share = INTERACTION_SHARE
        elif scenes is not None:
            self._close_starts = [self._goal_starts(i, k) for i, k in self.items]
            self._close_share = GOAL_SHARE
        # set-off windows drawn first, a share of the time (pairs only)
        self._setoff_share = setoff_share if pairs is not None else 0.0
        self._setoff_starts = [self._setoffs(i) for i, _ in self.items] if self._setoff_share > 0.0 else None

    def _interaction_starts(self, clip: int, k: int) -> torch.Tensor:
        """Window starts whose future frames bring the partner's pelvis within INTERACTION_RANGE."""
        n = self.lib.frames(clip)
        partner = np.asarray(self.pairs[k].partner[:n, 0, :2], np.float64)
        return self._starts_within(clip, partner, INTERACTION_RANGE)

    def _goal_starts(self, clip: int, k: int) -> torch.Tensor:
        """Window starts whose future frames bring the ego's pelvis within GOAL_RANGE of the scene's goal."""
        return self._starts_within(clip, np.asarray(self.scenes[k].goal[:2], np.float64), GOAL_RANGE)

    def _starts_within(self, clip: int, target: np.ndarray, radius: float) -> torch.Tensor:
        """Window starts with a future frame whose ego pelvis (floor plane) is within `radius` of `target`
        ((2,) or per-frame (n, 2) world xy)."""
        a = int(self.lib.offsets[clip])
        n = self.lib.frames(clip)
        ego = np.asarray(self.lib.pelvis[a:a + n, :2], np.float64)
        close = np.linalg.norm(ego - target, axis=-1) < radius
        starts = n - 1 - self.span + 1  # windows over the n - 1 feature rows
        h = self.cfg.history
        ok = [s for s in range(starts) if close[s + h:s + self.span].any()]
        return torch.tensor(ok, dtype=torch.long)

    def _setoffs(self, clip: int) -> torch.Tensor:
        """Window starts whose pelvis keeps still over the history and moves off over the future (SETOFF_*)."""
        a = int(self.lib.offsets[clip])
        xy = np.asarray(self.lib.pelvis[a:a + self.lib.frames(clip), :2], np.float64)
        h, starts = self.cfg.history, self.lib.frames(clip) - self.span
        s = np.arange(max(starts, 0))
        if not len(s):
            return torch.zeros(0, dtype=torch.long)
        still = np.linalg.norm(xy[s + h] - xy[s], axis=-1) < SETOFF_STILL
        moves = np.linalg.norm(xy[s + self.span] - xy[s + h], axis=-1) > SETOFF_MOVE
        return torch.from_numpy(s[still & moves]).long()

    def _one_of(self, starts: list[torch.Tensor] | None, p: int, share: float) -> int | None:
        """A start drawn from item p's `starts`, `share` of the time when it has any; else None."""
        if starts is None or not len(starts[p]) or float(torch.rand((), generator=self.gen)) >= share:
            return None
        return int(starts[p][int(torch.randint(0, len(starts[p]), (1,), generator=self.gen))])

    def _window_start(self, p: int, rows: int) -> int:
        for starts, share in ((self._setoff_starts, self._setoff_share), (self._close_starts, self._close_share)):
            s = self._one_of(starts, p, share)
            if s is not None:
                return s
        return int(torch.randint(0, rows - self.span + 1, (1,), generator=self.gen))

    def _caption(self, window: torch.Tensor, clip: int) -> str:
        """The caption a window trains with (one of its phrasings is drawn after): its clip's, or, for a window
        whose body keeps still, STILL_CAPTION a share of the time, or, for a plain walk at a slow pace,
        SLOW_WALK_CAPTION a share of the time (recipe.py says why for both)."""
        if self.still_share > 0.0 and is_still(window) and \
                float(torch.rand((), generator=self.gen)) < self.still_share:
            return STILL_CAPTION
        caption = self.lib.captions[clip]
        if self.slow_walk_share > 0.0:
            slow = slow_walk_caption(caption)
            if slow is not None and SLOW_WALK_SPEED[0] <= window_speed(window) <= SLOW_WALK_SPEED[1] and \
                    float(torch.rand((), generator=self.gen)) < self.slow_walk_share:
                return slow
        return caption

    def _partner_world(self, k: int) -> torch.Tensor:
        if k not in self._partner_cache:
            self._partner_cache[k] = torch.from_numpy(np.asarray(self.pairs[k].partner, np.float32))
        return self._partner_cache[k]

    def sample(self, n: int, fwsr: bool = False) -> Batch:
        cfg, h, f = self.cfg, self.cfg.history, self.cfg.future
        picks = torch.multinomial(self.weights, n, replacement=True, generator=self.gen).tolist()
        hist, fut, texts, partners, presents, occs, goals = [], [], [], [], [], [], []
        frames, recents, rpartners, rpresents, anchored, futures, fpresents = [], [], [], [], [], [], []
        for p in picks:
            clip, k = self.items[p]
            anchored.append(derived_kind(self.lib.names[clip]) in ANCHORED_KINDS)
            feats = self.lib.features(clip)
            s = self._window_start(p, feats.shape[0])
            seg, rot, trans = canonicalize(feats[s:s + self.span])
            seg = self.stats.normalize(seg)
            hist.append(seg[:h])
            fut.append(seg[h:])
            texts.append(pick_phrasing(self._caption(feats[s:s + self.span], clip), self.gen, self.wider_phrasings,
                                       self.path_tail_share))
            if self.pairs is not None:
                lag = int(torch.randint(0, f + 1, (1,), generator=self.gen))
                end = s + h - 1 - lag  # last partner frame seen by the diffusion
                pw, pr = self._partner_window(k, end, cfg.partner_window, rot, trans)
                partners.append(pw)
                presents.append(pr)
                # where the partner really is while the segment plays and just after (the rollout clearance loss,
                # not an input): the segment's last pose must keep out of the partner's way, as control asks
                fw, fp = self._partner_window(k, s + h + f - 1 + ROLLOUT_LOOK_AHEAD, f + ROLLOUT_LOOK_AHEAD, rot, trans)
                futures.append(fw)
                fpresents.append(fp)
            if self.scenes is not None:
                sc = self.scenes[k]
                m = np.eye(4, dtype=np.float32)
                m[:3, :3], m[:3, 3] = rot.numpy(), trans.numpy()
                occs.append(torch.from_numpy(np.asarray(
                    sc.grid().sample_ego(m, bounds=cfg.scene_bounds, resolution=cfg.voxel_resolution), np.float32)))
                goals.append(world_points_to_canonical(torch.as_tensor(sc.goal, dtype=torch.float32).view(1, 3),
                                                       rot, trans)[0])
            if fwsr:
                fi = int(torch.randint(1, f, (1,), generator=self.gen))
                frames.append(fi)
                # the H real frames before future frame fi, in the segment's canonical frame
                recents.append(self.stats.normalize(to_canonical(feats[s + fi:s + fi + h], rot, trans)))
                if self.pairs is not None:
                    pw, pr = self._partner_window(k, s + h + fi, h, rot, trans)
                else:
                    pw, pr = torch.zeros(h, NUM_JOINTS, 3), torch.zeros(h, dtype=torch.bool)
                rpartners.append(pw)
                rpresents.append(pr)
        batch = Batch(torch.stack(hist), torch.stack(fut), texts, anchored=torch.tensor(anchored))
        if partners:
            batch.partner, batch.present = torch.stack(partners), torch.stack(presents)
            batch.partner_future, batch.future_present = torch.stack(futures), torch.stack(fpresents)
        if occs:
            batch.occupancy, batch.goal = torch.stack(occs), torch.stack(goals)
        if fwsr:
            batch.frame = torch.tensor(frames)
            batch.recent = torch.stack(recents)
            batch.recent_partner, batch.recent_present = torch.stack(rpartners), torch.stack(rpresents)
        return batch

    def _partner_window(self, k: int, end: int, w: int, rot: torch.Tensor, trans: torch.Tensor):
        """Partner joints of frames end-w+1..end in the canonical frame; frames before 0 are absent."""
        world = self._partner_world(k)
        idx = torch.arange(end - w + 1, end + 1)
        present = (idx >= 0) & (idx < world.shape[0])
        pts = world[idx.clamp(0, world.shape[0] - 1)]
        can = world_points_to_canonical(pts, rot, trans) * present.view(-1, 1, 1)
        return can, present


def world_joints(lib: ClipLibrary, clip: int) -> torch.Tensor:
    """(T, 22, 3) FK joints of a library clip."""
    rot, pel = lib.pose(clip)
    return forward_kinematics(rot, pel)[0]
