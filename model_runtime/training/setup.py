"""What a stage needs before its first step: a library that can train at all, feature statistics, the
samplers (with generated partners and scenes for the interaction stages) and the decoder's sensitivity."""
from __future__ import annotations

import copy
import functools
import importlib
from typing import Callable

import torch

from ..config import ModelConfig
from ..data.library import ClipLibrary
from ..errors import RemogenError
from ..model import ReMoGenModel
from .recipe import MIRROR_STAGES, WINDOW_RECIPES, WindowRecipe
from .samples import SegmentSampler


def fit_stats(model: ReMoGenModel, lib: ClipLibrary, clip_ids: list[int], samples: int = 20000, seed: int = 0) -> None:
    """Feature mean/std from canonicalised training segments (computed once, reused by every later stage)."""
    from ..features import canonicalize
    gen = torch.Generator().manual_seed(seed)
    cfg = model.cfg
    span = cfg.history + cfg.future
    ids = [i for i in clip_ids if lib.frames(i) - 1 >= span]
    rows = []
    per = max(1, samples // max(1, len(ids)))
    for i in ids:
        feats = lib.features(i)
        # all of a clip's windows canonicalised in one batch (one call per window took minutes on a large library)
        starts = torch.randint(0, feats.shape[0] - span + 1, (per,), generator=gen)
        rows.append(canonicalize(feats[starts[:, None] + torch.arange(span)])[0].reshape(-1, feats.shape[-1]))
    model.stats.fit(torch.cat(rows))


def check_library(lib: ClipLibrary, cfg: ModelConfig) -> None:
    """Fail at once, before minutes of set-up, when the library cannot give training and held-out segments."""
    need = cfg.history + cfg.future + 1
    if len(lib) < 2:
        raise RemogenError(f"the clip library has {len(lib)} clip{'' if len(lib) == 1 else 's'}; training needs at "
                           "least 2 (one is held out for validation): add motion files and run "
                           "python -m model_runtime.data.prepare again")
    train_ids, val_ids = lib.split("train", min_frames=need), lib.split("val", min_frames=need)
    if not train_ids or not val_ids:
        raise RemogenError(f"training needs a training clip and a held-out clip of at least {need} frames "
                           f"({need / 10:g} s at 10 fps); the library has {len(train_ids)} and {len(val_ids)}: "
                           "add longer clips")


def _derive(lib, train_ids: list[int], val_ids: list[int], derive: Callable, seed: int):
    """Add derived clips made from both splits; each joins its source clip's split. Returns (library, train ids,
    held-out ids, number of derived clips)."""
    lib, derived = derive(lib, train_ids + val_ids, seed=seed)
    train_ids = train_ids + [i for i in derived if not lib.is_held_out(i)]
    val_ids = val_ids + [i for i in derived if lib.is_held_out(i)]
    return lib, train_ids, val_ids, len(derived)


def _hhi_copies(windows: WindowRecipe) -> Callable:
    """The derivation that adds the HHI copies of real clips (data/hhi_copies.py) as the recipe makes them."""
    from ..data.avoidance import STEP_RULES
    from ..data.hhi_copies import add_hhi_copies
    return functools.partial(add_hhi_copies, step_rule=STEP_RULES[windows.step_aside_rule],
                             face_arrivals=windows.face_arrivals, walk_aside=windows.walk_aside)


def _chain(*derives: Callable) -> Callable:
    """One derivation that runs `derives` in turn, each on the clips given (real ones: the derived clips of one
    are never the sources of the next), and returns the library with all their copies."""
    def derive(lib, clip_ids: list[int], seed: int = 0):
        new: list[int] = []
        for d in derives:
            lib, made = d(lib, clip_ids, seed=seed)
            new += made
        return lib, new
    return derive


def _derive_then_build(lib, train_ids: list[int], val_ids: list[int], derive: Callable, build: Callable, seed: int):
    """Add derived clips (each joins its source clip's split), then build the stage's pairs or scenes for
    both splits. Returns (library, train ids, held-out ids, built for training, built for held-out)."""
    lib, train_ids, val_ids, _ = _derive(lib, train_ids, val_ids, derive, seed)
    return lib, train_ids, val_ids, build(lib, train_ids, seed=seed), build(lib, val_ids, seed=seed + 1)


# The copies a window recipe adds to a stage, in the order they are made: (WindowRecipe field naming the stages,
# module, function, what the set-up note calls them). The start-up copies come last so that some set off into the
# reversed walks (setting off backwards); they leave the slowed walks out (data/startups.py STARTUP_NUMBER).
RECIPE_COPIES = (
    # forward walks played backwards: too few real backward walks to learn the caption from
    ("reversal_stages", "..data.reversals", "add_reversals", "reversed copies of forward walks (walking backwards)"),
    # forward walks played slower: captions hardly ever say how fast a walk goes
    ("slowed_walk_stages", "..data.slowed_walks", "add_slowed_walks",
     "slowed copies of forward walks (walking slowly)"),
    # standing, then setting off: no clip starts from standing, every ego does
    ("startup_stages", "..data.startups", "add_startups", "start-up copies (standing, then setting off)"),
)


def build_samplers(stage: str, model: ReMoGenModel, lib: ClipLibrary, seed: int, rank: int,
                   note: Callable[[str], None] = lambda msg: None, mirror: bool = True,
                   windows: WindowRecipe = WINDOW_RECIPES["captured"]
                   ) -> tuple[SegmentSampler, SegmentSampler | None]:
    """Training and validation samplers for a stage (interaction stages get generated pairs/scenes); no
    validation sampler (None) when no held-out clip fits the stage's pair rules. `windows`: how the training
    windows are drawn and captioned (the held-out ones keep the captured recipe, so losses stay comparable)."""
    train_ids, val_ids = lib.split("train"), lib.split("val")
    if mirror and stage in MIRROR_STAGES:
        # mirrored copies first: the derivations below then see real clips only, as before (data/mirror.py)
        from ..data.mirror import add_mirrors
        lib, train_ids, val_ids, n = _derive(lib, train_ids, val_ids, add_mirrors, seed)
        note(f"{n} mirrored copies of real clips")
    for stages, module, derive, what in RECIPE_COPIES:
        if stage in getattr(windows, stages):
            lib, train_ids, val_ids, n = _derive(lib, train_ids, val_ids,
                                                 getattr(importlib.import_module(module, __package__), derive), seed)
            note(f"{n} {what}")
    pairs_tr = pairs_va = scenes_tr = scenes_va = None
    if stage in windows.hhi_copy_stages and stage not in ("hhi", "fwsr"):
        # the HHI stage's copies of real clips as plain motion (no partner): the decoder learns to render them
        lib, train_ids, val_ids, n = _derive(lib, train_ids, val_ids, _hhi_copies(windows), seed)
        note(f"{n} HHI copies (turned, avoiding, stepping aside, stopping, following)")
    if stage in ("hhi", "fwsr"):
        from ..data.pairs import build_hhi_pairs
        note(f"building partners for {len(train_ids) + len(val_ids)} clips (turned, avoiding, stepping-aside, "
             "stopping and following copies of real clips, then HHI pairs) ...")
        # copies of real clips for what the data has no example of: a turn on the spot, getting out of a walker's
        # way, stopping at someone, following someone (data/hhi_copies.py)
        lib, train_ids, val_ids, pairs_tr, pairs_va = _derive_then_build(lib, train_ids, val_ids, _hhi_copies(windows),
                                                                         build_hhi_pairs, seed)
        note(f"{len(pairs_tr)} training and {len(pairs_va)} held-out HHI pairs")
        if not pairs_tr:
            raise RemogenError(f"no training clip fits an HHI pair rule (walks, turns, gestures, standing clips), so "
                               f"the {stage} stage cannot train on this library; the stages before it are saved")
    if stage == "hsi":
        from ..data.detours import add_arrivals
        from ..data.pairs import build_hsi_scenes
        from ..data.turn_arrivals import add_turn_arrivals
        turns = stage in windows.turn_arrival_stages
        copies = "detour and turn-then-walk copies" if turns else "detour copies"
        note(f"building scenes for {len(train_ids) + len(val_ids)} clips ({copies} of straight walks, then "
             "obstacles and goals) ...")
        # detour-and-stop copies of straight walks: the data has no stop at a target, no walk around anything
        derive = add_arrivals
        if turns:
            # and turning on the spot toward a goal beside or behind, then walking there (data/turn_arrivals.py)
            derive = _chain(add_arrivals, add_turn_arrivals)
        lib, train_ids, val_ids, scenes_tr, scenes_va = _derive_then_build(lib, train_ids, val_ids, derive,
                                                                           build_hsi_scenes, seed)
        note(f"{len(scenes_tr)} training and {len(scenes_va)} held-out HSI scenes")
    # the samplers keep a CPU copy of the statistics: the model itself may move to a GPU after this
    stats = copy.deepcopy(model.stats).cpu()
    # caption balance and head shares for the training windows only: held-out losses stay comparable across recipes
    tr = SegmentSampler(lib, train_ids, model.cfg, stats, seed=seed * 1000 + rank, pairs=pairs_tr,
                        scenes=scenes_tr, caption_balance_power=windows.caption_balance if stage == "prior" else 0.0,
                        head_shares=windows.head_shares if stage in windows.head_share_stages else (),
                        still_share=windows.still_share, slow_walk_share=windows.slow_walk_share,
                        wider_phrasings=windows.wider_phrasings,
                        setoff_share=windows.setoff_share if stage == "hhi" else 0.0,
                        kind_weights={"slowed": windows.slowed_walk_weight}, path_tail_share=windows.path_tail_share)
    if pairs_va == [] or scenes_va == []:
        note(f"note: no held-out clip fits the {stage} stage's rules: it trains without a held-out loss")
        return tr, None
    va = SegmentSampler(lib, val_ids, model.cfg, stats, seed=seed + 7, pairs=pairs_va, scenes=scenes_va)
    return tr, va


def decoder_sensitivity(model: ReMoGenModel, lib: ClipLibrary, seed: int) -> None:
    """Finite-difference decoder sensitivity on real training segments (stored in the checkpoint)."""
    s = SegmentSampler(lib, lib.split("train"), model.cfg, model.stats, seed=seed)
    b = s.sample(32)
    with torch.no_grad():
        z, _ = model.vae.encode(b.hist, b.fut)
    model.compute_decoder_sensitivity(b.hist, z)
