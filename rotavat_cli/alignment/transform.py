"""RotAvat: re-seat each mesh on the ground, upright, keeping its foot and crown pixels.

Per person (vectorised over people; the same transform for vertices and joints):

(i)   scale about the camera centre by ``s1`` so the foot point ``F`` lands on the ground:
      ``F1 = s1 F`` with ``n . F1 + h = 0``;
(ii)  rotate about ``F1``, about the normal ``m`` of the plane through the camera centre, the
      foot and the crown, so the foot->crown axis points along ``n_p``, the ground normal
      projected onto that plane;
(iii) scale about ``F1`` by ``s3`` so the crown falls back on its original camera ray.

Every point maps as ``X' = F1 + s3 R (s1 X - F1)``. Since ``F1`` is on the foot's ray and the
new crown on the crown's ray, both pixels are unchanged exactly (``upright="paper"``).

When the mesh was made with another focal than the camera's (an HPS method's guess), the rays
are those of the pixels the method drew, read in the real camera (``foot_rays_cam``,
``head_rays_cam``; :func:`method_rays_cam`). The person is first re-expressed in the camera: the
body, rigid and undistorted, moves so its foot lies on the foot pixel's ray (scale ``s1`` about
the camera centre plus the small shift that closes the gap between the two cameras' rays); then
(ii) and (iii) as above with the crown ray. The map is ``X' = F1 + s3 s1 R (X - F)``: which point
of the body is kept on its ray while re-expressing (root, foot) does not change the result.

Options beyond the paper: ``upright="full"`` rotates the axis to the true vertical ``n`` and
picks ``s3`` so the crown comes as close as possible to its ray (its pixel moves a little; the
change is reported); a per-person ``stature_m`` (e.g. one per track) replaces step (iii); a
per-person ``elevation_m`` puts the foot point that high above the ground instead of on it (a
person in the air: :mod:`rotavat_cli.alignment.flight`).

The foot point is the ground contact (:func:`rotavat_cli.bodies.landmarks.ground_contact`: the mid-sole
when both soles are level, else on the lower sole's level), so a person on one leg ends with the
standing foot on the ground.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import pixel_rays_cam, project_cam_to_px
from ..geometry.rotations import axis_angle_to_matrix, cross3

__all__ = [
    "FLAGS", "UPRIGHT", "AlignTransform", "rotavat_transforms", "affine_maps", "transformed_blocks", "apply_transforms",
    "coords_first", "points_from_coords", "closest_scale_on_line", "person_blocks", "method_rays_cam",
]

# Flag codes of people that are left unchanged (0 = aligned).
FLAGS = {
    0: "",
    1: "degenerate_mesh",  # non-finite foot/crown, or crown at the foot
    2: "foot_above_horizon",  # the foot ray never meets the ground in front of the camera
    3: "foot_head_same_ray",  # camera, foot and crown are collinear: no plane to rotate in
    4: "head_ray_misses_axis",  # the upright axis never meets the crown ray in front of the camera
    5: "cut_by_border",  # its foot or crown pixel is outside the image or at its edge: no seen foot to re-seat it by
}
_EPS = 1e-9  # relative tolerance for parallel rays and zero-length axes
UPRIGHT = ("paper", "full")  # the paper's in-plane vertical, or the true vertical


@dataclass(frozen=True)
class AlignTransform:
    """Per-person RotAvat transforms: ``X' = pivot + s3 s1 R (X - foot)`` where flag == 0.

    ``foot_cam`` is the foot point before, ``pivot_cam`` after (on the ground); when the foot lies on
    its own ray (same focal) ``pivot = s1 foot`` and this is the paper's ``pivot + s3 R (s1 X - pivot)``.
    """

    depth_scale: np.ndarray  # (P,) s1: the foot's depth after over before
    rotation: np.ndarray  # (P, 3, 3) R
    rotation_deg: np.ndarray  # (P,) angle of R
    pivot_cam: np.ndarray  # (P, 3) F1, the foot on the ground
    final_scale: np.ndarray  # (P,) s3
    stature_m: np.ndarray  # (P,) |crown - foot| after the transform
    flag: np.ndarray  # (P,) int, see FLAGS
    foot_cam: np.ndarray  # (P, 3) F, the foot point (ground contact) before the transform

    @property
    def ok(self) -> np.ndarray:
        """(P,) people that were aligned."""
        return self.flag == 0

    def rows(self, people: slice) -> "AlignTransform":
        """The transforms of some people (a slice of the P)."""
        return AlignTransform(**{f.name: getattr(self, f.name)[people] for f in dataclasses.fields(self)})


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (..., 3) and norms (...,); zero vectors stay zero."""
    norm = np.linalg.norm(v, axis=-1)
    return np.divide(v, norm[..., None], out=np.zeros_like(v), where=norm[..., None] > 0), norm


