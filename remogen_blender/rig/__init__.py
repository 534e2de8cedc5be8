"""Rigs, one module per job:

- `partner`: checking that the partner is an armature and reading its 22 SMPL-X joints through a bone map;
- `bone_map`: guessing the partner's and the target's bone maps and storing them in the scene settings;
- `ego`: creating the SMPL-X ego armature; `body`: its skinned body mesh (proxy capsules or SMPL-X);
- `pose`: writing model poses onto the ego's pose bones;
- `target`: retargeting those poses onto the user's own armature (`rotations`, `leg_ik`: its maths).

Pose-bone arrays are in Blender's depth-first hierarchy order, not SMPL-X order: every reader/writer
builds its index permutation once and reuses it per frame with `foreach_get` / `foreach_set`.
"""
from .bone_map import PARTNER, TARGET, bone_map_dict, ensure_bone_map, fill_bone_map
from .ego import EGO_MARK, build_armature, create_ego, ego_rest_heads
from .partner import PartnerReader, check_armature, check_partner
from .pose import EgoWriter
from .target import TargetWriter

__all__ = ["EGO_MARK", "EgoWriter", "PARTNER", "PartnerReader", "TARGET", "TargetWriter", "bone_map_dict",
           "build_armature", "check_armature", "check_partner", "create_ego", "ego_rest_heads",
           "ensure_bone_map", "fill_bone_map"]
