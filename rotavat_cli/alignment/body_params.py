"""Body-model parameters through RotAvat: the aligned people's SMPL parameters, in the camera and the world.

RotAvat moves each person by one similarity ``X' = s R X + b`` (:func:`.transform.affine_maps`): a
rotation, a uniform scale and a translation, the body never deformed. SMPL poses a body as
``M(betas, theta, transl)``: the root orientation turns the body about its root joint (the pelvis,
``J0(betas) + transl``), the other joints' rotations are relative to their parents. So the aligned body
is the same model posed with

- the same ``betas`` and ``body_pose`` (every non-root joint keeps its rotation relative to its parent),
- the root orientation ``R R0`` (camera frame), or ``R_world_from_cam R R0`` (world frame),
- the pelvis moved as a point, ``p' = s R p + b``; ``transl' = p' - J0(betas)``, where
  ``J0(betas) = smpl_pelvis - smpl_transl`` needs no model,
- and the scale ``s`` about the pelvis: ``vertices = p' + s (M(betas, theta', transl') - p')``.

A person align leaves unchanged (a flag of :data:`.transform.FLAGS`) keeps their parameters and gets
``smpl_scale = 1``. Aligning an aligned sequence again composes the scales. The keys are ``sequence.SMPL_PARAM_KEYS`` and ``sequence.WORLD_PARAM_KEYS``; the
contract's page (docs/conventions.md, "Body-model parameters") says how a tool without scale uses them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..geometry.camera import Camera
from ..geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from ..sequence import SMPL_PARAM_KEYS
from .transform import AlignTransform, affine_maps

__all__ = ["aligned_body_params", "person_similarities"]


def person_similarities(transform: AlignTransform) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each person's move as a similarity ``X' = s R X + b``: scale (P,), rotation (P, 3, 3), offset (P, 3) m.

    People the transform leaves unchanged (flagged) get ``s = 1``, ``R = I``, ``b = 0``, as
    :func:`.transform.apply_transforms` leaves their points.
    """
    A, b = affine_maps(transform)
    ok = transform.ok
    scale = np.where(ok, transform.depth_scale * transform.final_scale, 1.0)
    rotation = np.where(ok[:, None, None], transform.rotation, np.eye(3))
    offset = np.where(ok[:, None], b, 0.0)
    return scale, rotation, offset


def _axis_angle_matrices(rotvec: np.ndarray) -> np.ndarray:
    """Axis-angle (P, 3) -> rotation matrices (P, 3, 3)."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    return axis_angle_to_matrix(rotvec, np.linalg.norm(rotvec, axis=-1))


def aligned_body_params(data: Mapping[str, np.ndarray], transform: AlignTransform,
                        camera: Camera) -> dict[str, np.ndarray]:
    """The aligned frame's body-model keys, or {} when the frame carries no parameters.

    data: the input frame's arrays (``SMPL_PARAM_KEYS``, camera frame, P people); transform: the
    frame's RotAvat transforms; camera: the camera the aligned frame lives in (its world frame).
    Returns float64 arrays: ``smpl_global_orient`` (P, 3), ``smpl_transl`` (P, 3), ``smpl_pelvis``
    (P, 3) of the aligned body (camera frame), ``smpl_scale`` (P,), ``world_global_orient`` (P, 3),
    ``world_transl`` (P, 3) (the camera's world frame, Y up, metres). ``smpl_betas`` and
    ``smpl_body_pose`` are unchanged (copied through with the frame's other keys).
    """
    if not all(key in data for key in SMPL_PARAM_KEYS):
        return {}
    scale, rotation, offset = person_similarities(transform)
    root_cam = _axis_angle_matrices(data["smpl_global_orient"])  # (P, 3, 3)
    pelvis = np.asarray(data["smpl_pelvis"], dtype=np.float64)
    rest_root = pelvis - np.asarray(data["smpl_transl"], dtype=np.float64)  # J0(betas): the model's own
    new_root_cam = rotation @ root_cam
    new_pelvis = scale[:, None] * np.einsum("pij,pj->pi", rotation, pelvis) + offset
    world_from_cam = camera.R_cam_from_world.T
    pelvis_world = camera.world_from_cam(new_pelvis)
    return {
        "smpl_global_orient": matrix_to_axis_angle(new_root_cam),
        "smpl_transl": new_pelvis - rest_root,
        "smpl_pelvis": new_pelvis,
        "smpl_scale": scale * np.asarray(data.get("smpl_scale", 1.0), dtype=np.float64),  # an aligned input's composes
        "world_global_orient": matrix_to_axis_angle(world_from_cam @ new_root_cam),
        "world_transl": pelvis_world - rest_root,
    }
