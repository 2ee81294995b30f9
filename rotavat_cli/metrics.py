"""Per-person error metrics for multi-person HPS evaluation: pure arrays, no I/O.

Inputs are metres (any float dtype); everything is computed in float64; outputs carry their
unit in the name (``*_mm``, ``*_deg``, ``*_pct``). Point sets are ``(P, N, 3)``: ``P`` people,
``N`` joints or vertices, all in one frame (the camera frame of ``CONVENTIONS.md``). Every
function is vectorised over people (one batched SVD for Procrustes, no per-person loop), and
``P = 0`` is valid everywhere.

One switch picks the alignment, so the metric families cannot drift apart:

- ``alignment="none"``: W-MPJPE / W-PVE (no alignment at all; rotavat's definition),
- ``alignment="root"``: MPJPE / PVE (pelvis joint subtracted on both sides),
- ``alignment="procrustes"``: PA-MPJPE / PA-PVE (per-person similarity, Umeyama).

SPEC's "W-MPJPE" is a different quantity (gravity frame + pelvis alignment); it lives in
:func:`w_spec_errors_mm`, see the note there.
"""

from __future__ import annotations

from typing import Literal, Mapping

import numpy as np

__all__ = [
    "ALIGNMENTS",
    "Alignment",
    "CAMERA_KEYS",
    "camera_errors",
    "detection_scores",
    "height_above_ground_m",
    "lean_deg",
    "mpjpe",
    "normalize_by_f1",
    "point_errors_mm",
    "procrustes_align",
    "pve",
    "root_err_mm",
    "stature_err_mm",
    "stature_m",
    "to_gravity_frame",
    "umeyama",
    "w_spec_errors_mm",
    "w_spec_mpjpe",
    "w_spec_pve",
]

Alignment = Literal["none", "root", "procrustes"]
ALIGNMENTS: tuple[str, ...] = ("none", "root", "procrustes")
CAMERA_KEYS: tuple[str, ...] = ("focal_px", "pitch_deg", "roll_deg", "height_m")

MM_PER_M = 1000.0
# Tolerance for "is this a unit vector / a rotation matrix": inputs come from YAML with ~1e-9
# rounding or from float32 dumps (~1e-7); 1e-5 accepts both and still rejects real mistakes.
_UNIT_TOL = 1e-5


# --------------------------------------------------------------------------- validation


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


# --------------------------------------------------------------------------- kernels


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

    ``out`` (C-contiguous, may be ``points``) receives the result. Rows are viewed in blocks of
    ``_row_block(N)`` against a tiled offset, so the inner loop spans 3 x block elements
    instead of 3 (6,890 = 130 x 53 for SMPL vertices; 24 joints are one block).
    """
    n_people, n_points, _ = points.shape
    if n_points == 0:
        return points.copy() if out is None else out
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


def _similarity(
    src: np.ndarray, dst: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Umeyama scale (P,), rotation (P, 3, 3), and centroids (P, 3) x2 for src -> dst."""
    n_points = src.shape[1]
    mu_src, mu_dst = _centroid(src), _centroid(dst)
    offset_src = n_points * np.einsum("pi,pi->p", mu_src, mu_src)
    offset_dst = n_points * np.einsum("pi,pi->p", mu_dst, mu_dst)
    second_src = np.einsum("pni,pni->p", src, src)
    var_src = second_src - offset_src
    var_dst = np.einsum("pni,pni->p", dst, dst) - offset_dst
    far = (offset_src > _MAX_OFFSET_TO_SPREAD_SQ * var_src) | (
        offset_dst > _MAX_OFFSET_TO_SPREAD_SQ * var_dst
    )
    if far.any():
        src_c, dst_c = _shift_rows(src, -mu_src), _shift_rows(dst, -mu_dst)
        cov = np.swapaxes(src_c, 1, 2) @ dst_c
        var_src = np.einsum("pni,pni->p", src_c, src_c)
    else:
        cov = np.swapaxes(src, 1, 2) @ dst - n_points * mu_src[:, :, None] * mu_dst[:, None, :]
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
    return np.where(finite, scale, np.nan), rot, mu_src, mu_dst


