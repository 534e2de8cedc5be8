"""Installing the CPU build of PyTorch into the extension's private folder (for the slim zip).

pip runs in a subprocess of Blender's own Python (`sys.executable`) with `--target`, so nothing outside
the extension's folder changes; a worker thread reads its output into a one-line status that the
preferences show. Failure ends with an actionable line, never a traceback. Blender's "Allow Online
Access" setting is obeyed: with it off, nothing is downloaded (local wheel folders still work).
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

DEFAULT_REQUIREMENT = "torch"
DEFAULT_INDEX = "https://download.pytorch.org/whl/cpu"
PYPI = "https://pypi.org/simple"     # where pip looks when given no index
OFFLINE_REFUSAL = ("Online access is off: enable Preferences > System > Network > Allow Online Access to "
                   "install PyTorch, or install the offline zip with PyTorch bundled")


@dataclass
class InstallStatus:
    running: bool = False
    done: bool = False
    ok: bool = False
    line: str = ""                 # the latest progress line, or the result
    log: list[str] = field(default_factory=list)


status = InstallStatus()


def _pip_cmd(target: Path, requirement: str, index_url: str | None, find_links: str | None,
             no_index: bool) -> list[str]:
    cmd = [sys.executable, "-m", "pip", "install", "--upgrade", "--no-input", "--disable-pip-version-check",
           "--target", str(target), requirement]
    if index_url:
        cmd += ["--index-url", index_url]
    if find_links:
        cmd += ["--find-links", find_links]
    if no_index:
        cmd += ["--no-index"]
    return cmd


def online_access_allowed() -> bool:
    """Blender's "Allow Online Access" (4.2+); True outside Blender or where the setting does not exist."""
    try:
        import bpy
    except ImportError:
        return True
    return bool(getattr(bpy.app, "online_access", True))


def offline_refusal(index_url: str | None, find_links: str | None = None, no_index: bool = False) -> str | None:
    """OFFLINE_REFUSAL when pip would go online while Blender forbids it, else None."""
    sources = ([] if no_index else [index_url or PYPI]) + ([find_links] if find_links else [])
    online = any(src.split(":", 1)[0].lower() in ("http", "https") for src in sources)
    return OFFLINE_REFUSAL if online and not online_access_allowed() else None


def _ensure_pip(on_line: Callable[[str], None]) -> str | None:
    """None when pip works (bootstrapping it with ensurepip if needed), else why not."""
    ok = subprocess.run([sys.executable, "-m", "pip", "--version"], capture_output=True).returncode == 0
    if ok:
        return None
    on_line("Bootstrapping pip (ensurepip)...")
    r = subprocess.run([sys.executable, "-m", "ensurepip", "--user"], capture_output=True, text=True)
    if r.returncode != 0:
        return "pip is not available in Blender's Python and ensurepip failed"
    return None


def install(target: Path, requirement: str = DEFAULT_REQUIREMENT, index_url: str | None = DEFAULT_INDEX,
            find_links: str | None = None, no_index: bool = False,
            on_line: Callable[[str], None] | None = None) -> tuple[bool, str]:
    """Run pip; returns (ok, one-line result). Blocking: call it from a thread in the UI."""
    say = on_line or (lambda _s: None)
    if not sys.executable or not os.path.exists(sys.executable):
        return False, "Cannot find Blender's Python executable to run pip; use the offline zip with PyTorch bundled"
    refusal = offline_refusal(index_url, find_links, no_index)
    if refusal:
        return False, refusal
    err = _ensure_pip(say)
    if err:
        return False, f"PyTorch install failed: {err}; use the offline zip with PyTorch bundled"
    target.mkdir(parents=True, exist_ok=True)
    cmd = _pip_cmd(target, requirement, index_url, find_links, no_index)
    say(f"Installing {requirement} into {target} ...")
    env = dict(os.environ, PYTHONNOUSERSITE="1")
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    except OSError as exc:
        return False, f"PyTorch install failed: could not run pip ({exc}); use the offline zip"
    last = ""
    assert proc.stdout is not None
    for raw in proc.stdout:
        line = raw.strip()
        if not line:
            continue
        last = line
        status.log.append(line)
        if line.startswith(("Collecting", "Downloading", "Installing", "Successfully", "Looking in")):
            say(line[:160])
    rc = proc.wait()
    if rc != 0:
        hint = ("check the internet connection (download.pytorch.org must be reachable) or install the offline "
                "zip with PyTorch bundled")
        return False, f"PyTorch install failed (pip exit {rc}: {last[:160]}); {hint}"
    return True, f"PyTorch installed into {target}; it is ready to use"


def install_async(target: Path, requirement: str = DEFAULT_REQUIREMENT, index_url: str | None = DEFAULT_INDEX,
                  find_links: str | None = None, no_index: bool = False,
                  on_done: Callable[[bool, str], None] | None = None) -> threading.Thread:
    """Start install() in a worker thread; `status` tracks it."""
    status.running, status.done, status.ok, status.line, status.log = True, False, False, "Starting...", []

    def run() -> None:
        def on_line(s: str) -> None:
            status.line = s
        try:
            ok, line = install(target, requirement, index_url, find_links, no_index, on_line)
        except Exception as exc:  # a worker thread must always report back
            ok, line = False, f"PyTorch install failed: {type(exc).__name__}: {exc}"
        status.ok, status.line, status.running, status.done = ok, line, False, True
        if on_done is not None:
            on_done(ok, line)

    th = threading.Thread(target=run, name="remogen-install-torch", daemon=True)
    th.start()
    return th
