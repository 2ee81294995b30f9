"""SMPL-family body models in numpy: load a user-supplied model file and pose it (linear blend skinning).

The licensed SMPL / SMPL-X model files are never shipped or downloaded: the user passes the file
they downloaded themselves (``--smpl-model SMPL_NEUTRAL.npz``, ``SMPLX_NEUTRAL.npz``, or the
``.pkl`` releases such as ``basicModel_neutral_lbs_10_207_0_v1.0.0.pkl``). An ``.npz`` is read with
``allow_pickle=False``; a ``.pkl`` (a Python 2 pickle holding chumpy arrays and scipy sparse
matrices) with the restricted unpickler, which rebuilds those as numpy arrays from their stored
values (:mod:`rotavat_cli.unpickle.model_files`). Only these keys are used (the layout of the
official releases, as read by ``vchoutas/smplx`` ``body_models.py``):

==================  ====================  =====================================================
key                 shape                 meaning
==================  ====================  =====================================================
``v_template``      (V, 3)                rest-pose template, metres, SMPL canonical frame
``shapedirs``       (V, 3, S)             shape (and, for SMPL-X, expression from column 300) blend shapes
``posedirs``        (V, 3, 9 (J-1))       pose-corrective blend shapes
``J_regressor``     (J, V)                joints from the shaped rest mesh (dense; sparse in a .pkl)
``weights``         (V, J)                skinning weights
``kintree_table``   (2, J)                row 0: parent of each joint (root's entry ignored)
``f``               (F, 3)                triangles (optional)
==================  ====================  =====================================================

Posing follows SMPL's linear blend skinning (Loper et al. 2015; ``smplx/lbs.py`` is the reference
the numbers were checked against): shape the template, regress the joints, add pose correctives
from ``R_j - I`` of every non-root joint, chain the joint transforms down the kinematic tree and
skin. ``global_orient`` rotates about the root *joint*, not the origin; ``transl`` is added last.

Examples
--------
>>> model = toy_chain_model()
>>> verts, joints = lbs(model, np.zeros((1, 0)), np.zeros((1, 3, 3)))
>>> np.allclose(verts[0], model.v_template)
True
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..settings import limits
from ..errors import InputError, file_error
from ..geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from ..unpickle.model_files import load_model_pickle
from ..unpickle.npz import open_npz

__all__ = [
    "BodyModel",
    "load_body_model",
    "pose_to_matrices",
    "pose_from_body",
    "lbs",
    "lbs_batch_rows",
    "posed_joints",
    "SMPLX_TO_SMPL24",
    "SMPLH_TO_SMPL24",
    "joints_to_smpl24",
    "SMPL_PARENTS",
    "toy_chain_model",
    "smpl_param_arrays",
]

# SMPL-X kinematic joints 0..21 are SMPL's 0..21 (same names); SMPL's 'left_hand'/'right_hand'
# (22, 23) have no SMPL-X twin: the middle finger's first joint (SMPL-X 28 'left_middle1',
# 43 'right_middle1', vchoutas/smplx joint_names.py) is the nearest stand-in (an approximation).
SMPLX_TO_SMPL24 = tuple(range(22)) + (28, 43)
# SMPL-H (52 joints) has the same 22 body joints, then 15 joints per hand without SMPL-X's jaw and eyes:
# the same stand-ins are 25 'left_middle1' and 40 'right_middle1' (smplx joint_names.py SMPLH_JOINT_NAMES).
SMPLH_TO_SMPL24 = tuple(range(22)) + (25, 40)

_REQUIRED = ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table")


@dataclass(frozen=True, eq=False)
class BodyModel:
    """A posable SMPL-family model: arrays in float64, parents as int64 (root's parent is -1)."""

    name: str
    v_template: np.ndarray  # (V, 3)
    shapedirs: np.ndarray  # (V, 3, S)
    posedirs: np.ndarray  # (9 (J-1), 3 V): pose feature -> flattened vertex offsets
    J_regressor: np.ndarray  # (J, V)
    weights: np.ndarray  # (V, J)
    parents: np.ndarray  # (J,)
    faces: np.ndarray | None  # (F, 3) int64

    @property
    def n_verts(self) -> int:
        return int(self.v_template.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.J_regressor.shape[0])

    @property
    def kind(self) -> str:
        """'smpl' (24 joints), 'smplx' (55), 'smplh' (52) or 'custom'."""
        return {24: "smpl", 55: "smplx", 52: "smplh"}.get(self.n_joints, "custom")


def _model_arrays(path: Path) -> dict[str, np.ndarray]:
    """Required (and optional 'f') arrays of a model file: an ``.npz`` (read without pickle) or an
    official ``.pkl`` (:func:`_pickled_model_arrays`)."""
    if path.suffix.lower() == ".pkl":
        return _pickled_model_arrays(path)
    with open_npz(path) as npz:  # declared sizes checked against the limits before reading
        missing = [k for k in _REQUIRED if k not in npz.keys()]
        if missing:
            raise file_error(path, f"not an SMPL-family .npz model (missing {', '.join(missing)})")
        keys = _REQUIRED + (("f",) if "f" in npz.keys() else ())
        try:
            return npz.read(keys, objects=False)
        except InputError as exc:
            if "object array" in str(exc):
                raise file_error(path, "a key is a pickled object (e.g. a scipy sparse matrix); re-save the "
                                       "model with dense numpy arrays") from None
            raise


def _pickled_model_arrays(path: Path) -> dict[str, np.ndarray]:
    """Required (and optional 'f') arrays of an official ``.pkl`` model: the restricted unpickler
    rebuilds its chumpy arrays and scipy sparse matrices as numpy arrays
    (:mod:`rotavat_cli.unpickle.model_files`); the other keys (``bs_style``, ``J``, ``hands_componentsl``
    ...) are not used."""
    content = load_model_pickle(path)
    if not isinstance(content, dict):
        raise file_error(path, f"not an SMPL-family .pkl model (it holds a {type(content).__name__}, "
                               "not a dict of arrays)")
    missing = [k for k in _REQUIRED if k not in content]
    if missing:
        raise file_error(path, f"not an SMPL-family .pkl model (missing {', '.join(missing)})")
    arrays = {}
    for key in _REQUIRED + (("f",) if "f" in content else ()):
        value = content[key]
        if not isinstance(value, np.ndarray) or value.dtype.kind not in "biuf":
            kind = f"a {value.dtype} array" if isinstance(value, np.ndarray) else f"a {type(value).__name__}"
            raise file_error(path, f"'{key}' is {kind}, not a numeric array")
        arrays[key] = value
    return arrays


def load_body_model(path: str | Path) -> BodyModel:
    """Load and validate an SMPL / SMPL-H / SMPL-X model file: ``.npz`` (no pickle) or the official
    ``.pkl`` (restricted unpickler: :func:`_pickled_model_arrays`).

    Read once per process for each version of the file (its path, size and modification time) under the
    same :mod:`rotavat_cli.settings.limits`: a batch's tasks, or a sequence read frame by frame, pose from one copy,
    whose arrays are read-only. A file that fails is read again next time (errors are not kept).
    """
    path = Path(path)
    try:
        stat = path.stat()
    except OSError:
        return _load_body_model(path)  # the reader says what is wrong with it
    return _cached_body_model(str(path), stat.st_size, stat.st_mtime_ns, limits.current())


@functools.lru_cache(maxsize=2)
def _cached_body_model(path: str, size: int, mtime_ns: int, limits_now: limits.Limits) -> BodyModel:
    """:func:`_load_body_model` of one version of a file (the key), its arrays made read-only."""
    model = _load_body_model(Path(path))
    for value in vars(model).values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    return model


def _load_body_model(path: Path) -> BodyModel:
    """Read and validate a model file (:func:`load_body_model` without the cache)."""
    arrays = _model_arrays(path)

    v_template = np.asarray(arrays["v_template"], dtype=np.float64)
    if v_template.ndim != 2 or v_template.shape[1] != 3 or v_template.shape[0] == 0:
        raise file_error(path, f"'v_template' must be (V, 3), got {list(v_template.shape)}")
    n_verts = v_template.shape[0]
    shapedirs = np.asarray(arrays["shapedirs"], dtype=np.float64)
    if shapedirs.ndim != 3 or shapedirs.shape[:2] != (n_verts, 3):
        raise file_error(path, f"'shapedirs' must be (V, 3, S) with V = {n_verts}, got {list(shapedirs.shape)}")
    J_regressor = np.asarray(arrays["J_regressor"], dtype=np.float64)
    if J_regressor.ndim != 2 or J_regressor.shape[1] != n_verts:
        raise file_error(path, f"'J_regressor' must be dense (J, V) with V = {n_verts}, got {list(J_regressor.shape)}")
    n_joints = J_regressor.shape[0]
    weights = np.asarray(arrays["weights"], dtype=np.float64)
    if weights.shape != (n_verts, n_joints):
        raise file_error(path, f"'weights' must be (V, J) = ({n_verts}, {n_joints}), got {list(weights.shape)}")
    posedirs = np.asarray(arrays["posedirs"], dtype=np.float64)
    n_pose = 9 * (n_joints - 1)
    if posedirs.shape == (n_verts, 3, n_pose):
        posedirs = posedirs.reshape(n_verts * 3, n_pose).T  # smplx: reshape(-1, P).T
    elif posedirs.shape != (n_pose, n_verts * 3):
        raise file_error(path, f"'posedirs' must be (V, 3, {n_pose}), got {list(posedirs.shape)}")
    kintree = np.asarray(arrays["kintree_table"])
    if kintree.ndim != 2 or kintree.shape != (2, n_joints) or kintree.dtype.kind not in "iuf":
        raise file_error(path, f"'kintree_table' must be (2, J) = (2, {n_joints}), got {list(kintree.shape)}")
    parents = kintree[0].astype(np.int64)
    parents[0] = -1
    if np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, n_joints)):
        raise file_error(path, "'kintree_table' must list each joint after its parent")
    faces = None
    if "f" in arrays:
        faces = np.asarray(arrays["f"])
        if faces.ndim != 2 or faces.shape[1] != 3 or faces.dtype.kind not in "iu" or (faces.size and faces.max() >= n_verts):
            raise file_error(path, "'f' must be (F, 3) vertex indices")
        faces = faces.astype(np.int64)
    for key, arr in (("v_template", v_template), ("shapedirs", shapedirs), ("posedirs", posedirs),
                     ("J_regressor", J_regressor), ("weights", weights)):
        if not np.all(np.isfinite(arr)):
            raise file_error(path, f"'{key}' has non-finite values")
    return BodyModel(path.name, v_template, shapedirs, posedirs, J_regressor, weights, parents, faces)


