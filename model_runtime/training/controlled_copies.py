"""Copies of the runtime's own reactions under test-time control, for the HHI stage to learn without it.

With test-time control on, the runtime keeps clear of a walker crossing the ego's path and faces one who walks up
and stops (the behaviour suite's crossing and approach families); the HHI module alone keeps clear far less often,
most of all for a standing ego. These copies are what the controlled runtime did in such encounters, so that the
module can learn the reaction the control made. Unlike the step-aside copies (data/avoidance.py: a standing clip
slid sideways), the motion is the model's own, so the decoder can render it.

Each copy is one encounter drawn as the behaviour suite draws its own, but from its own generator seed (never the
suite's val or test seeds) and with a partner taken from a real walk of the library's training side instead of
the suite's walk:
- crossing (`<walk>#ctlavoid<k>`, pair kind avoid_walker): the ego stands or walks forward from the origin facing
  -Y; a walker at 0.8-1.6 m/s from any direction passes within 0.3 m of where the ego would be after 2.5 s; 5 s.
- approach (`<walk>#ctlgreeted<k>`, pair kind face_arrival; `approach_share` of the draws): a walker from any
  direction walks straight at the standing ego and comes to rest 0.9-1.5 m from it (a real walk slowed into a
  real standing clip, data/face_arrivals.arriving_partner); 3 s more.
The ego is rolled out by a ReactionSession with control, FWSR and cleanup on, alpha 1; a rollout is kept when it
keeps pairs.hhi.AVOID_CLEARANCE from the walker at every frame. The partner is stored as a clip beside the copy,
and both fall on the training side with the walk they come from. The ego's motion comes from the model, so its
dataset tag is the model's licence: "bandai" (non-commercial) when the model file was trained on that data, else
"cmu".

    python -m model_runtime.training.controlled_copies --library CLIPS.npz --out CLIPS_PLUS.npz \\
        [--model FILE] [--episodes N] [--approach-share S] [--seed S] [--control-set NAME=VALUE ...]

writes the library with the copies appended; `python -m model_runtime.train hhi --library CLIPS_PLUS.npz ...`
then trains on them beside the usual pairs, drawn recipe.CONTROLLED_COPY_WEIGHT times as often as their frame
count says.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..behaviour.scenarios import (APPROACH_AFTER, CROSS_FRAMES, CROSS_MISS, CROSS_TIME, FPS, STAND_TEXT, WALK_TEXT,
                                   Episode, crossing_point)
from ..data.detours import BLEND_FRAMES, STAND_FRAMES
from ..data.face_arrivals import ARRIVE_DISTANCE, arriving_partner
from ..data.library import ClipLibrary, non_commercial
from ..data.meeting import MIN_STAND
from ..data.new_clips import NewClip, copy_name, extend_library, new_clip, partner_clip_name
from ..data.pairs import ClipCache
from ..data.pairs.clips import pose_joints
from ..data.pairs.hhi import AVOID_CLEARANCE
from ..data.stretches import WalkPool, calm_standing, clearance, moved, partner_walk, rotate_xy, walks, yaw_of
from ..data.turns import pivot_turn

if TYPE_CHECKING:
    from ..control import ControlConfig
    from ..model import ReMoGenModel

KIND = "ctlavoid"            # a crossing walker (pair kind avoid_walker)
APPROACH_KIND = "ctlgreeted"  # a walker who comes up and stops (pair kind face_arrival)
SEED = 3003                  # the suite's splits draw from 1001 (val) and 2002 (test)
CROSS_FRAME = int(round(CROSS_TIME * FPS))           # the frame the walker passes where the ego should be
AFTER_ARRIVAL = int(round(APPROACH_AFTER * FPS))     # frames an approach copy goes on once the walker rests


@dataclass
class Encounter:
    """One drawn episode: its kind of copy, the ego's prompt and noise seed, and the walker placed in the world."""
    kind: str                    # KIND or APPROACH_KIND
    text: str
    seed: int
    source: int                  # library index of the walker's real walk
    rotations: np.ndarray        # (T, 22, 4) the walker's pose
    pelvis: np.ndarray           # (T, 3)
    joints: np.ndarray           # (T, 22, 3)

    @property
    def frames(self) -> int:
        return len(self.pelvis)


