"""Benchmark of the extension under the `bpy` module; prints one JSON line per measurement.

    python -m remogen_blender.bench [--model PATH | --config default] [--frames 300] [--threads 1] [--no-helper]

- live_tick_ms: one model frame of the live path (read the partner, check/sample the scene grid, step the
  session, interpolate, write the ego pose), timed around FrameDriver.update(); the scene's own
  evaluation (frame_set) is timed separately as frame_set_ms.
- bake_model_fps: model frames per second of a headless bake (frame_set per model frame + keying).
- voxelise_s: extracting the evaluated triangles of a ~100k-triangle collection and building the grid.
Runs as the extension does by default, with each segment's diffusion in the runtime's helper process (timed
once it has started); --no-helper runs it in Blender's process, as with that preference off.
Targets: live tick p50 <= 8 ms with the default model, bake >= 150 model frames/s, voxelisation of
100k triangles <= 2 s.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np


def _emit(**kw) -> None:
    print(json.dumps(kw), flush=True)


def _scene(bpy, n_tri: int):
    from . import rig
    ctx = bpy.context
    scene = ctx.scene
    scene.render.fps = 24
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    # subdivided cubes: 6 * 4^level * 2 triangles each
    level = 5
    per = 6 * 4 ** level * 2
    count = max(1, round(n_tri / per))
    for i in range(count):
        me = bpy.data.meshes.new(f"Prop{i}")
        s = 0.35
        v = [(x, y, z) for x in (-s, s) for y in (-s, s) for z in (0.0, 2 * s)]
        f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        me.from_pydata(v, [], f)
        ob = bpy.data.objects.new(f"Prop{i}", me)
        props.objects.link(ob)
        ang = 2 * math.pi * i / count
        ob.location = (2.5 * math.cos(ang), 2.5 * math.sin(ang), 0.0)
        ob.modifiers.new("sub", 'SUBSURF').levels = level
    ego = rig.create_ego(ctx, name="Ego")
    partner = rig.create_ego(ctx, name="Partner", location=(0.0, -4.0, 0.0), yaw=math.pi)
    partner.keyframe_insert("location", frame=1)
    partner.location = (0.0, -1.0, 0.0)
    partner.keyframe_insert("location", frame=240)
    goal = bpy.data.objects.new("Goal", None)
    scene.collection.objects.link(goal)
    goal.location = (1.0, -2.0, 0.0)
    st = scene.remogen
    st.ego, st.partner, st.scene_collection, st.goal = ego, partner, props, goal
    st.text = "walk to the person and wave"
    return scene, props


def run(args: argparse.Namespace) -> None:
    import bpy
    import torch
    from . import register, unregister
    from ._runtime import runtime
    from .bake import bake
    from .frame import FrameDriver, scene_fps
    from .scene import VOXEL_SIZE, world_triangles

    torch.set_num_threads(args.threads)
    register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene, props = _scene(bpy, args.triangles)
        rt = runtime()
        if args.model:
            model, source = rt.load_model(args.model), args.model
        else:
            try:
                model, source = rt.load_model(), "shipped weights"
            except rt.ModelFileError:
                model, source = rt.load_model(config=args.config), f"config={args.config} (random weights)"
        common = {"model": source, "threads": args.threads, "bpy": bpy.app.version_string}

        # voxelisation: first extraction includes the lazy evaluation of the modifiers, as for a user
        dg = bpy.context.evaluated_depsgraph_get()
        og = runtime().OccupancyGrid
        t0 = time.perf_counter()
        v, f = world_triangles(props, dg)
        t1 = time.perf_counter()
        og.from_triangles(v, f, voxel_size=VOXEL_SIZE)
        t2 = time.perf_counter()
        _emit(metric="voxelise_s", value=round(t2 - t0, 3), extract_s=round(t1 - t0, 3),
              grid_s=round(t2 - t1, 3), triangles=int(len(f)), voxel_size=VOXEL_SIZE, target_max=2.0, **common)

        # live tick: one model frame per update(), the scene moved to that time first (not timed in the tick)
        driver = FrameDriver(scene, model=model)
        # timed once the diffusion helper process runs, as it does a second or two into a session
        common["helper_process"] = driver.group.helper_ready(timeout=60.0)
        fps = scene_fps(scene)
        ticks, fsets = [], []
        warm = 24
        for k in range(warm + args.frames):
            frame = scene.frame_start + k * driver.dt * fps
            fi = int(frame)
            t0 = time.perf_counter()
            scene.frame_set(fi, subframe=frame - fi)
            t1 = time.perf_counter()
            driver.update(scene, bpy.context.evaluated_depsgraph_get(), model_time=k * driver.dt)
            t2 = time.perf_counter()
            if k >= warm:
                fsets.append(t1 - t0)
                ticks.append(t2 - t1)
        tk = np.array(ticks) * 1e3
        _emit(metric="live_tick_ms", p50=round(float(np.median(tk)), 3),
              p99=round(float(np.percentile(tk, 99)), 3), frames=len(tk),
              frame_set_ms_p50=round(float(np.median(fsets)) * 1e3, 3), target_p50_max=8.0, **common)
        driver.restore_rest()

        # headless bake of the same scene
        n_scene = int(round(args.frames * driver.dt * fps))
        res = bake(scene, scene.frame_start, scene.frame_start + n_scene - 1, model=model)
        _emit(metric="bake_model_fps", value=round(res.model_fps, 1), model_frames=res.model_frames,
              scene_frames=res.frames, seconds=round(res.seconds, 3), target_min=150.0,
              **{**common, "helper_process": False})   # a bake never uses the helper
    finally:
        unregister()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", help="model file (default: shipped weights, else --config)")
    ap.add_argument("--config", default="default", help="preset used when there are no shipped weights")
    ap.add_argument("--frames", type=int, default=300, help="model frames timed for the live tick and bake")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--triangles", type=int, default=100_000, help="scene size for the voxelisation")
    ap.add_argument("--no-helper", action="store_true",
                    help="run the diffusion in Blender's process (no helper process), as with the preference off")
    args = ap.parse_args(argv)
    if args.no_helper:
        from ._runtime import HELPER_ENV
        os.environ[HELPER_ENV] = "0"
    run(args)
    return 0


if __name__ == "__main__":
    rc = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(rc)   # the bpy module can hang at interpreter exit with add-on classes registered
