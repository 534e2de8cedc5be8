"""Add-on preferences: model file, SMPL-X model folder, CPU threads, the diffusion helper process, and installing
PyTorch."""
import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty

from . import _runtime, deps


def get_prefs() -> "RemogenPreferences | None":
    addon = bpy.context.preferences.addons.get(__package__)
    return addon.preferences if addon is not None else None


def _model_changed(_self, _context) -> None:
    _runtime.clear_model_cache()


class RemogenPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    model_file: StringProperty(
        name="Model file", subtype='FILE_PATH', default="", update=_model_changed,
        description="A ReMoGen .pt model; empty uses the weights shipped with the add-on")
    smplx_folder: StringProperty(
        name="SMPL-X model folder", subtype='DIR_PATH', default="",
        description="Your own SMPL-X model folder (with SMPLX_NEUTRAL.npz) for the real body mesh; needs the "
                    "'smplx' Python package. Empty uses a simple proxy body")
    cpu_threads: IntProperty(
        name="CPU threads", default=1, min=0, max=256, update=_model_changed,
        description="Threads PyTorch may use. 1 is fastest for the default model: PyTorch's threads spin "
                    "against Blender's own (measured 200x slower with 2 on a busy 2-core machine). "
                    "0 keeps PyTorch's own choice")
    helper_process: BoolProperty(
        name="Diffusion in a helper process", default=True,
        description="Run each segment's diffusion in a second Python process while Blender plays frames: the "
                    "same motion, a fraction of the work per frame on Blender's thread (uses a second CPU core; "
                    "starts in a second or two, meanwhile it runs in Blender)")
    torch_requirement: StringProperty(
        name="PyTorch requirement", default=deps.DEFAULT_REQUIREMENT,
        description="What 'Install PyTorch' asks pip for")
    torch_index: StringProperty(
        name="Package index", default=deps.DEFAULT_INDEX,
        description="Where pip downloads PyTorch from (the CPU build by default)")

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        layout.prop(self, "model_file")
        layout.prop(self, "smplx_folder")
        layout.prop(self, "cpu_threads")
        layout.prop(self, "helper_process")
        box = layout.box()
        err = _runtime.torch_error()
        if err:
            box.label(text=err, icon='ERROR')
        else:
            box.label(text="PyTorch is available", icon='CHECKMARK')
        row = box.row()
        row.enabled = not deps.status.running
        row.operator("remogen.install_torch", icon='IMPORT')
        refusal = deps.offline_refusal(self.torch_index or None)
        if refusal and deps.status.line != refusal:
            box.label(text=refusal, icon='ERROR')
        if deps.status.line:
            box.label(text=deps.status.line, icon='INFO' if deps.status.ok or deps.status.running else 'ERROR')
        col = box.column(align=True)
        col.prop(self, "torch_requirement")
        col.prop(self, "torch_index")


class REMOGEN_OT_install_torch(bpy.types.Operator):
    """Download and install the CPU build of PyTorch into this add-on's private folder"""
    bl_idname = "remogen.install_torch"
    bl_label = "Install PyTorch"

    def execute(self, context: bpy.types.Context) -> set[str]:
        if deps.status.running:
            self.report({'WARNING'}, "PyTorch is already being installed")
            return {'CANCELLED'}
        prefs = get_prefs()
        req = prefs.torch_requirement if prefs else deps.DEFAULT_REQUIREMENT
        index = prefs.torch_index if prefs else deps.DEFAULT_INDEX
        refusal = deps.offline_refusal(index or None)
        if refusal:       # before any folder is made or pip started
            deps.status.ok, deps.status.line, deps.status.done = False, refusal, True
            self.report({'ERROR'}, refusal)
            return {'CANCELLED'}
        target = _runtime.private_site_packages(create=True)
        if target is None:
            self.report({'ERROR'}, "No folder to install PyTorch into (is the add-on installed as an extension?)")
            return {'CANCELLED'}
        if bpy.app.background:   # no event loop to poll a thread: run it here
            ok, line = deps.install(target, req, index or None)
            deps.status.ok, deps.status.line, deps.status.done = ok, line, True
            _after_install(ok)
            self.report({'INFO'} if ok else {'ERROR'}, line)
            return {'FINISHED'} if ok else {'CANCELLED'}
        deps.install_async(target, req, index or None)
        bpy.app.timers.register(_poll_install, first_interval=0.5)
        self.report({'INFO'}, "Installing PyTorch in the background; see the add-on preferences for progress")
        return {'FINISHED'}


def _after_install(ok: bool) -> None:
    if ok:
        _runtime.forget_torch_check()
        _runtime.add_private_site_packages()


def _poll_install() -> float | None:
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type in {'PREFERENCES', 'VIEW_3D'}:
                area.tag_redraw()
    if deps.status.running:
        return 0.5
    _after_install(deps.status.ok)
    return None


CLASSES = (RemogenPreferences, REMOGEN_OT_install_torch)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    if bpy.app.timers.is_registered(_poll_install):
        bpy.app.timers.unregister(_poll_install)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