def _procrustes_residual(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Aligned prediction minus ground truth after a per-person similarity: (P, N, 3)."""
    scale, rot, mu_pred, mu_gt = _similarity(pred, gt)
    row_mat = np.ascontiguousarray(scale[:, None, None] * np.swapaxes(rot, 1, 2))  # s R^T
    resid = _apply_row_matrix(pred, row_mat)
    resid -= gt
    # s R (x - mu_pred) + mu_gt - y  =  (s R x - y) + (mu_gt - s R mu_pred)
    return _shift_rows(resid, mu_gt - (mu_pred[:, None, :] @ row_mat)[:, 0], out=resid)


# --------------------------------------------------------------------------- alignment


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-person similarity ``dst ≈ s·R·src + t`` (Umeyama 1991, no reflections).

    src, dst: (P, N, 3). Returns scale (P,), R (P, 3, 3) with det +1, t (P, 3), float64.
    """
    src64, dst64 = _pair(src, dst, "points")
    if src64.shape[0] == 0:
        return np.zeros(0), np.zeros((0, 3, 3)), np.zeros((0, 3))
    scale, rot, mu_src, mu_dst = _similarity(src64, dst64)
    return scale, rot, mu_dst - scale[:, None] * np.einsum("pij,pj->pi", rot, mu_src)


def procrustes_align(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Similarity-align each predicted person onto its ground truth: (P, N, 3) -> (P, N, 3).

    Scale, rotation (proper, det +1: a mirrored pose is *not* reflected back) and translation
    are solved per person with one batched SVD. Returns float64. A person with a non-finite
    point gets NaN; one whose predicted points all coincide is sent to the gt centroid.

    Example:
        >>> gt = np.array([[[0., 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]]])
        >>> pred = 2.0 * gt + 5.0        # scaled and shifted copy
        >>> bool(np.allclose(procrustes_align(pred, gt), gt))
        True
    """
    pred64, gt64 = _pair(pred, gt, "points")
    if pred64.shape[0] == 0:
        return pred64.copy()
    return _procrustes_residual(pred64, gt64) + gt64


def point_errors_mm(
    pred: np.ndarray,
    gt: np.ndarray,
    alignment: Alignment = "none",
    pred_root: np.ndarray | None = None,
    gt_root: np.ndarray | None = None,
) -> np.ndarray:
    """Per-point Euclidean error in mm after the chosen alignment: (P, N, 3) x2 -> (P, N).

    pred, gt: (P, N, 3) metres, same frame. pred_root, gt_root: (P, 3) metres, required for
    ``alignment="root"`` (the pelvis *joint*, also for vertices, as SPIN/SPEC do) and ignored
    otherwise (Procrustes absorbs any translation).
    """
    _check_alignment(alignment)
    pred64, gt64 = _pair(pred, gt, "points")
    n_people, n_points = pred64.shape[:2]
    if alignment == "procrustes":
        if n_people == 0:
            return np.zeros((0, n_points))
        return _norm_mm_scratch(_procrustes_residual(pred64, gt64))
    diff = pred64 - gt64
    if alignment == "root":
        root_diff = _roots(pred_root, "pred_root", n_people) - _roots(gt_root, "gt_root", n_people)
        _shift_rows(diff, -root_diff, out=diff)
    return _norm_mm_scratch(diff)


def mpjpe(
    pred_joints: np.ndarray,
    gt_joints: np.ndarray,
    alignment: Alignment = "root",
    root_index: int = 0,
) -> np.ndarray:
    """Mean per-joint position error per person, mm: (P, J, 3) x2 -> (P,).

    ``alignment="root"`` is MPJPE (root = joint ``root_index``; 0 = pelvis in SMPL order),
    ``"procrustes"`` is PA-MPJPE, ``"none"`` is W-MPJPE (no alignment at all).

    Example:
        >>> gt = np.array([[[0., 0, 0], [0, -0.5, 0]]])       # pelvis, spine
        >>> pred = gt + np.array([0.3, 0.4, 1.2])             # 1.3 m off
        >>> [mpjpe(pred, gt, a).round(6).tolist() for a in ("none", "root", "procrustes")]
        [[1300.0], [0.0], [0.0]]
    """
    pred64, gt64 = _pair(pred_joints, gt_joints, "joints")
    _check_root_index(root_index, pred64.shape[1])
    errors = point_errors_mm(
        pred64, gt64, alignment, pred64[:, root_index], gt64[:, root_index]
    )
    return errors.mean(axis=1)


def pve(
    pred_verts: np.ndarray,
    gt_verts: np.ndarray,
    alignment: Alignment = "root",
    pred_root: np.ndarray | None = None,
    gt_root: np.ndarray | None = None,
) -> np.ndarray:
    """Per-vertex error per person, mm: (P, V, 3) x2 -> (P,).

    ``alignment="root"`` is PVE and needs the pelvis joints pred_root, gt_root (P, 3);
    ``"procrustes"`` is PA-PVE; ``"none"`` is W-PVE.
    """
    return point_errors_mm(pred_verts, gt_verts, alignment, pred_root, gt_root).mean(axis=1)


# --------------------------------------------------------------------------- SPEC variant


def to_gravity_frame(
    points_cam: np.ndarray,
    R_world_from_cam: np.ndarray,
    t_world_from_cam: np.ndarray | None = None,
) -> np.ndarray:
    """Move camera-frame points into a gravity-aligned world frame: ``R·X + t``, (P, N, 3).

    R_world_from_cam: (3, 3) shared or (P, 3, 3) per person; t_world_from_cam: (3,) or (P, 3)
    metres, default 0 (rotation only, as SPEC does). Returns float64 (P, N, 3).
    """
    pts = _points(points_cam, "points_cam")
    rot = _rotation(R_world_from_cam, "R_world_from_cam", pts.shape[0])
    out = _apply_row_matrix(pts, np.swapaxes(rot, -1, -2))
    if t_world_from_cam is not None:
        t = np.asarray(t_world_from_cam, dtype=np.float64)
        if t.shape not in ((3,), (pts.shape[0], 3)):
            raise ValueError(f"t_world_from_cam must have shape (3,) or (P, 3), got {t.shape}")
        out += t[..., None, :] if t.ndim == 2 else t
    return out


def w_spec_errors_mm(
    pred_cam: np.ndarray,
    gt_cam: np.ndarray,
    R_world_from_cam_pred: np.ndarray,
    R_world_from_cam_gt: np.ndarray,
    pred_root_cam: np.ndarray,
    gt_root_cam: np.ndarray,
) -> np.ndarray:
    """SPEC-style world error per point, mm: each side in its own gravity frame, pelvis-aligned.

    pred_cam, gt_cam: (P, N, 3) metres in their cameras; R_world_from_cam_*: (3, 3) or
    (P, 3, 3), the *predicted* and the *true* camera rotation; *_root_cam: (P, 3) pelvis
    joints. Returns (P, N). Errors in the estimated camera pitch/roll and in the body's tilt
    count; depth and ground-position errors do not (use ``alignment="none"`` for those).

    What SPEC does (mkocabas/SPEC, ``spec/utils/compute_error.py``, ``compute_error``,
    ``eval_single`` and ``eval_j_24``): SPEC predicts the body in a gravity-aligned world frame
    (camera yaw 0) and builds the gt mesh from the world-frame pose (``pose`` /
    ``pose_0yaw_inverseyz``). Its "W-MPJPE" and "W-V2V" subtract the pelvis (H36M-regressor
    joint 0 for the 14-joint 3DPW protocol, SMPL joint 0 for the 24-joint SPEC-SYN/SPEC-MTP
    protocol) from both sides and average the joint/vertex distances; vertices are also
    offset by the *pelvis joint*, not the vertex centroid. Its camera-frame MPJPE/V2V first
    rotates the prediction with the predicted ``cam_rotmat`` (gt ``cam_rotmat`` on SPEC-SYN)
    and compares with the camera-frame gt (``pose_cam``). Note: its log line "C-MPJPE" prints
    the W-MPJPE array again. rotavat's W-MPJPE (``alignment="none"``) is stricter: no pelvis
    alignment at all.
    """
    pred64, gt64 = _pair(pred_cam, gt_cam, "cam")
    n_people = pred64.shape[0]
    rot_pred = _rotation(R_world_from_cam_pred, "R_world_from_cam_pred", n_people)
    rot_gt = _rotation(R_world_from_cam_gt, "R_world_from_cam_gt", n_people)
    pred_root = _roots(pred_root_cam, "pred_root_cam", n_people)
    gt_root = _roots(gt_root_cam, "gt_root_cam", n_people)
    # |R_p (x_p - r_p) - R_g (x_g - r_g)| = |R_g^T R_p (x_p - r_p) - (x_g - r_g)|: one rotation
    # (gt camera <- pred camera via the gravity frame) instead of two; in row-vector form the
    # right factor is M = R_p^T R_g, and the roots fold into one per-person offset.
    rel_row = np.swapaxes(rot_pred, -1, -2) @ rot_gt  # (3, 3) or (P, 3, 3)
    offset = gt_root - (pred_root[:, None, :] @ rel_row)[:, 0]  # (P, 3)
    diff = _apply_row_matrix(pred64, rel_row)
    diff -= gt64
    _shift_rows(diff, offset, out=diff)
    return _norm_mm_scratch(diff)


def w_spec_mpjpe(
    pred_joints_cam: np.ndarray,
    gt_joints_cam: np.ndarray,
    R_world_from_cam_pred: np.ndarray,
    R_world_from_cam_gt: np.ndarray,
    root_index: int = 0,
) -> np.ndarray:
    """SPEC's W-MPJPE per person, mm: (P, J, 3) x2 -> (P,) (see :func:`w_spec_errors_mm`)."""
    pred64, gt64 = _pair(pred_joints_cam, gt_joints_cam, "joints_cam")
    _check_root_index(root_index, pred64.shape[1])
    return w_spec_errors_mm(
        pred64, gt64, R_world_from_cam_pred, R_world_from_cam_gt,
        pred64[:, root_index], gt64[:, root_index],
    ).mean(axis=1)


def w_spec_pve(
    pred_verts_cam: np.ndarray,
    gt_verts_cam: np.ndarray,
    R_world_from_cam_pred: np.ndarray,
    R_world_from_cam_gt: np.ndarray,
    pred_root_cam: np.ndarray,
    gt_root_cam: np.ndarray,
) -> np.ndarray:
    """SPEC's W-V2V per person, mm: (P, V, 3) x2 -> (P,); roots are the pelvis joints (P, 3)."""
    return w_spec_errors_mm(
        pred_verts_cam, gt_verts_cam, R_world_from_cam_pred, R_world_from_cam_gt,
        pred_root_cam, gt_root_cam,
    ).mean(axis=1)


# --------------------------------------------------------------------------- ground-aware


def height_above_ground_m(
    points_cam: np.ndarray, up_cam: np.ndarray, ground_offset_m: float
) -> np.ndarray:
    """Signed height above the ground plane ``n·X + h``, metres: (..., 3) -> (...).

    up_cam: (3,) unit world-up in the camera frame (the *true* camera's); ground_offset_m: h.
    """
    pts = np.asarray(points_cam, dtype=np.float64)
    if pts.shape[-1:] != (3,):
        raise ValueError(f"points_cam must have shape (..., 3), got {pts.shape}")
    return pts @ _unit_vector(up_cam, "up_cam") + float(ground_offset_m)


def lean_deg(feet_cam: np.ndarray, heads_cam: np.ndarray, up_cam: np.ndarray) -> np.ndarray:
    """Angle between each foot→crown axis and world up, degrees: (P, 3) x2 -> (P,).

    0 = upright. NaN where head and foot coincide (no axis).
    """
    feet, heads = np.asarray(feet_cam, np.float64), np.asarray(heads_cam, np.float64)
    if feet.shape != heads.shape or feet.shape[-1:] != (3,):
        raise ValueError(f"feet_cam {feet.shape} and heads_cam {heads.shape} must both be (P, 3)")
    up = _unit_vector(up_cam, "up_cam")
    axis = heads - feet
    along = axis @ up
    across = np.linalg.norm(np.cross(axis, up), axis=-1)
    angle = np.degrees(np.arctan2(across, along))  # stable near 0 and 180, unlike arccos
    return np.where((along == 0.0) & (across == 0.0), np.nan, angle)


def root_err_mm(pred_root: np.ndarray, gt_root: np.ndarray) -> np.ndarray:
    """Euclidean distance between predicted and true roots, mm: (P, 3) x2 -> (P,)."""
    pred, gt = np.asarray(pred_root, np.float64), np.asarray(gt_root, np.float64)
    if pred.shape != gt.shape or pred.shape[-1:] != (3,):
        raise ValueError(f"pred_root {pred.shape} and gt_root {gt.shape} must both be (P, 3)")
    return np.linalg.norm(pred - gt, axis=-1) * MM_PER_M


def stature_m(feet: np.ndarray, heads: np.ndarray) -> np.ndarray:
    """Foot-to-crown length ‖head − foot‖, metres: (P, 3) x2 -> (P,)."""
    feet64, heads64 = np.asarray(feet, np.float64), np.asarray(heads, np.float64)
    if feet64.shape != heads64.shape or feet64.shape[-1:] != (3,):
        raise ValueError(f"feet {feet64.shape} and heads {heads64.shape} must both be (P, 3)")
    return np.linalg.norm(heads64 - feet64, axis=-1)


def stature_err_mm(
    pred_feet: np.ndarray, pred_heads: np.ndarray, gt_feet: np.ndarray, gt_heads: np.ndarray
) -> np.ndarray:
    """Absolute stature error ``|‖head−foot‖ pred − ‖head−foot‖ gt|``, mm: (P, 3) x4 -> (P,)."""
    return np.abs(stature_m(pred_feet, pred_heads) - stature_m(gt_feet, gt_heads)) * MM_PER_M


# --------------------------------------------------------------------------- detection


def detection_scores(matched: int, missed: int, false_positives: int) -> dict[str, float]:
    """Precision, recall and F1 from match counts (TP, FN, FP).

    ``f1 = TP / (TP + (FP + FN) / 2)``, the harmonic mean of precision and recall. Empty-case
    convention (rotavat's choice): a ratio with nothing to count is perfect, so no predictions
    gives precision 1, no ground truth gives recall 1, and a frame with neither gives
    precision = recall = f1 = 1 (nothing to find, nothing wrongly found). F1 is then 0
    whenever one side is empty and the other is not. agora_evaluation instead returns
    (0, 0, 0) when there is no ground truth (``compute_prf1`` in
    pixelite1201/agora_evaluation ``agora_evaluation/compute_average_error.py``) and rounds to
    2 decimals; rotavat does not round here.

    Example:
        >>> detection_scores(matched=8, missed=2, false_positives=2)
        {'precision': 0.8, 'recall': 0.8, 'f1': 0.8}
        >>> detection_scores(0, 0, 0)
        {'precision': 1.0, 'recall': 1.0, 'f1': 1.0}
    """
    counts = {"matched": matched, "missed": missed, "false_positives": false_positives}
    for name, value in counts.items():
        if int(value) != value or value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    tp, fn, fp = int(matched), int(missed), int(false_positives)
    precision = tp / (tp + fp) if tp + fp else 1.0
    recall = tp / (tp + fn) if tp + fn else 1.0
    f1 = tp / (tp + 0.5 * (fp + fn)) if tp + fp + fn else 1.0
    return {"precision": precision, "recall": recall, "f1": f1}


def normalize_by_f1(err_mm: float | np.ndarray, f1: float) -> float | np.ndarray:
    """AGORA's normalised errors: NMJE = MPJPE / F1, NMVE = PVE / F1 (mm); inf when F1 = 0.

    Source: pixelite1201/agora_evaluation, ``agora_evaluation/compute_average_error.py``
    (``error_dict['body-NMJE'] = body-MPJPE / f1``, same for NMVE, with MPJPE/MVE averaged
    over matched pairs only) and ``docs/evaluation_metric.md``. AGORA divides by F1 rounded to
    2 decimals; rotavat uses the exact F1.
    """
    if not 0.0 <= f1 <= 1.0:
        raise ValueError(f"f1 must be in [0, 1], got {f1!r}")
    err = np.asarray(err_mm, dtype=np.float64)
    out = err / f1 if f1 > 0.0 else np.where(np.isnan(err), np.nan, np.inf)
    return float(out) if out.ndim == 0 else out


# --------------------------------------------------------------------------- camera


def camera_errors(pred: Mapping[str, float], gt: Mapping[str, float]) -> dict[str, float]:
    """Camera errors, absolute and signed (pred − gt): focal/height in % of gt, angles in deg.

    pred, gt: mappings with ``focal_px``, ``pitch_deg``, ``roll_deg``, ``height_m`` (camera.yaml
    keys). Returns ``focal_pct``, ``pitch_deg``, ``roll_deg``, ``height_pct`` (absolute) and the
    same keys with ``_signed``; angle differences are wrapped to [-180, 180).

    Example:
        >>> gt = {"focal_px": 1000, "pitch_deg": 20, "roll_deg": 0, "height_m": 5}
        >>> pred = {"focal_px": 1100, "pitch_deg": 18, "roll_deg": 1, "height_m": 4.5}
        >>> errs = camera_errors(pred, gt)
        >>> {k: round(v, 9) for k, v in errs.items()}  # doctest: +NORMALIZE_WHITESPACE
        {'focal_pct': 10.0, 'focal_pct_signed': 10.0, 'pitch_deg': 2.0, 'pitch_deg_signed': -2.0,
         'roll_deg': 1.0, 'roll_deg_signed': 1.0, 'height_pct': 10.0, 'height_pct_signed': -10.0}
    """
    for side, cam in (("pred", pred), ("gt", gt)):
        missing = [key for key in CAMERA_KEYS if key not in cam]
        if missing:
            raise ValueError(f"{side} camera is missing {', '.join(missing)}")
    for key in ("focal_px", "height_m"):
        if float(gt[key]) == 0.0:
            raise ValueError(f"gt {key} is 0; a percentage error is undefined")

    def pct(key: str) -> float:
        return 100.0 * (float(pred[key]) - float(gt[key])) / float(gt[key])

    def wrapped(key: str) -> float:
        return (float(pred[key]) - float(gt[key]) + 180.0) % 360.0 - 180.0

    signed = {
        "focal_pct": pct("focal_px"),
        "pitch_deg": wrapped("pitch_deg"),
        "roll_deg": wrapped("roll_deg"),
        "height_pct": pct("height_m"),
    }
    out: dict[str, float] = {}
    for key, value in signed.items():
        out[key] = abs(value)
        out[f"{key}_signed"] = value
    return out
