"""Avoidance copies for the HHI stage: getting out of a walking partner's way, which no clip of the open data
shows (its walks are single-person captures).

avoid (`<source>#avoid<k>`)
    The partner is a straight stretch of *another* real walk, moved rigidly and re-timed to 0.8-1.6 m/s by
    resampling, whose path crosses the ego's straight walk head-on (180 +- 10 deg, HEAD_ON_SHARE of them) or
    at 30-150 deg, timed so that their pelvises would pass within 0.3 m: without a reaction they collide.
    The ego is its real straight walk bent around the partner by `detours.bend_path` (each frame's body
    turned about its own pelvis, the pelvis path re-integrated): the heading swings out, holds, and swings
    back, so the walk goes on parallel to its old line. The gentlest swerve is chosen that keeps
    TARGET_CLEARANCE (0.40-0.50 m) between every pair of joints at every frame: the smallest angle of
    15-60 deg, starting when the partner comes within a distance drawn from 1.5-3 m (earlier, up to 3.5 m,
    where that cannot clear), swinging back as early as still clears and at the latest once the partner
    has passed. The side: behind a crossing partner (towards the side it comes from, which the walk reaches
    after the partner has left it), and away from the side an oncoming partner is on; at the closest
    approach the partner is always on the other side of the ego from where it swerved. Copies that cannot
    clear this way are not made. Feet slide a little while the heading changes, as in the detour copies.
stepaside (`<source>#stepaside<k>`)
    The ego is a calm real standing clip (a gesture, a bow; feet planted), the partner a real walk coming
    straight at it (within 45 deg of the ego's facing) on a line through the ego's spot. When the partner
    comes within 2-3 m the ego's whole body is translated 0.5-0.8 m (more, up to 1 m, where the partner would
    still pass closer than TARGET_CLEARANCE) sideways off the partner's line over about 1 s (smoothstep).
    The step is a synthetic shift of a real clip: the feet slide instead of stepping; the copies teach that
    and where to make room, not the footwork. `StepRule` says where the partner comes from, when the step
    starts and what the caption says. AHEAD_RULE is the above (the shipped recipe). YIELD_RULE (`--windows
    yield`, not shipped): the partner from any direction on a line 0-0.3 m off the ego's spot on either
    side, the ego stepping away from that line (to the partner's right where the line passes within
    KEEP_RIGHT_WITHIN: one convention instead of a coin toss the module would average into no step at all),
    1.5-2.5 s before the partner would reach it at its pace, the clip's own caption kept (the module, not the
    text, must make room whatever the ego was told to do). KEEP_RIGHT_RULE (`--windows keepright`, not
    shipped): the same, always to the partner's right, the step widened up to 1.4 m to clear.

Both keep the source's licence and held-out split and its caption: a step-aside copy's is prefixed "a person
steps aside and"; an avoid copy of a walk-and-turn clip, a straight stretch of it, says "a person walks
forward" in the clip's style. Both store their partner as a clip (new_clips.partner_clip_name) that the pair
builder (pairs.hhi, kinds avoid_walker and step_aside) checks again on its FK joints.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .detours import HEADING_RATE, WALK_SPEED, bend_path, bend_pelvis
from .geometry import normalized
from .library import ClipLibrary
from .new_clips import NewClip, copy_name, new_clip, partner_clip_name
from .pairs import FPS, ClipCache, facing_xy
from .stretches import (Stretch, WalkPool, clearance, clip_stretch, moved, partner_walk, rotate_xy,
                        straight_caption, walk_stretch, yaw_of)
from .turns import smoothstep

AVOID_FRAMES = (28, 50)              # frames of an avoidance copy (inclusive; at most the walk's straight stretch)
HEAD_ON_SHARE = 0.3                  # partners met head-on; the rest cross at CROSS_ANGLE
HEAD_ON_SPREAD = np.radians(10.0)
CROSS_ANGLE = (np.radians(30.0), np.radians(150.0))   # between the two walking directions
MISS = 0.3                           # m: the un-bent pelvis paths pass within this at the crossing
BEND_START = (1.5, 3.0)              # m between the pelvises when the swing starts
BEND_START_MAX = 3.5                 # m: the swing may start earlier, up to this far, where a later one cannot clear
SWERVE_ANGLES = np.radians(np.arange(15.0, 61.0, 5.0))   # heading swings tried, smallest first
TARGET_CLEARANCE = (0.40, 0.50)      # m joint to joint the swing (or step) is chosen to keep
MIN_STRAIGHT = 4                     # frames of unchanged walking (or standing) before the reaction starts
AVOID_AFTER = 10                     # frames after the crossing for the swerve to swing back
AVOID_COPIES = 4                     # per straight walk
STEP_FRAMES = (32, 50)
STEP_DISTANCE = (0.5, 0.8)           # m sideways
STEP_MAX = 1.0                       # m: the most a step is widened to keep TARGET_CLEARANCE
STEP_DURATION = (8, 12)              # frames (inclusive)
STEP_START = (2.0, 3.0)              # m between the pelvises when the step starts
APPROACH_SPREAD = np.radians(45.0)   # the partner comes from within this of straight ahead of the ego
PASS_OFFSET = (0.0, 0.2)             # m: its line misses the ego's spot by this, opposite the step
STEP_AFTER = 5                       # frames after the partner passes the ego's spot
KEEP_RIGHT_WITHIN = 0.12             # m: a partner's line this close to the ego's spot is yielded to on its right
STEP_COPIES = 1                      # per calm standing clip
ATTEMPTS = 6                         # placements tried per copy


@dataclass(frozen=True)
class StepRule:
    """Where a step-aside copy's partner comes from, when the ego steps and what its caption says."""
    approach_spread: float = APPROACH_SPREAD    # rad off straight ahead the partner may come from
    pass_offset: tuple[float, float] = PASS_OFFSET   # m its line misses the ego's spot by
    either_side: bool = False       # the line may pass on either side (else always opposite a random step)
    start_m: tuple[float, float] | None = STEP_START  # m between the pelvises when the step starts, or ...
    start_s: tuple[float, float] | None = None       # ... seconds before the partner would reach the ego's spot
    duration: tuple[int, int] = STEP_DURATION        # frames (inclusive)
    prefix_caption: bool = True     # "a person steps aside and ..." (else the standing clip's own caption)
    keep_right_within: float = KEEP_RIGHT_WITHIN   # m: with either_side, a line this close is passed on its right
    step_max: float = STEP_MAX      # m: the most a step is widened to keep TARGET_CLEARANCE


