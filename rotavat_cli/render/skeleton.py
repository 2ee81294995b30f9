"""People without triangles: skeletons (bones from the joint layout) and point clouds, as small meshes.

A sequence from a joints-only import (CLIFF, 4D-Humans, WHAM ... without a body model) has
``joints`` and no ``vertices``; a point-cloud sequence has ``vertices`` and no ``faces``. Both are
drawn here as triangles, so every view, both rasterisers (depth test, shading) and the glTF export
take them unchanged:

- **skeleton**: a 6-sided tube per bone and an icosahedron per joint; the bones come from the
  layout's joint *names* (:data:`rotavat_cli.bodies.joint_layouts.LAYOUT_NAMES`), so one bone list per
  skeleton family serves every layout that carries its joints (SMPL-24, SMPL-45, SMPL-X and
  HybrIK-29 share SMPL's kinematic tree; OpenPose-25, SPIN-49 and PHALP-44 share OpenPose's);
- **points**: an icosahedron per joint of a layout without bones, an octahedron per vertex of a point cloud.

Sizes are in metres, times a per-person ``scale`` >= 1 with which the caller keeps them at least a
pixel or so thick in its view (rotavat_cli.render.grid), so a skeleton 30 px tall is still visible.

Bone lists: SMPL's from ``SMPL_PARENTS`` (rotavat_cli.formats.smpl, SMPL's kintree);
OpenPose BODY_25's are ``POSE_BODY_25_PAIRS_RENDER_GPU`` (CMU-Perceptual-Computing-Lab/openpose
@3c9441a, include/openpose/pose/poseParametersRender.hpp); COCO-17's the COCO keypoint skeleton;
Human3.6M-17's the parents of facebookresearch/VideoPose3D's h36m skeleton.

>>> layout_bones("smpl24")[:3]
((0, 1), (0, 2), (0, 3))
>>> len(layout_bones("phalp44 (OpenPose-25 + 19 extra)")), layout_bones("cliff49x") is None
(24, True)
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..formats.smpl import SMPL_PARENTS
from ..bodies.joint_layouts import LAYOUT_NAMES, layout_by_count, layout_key
from ..bodies.landmarks import SMPL_JOINT_NAMES

__all__ = ["Shapes", "BONE_FAMILIES", "layout_name", "layout_bones", "skeleton_shapes", "point_shapes",
           "BONE_RADIUS_M", "JOINT_RADIUS_M", "POINT_RADIUS_M"]

BONE_RADIUS_M = 0.02  # bone tubes: 4 cm across (a limb is ~10 cm: the tube reads as a line, not a body)
JOINT_RADIUS_M = 0.035  # joint balls, and the points of a layout without bones
POINT_RADIUS_M = 0.012  # point-cloud vertices: SMPL's 6,890 vertices ~2 cm apart close into a surface

_SMPL_BONES = tuple((SMPL_JOINT_NAMES[p], SMPL_JOINT_NAMES[c]) for c, p in enumerate(SMPL_PARENTS) if p >= 0)
_OPENPOSE_BONES = (
    ("neck", "mid_hip"), ("neck", "right_shoulder"), ("neck", "left_shoulder"), ("right_shoulder", "right_elbow"),
    ("right_elbow", "right_wrist"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
    ("mid_hip", "right_hip"), ("right_hip", "right_knee"), ("right_knee", "right_ankle"), ("mid_hip", "left_hip"),
    ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("neck", "nose"), ("nose", "right_eye"),
    ("right_eye", "right_ear"), ("nose", "left_eye"), ("left_eye", "left_ear"), ("left_ankle", "left_big_toe"),
    ("left_big_toe", "left_small_toe"), ("left_ankle", "left_heel"), ("right_ankle", "right_big_toe"),
    ("right_big_toe", "right_small_toe"), ("right_ankle", "right_heel"))
_COCO_BONES = (
    ("nose", "left_eye"), ("nose", "right_eye"), ("left_eye", "left_ear"), ("right_eye", "right_ear"),
    ("left_shoulder", "right_shoulder"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
    ("right_shoulder", "right_elbow"), ("right_elbow", "right_wrist"), ("left_shoulder", "left_hip"),
    ("right_shoulder", "right_hip"), ("left_hip", "right_hip"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"),
    ("right_hip", "right_knee"), ("right_knee", "right_ankle"))
_H36M_BONES = (
    ("pelvis", "right_hip"), ("right_hip", "right_knee"), ("right_knee", "right_ankle"), ("pelvis", "left_hip"),
    ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("pelvis", "spine"), ("spine", "thorax"),
    ("thorax", "neck_nose"), ("neck_nose", "head"), ("thorax", "left_shoulder"), ("left_shoulder", "left_elbow"),
    ("left_elbow", "left_wrist"), ("thorax", "right_shoulder"), ("right_shoulder", "right_elbow"),
    ("right_elbow", "right_wrist"))
# Which bone list each layout of joint_layouts.LAYOUT_NAMES uses (by the joints it carries).
BONE_FAMILIES: dict[str, tuple[tuple[str, str], ...]] = {
    **{name: _SMPL_BONES for name in ("smpl24", "smpl45", "romp54", "romp71", "smplx127", "smplx144", "hybrik29")},
    **{name: _OPENPOSE_BONES for name in ("openpose25", "spin49", "phalp44", "phalp45")},
    "coco17": _COCO_BONES,
    "h36m17": _H36M_BONES,
}


def layout_name(declared: str | None, n_joints: int) -> str | None:
    """The layout of ``joints``: meta.yaml's ``import.joints_layout`` (its first word: 'phalp44 (...)'
    is 'phalp44'), else SMPL's family by joint count (the contract's joints are in SMPL order), else None."""
    if declared:
        name = layout_key(declared)
        if name in LAYOUT_NAMES and len(LAYOUT_NAMES[name]) <= n_joints:
            return name
    return layout_by_count(n_joints)


@functools.lru_cache(maxsize=None)
def layout_bones(layout: str | None) -> tuple[tuple[int, int], ...] | None:
    """(B,) joint-index pairs of a layout's bones (by joint names); None for a layout without bones."""
    name = layout_key(layout)
    if name not in BONE_FAMILIES or name not in LAYOUT_NAMES:
        return None
    index = {joint: i for i, joint in enumerate(LAYOUT_NAMES[name])}
    return tuple((index[a], index[b]) for a, b in BONE_FAMILIES[name] if a in index and b in index)