def draw_crossing(lib: ClipLibrary, clips: ClipCache, pool: WalkPool, rng: np.random.Generator) -> Encounter | None:
    """A crossing as the behaviour suite draws them, the walker a real walk of `pool`; None when no walk fits."""
    walks_forward = bool(rng.integers(2))
    heading = rng.uniform(0.0, 2.0 * math.pi)
    offset = rng.uniform(0.0, CROSS_MISS) * rng.choice((-1.0, 1.0))
    seed = int(rng.integers(2 ** 31))
    part = partner_walk(lib, clips, pool, CROSS_FRAMES, -1, rng)
    if part is None:
        return None
    at = crossing_point(walks_forward, heading, offset)
    p = moved(part, heading - yaw_of(part.heading), CROSS_FRAME, at)
    return Encounter(KIND, WALK_TEXT if walks_forward else STAND_TEXT, seed, p.source, p.rotations, p.pelvis,
                     p.joints)


def draw_approach(lib: ClipLibrary, clips: ClipCache, pool: WalkPool, stands: list[int], rng: np.random.Generator
                  ) -> Encounter | None:
    """A walker from any direction walks straight at the standing ego (facing -Y at the origin) and comes to rest
    ARRIVE_DISTANCE from it, as the suite's approach family (the walk a real one slowed into a real standing clip,
    data/face_arrivals.arriving_partner); None when no walk fits."""
    off = rng.uniform(-math.pi, math.pi)                 # where the walker comes from, off the ego's facing
    stop = rng.uniform(*ARRIVE_DISTANCE)
    seed = int(rng.integers(2 ** 31))
    got = arriving_partner(lib, clips, pool, stands, -1, rng)
    if got is None:
        return None
    src, rot, pel, rest = got
    frames = min(len(pel), rest + AFTER_ARRIVAL)
    rot, pel = rot[:frames], pel[:frames]
    toward = rotate_xy(np.array([0.0, -1.0]), off)
    heading = pel[rest, :2].astype(np.float64) - pel[0, :2]
    rot, pel = pivot_turn(rot, pel, np.full(frames, yaw_of(-toward) - yaw_of(heading)))
    pel = pel.copy()
    pel[:, :2] = (pel[:, :2] + (stop * toward - pel[rest, :2])).astype(pel.dtype)
    return Encounter(APPROACH_KIND, STAND_TEXT, seed, src, rot, pel, pose_joints(rot, pel).astype(np.float32))


