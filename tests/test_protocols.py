"""Evaluation protocols (issue 18): each benchmark's root, joint set, alignment, matching, rounding and
temporal metrics, pinned on small hand-made cases whose numbers are worked out by hand (or by a
straightforward reference written here, following the benchmark's code), and the --joints bugs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.errors import InputError
from rotavat_cli.metrics.evaluate import EvalOptions, evaluate, merge_results
from rotavat_cli.metrics.protocols import agora_prf1, agora_round
from rotavat_cli.metrics.temporal import (TrackSeries, accel_errors, chunk_aligned_errors, first_frames_aligned_errors,
                                          foot_sliding, jitter, rte)
from rotavat_cli.sequence import open_sequence, write_camera_yaml

FOCAL, SIZE = 1000.0, (1280, 720)
# 24 SMPL-ordered joints, metres about the pelvis: hips at +-0.1 m in x, the others spread on a grid.
SKELETON = np.array([[0.0, 0.0, 0.0], [-0.1, 0.05, 0.0], [0.1, 0.05, 0.0]]
                    + [[0.05 * (i % 5) - 0.1, -0.1 * (i // 5) + 0.6, 0.02 * (i % 3)] for i in range(21)])


def write_seq(path: Path, frames: dict[str, dict], fps: float | None = None) -> Path:
    """A contract sequence of hand-made frames (npz per frame, meta.yaml with a camera focal)."""
    path.mkdir(parents=True, exist_ok=True)
    for name, data in frames.items():
        np.savez(path / f"{name}.npz", **data)
    meta = f"image_size: [{SIZE[0]}, {SIZE[1]}]\nfocal_length: {FOCAL}\nfocal_kind: camera\n"
    (path / "meta.yaml").write_text(meta + (f"fps: {fps}\n" if fps else ""))
    return path


def frame(joints, ids=None, verts=None) -> dict:
    """One frame's arrays: joints (P, J, 3), optional person_ids and vertices."""
    out = {"joints": np.asarray(joints, dtype=np.float64)}
    if ids is not None:
        out["person_ids"] = np.asarray(ids)
    if verts is not None:
        out["vertices"] = np.asarray(verts, dtype=np.float64)
    return out


def body(at=(0.0, 0.0, 5.0)) -> np.ndarray:
    """The skeleton placed at ``at`` (camera frame, metres): (24, 3)."""
    return SKELETON + np.asarray(at)


def run(tmp_path: Path, gt: dict, pred: dict, fps: float | None = None, **options):
    return evaluate(open_sequence(write_seq(tmp_path / "pred", pred)), open_sequence(write_seq(tmp_path / "gt", gt, fps)),
                    EvalOptions(**options))


# ---- bug 1 and 2: --joints never changes the root nor turns mpjpe into w_mpjpe -----------------------


def test_joints_reordered_or_without_the_pelvis_keep_the_pelvis_root(tmp_path):
    """Pred = gt moved 1 m, with joint 3 off by 30 mm: MPJPE about SMPL joint 0 is 30/24 mm whatever
    --joints lists (today: 1000+ mm for a reordered list (bug 1), another root for '1-23' (bug 2))."""
    gt = body()
    pred = gt + [1.0, 0.0, 0.0]
    pred[3] += [0.0, 0.03, 0.0]
    kw = {"gt": {"000000": frame([gt], [1])}, "pred": {"000000": frame([pred], [1])}}
    assert run(tmp_path / "a", **kw).metrics["mpjpe"] == pytest.approx(30.0 / 24)
    reordered = (3, 0, 1, 2, *range(4, 24))
    assert run(tmp_path / "b", **kw, joints=reordered).metrics["mpjpe"] == pytest.approx(30.0 / 24)
    without_pelvis = run(tmp_path / "c", **kw, joints=tuple(range(1, 24)))
    assert without_pelvis.metrics["mpjpe"] == pytest.approx(30.0 / 23)  # joint 3 of 23, root still joint 0
    assert without_pelvis.metrics["root_err"] != without_pelvis.metrics["root_err"]  # no camera: NaN


