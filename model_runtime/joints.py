"""The 22-joint SMPL-X body: names, parents and rest positions. Plain Python and NumPy, no torch.

Numbers are the NEUTRAL SMPL-X body (betas = 0, rest pose) converted to Blender's Z-up world with
x' = x, y' = -z, z' = y. In that frame the rest body faces -Y and its left side is at +X. Only derived
skeleton numbers are stored here, never SMPL-X model data. The Blender extension reads these without
importing PyTorch.
"""
from __future__ import annotations

import numpy as np

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist",
)
NUM_JOINTS = 22
PARENTS: tuple[int, ...] = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}

# Rest joint positions, Z-up metres (reference file's `rest_zup`). The pelvis is not at the origin.
REST_JOINTS_ZUP: tuple[tuple[float, float, float], ...] = (
    (0.003123, -0.012037, -0.351407), (0.061313, 0.013965, -0.444171),
    (-0.060144, 0.009214, -0.455315), (0.000361, 0.015581, -0.241517),
    (0.116008, 0.023361, -0.822924), (-0.104354, 0.026038, -0.817696),
    (0.009808, 0.021521, -0.109664), (0.072555, 0.055237, -1.225984),
    (-0.088937, 0.046230, -1.228423), (-0.001522, -0.006926, -0.057428),
    (0.119812, -0.062980, -1.283981), (-0.127750, -0.072819, -1.286752),
    (-0.013687, 0.024690, 0.107739), (0.044842, 0.000295, 0.027515),
    (-0.049217, 0.006474, 0.026910), (0.011097, 0.003952, 0.268190),
    (0.164081, 0.015756, 0.085243), (-0.151795, 0.019143, 0.080435),
    (0.418204, 0.058214, 0.013093), (-0.422944, 0.045610, 0.043942),
    (0.670191, 0.060687, 0.036314), (-0.672212, 0.060935, 0.039410),
)
# The foot joints sit above the sole; this lifts a standing rest body so its soles touch z = 0.
SOLE_BELOW_FOOT_JOINT = 0.02
# the heel's sole lies this far below the ankle joint of a body standing flat (rest pose, soles on the floor)
ANKLE_ABOVE_SOLE = (REST_JOINTS_ZUP[JOINT_INDEX["left_ankle"]][2]
                    - min(REST_JOINTS_ZUP[JOINT_INDEX[f"{side}_foot"]][2] for side in ("left", "right"))
                    + SOLE_BELOW_FOOT_JOINT)
LEFT_HIP, RIGHT_HIP = JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]
FOOT_JOINTS = (JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"],
               JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"])




def rest_joints_np() -> np.ndarray:
    """(22, 3) float64 rest joints with the pelvis at the origin."""
    j = np.asarray(REST_JOINTS_ZUP, dtype=np.float64)
    return j - j[0]


def rest_offsets_np() -> np.ndarray:
    """(22, 3) float64 bone vectors joint - parent in the rest pose (row 0 is zero)."""
    j = np.asarray(REST_JOINTS_ZUP, dtype=np.float64)
    off = np.zeros_like(j)
    for i, p in enumerate(PARENTS):
        if p >= 0:
            off[i] = j[i] - j[p]
    return off


def standing_pelvis_height() -> float:
    """Pelvis height above the floor for the rest body standing upright."""
    j = np.asarray(REST_JOINTS_ZUP, dtype=np.float64)
    return float(j[0, 2] - j[list(FOOT_JOINTS), 2].min()) + SOLE_BELOW_FOOT_JOINT