@dataclass(frozen=True)
class Shapes:
    """Triangles of several people: ``points`` (N, 3) camera frame, ``faces`` (F, 3) into them,
    ``person`` (N,) index of each point's person, ``normals`` (N, 3) unit."""

    points: np.ndarray
    faces: np.ndarray
    person: np.ndarray
    normals: np.ndarray

    @staticmethod
    def empty() -> "Shapes":
        return Shapes(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))

    @staticmethod
    def join(parts: list["Shapes"]) -> "Shapes":
        """One Shapes of several (faces re-indexed)."""
        parts = [p for p in parts if len(p.points)]
        if not parts:
            return Shapes.empty()
        offsets = np.cumsum([0] + [len(p.points) for p in parts[:-1]])
        return Shapes(np.concatenate([p.points for p in parts]), np.concatenate([p.faces + o for p, o in zip(parts, offsets)]),
                      np.concatenate([p.person for p in parts]), np.concatenate([p.normals for p in parts]))


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit icosahedron: (12, 3) vertices, (20, 3) faces."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
                  [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def _octahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit octahedron: (6, 3) vertices, (8, 3) faces (point clouds: thousands of them per person)."""
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], dtype=np.int64)
    return v, f


_BALL = _icosahedron()  # joints
_DOT = _octahedron()  # points: 8 triangles instead of 20 (a 1 cm ball shows no facets)
_TUBE_SIDES = 6


def _balls(centres: np.ndarray, radius: np.ndarray, person: np.ndarray, shape: tuple = _BALL) -> Shapes:
    """A ``shape`` (unit vertices, faces) of ``radius`` (M,) around each of ``centres`` (M, 3)."""
    unit_v, unit_f = shape
    M = len(centres)
    if M == 0:
        return Shapes.empty()
    points = centres[:, None, :] + radius[:, None, None] * unit_v[None]
    faces = (unit_f[None] + len(unit_v) * np.arange(M)[:, None, None]).reshape(-1, 3)
    return Shapes(points.reshape(-1, 3), faces, np.repeat(person, len(unit_v)),
                  np.broadcast_to(unit_v, (M, len(unit_v), 3)).reshape(-1, 3).copy())


def _tubes(a: np.ndarray, b: np.ndarray, radius: np.ndarray, person: np.ndarray) -> Shapes:
    """A 6-sided open tube of ``radius`` (M,) from each ``a`` (M, 3) to ``b`` (M, 3)."""
    M = len(a)
    axis = b - a
    length = np.linalg.norm(axis, axis=1)
    keep = length > 1e-9
    a, axis, radius, person, length = a[keep], axis[keep], radius[keep], person[keep], length[keep]
    M = len(a)
    if M == 0:
        return Shapes.empty()
    d = axis / length[:, None]
    helper = np.where(np.abs(d[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(d, u)
    angle = 2.0 * np.pi * np.arange(_TUBE_SIDES) / _TUBE_SIDES
    ring = np.cos(angle)[None, :, None] * u[:, None] + np.sin(angle)[None, :, None] * w[:, None]  # (M, S, 3)
    points = np.concatenate([a[:, None] + radius[:, None, None] * ring, a[:, None] + axis[:, None] + radius[:, None, None] * ring], axis=1)
    k = np.arange(_TUBE_SIDES)
    k1 = (k + 1) % _TUBE_SIDES
    quad = np.concatenate([np.stack([k, k1, _TUBE_SIDES + k], 1), np.stack([k1, _TUBE_SIDES + k1, _TUBE_SIDES + k], 1)])
    faces = (quad[None] + 2 * _TUBE_SIDES * np.arange(M)[:, None, None]).reshape(-1, 3)
    return Shapes(points.reshape(-1, 3), faces, np.repeat(person, 2 * _TUBE_SIDES),
                  np.concatenate([ring, ring], axis=1).reshape(-1, 3))


def skeleton_shapes(joints_cam: np.ndarray, bones: tuple[tuple[int, int], ...] | None, scale: np.ndarray) -> Shapes:
    """People's joints (P, J, 3) as tubes along ``bones`` plus joint balls (or balls alone without
    bones); ``scale`` (P,) multiplies the default radii (>= 1: see :func:`min_radius_m`). Joints that
    are not finite are left out with their bones."""
    joints = np.asarray(joints_cam, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[0] == 0:
        return Shapes.empty()
    P, J = joints.shape[:2]
    finite = np.isfinite(joints).all(axis=-1)  # (P, J)
    person = np.broadcast_to(np.arange(P)[:, None], (P, J))
    ball_r = (JOINT_RADIUS_M if bones else 1.4 * JOINT_RADIUS_M) * np.broadcast_to(np.asarray(scale, float)[:, None], (P, J))
    drawn = finite.copy()
    pairs = np.asarray(bones or (), dtype=np.int64).reshape(-1, 2)
    pairs = pairs[(pairs < J).all(axis=1)]
    if len(pairs):  # balls at the bones' joints only (a layout's extra points would clutter the skeleton)
        drawn &= np.isin(np.arange(J), pairs)[None]
    parts = [_balls(joints[drawn], ball_r[drawn], person[drawn])]
    if len(pairs):
        ok = finite[:, pairs[:, 0]] & finite[:, pairs[:, 1]]  # (P, B)
        pp, bb = np.nonzero(ok)
        parts.append(_tubes(joints[pp, pairs[bb, 0]], joints[pp, pairs[bb, 1]], BONE_RADIUS_M * np.asarray(scale, float)[pp], pp))
    return Shapes.join(parts)


def point_shapes(points_cam: np.ndarray, scale: np.ndarray) -> Shapes:
    """People's points (P, N, 3) (a point cloud without faces) as small balls; ``scale`` (P,) as above."""
    pts = np.asarray(points_cam, dtype=np.float64)
    if pts.ndim != 3 or pts.shape[0] == 0:
        return Shapes.empty()
    P, N = pts.shape[:2]
    finite = np.isfinite(pts).all(axis=-1)
    person = np.broadcast_to(np.arange(P)[:, None], (P, N))
    radius = POINT_RADIUS_M * np.broadcast_to(np.asarray(scale, float)[:, None], (P, N))
    return _balls(pts[finite], radius[finite], person[finite], _DOT)
