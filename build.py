#!/usr/bin/env python3
"""Build the ReMoGen Blender extension zip from `addon_manifest.toml` (the single source of the manifest).

    python build.py                          # dist/remogen_blender-<version>.zip (slim: PyTorch not bundled)
    python build.py --wheels linux-x64       # dist/remogen_blender-<version>-linux_x64.zip with the CPU torch wheels
    python build.py --wheels linux-x64 --wheel-dir WHEELS   # bundle wheels already downloaded (offline)
    python build.py --install ~/.config/blender/4.5         # also install into that Blender user folder

The zip holds `remogen_blender/` at its root with `model_runtime/` (and the default weights when they
exist) vendored inside it as a sub-package. It is built and validated with Blender's own extension tool
(`blender_ext.py`, found inside an installed `bpy` package or given with --blender-ext); stdlib only.
"""
from __future__ import annotations

import argparse
import glob
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
MANIFEST_SRC = ROOT / "addon_manifest.toml"
PACKAGE = ROOT / "remogen_blender"
RUNTIME = ROOT / "model_runtime"
REQUIRED = ("schema_version", "id", "version", "name", "tagline", "maintainer", "type", "blender_version_min",
            "license")
# Blender platform -> pip platform tags (newest first; pip also accepts older compatible manylinux/macOS tags).
PIP_PLATFORMS = {
    "linux-x64": ["manylinux_2_28_x86_64", "manylinux2014_x86_64", "manylinux_2_17_x86_64"],
    "linux-arm64": ["manylinux_2_28_aarch64", "manylinux2014_aarch64", "manylinux_2_17_aarch64"],
    "windows-x64": ["win_amd64"],
    "windows-arm64": ["win_arm64"],
    "macos-arm64": ["macosx_14_0_arm64", "macosx_13_0_arm64", "macosx_12_0_arm64", "macosx_11_0_arm64"],
    "macos-x64": ["macosx_10_15_x86_64", "macosx_10_9_x86_64"],
}
BLENDER_PYTHON = "3.11"    # Blender 4.2 - 5.0
SKIP_WHEELS = ("numpy-", "setuptools-")  # Blender ships numpy; setuptools (only for torch C++ builds) would
# drop a distutils-precedence .pth into the site-packages that every extension shares
RUNTIME_WEIGHTS = ("default.pt", "MODEL_CARD.md")


class BuildError(Exception):
    pass


# ---------------------------------------------------------------------------- manifest

def load_manifest(path: Path = MANIFEST_SRC) -> tuple[dict, str]:
    """(parsed manifest, its text) after checks that give one-line reasons."""
    if not path.is_file():
        raise BuildError(f"{path} not found")
    text = path.read_text(encoding="utf-8")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise BuildError(f"{path.name} is not valid TOML: {exc}") from None
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise BuildError(f"{path.name} lacks {', '.join(missing)}")
    if data["id"] != PACKAGE.name:
        raise BuildError(f"{path.name}: id {data['id']!r} must equal the package folder name {PACKAGE.name!r}")
    if not re.fullmatch(r"\d+\.\d+\.\d+([-+][0-9A-Za-z.-]+)?", str(data["version"])):
        raise BuildError(f"{path.name}: version {data['version']!r} is not semantic (like 1.2.3)")
    if data["type"] != "add-on":
        raise BuildError(f"{path.name}: type must be 'add-on'")
    if "wheels" in data or "platforms" in data:
        raise BuildError(f"{path.name}: leave out 'wheels' and 'platforms'; build.py --wheels adds them")
    return data, text


def manifest_text(src_text: str, wheels: list[str], platforms: list[str]) -> str:
    """The blender_manifest.toml text: the source verbatim plus wheels/platforms before the first table."""
    extra = ""
    if platforms:
        extra += "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]\n"
    if wheels:
        extra += "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]\n"
    if not extra:
        return src_text
    m = re.search(r"^\[", src_text, flags=re.M)
    pos = m.start() if m else len(src_text)
    out = src_text[:pos] + "\n# added by build.py\n" + extra + "\n" + src_text[pos:]
    tomllib.loads(out)   # still valid TOML
    return out


# ---------------------------------------------------------------------------- staging

def _ignore(_dir: str, names: list[str]) -> set[str]:
    return {n for n in names if n == "__pycache__" or n.endswith((".pyc", ".tmp")) or n.startswith(".")}


