"""Without PyTorch the add-on registers and says so; panels draw; the PyTorch installer works and fails clearly."""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parents[2]


class FakeLayout:
    """Records what a draw() call asks for; every layout method returns another FakeLayout."""

    def __init__(self, log: list) -> None:
        self.log = log

    def __getattr__(self, name):
        def call(*args, **kwargs):
            self.log.append((name, args, kwargs))
            return FakeLayout(self.log)
        return call

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)


def _draw(panel_cls, context) -> list:
    log: list = []
    fake = type("P", (), {"layout": FakeLayout(log)})()
    panel_cls.draw(fake, context)
    return log


def test_register_does_not_import_torch():
    code = ("import sys, os; import bpy; sys.path.insert(0, sys.argv[1]); import remogen_blender as r; "
            "r.register(); bad = 'torch' in sys.modules; r.unregister(); "
            "print('TORCH_IMPORTED' if bad else 'CLEAN', flush=True); os._exit(0)")
    out = subprocess.run([sys.executable, "-c", code, str(ROOT)], capture_output=True, text=True, timeout=120)
    assert "CLEAN" in out.stdout, out.stdout + out.stderr


def test_without_torch_panel_and_operators_say_so(fresh, monkeypatch):
    from remogen_blender import _runtime
    from remogen_blender.panels import REMOGEN_PT_main
    real = _runtime.importlib.util.find_spec
    monkeypatch.setattr(_runtime.importlib.util, "find_spec", lambda n, *a: None if n == "torch" else real(n, *a))
    _runtime.forget_torch_check()
    try:
        assert _runtime.torch_error().startswith("PyTorch is not installed:")
        labels = [kw.get("text") for name, a, kw in _draw(REMOGEN_PT_main, fresh) if name == "label"]
        assert "PyTorch is not installed" in labels
        # the ego rig needs only the runtime's torch-free surface; generating motion needs PyTorch
        assert bpy.ops.remogen.create_ego() == {'FINISHED'}
        with pytest.raises(RuntimeError, match="PyTorch is not installed: press 'Install PyTorch'"):
            bpy.ops.remogen.bake()
    finally:
        monkeypatch.undo()
        _runtime.forget_torch_check()
    assert _runtime.torch_error() is None


def test_panels_draw(fresh):
    import scenes
    from remogen_blender import live
    from remogen_blender.panels import REMOGEN_PT_bone_map, REMOGEN_PT_main, REMOGEN_UL_bone_map
    scenes.demo_scene(fresh)
    log = _draw(REMOGEN_PT_main, fresh)
    ops = [a[0] for name, a, kw in log if name == "operator"]
    assert "remogen.live_start" in ops and "remogen.bake" in ops
    labels = [kw.get("text", "") for name, a, kw in log if name == "label"]
    assert any(t.startswith("Bone map: mixamo (22/22)") for t in labels)
    bpy.ops.remogen.live_start()
    ops = [a[0] for name, a, kw in _draw(REMOGEN_PT_main, fresh) if name == "operator"]
    assert "remogen.live_stop" in ops
    live.stop()
    assert REMOGEN_PT_bone_map.poll(fresh)
    _draw(REMOGEN_PT_bone_map, fresh)
    st = fresh.scene.remogen
    REMOGEN_UL_bone_map.draw_item(None, fresh, FakeLayout([]), st, st.bone_map[0], 0, st, "bone_map_index")


def test_the_panel_names_the_training_phrasing_a_prompt_leans_toward(fresh, monkeypatch):
    """Under a prompt in other words than the captions, the closest training phrasing the loaded model reads it
    by; none for a caption's own words, none before a model is loaded (drawing never loads one)."""
    from model_runtime import load_model
    from model_runtime.text_blend import attach_prompt_blend, blend_meta
    from remogen_blender import _runtime, panels
    st = fresh.scene.remogen

    def labels():
        return [kw.get("text", "") for name, a, kw in _draw(panels.REMOGEN_PT_main, fresh) if name == "label"]

    monkeypatch.setitem(_runtime._model_cache, "model", None)
    st.text = "someone keeps running fast"    # the tiny preset's hashed encoder matches words, not meanings
    assert not any(t.startswith("Closest training phrasing") for t in labels())
    model = load_model(config="tiny", seed=0)
    model.meta["prompt_blend"] = blend_meta(["a person runs", "a person walks forward"])
    attach_prompt_blend(model)
    monkeypatch.setitem(_runtime._model_cache, "model", model)
    shown = [t for t in labels() if t.startswith("Closest training phrasing")]
    assert len(shown) == 1 and "run" in shown[0]
    st.text = "a person runs"
    assert not any(t.startswith("Closest training phrasing") for t in labels())


