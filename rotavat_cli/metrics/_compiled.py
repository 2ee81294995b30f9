"""Compiled (numba) kernels of the fused vertex pass (package-private; optional: ``rotavat[fast]``).

Importing this module imports numba; :func:`rotavat_cli.metrics.fused.compiled_kernels` does it
lazily and falls back to the numpy pass when numba is missing. The kernels compute exactly the
quantities of the numpy pass in :mod:`.fused` with the same arithmetic (float32 per vertex on
coordinates taken about a float32 reference point per person and side, float64 moments of those
float32 numbers), but each person's 6,890 x 3 coordinates are read into a cache-sized scratch
once and every error is one loop over it, where numpy needs ~40 passes over memory.

Fast-math flags allow reassociation and contraction (vectorised sums and FMAs) but not
``nnan``/``ninf``: a NaN coordinate still gives a NaN error.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_FASTMATH = {"reassoc", "contract", "arcp", "nsz"}
_JIT = {"cache": True, "nogil": True, "fastmath": _FASTMATH, "boundscheck": False}


@njit(**_JIT)
def _centred_rows(points: np.ndarray, ref: np.ndarray, out: np.ndarray) -> None:
    """out (3, V) float32 = (points - ref) transposed, from one person's points (V, 3)."""
    flat = points.ravel()
    r0, r1, r2 = ref[0], ref[1], ref[2]
    for v in range(out.shape[1]):
        out[0, v] = flat[3 * v] - r0
        out[1, v] = flat[3 * v + 1] - r1
        out[2, v] = flat[3 * v + 2] - r2


@njit(**_JIT)
def _moments(rows: np.ndarray, out: np.ndarray) -> None:
    """float64 moments of rows (6, V) = pred xyz, gt xyz: out (17,) = sums (6), |pred|^2, |gt|^2, pred x gt (9)."""
    s0 = s1 = s2 = s3 = s4 = s5 = q0 = q1 = 0.0
    c00 = c01 = c02 = c10 = c11 = c12 = c20 = c21 = c22 = 0.0
    for v in range(rows.shape[1]):
        x, y, z = np.float64(rows[0, v]), np.float64(rows[1, v]), np.float64(rows[2, v])
        a, b, c = np.float64(rows[3, v]), np.float64(rows[4, v]), np.float64(rows[5, v])
        s0 += x
        s1 += y
        s2 += z
        s3 += a
        s4 += b
        s5 += c
        q0 += x * x + y * y + z * z
        q1 += a * a + b * b + c * c
        c00 += x * a
        c01 += x * b
        c02 += x * c
        c10 += y * a
        c11 += y * b
        c12 += y * c
        c20 += z * a
        c21 += z * b
        c22 += z * c
    values = (s0, s1, s2, s3, s4, s5, q0, q1, c00, c01, c02, c10, c11, c12, c20, c21, c22)
    for k in range(17):
        out[k] = values[k]


@njit(**_JIT)
def _affine_error_sum(rows: np.ndarray, lin: np.ndarray, shift: np.ndarray) -> float:
    """Sum over vertices of |lin @ pred + shift - gt|, float32 per vertex: rows (6, V), lin (3, 3)."""
    m00, m01, m02 = lin[0, 0], lin[0, 1], lin[0, 2]
    m10, m11, m12 = lin[1, 0], lin[1, 1], lin[1, 2]
    m20, m21, m22 = lin[2, 0], lin[2, 1], lin[2, 2]
    t0, t1, t2 = shift[0], shift[1], shift[2]
    total = 0.0
    for v in range(rows.shape[1]):
        x, y, z = rows[0, v], rows[1, v], rows[2, v]
        ex = m00 * x + m01 * y + m02 * z + t0 - rows[3, v]
        ey = m10 * x + m11 * y + m12 * z + t1 - rows[4, v]
        ez = m20 * x + m21 * y + m22 * z + t2 - rows[5, v]
        total += np.float64(np.sqrt(ex * ex + ey * ey + ez * ez))
    return total


@njit(**_JIT)
def _shift_error_sum(rows: np.ndarray, shift: np.ndarray) -> float:
    """Sum over vertices of |pred - gt + shift|, float32 per vertex: rows (6, V), shift (3,)."""
    t0, t1, t2 = shift[0], shift[1], shift[2]
    total = 0.0
    for v in range(rows.shape[1]):
        ex = rows[0, v] - rows[3, v] + t0
        ey = rows[1, v] - rows[4, v] + t1
        ez = rows[2, v] - rows[5, v] + t2
        total += np.float64(np.sqrt(ex * ex + ey * ey + ez * ez))
    return total


@njit(**_JIT)
def rigid_errors_and_moments(
    pred: np.ndarray,
    gt: np.ndarray,
    refs: np.ndarray,
    offsets: np.ndarray,
    spec_col: np.ndarray,
    with_spec: bool,
    sums: np.ndarray,
    moments: np.ndarray,
) -> None:
    """Per person: error sums of W, root-aligned and SPEC residuals, and the Umeyama moments.

    pred, gt: (P, V, 3) C-contiguous; refs: (P, 2, 3) float32; offsets: (P, 3, 3) float32 (W,
    root, SPEC shifts of :func:`.fused._vertex_offsets`); spec_col: (P, 3, 3) float32. Writes
    sums[:, 0], [:, 1] and, with ``with_spec``, [:, 3] (float64), and moments (P, 17).
    """
    rows = np.empty((6, pred.shape[1]), np.float32)
    for i in range(pred.shape[0]):
        _centred_rows(pred[i], refs[i, 0], rows[:3])
        _centred_rows(gt[i], refs[i, 1], rows[3:])
        _moments(rows, moments[i])
        sums[i, 0] = _shift_error_sum(rows, offsets[i, 0])
        sums[i, 1] = _shift_error_sum(rows, offsets[i, 1])
        if with_spec:
            sums[i, 3] = _affine_error_sum(rows, spec_col[i], offsets[i, 2])


@njit(**_JIT)
def affine_errors(
    pred: np.ndarray, gt: np.ndarray, refs: np.ndarray, lin: np.ndarray, shift: np.ndarray, sums: np.ndarray
) -> None:
    """sums[i] = sum over vertices of |lin[i] @ pred + shift[i] - gt| about refs (the PA residual).

    pred, gt: (P, V, 3) C-contiguous; refs: (P, 2, 3), lin: (P, 3, 3), shift: (P, 3) float32.
    """
    rows = np.empty((6, pred.shape[1]), np.float32)
    for i in range(pred.shape[0]):
        _centred_rows(pred[i], refs[i, 0], rows[:3])
        _centred_rows(gt[i], refs[i, 1], rows[3:])
        sums[i] = _affine_error_sum(rows, lin[i], shift[i])
