"""The "ReMoGen" tab in the 3D view sidebar."""
from __future__ import annotations

import bpy

from . import _runtime, deps, live, rig


def _bone_ok(ob: bpy.types.Object | None, spec: str) -> bool:
    if ob is None or not spec:
        return False
    bones = ob.data.bones
    if spec.startswith("lerp:"):
        parts = spec.split(":")
        return len(parts) == 4 and parts[1] in bones and parts[2] in bones
    if spec.startswith("end:"):
        return spec[4:] in bones
    return spec in bones


def _map_summary(layout: bpy.types.UILayout, st, ob: bpy.types.Object, slot) -> None:
    """"Bone map: mixamo (22/22)" with a Detect button; red when joints are unmapped."""
    rows = getattr(st, slot.rows)
    made_for = getattr(st, slot.rig) == ob.name
    mapped = sum(1 for it in rows if _bone_ok(ob, it.bone))
    row = layout.row()
    row.alert = mapped < 22 and made_for
    family = getattr(st, slot.family) or "custom"
    row.label(text=f"Bone map: {family} ({mapped}/22)" if made_for else "Bone map: not detected yet",
              icon='BONE_DATA')
    row.operator("remogen.guess_bone_map", text="", icon='FILE_REFRESH').target = slot is rig.TARGET


