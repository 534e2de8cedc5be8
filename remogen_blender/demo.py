"""Demo scene: a shipped CMU walk as the partner, a table, a goal; bake the ego; save demo.blend and a PNG strip.

    python -m remogen_blender.demo --out demo_out            # in a Python with the bpy module
    python -m remogen_blender.demo --out demo_out --model my.pt
    python -m remogen_blender.demo --out demo_out --target mixamo   # a character of your own instead of the ego

`--target mixamo` puts a Mixamo-named character where the ego would stand: other proportions (legs 1.15 times
the ego's), an A-pose rest; the bake retargets the ego's motion onto it (the ego itself is not made).

The partner clip (the runtime's WALK_CLIP, model_runtime/data/clips/cmu_05_01_walk.npz) is CMU trial 05_01
retargeted to the SMPL-X body at 10 fps; `python -m remogen_blender.demo make-clip BVH` rebuilds it. CMU data: "The data used in this project was
obtained from mocap.cs.cmu.edu. The database was created with funding from NSF EIA-0196217."
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from ._runtime import api

CLIP = api().WALK_CLIP
# Mixamo's bone names (without the "mixamorig:" prefix an import adds) for the 22 SMPL-X joints.
MIXAMO_NAMES = {
    "pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck", "head": "Head",
    "left_hip": "LeftUpLeg", "left_knee": "LeftLeg", "left_ankle": "LeftFoot", "left_foot": "LeftToeBase",
    "left_collar": "LeftShoulder", "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm", "left_wrist": "LeftHand",
}
MIXAMO_NAMES.update({"right_" + k[5:]: v.replace("Left", "Right") for k, v in list(MIXAMO_NAMES.items())
                     if k.startswith("left_")})
# Seconds the scene goes on after the partner's walk ends (it stands there): the ego needs about 4 s to walk to
# the goal beside it, and waves once there. Baked with the shipped weights, seeds 0-11, a wrist waved (side to side
# by 8 cm or more) in 4 of 12 bakes with the walk alone, 9 with 3 s more, 11 with 4 s more.
HOLD_SECONDS = 4.0
TARGET_LEG_SCALE = 1.15     # the demo character's legs against the ego's
TARGET_A_POSE_DEG = 45.0    # its arms in the rest pose, below the T-pose
CREDIT = ("CMU Graphics Lab Motion Capture Database, trial 05_01 (walk). The data used in this project was "
          "obtained from mocap.cs.cmu.edu. The database was created with funding from NSF EIA-0196217.")


def make_clip(bvh: str, out: Path = CLIP) -> Path:
    """Retarget a CMU BVH to the SMPL-X body at 10 fps and store just the pose channels (a few kB)."""
    from ._runtime import runtime
    motion = runtime().load_motion(bvh, fps=120.0, caption="walk")
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, local_rotations=motion.local_rotations.astype(np.float32),
                        pelvis=motion.root[:, :3, 3].astype(np.float32), fps=np.float32(motion.fps),
                        caption=np.str_(motion.caption or "walk"), credit=np.str_(CREDIT))
    return out


def humanoid_heads(scale: float = 1.0, leg_scale: float = 1.0, a_pose_deg: float = 0.0) -> np.ndarray:
    """(22, 3) SMPL-X-ordered rest joints of a standing humanoid, soles at z = 0: the SMPL-X body with legs
    (hip to toe) `leg_scale` times as long and arms lowered `a_pose_deg` from the T-pose, scaled by `scale`."""
    rt = api()
    rest = rt.rest_joints_np()
    names, parents = rt.JOINT_NAMES, rt.PARENTS
    feet = [i for i, n in enumerate(names) if n.endswith(("ankle", "foot"))]
    sole = rt.standing_pelvis_height() - (rest[0, 2] - rest[feet, 2].min())   # sole below the foot joints
    heads = np.zeros_like(rest)
    for i in range(1, len(names)):
        off = rest[i] - rest[parents[i]]
        if names[i].endswith(("knee", "ankle", "foot")):
            off = off * leg_scale
        if names[i].endswith(("elbow", "wrist")):
            a = math.radians(a_pose_deg) * (1.0 if names[i].startswith("left") else -1.0)
            off = np.array(((math.cos(a), 0.0, math.sin(a)), (0.0, 1.0, 0.0), (-math.sin(a), 0.0, math.cos(a)))) @ off
        heads[i] = heads[parents[i]] + off
    heads[:, 2] += sole - heads[feet, 2].min()
    return heads * scale


def make_mixamo_character(context, name: str = "Character", location=(0.0, 0.0, 0.0), yaw: float = 0.0):
    """A Mixamo-named armature with the demo's proportions and A-pose rest, and a capsule body."""
    from . import rig
    from .rig.body import link_body, proxy_body
    joints = list(api().JOINT_NAMES)
    bones = ["mixamorig:" + MIXAMO_NAMES[j] for j in joints]
    ob = rig.build_armature(context, name, humanoid_heads(1.0, TARGET_LEG_SCALE, TARGET_A_POSE_DEG), bones,
                            location=location, yaw=yaw)
    link_body(ob, name + "_Body", *proxy_body(bones, ob, radius_names=joints))
    return ob


