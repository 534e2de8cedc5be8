"""Operators: create the ego, the ego list, live start/stop, bake, and bone-map editing. Each reports one line
on failure."""
import bpy
from bpy.props import BoolProperty, IntProperty

from . import live, rig
from ._runtime import UserError, error_line, remogen_errors

TIMER_INTERVAL = 1.0 / 60.0
BAKE_TICK_SECONDS = 0.1    # model frames generated per timer tick of a UI bake: the UI stays responsive


def _fail(op: bpy.types.Operator, exc: BaseException) -> set[str]:
    op.report({'ERROR'}, error_line(exc))
    return {'CANCELLED'}


class REMOGEN_OT_create_ego(bpy.types.Operator):
    """Create an SMPL-X ego armature with a skinned body at the 3D cursor"""
    bl_idname = "remogen.create_ego"
    bl_label = "Create Ego"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context: bpy.types.Context) -> set[str]:
        from .preferences import get_prefs
        prefs = get_prefs()
        try:
            ob = rig.create_ego(context, location=tuple(context.scene.cursor.location),
                                smplx_folder=prefs.smplx_folder if prefs else "")
        except remogen_errors() as exc:
            return _fail(self, exc)
        context.scene.remogen.ego = ob
        self.report({'INFO'}, f"Created ego '{ob.name}'")
        return {'FINISHED'}


EGO_SPACING = 1.0   # m along +X between egos added at the 3D cursor, so that they do not start inside each other


class REMOGEN_OT_ego_add(bpy.types.Operator):
    """Add an ego to the list: a new SMPL-X ego armature next to the 3D cursor, with its own settings"""
    bl_idname = "remogen.ego_add"
    bl_label = "Add Ego"
    bl_options = {'REGISTER', 'UNDO'}

    create: BoolProperty(name="Create Armature", default=True,
                         description="Create an SMPL-X ego armature for the entry (off: pick one yourself)")

    def execute(self, context: bpy.types.Context) -> set[str]:
        from .preferences import get_prefs
        st = context.scene.remogen
        ob = None
        if self.create:
            prefs = get_prefs()
            cursor = context.scene.cursor.location
            place = (cursor.x + EGO_SPACING * (len(st.egos) + 1), cursor.y, cursor.z)
            try:
                ob = rig.create_ego(context, name="SMPLX_Ego", location=place,
                                    smplx_folder=prefs.smplx_folder if prefs else "")
            except remogen_errors() as exc:
                return _fail(self, exc)
        item = st.egos.add()
        item.ego = ob
        item.seed = len(st.egos)        # another seed than the first ego's, so that they do not move alike
        st.ego_index = len(st.egos) - 1
        self.report({'INFO'}, f"Added ego {len(st.egos) + 1}" + (f" '{ob.name}'" if ob is not None else ""))
        return {'FINISHED'}


class REMOGEN_OT_ego_remove(bpy.types.Operator):
    """Remove the selected ego from the list (its armature stays in the file)"""
    bl_idname = "remogen.ego_remove"
    bl_label = "Remove Ego"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        st = context.scene.remogen
        return 0 <= st.ego_index < len(st.egos)

    def execute(self, context: bpy.types.Context) -> set[str]:
        st = context.scene.remogen
        if not 0 <= st.ego_index < len(st.egos):
            self.report({'ERROR'}, "Select an ego of the list first")
            return {'CANCELLED'}
        ob = st.egos[st.ego_index].ego
        st.egos.remove(st.ego_index)
        st.ego_index = min(st.ego_index, len(st.egos) - 1)
        kept = f"; armature '{ob.name}' kept" if ob is not None else ""
        self.report({'INFO'}, f"Removed the ego from the list{kept}")
        return {'FINISHED'}


