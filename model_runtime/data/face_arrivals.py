"""Face-an-arrival copies for the HHI stage (`<source>#greeted<k>`): someone walks up to a standing ego and stops
in front of it; the ego makes room while they come on, then turns to face them.

Why: in the step-aside copies a partner who walks at a standing ego always passes by, so a module trained on more
of them (data/avoidance.py YIELD_RULE) also stepped away from a partner who slows down and stops in front of it,
and ended turned away from them (the approach family of the behaviour suite, val, control off: 52-67 deg off
facing against 41.5 before). Here a walker coming on at its pace is made room for, as in the step-aside copies,
and once it has stopped it is faced: the two kinds agree on what to do at each moment.

The partner is a straight stretch of a real walk (2-3.5 s) slowed to rest in a calm real standing clip
(`detours.come_to_rest`, as the arrival copies), moved rigidly so that it walks straight at the ego's spot from
any direction and stops ARRIVE_DISTANCE from it, facing it. The ego is a calm real standing clip shifted
ROOM_DISTANCE to the walker's right over ROOM_FRAMES, starting ROOM_START_S before the walker would reach its spot
at the pace it came on at (the feet slide, as in the step-aside copies), then turned on the spot
(`turns.pivot_turn`, at the pivot copies' pace) toward where the walker stopped; a walker that stops within
FACING_ALREADY of the ego's facing is not turned to. The copy keeps the standing clip's caption (the module, not
the text, reacts to the partner), licence and held-out split; its partner is stored as a clip
(`new_clips.partner_clip_name`) that the pair builder (pairs.hhi, kind face_arrival) checks again on its FK joints.
Only the "yield" and "keepright" window recipes make these copies; the shipped recipe does not.
"""
from __future__ import annotations

import numpy as np

from .detours import BLEND_FRAMES, SLOW_IN, STAND_FRAMES, walk_to_rest
from .geometry import normalized
from .library import ClipLibrary
from .new_clips import NewClip, copy_name, new_clip, partner_clip_name
from .pairs import FPS, ClipCache, facing_xy, pose_joints
from .stretches import WalkPool, clearance, rotate_xy, yaw_of
from .turns import pivot_turn, smoothstep, turn_duration, turn_profile

WALK_FRAMES = (20, 35)               # frames of the partner's walk before it slows to rest
ARRIVE_DISTANCE = (0.9, 1.5)         # m from the ego's pelvis to where the partner stops
FACING_ALREADY = np.radians(15.0)    # a partner stopping within this of the ego's facing is not turned to
MIN_CLEARANCE = 0.35                 # m between any two joints at every frame
ROOM_START_S = (1.5, 2.5)            # s before the walker would reach the ego's spot at its pace: the ego steps aside
ROOM_FRAMES = (6, 10)                # frames the step takes (inclusive)
ROOM_DISTANCE = (0.4, 0.7)           # m sideways
AFTER_TURN = 4                       # frames the copy keeps after the turn ends, at least
AT_REST = 8                          # frames the copy keeps after the partner has come to rest, at least
COPIES = 1                           # per calm standing clip
ATTEMPTS = 6


def arriving_partner(lib: ClipLibrary, clips: ClipCache, walks: WalkPool, stands: list[int], not_source: int,
                     rng: np.random.Generator) -> tuple[int, np.ndarray, np.ndarray, int] | None:
    """(walk clip, rotations, pelvis, the frame it comes to rest) of a real straight walk slowed to rest, or None."""
    walk = int(rng.integers(WALK_FRAMES[0], WALK_FRAMES[1] + 1))
    src = walks.pick(rng, walk + 2, not_source)
    got = walk_to_rest(lib, clips, src, walk, stands, rng) if src is not None else None
    if got is None:
        return None
    rot, pel, start, stop = got
    return src, rot, pel, stop - start + SLOW_IN - 1     # the last frame of the slowed walk (detours.slow_to_rest)


