"""Rigs, one module per job:

- `partner`: checking that the partner is an armature and reading its 22 SMPL-X joints through a bone map;
- `bone_map`: guessing the partner's bone map and storing it in the scene settings;
- `ego`: creating the SMPL-X ego armature; `body`: its skinned body mesh (proxy capsules or SMPL-X);
- `pose`: writing model poses onto the ego's pose bones.

Pose-bone arrays are in Blender's depth-first hierarchy order, not SMPL-X order: every reader/writer
builds its index permutation once and reuses it per frame with `foreach_get` / `foreach_set`.
"""
from .bone_map import bone_map_dict, fill_bone_map
from .ego import EGO_MARK, create_ego, ego_rest_heads
from .partner import PartnerReader, check_partner
from .pose import EgoWriter

__all__ = ["EGO_MARK", "EgoWriter", "PartnerReader", "bone_map_dict", "check_partner", "create_ego",
           "ego_rest_heads", "fill_bone_map"]
