"""The "ReMoGen" tab in the 3D view sidebar."""
from __future__ import annotations

import bpy

from . import _runtime, deps, live


def _bone_ok(partner: bpy.types.Object | None, spec: str) -> bool:
    if partner is None or not spec:
        return False
    bones = partner.data.bones
    if spec.startswith("lerp:"):
        parts = spec.split(":")
        return len(parts) == 4 and parts[1] in bones and parts[2] in bones
    if spec.startswith("end:"):
        return spec[4:] in bones
    return spec in bones


class REMOGEN_UL_bone_map(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        partner = context.scene.remogen.partner
        row = layout.row(align=True)
        row.alert = not _bone_ok(partner, item.bone)
        split = row.split(factor=0.42)
        split.label(text=item.joint)
        split.prop(item, "bone", text="", emboss=True)


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
            mapped = sum(1 for it in st.bone_map if _bone_ok(st.partner, it.bone))
            row = col.row()
            row.alert = mapped < 22 and st.bone_map_rig == st.partner.name
            label = (f"Bone map: {st.bone_map_family or 'custom'} ({mapped}/22)"
                     if st.bone_map_rig == st.partner.name else "Bone map: not detected yet")
            row.label(text=label, icon='BONE_DATA')
            row.operator("remogen.guess_bone_map", text="", icon='FILE_REFRESH')
        col.prop(st, "scene_collection")
        col.prop(st, "goal")
        row = col.row(align=True)
        row.prop(st, "ego")
        row.operator("remogen.create_ego", text="", icon='ADD')
        if st.ego is None:
            col.operator("remogen.create_ego", icon='ARMATURE_DATA')

        col = layout.column(align=True)
        col.prop(st, "text", text="")
        text_note = _runtime.api().prompt_warning(st.text)   # torch-free: shown before PyTorch is installed too
        if text_note:
            col.label(text=text_note, icon='ERROR')
        col.prop(st, "alpha_hhi", slider=True)
        col.prop(st, "alpha_hsi", slider=True)
        col.prop(st, "guidance")
        row = col.row(align=True)
        row.prop(st, "seed")
        row.prop(st, "use_fwsr", toggle=True)
        row.prop(st, "use_foot_lock", toggle=True)

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


class REMOGEN_PT_bone_map(bpy.types.Panel):
    bl_label = "Bone Map"
    bl_idname = "REMOGEN_PT_bone_map"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "ReMoGen"
    bl_parent_id = "REMOGEN_PT_main"
    bl_options = {'DEFAULT_CLOSED'}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.scene.remogen.partner is not None

    def draw(self, context: bpy.types.Context) -> None:
        st = context.scene.remogen
        layout = self.layout
        layout.template_list("REMOGEN_UL_bone_map", "", st, "bone_map", st, "bone_map_index", rows=8)
        row = layout.row(align=True)
        row.operator("remogen.guess_bone_map")
        row.operator("remogen.bone_from_active")
        layout.label(text="Entries: a bone, lerp:A:B:0.5 or end:A", icon='INFO')


CLASSES = (REMOGEN_UL_bone_map, REMOGEN_PT_main, REMOGEN_PT_bone_map)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
