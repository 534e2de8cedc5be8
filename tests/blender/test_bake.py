"""Bake: keys on every frame in a new action, deterministic for the seed, one undo step, failures change nothing."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")


def _fcurves(action):
    import scenes
    return scenes.action_fcurves(action)


def _curves(action) -> dict:
    import scenes
    return scenes.action_curves(action)


def _scene(fps=24, frames=(1, 30)):
    import scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return scenes.demo_scene(bpy.context, fps=fps, frames=frames)


def _window_override():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == 'VIEW_3D')
    return bpy.context.temp_override(window=win, area=area)


def test_bake_keys_every_frame_into_new_action(fresh):
    d = _scene()
    ego = d["ego"]
    user = bpy.data.actions.new("UserAction")          # the user's own action must survive untouched
    ego.animation_data_create().action = user
    user_id = user.session_uid
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    act = ego.animation_data.action
    assert act.name.startswith("ReMoGen_") and act.session_uid != user_id
    assert "UserAction" in bpy.data.actions and bpy.data.actions["UserAction"].use_fake_user
    curves = _curves(act)
    assert len(curves) == 22 * 4 + 3
    for co in curves.values():
        assert np.array_equal(co[:, 0], np.arange(1, 31, dtype=np.float32))
    assert bpy.context.scene.frame_current == 1
    # evaluating the action reproduces a pose that moved away from rest
    bpy.context.scene.frame_set(30)
    assert any(np.abs(np.array(pb.rotation_quaternion) - (1, 0, 0, 0)).max() > 1e-4 for pb in ego.pose.bones)


def test_bake_same_seed_same_curves_other_seed_differs(fresh):
    d = _scene()
    bpy.ops.remogen.bake()
    a = _curves(d["ego"].animation_data.action)
    bpy.ops.remogen.bake()
    b = _curves(d["ego"].animation_data.action)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    bpy.context.scene.remogen.seed = 7
    bpy.ops.remogen.bake()
    c = _curves(d["ego"].animation_data.action)
    assert any(not np.array_equal(a[k], c[k]) for k in a)


def test_bake_other_fps_and_range(fresh):
    d = _scene(fps=30, frames=(11, 40))
    assert bpy.ops.remogen.bake(frame_start=15, frame_end=25) == {'FINISHED'}
    curves = _curves(d["ego"].animation_data.action)
    for co in curves.values():
        assert np.array_equal(co[:, 0], np.arange(15, 26, dtype=np.float32))


def test_undo_removes_bake(fresh):
    d = _scene(frames=(1, 12))
    ego_name = d["ego"].name
    with _window_override():
        bpy.ops.ed.undo_push(message="before bake")
        assert bpy.ops.remogen.bake() == {'FINISHED'}
        bpy.ops.ed.undo_push(message="bake")
        assert any(a.name.startswith("ReMoGen_") for a in bpy.data.actions)
        bpy.ops.ed.undo()
    assert not any(a.name.startswith("ReMoGen_") for a in bpy.data.actions)
    ego = bpy.data.objects[ego_name]
    assert ego.animation_data is None or ego.animation_data.action is None


def _snapshot():
    scene = bpy.context.scene
    ego = scene.remogen.ego
    pose = [tuple(pb.rotation_quaternion) + tuple(pb.location) for pb in ego.pose.bones] if ego else None
    return (sorted(a.name for a in bpy.data.actions), scene.frame_current, pose,
            ego.animation_data.action.name if ego and ego.animation_data and ego.animation_data.action else None)


@pytest.mark.parametrize("case", ["no_partner", "non_humanoid", "partner_nan", "goal_nan", "empty_collection",
                                  "huge_collection", "missing_model", "foreign_model", "empty_range",
                                  "guidance_out_of_range"])
def test_bad_inputs_leave_file_unchanged(fresh, case, tmp_path, monkeypatch):
    import scenes
    from remogen_blender import scene as scene_mod
    d = _scene(frames=(1, 12))
    st = bpy.context.scene.remogen
    kwargs = {}
    if case == "no_partner":
        st.partner = None
        match = "Pick a partner armature"
    elif case == "non_humanoid":
        st.partner = scenes.make_tentacle()
        match = "not humanoid enough"
    elif case == "partner_nan":
        d["partner"].animation_data_clear()
        d["partner"].location = (float("nan"), 0.0, 0.0)
        match = "NaN"
    elif case == "goal_nan":
        d["goal"].location = (0.0, float("inf"), 0.0)
        match = "Goal 'Goal' has a NaN"
    elif case == "empty_collection":
        st.scene_collection = bpy.data.collections.new("Empty")
        match = "has no mesh triangles"
    elif case == "huge_collection":
        monkeypatch.setattr(scene_mod, "MAX_TRIANGLES", 10)
        match = "more than 10 triangles"
    elif case == "missing_model":
        monkeypatch.setenv("REMOGEN_MODEL_FILE", str(tmp_path / "nope.pt"))
        match = "not found"
    elif case == "foreign_model":
        p = tmp_path / "foreign.pt"
        import torch
        torch.save({"weights": torch.zeros(3)}, p)
        monkeypatch.setenv("REMOGEN_MODEL_FILE", str(p))
        match = "not a ReMoGen model file"
    elif case == "guidance_out_of_range":
        st["guidance"] = 1e30          # as stored in a file saved before the property had a limit
        match = "Guidance 1e+30 is out of range: set it between 0 and 20"
    else:
        kwargs = {"frame_start": 10, "frame_end": 5}
        match = "is empty"
    before = _snapshot()
    with pytest.raises(RuntimeError) as exc:
        bpy.ops.remogen.bake(**kwargs)
    msg = str(exc.value).strip()
    assert match in msg and "\n" not in msg and "Traceback" not in msg
    assert _snapshot() == before


@pytest.mark.parametrize("fps", [10, 24])
def test_baked_action_replays_the_live_motion(fresh, fps):
    """The baked keys reproduce what Live shows at every scene frame (< 1 mm); at 24 fps most scene frames
    fall between two model frames, so the bake's interpolation must be Live's."""
    from remogen_blender import live, rig
    n = 2 * fps
    d = _scene(fps=fps, frames=(1, n))
    scene = bpy.context.scene
    ego = d["ego"]
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    act = ego.animation_data.action
    w = rig.EgoWriter(ego)

    def heads():
        bpy.context.view_layer.update()
        return w.world_heads(bpy.context.evaluated_depsgraph_get())

    baked = []
    for f in range(1, n + 1):
        scene.frame_set(f)
        baked.append(heads())
    scene.frame_set(1)
    bpy.ops.remogen.live_start()        # takes the baked action off the ego while it runs
    lived = []
    for f in range(1, n + 1):
        scene.frame_set(f)
        lived.append(heads())
    assert live.is_running(), live.message()
    live.stop()
    assert np.abs(np.array(baked) - np.array(lived)).max() < 1e-3
    assert np.abs(np.array(lived[-1]) - np.array(lived[0])).max() > 1e-2     # the ego did move
    assert ego.animation_data.action == act                                   # and got its action back


def test_continuous_quaternions():
    from model_runtime import continuous_quaternions as _continuous
    rng = np.random.default_rng(0)
    q = rng.normal(size=(50, 3, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q = np.cumsum(q * 0.05, axis=0) + np.array([1.0, 0.0, 0.0, 0.0])   # a smooth path
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    signs = rng.choice([-1.0, 1.0], size=(50, 3, 1))
    out = _continuous(q * signs)
    assert np.all(np.sum(out[1:] * out[:-1], axis=-1) > 0)
    assert np.allclose(np.abs(np.sum(out * q, axis=-1)), 1.0)


def test_nan_weights_stop_bake_and_change_nothing(fresh):
    """With a scene collection the NaN used to be blamed on the ego's transform."""
    import scenes
    from remogen_blender import _runtime
    _scene(frames=(1, 24))
    assert bpy.context.scene.remogen.scene_collection is not None
    scenes.poison_weights(_runtime.get_model())
    before = _snapshot()
    with pytest.raises(RuntimeError) as exc:
        bpy.ops.remogen.bake()
    msg = str(exc.value).strip()
    assert "non-finite joints at model frame 0" in msg and "NaN or infinite weights" in msg, msg
    assert "ego-to-world" not in msg and "\n" not in msg
    assert _snapshot() == before