def test_cli_joints_subset_reports_the_pelvis_relative_mpjpe(tmp_path, runner):
    gt = body()
    pred = gt + [1.0, 0.0, 0.0]
    pred[3] += [0.0, 0.03, 0.0]
    write_seq(tmp_path / "gt", {"000000": frame([gt], [1])})
    write_seq(tmp_path / "pred", {"000000": frame([pred], [1])})
    for spec in ("3,0,1,2,4-23", "0-23", "left_hip,pelvis,right_hip,3-23"):
        res = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", tmp_path / "out", "--force",
                     "--joints", spec, "--json")
        assert res.exit_code == 0, res.output
        assert json.loads(res.stdout)["predictions"][0]["metrics"]["mpjpe"] == pytest.approx(30.0 / 24), spec


# ---- bug 3: usage errors exit 2, never 1 ---------------------------------------------------------------


@pytest.mark.parametrize("args, message", [
    (["--joints", "0-30", "--match", "hungarian"], "--joints asks for joint 30 but the frame has 24 joints"),
    (["--joints", "0-30", "--match", "agora"], "--joints asks for joint 30 but the frame has 24 joints"),
    (["--joints", "0-30"], "--joints asks for joint 30"),
    (["--joints", "5-2"], "range '5-2' must go up"),
    (["--fail-if", "nosuch:w_mpjpe>300"], "no prediction named 'nosuch'"),
    (["--fail-if", "W_MPJPE>300"], "unknown metric 'W_MPJPE'; names are lower case: 'w_mpjpe'"),
    (["--protocol", "nosuch"], "must be one of paper, spec, agora, bedlam, wham"),
    (["--protocol", "agora", "--match", "hungarian"], "--protocol agora matches people its own way"),
    (["--protocol", "wham", "--joints", "0-5"], "--joints applies to --protocol paper"),
    (["--protocol", "agora", "--fail-if", "pve>100"], "--protocol agora does not report pve"),
])
def test_usage_errors_exit_2_with_one_line(tmp_path, runner, args, message):
    write_seq(tmp_path / "gt", {"000000": frame([body()], [1])})
    write_seq(tmp_path / "pred", {"000000": frame([body()], [1])})
    res = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", tmp_path / "out", *args)
    assert res.exit_code == 2, res.output
    assert message in res.stderr
    assert "Traceback" not in res.output and len(res.stderr.strip().splitlines()) == 1


def test_frame_names_matching_none_of_the_ground_truth_exit_2(tmp_path, runner):
    write_seq(tmp_path / "gt", {"000000": frame([body()], [1]), "000001": frame([body()], [1])})
    write_seq(tmp_path / "pred", {"frame_0000": frame([body()], [1])})
    res = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", tmp_path / "out")
    assert res.exit_code == 2
    assert "none of its 1 frame names (e.g. 'frame_0000') is among the ground truth's 2" in res.stderr
    with pytest.raises(InputError, match="frames are paired by name"):
        evaluate(open_sequence(tmp_path / "pred"), open_sequence(tmp_path / "gt"))


# ---- pelvis rule: SMPL joint 0 (paper, spec) vs the hips' midpoint (agora, bedlam, wham) --------------


def test_hip_midpoint_root_against_joint_0(tmp_path):
    """Only joint 0 moves, by 33.3 mm: about joint 0 every other joint is off (23/24 x 33.3), about the
    hips only joint 0 is (33.3/24 = 1.3875, 1.4 rounded as AGORA does); the same vertices give PVE
    33.3 mm about joint 0 and 0 about the hips."""
    gt = body()
    pred = gt.copy()
    pred[0] += [0.0, 0.0, 0.0333]
    verts = gt[None, 3:13] + np.zeros((1, 10, 3))
    kw = {"gt": {"000000": frame([gt], [1], verts)}, "pred": {"000000": frame([pred], [1], verts)}}
    paper = run(tmp_path / "paper", **kw).metrics
    assert paper["mpjpe"] == pytest.approx(23 / 24 * 33.3) and paper["pve"] == pytest.approx(33.3, rel=1e-6)
    for name in ("bedlam", "wham"):
        got = run(tmp_path / name, **kw, protocol=name).metrics
        assert got["mpjpe"] == pytest.approx(33.3 / 24), name
        assert got["pve"] == pytest.approx(0.0, abs=1e-4), name
    assert run(tmp_path / "agora", **kw, protocol="agora").metrics["mpjpe"] == 1.4
    assert run(tmp_path / "spec", **kw, protocol="spec").metrics["mpjpe"] == pytest.approx(23 / 24 * 33.3)


