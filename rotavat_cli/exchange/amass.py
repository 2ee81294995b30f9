"""AMASS-style parameter files: one ``.npz`` per person, as AMASS (Mahmood et al. 2019) ships its motions.

AMASS's keys: ``poses`` (N, 3 J) axis-angle, the root orientation first, then every other joint of the
model (SMPL+H: 156 numbers, SMPL-X: 165); ``trans`` (N, 3) m; ``betas`` (B,); ``gender``
(``neutral`` | ``male`` | ``female``); ``mocap_framerate`` (its SMPL+H releases; the SMPL-X ones call it
``mocap_frame_rate``: both are written). SMPL-X releases split ``poses`` into ``root_orient``,
``pose_body`` (21 joints), ``pose_hand`` (30), ``pose_jaw``, ``pose_eye``: those are written too, as far
as the model has the joints.

**AMASS's world is Z up** (its floor is the XY plane): Meshcapade's SMPL Blender add-on imports an AMASS
file with the body model's Y-up rest pose and turns the root by -90 degrees about X only when the scene is
Blender's own (Z up) rather than AMASS's ("AMASS target floor is XY ground plane for template in OpenGL
Y-up space", ``meshcapade_addon/blender.py``, ``correct_for_anim_format``). rotavat's world is Y up
(docs/conventions.md), so the root orientation and the pelvis are turned by :data:`R_AMASS_FROM_WORLD`
(+90 degrees about X: world up -> AMASS up, toward the camera -> -Y). ``trans`` is then what places the
pelvis there: ``trans = R p_world - J0(betas)`` (SMPL rotates about the pelvis joint, ``J0 + trans``).

What cannot be stored: ``smpl_scale`` (AMASS has no scale). The pelvis path is kept exact, so a person
scaled by ``s`` about the pelvis stands ``(s - 1)`` times its pelvis height off the ground (below it for
``s < 1``). Pose correctives are the reader's (the model's own), as AMASS's.

>>> (R_AMASS_FROM_WORLD @ [0.0, 1.0, 0.0]).tolist(), (R_AMASS_FROM_WORLD @ [0.0, 0.0, 1.0]).tolist()
([0.0, 0.0, 1.0], [0.0, -1.0, 0.0])
>>> gender_from_model_name("SMPLX_FEMALE.npz"), gender_from_model_name("basicmodel_m_lbs_10_207_0_v1.1.0.npz")
('female', 'male')
"""

from __future__ import annotations

import re

import numpy as np
from scipy.spatial.transform import Rotation

from ..formats.smpl import BodyModel
from .body import rest_shape

__all__ = ["R_AMASS_FROM_WORLD", "gender_from_model_name", "amass_arrays", "lift_m"]

# rotavat's world (Y up, Z toward the camera) -> AMASS's (Z up): +90 degrees about X
R_AMASS_FROM_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# SMPL-X's joint groups in ``poses`` order (vchoutas/smplx body_models.py SMPLX.forward: global_orient, body_pose,
# jaw_pose, leye_pose, reye_pose, left_hand_pose, right_hand_pose), SMPL-H's (body, hands)
_GROUPS = {55: {"pose_body": (1, 22), "pose_jaw": (22, 23), "pose_eye": (23, 25), "pose_hand": (25, 55)},
           52: {"pose_body": (1, 22), "pose_hand": (22, 52)}}


def gender_from_model_name(name: str) -> str | None:
    """``neutral``/``male``/``female`` from a model file's name (``SMPLX_NEUTRAL.npz``, ``SMPL_MALE.npz``,
    ``basicmodel_f_lbs_...``), or None when the name does not say."""
    lower = name.lower()
    for gender in ("female", "male", "neutral"):  # female first: it contains "male"
        if gender in lower:
            return gender
    match = re.search(r"(?:^|[_-])([fmn])(?:[_-]|$)", lower)
    return {"f": "female", "m": "male", "n": "neutral"}[match.group(1)] if match else None


def lift_m(model: BodyModel, betas: np.ndarray, scale: float) -> float:
    """How far above the ground (m) a person scaled by ``scale`` about the pelvis stands once unscaled with
    the pelvis kept in place: ``(scale - 1)`` times the pelvis's height above the rest mesh's lowest point."""
    verts, joints = rest_shape(model, betas)
    return float((scale - 1.0) * (joints[0, 1] - verts[:, 1].min()))


def amass_arrays(model: BodyModel, betas: np.ndarray, root_world_from_model: np.ndarray, body_pose: np.ndarray,
                 pelvis_world: np.ndarray, fps: float, gender: str) -> dict[str, np.ndarray]:
    """An AMASS-style file's arrays (float64; text as numpy unicode, read without pickle).

    betas: (B,) the person's shape; root_world_from_model: (N, 3, 3) root orientation in rotavat's world;
    body_pose: (N, J - 1, 3) axis-angle; pelvis_world: (N, 3) m; fps: frames per second.
    """
    n_frames, n_body = body_pose.shape[:2]
    root = Rotation.from_matrix(R_AMASS_FROM_WORLD @ np.asarray(root_world_from_model, np.float64)).as_rotvec()
    rest_root = rest_shape(model, betas)[1][0]
    trans = np.asarray(pelvis_world, np.float64) @ R_AMASS_FROM_WORLD.T - rest_root
    poses = np.concatenate([root[:, None], np.asarray(body_pose, np.float64)], axis=1)  # (N, J, 3)
    out = {"poses": poses.reshape(n_frames, -1), "trans": trans, "betas": np.asarray(betas, np.float64),
           "num_betas": np.array(len(betas)), "gender": np.array(gender),
           "mocap_framerate": np.array(float(fps)), "mocap_frame_rate": np.array(float(fps)),
           "surface_model_type": np.array(model.kind), "root_orient": root}
    for key, (start, stop) in _GROUPS.get(n_body + 1, {"pose_body": (1, min(22, n_body + 1))}).items():
        out[key] = poses[:, start:stop].reshape(n_frames, -1)
    return out