class REMOGEN_OT_live_start(bpy.types.Operator):
    """React live: follow the partner, the scene and the sliders every frame (Esc or Stop ends it)"""
    bl_idname = "remogen.live_start"
    bl_label = "Start Live"

    _timer = None
    _state = None

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return hasattr(context.scene, "remogen")

    def _start(self, context: bpy.types.Context) -> bool:
        try:
            live.start(context)
        except (ReferenceError, *remogen_errors()) as exc:
            _fail(self, exc)
            return False
        return True

    def execute(self, context: bpy.types.Context) -> set[str]:
        # Without a window event loop (scripts, background): frame changes drive it.
        if not self._start(context):
            return {'CANCELLED'}
        self.report({'INFO'}, "Live started (follows frame changes)")
        return {'FINISHED'}

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if not self._start(context):
            return {'CANCELLED'}
        wm = context.window_manager
        self._timer = wm.event_timer_add(TIMER_INTERVAL, window=context.window)
        wm.modal_handler_add(self)
        self._state = live.state()
        return {'RUNNING_MODAL'}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        if not live.is_running():          # Stop button, an error in a handler, or a file load
            return self._finish(context, report=True)
        if live.state() is not self._state:   # Start pressed again: the newer modal owns the session
            cleanup_modal(context, self._timer, clear_status=False)
            self._timer = None
            return {'CANCELLED'}
        if event.type == 'ESC' and event.value == 'PRESS':
            live.stop("Stopped (Esc)")
            return self._finish(context)
        if event.type == 'TIMER' and event.time_duration >= 0 and self._timer is not None:
            live.tick(context)
            if not live.is_running():
                return self._finish(context, report=True)
            if context.workspace is not None:
                context.workspace.status_text_set(live.status_line())
        return {'PASS_THROUGH'}

    def _finish(self, context: bpy.types.Context, report: bool = False) -> set[str]:
        cleanup_modal(context, self._timer)
        self._timer = None
        msg = live.message()
        if report and msg.startswith("Live stopped:"):
            self.report({'ERROR'}, msg)
        return {'CANCELLED'}

    def cancel(self, context: bpy.types.Context) -> None:   # Blender cancels modals on file load / quit
        live.stop("Live stopped: cancelled")
        cleanup_modal(context, self._timer)
        self._timer = None


def cleanup_modal(context: bpy.types.Context, timer, clear_status: bool = True) -> None:
    """Remove the modal's timer and status text (safe to call twice, or with no timer)."""
    if timer is not None:
        try:
            context.window_manager.event_timer_remove(timer)
        except (ReferenceError, ValueError, RuntimeError):
            pass
    if clear_status and context.workspace is not None:
        context.workspace.status_text_set(None)


class REMOGEN_OT_live_stop(bpy.types.Operator):
    """Stop live and put the ego and the target back as they were before Live"""
    bl_idname = "remogen.live_stop"
    bl_label = "Stop"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return live.is_running()

    def execute(self, context: bpy.types.Context) -> set[str]:
        live.stop("Stopped")
        return {'FINISHED'}


class ModalBake:
    """A bake run a chunk of model frames per timer tick, with progress in the status bar and the cursor.

    The operator's modal() only forwards events here, so the stepping and cancelling work (and are
    tested) without a window.
    """

    def __init__(self, context: bpy.types.Context, job, timer: bool = False) -> None:
        self.job = job
        self.timer = None
        wm = context.window_manager
        wm.progress_begin(0, job.total)
        if timer:
            self.timer = wm.event_timer_add(TIMER_INTERVAL, window=context.window)
        self._show(context)

    def _show(self, context: bpy.types.Context) -> None:
        context.window_manager.progress_update(self.job.done)
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"ReMoGen bake: {self.job.done:,} / {self.job.total:,} model frames "
                f"({100 * self.job.done // max(self.job.total, 1)} %), Esc or right-click to cancel")

    def tick(self, context: bpy.types.Context, seconds: float = BAKE_TICK_SECONDS) -> bool:
        """Generate for about `seconds`; True when every model frame is generated. Errors end the bake."""
        try:
            done = self.job.step(seconds=seconds)
        except BaseException:
            self.close(context)
            raise
        self._show(context)
        return done

    def finish(self, context: bpy.types.Context):
        """Key the frames (the bake's only change) and end; returns the BakeResult."""
        try:
            return self.job.finish()
        finally:
            self.close(context)

    def cancel(self, context: bpy.types.Context) -> None:
        """Stop: the ego, its action and the scene stay exactly as before the bake."""
        self.job.cancel()
        self.close(context)

    def close(self, context: bpy.types.Context) -> None:
        context.window_manager.progress_end()
        cleanup_modal(context, self.timer)
        self.timer = None


