"""Body-model parameters of a frame in the export's world, and a track's rest skeleton.

A frame imported with a body model carries, per person, in the camera frame: ``smpl_global_orient``
(P, 3) and ``smpl_body_pose`` (P, 3 (J - 1)) axis-angle, ``smpl_betas`` (P, B), ``smpl_transl`` and
``smpl_pelvis`` (P, 3) m; an aligned frame adds ``smpl_scale`` (P,) (about the pelvis) and the root in
the world of its camera.yaml, ``world_global_orient`` and ``world_transl`` (docs/conventions.md). The
posing rule, in either frame: ``out = model(betas, body_pose, global_orient, transl)``, ``pelvis =
out.joints[:, 0]``, ``vertices = pelvis + scale (out.vertices - pelvis)``. So a person is fully placed
in the world (Y up, metres) by

- ``root_world_from_model`` (3, 3): the root joint's rotation, model frame -> world,
- ``pelvis_world`` (3,): where the root joint is,
- ``scale``: the uniform scale about it,

and the body pose and betas, which no frame change touches (:class:`BodyFrame`).

>>> from rotavat_cli.formats.smpl import toy_chain_model
>>> joint_names(toy_chain_model())
('joint_0', 'joint_1', 'joint_2')
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry.camera import Camera
from ..errors import InputError, file_error
from ..formats.smpl import BodyModel, lbs, pose_from_body, pose_to_matrices
from ..bodies.joint_layouts import LAYOUT_NAMES
from ..sequence import SMPL_PARAM_KEYS, WORLD_PARAM_KEYS, Frame

__all__ = ["BodyFrame", "body_frame", "has_body_params", "check_model", "check_frame_fits", "joint_names",
           "rest_shape", "quaternions_xyzw", "continuous_quaternions"]

_SMPLX55 = LAYOUT_NAMES["smplx144"][:55]
# SMPL-H: SMPL-X's skeleton without the jaw and the eyes (22 body joints, 15 per hand; smplx joint_names.py)
_NAMES_BY_COUNT = {24: LAYOUT_NAMES["smpl24"], 55: _SMPLX55, 52: _SMPLX55[:22] + _SMPLX55[25:]}


def joint_names(model: BodyModel) -> tuple[str, ...]:
    """The model's joint names (SMPL 24, SMPL-H 52, SMPL-X 55: smplx's names), else ``joint_<j>``."""
    return tuple(_NAMES_BY_COUNT.get(model.n_joints, tuple(f"joint_{j}" for j in range(model.n_joints))))


def has_body_params(frame: Frame) -> bool:
    """Whether a frame carries the body-model parameters (every key of ``SMPL_PARAM_KEYS``)."""
    return all(frame.get(key) is not None for key in SMPL_PARAM_KEYS)


def check_model(model: BodyModel, model_path: Path, meta: Mapping, meta_name: str) -> None:
    """InputError unless the model file fits meta.yaml's ``body_model`` (its joint count; ``kind`` and
    ``file`` name the file the parameters were made with). A sequence that names none passes."""
    declared = meta.get("body_model") if isinstance(meta, Mapping) else None
    if not isinstance(declared, Mapping):
        return
    joints = declared.get("joints")
    if isinstance(joints, int) and not isinstance(joints, bool) and joints != model.n_joints:
        made_with = " ".join(str(declared[k]) for k in ("kind", "file") if declared.get(k))
        raise InputError(f"{model_path}: has {model.n_joints} joints, but {meta_name} says the parameters were made "
                         f"with {joints} ({made_with or 'another model'}): pass that model's .npz to --smpl-model")


def check_frame_fits(frame: Frame, model: BodyModel, model_path: Path) -> None:
    """InputError unless a frame's parameters and meshes fit the model: ``smpl_body_pose`` holds 3 (J - 1)
    numbers per person, and ``vertices`` (if any) the model's vertex count."""
    pose = frame.get("smpl_body_pose")
    if pose is not None and frame.n_people and pose.shape[1] != 3 * (model.n_joints - 1):
        raise file_error(frame.source, f"'smpl_body_pose' holds {pose.shape[1] // 3} joints per person, but "
                                       f"{model_path} has {model.n_joints - 1} besides the root: pass the model the "
                                       "parameters were made with to --smpl-model")
    verts = frame.get("vertices")
    if verts is not None and frame.n_people and verts.shape[1] and verts.shape[1] != model.n_verts:
        raise file_error(frame.source, f"meshes of {verts.shape[1]} vertices, but {model_path} has {model.n_verts}: "
                                       "pass the model the meshes were made with to --smpl-model")