AHEAD_RULE = StepRule()
YIELD_RULE = StepRule(approach_spread=np.pi, pass_offset=(0.0, 0.3), either_side=True, start_m=None,
                      start_s=(1.5, 2.5), duration=(6, 10), prefix_caption=False)
KEEP_RIGHT_RULE = StepRule(approach_spread=np.pi, pass_offset=(0.0, 0.3), either_side=True, start_m=None,
                           start_s=(1.5, 2.5), duration=(6, 12), prefix_caption=False, keep_right_within=np.inf,
                           step_max=1.4)
STEP_RULES = {"ahead": AHEAD_RULE, "yield": YIELD_RULE, "right": KEEP_RIGHT_RULE}


def _left(v: np.ndarray) -> np.ndarray:
    return np.array([-v[1], v[0]])


def swerve_profile(frames: int, onset: int, angle: float, back: int) -> np.ndarray:
    """(frames,) heading added per frame: 0 until onset, swings to `angle` (at detours.HEADING_RATE), holds,
    and from frame `back` swings back to 0."""
    d = max(2.0, abs(angle) / HEADING_RATE * FPS)
    t = np.arange(frames, dtype=np.float64)
    return angle * (smoothstep((t - onset) / d) - smoothstep((t - back) / d))


def swerve_frames(angle: float) -> int:
    """Frames one swing of a swerve takes."""
    return int(np.ceil(max(2.0, abs(angle) / HEADING_RATE * FPS)))