# The strip's camera looks from behind the ego, turned toward -X (the goal's side; the table stands at +X
# and further away), from high enough that the table cannot hide the ego's legs (at 40 degrees it covered the
# ego's first pose once the camera came closer to a shorter path).
VIEW_AZIMUTH = math.radians(20.0)
VIEW_ELEVATION = math.radians(50.0)
FRAME_MARGIN = 0.06            # share of the picture left free at each edge


def build_scene(context, fps: int = 24, target: str | None = None):
    """The demo scene in the current (empty) file; returns (scene, number of frames). target "mixamo": a
    Mixamo-named character stands where the ego would, set as the target rig ("Target only")."""
    import bpy
    from . import action, rig
    from ._runtime import api
    clip = np.load(CLIP)
    rots, pelvis, clip_fps = clip["local_rotations"], clip["pelvis"], float(clip["fps"])
    pelvis = pelvis - np.array([pelvis[0, 0], 0.0, 0.0], dtype=np.float32)    # walk along x = 0
    scene = context.scene
    scene.render.fps = fps
    # the partner's walk, then its last pose held while the ego arrives and waves
    n_frames = int(math.floor((len(rots) - 1) / clip_fps * fps + HOLD_SECONDS * fps)) + 1
    scene.frame_start, scene.frame_end = 1, n_frames

    partner = rig.create_ego(context, name="Partner")
    del partner[rig.EGO_MARK]
    writer = rig.EgoWriter(partner)
    loc, rot = writer.pose_channels(pelvis, rots)
    frames = 1.0 + np.arange(len(rots)) / clip_fps * fps
    action.write_pose_keys(partner, "CMU_05_01_walk", frames, list(api().JOINT_NAMES),
                           loc, api().continuous_quaternions(rot), root="pelvis")

    end_y = float(pelvis[-1, 1])                 # the walk heads for -Y; the ego waits beyond its end
    if target == "mixamo":
        ego = None
        character = make_mixamo_character(context, location=(0.0, end_y - 1.1, 0.0), yaw=math.pi)
    else:
        ego = rig.create_ego(context, name="Ego", location=(0.0, end_y - 1.1, 0.0), yaw=math.pi)
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    me = bpy.data.meshes.new("Table")
    sx, sy, h = 0.6, 0.35, 0.75
    me.from_pydata([(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (0.0, h)], [],
                   [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    table = bpy.data.objects.new("Table", me)
    props.objects.link(table)
    table.location = (1.1, end_y - 0.6, 0.0)
    goal = bpy.data.objects.new("Goal", None)
    scene.collection.objects.link(goal)
    goal.location = (-0.9, end_y + 0.3, 0.0)
    goal.empty_display_type = 'SPHERE'
    goal.empty_display_size = 0.15
    marker = _goal_marker(goal)

    st = scene.remogen
    st.partner, st.ego, st.scene_collection, st.goal = partner, ego, props, goal
    if target == "mixamo":
        st.target, st.target_mode = character, 'TARGET'
    st.text = "walk to the person and wave"
    # looks for the strip render
    reacting = ego if ego is not None else character
    for ob, colour in ((partner.children[0], (0.25, 0.45, 0.9, 1.0)),
                       (reacting.children[0], (0.95, 0.55, 0.2, 1.0)),
                       (table, (0.6, 0.6, 0.6, 1.0)), (marker, (0.2, 0.75, 0.3, 1.0))):
        ob.color = colour
    floor_me = bpy.data.meshes.new("Floor")       # looks only: not in Props, so not an obstacle
    floor_me.from_pydata([(-3.0, -6.0, 0.0), (3.0, -6.0, 0.0), (3.0, 3.0, 0.0), (-3.0, 3.0, 0.0)], [], [(0, 1, 2, 3)])
    floor = bpy.data.objects.new("Floor", floor_me)
    scene.collection.objects.link(floor)
    floor.color = (0.85, 0.85, 0.8, 1.0)
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.world.color = (0.75, 0.78, 0.82)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.frame_set(1)
    return scene, n_frames


def _goal_marker(goal):
    """A flat green disc under the goal: empties do not render, and a mesh outside Props is no obstacle."""
    import bpy
    sides, radius = 24, 0.22
    ang = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    verts = [(radius * math.cos(a), radius * math.sin(a), 0.01) for a in ang] + [(0.0, 0.0, 0.01)]
    me = bpy.data.meshes.new("GoalMarker")
    me.from_pydata(verts, [], [(k, (k + 1) % sides, sides) for k in range(sides)])
    marker = bpy.data.objects.new("GoalMarker", me)
    for coll in goal.users_collection:
        coll.objects.link(marker)
    marker.parent = goal
    return marker


def strip_subjects(scene) -> list:
    """What every frame of the strip must show: the bodies (ego or target, partner), the table and the goal marker."""
    st = scene.remogen
    bodies = [c for ob in (st.ego, st.target, st.partner) if ob is not None for c in ob.children if c.type == 'MESH']
    return bodies + [scene.objects["Table"], scene.objects["GoalMarker"]]


def world_corners(objects) -> np.ndarray:
    """(8 * len(objects), 3) world corners of the objects' evaluated bounding boxes (posed bodies too)."""
    import bpy
    dg = bpy.context.evaluated_depsgraph_get()
    out = []
    for ob in objects:
        ev = ob.evaluated_get(dg)
        mw = np.array(ev.matrix_world)
        corners = np.array([tuple(c) for c in ev.bound_box], dtype=np.float64)
        out.append(corners @ mw[:3, :3].T + mw[:3, 3])
    return np.concatenate(out)


def frame_camera(scene, frames: list[int], azimuth: float = VIEW_AZIMUTH, elevation: float = VIEW_ELEVATION,
                 margin: float = FRAME_MARGIN) -> None:
    """Aim scene.camera from a fixed direction, as close as keeps the strip's subjects in view at `frames`.

    The lens shift centres them: it moves the picture without changing the perspective.
    """
    from mathutils import Vector
    points = []
    for f in frames:
        scene.frame_set(f)
        points.append(world_corners(strip_subjects(scene)))
    pts = np.concatenate(points)
    back = np.array((-math.sin(azimuth) * math.cos(elevation), -math.cos(azimuth) * math.cos(elevation),
                     math.sin(elevation)))                      # from the subjects toward the camera
    fwd = -back
    right = np.cross(fwd, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    centre = 0.5 * (pts.min(0) + pts.max(0))
    cam = scene.camera
    data = cam.data
    data.sensor_fit = 'AUTO'
    r = scene.render
    rx, ry = r.resolution_x * r.pixel_aspect_x, r.resolution_y * r.pixel_aspect_y
    span = data.sensor_width / data.lens                     # picture width (larger side) at unit depth
    width, height = (span, span * ry / rx) if rx >= ry else (span * rx / ry, span)
    rel = pts - centre

    def view(dist: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        depth = rel @ fwd + dist
        return rel @ right / depth, rel @ up / depth, depth

    def fits(dist: float) -> bool:
        u, v, depth = view(dist)
        return (depth.min() > 2.0 * data.clip_start and np.ptp(u) <= width * (1.0 - 2.0 * margin)
                and np.ptp(v) <= height * (1.0 - 2.0 * margin))

    near, far = 0.1, 1000.0
    for _ in range(60):                                     # bisection on the camera distance
        mid = 0.5 * (near + far)
        near, far = (near, mid) if fits(mid) else (mid, far)
    u, v, _ = view(far)
    cam.location = tuple(centre + back * far)
    cam.rotation_euler = Vector(tuple(fwd)).to_track_quat('-Z', 'Y').to_euler()
    data.shift_x = 0.5 * (u.min() + u.max()) / span
    data.shift_y = 0.5 * (v.min() + v.max()) / span
    data.clip_end = max(data.clip_end, float(far + np.abs(rel).max() * 2.0))


def render_strip(scene, frames: list[int], path: Path, size: int = 240) -> Path:
    """Workbench renders of a few frames side by side in one PNG (works without a GPU)."""
    import bpy
    r = scene.render
    r.engine = 'BLENDER_WORKBENCH'
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    scene.display.shading.color_type = 'OBJECT'
    r.image_settings.file_format = 'PNG'
    r.film_transparent = False
    frame_camera(scene, frames)
    tiles = []
    for f in frames:
        scene.frame_set(f)
        tmp = path.with_name(f".strip_{f}.png")
        r.filepath = str(tmp)
        bpy.ops.render.render(write_still=True)
        img = bpy.data.images.load(str(tmp))
        px = np.empty(img.size[0] * img.size[1] * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        tiles.append(px.reshape(img.size[1], img.size[0], 4))
        bpy.data.images.remove(img)
        tmp.unlink()
    strip = np.concatenate(tiles, axis=1)
    out = bpy.data.images.new("strip", width=strip.shape[1], height=strip.shape[0], alpha=True)
    out.pixels.foreach_set(strip.ravel())
    out.filepath_raw = str(path)
    out.file_format = 'PNG'
    out.save()
    bpy.data.images.remove(out)
    return path


def run(out_dir: Path, model_path: str | None, strip_frames: int = 6, size: int = 240,
        target: str | None = None) -> int:
    import bpy
    from . import register, unregister
    from ._runtime import api, get_model, remogen_errors, runtime
    from .bake import bake

    register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        out_dir.mkdir(parents=True, exist_ok=True)
        try:
            model = get_model(path=model_path or "", threads=1)
            note = model_path or "shipped weights"
        except api().ModelFileError as exc:
            if model_path:
                raise
            print(f"remogen demo: {exc}\nremogen demo: using an UNTRAINED default-size model instead; "
                  "the motion will not be meaningful", file=sys.stderr)
            model, note = runtime().load_model(config="default"), "untrained default-size model"
            import torch
            torch.set_num_threads(1)
        scene, n = build_scene(bpy.context, target=target)
        t0 = time.perf_counter()
        res = bake(scene, 1, n, model=model)
        shots = [int(round(v)) for v in np.linspace(1, n, strip_frames)]
        strip = render_strip(scene, shots, out_dir / "demo_strip.png", size=size)   # also frames the camera
        scene.frame_set(1)
        blend = out_dir / "demo.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(blend))
        onto = ", ".join(f"'{ob}'" for ob, _act, _old in res.keyed)
        print(f"remogen demo: baked {res.frames} frames ({res.model_frames} model frames, {res.model_fps:.0f}/s) "
              f"onto {onto} with the {note} in {time.perf_counter() - t0:.1f} s; saved {blend} and {strip} "
              f"(frames {shots})")
        return 0
    except remogen_errors() as exc:
        print(f"remogen demo: error: {exc}", file=sys.stderr)
        return 1
    finally:
        unregister()


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", nargs="?", default="run", choices=["run", "make-clip"])
    ap.add_argument("bvh", nargs="?", help="make-clip: the CMU BVH to convert")
    ap.add_argument("--out", default="demo_out", help="folder for demo.blend and demo_strip.png")
    ap.add_argument("--model", help="model file (default: the shipped weights)")
    ap.add_argument("--shots", type=int, default=6, help="frames in the PNG strip")
    ap.add_argument("--size", type=int, default=240, help="pixel size of each frame in the strip")
    ap.add_argument("--target", choices=["mixamo"],
                    help="retarget onto a character of your own instead of the ego: a Mixamo-named rig with "
                         "longer legs and an A-pose rest")
    args = ap.parse_args(argv)
    if args.command == "make-clip":
        if not args.bvh:
            ap.error("make-clip needs the BVH path")
        print(make_clip(args.bvh))
        return 0
    return run(Path(args.out).resolve(), args.model, args.shots, args.size, args.target)


if __name__ == "__main__":
    rc = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(rc)   # skips interpreter shutdown, where the bpy module can hang with classes registered
