"""All per-person errors of matched pairs in one call: what ``evaluate`` runs on every frame.

Precision: the single-metric functions (:func:`mpjpe`, :func:`pve`, :func:`point_errors_mm`,
:func:`procrustes_align`, :func:`umeyama`, :func:`w_spec_errors_mm`, ...) compute everything in
float64. :func:`person_errors_mm`, which computes all of them at once for ``evaluate``, uses
those same functions for the joints, but its vertex pass is memory-bound (6,890 x 3 points per
person and side), so it works in float32 per vertex, on coordinates taken about a reference
point of each side (its root; rounded to float32 once, so the rounding scales with the body's
size, not with its distance from the camera). Umeyama's moments are float64 sums of exact
float64 products of those float32 numbers, and every mean accumulates in float64. Worst case,
every rounding aligned, a vertex is off by ~5e-7 x (its distance from the root + its error,
which for W-PVE includes the pelvis offset): 1e-3 mm for a vertex 1.2 m from the pelvis and
0.8 m off. Measured against float64, the means differ by at most 3e-5 mm on bodies 4-20 m away
and 2e-4 mm on bodies 25-30 m away placed up to 3 m off (tests, ``benchmarks/bench_eval.py``).

Engines: that vertex pass runs in numpy (:func:`_vertex_errors_numpy`) or, when numba is
installed, in the compiled kernels of :mod:`._compiled` (:func:`_vertex_errors_compiled`), which
do the same arithmetic reading each person once; the two agree to ~1e-5 mm (tested).
"""

from __future__ import annotations

import functools
import importlib
import warnings
from types import ModuleType

import numpy as np

from ._common import MM_PER_M, _check_root_index, _pair, _roots, _rotation
from ._kernels import _centred_moments, _far_from_origin, _scale_rotation
from .points import mpjpe, point_errors_mm, w_spec_errors_mm

__all__ = ["ENGINES", "JOINT_ERROR_KEYS", "VERTEX_ERROR_KEYS", "compiled_kernels", "person_errors_mm", "resolve_engine"]


JOINT_ERROR_KEYS: tuple[str, ...] = ("w_mpjpe", "mpjpe", "pa_mpjpe", "w_mpjpe_spec")
VERTEX_ERROR_KEYS: tuple[str, ...] = ("w_pve", "pve", "pa_pve", "w_pve_spec")
# Who runs the vertex pass: "numba" (compiled kernels, ``pip install 'rotavat[fast]'``), "numpy",
# or "auto" (numba when it is installed).
ENGINES: tuple[str, ...] = ("auto", "numpy", "numba")

# People per block of the fused vertex pass. The block's float32/float64 scratch (~0.7 MB per
# SMPL person) is allocated once and reused, so no pass pays for fresh pages; 8 people keep it
# near the caches and still spread each block's ~40 numpy calls (one SVD batch among them)
# over enough work. Measured per pair: 6-12 within noise, 32 ~1.5x slower (cache misses).
_VERTEX_BLOCK = 8
# The float32 coordinates are taken about a reference point per person and side: the root, or
# the first vertex when the root is farther than this from it (inconsistent joints), so the
# float32 rounding scales with the body's size, not with its distance from the camera.
_MAX_REFERENCE_OFFSET_M = 2.0


