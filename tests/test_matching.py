"""Tests for rotavat_cli.metrics.matching: ids, Hungarian with a gate, AGORA's greedy protocol."""

from __future__ import annotations

import numpy as np
import pytest

from rotavat_cli.metrics.matching import (box_iou, keypoint_boxes_px, match_agora, match_by_ids, match_hungarian,
                                          mean_keypoint_distance_px)

# A 4-keypoint "person": corners of a 40 x 100 px box.
BODY_PX = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 100.0], [0.0, 100.0]])


def _people(*offsets_px) -> np.ndarray:
    """Stack of BODY_PX shifted by each (dx, dy), (P, 4, 2)."""
    return np.array([BODY_PX + np.asarray(o, float) for o in offsets_px]).reshape(-1, 4, 2)


def _assert_pairs(result, pred_idx, gt_idx):
    """Check values, int64 dtype and gt-sorted order of a matcher's output."""
    got_pred, got_gt = result
    assert got_pred.dtype == np.int64 and got_gt.dtype == np.int64
    np.testing.assert_array_equal(got_pred, pred_idx)
    np.testing.assert_array_equal(got_gt, gt_idx)
    assert np.all(np.diff(got_gt) > 0)


# --------------------------------------------------------------------------- ids


def test_ids_swap_miss_and_false_positive():
    # gt ids 5, 6, 7; predictions 7, 9 (false positive), 5; id 6 is missed.
    _assert_pairs(match_by_ids([7, 9, 5], [5, 6, 7]), [2, 0], [0, 2])


def test_ids_empty_frames():
    _assert_pairs(match_by_ids([], [1, 2]), [], [])
    _assert_pairs(match_by_ids([1, 2], np.zeros(0, int)), [], [])
    _assert_pairs(match_by_ids([], []), [], [])


def test_ids_duplicates_raise():
    with pytest.raises(ValueError, match="duplicate person ids in pred_ids: 3"):
        match_by_ids([3, 1, 3], [1, 2])
    with pytest.raises(ValueError, match="duplicate person ids in gt_ids: 2, 4"):
        match_by_ids([1], [2, 4, 2, 4])
    with pytest.raises(ValueError, match="1-D"):
        match_by_ids([[1, 2]], [1])


# --------------------------------------------------------------------------- Hungarian


def test_hungarian_swap_and_cost():
    gt = _people((0, 0), (300, 0), (600, 0))
    pred = _people((603, 4), (0, 0), (300, 5))  # reversed order, small offsets
    cost = mean_keypoint_distance_px(pred, gt)
    assert cost[0, 2] == pytest.approx(5.0) and cost[2, 1] == pytest.approx(5.0)
    _assert_pairs(match_hungarian(pred, gt, threshold_px=20.0), [1, 2, 0], [0, 1, 2])


def test_hungarian_threshold_misses_and_false_positives():
    gt = _people((0, 0), (300, 0))
    pred = _people((900, 0), (310, 0), (0, 30))  # a false positive, 10 px and 30 px away
    _assert_pairs(match_hungarian(pred, gt, threshold_px=20.0), [1], [1])
    _assert_pairs(match_hungarian(pred, gt, threshold_px=30.0), [2, 1], [0, 1])
    _assert_pairs(match_hungarian(pred, gt, threshold_px=5.0), [], [])


def test_hungarian_gates_before_assigning():
    # Costs (K = 1): p0-g0 = 1, p0-g1 = 9, p1-g0 = 9, p1-g1 = 12 > threshold 10. Assigning
    # first would take the cheaper diagonal (13 < 18) and then drop p1-g1: one match. Gating
    # first keeps both allowed cross pairs.
    x = -0.85
    y = np.sqrt(81.0 - (x - 1.0) ** 2)
    gt = np.array([[[1.0, 0.0]], [[-9.0, 0.0]]])
    pred = np.array([[[0.0, 0.0]], [[x, y]]])
    np.testing.assert_allclose(
        mean_keypoint_distance_px(pred, gt), [[1.0, 9.0], [9.0, 12.0]], atol=1e-9
    )
    _assert_pairs(match_hungarian(pred, gt, threshold_px=10.0), [1, 0], [0, 1])


def test_hungarian_ignores_nan_and_zero_confidence_keypoints():
    gt = _people((0, 0), (300, 0))
    pred = _people((300, 0), (2, 0))
    pred[0, :3] = np.nan  # only keypoint 3 left
    conf = np.ones((2, 4, 1))
    conf[1, 0] = 0.0
    pred_conf = np.concatenate([pred, conf], axis=-1)
    pred_conf[1, 0, :2] = 1e6  # garbage where the confidence is 0
    cost = mean_keypoint_distance_px(pred_conf, gt)
    assert cost[0, 1] == pytest.approx(0.0) and cost[1, 0] == pytest.approx(2.0)
    _assert_pairs(match_hungarian(pred_conf, gt, threshold_px=10.0), [1, 0], [0, 1])


