"""Multi-person metrics (issue 33): group PA-MPJPE (one similarity for a frame's matched people together, as
the Hi4D/CHI3D pair PA-MPJPE of BUDDI and PromptHMR) and PCRD (BEV's share of right depth relations), pinned
on cases worked out by hand, against a plain one-group-at-a-time Procrustes written here, and end to end
through ``evaluate`` (pooling per frame and per pair, frames never mixed in a scoring batch)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke

from rotavat_cli.metrics.evaluate import EvalOptions, evaluate, merge_results
from rotavat_cli.metrics.multi_person import (DEPTH_EQUAL_M, depth_order_shares, group_pa_errors_mm, group_pairs,
                                              mean_over_groups, pcrd, pooled_over_pairs)
from rotavat_cli.sequence import open_sequence

FOCAL, SIZE = 1000.0, (1280, 720)
# 24 joints about the pelvis (metres), spread in 3D so every fit is well posed.
SKELETON = np.array([[0.0, 0.0, 0.0], [-0.1, 0.05, 0.0], [0.1, 0.05, 0.0]]
                    + [[0.05 * (i % 5) - 0.1, -0.1 * (i // 5) + 0.6, 0.03 * (i % 3)] for i in range(21)])


def rotation(axis, angle_rad: float) -> np.ndarray:
    """Rodrigues: a proper rotation (3, 3) about ``axis``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * cross + (1 - math.cos(angle_rad)) * cross @ cross


def reference_group_pa_mm(pred: np.ndarray, gt: np.ndarray) -> float:
    """One frame's pair PA-MPJPE the way BUDDI's ProcrustesAlignment and PromptHMR's evaluator compute it: all the
    people's joints stacked into one set, one SVD, mean over the stacked joints (mm)."""
    x, y = pred.reshape(-1, 3), gt.reshape(-1, 3)
    x0, y0 = x - x.mean(0), y - y.mean(0)
    k = x0.T @ y0
    u, _, vt = np.linalg.svd(k)
    z = np.eye(3)
    z[2, 2] = np.sign(np.linalg.det(u @ vt))
    r = vt.T @ z @ u.T
    scale = np.trace(r @ k) / (x0 ** 2).sum()
    return float(np.linalg.norm(scale * x0 @ r.T + y.mean(0) - y, axis=1).mean() * 1000.0)


# ---- group PA-MPJPE ---------------------------------------------------------------------------------


def test_one_similarity_of_the_whole_group_is_no_error():
    """Both people moved by the same scale, rotation and translation: 0 (each person's PA-MPJPE too)."""
    gt = np.stack([SKELETON + [-0.6, 0.0, 5.0], SKELETON + [0.7, 0.1, 6.5]])
    pred = 1.3 * gt @ rotation([0.2, 1.0, 0.1], 0.7).T + [0.4, -0.2, 3.0]
    assert group_pa_errors_mm(pred, gt, np.array([0, 0])) == pytest.approx([0.0, 0.0], abs=1e-9)


def test_one_person_one_metre_off_along_the_line_of_the_pair():
    """Worked by hand on the x axis: A's joints at x = -1.5, -0.5, B's at 0.5, 1.5 (1 m between them); the
    prediction puts B 1 m farther. Centred, the prediction is ±h ± e with h = 1.5, e = 0.5 against ±a ± e,
    a = 1: the fitted scale is (h a + e²) / (h² + e²) = 0.7, the residuals ±(0.7 h - a) ± e (0.7 - 1) =
    ±0.05 ∓ 0.15, so every person's mean error is (0.1 + 0.2) / 2 m = 150 mm; each one alone is exact."""
    line = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0]])
    gt = np.stack([line + [-1.0, 0.0, 0.0], line + [1.0, 0.0, 0.0]])
    pred = gt.copy()
    pred[1] += [1.0, 0.0, 0.0]
    assert group_pa_errors_mm(pred, gt, np.zeros(2, int)) == pytest.approx([150.0, 150.0], abs=1e-9)
    assert reference_group_pa_mm(pred, gt) == pytest.approx(150.0, abs=1e-9)


def test_a_displaced_person_in_3d_matches_a_plain_procrustes_and_per_person_pa_does_not_see_it():
    from rotavat_cli.metrics import mpjpe

    gt = np.stack([SKELETON + [-0.5, 0.0, 5.0], SKELETON + [0.5, 0.0, 5.0]])
    pred = gt.copy()
    pred[1] += [0.0, 0.0, 1.0]  # one metre deeper than it is
    errors = group_pa_errors_mm(pred, gt, np.zeros(2, int))
    assert errors.mean() == pytest.approx(reference_group_pa_mm(pred, gt), rel=1e-12)
    assert errors.mean() > 50.0 and mpjpe(pred, gt, "procrustes") == pytest.approx([0.0, 0.0], abs=1e-9)


