"""Array kernels shared by the metrics: row shifts, BLAS reductions, the batched Umeyama solve (package-private)."""

from __future__ import annotations

import numpy as np

from ._common import MM_PER_M

# The vertex metrics are memory-bound (each pass over a (P, 6890, 3) array costs about as much
# as the whole SVD part), so the kernels below avoid passes numpy makes slow: reductions and
# broadcasts over the length-3 axis run a 3-element inner loop, ~2-5x slower than a flat pass.


def _norm_mm_scratch(diff_m: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis, metres -> mm: (P, N, 3) -> (P, N). Overwrites diff_m."""
    sq = np.square(diff_m, out=diff_m) @ np.ones(3)  # BLAS row sums, ~5x (d*d).sum(-1)
    return np.multiply(np.sqrt(sq, out=sq), MM_PER_M, out=sq)


def _row_block(n_points: int) -> int:
    """Rows per block for :func:`_shift_rows`: the largest divisor of n_points up to 64."""
    return max(k for k in range(1, min(n_points, 64) + 1) if n_points % k == 0)


def _shift_rows(points: np.ndarray, shift: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Add a per-person offset to every point: (P, N, 3) + (P, 3) -> (P, N, 3).

    ``out`` (any memory layout, may be ``points``) receives the result. C-contiguous arrays are
    viewed in row blocks of ``_row_block(N)`` against a tiled offset, so the inner loop spans
    3 x block elements instead of 3 (6,890 = 130 x 53 for SMPL vertices; 24 joints are one
    block). Any other layout (Fortran order, a fancy-indexed joint subset, a strided view) takes
    a plain broadcast add: reshaping such an array copies it, and a write into the copy is lost.
    """
    n_people, n_points, _ = points.shape
    if n_points == 0:
        return points.copy() if out is None else out
    if not (points.flags.c_contiguous and (out is None or out.flags.c_contiguous)):
        return np.add(points, shift[:, None, :], out=out)
    block = _row_block(n_points)
    shape = (n_people, n_points // block, 3 * block)
    tiled = np.tile(shift, (1, block))[:, None, :]
    if out is None:
        return (points.reshape(shape) + tiled).reshape(points.shape)
    np.add(points.reshape(shape), tiled, out=out.reshape(shape))
    return out


def _apply_row_matrix(points: np.ndarray, mat: np.ndarray) -> np.ndarray:
    """Right-multiply row vectors by a (3, 3) or (P, 3, 3) matrix: (P, N, 3) -> (P, N, 3)."""
    # matmul takes a fast path only for C-contiguous 3x3 operands (~4x vs a transposed view).
    return points @ np.ascontiguousarray(mat)


def _centroid(points: np.ndarray) -> np.ndarray:
    """Mean over the point axis as a BLAS product: (P, N, 3) -> (P, 3)."""
    n_points = points.shape[1]
    if n_points == 0:
        raise ValueError("cannot align point sets with N = 0 points")
    # ones @ X is ~8x faster than X.mean(axis=1) for large N (mean reduces a strided axis).
    return (np.ones((1, 1, n_points)) @ points)[:, 0] / n_points


# Umeyama needs the cross-covariance and the source variance about the centroids. Taking the
# moments about the origin and correcting with the centroids skips centring both arrays (PA-PVE
# runs ~2x faster) but loses ~eps * (|centroid| / spread)^2 relative accuracy. Batches where
# that ratio squared passes 1e8 (a 0.3 m body 3 km from the origin) are centred first instead,
# which bounds the loss at ~1e-8 relative, far below a micrometre.
_MAX_OFFSET_TO_SPREAD_SQ = 1e8
# A source counts as collapsed (all points equal) when its variance is within the rounding noise
# of centred coordinates, ~(eps * |centroid|)^2 per point.
_COLLAPSED_SPREAD_SQ = (16.0 * np.finfo(np.float64).eps) ** 2


def _far_from_origin(
    n_points: int,
    mu_src: np.ndarray,
    mu_dst: np.ndarray,
    second_src: np.ndarray,
    second_dst: np.ndarray,
) -> np.ndarray:
    """People whose moments about the origin are too far to centre afterwards: (P,) bool.

    mu_*: (P, 3) centroids; second_*: (P,) sums of squared norms about the same origin.
    """
    offset_src = n_points * np.einsum("pi,pi->p", mu_src, mu_src)
    offset_dst = n_points * np.einsum("pi,pi->p", mu_dst, mu_dst)
    return (offset_src > _MAX_OFFSET_TO_SPREAD_SQ * (second_src - offset_src)) | (
        offset_dst > _MAX_OFFSET_TO_SPREAD_SQ * (second_dst - offset_dst)
    )


def _centred_moments(
    n_points: int, mu_src: np.ndarray, mu_dst: np.ndarray, cross: np.ndarray, second_src: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Cross-covariance (P, 3, 3) and source variance (P,) about the centroids, from moments
    about the origin: cross (P, 3, 3) = sum src dst^T, second_src (P,) = sum |src|^2."""
    cov = cross - n_points * mu_src[:, :, None] * mu_dst[:, None, :]
    return cov, second_src - n_points * np.einsum("pi,pi->p", mu_src, mu_src)


def _scale_rotation(
    cov: np.ndarray, var_src: np.ndarray, second_src: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Umeyama scale (P,) and proper rotation (P, 3, 3) from the centred moments.

    cov: (P, 3, 3) sum (src - mu_src)(dst - mu_dst)^T; var_src: (P,) sum |src - mu_src|^2;
    second_src: (P,) sum |src|^2 about the origin the coordinates were taken in.
    """
    finite = np.isfinite(cov).all(axis=(1, 2)) & np.isfinite(var_src)
    # np.linalg.svd raises on NaN; give such people the identity and NaN results below.
    u, sing, vt = np.linalg.svd(np.where(finite[:, None, None], cov, np.eye(3)))
    # Reflection fix: flip the axis of the smallest singular value when det(V U^T) < 0.
    sign = np.where(np.linalg.det(u) * np.linalg.det(vt) < 0.0, -1.0, 1.0)
    diag = np.ones_like(sing)
    diag[:, 2] = sign
    rot = (np.swapaxes(vt, 1, 2) * diag[:, None, :]) @ np.swapaxes(u, 1, 2)  # V D U^T
    # A collapsed source (all points equal) gets scale 0: every point lands on dst's centroid.
    collapsed = var_src <= _COLLAPSED_SPREAD_SQ * second_src
    scale = np.einsum("pi,pi->p", sing, diag) / np.where(collapsed, 1.0, var_src)
    scale = np.where(collapsed, 0.0, scale)
    return np.where(finite, scale, np.nan), rot


def _similarity(
    src: np.ndarray, dst: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Umeyama scale (P,), rotation (P, 3, 3), and centroids (P, 3) x2 for src -> dst."""
    n_points = src.shape[1]
    mu_src, mu_dst = _centroid(src), _centroid(dst)
    second_src = np.einsum("pni,pni->p", src, src)
    second_dst = np.einsum("pni,pni->p", dst, dst)
    if _far_from_origin(n_points, mu_src, mu_dst, second_src, second_dst).any():
        src_c, dst_c = _shift_rows(src, -mu_src), _shift_rows(dst, -mu_dst)
        cov, var_src = np.swapaxes(src_c, 1, 2) @ dst_c, np.einsum("pni,pni->p", src_c, src_c)
    else:
        cross = np.swapaxes(src, 1, 2) @ dst
        cov, var_src = _centred_moments(n_points, mu_src, mu_dst, cross, second_src)
    return (*_scale_rotation(cov, var_src, second_src), mu_src, mu_dst)


def _procrustes_residual(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Aligned prediction minus ground truth after a per-person similarity: (P, N, 3)."""
    scale, rot, mu_pred, mu_gt = _similarity(pred, gt)
    row_mat = np.ascontiguousarray(scale[:, None, None] * np.swapaxes(rot, 1, 2))  # s R^T
    resid = _apply_row_matrix(pred, row_mat)
    resid -= gt
    # s R (x - mu_pred) + mu_gt - y  =  (s R x - y) + (mu_gt - s R mu_pred)
    return _shift_rows(resid, mu_gt - (mu_pred[:, None, :] @ row_mat)[:, 0], out=resid)

