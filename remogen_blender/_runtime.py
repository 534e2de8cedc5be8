"""Access to model_runtime and PyTorch, imported lazily.

Nothing here imports torch at module import time: registering the add-on must work (and the panel must
say why nothing runs) when PyTorch is missing. The built extension carries its own copy of
model_runtime as a sub-package (``<ext>.model_runtime``) so that it never picks up, or clashes with, a
``model_runtime`` installed elsewhere; the source tree uses the top-level package.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import sys
import warnings
from pathlib import Path
from types import ModuleType
from typing import Any

_HERE = Path(__file__).resolve().parent
_VENDORED = (_HERE / "model_runtime").is_dir()
RUNTIME_PACKAGE = f"{__package__}.model_runtime" if _VENDORED else "model_runtime"

# Environment override for the model file (CI, batch machines); the preferences win when set.
MODEL_ENV = "REMOGEN_MODEL_FILE"


class UserError(Exception):
    """A predictable problem reported to the user as one line (no traceback)."""


def private_site_packages(create: bool = False) -> Path | None:
    """The extension's private folder that the "Install PyTorch" button installs into."""
    try:
        import bpy
    except ImportError:
        return None
    try:
        # Only an installed extension (bl_ext.<repo>.<id>) has a user folder of its own.
        p = bpy.utils.extension_path_user(__package__, path="site-packages", create=create)
    except (ValueError, AttributeError, RuntimeError):
        p = bpy.utils.user_resource("EXTENSIONS", path=os.path.join(".remogen", "site-packages"), create=create)
    return Path(p) if p else None


def add_private_site_packages() -> None:
    """Make a PyTorch installed by the preferences button importable."""
    p = private_site_packages()
    if p is not None and p.is_dir() and str(p) not in sys.path:
        sys.path.append(str(p))  # appended: a torch already on sys.path keeps priority
        importlib.invalidate_caches()


_torch_state: dict[str, Any] = {"checked": False, "error": None}


def torch_error() -> str | None:
    """None when PyTorch can be imported, else a one-line reason. Cheap after the first call."""
    if not _torch_state["checked"]:
        add_private_site_packages()
        if importlib.util.find_spec("torch") is None:
            _torch_state["error"] = ("PyTorch is not installed: press 'Install PyTorch' in the add-on "
                                     "preferences, or install the offline zip that bundles it")
        else:
            _torch_state["error"] = None
        _torch_state["checked"] = True
    return _torch_state["error"]


def forget_torch_check() -> None:
    _torch_state["checked"] = False


def api() -> ModuleType:
    """The runtime's public package without PyTorch: joint names, parents, bone maps, quaternion maths.

    Importing the package imports no torch; its model parts (load_model, ReactionSession, load_motion,
    OccupancyGrid) need `runtime()`, which checks for PyTorch first.
    """
    return importlib.import_module(RUNTIME_PACKAGE)


def runtime() -> ModuleType:
    """The runtime's public package, once PyTorch is known to import; raises UserError when it is missing."""
    err = torch_error()
    if err:
        raise UserError(err)
    try:
        import torch  # noqa: F401  (a broken install fails here, with a message, not later in a step)
        return api()
    except ImportError as exc:
        raise UserError(f"PyTorch is not usable ({exc}); reinstall it from the add-on preferences") from None


def remogen_errors() -> tuple[type[BaseException], ...]:
    """The exception types that carry a one-line user message."""
    return (UserError, api().RemogenError)


def error_line(exc: BaseException) -> str:
    """One line for the user: the message of a predictable error, else the type and message."""
    msg = str(exc) if isinstance(exc, remogen_errors()) else f"{type(exc).__name__}: {exc}"
    return " ".join(msg.split())


# ---------------------------------------------------------------------------- model cache

_model_cache: dict[str, Any] = {"key": None, "model": None, "note": ""}


def settings_from_prefs() -> tuple[str, int]:
    """(model file or "" for the shipped weights, CPU threads or 0 for PyTorch's own choice)."""
    from .preferences import get_prefs
    prefs = get_prefs()
    path = (prefs.model_file if prefs is not None else "") or os.environ.get(MODEL_ENV, "")
    threads = int(prefs.cpu_threads) if prefs is not None else 1   # see the preference's description
    return path, threads


HELPER_ENV = "REMOGEN_HELPER_PROCESS"   # "0": no helper process (where preferences are not at hand)


def use_helper_process() -> bool:
    """Whether runs pipeline their diffusion through the runtime's helper process (the preference, default on)."""
    from .preferences import get_prefs
    prefs = get_prefs()
    if prefs is not None:
        return bool(prefs.helper_process)
    return os.environ.get(HELPER_ENV, "1") != "0"


def get_model(path: str | None = None, threads: int | None = None) -> Any:
    """The model for the current preferences, loaded once and reused while the file is unchanged."""
    if path is None or threads is None:
        p, t = settings_from_prefs()
        path = p if path is None else path
        threads = t if threads is None else threads
    rt = runtime()
    if threads and threads > 0:
        import torch
        torch.set_num_threads(int(threads))
    resolved = _resolve_model_path(path)
    try:
        stamp = os.stat(resolved).st_mtime_ns if resolved else None
    except OSError:
        stamp = None
    key = f"{resolved}|{stamp}"
    if _model_cache["key"] != key:
        with warnings.catch_warnings(record=True) as caught:   # e.g. a partly trained model file
            warnings.simplefilter("always")
            _model_cache["model"] = rt.load_model(resolved or None)
        _model_cache["model"].warm_text()   # at load, not at the first prompt of a live rig
        _model_cache["key"] = key
        _model_cache["note"] = " ".join(str(w.message) for w in caught)
        if _model_cache["note"]:
            print(f"ReMoGen: {_model_cache['note']}")
    return _model_cache["model"]


def loaded_model():
    """The model already loaded for the live rig or a bake, or None; never loads one (the panel draws often)."""
    return _model_cache["model"]


def model_note() -> str:
    """A warning from loading the current model (empty when it loaded cleanly), for the panel."""
    return _model_cache["note"]


def clear_model_cache() -> None:
    _model_cache["key"] = None
    _model_cache["model"] = None
    _model_cache["note"] = ""


def _resolve_model_path(path: str) -> str:
    if not path:
        return ""
    try:
        import bpy
        path = bpy.path.abspath(path)  # "//model.pt" is relative to the .blend
    except ImportError:
        pass
    return os.path.abspath(os.path.expanduser(path))
