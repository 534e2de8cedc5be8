"""Scene meshes -> world triangles -> one cached OccupancyGrid, rebuilt only when the meshes change."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")


def _props(ctx):
    import scenes
    coll = bpy.data.collections.new("Props")
    ctx.scene.collection.children.link(coll)
    a = scenes.make_box("A", (1.0, 2.0, 0.0), collection=coll)
    b = scenes.make_box("B", (-1.0, 0.5, 0.0), size=(1.0, 0.4, 0.5), collection=coll)
    return coll, a, b


def test_world_triangles_match_mathutils(fresh):
    from remogen_blender.scene import world_triangles
    coll, a, b = _props(fresh)
    a.rotation_euler = (0.2, 0.1, 0.9)
    a.scale = (1.0, 2.0, 0.5)
    a.modifiers.new("sub", 'SUBSURF').levels = 1
    fresh.view_layer.update()
    dg = fresh.evaluated_depsgraph_get()
    v, f = world_triangles(coll, dg)
    ref = []
    for ob in (a, b):                 # sorted by name, like world_triangles
        oe = ob.evaluated_get(dg)
        me = oe.data
        for tri in me.loop_triangles:
            ref.append([np.array(oe.matrix_world @ me.vertices[i].co) for i in tri.vertices])
    assert f.shape == (len(ref), 3)
    assert np.abs(v[f] - np.array(ref)).max() < 1e-5
    assert f.shape[0] == 6 * 4 * 2 + 12        # the subsurf level is applied: evaluated meshes


def test_cache_rebuilds_only_on_change(fresh):
    from remogen_blender.scene import SceneCache
    coll, a, _ = _props(fresh)
    cache = SceneCache()
    dg = fresh.evaluated_depsgraph_get()
    g1 = cache.grid(coll, dg)
    assert cache.grid(coll, dg) is g1 and cache.builds == 1
    a.location.x += 0.5                                  # moved
    fresh.view_layer.update()
    g2 = cache.grid(coll, fresh.evaluated_depsgraph_get())
    assert g2 is not g1 and cache.builds == 2
    assert cache.grid(coll, fresh.evaluated_depsgraph_get()) is g2 and cache.builds == 2
    a.data.vertices[0].co.z += 0.3                       # edited in place: counts and matrices unchanged
    a.data.update()
    updates = []

    def hook(scene, depsgraph):
        updates.append(1)
        cache.on_depsgraph_update(coll, depsgraph)
    bpy.app.handlers.depsgraph_update_post.append(hook)
    try:
        fresh.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(hook)
    assert updates
    cache.grid(coll, fresh.evaluated_depsgraph_get())
    assert cache.builds == 3


def test_character_meshes_are_not_scenery(fresh):
    from remogen_blender.scene import world_triangles
    coll, _, _ = _props(fresh)
    bpy.ops.remogen.create_ego()
    ego = fresh.scene.remogen.ego
    for ob in [ego] + list(ego.children):
        coll.objects.link(ob)                            # the user picked a collection holding the ego too
    v, f = world_triangles(coll, fresh.evaluated_depsgraph_get())
    assert len(f) == 24                                  # just the two boxes


def test_live_builds_grid_once(fresh):
    import scenes
    from remogen_blender import live
    scenes.demo_scene(fresh)
    bpy.ops.remogen.live_start()
    for f in range(2, 20):
        fresh.scene.frame_set(f)
    cache = live.state().driver.scene_cache
    assert cache.builds == 1
    live.stop()


def test_nan_mesh_is_reported(fresh):
    from remogen_blender._runtime import UserError
    from remogen_blender.scene import world_triangles
    coll, a, _ = _props(fresh)
    a.data.vertices[0].co.x = float("nan")
    with pytest.raises(UserError, match="Mesh 'A' has NaN"):
        world_triangles(coll, fresh.evaluated_depsgraph_get())