def roll_out(model: "ReMoGenModel", ep: Encounter, control_config: "ControlConfig | None" = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(joints (T, 22, 3), local rotations (T, 22, 4) w-first, pelvis (T, 3)) of the ego, rolled out as the
    behaviour suite rolls out its episodes, with the runtime's defaults (control on; `control_config` None: the
    default settings)."""
    from ..behaviour.suite import roll_out_frames
    frames = roll_out_frames(model, Episode(ep.kind, 0, ep.seed, ep.text, ep.frames, partner=ep.joints), 1.0,
                             control_config=control_config)
    return (np.stack([f.joints for f in frames]), np.stack([f.local_rotations for f in frames]),
            np.stack([f.position for f in frames]))


def model_licence_tag(model: "ReMoGenModel") -> str:
    """The dataset tag of motion the model made: its most restrictive training data."""
    return "bandai" if non_commercial((), model.meta) else "cmu"


def controlled_copies(model: "ReMoGenModel", lib: ClipLibrary, episodes: int, seed: int = SEED,
                      approach_share: float = 0.0, progress: Callable[[int, int], None] = lambda done, kept: None,
                      control_config: "ControlConfig | None" = None) -> tuple[list[NewClip], dict]:
    """Up to `episodes` controlled copies (each with its partner clip): crossings, and walkers who come up and
    stop for `approach_share` of them; and counts of what was drawn. `control_config` pins the test-time control
    the copies are made with (None: the runtime's defaults, which change as the runtime does)."""
    train = lib.split("train")
    clips = ClipCache(lib, train)
    pool = WalkPool.of(clips, walks(lib, clips, train))
    # standing clips a walker can come to rest in (detours.come_to_rest cuts this much of one)
    stands = [i for i in calm_standing(lib, clips, train, MIN_STAND)
              if lib.frames(i) >= STAND_FRAMES[1] + BLEND_FRAMES]
    tag = model_licence_tag(model)
    out: list[NewClip] = []
    counts = {"drawn": 0, "no_walk": 0, "too_close": 0, "kept": 0}
    for k in range(episodes):
        rng = np.random.default_rng([seed, k])
        approach = rng.random() < approach_share
        ep = draw_approach(lib, clips, pool, stands, rng) if approach else draw_crossing(lib, clips, pool, rng)
        counts["drawn"] += 1
        if ep is None:
            counts["no_walk"] += 1
            continue
        joints, rots, pelvis = roll_out(model, ep, control_config)
        if not np.isfinite(joints).all() or clearance(joints, ep.joints) < AVOID_CLEARANCE:
            counts["too_close"] += 1
            progress(k + 1, counts["kept"])
            continue
        if not out:   # the stored pose must give back the joints the runtime showed
            err = float(np.abs(pose_joints(rots, pelvis) - joints).max())
            if err > 1e-3:
                raise RuntimeError(f"a rollout's pose does not reproduce its joints ({err:.4f} m off)")
        name = copy_name(lib, ep.source, ep.kind, k)
        ego = replace(new_clip(lib, ep.source, name, ep.text, rots, pelvis), source=tag)   # the model's licence
        out += [ego, new_clip(lib, ep.source, partner_clip_name(name), lib.captions[ep.source], ep.rotations,
                              ep.pelvis, ego=False)]
        counts["kept"] += 1
        progress(k + 1, counts["kept"])
    return out, counts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.training.controlled_copies",
                                 description="Append copies of the controlled runtime's crossing and approach "
                                             "reactions to a clip library, for the HHI stage.")
    ap.add_argument("--library", required=True, help="the clip library (.npz) to extend")
    ap.add_argument("--out", required=True, help="where to write the extended library (.npz)")
    ap.add_argument("--model", default=None, help="model file whose controlled runtime makes the copies "
                                                  "(default: the shipped weights)")
    ap.add_argument("--episodes", type=int, default=1000, help="encounters to draw (default 1000)")
    ap.add_argument("--approach-share", type=float, default=0.0,
                    help="share of the episodes where the walker comes up and stops instead of crossing (default 0)")
    ap.add_argument("--seed", type=int, default=SEED, help=f"generator seed (default {SEED}; the behaviour "
                                                           "suite's val and test splits use 1001 and 2002)")
    ap.add_argument("--control-set", action="append", default=[], metavar="NAME=VALUE",
                    help="override one test-time control setting the copies are made with (a field of "
                         "model_runtime.ControlConfig); repeatable. To remake copies an earlier runtime made")
    args = ap.parse_args(argv)
    from .. import load_model
    from ..behaviour.control_overrides import control_config_from
    from ..behaviour.scenarios import SPLIT_SEEDS
    from ..errors import RemogenError
    try:
        if args.episodes < 1:
            raise RemogenError(f"--episodes must be at least 1, got {args.episodes}")
        if not 0.0 <= args.approach_share <= 1.0:
            raise RemogenError(f"--approach-share must be in 0..1, got {args.approach_share}")
        if args.seed in SPLIT_SEEDS.values():
            raise RemogenError(f"--seed {args.seed} is a behaviour-suite split's seed; pick another")
        control_config = control_config_from(args.control_set)
        lib = ClipLibrary.load(args.library)
        model = load_model(args.model)
    except (RemogenError, OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    t0 = time.time()

    def progress(done: int, kept: int) -> None:
        if done % 50 == 0 or done == args.episodes:
            print(f"{done}/{args.episodes} episodes, {kept} kept ({time.time() - t0:.0f} s)", file=sys.stderr)

    made, counts = controlled_copies(model, lib, args.episodes, args.seed, args.approach_share, progress,
                                     control_config)
    out, _ = extend_library(lib, made)
    path = out.save(args.out)
    print(f"{counts['kept']} of {counts['drawn']} episodes kept ({counts['too_close']} came within "
          f"{AVOID_CLEARANCE} m, {counts['no_walk']} found no walk); wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