def pose_to_matrices(pose: np.ndarray, n_joints: int) -> np.ndarray:
    """Pose as axis-angle (P, J*3) / (P, J, 3) or rotation matrices (P, J, 3, 3) / (P, J*9) -> (P, J, 3, 3).

    Raises ValueError if the shape fits neither form for ``n_joints`` joints.
    """
    pose = np.asarray(pose, dtype=np.float64)
    n_people = pose.shape[0] if pose.ndim else 0
    if pose.shape[1:] == (n_joints, 3, 3):
        return pose
    if pose.shape[1:] in ((n_joints * 3,), (n_joints, 3)):
        rotvec = pose.reshape(n_people, n_joints, 3)
        return axis_angle_to_matrix(rotvec, np.linalg.norm(rotvec, axis=-1))
    if pose.shape[1:] == (n_joints * 9,):
        return pose.reshape(n_people, n_joints, 3, 3)
    raise ValueError(f"pose of shape {list(pose.shape)} is neither axis-angle nor rotation matrices for {n_joints} joints")


# transient memory of lbs per posed vertex: the (4, 4) blend of joint transforms, float64
_LBS_BYTES_PER_VERTEX = 16 * 8
_LBS_CHUNK_BYTES = 64 << 20  # people are posed in chunks whose transforms take at most this