class REMOGEN_UL_bone_map(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        st = context.scene.remogen
        ob = st.target if active_propname.startswith("target_") else st.partner
        row = layout.row(align=True)
        row.alert = not _bone_ok(ob, item.bone)
        split = row.split(factor=0.42)
        split.label(text=item.joint)
        split.prop(item, "bone", text="", emboss=True)


class REMOGEN_UL_egos(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.alert = item.ego is None
        split = row.split(factor=0.45)
        split.label(text=f"{index + 2}. {item.ego.name if item.ego is not None else '(no armature)'}",
                    icon='ARMATURE_DATA')
        split.label(text=item.text)


# (model id, prompt) -> the note under the prompt: the panel redraws often, and a lookup costs about 1.6 ms
_NEAREST_NOTES: dict[tuple[int, str], str] = {}
NEAREST_NOTES_KEPT = 64
# A prompt this close to a training phrasing is read as written: no note
NEAREST_NOTE_BELOW = 0.999


def nearest_phrasing_note(text: str) -> str:
    """'Closest training phrasing: "someone is running" (0.66)' under a prompt in words the loaded model was not
    trained on, so the animator sees which motion it leans toward; empty without a loaded model, a prompt or the
    model file's phrasing record."""
    model = _runtime.loaded_model()
    if model is None or not text.strip():
        return ""
    key = (id(model), text)
    if key not in _NEAREST_NOTES:
        near = model.nearest_phrasing(text)
        _NEAREST_NOTES[key] = (f'Closest training phrasing: "{near[0]}" ({near[1]:.2f})'
                               if near is not None and near[1] < NEAREST_NOTE_BELOW else "")
        if len(_NEAREST_NOTES) > NEAREST_NOTES_KEPT:
            _NEAREST_NOTES.pop(next(iter(_NEAREST_NOTES)))
    return _NEAREST_NOTES[key]


def draw_ego_settings(layout: bpy.types.UILayout, src) -> bpy.types.UILayout:
    """The settings of one ego (scene.remogen for the first, an entry of the ego list for the others); returns
    the row of toggles, for the first ego's scene-wide toggles to join."""
    col = layout.column(align=True)
    col.prop(src, "text", text="")
    text_note = _runtime.api().prompt_warning(src.text)   # torch-free: shown before PyTorch is installed too
    if text_note:
        col.label(text=text_note, icon='ERROR')
    else:
        near = nearest_phrasing_note(src.text)
        if near:
            col.label(text=near, icon='INFO')
    col.prop(src, "alpha_hhi", slider=True)
    col.prop(src, "alpha_hsi", slider=True)
    col.prop(src, "guidance")
    row = col.row(align=True)
    row.prop(src, "seed")
    row.prop(src, "use_fwsr", toggle=True)
    return row


class REMOGEN_PT_main(bpy.types.Panel):
    bl_label = "ReMoGen"
    bl_idname = "REMOGEN_PT_main"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "ReMoGen"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        st = context.scene.remogen
        err = _runtime.torch_error()
        if err:
            box = layout.box()
            box.alert = True
            box.label(text="PyTorch is not installed", icon='ERROR')
            box.label(text="Install it from the add-on preferences (or use the offline zip)")
            box.operator("remogen.install_torch", icon='IMPORT')
            if deps.status.line:
                box.label(text=deps.status.line)

        col = layout.column()
        col.prop(st, "partner")
        if st.partner is not None:
            _map_summary(col, st, st.partner, rig.PARTNER)
        col.prop(st, "scene_collection")
        col.prop(st, "goal")
        row = col.row(align=True)
        row.prop(st, "ego")
        row.operator("remogen.create_ego", text="", icon='ADD')
        if st.ego is None and st.target is None:
            col.operator("remogen.create_ego", icon='ARMATURE_DATA')
        col.prop(st, "target")
        if st.target is not None:
            col.prop(st, "target_mode", text="")
            _map_summary(col, st, st.target, rig.TARGET)

        row = draw_ego_settings(layout, st)
        row.prop(st, "use_foot_lock", toggle=True)
        row.prop(st, "use_control", toggle=True)

        row = layout.row(align=True)
        row.scale_y = 1.4
        if live.is_running():
            row.operator("remogen.live_stop", icon='PAUSE')
        else:
            row.operator_context = 'INVOKE_DEFAULT'
            row.operator("remogen.live_start", icon='PLAY')
        row.operator("remogen.bake", icon='REC')
        if _runtime.model_note():
            layout.label(text=_runtime.model_note(), icon='ERROR')
        line = live.status_line()
        if line:
            layout.label(text=line, icon='ERROR' if line.startswith("Live stopped:") else 'INFO')


class REMOGEN_PT_egos(bpy.types.Panel):
    """More egos: each with its own armature and settings, reacting to the nearest other character."""
    bl_label = "More Egos"
    bl_idname = "REMOGEN_PT_egos"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "ReMoGen"
    bl_parent_id = "REMOGEN_PT_main"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context: bpy.types.Context) -> None:
        st = context.scene.remogen
        layout = self.layout
        row = layout.row()
        row.template_list("REMOGEN_UL_egos", "", st, "egos", st, "ego_index", rows=3)
        col = row.column(align=True)
        col.operator("remogen.ego_add", text="", icon='ADD')
        col.operator("remogen.ego_remove", text="", icon='REMOVE')
        if 0 <= st.ego_index < len(st.egos):
            item = st.egos[st.ego_index]
            layout.prop(item, "ego")
            draw_ego_settings(layout, item)
        layout.label(text="Each ego reacts to the nearest other character", icon='INFO')


def _draw_bone_map(layout: bpy.types.UILayout, st, slot) -> None:
    rows = slot.rows
    layout.template_list("REMOGEN_UL_bone_map", rows, st, rows, st, rows + "_index", rows=8)
    row = layout.row(align=True)
    row.operator("remogen.guess_bone_map").target = slot is rig.TARGET
    row.operator("remogen.bone_from_active").target = slot is rig.TARGET
    layout.label(text="Entries: a bone, lerp:A:B:0.5 or end:A", icon='INFO')


class _BoneMapPanel:
    """A rig's bone map: 22 SMPL-X joints -> bone names, editable (a collapsed sub-panel)."""
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "ReMoGen"
    bl_parent_id = "REMOGEN_PT_main"
    bl_options = {'DEFAULT_CLOSED'}
    slot = rig.PARTNER

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return getattr(context.scene.remogen, cls.slot.what.lower()) is not None


class REMOGEN_PT_bone_map(_BoneMapPanel, bpy.types.Panel):
    bl_label = "Bone Map"
    bl_idname = "REMOGEN_PT_bone_map"

    def draw(self, context: bpy.types.Context) -> None:
        _draw_bone_map(self.layout, context.scene.remogen, rig.PARTNER)


class REMOGEN_PT_target_bone_map(_BoneMapPanel, bpy.types.Panel):
    bl_label = "Target Bone Map"
    bl_idname = "REMOGEN_PT_target_bone_map"
    slot = rig.TARGET

    def draw(self, context: bpy.types.Context) -> None:
        _draw_bone_map(self.layout, context.scene.remogen, rig.TARGET)


CLASSES = (REMOGEN_UL_bone_map, REMOGEN_UL_egos, REMOGEN_PT_main, REMOGEN_PT_egos, REMOGEN_PT_bone_map,
           REMOGEN_PT_target_bone_map)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
