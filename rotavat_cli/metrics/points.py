"""Point-set errors of matched people: W-/root-aligned/PA-MPJPE and PVE, Umeyama, SPEC's gravity-frame variant."""

from __future__ import annotations

import numpy as np

from ._common import Alignment, _check_alignment, _check_root_index, _pair, _points, _roots, _rotation
from ._kernels import _apply_row_matrix, _norm_mm_scratch, _procrustes_residual, _shift_rows, _similarity

__all__ = ["umeyama", "procrustes_align", "point_errors_mm", "mpjpe", "pve", "to_gravity_frame", "w_spec_errors_mm",
           "w_spec_mpjpe", "w_spec_pve"]



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