class REMOGEN_OT_bake(bpy.types.Operator):
    """Generate the frame range for the seed and key it into a new action on each posed armature (Esc cancels)"""
    bl_idname = "remogen.bake"
    bl_label = "Bake"
    bl_options = {'REGISTER', 'UNDO'}

    frame_start: IntProperty(name="Start", default=-1, description="-1: the scene's start")
    frame_end: IntProperty(name="End", default=-1, description="-1: the scene's end")

    _run = None     # the ModalBake of an invoked (UI) bake

    def _job(self, context: bpy.types.Context):
        from .bake import BakeJob
        if live.is_running():
            live.stop("Stopped for baking")
        scene = context.scene
        f0 = scene.frame_start if self.frame_start < 0 else self.frame_start
        f1 = scene.frame_end if self.frame_end < 0 else self.frame_end
        return BakeJob(scene, f0, f1)

    def execute(self, context: bpy.types.Context) -> set[str]:
        # Scripts and background runs: the whole bake now, with the progress cursor.
        try:
            run = ModalBake(context, self._job(context))
            while not run.tick(context):
                pass
            res = run.finish(context)
        except (ReferenceError, *remogen_errors()) as exc:
            return _fail(self, exc)
        return self._report(res)

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        try:
            self._run = ModalBake(context, self._job(context), timer=True)
        except (ReferenceError, *remogen_errors()) as exc:
            return _fail(self, exc)
        context.window_manager.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[str]:
        run = self._run
        if event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
            run.cancel(context)
            self.report({'INFO'}, "Bake cancelled; nothing was changed")
            return {'CANCELLED'}
        if event.type != 'TIMER':
            return {'RUNNING_MODAL'}     # the scene must not change under the bake: other events wait
        try:
            if not run.tick(context):
                return {'RUNNING_MODAL'}
            res = run.finish(context)
        except (ReferenceError, *remogen_errors()) as exc:
            return _fail(self, exc)
        return self._report(res)

    def cancel(self, context: bpy.types.Context) -> None:   # Blender cancels modals on file load / quit
        if self._run is not None:
            self._run.cancel(context)

    def _report(self, res) -> set[str]:
        into = " and ".join(f"'{act.name}'" + (f" (previous action '{old}' kept)" if old else "")
                            for _ob, act, old in res.keyed)
        self.report({'INFO'}, f"Baked {res.frames} frames ({res.model_frames} model frames, {res.model_fps:.0f}/s) "
                              f"into {into}")
        return {'FINISHED'}


_TARGET_MAP_HELP = "The target rig's bone map instead of the partner's"


def _map_slot(st, target: bool):
    """(the rig whose map is edited, where the map lives) for the partner or the target."""
    return (st.target, rig.TARGET) if target else (st.partner, rig.PARTNER)


class REMOGEN_OT_guess_bone_map(bpy.types.Operator):
    """Detect the rig's bone map from its bone names (SMPL-X, Mixamo, BVH/CMU, Rigify, Bandai, ...)"""
    bl_idname = "remogen.guess_bone_map"
    bl_label = "Detect Bone Map"
    bl_options = {'REGISTER', 'UNDO'}

    target: BoolProperty(name="Target", default=False, description=_TARGET_MAP_HELP)

    def execute(self, context: bpy.types.Context) -> set[str]:
        st = context.scene.remogen
        ob, slot = _map_slot(st, self.target)
        if ob is None:
            self.report({'ERROR'}, f"Pick a {slot.what.lower()} armature first")
            return {'CANCELLED'}
        try:
            missing = rig.fill_bone_map(st, ob, slot=slot)
        except remogen_errors() as exc:
            return _fail(self, exc)
        if missing:
            self.report({'WARNING'}, f"{slot.what} '{ob.name}': no bones found for {', '.join(missing[:6])}"
                                     f"{' ...' if len(missing) > 6 else ''}; map them by hand")
        else:
            self.report({'INFO'}, f"Bone map: {getattr(st, slot.family)}, all 22 joints mapped")
        return {'FINISHED'}


class REMOGEN_OT_bone_from_active(bpy.types.Operator):
    """Map the selected SMPL-X joint to the rig's active bone"""
    bl_idname = "remogen.bone_from_active"
    bl_label = "Use Active Bone"
    bl_options = {'REGISTER', 'UNDO'}

    target: BoolProperty(name="Target", default=False, description=_TARGET_MAP_HELP)

    def execute(self, context: bpy.types.Context) -> set[str]:
        st = context.scene.remogen
        ob, slot = _map_slot(st, self.target)
        rows = getattr(st, slot.rows)
        index = getattr(st, slot.rows + "_index")
        if ob is None or not (0 <= index < len(rows)):
            self.report({'ERROR'}, f"Pick a {slot.what.lower()} and a bone-map row first")
            return {'CANCELLED'}
        bone = ob.data.bones.active
        if bone is None:
            self.report({'ERROR'}, f"{slot.what} '{ob.name}' has no active bone; select one in Pose Mode")
            return {'CANCELLED'}
        rows[index].bone = bone.name
        setattr(st, slot.rig, ob.name)
        return {'FINISHED'}


CLASSES = (REMOGEN_OT_create_ego, REMOGEN_OT_ego_add, REMOGEN_OT_ego_remove, REMOGEN_OT_live_start,
           REMOGEN_OT_live_stop, REMOGEN_OT_bake,
           REMOGEN_OT_guess_bone_map, REMOGEN_OT_bone_from_active)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    if live.is_running():
        live.stop("Add-on disabled")
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)


__all__ = ["CLASSES", "register", "unregister", "UserError"]
