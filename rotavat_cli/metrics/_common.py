"""Shared constants and argument checks of the metrics (package-private)."""

from __future__ import annotations

from typing import Literal

import numpy as np

Alignment = Literal["none", "root", "procrustes"]
ALIGNMENTS: tuple[str, ...] = ("none", "root", "procrustes")
CAMERA_KEYS: tuple[str, ...] = ("focal_px", "pitch_deg", "roll_deg", "height_m")

MM_PER_M = 1000.0
# Tolerance for "is this a unit vector / a rotation matrix": inputs come from YAML with ~1e-9
# rounding or from float32 dumps (~1e-7); 1e-5 accepts both and still rejects real mistakes.
_UNIT_TOL = 1e-5




def _points(x: np.ndarray, name: str) -> np.ndarray:
    """Return ``x`` as float64 of shape (P, N, 3), else raise ValueError naming ``name``."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (P, N, 3), got {arr.shape}")
    return arr


def _pair(pred: np.ndarray, gt: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate a prediction/ground-truth pair of (P, N, 3) arrays with equal shapes."""
    pred64, gt64 = _points(pred, f"pred_{what}"), _points(gt, f"gt_{what}")
    if pred64.shape != gt64.shape:
        raise ValueError(f"pred_{what} {pred64.shape} and gt_{what} {gt64.shape} differ in shape")
    return pred64, gt64


def _roots(x: np.ndarray | None, name: str, n_people: int) -> np.ndarray:
    """Return a (P, 3) float64 root array, else raise ValueError naming ``name``."""
    if x is None:
        raise ValueError(f"alignment='root' needs {name} of shape (P, 3) (the pelvis joint)")
    arr = np.asarray(x, dtype=np.float64)
    if arr.shape != (n_people, 3):
        raise ValueError(f"{name} must have shape ({n_people}, 3), got {arr.shape}")
    return arr


def _unit_vector(x: np.ndarray, name: str) -> np.ndarray:
    """Return a (3,) float64 unit vector, else raise ValueError."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {arr.shape}")
    norm = float(np.linalg.norm(arr))
    if abs(norm - 1.0) > _UNIT_TOL:
        raise ValueError(f"{name} must be a unit vector, its norm is {norm:.6g}")
    return arr


def _rotation(x: np.ndarray, name: str, n_people: int) -> np.ndarray:
    """Return a (3, 3) or (P, 3, 3) float64 rotation, else raise ValueError."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.shape not in ((3, 3), (n_people, 3, 3)):
        raise ValueError(f"{name} must have shape (3, 3) or ({n_people}, 3, 3), got {arr.shape}")
    gram = arr @ np.swapaxes(arr, -1, -2)
    if arr.size and (
        np.abs(gram - np.eye(3)).max() > _UNIT_TOL
        or np.abs(np.linalg.det(arr) - 1.0).max() > _UNIT_TOL
    ):
        raise ValueError(f"{name} must be a rotation matrix (orthonormal, det = +1)")
    return arr


def _check_root_index(root_index: int, n_joints: int) -> None:
    """Raise ValueError unless ``root_index`` addresses one of ``n_joints`` joints."""
    if not -n_joints <= root_index < n_joints:
        raise ValueError(f"root_index {root_index} is out of range for J = {n_joints} joints")


def _check_alignment(alignment: str) -> None:
    """Raise ValueError unless ``alignment`` is one of :data:`ALIGNMENTS`."""
    if alignment not in ALIGNMENTS:
        raise ValueError(f"alignment must be one of {ALIGNMENTS}, got {alignment!r}")