def test_hungarian_all_nan_pair_is_never_matched():
    gt = _people((0, 0))
    pred = np.full((1, 4, 2), np.nan)
    assert mean_keypoint_distance_px(pred, gt)[0, 0] == np.inf
    _assert_pairs(match_hungarian(pred, gt, threshold_px=np.inf), [], [])


@pytest.mark.parametrize(("n_pred", "n_gt"), [(0, 0), (0, 2), (3, 0)])
def test_empty_frames(n_pred, n_gt):
    pred = _people(*[(300 * i, 0) for i in range(n_pred)])
    gt = _people(*[(300 * i, 0) for i in range(n_gt)])
    _assert_pairs(match_hungarian(pred, gt, threshold_px=50.0), [], [])
    _assert_pairs(match_agora(pred, gt), [], [])
    assert mean_keypoint_distance_px(pred, gt).shape == (n_pred, n_gt)


def test_keypoint_count_mismatch_raises():
    with pytest.raises(ValueError, match="K = 4 keypoints but gt_px has K = 3"):
        match_hungarian(_people((0, 0)), np.zeros((1, 3, 2)), 10.0)


def test_hungarian_random_permutation():
    rng = np.random.default_rng(0)
    gt = rng.uniform(0, 1000, size=(6, 17, 2))
    perm = rng.permutation(6)
    pred = gt[perm] + rng.normal(0.0, 2.0, size=(6, 17, 2))
    pred_idx, gt_idx = match_hungarian(pred, gt, threshold_px=50.0)
    np.testing.assert_array_equal(gt_idx, np.arange(6))
    np.testing.assert_array_equal(perm[pred_idx], gt_idx)


# --------------------------------------------------------------------------- AGORA


def test_box_iou_pixel_inclusive_convention():
    a = np.array([[0.0, 0.0, 9.0, 9.0]])  # 10 x 10 pixels
    b = np.array([[5.0, 0.0, 14.0, 9.0], [10.0, 0.0, 19.0, 9.0]])
    np.testing.assert_allclose(box_iou(a, b), [[50.0 / 150.0, 0.0]])
    np.testing.assert_allclose(box_iou(a, b, pixel_inclusive=False), [[36.0 / 126.0, 0.0]])
    boxes = keypoint_boxes_px(np.array([[[3.0, 4.0], [np.nan, 0.0], [1.0, 8.0]]]))
    np.testing.assert_allclose(boxes, [[1.0, 4.0, 3.0, 8.0]])


def test_agora_swap_and_false_positive():
    gt = _people((0, 0), (300, 0))
    pred = _people((305, 0), (900, 0), (2, 1))
    _assert_pairs(match_agora(pred, gt), [2, 0], [0, 1])


def test_agora_iou_gate_blocks_a_lone_candidate():
    gt = _people((0, 0))
    pred = _people((41, 0))  # boxes x 0..40 and 41..81: no shared pixel column
    _assert_pairs(match_agora(pred, gt), [], [])
    _assert_pairs(match_agora(pred, gt, iou_threshold=0.0), [0], [0])


def test_agora_cost_is_the_spectral_norm():
    # A: every keypoint 1 px off in x -> mean distance 1, spectral norm ||(1,1,1,1)|| = 2.
    # B: keypoints 1.2 px off in four directions -> mean 1.2, spectral norm 1.2 * sqrt(2).
    # AGORA's l2_error (np.linalg.norm(., 2) on a (K, 2) array) prefers B; mean distance A.
    gt = _people((0, 0))
    pred_a = BODY_PX + [1.0, 0.0]
    pred_b = BODY_PX + 1.2 * np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    pred = np.stack([pred_a, pred_b])
    _assert_pairs(match_agora(pred, gt), [1], [0])
    _assert_pairs(match_hungarian(pred, gt, threshold_px=10.0), [0], [0])


def test_agora_low_iou_pair_ends_matching_early():
    # Two narrow people 6 px apart (boxes share no pixel). pred0 = gt0 exactly; pred1 sits on
    # gt1 but upside down (spectral cost 20). The cross pair pred0-gt1 costs 12 < 20 with
    # IoU 0: agora_evaluation counts it as a false positive, and 1 match + 1 such count
    # reaches Np = 2, so its loop stops before pairing pred1 with gt1.
    narrow = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 10.0], [0.0, 10.0]])
    gt = np.stack([narrow, narrow + [6.0, 0.0]])
    pred = np.stack([narrow, narrow[[3, 2, 1, 0]] + [6.0, 0.0]])
    _assert_pairs(match_agora(pred, gt), [0], [0])
    _assert_pairs(match_agora(pred, gt, faithful=False), [0, 1], [0, 1])


def test_agora_random_scene_matches_hungarian_when_unambiguous():
    rng = np.random.default_rng(0)
    gt = _people(*[(200 * i, 50 * (i % 2)) for i in range(5)])
    perm = rng.permutation(5)
    pred = gt[perm] + rng.normal(0.0, 1.0, size=gt.shape)
    expected = match_hungarian(pred, gt, threshold_px=30.0)
    _assert_pairs(match_agora(pred, gt), *expected)
    np.testing.assert_array_equal(perm[expected[0]], expected[1])