def test_bake_stops_at_the_first_non_finite_frame(fresh, monkeypatch):
    """Whatever the cause, a non-finite model frame stops the bake there and nothing is keyed."""
    import scenes
    from model_runtime import ReactionGroup
    from remogen_blender.bake import UserError, bake
    _scene(frames=(1, 24))
    real_step = ReactionGroup.step
    made = []

    def step(self, *a, **kw):
        frames = real_step(self, *a, **kw)
        f = frames[0]
        made.append(f.index)
        if f.index == 5:
            f.local_rotations[3, 1] = float("inf")
        return frames

    monkeypatch.setattr(ReactionGroup, "step", step)
    before = _snapshot()
    with pytest.raises(UserError, match="non-finite joints at model frame 5 .*guidance"):
        bake(bpy.context.scene)
    assert made[-1] == 5 and _snapshot() == before
    assert np.isfinite(scenes.ego_pose(bpy.context.scene.remogen.ego)).all()


def test_bake_bounds_model_frames_not_scene_frames(fresh):
    """12 scene frames at 1/1000 fps are 11,000 s of motion: refused before any model frame is made."""
    from remogen_blender.bake import MAX_MODEL_SECONDS
    _scene(frames=(1, 12))
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = 1, 1000.0
    before = _snapshot()
    with pytest.raises(RuntimeError) as exc:
        bpy.ops.remogen.bake()
    msg = str(exc.value)
    limit = int(MAX_MODEL_SECONDS * 10)
    assert "110,001 model frames" in msg and f"limit is {limit:,}" in msg, msg
    assert _snapshot() == before