def stage(out_dir: Path, manifest_src: str, wheel_files: list[Path], platforms: list[str]) -> Path:
    """A folder with exactly what goes into the zip."""
    if out_dir.exists():
        shutil.rmtree(out_dir)
    shutil.copytree(PACKAGE, out_dir, ignore=_ignore)
    if (out_dir / "model_runtime").exists():
        raise BuildError("remogen_blender/model_runtime exists in the source tree; remove it (build.py vendors it)")
    shutil.copytree(RUNTIME, out_dir / "model_runtime", ignore=_ignore)
    weights = out_dir / "model_runtime" / "weights"
    if weights.is_dir():
        for p in weights.iterdir():   # only the shipped default weights and their card, never training runs
            if p.name not in RUNTIME_WEIGHTS:
                shutil.rmtree(p) if p.is_dir() else p.unlink()
    if wheel_files:
        (out_dir / "wheels").mkdir()
        for w in wheel_files:
            shutil.copy2(w, out_dir / "wheels" / w.name)
    (out_dir / "blender_manifest.toml").write_text(
        manifest_text(manifest_src, [w.name for w in wheel_files], platforms), encoding="utf-8")
    return out_dir


# ---------------------------------------------------------------------------- Blender's tool

def find_blender_ext(explicit: str | None = None) -> Path | None:
    """blender_ext.py from --blender-ext, $BLENDER_EXT, an installed bpy, or a bpy virtualenv in the repo."""
    cands: list[str] = []
    if explicit:
        cands.append(explicit)
    if os.environ.get("BLENDER_EXT"):
        cands.append(os.environ["BLENDER_EXT"])
    pattern = os.path.join("*", "scripts", "addons_core", "bl_pkg", "cli", "blender_ext.py")
    try:
        spec = importlib.util.find_spec("bpy")   # locates the package without importing it
    except (ImportError, ValueError):
        spec = None
    if spec is not None and spec.origin:
        cands += sorted(glob.glob(os.path.join(os.path.dirname(spec.origin), pattern)))
    cands += sorted(glob.glob(str(ROOT / ".venv-bpy*" / "lib" / "python3*" / "site-packages" / "bpy" / pattern)))
    for c in cands:
        if os.path.isfile(c):
            return Path(c)
    return None


def _run_ext(tool: Path, args: list[str]) -> tuple[int, str]:
    r = subprocess.run([sys.executable, str(tool), *args], capture_output=True, text=True)
    return r.returncode, (r.stdout + r.stderr).strip()


def build_zip(staged: Path, out_zip: Path, tool: Path | None) -> None:
    out_zip.parent.mkdir(parents=True, exist_ok=True)
    if out_zip.exists():
        out_zip.unlink()
    if tool is None:
        raise BuildError("Blender's blender_ext.py not found: pip install 'bpy==4.5.*' (or run inside the bpy "
                         "virtualenv), or pass --blender-ext PATH")
    rc, out = _run_ext(tool, ["validate", str(staged)])
    if rc != 0:
        raise BuildError(f"manifest rejected by Blender's validator: {out.splitlines()[-1] if out else rc}")
    rc, out = _run_ext(tool, ["build", "--source-dir", str(staged), "--output-filepath", str(out_zip)])
    if rc != 0 or not out_zip.is_file():
        raise BuildError(f"blender_ext.py build failed: {out.splitlines()[-1] if out else rc}")
    rc, out = _run_ext(tool, ["validate", str(out_zip)])
    if rc != 0:
        raise BuildError(f"the built zip does not validate: {out.splitlines()[-1] if out else rc}")


# ---------------------------------------------------------------------------- wheels

def _wheel_matches(name: str, platform: str) -> bool:
    tag = name[:-4].split("-")[-1]        # the platform tag (may be dotted: several tags)
    if tag == "any":
        return True
    return any(t in PIP_PLATFORMS[platform] or _same_family(t, platform) for t in tag.split("."))


def _same_family(tag: str, platform: str) -> bool:
    arch = {"x64": ("x86_64", "amd64"), "arm64": ("aarch64", "arm64")}[platform.split("-")[1]]
    osname = {"linux": ("manylinux", "musllinux"), "windows": ("win",), "macos": ("macosx",)}[platform.split("-")[0]]
    return tag.startswith(osname) and tag.endswith(arch) and not tag.startswith("musllinux")


