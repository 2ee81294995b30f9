"""Multi-person metrics of matched people: one similarity for a whole group, and the people's depth order.

A *group* is the matched people of one frame (``groups``: (M,) labels, one per matched pair; equal
labels = the same frame). Both metrics take the pairing of prediction and ground truth as given
(rotavat's matching, by ids or in 2D): they never search over permutations of the people.

- :func:`group_pa_errors_mm`: the group PA-MPJPE. One similarity (Umeyama: scale, proper rotation,
  translation) is fitted to the joints of all the group's people stacked, as the Hi4D / CHI3D
  "pair PA-MPJPE" of PromptHMR (yufu-wang/PromptHMR@d8f4031 ``prompt_hmr/evaluator.py``
  ``eval_3d``: ``pair_pa_mpjpe``, the two people's joints reshaped into one set) and BUDDI
  (muelea/buddi@8851315 ``llib/methods/hhcs_optimization/evaluation/hi4d_eval.py``:
  ``est_pa_mpjpe_h0h1``, ``pairwise_pa_mpjpe`` of the concatenated joints). Unlike per-person
  PA-MPJPE it counts where the people are relative to each other (one person 1 m off the other).
  Reported per person (its mean joint error after its group's similarity) and pooled per group
  (:func:`mean_over_groups`: a group's value is the mean over all of its stacked joints, then the
  mean over groups, as both benchmarks average over their frames).
- :func:`depth_order_shares` / :func:`pcrd`: BEV's PCRD (percentage of correct relative depth,
  Relative Human; Arthur151/ROMP@5632806 ``simple_romp/evaluation/RH_evaluation/evaluation.py``
  ``_calc_relative_depth_error_weak_``, ``get_results``). For every pair of people of a group, the
  predicted depth difference Δp must agree with the truth's relation: equal (|Δp| < 0.2 m),
  closer (Δp < −0.2 m) or farther (Δp > 0.2 m); a Δp of exactly ±0.2 m is never right, as in BEV's
  code. Relative Human annotates the truth's relation as ordinal depth layers; rotavat's truth is
  metric, so its pairs are *equal* when their true depths differ by less than the same 0.2 m, else
  closer or farther by the sign. Depth = the camera-frame z of each person's root (BEV's
  ``cam_trans[2]``). Pooled over every pair of every group (BEV's ``dr_corrects.sum() /
  dr_all.sum()``) by :func:`pooled_over_pairs`.

Every function is vectorised over people and groups (one batched SVD over the groups; pairs built
per group size, never per person), float64, and ``M = 0`` is valid.
"""

from __future__ import annotations

import math

import numpy as np

from ._common import MM_PER_M, _pair
from ._kernels import _scale_rotation

__all__ = ["DEPTH_EQUAL_M", "group_pa_errors_mm", "mean_over_groups", "group_pairs", "depth_order_shares", "pcrd",
           "pooled_over_pairs"]

# BEV's dr_thresh: two people are at the same depth when their roots differ by less than this, metres.
DEPTH_EQUAL_M = 0.2


def _group_labels(groups: np.ndarray, n_people: int) -> tuple[np.ndarray, np.ndarray]:
    """Each pair's group as 0..G-1 (inverse) and each group's size (G,); ValueError for a wrong shape."""
    labels = np.asarray(groups)
    if labels.shape != (n_people,):
        raise ValueError(f"groups must have shape ({n_people},), got {labels.shape}")
    _, inverse, counts = np.unique(labels, return_inverse=True, return_counts=True)
    return inverse.reshape(-1), counts


def _sum_by_group(values: np.ndarray, inverse: np.ndarray, n_groups: int) -> np.ndarray:
    """Sum of the rows of each group: (M, ...) -> (G, ...); a NaN stays in its own group."""
    out = np.zeros((n_groups, *values.shape[1:]))
    np.add.at(out, inverse, values)
    return out