def test_bake_cancel_changes_nothing(fresh):
    """Scripts: cancelled() stops the bake between model frames; the ego, its action and the frame stay."""
    from remogen_blender.bake import BakeCancelled, bake
    d = _scene(frames=(1, 48))
    scene = bpy.context.scene
    user = bpy.data.actions.new("UserAction")
    d["ego"].animation_data_create().action = user
    scene.frame_set(7)
    before = _snapshot()
    seen = []
    with pytest.raises(BakeCancelled, match="after 4 of 21 model frames"):
        bake(scene, progress=lambda k, n: seen.append((k, n)), cancelled=lambda: len(seen) >= 4)
    assert seen == [(1, 21), (2, 21), (3, 21), (4, 21)]
    assert _snapshot() == before and not user.use_fake_user


def test_modal_bake_steps_in_chunks_and_esc_cancels(fresh):
    """What the UI operator runs per timer tick: chunks with progress; cancel leaves the file as it was."""
    from remogen_blender.bake import BakeJob
    from remogen_blender.operators import ModalBake
    d = _scene(frames=(1, 48))
    before = _snapshot()
    run = ModalBake(bpy.context, BakeJob(bpy.context.scene))
    assert run.tick(bpy.context, seconds=0.0) is False          # one model frame per tick at the least
    assert run.job.done == 1 and run.job.total == 21
    run.tick(bpy.context, seconds=0.0)
    assert run.job.done == 2
    run.cancel(bpy.context)
    assert _snapshot() == before
    # run to the end: the same keys as a bake in one go
    run = ModalBake(bpy.context, BakeJob(bpy.context.scene))
    while not run.tick(bpy.context, seconds=0.05):
        pass
    res = run.finish(bpy.context)
    chunked = _curves(res.action)
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    whole = _curves(d["ego"].animation_data.action)
    assert chunked.keys() == whole.keys() and all(np.array_equal(chunked[k], whole[k]) for k in whole)


def test_bake_never_uses_the_helper_process(fresh, monkeypatch):
    """A bake runs every segment in Blender's process, whatever the helper preference says (Live follows it)."""
    from remogen_blender import frame
    from remogen_blender.bake import BakeJob
    _scene(frames=(1, 12))
    monkeypatch.setattr(frame, "use_helper_process", lambda: True)
    job = BakeJob(bpy.context.scene)
    assert job.driver.group.pipeline is False
    job.cancel()


def test_centimetre_partner_is_named_before_the_scene(fresh):
    """A rig and props imported in centimetres: the partner's scale is the message, not the scene's size."""
    d = _scene(frames=(1, 12))
    d["partner"].animation_data_clear()
    d["partner"].scale = (100.0, 100.0, 100.0)
    d["props"].objects["Table"].scale = (100.0, 100.0, 100.0)
    before = _snapshot()
    with pytest.raises(RuntimeError, match="looks like centimetres: scale it by 0.01"):
        bpy.ops.remogen.bake()
    assert _snapshot() == before


def test_multi_line_runtime_message_is_reported_as_one_line(fresh, monkeypatch):
    """A runtime message that spans lines (a goal array printed whole) reaches the user as one line."""
    from remogen_blender import frame
    _scene(frames=(1, 12))
    monkeypatch.setattr(frame.FrameDriver, "_goal", staticmethod(lambda st, dg: np.zeros((4, 3))))
    before = _snapshot()
    with pytest.raises(RuntimeError) as exc:
        bpy.ops.remogen.bake()
    msg = str(exc.value).strip()
    assert "goal" in msg and "\n" not in msg, msg
    assert _snapshot() == before