def bent_joints(s: Stretch, yaw: np.ndarray) -> np.ndarray:
    """The joints of `bend_path(s, yaw)` without FK: each frame's body turned about its pelvis, moved onto the
    re-integrated pelvis path."""
    pel = bend_pelvis(s.pelvis, yaw).astype(np.float64)
    j = s.joints.astype(np.float64) - s.pelvis[:, None, :]
    j[..., :2] = rotate_xy(j[..., :2], yaw[:, None])
    return (j + pel[:, None, :]).astype(np.float32)


def passes_away(ego: np.ndarray, bent: np.ndarray, partner: np.ndarray, heading: np.ndarray) -> bool:
    """Whether the bent ego left its line to the side away from the partner: at the closest approach, the
    ego's offset from its un-bent position and the partner's side of the ego are opposite. Pelvis paths (T, 2)."""
    t = int(np.argmin(np.linalg.norm(bent - partner, axis=1)))
    side = _left(heading)
    return float((bent[t] - ego[t]) @ side) * float((partner[t] - bent[t]) @ side) < 0


def _crossing_frame(frames: int, closing: float, start: tuple[float, float], after: int,
                    rng: np.random.Generator) -> tuple[int, float] | None:
    """(frame of the crossing, distance at which the reaction starts) for partners closing at `closing` m/s:
    the reaction distance drawn from `start` (lowered to fit the copy, never below start[0]), the crossing
    late enough that the reaction starts after MIN_STRAIGHT frames and early enough to leave `after` frames."""
    last = frames - 1 - after
    reach = min(float(rng.uniform(*start)), (last - MIN_STRAIGHT) * closing / FPS)
    if reach < start[0]:
        return None
    first = MIN_STRAIGHT + int(np.ceil(reach * FPS / closing))
    if first > last:
        return None
    return int(rng.integers(first, min(last, first + 8) + 1)), reach


