"""RotAvat: re-seat each mesh on the ground, upright, keeping its foot and crown pixels.

Per person (vectorised over people; the same transform for vertices and joints):

(i)   scale about the camera centre by ``s1`` so the mid-sole point ``F`` lands on the ground:
      ``F1 = s1 F`` with ``n . F1 + h = 0``;
(ii)  rotate about ``F1``, about the normal ``m`` of the plane through the camera centre, the
      foot and the crown, so the foot->crown axis points along ``n_p``, the ground normal
      projected onto that plane;
(iii) scale about ``F1`` by ``s3`` so the crown falls back on its original camera ray.

Every point maps as ``X' = F1 + s3 R (s1 X - F1)``. Since ``F1`` is on the foot's ray and the
new crown on the crown's ray, both pixels are unchanged exactly (``upright="paper"``).

Options beyond the paper: ``upright="full"`` rotates the axis to the true vertical ``n`` and
picks ``s3`` so the crown comes as close as possible to its ray (its pixel moves a little; the
change is reported); a per-person ``stature_m`` (e.g. one per track) replaces step (iii).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rotations import axis_angle_to_matrix

__all__ = ["FLAGS", "AlignTransform", "rotavat_transforms", "apply_transforms", "closest_scale_on_line", "person_blocks"]

# Flag codes of people that are left unchanged (0 = aligned).
FLAGS = {
    0: "",
    1: "degenerate_mesh",  # non-finite foot/crown, or crown at the foot
    2: "foot_above_horizon",  # the foot ray never meets the ground in front of the camera
    3: "foot_head_same_ray",  # camera, foot and crown are collinear: no plane to rotate in
    4: "head_ray_misses_axis",  # the upright axis never meets the crown ray in front of the camera
}
_EPS = 1e-9  # relative tolerance for parallel rays and zero-length axes


@dataclass(frozen=True)
class AlignTransform:
    """Per-person RotAvat transforms: ``X' = pivot + s3 R (s1 X - pivot)`` where flag == 0."""

    depth_scale: np.ndarray  # (P,) s1
    rotation: np.ndarray  # (P, 3, 3) R
    rotation_deg: np.ndarray  # (P,) angle of R
    pivot_cam: np.ndarray  # (P, 3) F1, the foot on the ground
    final_scale: np.ndarray  # (P,) s3
    stature_m: np.ndarray  # (P,) |crown - foot| after the transform
    flag: np.ndarray  # (P,) int, see FLAGS

    @property
    def ok(self) -> np.ndarray:
        """(P,) people that were aligned."""
        return self.flag == 0


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (..., 3) and norms (...,); zero vectors stay zero."""
    norm = np.linalg.norm(v, axis=-1)
    return np.divide(v, norm[..., None], out=np.zeros_like(v), where=norm[..., None] > 0), norm


def closest_scale_on_line(origin: np.ndarray, direction: np.ndarray, ray: np.ndarray) -> np.ndarray:
    """k (P,) such that ``origin + k direction`` is closest to the line through 0 along ``ray``."""
    d = direction
    r, _ = _unit(ray)
    d_perp = d - np.sum(d * r, axis=-1, keepdims=True) * r
    o_perp = origin - np.sum(origin * r, axis=-1, keepdims=True) * r
    denom = np.sum(d_perp * d_perp, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return -np.sum(o_perp * d_perp, axis=-1) / denom


def rotavat_transforms(
    feet_cam: np.ndarray,
    heads_cam: np.ndarray,
    up_cam: np.ndarray,
    ground_offset_m: float,
    upright: str = "paper",
    stature_m: np.ndarray | None = None,
) -> AlignTransform:
    """RotAvat transforms from mid-sole and crown points (P, 3), camera frame; see the module doc.

    ``stature_m`` (P,) fixes the final foot->crown length instead of putting the crown back on
    its ray (NaN entries keep the ray rule).
    """
    if upright not in ("paper", "full"):
        raise ValueError(f"upright must be 'paper' or 'full', got {upright!r}")
    F = np.asarray(feet_cam, dtype=np.float64)
    H = np.asarray(heads_cam, dtype=np.float64)
    n = np.asarray(up_cam, dtype=np.float64)
    n = n / np.linalg.norm(n)
    P = F.shape[0]
    flag = np.zeros(P, dtype=np.int64)
    finite = np.all(np.isfinite(F), axis=-1) & np.all(np.isfinite(H), axis=-1)
    F = np.where(finite[:, None], F, 0.0)
    H = np.where(finite[:, None], H, 0.0)
    scale_ref = np.maximum(np.linalg.norm(F, axis=-1), 1e-12)

    # (i) scale about the camera centre: n . (s1 F) + h = 0
    nF = F @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        s1 = -ground_offset_m / nF
    foot_ok = (nF < -_EPS * scale_ref) & (F[:, 2] > 0)
    s1 = np.where(foot_ok, s1, 1.0)
    F1, H1 = s1[:, None] * F, s1[:, None] * H

    # (ii) rotate about F1 in the plane (O, F1, H1) so the axis follows n projected on it
    axis, length = _unit(H1 - F1)
    m, m_norm = _unit(np.cross(F1, H1))
    degenerate = ~finite | (length <= _EPS * s1 * scale_ref)
    same_ray = m_norm <= _EPS * np.linalg.norm(F1, axis=-1) * np.maximum(np.linalg.norm(H1, axis=-1), 1e-12)
    if upright == "paper":
        target, _ = _unit(n - (m @ n)[:, None] * m)
    else:
        target = np.broadcast_to(n, F.shape).copy()
    rot_axis, sin_a = _unit(np.cross(axis, target))
    angle = np.arctan2(sin_a, np.sum(axis * target, axis=-1))
    R = axis_angle_to_matrix(rot_axis, angle)

    # (iii) scale about F1 so the crown is back on its ray (or has the given stature)
    k = closest_scale_on_line(F1, target, H)  # F1 + k target meets (or nears) the crown ray
    s3 = k / np.where(length > 0, length, 1.0)
    if stature_m is not None:
        fixed = np.isfinite(np.asarray(stature_m, dtype=np.float64))
        s3 = np.where(fixed, np.asarray(stature_m, dtype=np.float64) / np.where(length > 0, length, 1.0), s3)
    new_head = F1 + (s3 * length)[:, None] * target
    misses = ~np.isfinite(s3) | (s3 <= 0) | (np.sum(new_head * H, axis=-1) <= 0)

    flag[misses] = 4
    flag[same_ray & ~degenerate] = 3
    flag[~foot_ok] = 2
    flag[degenerate] = 1
    ok = flag == 0
    eye = np.broadcast_to(np.eye(3), (P, 3, 3))
    return AlignTransform(
        depth_scale=np.where(ok, s1, 1.0),
        rotation=np.where(ok[:, None, None], R, eye),
        rotation_deg=np.where(ok, np.rad2deg(angle), 0.0),
        pivot_cam=np.where(ok[:, None], F1, 0.0),
        final_scale=np.where(ok, s3, 1.0),
        stature_m=np.where(ok, s3 * length, np.nan),
        flag=flag,
    )


_BLOCK_BYTES = 384 * 1024  # work per block of people: small temporaries stay in cache and off mmap


def person_blocks(n_people: int, bytes_per_person: int) -> list[slice]:
    """Slices over people sized so a block's temporaries fit ``_BLOCK_BYTES``.

    Whole-frame float64 temporaries (MBs) cost more in page faults than the arithmetic; a few
    people per block keeps every temporary in cache, with one vectorised call per block.
    """
    step = max(1, _BLOCK_BYTES // max(1, bytes_per_person))
    return [slice(start, start + step) for start in range(0, n_people, step)]


def apply_transforms(points_cam: np.ndarray, transform: AlignTransform, dtype: np.dtype | None = None) -> np.ndarray:
    """Apply per-person transforms to points (P, N, 3); flagged people come back unchanged.

    ``X' = pivot + s3 R (s1 X - pivot)`` is one affine map ``X' = A X + b`` per person, computed
    in float64 and stored as ``dtype`` (default float64), a block of people at a time
    (:func:`person_blocks`). Flagged people have ``A = I``, ``b = 0`` exactly.
    """
    t = transform
    X = np.asarray(points_cam)
    A_T = np.ascontiguousarray(np.swapaxes((t.depth_scale * t.final_scale)[:, None, None] * t.rotation, 1, 2))
    b = t.pivot_cam - t.final_scale[:, None] * np.einsum("pij,pj->pi", t.rotation, t.pivot_cam)
    out = np.empty(X.shape, dtype=dtype or np.float64)
    for block in person_blocks(X.shape[0], X.shape[1] * 3 * 8):
        moved = np.matmul(X[block], A_T[block], dtype=np.float64)
        moved += b[block, None, :]
        out[block] = moved
    return out
