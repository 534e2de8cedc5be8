"""`scene.remogen`: the settings an animator edits (names are the public contract), the list of further
egos, and the bone maps."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, IntProperty,
                       PointerProperty, StringProperty)

from ._runtime import api

# Hard limits (Blender clamps to them): the runtime's own guidance bound (far beyond the trained range the
# output blows up: 1e30 gives NaN joints); the seed is a 32-bit property.
GUIDANCE_MAX = float(api().MAX_GUIDANCE)
GUIDANCE_DEFAULT = float(api().DEFAULT_GUIDANCE)    # the runtime's, chosen with the shipped weights
SEED_MAX = 2**31 - 1
_GUIDANCE_HELP = f"Classifier-free guidance on the text (0 to {GUIDANCE_MAX:g})"


def _is_armature(_self, ob: bpy.types.Object) -> bool:
    return ob.type == 'ARMATURE'


def _is_target_candidate(self: "RemogenSettings", ob: bpy.types.Object) -> bool:
    return ob.type == 'ARMATURE' and ob != self.partner and ob != self.ego


def _partner_changed(self: "RemogenSettings", _context: bpy.types.Context) -> None:
    # A new partner gets an automatic bone map; a failure leaves the old one and the panel says why.
    from . import rig
    if self.partner is not None and self.bone_map_rig != self.partner.name:
        rig.fill_bone_map(self, self.partner, quiet=True)


def _target_changed(self: "RemogenSettings", _context: bpy.types.Context) -> None:
    from . import rig
    if self.target is not None and self.target_bone_map_rig != self.target.name:
        rig.fill_bone_map(self, self.target, quiet=True, slot=rig.TARGET)


class RemogenBoneMapItem(bpy.types.PropertyGroup):
    """One SMPL-X joint and the rig's bone (or "lerp:A:B:t", "end:A") that gives its position."""
    joint: StringProperty(name="Joint", description="SMPL-X body joint")
    bone: StringProperty(name="Bone", description="The rig's bone name, 'lerp:A:B:t' (a point between two "
                         "bones' heads) or 'end:A' (the tail of bone A)")


class RemogenEgoSettings:
    """What one ego does: the scene's first ego keeps these on `scene.remogen`, every other ego on its entry
    of `scene.remogen.egos` (shared here so both stay alike)."""
    text: StringProperty(
        name="Intent", default="walk to the person and wave", description="What the ego should do")
    alpha_hhi: FloatProperty(
        name="Partner (HHI)", default=1.0, min=0.0, max=1.0, subtype='FACTOR',
        description="How strongly the ego reacts to the nearest other character: the partner or another ego")
    alpha_hsi: FloatProperty(
        name="Scene (HSI)", default=1.0, min=0.0, max=1.0, subtype='FACTOR',
        description="How strongly the ego reacts to the scene meshes and the goal")
    guidance: FloatProperty(
        name="Guidance", default=GUIDANCE_DEFAULT, min=0.0, max=GUIDANCE_MAX, soft_max=10.0,
        description=_GUIDANCE_HELP)
    seed: IntProperty(
        name="Seed", default=0, min=0, max=SEED_MAX,
        description="Same seed and inputs give the same motion")
    use_fwsr: BoolProperty(
        name="FWSR", default=True, description="Frame-wise segment refinement: react within a frame")


class RemogenEgoItem(RemogenEgoSettings, bpy.types.PropertyGroup):
    """One more ego of the scene: its armature and its own settings."""
    ego: PointerProperty(
        name="Ego", type=bpy.types.Object, poll=_is_armature,
        description="An SMPL-X ego armature (press + in the More Egos list to create one)")


class RemogenSettings(RemogenEgoSettings, bpy.types.PropertyGroup):
    partner: PointerProperty(
        name="Partner", type=bpy.types.Object, poll=_is_armature, update=_partner_changed,
        description="The armature the ego reacts to")
    scene_collection: PointerProperty(
        name="Scene", type=bpy.types.Collection,
        description="Meshes the ego must walk around (voxelised once, rebuilt when they change)")
    goal: PointerProperty(
        name="Goal", type=bpy.types.Object, description="Optional object the ego heads for")
    ego: PointerProperty(
        name="Ego", type=bpy.types.Object, poll=_is_armature,
        description="The generated SMPL-X character (press Create Ego)")
    target: PointerProperty(
        name="Target", type=bpy.types.Object, poll=_is_target_candidate, update=_target_changed,
        description="Your own humanoid armature: ReMoGen poses it from the ego's motion (retargeted), "
                    "instead of the ego or beside it")
    target_mode: EnumProperty(
        name="Pose", default='TARGET',
        items=(('TARGET', "Target only", "Pose only the target; the motion starts where the target stands "
                "and no ego is needed"),
               ('BOTH', "Target and ego", "Pose the ego and the target; the target does the ego's motion "
                "from its own place and facing")),
        description="Which armatures Live and Bake pose when a target is set")
    use_foot_lock: BoolProperty(
        name="Plant Feet", default=True,
        description="Keep a foot that touches the floor fixed there, and lift a foot swept fast across the floor "
                    "into a step (leg IK on the generated pose)")
    use_control: BoolProperty(
        name="Steer", default=True,
        description="Test-time control: steer each segment away from the partner and obstacles, toward the goal, "
                    "and against foot sliding (the alpha sliders scale the partner and scene parts)")

    # More egos: each reacts to the nearest other character, partner or ego; all are stepped together.
    egos: CollectionProperty(type=RemogenEgoItem)
    ego_index: IntProperty(name="Ego row", default=0)

    # Bone map storage (shown and editable in the panel).
    bone_map: CollectionProperty(type=RemogenBoneMapItem)
    bone_map_index: IntProperty(name="Bone map row", default=0)
    bone_map_family: StringProperty(name="Rig family", default="")
    bone_map_rig: StringProperty(
        name="Mapped rig", default="", description="The partner object the bone map was made for")
    show_bone_map: BoolProperty(name="Show bone map", default=False)
    target_bone_map: CollectionProperty(type=RemogenBoneMapItem)
    target_bone_map_index: IntProperty(name="Target bone map row", default=0)
    target_bone_map_family: StringProperty(name="Target rig family", default="")
    target_bone_map_rig: StringProperty(
        name="Mapped target", default="", description="The target object the target bone map was made for")


CLASSES = (RemogenBoneMapItem, RemogenEgoItem, RemogenSettings)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.remogen = PointerProperty(type=RemogenSettings)


def unregister() -> None:
    del bpy.types.Scene.remogen
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