def test_protocols_take_the_first_24_joints(tmp_path):
    """A 25th joint off by 1 m counts under paper (all joints), not under the others (24 SMPL joints)."""
    gt = np.vstack([body(), [[0.0, 0.0, 5.0]]])
    pred = gt.copy()
    pred[24] += [1.0, 0.0, 0.0]
    kw = {"gt": {"000000": frame([gt], [1])}, "pred": {"000000": frame([pred], [1])}}
    assert run(tmp_path / "paper", **kw).metrics["mpjpe"] == pytest.approx(1000.0 / 25)
    assert run(tmp_path / "bedlam", **kw, protocol="bedlam").metrics["mpjpe"] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(InputError, match="scores the first 24 joints .* but the frame has 4"):
        run(tmp_path / "short", gt={"000000": frame([SKELETON[:4] + 5.0], [1])},
            pred={"000000": frame([SKELETON[:4] + 5.0], [1])}, protocol="wham")


# ---- SPEC: gravity frames of each side's camera, pelvis joint 0 -------------------------------------


def test_spec_w_mpjpe_is_pelvis_aligned_in_each_gravity_frame(tmp_path):
    """The same camera-frame body seen by cameras pitched 0.2 and 0.1 rad: SPEC's W-MPJPE is the error
    of rotating the pelvis-relative joints by the pitch difference (reference: each side rotated by its
    own camera, joint 0 subtracted, mean distance), its MPJPE (camera frame) is 0."""
    gt = body((0.3, 0.5, 6.0))
    frames = {"000000": frame([gt], [1])}
    cams = {"gt": Camera(SIZE, FOCAL, None, 0.2, 0.0, 3.0), "pred": Camera(SIZE, FOCAL, None, 0.1, 0.0, 3.0)}
    for side, cam in cams.items():
        write_seq(tmp_path / side, frames)
        write_camera_yaml(tmp_path / side / "camera.yaml", cam)
    got = evaluate(open_sequence(tmp_path / "pred"), open_sequence(tmp_path / "gt"), EvalOptions(protocol="spec"))
    world = {side: (gt - gt[0]) @ cam.R_cam_from_world for side, cam in cams.items()}  # x_world = R^T x_cam, as rows
    expected = 1000.0 * np.linalg.norm(world["pred"] - world["gt"], axis=1).mean()
    # by hand: a 0.1 rad rotation about x moves a point at distance r from the x axis by 2 r sin(0.05)
    by_hand = 1000.0 * 2 * np.sin(0.05) * np.hypot(SKELETON[:, 1], SKELETON[:, 2]).mean()
    assert expected == pytest.approx(by_hand)
    assert got.metrics["w_mpjpe"] == pytest.approx(by_hand)
    assert got.metrics["mpjpe"] == pytest.approx(0.0, abs=1e-9)
    assert set(got.metrics) == {"mpjpe", "pa_mpjpe", "w_mpjpe"}
    assert any("H36M joint regressor" in note for note in got.notes)


# ---- AGORA: matching, rounding, F1, predictions on images without ground truth ------------------------


def test_agora_rounds_and_normalises_like_its_code(tmp_path):
    """1 true person matched (joint 5 off by 29.7 mm: MPJPE 1.2375 mm), 2 far false positives, and a
    prediction-only frame AGORA never sees: precision 1/3 -> 0.33, recall 1, F1 0.5, MPJPE 1.2,
    NMJE round(1.2 / 0.5, 1) = 2.4 (paper: 1.2375 mm, 3 FPs, F1 1 / 2.5 = 0.4, NMJE 3.09375)."""
    gt = body((0.0, 0.0, 5.0))
    pred = gt.copy()
    pred[5] += [0.0297, 0.0, 0.0]
    fps_far = [body((-3.0, 0.0, 8.0)), body((3.0, 0.0, 8.0))]
    kw = {"gt": {"000000": frame([gt], [1])},
          "pred": {"000000": frame([pred, *fps_far]), "000001": frame([body()])}}
    agora = run(tmp_path / "agora", **kw, protocol="agora")
    assert {k: agora.metrics[k] for k in ("mpjpe", "precision", "recall", "f1", "nmje")} == {
        "mpjpe": 1.2, "precision": 0.33, "recall": 1.0, "f1": 0.5, "nmje": 2.4}
    assert agora.false_positives == 2 and agora.frames_pred_only == 1
    assert any("ignored, as AGORA does" in note for note in agora.notes)
    paper = run(tmp_path / "paper", **kw, match="hungarian", threshold_px=50.0)
    assert paper.false_positives == 3 and paper.metrics["f1"] == pytest.approx(0.4)
    assert paper.metrics["mpjpe"] == pytest.approx(29.7 / 24) and paper.metrics["nmje"] == pytest.approx(3.09375)