def lbs_batch_rows(model: BodyModel) -> int:
    """How many people :func:`lbs` poses in one batch on ``model``: those whose (P, V, 4, 4) skinning transforms
    fit in ``_LBS_CHUNK_BYTES`` (at least 1). More people are posed batch by batch, so memory stays flat; a reader
    posing a long clip one frame at a time asks for this many rows at once (:mod:`.row_blocks`)."""
    return max(1, _LBS_CHUNK_BYTES // (model.n_verts * _LBS_BYTES_PER_VERTEX))


def pose_from_body(root_orient: np.ndarray, body_pose: np.ndarray, n_joints: int) -> np.ndarray:
    """Axis-angle pose (P, n_joints, 3) for a body model: root (P, 3), then the body joints (P, 3 K)
    in order (K beyond ``n_joints - 1`` ignored), every further joint (hands, face) at rest."""
    n_people = root_orient.shape[0]
    body = body_pose.reshape(n_people, body_pose.shape[-1] // 3, 3)
    pose = np.zeros((n_people, n_joints, 3))
    pose[:, 0] = root_orient
    pose[:, 1:1 + body.shape[1]] = body[:, :n_joints - 1]
    return pose


def check_posed_size(model: BodyModel, n_people: int) -> None:
    """Refuse to pose more people at once than one contract frame may hold (``limits.max_frame_mb``):
    a parameter file of a few MB can name enough people in one image to need gigabytes of meshes.

    Raises InputError (the caller's reader names the file).
    """
    needed = n_people * model.n_verts * 3 * 8  # float64 vertices (P, V, 3)
    limit = limits.current().max_frame_bytes
    if needed > limit:
        raise InputError(f"posing {n_people} people on {model.name} ({model.n_verts} vertices) needs "
                         f"{limits.human_bytes(needed)} of meshes, over limits.max_frame_mb "
                         f"({limits.human_bytes(limit)}); raise it in the config if this is real")


def _rows(values: np.ndarray | None, n_people: int, rows: slice) -> np.ndarray | None:
    """Rows ``rows`` of a per-person array given as (P, ...) (or reshapeable to it); None stays None."""
    if values is None:
        return None
    values = np.asarray(values)
    return values.reshape(n_people, -1)[rows]


def lbs(model: BodyModel, betas: np.ndarray, pose: np.ndarray, transl: np.ndarray | None = None,
        expression: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pose the model: -> vertices (P, V, 3), joints (P, J, 3), float64, the model's frame (+ transl).

    betas: (P, B) shape coefficients (B may be smaller or larger than the model's components:
        extra coefficients are ignored, missing ones are zero).
    pose: (P, J, 3) axis-angle or (P, J, 3, 3) rotation matrices, joint 0 = global orientation.
    transl: (P, 3) added to vertices and joints (metres), or None.
    expression: (P, E) SMPL-X expression coefficients (shapedirs columns 300...), or None.
    """
    rot = pose_to_matrices(pose, model.n_joints)  # (P, J, 3, 3)
    n_people = rot.shape[0]
    if n_people == 0:
        return np.zeros((0, model.n_verts, 3)), np.zeros((0, model.n_joints, 3))
    check_posed_size(model, n_people)
    chunk = lbs_batch_rows(model)
    if n_people > chunk:  # many people: the (P, V, 4, 4) transforms are made a few people at a time
        parts = [lbs(model, _rows(betas, n_people, s), rot[s], _rows(transl, n_people, s),
                     _rows(expression, n_people, s)) for s in (slice(i, i + chunk) for i in range(0, n_people, chunk))]
        return np.concatenate([v for v, _ in parts]), np.concatenate([j for _, j in parts])
    betas = np.asarray(betas, dtype=np.float64).reshape(n_people, -1)
    n_components = min(300, model.shapedirs.shape[2]) if model.kind == "smplx" else model.shapedirs.shape[2]
    n_shape = min(betas.shape[1], n_components)
    v_shaped = model.v_template[None] + np.einsum("vcs,ps->pvc", model.shapedirs[:, :, :n_shape], betas[:, :n_shape])
    if expression is not None and model.shapedirs.shape[2] > 300:
        expression = np.asarray(expression, dtype=np.float64).reshape(n_people, -1)
        n_expr = min(expression.shape[1], model.shapedirs.shape[2] - 300)
        v_shaped = v_shaped + np.einsum("vcs,ps->pvc", model.shapedirs[:, :, 300:300 + n_expr], expression[:, :n_expr])
    rest_joints = model.J_regressor @ v_shaped  # (P, J, 3): matrix products (BLAS), not einsum's loops
    pose_feature = (rot[:, 1:] - np.eye(3)).reshape(n_people, -1)  # (P, 9 (J-1))
    v_posed = v_shaped + (pose_feature @ model.posedirs).reshape(n_people, -1, 3)
    posed_joints, rel_transforms = _rigid_transforms(rot, rest_joints, model.parents)
    T = (model.weights @ rel_transforms.reshape(n_people, model.n_joints, 16)).reshape(n_people, -1, 4, 4)  # (P, V, 4, 4)
    verts = np.einsum("pvab,pvb->pva", T[..., :3, :3], v_posed) + T[..., :3, 3]
    if transl is not None:
        transl = np.asarray(transl, dtype=np.float64).reshape(n_people, 1, 3)
        verts = verts + transl
        posed_joints = posed_joints + transl
    return verts, posed_joints


def posed_joints(model: BodyModel, betas: np.ndarray, pose: np.ndarray, transl: np.ndarray | None = None) -> np.ndarray:
    """The joints (P, J, 3) :func:`lbs` gives, without posing the meshes (float64; equal to its joints up
    to rounding): the rest joints come from the regressor applied to the template and the shape blend
    shapes (linear), then the kinematic chain. Cheap for many people: no (P, V, ...) array is made.

    betas, pose, transl: as for :func:`lbs` (no expression: it moves the face only).
    """
    rot = pose_to_matrices(pose, model.n_joints)  # (P, J, 3, 3)
    n_people = rot.shape[0]
    if n_people == 0:
        return np.zeros((0, model.n_joints, 3))
    betas = np.asarray(betas, dtype=np.float64).reshape(n_people, -1)
    n_components = min(300, model.shapedirs.shape[2]) if model.kind == "smplx" else model.shapedirs.shape[2]
    n_shape = min(betas.shape[1], n_components)
    joints_template = model.J_regressor @ model.v_template  # (J, 3)
    joints_shapedirs = np.einsum("jv,vcs->jcs", model.J_regressor, model.shapedirs[:, :, :n_shape])  # (J, 3, S)
    rest_joints = joints_template[None] + np.einsum("jcs,ps->pjc", joints_shapedirs, betas[:, :n_shape])
    joints, _ = _rigid_transforms(rot, rest_joints, model.parents)
    if transl is not None:
        joints = joints + np.asarray(transl, dtype=np.float64).reshape(n_people, 1, 3)
    return joints


def _rigid_transforms(rot: np.ndarray, joints: np.ndarray, parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Chain joint rotations down the tree: -> posed joints (P, J, 3), skinning transforms (P, J, 4, 4)."""
    n_people, n_joints = joints.shape[:2]
    rel = joints.copy()
    rel[:, 1:] -= joints[:, parents[1:]]
    local = np.zeros((n_people, n_joints, 4, 4))
    local[..., :3, :3] = rot
    local[..., :3, 3] = rel
    local[..., 3, 3] = 1.0
    world = np.empty_like(local)
    world[:, 0] = local[:, 0]
    for j in range(1, n_joints):  # the kinematic chain is sequential; people stay vectorised
        world[:, j] = world[:, parents[j]] @ local[:, j]
    posed = world[..., :3, 3].copy()
    skin = world.copy()
    skin[..., :3, 3] -= np.einsum("pjab,pjb->pja", world[..., :3, :3], joints)
    return posed, skin


def joints_to_smpl24(joints: np.ndarray) -> tuple[np.ndarray, str]:
    """SMPL-24 joints from SMPL (24 or 45 = 24 + vertex joints), SMPL-H (52) or SMPL-X (55 / 127) joint sets.

    Returns (joints (P, 24, 3), note); raises ValueError for other joint counts.
    """
    n = joints.shape[1]
    if n in (24, 45):  # SMPL kinematic joints first (smplx.SMPL appends 21 vertex joints)
        return joints[:, :24], "smpl24"
    if n == 52:  # SMPL-H kinematic joints
        return joints[:, list(SMPLH_TO_SMPL24)], "smpl24 (from SMPL-H: hands = middle1 joints)"
    if n in (55, 127, 144):  # SMPL-X kinematic joints first (55), then vertex/face joints
        return joints[:, list(SMPLX_TO_SMPL24)], "smpl24 (from SMPL-X: hands = middle1 joints)"
    raise ValueError(f"cannot map {n} joints to SMPL-24")


# Parents of SMPL's 24 joints (``landmarks.SMPL_JOINT_NAMES`` order; kinematic tree of the official model files).
SMPL_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21)


def toy_chain_model() -> BodyModel:
    """A 3-joint, 4-vertex chain (doctests and quick checks): joints at y = 0, 1, 2, one vertex each + tip."""
    v_template = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.0, 3.0, 0.0]])
    J_regressor = np.eye(3, 4)
    weights = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0, 0, 1.0]])
    return BodyModel("toy", v_template, np.zeros((4, 3, 0)), np.zeros((18, 12)), J_regressor, weights,
                     np.array([-1, 0, 1]), np.array([[0, 1, 2], [1, 2, 3]]))


