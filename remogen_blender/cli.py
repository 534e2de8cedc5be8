"""`blender -b -c remogen bake ...` (registered with bpy.utils.register_cli_command) and the same for batch.py.

`cli_main(argv) -> int` parses its own arguments and opens the .blend itself when given `--blend`, so it
behaves the same whether Blender loaded a file before the command runs or not. Ctrl-C (SIGINT) or SIGTERM
stops a bake between two model frames: exit status 130 or 143, and no output file. The output is written
under a temporary name and renamed only once complete.
"""
from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import sys
import time
from typing import Iterator, Sequence

from .properties import GUIDANCE_MAX, SEED_MAX

USAGE_EXAMPLE = ('remogen bake --blend scene.blend --partner Partner --scene-collection Props --goal Goal '
                 '--text "walk to the person and wave" --alpha-hhi 1 --alpha-hsi 0.5 --frames 1 240 --seed 0 '
                 '--output out.blend')


class _Parser(argparse.ArgumentParser):
    """Argument errors as one line (argparse prints the whole usage first)."""

    def error(self, message: str) -> None:   # type: ignore[override]
        print(f"{self.prog}: error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(2)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="remogen", description="ReMoGen reactive motion for Blender, headless",
                                epilog="example: " + USAGE_EXAMPLE)
    sub = p.add_subparsers(dest="command", required=True)
    b = sub.add_parser("bake", help="generate the ego's reaction for a frame range into a new action")
    b.add_argument("--blend", help=".blend file to open (default: the file Blender has open)")
    b.add_argument("--scene", help="scene name (default: the active scene)")
    b.add_argument("--partner", help="partner armature object (default: the one set in the file)")
    b.add_argument("--scene-collection", help="collection of scene meshes (default: the one set in the file)")
    b.add_argument("--goal", help="goal object (default: the one set in the file)")
    b.add_argument("--ego", help="ego armature (default: the file's; created when there is none, unless the "
                                 "file's target rig is posed alone)")
    b.add_argument("--text", help="intent text")
    b.add_argument("--alpha-hhi", type=float, help="partner influence 0..1")
    b.add_argument("--alpha-hsi", type=float, help="scene influence 0..1")
    b.add_argument("--guidance", type=float, help=f"classifier-free guidance 0..{GUIDANCE_MAX:g}")
    b.add_argument("--seed", type=int, help=f"random seed 0..{SEED_MAX}")
    b.add_argument("--fwsr", dest="fwsr", action="store_true", default=None, help="frame-wise refinement on")
    b.add_argument("--no-fwsr", dest="fwsr", action="store_false", help="frame-wise refinement off")
    b.add_argument("--plant-feet", dest="plant_feet", action="store_true", default=None,
                   help="keep planted feet fixed (leg IK; the default)")
    b.add_argument("--no-plant-feet", dest="plant_feet", action="store_false", help="leave the feet as generated")
    b.add_argument("--control", dest="control", action="store_true", default=None,
                   help="test-time control: steer around the partner and obstacles, to the goal (the default)")
    b.add_argument("--no-control", dest="control", action="store_false", help="the learned model alone")
    b.add_argument("--frames", type=int, nargs=2, metavar=("START", "END"), help="frame range (default: scene's)")
    b.add_argument("--model", help="model file (default: the preferences', else the shipped weights)")
    b.add_argument("--threads", type=int, default=1,
                   help="CPU threads for PyTorch (default 1, fastest for the default model; 0: PyTorch's choice)")
    b.add_argument("--output", required=True, help=".blend to save the result to")
    return p


def _err(msg: str) -> int:
    print(f"remogen: error: {' '.join(msg.split())}", file=sys.stderr)
    return 1


class _Signals:
    """SIGINT / SIGTERM noted (not acted on at once) so the bake stops cleanly between model frames."""

    EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}   # 128 + the signal number, as shells report it

    def __init__(self) -> None:
        self.received: int | None = None
        self.count = 0          # a second Ctrl-C can mean "now"

    def __call__(self, signum: int, _frame) -> None:
        self.received = signum
        self.count += 1

    def requested(self) -> bool:
        return self.received is not None

    def exit_code(self) -> int:
        return self.EXIT.get(self.received, 128 + int(self.received or 0))


@contextlib.contextmanager
def _stop_on_signals() -> Iterator[_Signals]:
    sig = _Signals()
    old = {}
    try:
        for s in sig.EXIT:
            old[s] = signal.signal(s, sig)
    except ValueError:   # not the main thread: signals stay as they are
        pass
    try:
        yield sig
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def partial_files(out: str, pid: int) -> tuple[str, str]:
    """The temporary file the process `pid` saves `out` under, and Blender's backup of it."""
    tmp = os.path.join(os.path.dirname(out), f".{os.path.basename(out)}.{pid}.partial.blend")
    return tmp, tmp + "1"


def remove_partial_files(out: str, pid: int) -> None:
    for leftover in partial_files(out, pid):
        with contextlib.suppress(FileNotFoundError):
            os.remove(leftover)


def _save_output(bpy, out: str, sig: _Signals) -> None:
    """Save a copy to `out` through a temporary file: `out` appears only complete, never after a signal."""
    tmp = partial_files(out, os.getpid())[0]
    try:
        bpy.ops.wm.save_as_mainfile(filepath=tmp, copy=True)
        if not sig.requested():
            os.replace(tmp, out)
    finally:
        remove_partial_files(out, os.getpid())