def test_agora_prf1_and_rounding_rules():
    assert agora_prf1(0, 0, 5) == {"precision": 0.0, "recall": 0.0, "f1": 0.0}  # no ground truth: all 0
    assert agora_prf1(2, 1, 0) == {"precision": 1.0, "recall": 0.67, "f1": 0.8}
    assert agora_round(0.35, 1) == 0.4  # numpy's rule on a pandas mean (Python's round(0.35, 1) is 0.3)
    assert agora_round(1.2375, 1) == 1.2


# ---- temporal metrics: hand-made tracks ---------------------------------------------------------------


def _track_frames(n: int, move, ids=(1,), verts=None) -> dict[str, dict]:
    """n frames of one body per id; ``move(t)`` -> (24, 3) displacement of frame t."""
    return {f"{t:06d}": frame([body() + move(t) for _ in ids], list(ids),
                              None if verts is None else [verts(t) for _ in ids]) for t in range(n)}


def test_paper_accel_and_jitter_in_frame_units(tmp_path):
    """Pred moves x = 0.001 t^3 m (all joints): second difference 6 t mm, third 6 mm, constant; gt still.
    Accel per window |6(t+1) mm| averaged over t = 0..3 -> 15 mm/frame^2; jitter 6 mm/frame^3."""
    gt = _track_frames(6, lambda t: 0.0)
    pred = _track_frames(6, lambda t: np.array([0.001 * t**3, 0.0, 0.0]))
    got = run(tmp_path, gt, pred).metrics
    assert got["accel_err"] == pytest.approx(np.mean([6.0 * (t + 1) for t in range(4)]))
    assert got["jitter"] == pytest.approx(6.0)


def test_wham_accel_is_hip_relative_and_in_metres_per_second_squared(tmp_path):
    """Joint 10 alone accelerates 2 mm/frame^2 (x = 0.001 t^2): paper (unaligned) 2/24 mm/frame^2, GVHMR
    (hips-relative, x fps^2 = 30^2) 0.002/24 * 900 m/s^2; the whole body accelerating: paper 2, GVHMR 0."""
    def one_joint(t):
        d = np.zeros((24, 3))
        d[10, 0] = 0.001 * t**2
        return d
    kw = {"gt": _track_frames(5, lambda t: 0.0), "pred": _track_frames(5, one_joint)}
    assert run(tmp_path / "p", **kw).metrics["accel_err"] == pytest.approx(2.0 / 24)
    assert run(tmp_path / "w", **kw, fps=30, protocol="wham").metrics["accel_err"] == pytest.approx(0.002 / 24 * 900)
    whole = {"gt": kw["gt"], "pred": _track_frames(5, lambda t: np.array([0.001 * t**2, 0.0, 0.0]))}
    assert run(tmp_path / "p2", **whole).metrics["accel_err"] == pytest.approx(2.0)
    assert run(tmp_path / "w2", **whole, fps=30, protocol="wham").metrics["accel_err"] == pytest.approx(0.0, abs=1e-9)