def smpl_param_arrays(model: BodyModel, betas: np.ndarray, pose: np.ndarray, transl: np.ndarray | None,
                      joints: np.ndarray) -> dict[str, np.ndarray]:
    """The frame keys ``sequence.SMPL_PARAM_KEYS`` of people posed by :func:`lbs` (camera frame, float64).

    betas (P, B), pose (P, J, 3) axis-angle or (P, J, 3, 3) matrices, transl (P, 3) or None: what was
    given to :func:`lbs`; joints (P, J, 3): the joints it returned, whose joint 0 is the root (pelvis).
    ``smpl_body_pose`` holds every non-root joint of the model, axis-angle (P, 3 (J - 1)); ``smpl_pelvis``
    the root joint where these parameters put it (the model's rest root for these betas plus ``transl``),
    so a consumer can place the body without the model (``rotavat align`` moves it as a point).

    >>> model = toy_chain_model()
    >>> keys = smpl_param_arrays(model, np.zeros((1, 0)), np.zeros((1, 3, 3)), np.ones((1, 3)),
    ...                          lbs(model, np.zeros((1, 0)), np.zeros((1, 3, 3)), np.ones((1, 3)))[1])
    >>> keys["smpl_pelvis"].tolist(), keys["smpl_body_pose"].shape
    ([[1.0, 1.0, 1.0]], (1, 6))
    """
    rot = pose_to_matrices(pose, model.n_joints)
    n_people = rot.shape[0]
    rotvec = matrix_to_axis_angle(rot)  # (P, J, 3)
    transl = np.zeros((n_people, 3)) if transl is None else np.asarray(transl, dtype=np.float64).reshape(n_people, 3)
    betas = np.asarray(betas, dtype=np.float64)
    n_betas = betas.shape[-1] if betas.ndim > 1 or not n_people else betas.size // n_people
    return {"smpl_global_orient": rotvec[:, 0].copy(),
            "smpl_body_pose": rotvec[:, 1:].reshape(n_people, 3 * (model.n_joints - 1)),
            "smpl_betas": betas.reshape(n_people, n_betas),
            "smpl_transl": transl.copy(),
            "smpl_pelvis": np.asarray(joints, dtype=np.float64)[:, 0].copy()}