def test_groups_get_their_own_similarity_in_any_order_and_dtype():
    """Groups of 2 and 3 people and a lone person, shuffled: each group as if alone; the lone person NaN."""
    rng = np.random.default_rng(33)
    gt = np.stack([SKELETON + [rng.uniform(-2, 2), 0.0, rng.uniform(4, 9)] for _ in range(6)])
    pred = gt + rng.normal(0.0, 0.05, gt.shape)
    groups = np.array([7, 7, 3, 3, 3, 9])
    errors = group_pa_errors_mm(pred, gt, groups)
    for label in (7, 3):
        rows = groups == label
        assert errors[rows].mean() == pytest.approx(reference_group_pa_mm(pred[rows], gt[rows]), rel=1e-10)
    assert math.isnan(errors[5])
    order = rng.permutation(6)
    assert group_pa_errors_mm(pred[order], gt[order], groups[order]) == pytest.approx(errors[order], nan_ok=True)
    as32 = group_pa_errors_mm(pred.astype(np.float32), gt.astype(np.float32), groups)
    assert as32.dtype == np.float64 and as32 == pytest.approx(errors, abs=1e-3, nan_ok=True)


def test_a_non_finite_joint_spoils_its_group_only():
    gt = np.stack([SKELETON + [x, 0.0, 5.0] for x in (-1.0, 0.0, 1.0, 2.0)])
    pred = gt + 0.01
    pred[0, 5, 1] = np.nan
    errors = group_pa_errors_mm(pred, gt, np.array([0, 0, 1, 1]))
    assert np.isnan(errors[:2]).all() and errors[2:] == pytest.approx([0.0, 0.0], abs=1e-9)


def test_no_people_and_shape_errors():
    assert group_pa_errors_mm(np.zeros((0, 24, 3)), np.zeros((0, 24, 3)), np.zeros(0, int)).shape == (0,)
    with pytest.raises(ValueError, match="groups must have shape"):
        group_pa_errors_mm(np.zeros((2, 24, 3)), np.zeros((2, 24, 3)), np.zeros(3, int))
    with pytest.raises(ValueError, match="differ in shape"):
        group_pa_errors_mm(np.zeros((2, 24, 3)), np.zeros((2, 23, 3)), np.zeros(2, int))


def test_the_sequence_value_weighs_every_frame_once():
    """Frame a: two people at 10 mm, frame b: three at 40 mm -> (10 + 40) / 2 = 25 (per person it would be 28);
    a frame without a value (a lone person: NaN) is left out."""
    values = np.array([10.0, 10.0, 40.0, 40.0, 40.0, np.nan])
    assert mean_over_groups(values, np.array(["a", "a", "b", "b", "b", "c"])) == pytest.approx(25.0)
    assert math.isnan(mean_over_groups(np.array([np.nan]), np.array(["a"])))
    assert math.isnan(mean_over_groups(np.zeros(0), np.zeros(0, str)))


# ---- PCRD ---------------------------------------------------------------------------------------------


def test_group_pairs_are_the_pairs_within_each_group():
    i, j = group_pairs(np.array([3, 1, 3, 1, 3, 7]))
    assert sorted(zip(i.tolist(), j.tolist())) == [(0, 2), (0, 4), (1, 3), (2, 4)]
    assert [a.size for a in group_pairs(np.array([5]))] == [0, 0]


def test_three_people_of_known_depths():
    """True roots at 5.0, 5.1, 7.0 m: people 0 and 1 are at the same depth (0.1 < 0.2 m), 2 is farther than both.
    Predicted 5.0, 5.5, 6.9: 0-1 said 0.5 m apart (wrong), 0-2 and 1-2 farther (right) -> 2 of 3 pairs."""
    gt, pred = np.array([5.0, 5.1, 7.0]), np.array([5.0, 5.5, 6.9])
    assert pcrd(pred, gt, np.zeros(3, int)) == pytest.approx(2 / 3)
    assert depth_order_shares(pred, gt, np.zeros(3, int)) == pytest.approx([0.5, 0.5, 1.0])
    assert pcrd(gt, gt, np.zeros(3, int)) == 1.0  # the truth itself
    assert pcrd(pred[::-1], gt, np.zeros(3, int)) == 0.0  # 2 before 1 before 0: every relation reversed or lost