def test_paper_foot_sliding_per_track_then_averaged(tmp_path):
    """Feet (SMPL joints 7, 8, 10, 11) of the true bodies stand still. Track 1 (3 frames): its predicted
    left foot (joint 10) slides 5 mm per frame: 8 contacts, mean 1.25 mm/frame; track 2 (2 frames) still:
    4 contacts, 0. Per track then averaged: 0.625 (pooled would be 10/12)."""
    def slide(t):
        d = np.zeros((24, 3))
        d[10, 0] = 0.005 * t
        return d
    gt = {f"{t:06d}": frame([body(), body((1.0, 0.0, 6.0))] if t < 2 else [body()], [1, 2] if t < 2 else [1])
          for t in range(3)}
    pred = {f"{t:06d}": frame([body() + slide(t), body((1.0, 0.0, 6.0))] if t < 2 else [body() + slide(t)],
                              [1, 2] if t < 2 else [1]) for t in range(3)}
    assert run(tmp_path, gt, pred).metrics["foot_sliding"] == pytest.approx(0.625)


def test_wham_world_metrics_hand_made(tmp_path):
    """One track, 4 frames, at 25 fps (meta.yaml), 6,890-vertex meshes:

    - pred = gt for frames 0, 1, then 50 mm off in x: the similarity on the first two frames is the
      identity, W-MPJPE = (0 + 0 + 50 + 50) / 4 = 25 mm;
    - WA-MPJPE: one similarity over all 4 frames (straightforward Umeyama reference below);
    - RTE: the true root walks 0.1 m per frame (path 0.3 m); the predicted root is the same path
      shifted: rigid fit (no scale) -> errors per frame from the reference below, / 0.3 x 100 %;
    - jitter: the prediction's third difference is -0.1 m in x for the one window -> 0.1 x 25^3 / 10;
    - foot sliding: GVHMR's foot vertices still in gt, predicted ones still too: 0 mm.
    """
    walk = lambda t: np.array([0.1 * t, 0.0, 0.0])
    off = lambda t: walk(t) + (np.array([0.05, 0.0, 0.0]) if t >= 2 else 0.0)
    verts = lambda t: np.zeros((6890, 3)) + [0.0, 1.0, 5.0]
    gt = _track_frames(4, walk, verts=verts)
    pred = _track_frames(4, off, verts=verts)
    got = run(tmp_path, gt, pred, fps=25, protocol="wham")
    g = np.stack([body() + walk(t) for t in range(4)])
    p = np.stack([body() + off(t) for t in range(4)])
    assert got.metrics["w_mpjpe"] == pytest.approx(25.0)
    wa = _umeyama_errors(p, g, p.reshape(-1, 3), g.reshape(-1, 3)).mean() * 1000  # one fit over all 96 points
    assert got.metrics["wa_mpjpe"] == pytest.approx(wa)
    # reference RTE: rigid fit of the root path
    pr, gr = p[:, 0], g[:, 0]
    u, _, vt = np.linalg.svd((gr - gr.mean(0)).T @ (pr - pr.mean(0)))
    rot = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    fitted = (pr - pr.mean(0)) @ rot.T + gr.mean(0)
    assert got.metrics["rte"] == pytest.approx(np.linalg.norm(gr - fitted, axis=1).mean() / 0.3 * 100)
    assert got.metrics["jitter"] == pytest.approx(0.1 * 25**3 / 10)  # x: 0.35 - 3 (0.25) + 3 (0.1) - 0 = -0.1 m
    assert got.metrics["foot_sliding"] == pytest.approx(0.0)
    assert got.units["jitter"] == "10 m/s^3" and got.units["rte"] == "%" and got.units["accel_err"] == "m/s^2"


def _umeyama_errors(pred, gt, src, dst):
    """Reference (textbook Umeyama, as GVHMR's align_pcl): fit dst ~ s R src + t, apply to pred (T, J, 3),
    mean joint error per frame against gt, metres."""
    sc, dc = src - src.mean(0), dst - dst.mean(0)
    u, sing, vt = np.linalg.svd(dc.T @ sc / len(src))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt))])
    rot = u @ d @ vt
    scale = np.trace(np.diag(sing) @ d) / ((sc**2).sum() / len(src))
    t = dst.mean(0) - scale * rot @ src.mean(0)
    return np.linalg.norm(scale * pred @ rot.T + t - gt, axis=-1).mean(-1)


