"""Every derived clip the HHI stage trains on, in one derivation (`add_hhi_copies`):

    turn        turned copies of standing clips (data/turns.py)
    avoid       straight walks bent around a crossing or oncoming real walker (data/avoidance.py)
    stepaside   calm standing clips stepping off a real walker's line (data/avoidance.py)
    arriveface  straight walks slowed to rest into a calm standing clip, for a partner ahead (data/meeting.py)
    follow      straight walks re-timed to follow a real walker (data/following.py)
    greeted     calm standing clips turning to face a real walker who walks up and stops (data/face_arrivals.py),
                only where asked for (`face_arrivals`)
    walkaside   calm standing clips turning and walking a few real steps out of a walker's way (data/walk_aside.py),
                only where asked for (`walk_aside`), in place of the stepaside copies

Only real clips are copied (a mirrored copy is no source; the random sides and angles cover both ways). Each
copy keeps its source's held-out split and licence; partners and the standing clips a stop ends in are taken
from clips of the same split.
"""
from __future__ import annotations

from .avoidance import AHEAD_RULE, STEP_FRAMES, StepRule, avoid_copies, step_aside_copies
from .face_arrivals import face_arrival_copies
from .following import follow_copies
from .library import ClipLibrary, is_derived
from .meeting import MIN_STAND, arrive_face_copies
from .new_clips import extend_library
from .pairs import ClipCache
from .stretches import WalkPool, by_split, calm_standing, walks
from .turns import add_pivot_turns
from .walk_aside import walk_aside_copies, walk_aside_stands


def add_hhi_copies(lib: ClipLibrary, clip_ids: list[int], seed: int = 0, step_rule: StepRule = AHEAD_RULE,
                   face_arrivals: bool = False, walk_aside: bool = False) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus the HHI copies of the clips of `clip_ids` (with their partner clips). Returns
    (library, indices of the copies that are egos). Deterministic for a seed; a clip's copies do not depend on
    which other clips are in `clip_ids` (partners come from all of `lib`'s real clips); `lib`'s own clips keep
    their indices. `step_rule`: how the step-aside copies are made (data/avoidance.py); `face_arrivals`: also make
    the greeted copies; `walk_aside`: walk-aside copies instead of the stepaside ones."""
    lib, turned = add_pivot_turns(lib, clip_ids, seed=seed)
    real = [i for i in range(len(lib)) if not is_derived(lib.names[i])]
    clips = ClipCache(lib, real)       # FK of the real clips only: the copies never start from a derived one
    all_walks = WalkPool.of(clips, walks(lib, clips, real))
    partners = {side: all_walks.split(side) for side in (False, True)}
    own = set(clip_ids)
    egos = all_walks.subset(own)
    step_stands = [i for i in calm_standing(lib, clips, real, STEP_FRAMES[0]) if i in own]
    end_stands = by_split(lib, calm_standing(lib, clips, real, MIN_STAND))
    making_room = (walk_aside_copies(lib, clips, egos, partners, walk_aside_stands(lib, clips, real), seed)
                   if walk_aside else step_aside_copies(lib, clips, step_stands, partners, seed, step_rule))
    new = (avoid_copies(lib, clips, egos, partners, seed)
           + making_room
           + arrive_face_copies(lib, clips, egos, end_stands, seed)
           + follow_copies(lib, clips, egos, partners, seed))
    if face_arrivals:
        new += face_arrival_copies(lib, clips, step_stands, partners, end_stands, seed)
    lib, copies = extend_library(lib, new)
    return lib, turned + copies