def _vertex_points(x: np.ndarray, name: str) -> np.ndarray:
    """Return ``x`` as a floating (P, V, 3) array with V >= 1, in its own float dtype."""
    arr = np.asarray(x)
    if not np.issubdtype(arr.dtype, np.floating):
        arr = arr.astype(np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (P, V, 3), got {arr.shape}")
    if arr.shape[1] == 0:
        raise ValueError(f"{name}: cannot align point sets with N = 0 points")
    return arr


def _reference_points(
    pred: np.ndarray, gt: np.ndarray, roots: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-person float32 origins for each side and their offsets from the roots.

    pred, gt: (P, V, 3); roots: (P, 2, 3) float64 (pred, gt). Returns refs (P, 2, 3) float32
    and ``refs - roots`` (P, 2, 3) float64 (exact: refs are float32 numbers).
    """
    first = np.stack([pred[:, 0], gt[:, 0]], axis=1).astype(np.float64)
    with np.errstate(invalid="ignore"):  # NaN roots fall back to the (NaN-propagating) vertex
        near = np.linalg.norm(roots - first, axis=-1) <= _MAX_REFERENCE_OFFSET_M
    refs = np.where(near[..., None], roots, first).astype(np.float32)
    return refs, refs - roots


def _vertex_offsets(
    refs: np.ndarray, ref_minus_root: np.ndarray, spec_col: np.ndarray | None
) -> np.ndarray:
    """Per-person offsets (P, 3, 3) float32 that turn the centred residuals into W, root, SPEC.

    With x = X + ref on each side: W is X_p - X_g + (ref_p - ref_g); root-aligned is
    X_p - X_g + (d_p - d_g) and SPEC is Q X_p - X_g + (Q d_p - d_g), where d = ref - root
    (zero when the roots are float32 numbers) and Q = spec_col (3, 3) or (P, 3, 3).
    """
    refs64 = refs.astype(np.float64)
    d_pred, d_gt = ref_minus_root[:, 0], ref_minus_root[:, 1]
    spec = d_pred if spec_col is None else (spec_col @ d_pred[..., None])[..., 0]
    return np.stack([refs64[:, 0] - refs64[:, 1], d_pred - d_gt, spec - d_gt], 1).astype(
        np.float32
    )


def _shift_rows_f32(rows: np.ndarray, shift: np.ndarray) -> None:
    """rows += shift per person and coordinate, in place: (P, 3, V) += (P, 3) float32."""
    if shift.any():
        rows += shift[:, :, None]


def _affine_rows_f32(
    lin: np.ndarray, src: np.ndarray, dst: np.ndarray, shift: np.ndarray, out: np.ndarray
) -> None:
    """out = lin @ src + shift - dst, float32: (P|., 3, 3), (P, 3, V) x2, (P, 3) -> (P, 3, V)."""
    np.matmul(lin, src, out=out)  # one small sgemm per person, on one thread
    out -= dst
    _shift_rows_f32(out, shift)


def _sq_norms_f32(rows: np.ndarray, out: np.ndarray) -> None:
    """Squared norm over the coordinate axis: (P, K, 3, V) -> out (P, K, V). Overwrites rows."""
    np.square(rows, out=rows)
    np.add(rows[:, :, 0], rows[:, :, 1], out=out)
    out += rows[:, :, 2]


def _row_moments(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sums (P, 2, 3), squared sums (P, 2) and pred x gt cross sums (P, 3, 3) of (P, 2, 3, V).

    Each entry is one BLAS dot over V. Unlike a matrix product over the rows (3-6x slower
    here), a dot of up to 10,000 elements also stays on one OpenBLAS thread, which matters
    when other processes keep the other cores busy.
    """
    sums = (rows[..., None, :] @ np.ones((rows.shape[-1], 1)))[..., 0, 0]
    second = (rows[..., None, :] @ rows[..., None])[..., 0, 0].sum(axis=-1)
    cross = (rows[:, 0, :, None, None, :] @ rows[:, 1, None, :, :, None])[..., 0, 0]
    return sums, second, cross


def _row_similarity(
    rows: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Umeyama pred -> gt from float64 rows (P, 2, 3, V): scale, rotation, centroids x2.

    Centres ``rows`` in place for people far from their origin (see :func:`_similarity`).
    """
    n_points = rows.shape[-1]
    sums, second, cross = _row_moments(rows)
    mu = sums / n_points
    if _far_from_origin(n_points, mu[:, 0], mu[:, 1], second[:, 0], second[:, 1]).any():
        rows -= mu[..., None]
        _, second_c, cov = _row_moments(rows)
        var_src = second_c[:, 0]
    else:
        cov, var_src = _centred_moments(n_points, mu[:, 0], mu[:, 1], cross, second[:, 0])
    return (*_scale_rotation(cov, var_src, second[:, 0]), mu[:, 0], mu[:, 1])


def _similarity_as_affine(
    scale: np.ndarray, rot: np.ndarray, mu_src: np.ndarray, mu_dst: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Umeyama's s R (x - mu_src) + mu_dst as lin (P, 3, 3) and shift (P, 3), float32."""
    lin = scale[:, None, None] * rot
    shift = mu_dst - (lin @ mu_src[..., None])[..., 0]
    return lin.astype(np.float32), shift.astype(np.float32)


def _vertex_block_mm(
    pred: np.ndarray,
    gt: np.ndarray,
    refs: np.ndarray,
    offsets: np.ndarray,
    spec_col: np.ndarray | None,
    scratch: tuple[np.ndarray, ...],
) -> np.ndarray:
    """W, root, PA (and SPEC) mean errors of one block, mm: (P, V, 3) x2 -> (P, 3 or 4).

    refs: (P, 2, 3) float32 origins; offsets: (P, 3, 3) float32 from :func:`_vertex_offsets`;
    spec_col: (3, 3) or (P, 3, 3) float32 R_gt^T R_pred, or None; scratch: >= P people.
    """
    n_people, n_verts = pred.shape[:2]
    rows32, rows64, resid, sq = (buf[:n_people] for buf in scratch)
    for side, points in enumerate((pred, gt)):  # transpose to rows, centre, round to float32
        np.subtract(points.transpose(0, 2, 1), refs[:, side, :, None], out=rows32[:, side],
                    casting="unsafe")
    src, dst = rows32[:, 0], rows32[:, 1]
    np.subtract(src, dst, out=resid[:, 1])
    np.add(resid[:, 1], offsets[:, 0, :, None], out=resid[:, 0])  # W
    _shift_rows_f32(resid[:, 1], offsets[:, 1])  # root-aligned
    _sq_norms_f32(resid, sq[:, 0:2])
    np.copyto(rows64, rows32)  # exact: moments of float32 numbers, accumulated in float64
    lin, shift = _similarity_as_affine(*_row_similarity(rows64))
    _affine_rows_f32(lin, src, dst, shift, resid[:, 0])
    if spec_col is None:
        _sq_norms_f32(resid[:, :1], sq[:, 2:3])
    else:
        _affine_rows_f32(spec_col, src, dst, offsets[:, 2], resid[:, 1])
        _sq_norms_f32(resid, sq[:, 2:4])
    np.sqrt(sq, out=sq)
    return np.add.reduce(sq, axis=-1, dtype=np.float64) * (MM_PER_M / n_verts)


def _vertex_errors_numpy(
    pred: np.ndarray, gt: np.ndarray, roots: np.ndarray, spec_col: np.ndarray | None
) -> np.ndarray:
    """Mean vertex errors with numpy, in blocks of people, mm: (P, V, 3) x2 -> (3 or 4, P)."""
    n_people, n_verts, _ = pred.shape
    n_metrics = 3 if spec_col is None else 4
    refs, ref_minus_root = _reference_points(pred, gt, roots)
    offsets = _vertex_offsets(refs, ref_minus_root, spec_col)
    spec32 = None if spec_col is None else spec_col.astype(np.float32)
    block = max(1, min(_VERTEX_BLOCK, n_people))
    scratch = (
        np.empty((block, 2, 3, n_verts), np.float32),  # centred pred, gt rows
        np.empty((block, 2, 3, n_verts)),  # the same in float64, for the Umeyama moments
        np.empty((block, 2, 3, n_verts), np.float32),  # two residuals
        np.empty((block, n_metrics, n_verts), np.float32),  # squared, then plain, errors
    )
    out = np.empty((n_metrics, n_people))
    for start in range(0, n_people, block):
        rows = slice(start, start + block)
        spec_rows = spec32 if spec32 is None or spec32.ndim == 2 else spec32[rows]
        out[:, rows] = _vertex_block_mm(
            pred[rows], gt[rows], refs[rows], offsets[rows], spec_rows, scratch
        ).T
    return out


def _vertex_errors_compiled(
    kernels: ModuleType,
    pred: np.ndarray,
    gt: np.ndarray,
    roots: np.ndarray,
    spec_col: np.ndarray | None,
) -> np.ndarray:
    """The same errors as :func:`_vertex_errors_numpy` from the numba kernels of :mod:`._compiled`.

    One kernel reads each person once for the W, root-aligned and SPEC errors and the Umeyama
    moments; the similarities are solved for all people at once (the numpy code's batched SVD);
    a second kernel reads each person again for the PA error. People whose moments would need
    re-centring (see :func:`._kernels._far_from_origin`) go through the numpy pass instead.
    """
    n_people, n_verts, _ = pred.shape
    n_metrics = 3 if spec_col is None else 4
    if n_people == 0:
        return np.empty((n_metrics, 0))
    pred, gt = _kernel_input(pred), _kernel_input(gt)
    refs, ref_minus_root = _reference_points(pred, gt, roots)
    offsets = _vertex_offsets(refs, ref_minus_root, spec_col)
    spec = np.eye(3) if spec_col is None else spec_col
    spec32 = np.ascontiguousarray(np.broadcast_to(spec, (n_people, 3, 3)), dtype=np.float32)
    sums, moments = np.zeros((n_people, 4)), np.empty((n_people, 17))
    kernels.rigid_errors_and_moments(
        pred, gt, refs, offsets, spec32, spec_col is not None, sums, moments
    )
    mu = moments[:, :6].reshape(n_people, 2, 3) / n_verts
    second, cross = moments[:, 6:8], moments[:, 8:].reshape(n_people, 3, 3)
    cov, var_src = _centred_moments(n_verts, mu[:, 0], mu[:, 1], cross, second[:, 0])
    scale, rot = _scale_rotation(cov, var_src, second[:, 0])
    lin, shift = _similarity_as_affine(scale, rot, mu[:, 0], mu[:, 1])
    pa_sums = np.empty(n_people)
    kernels.affine_errors(pred, gt, refs, lin, shift, pa_sums)
    sums[:, 2] = pa_sums
    out = sums[:, :n_metrics].T * (MM_PER_M / n_verts)
    far = _far_from_origin(n_verts, mu[:, 0], mu[:, 1], second[:, 0], second[:, 1])
    if far.any():
        far_spec = spec_col if spec_col is None or spec_col.ndim == 2 else spec_col[far]
        out[:, far] = _vertex_errors_numpy(pred[far], gt[far], roots[far], far_spec)
    return out


def _kernel_input(points: np.ndarray) -> np.ndarray:
    """C-contiguous float32 or float64 points for the kernels (float16 widens exactly to float32)."""
    return np.ascontiguousarray(points, dtype=np.float32 if points.dtype.itemsize <= 4 else np.float64)


@functools.cache
def compiled_kernels() -> ModuleType | None:
    """The numba kernels (:mod:`._compiled`), imported on first use; None without numba.

    A numba that is installed but cannot load them (an incompatible numpy, no writable cache
    directory, ...) also gives None, with a warning saying why.
    """
    try:
        return importlib.import_module("._compiled", __package__)
    except ImportError:
        return None
    except Exception as exc:  # noqa: BLE001 - any failure of the optional engine falls back to numpy
        warnings.warn(f"numba kernels unavailable, using numpy for the vertex metrics: {exc}", stacklevel=2)
        return None


def resolve_engine(engine: str) -> ModuleType | None:
    """The kernels ``engine`` asks for: the compiled module, or None for the numpy pass; ValueError if unavailable."""
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
    kernels = None if engine == "numpy" else compiled_kernels()
    if engine == "numba" and kernels is None:
        raise ValueError("engine='numba' needs numba: pip install 'rotavat[fast]'")
    return kernels


def _vertex_errors_mm(
    pred: np.ndarray,
    gt: np.ndarray,
    roots: np.ndarray,
    spec_col: np.ndarray | None,
    engine: str = "auto",
) -> np.ndarray:
    """Mean vertex errors, mm: (P, V, 3) x2 -> (3 or 4, P) float64.

    roots: (P, 2, 3) float64 (pred, gt). Rows: W-PVE, PVE, PA-PVE and, when spec_col
    ((3, 3) or (P, 3, 3) float64, R_gt^T R_pred) is given, SPEC's W-PVE.
    """
    kernels = resolve_engine(engine)
    if kernels is None:
        return _vertex_errors_numpy(pred, gt, roots, spec_col)
    return _vertex_errors_compiled(kernels, pred, gt, roots, spec_col)


def person_errors_mm(
    pred_joints: np.ndarray | None = None,
    gt_joints: np.ndarray | None = None,
    pred_verts: np.ndarray | None = None,
    gt_verts: np.ndarray | None = None,
    R_world_from_cam_pred: np.ndarray | None = None,
    R_world_from_cam_gt: np.ndarray | None = None,
    root_index: int = 0,
    pred_verts_root: np.ndarray | None = None,
    gt_verts_root: np.ndarray | None = None,
    engine: str = "auto",
    pred_root: np.ndarray | None = None,
    gt_root: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Every per-person error of matched pairs in one call, mm: a dict of (P,) float64.

    pred_joints, gt_joints: (P, J, 3); pred_verts, gt_verts: (P, V, 3), metres, camera frame,
    any float dtype (pass float32 as loaded: the vertex pass converts block by block).
    R_world_from_cam_pred/_gt: (3, 3) or (P, 3, 3), both or neither. The root (P, 3) is
    ``pred_root``/``gt_root`` if given (e.g. the hips' midpoint, or the pelvis of a joint set the
    subset passed as joints lacks), else joint ``root_index``; the vertex root is *_verts_root
    (P, 3) if given, else that root, else the vertex centroid.
    ``engine`` (:data:`ENGINES`) picks who runs the vertex pass: "auto" takes the numba kernels
    when numba is installed (``pip install 'rotavat[fast]'``, ~4x faster), else numpy; both
    give the same numbers to ~1e-5 mm.

    Keys, present when their inputs are: :data:`JOINT_ERROR_KEYS` (``w_mpjpe``, ``mpjpe``,
    ``pa_mpjpe``, ``w_mpjpe_spec``) and :data:`VERTEX_ERROR_KEYS` (``w_pve``, ``pve``,
    ``pa_pve``, ``w_pve_spec``); the ``*_spec`` ones need both rotations. Joint errors are
    :func:`mpjpe` / :func:`w_spec_mpjpe` exactly. Vertex errors come from one fused pass over
    blocks of people (each block is read, transposed and converted once, and all four errors
    share it), with float32 per-vertex arithmetic: they match :func:`pve` / :func:`w_spec_pve`
    to ~1e-5 mm, 2e-4 mm on far bodies (measured; bound in the module docstring).

    Example:
        >>> gt = np.array([[[0., 0, 5], [0, -0.5, 5], [0.3, 0, 5], [0, 0, 5.4]]])  # 1 person
        >>> pred = gt + [0.0, 0.3, 0.4]                                            # 0.5 m off
        >>> errs = person_errors_mm(pred, gt, pred_verts=pred, gt_verts=gt)  # same points twice
        >>> {k: v.round(3).tolist() for k, v in errs.items()}  # doctest: +NORMALIZE_WHITESPACE
        {'w_mpjpe': [500.0], 'mpjpe': [0.0], 'pa_mpjpe': [0.0], 'w_pve': [500.0], 'pve': [0.0],
         'pa_pve': [0.0]}
    """
    if (pred_joints is None) != (gt_joints is None) or (pred_verts is None) != (gt_verts is None):
        raise ValueError("pass both pred and gt joints (or neither), and the same for vertices")
    if (R_world_from_cam_pred is None) != (R_world_from_cam_gt is None):
        raise ValueError("SPEC errors need both R_world_from_cam_pred and R_world_from_cam_gt")
    if (pred_root is None) != (gt_root is None):
        raise ValueError("pass both pred_root and gt_root (or neither)")
    spec = R_world_from_cam_pred is not None
    out: dict[str, np.ndarray] = {}
    pj = gj = None
    if pred_joints is not None:
        pj, gj = _pair(pred_joints, gt_joints, "joints")
        if pred_root is None:
            _check_root_index(root_index, pj.shape[1])
            pred_root, gt_root = pj[:, root_index], gj[:, root_index]
        out["w_mpjpe"] = mpjpe(pj, gj, "none")
        out["mpjpe"] = point_errors_mm(pj, gj, "root", pred_root, gt_root).mean(axis=1)
        out["pa_mpjpe"] = mpjpe(pj, gj, "procrustes")
        if spec:
            out["w_mpjpe_spec"] = w_spec_errors_mm(
                pj, gj, R_world_from_cam_pred, R_world_from_cam_gt, pred_root, gt_root
            ).mean(axis=1)
    if pred_verts is None:
        return out
    pv, gv = _vertex_points(pred_verts, "pred_verts"), _vertex_points(gt_verts, "gt_verts")
    if pv.shape != gv.shape:
        raise ValueError(f"pred_verts {pv.shape} and gt_verts {gv.shape} differ in shape")
    n_people = pv.shape[0]
    if pj is not None and pj.shape[0] != n_people:
        raise ValueError(f"{pj.shape[0]} people have joints but {n_people} have vertices")
    roots = np.stack(
        [
            _vertex_root(pred_verts_root, pred_root, pv, "pred_verts_root"),
            _vertex_root(gt_verts_root, gt_root, gv, "gt_verts_root"),
        ],
        axis=1,
    )
    spec_col = None
    if spec:
        rot_pred = _rotation(R_world_from_cam_pred, "R_world_from_cam_pred", n_people)
        rot_gt = _rotation(R_world_from_cam_gt, "R_world_from_cam_gt", n_people)
        spec_col = np.swapaxes(rot_gt, -1, -2) @ rot_pred  # gt camera <- pred camera
    values = _vertex_errors_mm(pv, gv, roots, spec_col, engine)
    out.update(zip(VERTEX_ERROR_KEYS, values))
    return out


def _vertex_root(
    verts_root: np.ndarray | None,
    joint_root: np.ndarray | None,
    verts: np.ndarray,
    name: str,
) -> np.ndarray:
    """The vertex root (P, 3) float64: ``verts_root`` if given, else the joints' root, else the centroid."""
    if verts_root is not None:
        return _roots(verts_root, name, verts.shape[0])
    if joint_root is not None:
        return _roots(joint_root, "pred_root/gt_root", verts.shape[0])
    return np.add.reduce(verts, axis=1, dtype=np.float64) / verts.shape[1]