@dataclass(frozen=True)
class BodyFrame:
    """A frame's people as body-model parameters in the world (Y up, metres).

    local_rot: (P, J, 3, 3) joint rotations; joint 0 = the root, world from model; the others relative to
    their parent. pelvis_world: (P, 3) the root joint. scale: (P,) about the root. betas: (P, B).
    """

    local_rot: np.ndarray
    pelvis_world: np.ndarray
    scale: np.ndarray
    betas: np.ndarray


def _matrices(rotvec: np.ndarray) -> np.ndarray:
    """Axis-angle (P, 3) -> (P, 3, 3)."""
    return pose_to_matrices(np.asarray(rotvec, dtype=np.float64).reshape(-1, 1, 3), 1)[:, 0]


def body_frame(frame: Frame, camera: Camera, n_joints: int, stored_world: bool) -> BodyFrame:
    """A frame's body parameters in the world of ``camera``.

    stored_world: use the frame's ``world_global_orient``/``world_transl`` when it has them (they are in the
    world of the sequence's own camera.yaml: pass False when ``camera`` is another one); otherwise the root
    is the camera-frame parameters taken to the world by ``camera``. ``smpl_scale`` defaults to 1.
    Raises InputError naming the frame for a scale that is not positive.
    """
    data = frame.data
    n_people = frame.n_people
    root_cam = _matrices(data["smpl_global_orient"])
    pelvis_cam = np.asarray(data["smpl_pelvis"], dtype=np.float64)
    scale = np.asarray(data["smpl_scale"], dtype=np.float64) if "smpl_scale" in data else np.ones(n_people)
    if np.any(scale <= 0):
        raise file_error(frame.source, "key 'smpl_scale' must be positive")
    if stored_world and all(key in data for key in WORLD_PARAM_KEYS):
        root_world = _matrices(data["world_global_orient"])
        rest_root = pelvis_cam - np.asarray(data["smpl_transl"], dtype=np.float64)  # J0(betas), the model's own
        pelvis_world = np.asarray(data["world_transl"], dtype=np.float64) + rest_root
    else:
        root_world = camera.R_cam_from_world.T @ root_cam
        pelvis_world = camera.world_from_cam(pelvis_cam)
    pose = pose_from_body(np.zeros((n_people, 3)), np.asarray(data["smpl_body_pose"], dtype=np.float64), n_joints)
    local_rot = pose_to_matrices(pose, n_joints).copy()
    local_rot[:, 0] = root_world
    return BodyFrame(local_rot, pelvis_world.reshape(n_people, 3), scale.reshape(n_people),
                     np.asarray(data["smpl_betas"], dtype=np.float64).reshape(n_people, -1))


def rest_shape(model: BodyModel, betas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The shaped rest mesh (V, 3) and rest joints (J, 3) of one person's betas (B,), model frame, metres
    (``v_template + shapedirs . betas``, joints by the regressor: lbs at zero pose, no translation)."""
    verts, joints = lbs(model, np.asarray(betas, dtype=np.float64).reshape(1, -1), np.zeros((1, model.n_joints, 3)))
    return verts[0], joints[0]


def quaternions_xyzw(rot: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) in glTF's order (x, y, z, w)."""
    rot = np.asarray(rot, dtype=np.float64)
    if not rot.size:
        return np.zeros(rot.shape[:-2] + (4,))
    return Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_quat().reshape(rot.shape[:-2] + (4,))


def continuous_quaternions(quat: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """``quat`` (..., 4) with each quaternion's sign flipped where it points away from ``previous`` (same
    shape, or None): q and -q are one rotation, but interpolating from one sign to the other turns the long
    way round (Blender keys the components as they are)."""
    if previous is None:
        return quat
    flip = np.sum(quat * previous, axis=-1, keepdims=True) < 0
    return np.where(flip, -quat, quat)
