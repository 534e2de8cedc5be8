"""The live session: one FrameDriver driven by frame changes and (in the UI) a window-manager timer.

This is plain Python state so it works without a window: `remogen.live_start` run from a script or a
background process follows `scene.frame_set()` through a frame_change_post handler; started from the UI
(invoke) the modal operator adds a timer that also keeps the ego living while the timeline stands still.
Any error, Stop, Esc, or loading another file ends it and puts the ego and the target rig back as they
were before Live (their poses and their own actions). A save while Live runs writes them as they were
before Live, too.
"""
from __future__ import annotations

import time
from typing import Any

import bpy
from bpy.app.handlers import persistent

from ._runtime import error_line
from .ego_state import HeldAction, PoseSnapshot
from .frame import FrameDriver, scene_time


class LiveState:
    def __init__(self, driver: FrameDriver, scene: bpy.types.Scene) -> None:
        self.driver = driver
        self.scene_name = scene.name
        self.last_scene_time = scene_time(scene)
        self.last_wall = time.perf_counter()
        # every armature Live poses (the ego, the target): its pose and action before Live
        self.held = [(ob, PoseSnapshot.take(ob), HeldAction(ob)) for ob in driver.posed_objects]

    def take_actions_off(self) -> None:
        for ob, _pose, action in self.held:
            action.take_off(ob)

    def put_back(self) -> None:
        for ob, pose, action in self.held:
            pose.restore(ob)
            action.put_back(ob)


_state: LiveState | None = None
_message: str = ""          # the last status or error line, shown in the panel


def is_running() -> bool:
    return _state is not None


def state() -> LiveState | None:
    return _state


def message() -> str:
    return _message


def status_line() -> str:
    if _state is None:
        return _message
    d = _state.driver
    egos = len(d.group.egos)
    many = f", {egos} egos" if egos > 1 else ""
    return (f"ReMoGen live: {d.update_ms:.1f} ms/frame (model step {d.step_ms:.1f} ms{many}), "
            f"model frame {d.latest_index}")


def start(context: bpy.types.Context) -> LiveState:
    """Start (or restart) live on the context's scene. Raises UserError / RemogenError with one line."""
    global _state, _message
    if _state is not None:
        stop("restarted")
    scene = context.scene
    driver = FrameDriver(scene)
    st = LiveState(driver, scene)
    # An action on a posed armature would overwrite the live pose on every frame; it comes back on stop.
    st.take_actions_off()
    _state = st
    _add_handlers()
    try:
        driver.update(scene, context.evaluated_depsgraph_get())
    except BaseException as exc:
        stop(error_line(exc))
        raise
    _message = "Live running"
    return st


def stop(reason: str = "Stopped") -> None:
    """End live: handlers off, the ego and the target back as they were before Live (poses and actions)."""
    global _state, _message
    st, _state = _state, None
    _remove_handlers()
    _message = reason
    if st is not None:
        st.put_back()


def tick(context: bpy.types.Context) -> None:
    """One timer tick (UI): follow the timeline, or keep living in wall time while it stands still."""
    if _state is None:
        return
    scene = context.scene
    now = time.perf_counter()
    dt, _state.last_wall = now - _state.last_wall, now
    if scene.name != _state.scene_name:
        return
    screen = context.screen
    if screen is not None and screen.is_animation_playing:
        return          # playback: the frame-change handler follows the timeline; wall time must not add to it
    t = scene_time(scene)
    _guarded(lambda: (_state.driver.update(scene, context.evaluated_depsgraph_get())
                      if t != _state.last_scene_time
                      else _state.driver.advance_wall(scene, dt, context.evaluated_depsgraph_get())))
    if _state is not None:
        _state.last_scene_time = t


def _guarded(fn) -> None:
    """Run a live update; a predictable error stops live with its one-line message, others with their type."""
    try:
        fn()
    except ReferenceError:
        stop("Live stopped: the partner, the ego or the target was deleted")
        print(f"ReMoGen: {_message}")
    except Exception as exc:  # noqa: BLE001 - nothing may leave a half-running session behind
        stop(f"Live stopped: {error_line(exc)}")
        print(f"ReMoGen: {_message}")


# ---------------------------------------------------------------------------- handlers

def _on_frame_change(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    if _state is None or scene.name != _state.scene_name:
        return
    _guarded(lambda: _state.driver.update(scene, depsgraph))
    if _state is not None:
        _state.last_scene_time = scene_time(scene)


def _on_depsgraph_update(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    if _state is None or scene.name != _state.scene_name:
        return
    try:
        _state.driver.scene_cache.on_depsgraph_update(scene.remogen.scene_collection, depsgraph)
    except ReferenceError:
        _state.driver.scene_cache.mark_dirty()


@persistent
def _on_load(*_args: Any) -> None:
    if _state is not None:
        stop("Live stopped: another file was loaded")


def _on_save_pre(*_args: Any) -> None:
    """The file gets the ego and the target as they were before Live: their own actions assigned, their poses."""
    if _state is not None:
        _state.put_back()


def _on_save_post(*_args: Any) -> None:
    """Back to live: the action off again, the live pose shown again."""
    if _state is not None:
        _guarded(_resume_after_save)


def _resume_after_save() -> None:
    _state.take_actions_off()
    _state.driver.show_latest()


_HANDLERS = (("frame_change_post", _on_frame_change), ("depsgraph_update_post", _on_depsgraph_update),
             ("load_pre", _on_load), ("save_pre", _on_save_pre), ("save_post", _on_save_post))


def _add_handlers() -> None:
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)


def _remove_handlers() -> None:
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        while fn in lst:
            lst.remove(fn)