def test_wham_chunks_of_100_frames():
    """101 frames; the prediction is 100 mm off from frame 1 on. Chunk 1 (frames 0-99) is moved by the
    similarity fitted on frames 0 and 1 (a compromise: reference below); chunk 2 is frame 100 alone,
    fitted on itself: error 0. One fit over all 101 frames would leave frame 100 as far off as frame 99."""
    g = np.stack([body() for _ in range(101)])
    p = g.copy()
    p[1:] += [0.1, 0.0, 0.0]
    per_frame = first_frames_aligned_errors(p, g)
    first = _umeyama_errors(p[:100], g[:100], p[:2].reshape(-1, 3), g[:2].reshape(-1, 3))
    assert per_frame[:100] == pytest.approx(first, rel=1e-9)
    assert first[99] > 0.04 and per_frame[100] == pytest.approx(0.0, abs=1e-12)
    assert chunk_aligned_errors(p, g)[:100] == pytest.approx(
        _umeyama_errors(p[:100], g[:100], p[:100].reshape(-1, 3), g[:100].reshape(-1, 3)), rel=1e-9)
    assert chunk_aligned_errors(p, g)[100] == pytest.approx(0.0, abs=1e-12)


def test_no_person_ids_no_tracks(tmp_path):
    got = run(tmp_path, {"000000": frame([body()]), "000001": frame([body()])},
              {"000000": frame([body()]), "000001": frame([body()])}, protocol="wham")
    assert np.isnan(got.metrics["w_mpjpe"]) and np.isnan(got.metrics["jitter"])
    assert any("no tracks (no matched pair whose ground truth has person_ids" in note for note in got.notes)


def test_tracks_skip_unmatched_frames(tmp_path):
    """A track is its person's matched frames in order: pred misses frame 1, so frames 0, 2, 3 form the
    track (x = 0, 0.004, 0.009 m -> one accel window of 1 mm/frame^2, gt still)."""
    xs = {0: 0.0, 2: 0.004, 3: 0.009}
    gt = _track_frames(4, lambda t: 0.0)
    pred = {f"{t:06d}": frame([body() + [x, 0.0, 0.0]], [1]) for t, x in xs.items()}
    pred["000001"] = frame([body((3.0, 0.0, 9.0))], [7])  # someone else
    assert run(tmp_path, gt, pred).metrics["accel_err"] == pytest.approx(1.0)


# ---- streaming, merging and the pure functions ---------------------------------------------------------


def test_track_series_streams_and_merges_exactly():
    """Fed frame by frame with small flushes, or in five frame ranges merged in order, the sums and counts
    equal the direct functions over the whole track (accel, jitter, foot sliding; with hip-relative accel)."""
    rng = np.random.default_rng(5)
    n = 23
    g = np.cumsum(rng.normal(scale=0.01, size=(n, 24, 3)), axis=0) + [0.0, 0.0, 5.0]
    p = g + rng.normal(scale=0.01, size=g.shape)
    items = {"pred": p, "gt": g, "pred_feet": p[:, :4], "gt_feet": g[:, :4]}
    for hips in (False, True):
        rel = (lambda j: j - 0.5 * (j[:, 1:2] + j[:, 2:3])) if hips else (lambda j: j)
        direct = {"accel": accel_errors(rel(p), rel(g)), "jitter": jitter(p),
                  "foot_sliding": foot_sliding(p[:, :4], g[:, :4], 0.01)}
        assert direct["foot_sliding"].size > 0
        streamed = TrackSeries(("accel", "jitter", "foot_sliding"), 0.01, True, hips)
        streamed.FLUSH_PAIRS = 5
        for t in range(n):
            streamed.add(np.array([7]), {k: v[t:t + 1] for k, v in items.items()})
        parts = []
        for a, b in [(0, 1), (1, 3), (3, 4), (4, 11), (11, 23)]:
            part = TrackSeries(("accel", "jitter", "foot_sliding"), 0.01, True, hips)
            for t in range(a, b):
                part.add(np.array([7]), {k: v[t:t + 1] for k, v in items.items()})
            parts.append(part)
        merged = parts[0]
        for part in parts[1:]:
            merged = merged.merge(part)
        for metric, values in direct.items():
            for series in (streamed, merged):
                total, count = series.per_track(metric)[7]
                assert count == values.size and total == pytest.approx(values.sum(), rel=1e-12)
        assert np.array_equal(merged.frames_of(7)["pred"], p)