def _crossing_heading(heading: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    if rng.random() < HEAD_ON_SHARE:
        phi = np.pi + float(rng.uniform(-HEAD_ON_SPREAD, HEAD_ON_SPREAD))
    else:
        phi = float(rng.uniform(*CROSS_ANGLE)) * (1.0 if rng.random() < 0.5 else -1.0)
    return rotate_xy(heading, phi)


def _swerve(ego: Stretch, partner: Stretch, onsets: list[int], back_after: int, target: float, side: float
            ) -> np.ndarray | None:
    """The gentlest swerve to `side` (+1 left, -1 right) that keeps `target` clearance and passes away from the
    partner: the smallest angle, then the latest onset of `onsets` (latest first), then the earliest swing back
    (at the latest from `back_after`, once the partner has passed). Only onsets whose widest swing that fits
    the copy clears are searched."""
    frames = len(ego.pelvis)

    def works(onset: int, angle: float, back: int) -> np.ndarray | None:
        yaw = swerve_profile(frames, onset, angle, back)
        j = bent_joints(ego, yaw)
        ok = clearance(j, partner.joints) >= target and passes_away(ego.pelvis[:, :2], j[:, 0, :2],
                                                                    partner.pelvis[:, :2], ego.heading)
        return yaw if ok else None

    def latest_back(onset: int, angle: float) -> int:
        return max(onset + swerve_frames(angle), back_after)

    def fits(onset: int, angle: float) -> bool:        # the copy straightens before it ends
        return latest_back(onset, angle) + swerve_frames(angle) <= frames - 2

    open_ = []
    for onset in onsets:
        widest = [a for a in SWERVE_ANGLES if fits(onset, a)]
        if widest and works(onset, side * widest[-1], latest_back(onset, widest[-1])) is not None:
            open_.append(onset)
    for angle in SWERVE_ANGLES:
        for onset in open_:
            if not fits(onset, angle) or works(onset, side * angle, latest_back(onset, angle)) is None:
                continue
            for back in range(onset + swerve_frames(angle), latest_back(onset, angle) + 1):
                yaw = works(onset, side * angle, back)
                if yaw is not None:
                    return yaw
    return None


def _swerve_side(ego: Stretch, partner: Stretch, heading: np.ndarray, tc: int, rng: np.random.Generator
                 ) -> float:
    """+1 (left) or -1 (right): behind a crossing partner (to the side it comes from); away from the side an
    oncoming partner passes on."""
    left = _left(ego.heading)
    across = -float(heading @ left)                       # > 0: it comes from the left
    if abs(across) < np.sin(HEAD_ON_SPREAD) + 1e-6:       # head-on: pass on the side it is not on
        across = -float((partner.pelvis[tc, :2] - ego.pelvis[tc, :2]) @ left)
    return float(np.sign(across)) if abs(across) > 1e-3 else float(rng.choice([1.0, -1.0]))


def _avoid_one(lib: ClipLibrary, clips: ClipCache, i: int, longest: int, pool: WalkPool, rng: np.random.Generator
               ) -> tuple[Stretch, np.ndarray, Stretch] | None:
    """(ego stretch, swerve yaw, placed partner) for walk i, or None."""
    frames = min(longest, int(rng.integers(AVOID_FRAMES[0], AVOID_FRAMES[1] + 1)))
    ego = walk_stretch(lib, clips, i, frames, rng, speeds=WALK_SPEED)
    part = partner_walk(lib, clips, pool, frames, i, rng) if ego is not None else None
    if part is None:
        return None
    heading = _crossing_heading(ego.heading, rng)
    crossing = _crossing_frame(frames, float(np.linalg.norm(part.speed * heading - ego.speed * ego.heading)),
                               BEND_START, AVOID_AFTER, rng)
    if crossing is None:
        return None
    tc, reach = crossing
    at = ego.pelvis[tc, :2] + float(rng.uniform(-MISS, MISS)) * _left(heading)
    partner = moved(part, yaw_of(heading) - yaw_of(part.heading), tc, at)
    dist = np.linalg.norm(ego.pelvis[:, :2] - partner.pelvis[:, :2], axis=1)
    near = np.flatnonzero(dist <= reach)
    if not len(near) or near[0] < MIN_STRAIGHT:
        return None
    onsets = [t for t in range(int(near[0]), MIN_STRAIGHT - 1, -2) if dist[t] <= BEND_START_MAX]
    back_after = int(np.argmin(dist)) + int(rng.integers(1, 4))
    yaw = _swerve(ego, partner, onsets, back_after, float(rng.uniform(*TARGET_CLEARANCE)),
                  _swerve_side(ego, partner, heading, tc, rng))
    return None if yaw is None else (ego, yaw, partner)


def avoid_copies(lib: ClipLibrary, clips: ClipCache, egos: WalkPool, partners: dict[bool, WalkPool], seed: int
                 ) -> list[NewClip]:
    """AVOID_COPIES avoidance copies (and their partner clips) of each walk of `egos` with a straight stretch
    of AVOID_FRAMES[0] frames; partners are walks of `partners` on the walk's side of the split."""
    out: list[NewClip] = []
    for i, longest in zip(egos.ids.tolist(), egos.longest.tolist()):
        if longest < AVOID_FRAMES[0]:
            continue
        rng = np.random.default_rng([seed, i, 21])
        pool = partners[lib.is_held_out(i)]
        for k in range(AVOID_COPIES):
            for _ in range(ATTEMPTS):
                got = _avoid_one(lib, clips, i, longest, pool, rng)
                if got is not None:
                    ego, yaw, partner = got
                    rot, pel = bend_path(ego.rotations, ego.pelvis, yaw)
                    name = copy_name(lib, i, "avoid", k)
                    out += [new_clip(lib, i, name, straight_caption(lib.captions[i]), rot, pel),
                            new_clip(lib, partner.source, partner_clip_name(name), lib.captions[partner.source],
                                     partner.rotations, partner.pelvis, ego=False)]
                    break
    return out


def step_caption(caption: str) -> str:
    rest = caption[len("a person "):] if caption.startswith("a person ") else caption
    return "a person steps aside" + (f" and {rest}" if rest else "")


def _line_and_step(heading: np.ndarray, rule: StepRule, rng: np.random.Generator) -> tuple[float, np.ndarray]:
    """(signed offset of the partner's line from the ego's spot along the step, unit step direction): the
    line passes opposite the step, or, with `rule.either_side`, on a random side with the step away from it
    (to the partner's right within `rule.keep_right_within`)."""
    if not rule.either_side:
        away = _left(heading) * (1.0 if rng.random() < 0.5 else -1.0)
        return 0.0, away             # its offset is drawn after the crossing frame (the order AHEAD_RULE's copies keep)
    miss = float(rng.uniform(*rule.pass_offset)) * (1.0 if rng.random() < 0.5 else -1.0)   # + : partner's left
    away = -_left(heading) if abs(miss) < rule.keep_right_within else -np.sign(miss) * _left(heading)
    return miss, away


def _step_one(lib: ClipLibrary, clips: ClipCache, s: int, pool: WalkPool, rng: np.random.Generator,
              rule: StepRule = AHEAD_RULE) -> tuple[Stretch, np.ndarray, Stretch] | None:
    """(standing stretch, per-frame sideways shift (T, 2), placed partner) for standing clip s, or None."""
    frames = min(lib.frames(s), int(rng.integers(STEP_FRAMES[0], STEP_FRAMES[1] + 1)))
    start = int(rng.integers(0, lib.frames(s) - frames + 1))
    ego = clip_stretch(lib, clips, s, start + np.arange(frames, dtype=np.float64))
    part = partner_walk(lib, clips, pool, frames, s, rng)
    if part is None:
        return None
    face = normalized(facing_xy(ego.joints.astype(np.float64)).mean(0))
    heading = -rotate_xy(face, float(rng.uniform(-rule.approach_spread, rule.approach_spread)))   # walks at the ego
    miss, away = _line_and_step(heading, rule, rng)
    reach_from = rule.start_m if rule.start_m is not None else tuple(part.speed * t for t in rule.start_s)
    crossing = _crossing_frame(frames, part.speed, reach_from, STEP_AFTER, rng)
    if crossing is None:
        return None
    tc, reach = crossing
    if rule.either_side:
        at = ego.pelvis[tc, :2] + miss * _left(heading)
    else:
        at = ego.pelvis[tc, :2] - float(rng.uniform(*rule.pass_offset)) * away
    partner = moved(part, yaw_of(heading) - yaw_of(part.heading), tc, at)
    dist = np.linalg.norm(ego.pelvis[:, :2] - partner.pelvis[:, :2], axis=1)
    near = np.flatnonzero(dist <= reach)
    if not len(near) or near[0] < MIN_STRAIGHT:
        return None
    ramp = smoothstep((np.arange(frames) - near[0]) / int(rng.integers(rule.duration[0], rule.duration[1] + 1)))
    target = float(rng.uniform(*TARGET_CLEARANCE))
    for amount in np.arange(float(rng.uniform(*STEP_DISTANCE)), rule.step_max + 1e-9, 0.05):
        shift = amount * ramp[:, None] * away
        j = ego.joints.copy()
        j[..., :2] += shift[:, None, :].astype(np.float32)
        if clearance(j, partner.joints) >= target:
            return ego, shift, partner
    return None


def step_aside_copies(lib: ClipLibrary, clips: ClipCache, stands: list[int], partners: dict[bool, WalkPool],
                      seed: int, rule: StepRule = AHEAD_RULE) -> list[NewClip]:
    """STEP_COPIES step-aside copies (and their partner clips) of each calm standing clip of `stands`, made by
    `rule`; the walking partners come from `partners` on the clip's side of the split."""
    out: list[NewClip] = []
    for s in stands:
        rng = np.random.default_rng([seed, int(s), 22])
        pool = partners[lib.is_held_out(s)]
        for k in range(STEP_COPIES):
            for _ in range(ATTEMPTS):
                got = _step_one(lib, clips, s, pool, rng, rule)
                if got is not None:
                    ego, shift, partner = got
                    pel = ego.pelvis.copy()
                    pel[:, :2] += shift.astype(pel.dtype)
                    name = copy_name(lib, s, "stepaside", k)
                    caption = step_caption(lib.captions[s]) if rule.prefix_caption else lib.captions[s]
                    out += [new_clip(lib, s, name, caption, ego.rotations, pel),
                            new_clip(lib, partner.source, partner_clip_name(name), lib.captions[partner.source],
                                     partner.rotations, partner.pelvis, ego=False)]
                    break
    return out