def group_pa_errors_mm(pred_joints: np.ndarray, gt_joints: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Each person's mean joint error after its group's similarity, mm: (M, J, 3) x2, (M,) -> (M,).

    pred_joints, gt_joints: (M, J, 3) metres, matched pairs in one frame (the camera's); groups: (M,)
    labels, the frame of each pair. One Umeyama similarity (scale, rotation with det +1, translation)
    per group maps the prediction's stacked joints onto the truth's. NaN for the people of a group
    of fewer than two, or of a group with a non-finite joint. The group's value (its stacked
    PA-MPJPE) is the mean of its people's values.

    Example:
        >>> gt = np.array([[[0., 0, 5], [0, -0.5, 5], [0.3, 0, 5]], [[1., 0, 6], [1, -0.5, 6], [1.3, 0, 6]]])
        >>> pred = 2.0 * gt + [0.1, 0.2, 0.3]        # one similarity of both people: no group error
        >>> group_pa_errors_mm(pred, gt, np.zeros(2, int)).round(6).tolist()
        [0.0, 0.0]
    """
    pred, gt = _pair(pred_joints, gt_joints, "joints")
    n_people, n_joints = pred.shape[:2]
    out = np.full(n_people, np.nan)
    if n_people == 0:
        return out
    if n_joints == 0:
        raise ValueError("group PA-MPJPE needs at least one joint per person")
    inverse, counts = _group_labels(groups, n_people)
    n_groups, n_points = len(counts), counts * n_joints
    mu_pred = _sum_by_group(pred.sum(axis=1), inverse, n_groups) / n_points[:, None]  # (G, 3)
    mu_gt = _sum_by_group(gt.sum(axis=1), inverse, n_groups) / n_points[:, None]
    src, dst = pred - mu_pred[inverse, None, :], gt - mu_gt[inverse, None, :]  # centred on the group
    cov = _sum_by_group(np.swapaxes(src, 1, 2) @ dst, inverse, n_groups)  # (G, 3, 3)
    var_src = _sum_by_group(np.einsum("mji,mji->m", src, src), inverse, n_groups)
    second_src = _sum_by_group(np.einsum("mji,mji->m", pred, pred), inverse, n_groups)
    scale, rot = _scale_rotation(cov, var_src, second_src)
    row_mat = scale[:, None, None] * np.swapaxes(rot, 1, 2)  # s R^T, for row vectors
    resid = src @ row_mat[inverse] - dst
    errors = np.sqrt(np.einsum("mji,mji->mj", resid, resid)).mean(axis=1) * MM_PER_M
    return np.where(counts[inverse] >= 2, errors, out)


def mean_over_groups(values: np.ndarray, groups: np.ndarray) -> float:
    """Mean over groups of each group's mean finite value; groups without one are left out; NaN when none.

    values: (M,) per person (e.g. :func:`group_pa_errors_mm`); groups: (M,) labels (frame names).
    """
    vals = np.asarray(values, dtype=np.float64)
    inverse, _ = _group_labels(groups, len(vals))
    finite = np.isfinite(vals)
    n_groups = int(inverse.max()) + 1 if len(inverse) else 0
    sums = np.bincount(inverse[finite], weights=vals[finite], minlength=n_groups)
    counts = np.bincount(inverse[finite], minlength=n_groups)
    scored = counts > 0
    return float((sums[scored] / counts[scored]).mean()) if scored.any() else math.nan


def group_pairs(groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (i, j), i < j, of people in the same group: two (K,) int arrays, K = sum n_g (n_g - 1) / 2.

    Built once per distinct group size (a few), never per person.
    """
    labels = np.asarray(groups)
    order = np.argsort(labels, kind="stable")
    _, starts, counts = np.unique(labels[order], return_index=True, return_counts=True)
    firsts, seconds = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for size in np.unique(counts[counts >= 2]):
        a, b = np.triu_indices(size, 1)
        base = starts[counts == size][:, None]
        firsts.append(order[(base + a).ravel()])
        seconds.append(order[(base + b).ravel()])
    return np.concatenate(firsts), np.concatenate(seconds)


def _relations_right(pred_depth: np.ndarray, gt_depth: np.ndarray, groups: np.ndarray,
                     equal_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scored pairs (i, j) and whether each one's predicted depth relation is right (K,) bool."""
    zp, zg = np.asarray(pred_depth, np.float64), np.asarray(gt_depth, np.float64)
    if zp.shape != zg.shape or zp.ndim != 1:
        raise ValueError(f"pred_depth {zp.shape} and gt_depth {zg.shape} must both have shape (M,)")
    if not equal_m > 0:
        raise ValueError(f"equal_m must be > 0, got {equal_m}")
    valid = np.isfinite(zp) & np.isfinite(zg)
    kept = np.flatnonzero(valid)
    labels = np.asarray(groups)
    if labels.shape != zp.shape:
        raise ValueError(f"groups must have shape {zp.shape}, got {labels.shape}")
    i, j = group_pairs(labels[kept])
    i, j = kept[i], kept[j]
    dp, dg = zp[j] - zp[i], zg[j] - zg[i]
    equal = np.abs(dg) < equal_m
    right = np.where(equal, np.abs(dp) < equal_m, np.where(dg > 0, dp > equal_m, dp < -equal_m))
    return i, j, right


def depth_order_shares(pred_depth: np.ndarray, gt_depth: np.ndarray, groups: np.ndarray,
                       equal_m: float = DEPTH_EQUAL_M) -> np.ndarray:
    """Each person's share of right depth relations with the other people of its group: (M,) x2, (M,) -> (M,).

    pred_depth, gt_depth: (M,) metres, each person's root depth (camera z); groups: (M,) labels.
    A relation is right when the predicted difference says what the true one says: equal
    (|Δ| < equal_m), closer or farther (module docstring). NaN for a person with no other person
    of finite depth in its group. :func:`pooled_over_pairs` turns the shares into PCRD.

    Example:
        >>> gt_depth = np.array([5.0, 6.0, 7.0])            # 1 m apart: each pair is "farther"
        >>> pred_depth = np.array([5.0, 5.1, 8.0])          # people 0 and 1 "equal" (0.1 m): wrong
        >>> depth_order_shares(pred_depth, gt_depth, np.zeros(3, int)).tolist()
        [0.5, 0.5, 1.0]
    """
    n_people = len(np.asarray(pred_depth))
    i, j, right = _relations_right(pred_depth, gt_depth, groups, equal_m)
    hits = np.bincount(i, right, n_people) + np.bincount(j, right, n_people)
    pairs = np.bincount(i, minlength=n_people) + np.bincount(j, minlength=n_people)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(pairs > 0, hits / np.maximum(pairs, 1), np.nan)


def pcrd(pred_depth: np.ndarray, gt_depth: np.ndarray, groups: np.ndarray, equal_m: float = DEPTH_EQUAL_M) -> float:
    """PCRD as a share of 1: right relations over all pairs of every group (NaN without a pair).

    Example:
        >>> pcrd(np.array([5.0, 5.1, 8.0]), np.array([5.0, 6.0, 7.0]), np.zeros(3, int))  # 2 of 3 pairs right
        0.6666666666666666
    """
    _, _, right = _relations_right(pred_depth, gt_depth, groups, equal_m)
    return float(right.mean()) if right.size else math.nan


def pooled_over_pairs(shares: np.ndarray, groups: np.ndarray) -> float:
    """PCRD from the per-person shares of :func:`depth_order_shares` and their groups: each person
    weighs its number of pairs (its group's people with a share, less one), so every pair counts
    once, as :func:`pcrd` pools them; NaN without a pair."""
    vals = np.asarray(shares, dtype=np.float64)
    inverse, _ = _group_labels(groups, len(vals))
    finite = np.isfinite(vals)
    n_groups = int(inverse.max()) + 1 if len(inverse) else 0
    others = (np.bincount(inverse[finite], minlength=n_groups) - 1.0)[inverse[finite]]
    total = others.sum()
    return float((vals[finite] * others).sum() / total) if total > 0 else math.nan