def test_merge_results_equals_one_evaluation(tmp_path):
    rng = np.random.default_rng(3)
    gt = {f"{t:06d}": frame([body((0.01 * t, 0.0, 5.0)), body((1.0, 0.0, 7.0 - 0.01 * t))], [1, 2]) for t in range(12)}
    pred = {k: frame(v["joints"] + rng.normal(scale=0.01, size=v["joints"].shape), [1, 2]) for k, v in gt.items()}
    ps, gs = open_sequence(write_seq(tmp_path / "pred", pred)), open_sequence(write_seq(tmp_path / "gt", gt))
    for name in ("paper", "wham"):
        whole = evaluate(ps, gs, EvalOptions(protocol=name))
        merged = merge_results([evaluate(ps, gs, EvalOptions(protocol=name), frames=(a, a + 5)) for a in (0, 5, 10)])
        for key, value in whole.metrics.items():
            assert merged.metrics[key] == pytest.approx(value, rel=1e-12, nan_ok=True), (name, key)


def test_pure_temporal_functions_by_hand():
    still = np.zeros((5, 2, 3))
    cubic = still + (0.001 * np.arange(5) ** 3)[:, None, None] * [1.0, 0.0, 0.0]
    assert accel_errors(cubic, still) == pytest.approx([0.006, 0.012, 0.018])
    assert jitter(cubic) == pytest.approx([0.006, 0.006])
    feet = still.copy()
    feet[3:, 0, 0] = 0.02  # the true foot 0 jumps 2 cm once: no contact there
    assert foot_sliding(cubic, feet, 0.01).size == 7
    path = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]])
    assert rte(2.0 * path, path) == pytest.approx([0.5, 0.0, 0.5])  # double-length path: +-0.1 m over 0.2 m
    assert np.isinf(rte(path, np.zeros((3, 3)))).all()  # a true root that never moves
    assert accel_errors(still[:2], still[:2]).size == 0 and jitter(still[:3]).size == 0


# ---- reports name the protocol beside every number -----------------------------------------------------


def test_reports_name_the_protocol(tmp_path, runner):
    gt = _track_frames(5, lambda t: np.array([0.01 * t, 0.0, 0.0]))
    write_seq(tmp_path / "gt", gt, fps=30)
    write_seq(tmp_path / "pred", _track_frames(5, lambda t: np.array([0.012 * t, 0.0, 0.0])))
    out = tmp_path / "out"
    res = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", out, "--protocol", "wham",
                 "--per-person", tmp_path / "pp.csv")
    assert res.exit_code == 0, res.output
    table = " ".join(res.output.split())  # the table and the notes as the terminal shows them; rich may wrap cells
    assert "rotavat eval, protocol wham" in table and "w_mpjpe (wham, mm)" in table
    assert "foot_sliding: skipped" in table
    report = json.loads((out / "metrics.json").read_text())
    assert report["protocol"] == "wham" and report["options"]["protocol"] == "wham"
    pred = report["predictions"][0]
    assert pred["protocol"] == "wham" and pred["units"]["rte"] == "%"
    assert set(pred["metrics"]) == {"mpjpe", "pa_mpjpe", "pve", "w_mpjpe", "wa_mpjpe", "rte", "jitter", "accel_err",
                                    "foot_sliding"}
    md = (out / "metrics.md").read_text()
    assert "Protocol `wham`: zju3dv/GVHMR@cb702cd" in md and " w_mpjpe (wham, mm) |" in md
    assert "jitter (wham, 10 m/s^3)" in md and "foot_sliding: skipped" in md
    header, row = (tmp_path / "pp.csv").read_text().splitlines()[:2]
    assert header.startswith("pred,frame,pred_index,gt_index,person_id,protocol,mpjpe")
    assert row.split(",")[5] == "wham"