def test_bone_from_active(fresh):
    import scenes
    scenes.demo_scene(fresh)
    st = fresh.scene.remogen
    st.bone_map_index = 3
    st.partner.data.bones.active = st.partner.data.bones["mixamorig:Head"]
    assert bpy.ops.remogen.bone_from_active() == {'FINISHED'}
    assert st.bone_map[3].bone == "mixamorig:Head"


def _fake_wheel(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(folder / "remogen_fakedep-0.1-py3-none-any.whl", "w") as z:
        z.writestr("remogen_fakedep/__init__.py", "VALUE = 42\n")
        z.writestr("remogen_fakedep-0.1.dist-info/METADATA", "Metadata-Version: 2.1\nName: remogen-fakedep\n"
                                                             "Version: 0.1\n")
        z.writestr("remogen_fakedep-0.1.dist-info/WHEEL", "Wheel-Version: 1.0\nGenerator: test\n"
                                                          "Root-Is-Purelib: true\nTag: py3-none-any\n")
        z.writestr("remogen_fakedep-0.1.dist-info/RECORD", "")


def test_installer_into_private_folder(tmp_path):
    from remogen_blender import deps
    _fake_wheel(tmp_path / "wheels")
    lines: list[str] = []
    ok, msg = deps.install(tmp_path / "site", "remogen-fakedep", index_url=None,
                           find_links=str(tmp_path / "wheels"), no_index=True, on_line=lines.append)
    assert ok, msg
    assert (tmp_path / "site" / "remogen_fakedep" / "__init__.py").is_file()
    assert any(ln.startswith("Installing") for ln in lines)


def test_installer_failure_is_actionable(tmp_path):
    from remogen_blender import deps
    ok, msg = deps.install(tmp_path / "site", "remogen-no-such-package==1.0", index_url=None,
                           find_links=str(tmp_path), no_index=True)
    assert not ok
    assert msg.startswith("PyTorch install failed (pip exit") and "offline zip" in msg and "\n" not in msg


def test_installer_async_reports_status(tmp_path):
    from remogen_blender import deps
    _fake_wheel(tmp_path / "wheels")
    th = deps.install_async(tmp_path / "site", "remogen-fakedep", index_url=None,
                            find_links=str(tmp_path / "wheels"), no_index=True)
    th.join(120)
    assert deps.status.done and deps.status.ok and not deps.status.running
    assert "installed" in deps.status.line


def test_panel_shows_a_partly_trained_model_warning(fresh, tiny_model_file):
    import scenes
    from remogen_blender import _runtime
    from remogen_blender.panels import REMOGEN_PT_main
    scenes.demo_scene(fresh)
    _runtime.clear_model_cache()
    try:
        _runtime.get_model(str(tiny_model_file), 1)
        labels = [kw.get("text", "") for name, a, kw in _draw(REMOGEN_PT_main, fresh) if name == "label"]
        assert any("untrained" in t for t in labels), labels
    finally:
        _runtime.clear_model_cache()
    assert _runtime.model_note() == ""


def test_panel_warns_about_a_prompt_the_text_encoder_cannot_read(fresh):
    import scenes
    from remogen_blender.panels import REMOGEN_PT_main
    scenes.demo_scene(fresh)
    st = fresh.scene.remogen

    def warnings_shown() -> list[str]:
        return [kw.get("text", "") for name, a, kw in _draw(REMOGEN_PT_main, fresh)
                if name == "label" and kw.get("icon") == 'ERROR' and "English" in kw.get("text", "")]

    st.text = "человек прыгает"
    shown = warnings_shown()
    assert len(shown) == 1 and "человек прыгает" in shown[0], shown
    st.text = "🙂🙂"
    assert len(warnings_shown()) == 1
    st.text = "a person jumps"
    assert warnings_shown() == []
