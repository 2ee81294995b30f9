"""One-frame person matching between predictions and ground truth: pure arrays, no I/O.

Every matcher returns ``(pred_idx, gt_idx)``: two int64 arrays of length ``M`` (matched
pairs), sorted by ``gt_idx``. Unmatched ground truth are misses and unmatched predictions are
false positives; the caller counts them as ``Ng - M`` and ``Np - M``. Keypoints are image
pixels ``(P, K, 2)``, or ``(P, K, 3)`` with a confidence in the last column; a keypoint that is
NaN, or whose confidence is <= 0, is ignored.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "keypoint_boxes_px",
    "box_iou",
    "match_agora",
    "match_by_ids",
    "match_hungarian",
    "mean_keypoint_distance_px",
]

_EMPTY = np.zeros(0, dtype=np.int64)


def _keypoints(x: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Split (P, K, 2|3) keypoints into float64 xy (P, K, 2) and a validity mask (P, K)."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] not in (2, 3):
        raise ValueError(f"{name} must have shape (P, K, 2) or (P, K, 3), got {arr.shape}")
    xy = arr[..., :2]
    valid = np.isfinite(xy).all(axis=-1)
    if arr.shape[-1] == 3:
        valid &= arr[..., 2] > 0.0
    return xy, valid


def _keypoint_pair(
    pred_px: np.ndarray, gt_px: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate a pred/gt keypoint pair with the same K: returns xy and masks for both."""
    pred_xy, pred_ok = _keypoints(pred_px, "pred_px")
    gt_xy, gt_ok = _keypoints(gt_px, "gt_px")
    if pred_xy.shape[1] != gt_xy.shape[1]:
        raise ValueError(
            f"pred_px has K = {pred_xy.shape[1]} keypoints but gt_px has K = {gt_xy.shape[1]}"
        )
    return pred_xy, pred_ok, gt_xy, gt_ok