def test_equal_and_apart_at_the_threshold():
    """BEV's rule, strict on both sides (exact binary numbers, a 0.25 m threshold): predicted 0.25 m apart is
    neither equal nor apart, so never right; truly 0.25 m apart is apart (not equal)."""
    groups = np.zeros(2, int)
    assert pcrd(np.array([5.0, 5.25]), np.array([5.0, 6.0]), groups, equal_m=0.25) == 0.0
    assert pcrd(np.array([5.0, 5.5]), np.array([5.0, 5.25]), groups, equal_m=0.25) == 1.0  # truly apart, said apart
    assert pcrd(np.array([5.0, 5.0]), np.array([5.0, 5.25]), groups, equal_m=0.25) == 0.0  # said equal: wrong
    assert DEPTH_EQUAL_M == 0.2
    with pytest.raises(ValueError, match="equal_m must be > 0"):
        pcrd(np.zeros(2), np.zeros(2), groups, equal_m=0.0)


def test_pcrd_pools_every_pair_of_every_frame_once():
    """Frame a: 3 people, 2 of 3 pairs right; frame b: 2 people, 1 right; a lone person and a NaN depth add
    nothing -> 3 / 4 (a mean over frames would give 0.83)."""
    pred = np.array([5.0, 5.5, 6.9, 3.0, 9.0, 4.0, np.nan])
    gt = np.array([5.0, 5.1, 7.0, 3.0, 8.0, 4.0, 6.0])
    frames = np.array(["a", "a", "a", "b", "b", "c", "b"])
    shares = depth_order_shares(pred, gt, frames)
    assert np.isnan(shares[5:]).all()  # alone in c; no depth
    assert pcrd(pred, gt, frames) == pytest.approx(0.75)
    assert pooled_over_pairs(shares, frames) == pytest.approx(0.75)
    assert math.isnan(pcrd(np.array([5.0]), np.array([5.0]), np.zeros(1, int)))


# ---- end to end --------------------------------------------------------------------------------------


def write_seq(path: Path, frames: dict[str, dict]) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    for name, data in frames.items():
        np.savez(path / f"{name}.npz", **data)
    (path / "meta.yaml").write_text(f"image_size: [{SIZE[0]}, {SIZE[1]}]\nfocal_length: {FOCAL}\nfocal_kind: camera\n")
    return path


def people(*at, ids=None) -> dict:
    joints = np.stack([SKELETON + np.asarray(a, float) for a in at])
    return {"joints": joints, "person_ids": np.asarray(ids if ids is not None else range(len(at)))}


def test_evaluate_reports_both_with_per_frame_and_per_pair_pooling(tmp_path):
    """Frame 0: three people, the third 1 m too deep; frame 1: two people exact; frame 2: one person (no
    group). group_pa_mpjpe = mean of frame 0's and frame 1's values (0); pcrd over frame 0's 3 pairs and frame
    1's 1: the too-deep person is still farther than both others (right), so 4 / 4; per-person PA-MPJPE 0."""
    gt_at = {"000000": [(-1.0, 0.0, 5.0), (0.0, 0.0, 5.1), (1.0, 0.0, 7.0)], "000001": [(-1.0, 0.0, 5.0), (1.0, 0.0, 6.0)],
             "000002": [(0.0, 0.0, 5.0)]}
    gt = {name: people(*at) for name, at in gt_at.items()}
    pred = {name: people(*at) for name, at in gt_at.items()}
    pred["000000"]["joints"][2] += [0.0, 0.0, 1.0]
    result = evaluate(open_sequence(write_seq(tmp_path / "pred", pred)), open_sequence(write_seq(tmp_path / "gt", gt)))
    frame0 = reference_group_pa_mm(pred["000000"]["joints"], gt["000000"]["joints"])
    assert result.metrics["group_pa_mpjpe"] == pytest.approx(frame0 / 2, rel=1e-9)
    assert result.metrics["pcrd"] == 1.0 and result.metrics["pa_mpjpe"] == pytest.approx(0.0, abs=1e-9)
    assert result.units["group_pa_mpjpe"] == "mm" and result.units["pcrd"] == ""
    rows = result.per_person
    assert np.mean(rows["group_pa_mpjpe"][:3]) == pytest.approx(frame0, rel=1e-9) and math.isnan(rows["pcrd"][5])
    assert not any("group_pa_mpjpe" in note or "pcrd" in note for note in result.notes)
    # Person 1 moved from 5.1 to 8.1 m: 3.1 m behind person 0 (truly at the same depth: wrong) and 0.1 m from
    # person 2 at 8.0 (said equal, truly 1.9 m apart: wrong) -> frame 0 has 1 of 3 pairs right, 2 of 4 in all.
    pred["000000"]["joints"][1] += [0.0, 0.0, 3.0]
    moved = evaluate(open_sequence(write_seq(tmp_path / "pred2", pred)), open_sequence(tmp_path / "gt"))
    assert moved.metrics["pcrd"] == pytest.approx(2 / 4)


