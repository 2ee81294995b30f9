"""Joint layouts: the names of each HPS tool's joints / 2D keypoints, in the tool's order.

A leaf module (it imports only :mod:`rotavat_cli.bodies.landmarks`, for SMPL's 24 joint names): whatever
addresses joints by name (the keypoint recipes of :mod:`rotavat_cli.formats.keypoints`, the skeletons
of :mod:`rotavat_cli.render.skeleton`, the posture angles of :mod:`rotavat_cli.bodies.posture`, the joint-order
check of :mod:`rotavat_cli.metrics.evaluate`) reads this one table. An importer records its layout in ``meta.yaml``
(``import.joints_layout``), sometimes with a description after the key
(``'phalp44 (OpenPose-25 + 19 extra)'``); :func:`layout_key` strips it. Files that store an
SMPL-family layout without naming it are recognised by their joint count (:func:`layout_by_count`).

>>> LAYOUT_NAMES["smpl24"].index("left_knee")
4
>>> LAYOUT_NAMES[layout_key("phalp44 (OpenPose-25 + 19 extra)")][:3]
('nose', 'neck', 'right_shoulder')
>>> layout_by_count(45), layout_by_count(17)
('smpl45', None)
"""

from __future__ import annotations

from .landmarks import SMPL_JOINT_NAMES

__all__ = ["LAYOUT_NAMES", "layout_by_count", "layout_key"]

# Keypoint names in order, from each tool's code.
# OpenPose BODY_25 (CMU-Perceptual-Computing-Lab/openpose, doc/02_output.md, "Pose Output Format (BODY_25)";
# the same order as agora_evaluation @c72c4a9 utils.py smpl_to_openpose 'coco25').
_OPENPOSE25 = ("nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder", "left_elbow",
               "left_wrist", "mid_hip", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle",
               "right_eye", "left_eye", "right_ear", "left_ear", "left_big_toe", "left_small_toe", "left_heel",
               "right_big_toe", "right_small_toe", "right_heel")
# SPIN's 24 extra joints after OpenPose's 25 (nkolot/SPIN @277892a constants.py JOINT_NAMES / JOINT_MAP; the first 19
# are 4D-Humans/PHALP's SMPL_to_J19 rows, which PHALP pads with one zero row to 45).
_SPIN_EXTRA24 = ("right_ankle_lsp", "right_knee_lsp", "right_hip_lsp", "left_hip_lsp", "left_knee_lsp",
                 "left_ankle_lsp", "right_wrist_lsp", "right_elbow_lsp", "right_shoulder_lsp", "left_shoulder_lsp",
                 "left_elbow_lsp", "left_wrist_lsp", "neck_lsp", "head_top_lsp", "pelvis_mpii", "thorax_mpii",
                 "spine_h36m", "jaw_h36m", "head_h36m", "nose_spin", "left_eye_spin", "right_eye_spin",
                 "left_ear_spin", "right_ear_spin")
# COCO-17 (cocodataset.org keypoints; mmpose/ViTPose 'coco' order).
_COCO17 = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder", "left_elbow",
           "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
           "right_ankle")
# Human3.6M 17 joints in the dataset's own order (facebookresearch/VideoPose3D h36m skeleton; HybrIK
# joints_name_17 'Pelvis', hips, knees, ankles, 'Torso', 'Neck', 'Nose', 'Head', shoulders, elbows, wrists).
_H36M17 = ("pelvis", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle", "spine",
           "thorax", "neck_nose", "head", "left_shoulder", "left_elbow", "left_wrist", "right_shoulder",
           "right_elbow", "right_wrist")
# smplx's vertex joints after SMPL's 24 (vchoutas/smplx vertex_joint_selector.py: face, feet, fingertips;
# the order of SMPL-45 from smplx.create(model_type='smpl'), used by AGORA (agora_evaluation @c72c4a9
# utils.py load_model, smpl_to_openpose: nose 24, eyes 25-26, ears 27-28, toes/heels 29-34) and CLIFF;
# Arthur151/ROMP @08209f2 simple_romp/romp/pack_smpl_info.py extra_joints_index lists the same 21).
_VERTEX_JOINTS21 = ("nose", "right_eye", "left_eye", "right_ear", "left_ear", "left_big_toe", "left_small_toe",
                    "left_heel", "right_big_toe", "right_small_toe", "right_heel", "left_thumb", "left_index",
                    "left_middle", "left_ring", "left_pinky", "right_thumb", "right_index", "right_middle",
                    "right_ring", "right_pinky")
# SPIN's J_regressor_extra rows (the joints 45-53 of SPIN's JOINT_MAP), used by simple_romp after SMPL-45
# (Arthur151/ROMP @012086a simple_romp/romp/smpl.py VertexJointSelector.forward: 24 + 21 + 9 + 17).
_REGRESSOR_EXTRA9 = ("right_hip_extra", "left_hip_extra", "neck_lsp", "head_top_lsp", "pelvis_mpii", "thorax_mpii",
                     "spine_h36m", "jaw_h36m", "head_h36m")