def _pairwise_diff(
    pred_xy: np.ndarray, pred_ok: np.ndarray, gt_xy: np.ndarray, gt_ok: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """All-pairs keypoint offsets (Np, Ng, K, 2), zero where either side is invalid, and mask."""
    both = pred_ok[:, None, :] & gt_ok[None, :, :]
    diff = pred_xy[:, None] - gt_xy[None, :]
    return np.where(both[..., None], diff, 0.0), both


def _sorted_by_gt(pred_idx: np.ndarray, gt_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return both index arrays as int64, ordered by gt index."""
    order = np.argsort(gt_idx, kind="stable")
    return np.asarray(pred_idx, np.int64)[order], np.asarray(gt_idx, np.int64)[order]


# --------------------------------------------------------------------------- by id


def match_by_ids(pred_ids: np.ndarray, gt_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pair people that carry the same track id: (Np,), (Ng,) -> (M,), (M,) int64.

    Ids must be unique within each side (ValueError names the duplicates).

    Example:
        >>> match_by_ids([7, 3, 9], [3, 4, 7])
        (array([1, 0]), array([0, 2]))
    """
    arrays = []
    for name, ids in (("pred_ids", pred_ids), ("gt_ids", gt_ids)):
        arr = np.asarray(ids)
        if arr.ndim != 1:
            raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
        values, counts = np.unique(arr, return_counts=True)
        if (counts > 1).any():
            dupes = ", ".join(str(v) for v in values[counts > 1].tolist())
            raise ValueError(f"duplicate person ids in {name}: {dupes}")
        arrays.append(arr)
    _, pred_idx, gt_idx = np.intersect1d(*arrays, assume_unique=True, return_indices=True)
    return _sorted_by_gt(pred_idx, gt_idx)


# --------------------------------------------------------------------------- Hungarian


def mean_keypoint_distance_px(pred_px: np.ndarray, gt_px: np.ndarray) -> np.ndarray:
    """Mean 2D distance over keypoints valid on both sides, px: (Np, K, ·), (Ng, K, ·) -> (Np, Ng).

    Keypoints are (·) = 2 or 3 columns; inf for a pair that shares no valid keypoint.
    """
    pred_xy, pred_ok, gt_xy, gt_ok = _keypoint_pair(pred_px, gt_px)
    diff, both = _pairwise_diff(pred_xy, pred_ok, gt_xy, gt_ok)
    dist_sum = np.sqrt(np.einsum("...i,...i->...", diff, diff)).sum(axis=-1)
    n_both = both.sum(axis=-1)
    return np.where(n_both > 0, dist_sum / np.maximum(n_both, 1), np.inf)


def match_hungarian(
    pred_px: np.ndarray, gt_px: np.ndarray, threshold_px: float
) -> tuple[np.ndarray, np.ndarray]:
    """Optimal one-to-one matching on mean keypoint distance, gated at ``threshold_px``.

    pred_px: (Np, K, 2|3), gt_px: (Ng, K, 2|3) pixels. Pairs farther than ``threshold_px`` (or
    sharing no valid keypoint) are never matched. The gate is applied *before* the assignment
    (gated pairs cost a constant larger than any sum of allowed costs), so the solver first
    maximises the number of allowed pairs, then minimises their total distance; assigning
    first and dropping afterwards could trade a good pair away for a gated one.
    Returns (pred_idx, gt_idx) int64, sorted by gt index.
    """
    from scipy.optimize import linear_sum_assignment  # lazy: ~0.5 s to import; only Hungarian matching uses it
    if not threshold_px >= 0.0:
        raise ValueError(f"threshold_px must be >= 0, got {threshold_px!r}")
    cost = mean_keypoint_distance_px(pred_px, gt_px)
    allowed = np.isfinite(cost) & (cost <= threshold_px)
    if not allowed.any():
        return _EMPTY.copy(), _EMPTY.copy()
    n_pairs = min(cost.shape)
    big = (n_pairs + 1.0) * float(cost[allowed].max()) + 1.0
    pred_idx, gt_idx = linear_sum_assignment(np.where(allowed, cost, big))
    keep = allowed[pred_idx, gt_idx]
    return _sorted_by_gt(pred_idx[keep], gt_idx[keep])


# --------------------------------------------------------------------------- AGORA


def keypoint_boxes_px(points_px: np.ndarray) -> np.ndarray:
    """Tight box around each person's valid keypoints, (P, K, 2|3) -> (P, 4) [x1, y1, x2, y2].

    NaN row for a person with no valid keypoint.
    """
    xy, valid = _keypoints(points_px, "points_px")
    lo = np.min(xy, axis=1, initial=np.inf, where=valid[..., None])
    hi = np.max(xy, axis=1, initial=-np.inf, where=valid[..., None])
    boxes = np.concatenate([lo, hi], axis=1)
    boxes[~valid.any(axis=1)] = np.nan
    return boxes


def box_iou(boxes_a: np.ndarray, boxes_b: np.ndarray, pixel_inclusive: bool = True) -> np.ndarray:
    """All-pairs IoU of [x1, y1, x2, y2] boxes: (A, 4), (B, 4) -> (A, B); NaN box -> IoU 0.

    ``pixel_inclusive=True`` counts a box as ``(x2 − x1 + 1)(y2 − y1 + 1)`` pixels, as
    agora_evaluation's ``get_bbx_overlap`` does.
    """
    a, b = np.asarray(boxes_a, np.float64), np.asarray(boxes_b, np.float64)
    if a.ndim != 2 or a.shape[1] != 4 or b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"boxes must have shape (N, 4), got {a.shape} and {b.shape}")
    pad = 1.0 if pixel_inclusive else 0.0
    width = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    height = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(width + pad, 0.0, None) * np.clip(height + pad, 0.0, None)
    area_a = (a[:, 2] - a[:, 0] + pad) * (a[:, 3] - a[:, 1] + pad)
    area_b = (b[:, 2] - b[:, 0] + pad) * (b[:, 3] - b[:, 1] + pad)
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        iou = inter / union
    return np.where(np.isfinite(iou) & (union > 0.0), iou, 0.0)


def match_agora(
    pred_px: np.ndarray,
    gt_px: np.ndarray,
    iou_threshold: float = 0.1,
    faithful: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """AGORA's greedy matching on 2D keypoints with a keypoint-box IoU gate.

    pred_px: (Np, K, 2|3), gt_px: (Ng, K, 2|3) pixels. Returns (pred_idx, gt_idx) int64,
    sorted by gt index.

    Re-implements ``match_2d_greedy`` and ``get_bbx_overlap`` of pixelite1201/agora_evaluation,
    ``agora_evaluation/matching.py`` (with ``l2_error`` from ``agora_evaluation/utils.py``):

    - cost of a (pred, gt) pair = ``np.linalg.norm(pred[:24, :2] - gt[:24, :2], 2)``. On a
      (K, 2) array ``ord=2`` is the *spectral* norm (largest singular value), not a sum or mean
      of distances; this reproduces it, with invalid keypoints' rows zeroed (AGORA has none)
      and inf, never matched, when no keypoint is valid on both sides. AGORA uses the first 24
      (SMPL-order) joints for the cost; pass exactly the keypoints you want.
    - pairs are visited in increasing cost (ties: pred-major order, like its ``argmin`` over
      ``itertools.product(pred, gt)``). A pair whose keypoint-box IoU (boxes from all the
      keypoints, pixel-inclusive ``+1`` areas) is >= ``iou_threshold`` and whose pred and gt
      are both free becomes a match.
    - AGORA quirk, kept when ``faithful`` is True: every visited pair with IoU below the
      threshold is counted as a "false positive" even if its pred or gt is already matched,
      and the loop stops once ``matches + that count >= Np`` (or every gt is matched). So a
      low-IoU cross pair that is cheaper than a true pair can end matching early.
      ``faithful=False`` skips low-IoU pairs without counting them (plain gated greedy).
    - not reproduced: the per-gt ``valid`` mask (occlusion <= 90 %), which needs data the
      rotavat contract does not carry; drop such gt before matching instead.
    """
    if not 0.0 <= iou_threshold <= 1.0:
        raise ValueError(f"iou_threshold must be in [0, 1], got {iou_threshold!r}")
    pred_xy, pred_ok, gt_xy, gt_ok = _keypoint_pair(pred_px, gt_px)
    n_pred, n_gt = pred_xy.shape[0], gt_xy.shape[0]
    if n_pred == 0 or n_gt == 0:
        return _EMPTY.copy(), _EMPTY.copy()
    diff, both = _pairwise_diff(pred_xy, pred_ok, gt_xy, gt_ok)
    cost = np.linalg.norm(diff, ord=2, axis=(-2, -1))
    cost = np.where(both.any(axis=-1), cost, np.inf)
    iou_ok = box_iou(keypoint_boxes_px(pred_px), keypoint_boxes_px(gt_px)) >= iou_threshold

    flat_order = np.argsort(cost, axis=None, kind="stable")
    flat_order = flat_order[np.isfinite(cost.ravel()[flat_order])]
    pred_free = np.ones(n_pred, dtype=bool)
    gt_free = np.ones(n_gt, dtype=bool)
    pred_idx: list[int] = []
    gt_idx: list[int] = []
    n_low_iou = 0
    # Greedy matching is sequential by nature: one step per visited pair (at most Np * Ng,
    # a handful of people per frame); all the per-pair maths above is vectorised.
    for flat in flat_order.tolist():
        if len(pred_idx) == n_gt or len(pred_idx) + n_low_iou >= n_pred:
            break
        p, g = divmod(flat, n_gt)
        if not iou_ok[p, g]:
            n_low_iou += faithful
        elif pred_free[p] and gt_free[g]:
            pred_free[p] = gt_free[g] = False
            pred_idx.append(p)
            gt_idx.append(g)
    return _sorted_by_gt(np.array(pred_idx, np.int64), np.array(gt_idx, np.int64))