def collect_wheels(platform: str, wheel_dir: Path | None, requirement: str, index_url: str,
                   cache: Path) -> list[Path]:
    """The wheels for one platform: from `wheel_dir`, else downloaded with pip (CPU torch and its deps)."""
    if platform not in PIP_PLATFORMS:
        raise BuildError(f"unknown platform {platform!r}; use one of {', '.join(PIP_PLATFORMS)}")
    if wheel_dir is None:
        dest = cache / platform
        dest.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "pip", "download", requirement, "--dest", str(dest), "--only-binary=:all:",
               "--python-version", BLENDER_PYTHON, "--implementation", "cp",
               "--abi", "cp" + BLENDER_PYTHON.replace(".", ""), "--abi", "abi3", "--abi", "none"]
        if index_url:   # empty: pip's own configuration (a local mirror, a proxy)
            cmd += ["--index-url", index_url, "--extra-index-url", "https://pypi.org/simple"]
        for tag in PIP_PLATFORMS[platform]:
            cmd += ["--platform", tag]
        print("build.py: " + " ".join(cmd), flush=True)
        if subprocess.run(cmd).returncode != 0:
            raise BuildError(f"pip could not download {requirement} for {platform}; check the network, or "
                             "download the wheels yourself and pass --wheel-dir")
        wheel_dir = dest
    wheels = sorted(p for p in Path(wheel_dir).glob("*.whl")
                    if _wheel_matches(p.name, platform) and not p.name.lower().startswith(SKIP_WHEELS))
    if not wheels:
        raise BuildError(f"no wheels for {platform} in {wheel_dir}")
    return wheels


# ---------------------------------------------------------------------------- install

def install(zip_path: Path, user_dir: Path, ext_id: str) -> Path:
    """Unpack into <user_dir>/extensions/user_default/<id>, like Preferences > Install from Disk.

    Bundled wheels are unpacked by Blender itself when the extension is enabled (it syncs every enabled
    extension's wheels into extensions/.local), so only the package is placed here.
    """
    dest = user_dir / "extensions" / "user_default" / ext_id
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    with zipfile.ZipFile(zip_path) as z:
        z.extractall(dest)
    return dest


# ---------------------------------------------------------------------------- main

def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--output-dir", default=str(ROOT / "dist"))
    ap.add_argument("--wheels", action="append", default=[], metavar="PLATFORM",
                    help=f"bundle the CPU PyTorch wheels for a platform ({', '.join(PIP_PLATFORMS)}); repeatable")
    ap.add_argument("--wheel-dir", help="take the wheels from this folder instead of downloading them")
    ap.add_argument("--torch-requirement", default="torch==2.13.0", help="what pip downloads for --wheels (the "
                                                                           "version model_runtime is tested with)")
    ap.add_argument("--torch-index", default="https://download.pytorch.org/whl/cpu",
                    help="index with the CPU builds of torch (its dependencies come from PyPI); '' uses pip's "
                         "configured index")
    ap.add_argument("--blender-ext", help="path of Blender's blender_ext.py")
    ap.add_argument("--install", metavar="DIR", help="install the slim zip (or the first --wheels zip) into "
                                                     "this Blender user folder (e.g. ~/.config/blender/4.5)")
    args = ap.parse_args(argv)
    try:
        data, src = load_manifest()
        tool = find_blender_ext(args.blender_ext)
        out_dir = Path(args.output_dir).resolve()
        work = ROOT / "build" / "extension"
        built: list[Path] = []
        if args.wheels:
            for platform in args.wheels:
                wheels = collect_wheels(platform, Path(args.wheel_dir) if args.wheel_dir else None,
                                        args.torch_requirement, args.torch_index, ROOT / "build" / "wheels")
                staged = stage(work / platform / data["id"], src, wheels, [platform])
                z = out_dir / f"{data['id']}-{data['version']}-{platform.replace('-', '_')}.zip"
                build_zip(staged, z, tool)
                built.append(z)
        else:
            staged = stage(work / "slim" / data["id"], src, [], [])
            z = out_dir / f"{data['id']}-{data['version']}.zip"
            build_zip(staged, z, tool)
            built.append(z)
        for z in built:
            print(f"build.py: built {z} ({z.stat().st_size / 1e6:.1f} MB), validated with {tool}")
        if args.install:
            dest = install(built[0], Path(args.install).expanduser().resolve(), data["id"])
            print(f"build.py: installed into {dest}; enable 'ReMoGen' in Preferences > Add-ons")
    except BuildError as exc:
        print(f"build.py: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