# simple_romp's last 17 (romp/smpl.py VertexJointSelector): J_regressor_h36m rows in SPIN's H36M_TO_J17 order
# [6, 5, 4, 1, 2, 3, 16, 15, 14, 11, 12, 13, 8, 10, 0, 7, 9] of the H36M order above.
_ROMP_J17 = tuple(f"h36m_{_H36M17[i]}" for i in (6, 5, 4, 1, 2, 3, 16, 15, 14, 11, 12, 13, 8, 10, 0, 7, 9))
# SMPL-X (vchoutas/smplx @4a05f0a joint_names.py JOINT_NAMES): 55 skeleton joints, then nose, eyes, ears, toes and
# heels (55-65), fingertips, 51 face landmarks (to 127) and 17 face-contour points (to 144).
_SMPLX_SKELETON = SMPL_JOINT_NAMES[:22] + ("jaw", "left_eye_smplhf", "right_eye_smplhf") + tuple(
    f"{side}_{finger}{k}" for side in ("left", "right") for finger in ("index", "middle", "pinky", "ring", "thumb")
    for k in (1, 2, 3))
_SMPLX144 = _SMPLX_SKELETON + _VERTEX_JOINTS21[:11] + _VERTEX_JOINTS21[11:] + tuple(
    f"face_{k}" for k in range(51)) + tuple(f"contour_{k}" for k in range(17))
# HybrIK-29 (Jeff-sjtu/HybrIK @078a7dd hybrik/models/layers/smpl/SMPL.py JOINT_NAMES; lbs.py leaf vertices
# [411, 2445, 5905, 3216, 6617]): SMPL's 24 (HybrIK calls 15 'jaw' and 22/23 'thumb'), then head top,
# middle fingers, big toes.
_HYBRIK29 = SMPL_JOINT_NAMES + ("head_top_411", "left_middle", "right_middle", "left_big_toe", "right_big_toe")
# TRACE's 44 (Arthur151/ROMP simple_romp/trace2 models/smpl.py): SMPL's 24, the first 11 vertex joints (face,
# toes, heels) and SPIN's 9 regressor rows (head top at 38).
_TRACE44 = SMPL_JOINT_NAMES + _VERTEX_JOINTS21[:11] + _REGRESSOR_EXTRA9
# GLAMR's body26fk (NVlabs/GLAMR @8c2213f lib/models/smpl.py get_ordered_joint_names("body26fk")).
_BODY26FK = ("pelvis_mpii", "left_hip", "right_hip", "spine_h36m", "left_knee", "right_knee", "neck", "left_ankle",
             "right_ankle", "left_big_toe", "right_big_toe", "left_small_toe", "right_small_toe", "left_heel",
             "right_heel", "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
             "left_elbow", "right_elbow", "left_wrist", "right_wrist")

LAYOUT_NAMES: dict[str, tuple[str, ...]] = {
    "openpose25": _OPENPOSE25,
    "spin49": _OPENPOSE25 + _SPIN_EXTRA24,
    "phalp44": _OPENPOSE25 + _SPIN_EXTRA24[:19],
    "phalp45": _OPENPOSE25 + _SPIN_EXTRA24[:19] + ("zero",),
    "coco17": _COCO17,
    "h36m17": _H36M17,
    "smpl24": SMPL_JOINT_NAMES,
    "smpl45": SMPL_JOINT_NAMES + _VERTEX_JOINTS21,
    "romp54": SMPL_JOINT_NAMES + _VERTEX_JOINTS21 + _REGRESSOR_EXTRA9,
    "romp71": SMPL_JOINT_NAMES + _VERTEX_JOINTS21 + _REGRESSOR_EXTRA9 + _ROMP_J17,
    "smplx127": _SMPLX144[:127],
    "smplx144": _SMPLX144,
    "hybrik29": _HYBRIK29,
    "trace44": _TRACE44,
    "body26fk": _BODY26FK,
}

# SMPL-family layouts by keypoint count (AGORA, BEDLAM, CLIFF store one of these without naming it).
_SMPL_FAMILY_BY_COUNT = {24: "smpl24", 29: "hybrik29", 45: "smpl45", 49: "spin49", 54: "romp54", 71: "romp71",
                         127: "smplx127", 144: "smplx144"}


def layout_by_count(n_keypoints: int) -> str | None:
    """The SMPL-family layout of ``n_keypoints`` points (24 SMPL, 45 smplx's SMPL, 127/144 SMPL-X, ...), or None."""
    return _SMPL_FAMILY_BY_COUNT.get(int(n_keypoints))


def layout_key(layout: str | None) -> str | None:
    """A layout's name without its description: 'phalp44 (OpenPose-25 + 19 extra)' is 'phalp44'."""
    return None if layout is None else str(layout).split(" ", 1)[0]