def _rows_dot(rows: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(P,) ``rows (P, 3) @ v (3,)`` by one kernel whatever P. numpy's matrix-vector product takes another BLAS kernel
    for a single row, which rounds differently; a lone row is computed beside a copy of itself, so a person's
    transform does not depend on how many people it is computed with (a frame, or align's chunk of frames)."""
    if len(rows) == 1:
        return (np.concatenate([rows, rows]) @ v)[:1]
    return rows @ v


def closest_scale_on_line(origin: np.ndarray, direction: np.ndarray, ray: np.ndarray) -> np.ndarray:
    """k (P,) such that ``origin + k direction`` is closest to the line through 0 along ``ray``."""
    d = direction
    r, _ = _unit(ray)
    d_perp = d - np.sum(d * r, axis=-1, keepdims=True) * r
    o_perp = origin - np.sum(origin * r, axis=-1, keepdims=True) * r
    denom = np.sum(d_perp * d_perp, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return -np.sum(o_perp * d_perp, axis=-1) / denom


def method_rays_cam(points_cam: np.ndarray, mesh_focal_px: np.ndarray | float, mesh_principal_point: tuple | np.ndarray,
                    focal_px: float, principal_point: tuple | np.ndarray) -> np.ndarray:
    """Rays (P, 3) (z = 1) of the camera through the pixels that points (P, 3) have in the method's camera.

    mesh_focal_px: scalar or (P,), the focal the meshes were made with; focal_px, principal_point:
    the real camera's. With equal intrinsics the rays point at the points themselves.
    """
    focal = np.broadcast_to(np.asarray(mesh_focal_px, dtype=np.float64), np.shape(points_cam)[:-1])
    pixels = project_cam_to_px(points_cam, focal, mesh_principal_point)
    return pixel_rays_cam(pixels, focal_px, principal_point)


def rotavat_transforms(
    feet_cam: np.ndarray,
    heads_cam: np.ndarray,
    up_cam: np.ndarray,
    ground_offset_m: float,
    upright: str = "paper",
    stature_m: np.ndarray | None = None,
    foot_rays_cam: np.ndarray | None = None,
    head_rays_cam: np.ndarray | None = None,
    elevation_m: np.ndarray | None = None,
    seen: np.ndarray | None = None,
) -> AlignTransform:
    """RotAvat transforms from foot (ground contact) and crown points (P, 3), camera frame; see the module doc.

    ``stature_m`` (P,) fixes the final foot->crown length instead of putting the crown back on
    its ray (NaN entries keep the ray rule). ``foot_rays_cam``/``head_rays_cam`` (P, 3): the rays
    the foot and crown must end on (default: through the points themselves). ``elevation_m`` (P,):
    the height above the ground the foot point ends at (default 0: on the ground; NaN entries: 0).
    ``seen`` (P,) bool: whose foot and crown pixels are seen whole (:func:`rotavat_cli.bodies.frame_points.in_view`);
    the others are left unchanged, flagged ``cut_by_border`` (default: everyone is seen).
    """
    if upright not in UPRIGHT:
        raise ValueError(f"upright must be one of {', '.join(UPRIGHT)}, got {upright!r}")
    F = np.asarray(feet_cam, dtype=np.float64)
    H = np.asarray(heads_cam, dtype=np.float64)
    rF = F if foot_rays_cam is None else np.asarray(foot_rays_cam, dtype=np.float64)
    rH = H if head_rays_cam is None else np.asarray(head_rays_cam, dtype=np.float64)
    n = np.asarray(up_cam, dtype=np.float64)
    n = n / np.linalg.norm(n)
    P = F.shape[0]
    flag = np.zeros(P, dtype=np.int64)
    finite = np.all(np.isfinite(np.concatenate([F, H, rF, rH], axis=-1)), axis=-1)
    F, H = (np.where(finite[:, None], a, 0.0) for a in (F, H))
    rF, rH = (np.where(finite[:, None], a, (0.0, 0.0, 1.0)) for a in (rF, rH))
    scale_ref = np.maximum(np.linalg.norm(F, axis=-1), 1e-12)

    # (i) onto the ground (or ``elevation`` above it) along the foot's ray: F1 = t rF with n . F1 + h = elevation
    elevation = np.zeros(P) if elevation_m is None else np.nan_to_num(np.asarray(elevation_m, dtype=np.float64))
    nr = _rows_dot(rF, n)
    ray_len = np.linalg.norm(rF, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (elevation - ground_offset_m) / nr
    foot_ok = (nr < -_EPS * ray_len) & (rF[:, 2] > 0) & (F[:, 2] > 0) & (elevation < ground_offset_m)
    F1 = np.where(foot_ok[:, None], t[:, None] * rF, F)
    s1 = np.where(foot_ok, F1[:, 2] / np.where(F[:, 2] > 0, F[:, 2], 1.0), 1.0)

    # (ii) rotate about F1 in the plane (O, F1, crown ray) so the axis follows n projected on it
    axis, length = _unit(H - F)
    m, m_norm = _unit(cross3(F1, rH))
    degenerate = ~finite | (length <= _EPS * scale_ref)
    same_ray = m_norm <= _EPS * np.linalg.norm(F1, axis=-1) * np.maximum(np.linalg.norm(rH, axis=-1), 1e-12)
    if upright == "paper":
        target, _ = _unit(n - _rows_dot(m, n)[:, None] * m)
    else:
        target = np.broadcast_to(n, F.shape).copy()
    rot_axis, sin_a = _unit(cross3(axis, target))
    angle = np.arctan2(sin_a, np.sum(axis * target, axis=-1))
    R = axis_angle_to_matrix(rot_axis, angle)

    # (iii) scale about F1 so the crown is back on its ray (or has the given stature)
    k = closest_scale_on_line(F1, target, rH)  # F1 + k target meets (or nears) the crown ray
    if stature_m is not None:
        fixed = np.isfinite(np.asarray(stature_m, dtype=np.float64))
        k = np.where(fixed, np.asarray(stature_m, dtype=np.float64), k)
    scale = k / np.where(length > 0, length, 1.0)  # s3 s1: the body's overall scale
    new_head = F1 + k[:, None] * target
    misses = ~np.isfinite(k) | (k <= 0) | (np.sum(new_head * rH, axis=-1) <= 0)

    flag[misses] = 4
    flag[same_ray & ~degenerate] = 3
    flag[~foot_ok] = 2
    if seen is not None:  # a person the image border cuts, who could otherwise be re-seated
        flag[~np.asarray(seen, bool) & (flag == 0)] = 5
    flag[degenerate] = 1
    ok = flag == 0
    eye = np.broadcast_to(np.eye(3), (P, 3, 3))
    return AlignTransform(
        depth_scale=np.where(ok, s1, 1.0),
        rotation=np.where(ok[:, None, None], R, eye),
        rotation_deg=np.where(ok, np.rad2deg(angle), 0.0),
        pivot_cam=np.where(ok[:, None], F1, F),
        final_scale=np.where(ok, scale / np.where(s1 != 0, s1, 1.0), 1.0),
        stature_m=np.where(ok, k, np.nan),
        flag=flag,
        foot_cam=F,
    )


# Bytes of arrays per block of people (3 SMPL meshes). Measured on frames of 10 SMPL meshes: 1 to 5
# people a block are within noise of each other, the whole frame in one block is 10-30% slower
# (its MBs of float64 temporaries fall out of cache into fresh, page-faulting memory).
_BLOCK_BYTES = 1024 * 1024


def person_blocks(n_people: int, bytes_per_person: int) -> list[slice]:
    """Slices over people sized so a block's arrays fit ``_BLOCK_BYTES``, in order."""
    step = max(1, _BLOCK_BYTES // max(1, bytes_per_person))
    return [slice(start, start + step) for start in range(0, n_people, step)]


def affine_maps(transform: AlignTransform) -> tuple[np.ndarray, np.ndarray]:
    """Each person's transform as one affine map ``X' = A X + b``: A (P, 3, 3), b (P, 3), float64."""
    t = transform
    A = (t.depth_scale * t.final_scale)[:, None, None] * t.rotation
    b = t.pivot_cam - np.einsum("pij,pj->pi", A, t.foot_cam)
    return A, b


def coords_first(points: np.ndarray) -> np.ndarray:
    """Points (p, N, 3) -> a coordinates-first copy (p, 3, N) of the same dtype.

    One coordinate at a time: a single transposing copy would run its inner loop over 3 values.

    >>> points = np.arange(12.0).reshape(2, 2, 3)
    >>> coords_first(points)[0]
    array([[0., 3.],
           [1., 4.],
           [2., 5.]])
    >>> np.array_equal(points_from_coords([coords_first(points)], 2, points.dtype), points)
    True
    """
    coords = np.empty((points.shape[0], 3, points.shape[1]), dtype=points.dtype)
    for k in range(3):
        coords[:, k] = points[..., k]
    return coords


def points_from_coords(blocks: list[np.ndarray], n_points: int, dtype: np.dtype) -> np.ndarray:
    """Coordinates-first blocks [(p, 3, N), ...] -> their points stacked (sum of p, N, 3) as ``dtype``.

    The inverse of :func:`coords_first` over a list of blocks, again one coordinate at a time.
    """
    points = np.empty((sum(len(block) for block in blocks), n_points, 3), dtype=dtype)
    start = 0
    for block in blocks:
        for k in range(3):
            points[start:start + len(block), :, k] = block[:, k]
        start += len(block)
    return points


def _affine_coords_first(coords: np.ndarray, A: np.ndarray, b: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """``A X + b`` per person on coordinates-first points (p, 3, N) of any float dtype -> (p, 3, N) ``dtype``.

    Each output coordinate is a float64 row of three products and sums over whole input rows,
    then stored as ``dtype``; two float64 rows are reused, so the temporaries stay small. The input
    is made float64 once (exact), not cast again by each of the nine products. (A float64 BLAS matmul
    spends more on zeroing and packing 3x3 operands than on the products; a mixed-dtype matmul falls
    back to a slow casting loop.)
    """
    moved = np.empty(coords.shape, dtype=dtype)
    coords = coords.astype(np.float64, copy=False)
    row = np.empty(coords[:, 0].shape, dtype=np.float64)
    term = np.empty_like(row)
    for i in range(3):
        np.multiply(coords[:, 0], A[:, i, 0, None], out=row)
        for j in (1, 2):
            row += np.multiply(coords[:, j], A[:, i, j, None], out=term)
        row += b[:, i, None]
        moved[:, i] = row
    return moved


def transformed_blocks(points_cam: np.ndarray, transform: AlignTransform,
                       dtype: np.dtype | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Points (P, N, 3) before and after the transforms, a block of people at a time, coordinates first.

    Yields (before (p, 3, N) in the input dtype, after (p, 3, N) as ``dtype``, default float64)
    for consecutive blocks of :func:`person_blocks`, so a caller that also reduces each block
    (align's drift report) does it while the block is in cache. Flagged people come back unchanged.
    """
    X = np.asarray(points_cam)
    A, b = affine_maps(transform)
    flagged = ~transform.ok
    bytes_per_person = X.shape[1] * (2 * 3 * X.itemsize + 2 * 8)  # before, after, two float64 rows
    for block in person_blocks(X.shape[0], bytes_per_person):
        before = coords_first(X[block])
        with np.errstate(invalid="ignore"):  # a flagged (degenerate) person may hold inf; replaced below
            after = _affine_coords_first(before, A[block], b[block], dtype or np.float64)
        keep = flagged[block]
        if keep.any():
            after[keep] = before[keep]
        yield before, after


def apply_transforms(points_cam: np.ndarray, transform: AlignTransform, dtype: np.dtype | None = None) -> np.ndarray:
    """Apply per-person transforms to points (P, N, 3); flagged people come back unchanged.

    ``X' = pivot + s3 s1 R (X - foot)`` is one affine map ``X' = A X + b`` per person
    (:func:`affine_maps`), computed in float64 and stored as ``dtype`` (default float64), a block
    of people at a time (:func:`transformed_blocks`).
    """
    X = np.asarray(points_cam)
    dtype = np.dtype(dtype or np.float64)
    moved = [after for _, after in transformed_blocks(X, transform, dtype)]
    return points_from_coords(moved, X.shape[1], dtype)
