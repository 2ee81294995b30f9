"""Batched rotations (column-vector convention: ``x_rotated = R @ x``)."""

from __future__ import annotations

import numpy as np

__all__ = ["axis_angle_to_matrix", "cross3", "matrix_to_axis_angle", "rotation_between"]


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products (..., 3) of vectors (..., 3), broadcast: ``np.cross``'s arithmetic at a third of its cost
    on a frame's ~10 people (16 vs 48 us a call).

    >>> cross3(np.array([1.0, 0.0, 0.0]), np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])).tolist()
    [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def axis_angle_to_matrix(axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Rodrigues: unit-or-not axes (..., 3) and angles (...,) -> rotation matrices (..., 3, 3).

    >>> R = axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), np.pi / 2)
    >>> np.round(R @ np.array([1.0, 0.0, 0.0]), 12) + 0.0
    array([0., 1., 0.])
    """
    k = np.asarray(axis, dtype=np.float64)
    norm = np.linalg.norm(k, axis=-1, keepdims=True)
    k = np.divide(k, norm, out=np.zeros_like(k), where=norm > 0)
    theta = np.asarray(angle_rad, dtype=np.float64)[..., None, None]
    zero = np.zeros_like(k[..., 0])
    K = np.stack([
        np.stack([zero, -k[..., 2], k[..., 1]], axis=-1),
        np.stack([k[..., 2], zero, -k[..., 0]], axis=-1),
        np.stack([-k[..., 1], k[..., 0], zero], axis=-1),
    ], axis=-2)
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + np.sin(theta) * K + (1.0 - np.cos(theta)) * (K @ K)


def rotation_between(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis (..., 3) and angle (...,) of the shortest rotation taking directions ``a`` to ``b``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    axis = np.cross(a, b)
    angle = np.arctan2(np.linalg.norm(axis, axis=-1), np.sum(a * b, axis=-1))
    return axis, angle


def matrix_to_axis_angle(rot: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> axis-angle vectors (..., 3) (angle in [0, pi], radians).

    The inverse of :func:`axis_angle_to_matrix` (scipy's quaternion route: stable near 0 and pi).

    >>> R = axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), np.pi / 2)
    >>> np.round(matrix_to_axis_angle(R), 12).tolist()
    [0.0, 0.0, 1.570796326795]
    """
    from scipy.spatial.transform import Rotation  # lazy: scipy takes ~0.1 s to import, only exports need it

    rot = np.asarray(rot, dtype=np.float64)
    flat = rot.reshape(-1, 3, 3)
    if not len(flat):
        return np.zeros(rot.shape[:-2] + (3,))
    return Rotation.from_matrix(flat).as_rotvec().reshape(rot.shape[:-2] + (3,))
