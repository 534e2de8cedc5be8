"""Packaging: build.py builds a validated zip; it installs and enables in a fresh Blender user folder (each in a
fresh process, so the source tree is not on the path) and its operators run; bundled wheels are installed."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from blender_env import subprocess_env

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent


def _build_module():
    spec = importlib.util.spec_from_file_location("remogen_build", ROOT / "build.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _fake_wheel(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    w = folder / "remogen_fakedep-0.1-py3-none-any.whl"
    with zipfile.ZipFile(w, "w") as z:
        z.writestr("remogen_fakedep/__init__.py", "VALUE = 42\n")
        z.writestr("remogen_fakedep-0.1.dist-info/METADATA", "Metadata-Version: 2.1\nName: remogen_fakedep\n"
                                                             "Version: 0.1\n")
        z.writestr("remogen_fakedep-0.1.dist-info/WHEEL", "Wheel-Version: 1.0\nGenerator: test\n"
                                                          "Root-Is-Purelib: true\nTag: py3-none-any\n")
        z.writestr("remogen_fakedep-0.1.dist-info/RECORD", "")
    (folder / "numpy-1.26.4-cp311-cp311-manylinux_2_17_x86_64.whl").write_bytes(b"")   # must be left out
    (folder / "torch-9.9-cp311-cp311-win_amd64.whl").write_bytes(b"")                 # other platform
    return w


def _build(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "build.py"), *args], capture_output=True, text=True,
                          timeout=300)


def _check_install(mode: str, zip_path: str, user: Path, model: Path, index: Path | None = None) -> dict:
    env = subprocess_env(drop=("REMOGEN_MODEL_FILE",))      # not the source tree: the installed zip
    env["BLENDER_USER_RESOURCES"] = str(user)
    extra = [str(index)] if index else []
    r = subprocess.run([sys.executable, str(HERE / "install_check.py"), mode, zip_path, str(model), *extra],
                       cwd=user.parent, env=env, capture_output=True, text=True, timeout=300)
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("RESULT ")), None)
    assert line, r.stdout[-2000:] + r.stderr[-2000:]
    out = json.loads(line[7:])
    assert "error" not in out, out.get("traceback")
    assert out["blender"] == list(bpy.app.version)           # the same Blender as this test process
    return out


def _assert_works(out: dict, user: Path) -> None:
    assert out["enabled"]
    assert out["ext_dir"] == str(user / "extensions" / "user_default" / "remogen_blender")
    assert out["create_ego"] == out["live_start"] == out["live_stop"] == out["bake"] == ["FINISHED"]
    assert out["bone_map_family"] == "smplx" and out["action"].startswith("ReMoGen_")
    assert out["runtime_file"].startswith(out["ext_dir"])      # the vendored runtime, not the source tree's
    assert out["toplevel_model_runtime"] is False
    assert out["disabled_ops"]


def test_slim_zip_builds_validates_installs_and_runs(tmp_path, tiny_model_file):
    r = _build(["--output-dir", str(tmp_path / "dist")])
    assert r.returncode == 0, r.stderr
    z = tmp_path / "dist" / "remogen_blender-0.1.0.zip"
    names = zipfile.ZipFile(z).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert "model_runtime/__init__.py" in names and "model_runtime/voxel.py" in names
    assert "model_runtime/text_tables/minilm_static.npz" in names      # the default text encoder's table
    assert not any("__pycache__" in n or n.startswith("wheels/") for n in names)
    weights = ROOT / "model_runtime" / "weights" / "default.pt"
    assert ("model_runtime/weights/default.pt" in names) == weights.is_file()
    user = tmp_path / "user"
    index = tmp_path / "index"                        # a local package index for the "Install PyTorch" button
    wheel = _fake_wheel(tmp_path / "wheels")
    (index / "remogen-fakedep").mkdir(parents=True)
    (index / "remogen-fakedep" / "index.html").write_text(f'<a href="file://{wheel}">{wheel.name}</a>')
    out = _check_install("zip", str(z), user, tiny_model_file, index)
    _assert_works(out, user)
    assert out["install_torch"] == ["FINISHED"]
    assert "remogen_blender" in out["private_fakedep"] and out["private_fakedep"].startswith(str(user))


def test_wheels_zip_and_install_folder(tmp_path, tiny_model_file):
    wheels = tmp_path / "wheels"
    _fake_wheel(wheels)
    user = tmp_path / "user"
    r = _build(["--output-dir", str(tmp_path / "dist"), "--wheels", "linux-x64", "--wheel-dir", str(wheels),
                "--install", str(user)])
    assert r.returncode == 0, r.stderr
    z = tmp_path / "dist" / "remogen_blender-0.1.0-linux_x64.zip"
    names = zipfile.ZipFile(z).namelist()
    assert [n for n in names if n.startswith("wheels/")] == ["wheels/remogen_fakedep-0.1-py3-none-any.whl"]
    manifest = zipfile.ZipFile(z).read("blender_manifest.toml").decode()
    assert 'platforms = ["linux-x64"]' in manifest and "./wheels/remogen_fakedep-0.1-py3-none-any.whl" in manifest
    out = _check_install("folder", "-", user, tiny_model_file)         # unpacked by build.py --install
    _assert_works(out, user)
    assert out["fakedep"].startswith(str(user / "extensions" / ".local"))   # Blender installed the wheel


def test_manifest_errors_are_one_line(tmp_path):
    b = _build_module()
    bad = tmp_path / "m.toml"
    src = (ROOT / "addon_manifest.toml").read_text()
    bad.write_text(src.replace('version = "0.1.0"', 'version = "one"'))
    with pytest.raises(b.BuildError, match="not semantic"):
        b.load_manifest(bad)
    bad.write_text(src.replace('id = "remogen_blender"', 'id = "other"'))
    with pytest.raises(b.BuildError, match="must equal the package folder name"):
        b.load_manifest(bad)
    bad.write_text("schema_version = [")
    with pytest.raises(b.BuildError, match="not valid TOML"):
        b.load_manifest(bad)
    text = b.manifest_text(src, ["a.whl"], ["linux-x64"])
    import tomllib
    d = tomllib.loads(text)
    assert d["wheels"] == ["./wheels/a.whl"] and d["permissions"]["files"]