def test_per_person_csv_of_an_older_version_is_replaced_without_force(tmp_path, runner):
    """The CSV gained a 'protocol' column; a file an older rotavat wrote (no such column) is still recognised."""
    write_seq(tmp_path / "gt", {"000000": frame([body()], [1])})
    write_seq(tmp_path / "pred", {"000000": frame([body((0.0, 0.0, 5.1))], [1])})
    old = tmp_path / "pp.csv"
    old.write_text("pred,frame,pred_index,gt_index,person_id,mpjpe,pa_mpjpe\nx,000000,0,0,1,1.0,1.0\n")
    res = invoke(runner, "eval", tmp_path / "pred", "--gt", tmp_path / "gt", "--out", tmp_path / "out",
                 "--per-person", old)
    assert res.exit_code == 0, res.output
    header, row = old.read_text().splitlines()
    assert header.split(",")[:7] == ["pred", "frame", "pred_index", "gt_index", "person_id", "protocol", "mpjpe"]
    assert row.split(",")[5] == "paper" and float(row.split(",")[6]) == pytest.approx(0.0, abs=1e-9)


def test_wham_rte_leaves_out_a_standing_track(tmp_path):
    """Track 1 walks 0.1 m per frame and is predicted exactly (RTE 0); track 2 stands still: no RTE (GVHMR
    would divide by a path length of 0), said in a note; W-MPJPE still pools both tracks."""
    gt = {f"{t:06d}": frame([body((0.1 * t, 0.0, 5.0)), body((1.0, 0.0, 7.0))], [1, 2]) for t in range(3)}
    pred = {k: frame(v["joints"] + [[[0.0, 0.0, 0.0]], [[0.0, 0.02, 0.0]]], [1, 2]) for k, v in gt.items()}
    got = run(tmp_path, gt, pred, fps=30, protocol="wham")
    assert got.metrics["rte"] == pytest.approx(0.0, abs=1e-9)
    assert any(note.startswith("rte: 1 track(s) left out") for note in got.notes)
    assert got.metrics["w_mpjpe"] == pytest.approx(0.0, abs=1e-9)  # a constant offset is fitted away


def test_a_newly_registered_person_metric_is_reported_under_the_paper_protocol(tmp_path, monkeypatch):
    """CONTRIBUTING's recipe: one registry entry is enough; the paper reports every registered metric."""
    import rotavat_cli.metrics.evaluate as E
    import rotavat_cli.metrics.person_metrics as PM
    import rotavat_cli.metrics.protocols as P

    def toy(pairs, pred_cam, gt_cam, engine):
        return {"toy_mm": np.full(len(pairs.gt_joints), 7.0)}

    families = (*PM.PERSON_METRIC_FAMILIES, PM.PersonMetric(("toy_mm",), toy))
    names = tuple(n for f in families for n in f.names)
    # An entry added to the registry's source reaches every module that imports it; patched, each copy.
    monkeypatch.setattr(E, "PERSON_METRIC_FAMILIES", families)
    for module in (E, P):
        monkeypatch.setattr(module, "PERSON_METRICS", names)
    result = run(tmp_path, {"000000": frame(body()[None])}, {"000000": frame(body((0.0, 0.0, 5.1))[None])})
    assert result.metrics["toy_mm"] == 7.0 and result.units["toy_mm"] == "mm"


def test_benchmark_protocols_refuse_joints_in_another_order(tmp_path):
    """An import's own layout (PHALP's OpenPose order) is not SMPL's: scoring its 'first 24 joints' would be wrong."""
    gt = {"000000": frame(body()[None])}
    pred_dir = write_seq(tmp_path / "pred", {"000000": frame(body((0.0, 0.0, 5.1))[None])})
    meta = (pred_dir / "meta.yaml").read_text()
    (pred_dir / "meta.yaml").write_text(meta + "import: {joints_layout: phalp44 (OpenPose-25 + 19 extra)}\n")
    gt_seq = open_sequence(write_seq(tmp_path / "gt", gt))
    with pytest.raises(InputError, match="scores SMPL's joints by index, but its joints are in the layout phalp44"):
        evaluate(open_sequence(pred_dir), gt_seq, EvalOptions(protocol="bedlam"))
    assert evaluate(open_sequence(pred_dir), gt_seq, EvalOptions(protocol="paper")).matched == 1  # paper: joint 0 only
    (pred_dir / "meta.yaml").write_text(meta + "import: {joints_layout: smpl24}\n")
    assert evaluate(open_sequence(pred_dir), gt_seq, EvalOptions(protocol="bedlam")).matched == 1