def test_frames_scored_in_one_batch_keep_their_own_similarity(tmp_path, monkeypatch):
    """Two frames queued into one scoring call (and one call per frame, and ranges merged) give the same numbers."""
    import rotavat_cli.metrics.evaluate as E

    rng = np.random.default_rng(5)
    gt = {f"{t:06d}": people(*[(rng.uniform(-2, 2), 0.0, rng.uniform(4, 8)) for _ in range(3)]) for t in range(4)}
    pred = {k: {**v, "joints": v["joints"] + rng.normal(0.0, 0.1, v["joints"].shape)} for k, v in gt.items()}
    seqs = (open_sequence(write_seq(tmp_path / "pred", pred)), open_sequence(write_seq(tmp_path / "gt", gt)))
    together = evaluate(*seqs)
    expected = np.mean([reference_group_pa_mm(pred[k]["joints"], gt[k]["joints"]) for k in gt])
    assert together.metrics["group_pa_mpjpe"] == pytest.approx(expected, rel=1e-9)
    monkeypatch.setattr(E, "SCORE_BATCH_PEOPLE", 1)
    one_by_one = evaluate(*seqs)
    merged = merge_results([evaluate(*seqs, frames=(0, 1)), evaluate(*seqs, frames=(1, 4))])
    for other in (one_by_one, merged):
        for name in ("group_pa_mpjpe", "pcrd"):
            assert other.metrics[name] == pytest.approx(together.metrics[name], rel=1e-12)


def test_single_person_frames_say_why_there_is_no_group_value(tmp_path):
    gt = {"000000": people((0.0, 0.0, 5.0))}
    result = evaluate(open_sequence(write_seq(tmp_path / "pred", gt)), open_sequence(write_seq(tmp_path / "gt", gt)))
    assert math.isnan(result.metrics["group_pa_mpjpe"]) and math.isnan(result.metrics["pcrd"])
    assert "group_pa_mpjpe, pcrd: no value: no frame has two matched people with joints" in result.notes


def test_only_the_paper_protocol_reports_them(tmp_path):
    gt = {"000000": people((-1.0, 0.0, 5.0), (1.0, 0.0, 6.0))}
    seqs = (open_sequence(write_seq(tmp_path / "pred", gt)), open_sequence(write_seq(tmp_path / "gt", gt)))
    for name in ("spec", "bedlam", "wham"):
        assert not {"group_pa_mpjpe", "pcrd"} & set(evaluate(*seqs, EvalOptions(protocol=name)).metrics)


def test_cli_gates_and_per_person_csv(tmp_path, runner):
    """pcrd is higher-better: `pcrd<0.9` trips on a prediction whose depth order is wrong; group_pa_mpjpe gates
    like the other errors; both are columns of the per-person CSV."""
    gt = {"000000": people((-1.0, 0.0, 5.0), (1.0, 0.0, 7.0))}
    swapped = {"000000": people((-1.0, 0.0, 7.0), (1.0, 0.0, 5.0))}
    write_seq(tmp_path / "gt", gt)
    write_seq(tmp_path / "pred", swapped)
    out = tmp_path / "ev"
    tripped = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", out, "--fail-if", "pcrd<0.9",
                     "--fail-if", "group_pa_mpjpe>5000", "--per-person", tmp_path / "pp.csv", "-q")
    assert tripped.exit_code == 1 and "pred: pcrd = 0 (pcrd<0.9)" in tripped.stderr
    assert "group_pa_mpjpe" not in tripped.stderr
    header = (tmp_path / "pp.csv").read_text().splitlines()[0].split(",")
    assert header[-2:] == ["group_pa_mpjpe", "pcrd"]
    refused = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", out, "--protocol", "wham",
                     "--fail-if", "pcrd<0.9")
    assert refused.exit_code == 2 and "--protocol wham does not report pcrd" in refused.stderr