def cli_main(argv: Sequence[str]) -> int:
    try:
        args = _parser().parse_args(list(argv))
    except SystemExit as exc:   # argparse already printed the error or the help
        return int(exc.code or 0)
    if args.command == "bake":
        with _stop_on_signals() as sig:
            return _bake(args, sig)
    return _err(f"unknown command {args.command!r}")


def _cancelled(sig: _Signals, what: str) -> int:
    name = signal.Signals(sig.received).name
    print(f"remogen: {name}: {what}; no output file was written", file=sys.stderr)
    return sig.exit_code()


def _bake(args: argparse.Namespace, sig: _Signals) -> int:
    import bpy
    from . import rig
    from ._runtime import get_model, remogen_errors
    from .bake import BakeCancelled, bake

    try:
        errors = (ReferenceError, *remogen_errors())
    except Exception as exc:  # noqa: BLE001 - torch broken in some unexpected way
        return _err(str(exc))
    if args.blend:
        if not os.path.isfile(args.blend):
            return _err(f"no .blend file at '{args.blend}'")
        try:
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        except RuntimeError as exc:
            return _err(f"cannot open '{args.blend}': {str(exc).strip().splitlines()[-1]}")
    if args.scene and args.scene not in bpy.data.scenes:
        return _err(f"no scene '{args.scene}' in the file")
    scene = bpy.data.scenes[args.scene] if args.scene else bpy.context.scene
    if bpy.context.window is not None and bpy.context.window.scene != scene:
        bpy.context.window.scene = scene
    st = scene.remogen
    try:
        _apply(args, scene, st)
        model = get_model(path=args.model or None, threads=args.threads)
        if st.ego is None and not (st.target is not None and st.target_mode == 'TARGET'):   # target alone: no ego
            st.ego = rig.create_ego(bpy.context, location=tuple(scene.cursor.location))
        f0, f1 = args.frames if args.frames else (scene.frame_start, scene.frame_end)
        t0 = time.perf_counter()
        last = [-1]

        def progress(k: int, n: int) -> None:
            pct = 100 * k // n
            if pct // 10 != last[0]:
                last[0] = pct // 10
                print(f"remogen: baking {pct}%", flush=True)

        res = bake(scene, f0, f1, model=model, progress=progress, cancelled=sig.requested)
    except BakeCancelled as exc:
        return _cancelled(sig, str(exc))
    except errors as exc:
        return _err(str(exc))
    if sig.requested():
        return _cancelled(sig, "stopped before saving")
    out = os.path.abspath(bpy.path.abspath(args.output))
    try:
        _save_output(bpy, out, sig)
    except RuntimeError as exc:
        return _err(f"cannot save '{out}': {str(exc).strip().splitlines()[-1]}")
    if sig.requested():
        return _cancelled(sig, "stopped while saving")
    print(f"remogen: baked frames {f0}-{f1} ({res.model_frames} model frames, {res.model_fps:.0f}/s, "
          f"{time.perf_counter() - t0:.1f} s) into action {', '.join(repr(a.name) for _ob, a, _old in res.keyed)}; "
          f"saved {out}")
    return 0


def _apply(args: argparse.Namespace, scene, st) -> None:
    """Copy command-line settings into scene.remogen, checking names first."""
    import bpy
    from ._runtime import UserError

    def obj(name: str, what: str, armature: bool = False):
        ob = bpy.data.objects.get(name)
        if ob is None:
            raise UserError(f"no object '{name}' for {what} in the file")
        if armature and ob.type != 'ARMATURE':
            raise UserError(f"{what} '{name}' is a {ob.type.lower()}, not an armature")
        return ob

    if args.partner:
        st.partner = obj(args.partner, "--partner", armature=True)
    if args.ego:
        st.ego = obj(args.ego, "--ego", armature=True)
    if args.goal:
        st.goal = obj(args.goal, "--goal")
    if args.scene_collection:
        coll = bpy.data.collections.get(args.scene_collection)
        if coll is None:
            raise UserError(f"no collection '{args.scene_collection}' in the file")
        st.scene_collection = coll
    if args.text is not None:
        st.text = args.text
    for name in ("alpha_hhi", "alpha_hsi"):
        v = getattr(args, name)
        if v is not None:
            if not 0.0 <= v <= 1.0:   # NaN fails this too
                raise UserError(f"--{name.replace('_', '-')} must be between 0 and 1, got {v}")
            setattr(st, name, v)
    if args.guidance is not None:
        if not (math.isfinite(args.guidance) and 0.0 <= args.guidance <= GUIDANCE_MAX):
            raise UserError(f"--guidance must be between 0 and {GUIDANCE_MAX:g}, got {args.guidance}")
        st.guidance = args.guidance
    if args.seed is not None:
        if not 0 <= args.seed <= SEED_MAX:
            raise UserError(f"--seed must be between 0 and {SEED_MAX} (a 32-bit seed), got {args.seed}")
        st.seed = args.seed
    if args.fwsr is not None:
        st.use_fwsr = args.fwsr
    if args.plant_feet is not None:
        st.use_foot_lock = args.plant_feet
    if args.control is not None:
        st.use_control = args.control