def _greeted_one(lib: ClipLibrary, clips: ClipCache, s: int, walks: WalkPool, stands: list[int],
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, np.ndarray] | None:
    """(ego rotations, ego pelvis, partner's walk clip, partner rotations, partner pelvis) for standing clip s."""
    got = arriving_partner(lib, clips, walks, stands, s, rng)
    if got is None:
        return None
    src, p_rot, p_pel, rest = got
    frames = min(len(p_pel), lib.frames(s))           # the partner's standing clip is cut to the ego's length
    if frames < rest + AT_REST:
        return None
    p_rot, p_pel = p_rot[:frames], p_pel[:frames]
    start = int(rng.integers(0, lib.frames(s) - frames + 1))
    a = int(lib.offsets[s]) + start
    e_rot, e_pel = lib.rotations[a:a + frames], lib.pelvis[a:a + frames]
    e_joints = clips.joints(s)[start:start + frames].astype(np.float64)
    face = normalized(facing_xy(e_joints[:3]).mean(0))
    off = float(rng.uniform(-np.pi, np.pi))                       # where the partner comes from, off facing
    toward = rotate_xy(face, off)
    spot = e_pel[0, :2].astype(np.float64)
    # move the partner: walking along -toward, its pelvis at rest ARRIVE_DISTANCE out along toward
    heading = normalized(p_pel[rest, :2].astype(np.float64) - p_pel[0, :2])
    p_rot, p_pel = pivot_turn(p_rot, p_pel, np.full(frames, yaw_of(-toward) - yaw_of(heading)))
    at = spot + float(rng.uniform(*ARRIVE_DISTANCE)) * toward
    p_pel = p_pel.copy()
    p_pel[:, :2] = (p_pel[:, :2] + (at - p_pel[rest, :2])).astype(p_pel.dtype)
    p_joints = pose_joints(p_rot, p_pel)
    dist = np.linalg.norm(p_joints[:, 0, :2] - spot, axis=1)
    # step off its line (to its right) while it still comes on at its pace, as a step-aside copy does
    pace = float(np.linalg.norm(p_pel[5, :2] - p_pel[0, :2])) * FPS / 5.0
    near = np.flatnonzero(dist <= pace * float(rng.uniform(*ROOM_START_S)))
    length = int(rng.integers(ROOM_FRAMES[0], ROOM_FRAMES[1] + 1))
    if not len(near) or near[0] < 2:
        return None
    right = np.array([-toward[1], toward[0]])            # the walker's right (it walks along -toward)
    shift = float(rng.uniform(*ROOM_DISTANCE)) * smoothstep((np.arange(frames) - near[0]) / length)[:, None] * right
    # then turn to face where it stopped, once the step is done and it has (nearly) come to rest
    to_partner = p_pel[rest, :2].astype(np.float64) - (spot + shift[-1])
    angle = float(np.arctan2(face[0] * to_partner[1] - face[1] * to_partner[0], face @ to_partner))
    if abs(angle) >= FACING_ALREADY:
        turn_from = max(int(near[0]) + length, rest - 2)
        if turn_from + int(np.ceil(turn_duration(angle))) + AFTER_TURN > frames:
            return None
        e_rot, e_pel = pivot_turn(e_rot, e_pel, turn_profile(frames, turn_from, angle))
    e_pel = e_pel.copy()
    e_pel[:, :2] = (e_pel[:, :2] + shift).astype(e_pel.dtype)
    if clearance(pose_joints(e_rot, e_pel).astype(np.float32), p_joints.astype(np.float32)) < MIN_CLEARANCE:
        return None
    return e_rot, e_pel, src, p_rot, p_pel


def face_arrival_copies(lib: ClipLibrary, clips: ClipCache, stands: list[int], walks: dict[bool, WalkPool],
                        rest: dict[bool, list[int]], seed: int) -> list[NewClip]:
    """COPIES face-an-arrival copies (and their partner clips) of each calm standing clip of `stands`; the partner's
    walk comes from `walks` and the standing clip it stops in from `rest`, both on the clip's side of the split."""
    out: list[NewClip] = []
    long_enough = STAND_FRAMES[1] + BLEND_FRAMES                 # what come_to_rest cuts from a standing clip
    rest = {side: [i for i in pool if lib.frames(i) >= long_enough] for side, pool in rest.items()}
    for s in stands:
        rng = np.random.default_rng([seed, int(s), 25])
        side = lib.is_held_out(s)
        if not rest[side]:
            continue
        for k in range(COPIES):
            for _ in range(ATTEMPTS):
                got = _greeted_one(lib, clips, s, walks[side], rest[side], rng)
                if got is not None:
                    e_rot, e_pel, src, p_rot, p_pel = got
                    name = copy_name(lib, s, "greeted", k)
                    out += [new_clip(lib, s, name, lib.captions[s], e_rot, e_pel),
                            new_clip(lib, src, partner_clip_name(name), lib.captions[src], p_rot, p_pel, ego=False)]
                    break
    return out
