"""Run in a fresh process by test_build.py: install + enable the built zip in a fresh user folder, use it.

argv: MODE ZIP_OR_DASH MODEL_FILE; MODE is "zip" (Install from Disk) or "folder" (already unpacked by
build.py --install). Prints one JSON line; ends with os._exit (the bpy module can hang at
interpreter exit).
"""
import json
import os
import sys

mode, zip_path, model_file = sys.argv[1:4]
index_dir = sys.argv[4] if len(sys.argv) > 4 else ""   # a PEP 503 index holding remogen-fakedep
out = {}
try:
    import bpy
    import addon_utils

    out["blender"] = list(bpy.app.version)
    mod = "bl_ext.user_default.remogen_blender"
    if mode == "zip":
        out["install"] = sorted(bpy.ops.extensions.package_install_files(
            repo="user_default", filepath=zip_path, enable_on_install=True))
    else:
        bpy.ops.extensions.repo_refresh_all()
        addon_utils.enable(mod, default_set=True)
    out["enabled"] = mod in {a.module for a in bpy.context.preferences.addons}
    ext = sys.modules[mod]
    out["ext_dir"] = os.path.dirname(ext.__file__)
    bpy.context.preferences.addons[mod].preferences.model_file = model_file
    if index_dir:   # the preferences' "Install PyTorch" button, pointed at a local index and a fake package
        prefs = bpy.context.preferences.addons[mod].preferences
        prefs.torch_requirement = "remogen-fakedep"
        prefs.torch_index = "file://" + index_dir
        out["install_torch"] = sorted(bpy.ops.remogen.install_torch())
        import remogen_fakedep
        out["private_fakedep"] = remogen_fakedep.__file__
        del sys.modules["remogen_fakedep"]
    out["fakedep"] = None
    try:
        import remogen_fakedep
        out["fakedep"] = remogen_fakedep.__file__
    except ImportError:
        pass

    # (no read_factory_settings here: it would disable the add-on again)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 12
    out["create_ego"] = sorted(bpy.ops.remogen.create_ego())
    ego = scene.remogen.ego
    scene.cursor.location = (0.0, -3.0, 0.0)
    bpy.ops.remogen.create_ego()
    partner = scene.remogen.ego
    partner.name = "Partner"
    partner.rotation_euler = (0.0, 0.0, 3.14159)
    partner.keyframe_insert("location", frame=1)
    partner.location = (0.0, -1.5, 0.0)
    partner.keyframe_insert("location", frame=12)
    scene.remogen.ego = ego
    scene.remogen.partner = partner
    out["bone_map_family"] = scene.remogen.bone_map_family
    out["live_start"] = sorted(bpy.ops.remogen.live_start())
    for f in range(1, 8):
        scene.frame_set(f)
    out["live_stop"] = sorted(bpy.ops.remogen.live_stop())
    out["bake"] = sorted(bpy.ops.remogen.bake())
    out["action"] = ego.animation_data.action.name
    rt = sys.modules.get(mod + ".model_runtime")
    out["runtime_file"] = rt.__file__ if rt else None
    out["toplevel_model_runtime"] = "model_runtime" in sys.modules
    addon_utils.disable(mod, default_set=True)
    out["disabled_ops"] = not hasattr(bpy.types, "REMOGEN_OT_bake")
except Exception as exc:  # report, don't hang
    import traceback
    out["error"] = f"{type(exc).__name__}: {exc}"
    out["traceback"] = traceback.format_exc()
print("RESULT " + json.dumps(out), flush=True)
sys.stderr.flush()
os._exit(0)
