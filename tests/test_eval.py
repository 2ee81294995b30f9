"""Sequence-level evaluation: hand-computed metrics, matching, unpaired frames, gates, the paper's point."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.errors import InputError
from rotavat_cli.metrics.evaluate import EvalOptions, evaluate, parse_joints
from rotavat_cli.metrics.report import parse_gate
from rotavat_cli.sequence import open_sequence, write_camera_yaml

JOINTS = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [0.0, -0.5, 0.0], [0.0, 0.0, 0.3]])


def write_seq(path: Path, frames: dict[str, dict], focal: float = 500.0) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    for name, data in frames.items():
        np.savez(path / f"{name}.npz", **data)
    (path / "meta.yaml").write_text(f"image_size: [640, 480]\nfocal_length: {focal}\n")
    return path


def people(offsets, ids=None, joints=JOINTS):
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
    out = {"joints": joints[None] + offsets[:, None]}
    if ids is not None:
        out["person_ids"] = np.asarray(ids)
    return out


def test_translation_only_offset(tmp_path):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5]], [1])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[0.03, 0.04, 5]], [1])})
    r = evaluate(open_sequence(pred), open_sequence(gt))
    assert r.metrics["w_mpjpe"] == pytest.approx(50.0)
    assert r.metrics["mpjpe"] == pytest.approx(0.0, abs=1e-9)
    assert r.metrics["pa_mpjpe"] == pytest.approx(0.0, abs=1e-6)
    assert (r.matched, r.missed, r.false_positives) == (1, 0, 0)


def test_rotation_about_pelvis(tmp_path):
    c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5]], [1])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[0, 0, 5]], [1], joints=JOINTS @ Rz.T)})
    r = evaluate(open_sequence(pred), open_sequence(gt))
    # joint 1 (0.2 m) and 2 (0.5 m) each move by r*sqrt(2); joint 3 lies on the axis
    expected = 1000.0 * (0.2 * np.sqrt(2) + 0.5 * np.sqrt(2)) / 4
    assert r.metrics["mpjpe"] == pytest.approx(expected)
    assert r.metrics["w_mpjpe"] == pytest.approx(expected)
    assert r.metrics["pa_mpjpe"] == pytest.approx(0.0, abs=1e-6)


def test_scale_only_about_pelvis(tmp_path):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5]], [1])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[0, 0, 5]], [1], joints=JOINTS * 1.5)})
    r = evaluate(open_sequence(pred), open_sequence(gt))
    assert r.metrics["mpjpe"] == pytest.approx(1000.0 * 0.5 * (0.2 + 0.5 + 0.3) / 4)
    assert r.metrics["pa_mpjpe"] == pytest.approx(0.0, abs=1e-6)


def test_id_swap_misses_and_false_positives(tmp_path):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5], [1, 0, 5], [2, 0, 5]], [1, 2, 3]),
                                     "000001": people([[0, 0, 5]], [1])})
    # person 2 and 1 swapped in order, person 3 missed, person 9 a false positive; frame 000002 pred-only
    pred = write_seq(tmp_path / "pred", {"000000": people([[1, 0, 5], [0, 0, 5], [5, 0, 5]], [2, 1, 9]),
                                         "000001": {"joints": np.zeros((0, 4, 3)), "person_ids": np.zeros(0, int)},
                                         "000002": people([[0, 0, 5]], [1])})
    r = evaluate(open_sequence(pred), open_sequence(gt))
    assert (r.matched, r.missed, r.false_positives) == (2, 2, 2)
    assert r.frames == 2 and r.frames_pred_only == 1
    assert r.metrics["w_mpjpe"] == pytest.approx(0.0)
    assert r.metrics["precision"] == pytest.approx(0.5) and r.metrics["recall"] == pytest.approx(0.5)
    assert r.metrics["nmje"] == pytest.approx(r.metrics["mpjpe"] / 0.5)


def test_hungarian_without_ids_and_threshold(tmp_path):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5], [1, 0, 5]])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[1.01, 0, 5], [0.01, 0, 5], [3, 0, 5]])})
    r = evaluate(open_sequence(pred), open_sequence(gt), EvalOptions(match="hungarian", threshold_px=20.0))
    assert (r.matched, r.missed, r.false_positives) == (2, 0, 1)
    assert r.metrics["w_mpjpe"] == pytest.approx(10.0)
    assert r.per_person["pred_index"] == [1, 0]
    r2 = evaluate(open_sequence(pred), open_sequence(gt), EvalOptions(match="hungarian", threshold_px=0.5))
    assert r2.matched == 0 and r2.missed == 2


def test_joint_count_mismatch_needs_joints_option(tmp_path):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5]], [1])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[0, 0, 5]], [1], joints=np.vstack([JOINTS, JOINTS]))})
    with pytest.raises(InputError, match="--joints"):
        evaluate(open_sequence(pred), open_sequence(gt))
    r = evaluate(open_sequence(pred), open_sequence(gt), EvalOptions(joints=parse_joints("0-3")))
    assert r.metrics["w_mpjpe"] == pytest.approx(0.0)


def test_gates_and_exit_codes(tmp_path, runner):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5]], [1])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[0.03, 0.04, 5]], [1])})
    ok = invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / "o", "--fail-if", "w_mpjpe>60", "-q")
    assert ok.exit_code == 0
    bad = invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / "o", "--fail-if", "w_mpjpe>40", "-q")
    assert bad.exit_code == 1 and "w_mpjpe" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    typo = invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / "o", "--fail-if", "w_mpjpf>40")
    assert typo.exit_code == 2 and "unknown metric" in typo.stderr
    data = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert data["predictions"][0]["metrics"]["w_mpjpe"] == pytest.approx(50.0)


def test_gate_parsing():
    g = parse_gate("pred_aligned:f1 <= 0.9")
    assert (g.row, g.metric, g.op, g.value) == ("pred_aligned", "f1", "<=", 0.9)
    with pytest.raises(InputError):
        parse_gate("w_mpjpe > lots")


def test_pred_defaults_to_current_directory(tmp_path, runner, monkeypatch):
    gt = write_seq(tmp_path / "gt", {"000000": people([[0, 0, 5]], [1])})
    pred = write_seq(tmp_path / "pred", {"000000": people([[0, 0, 5.1]], [1])})
    monkeypatch.chdir(pred)
    before = sorted(p.name for p in pred.iterdir())
    inside = invoke(runner, "eval", "--gt", gt, "--out", ".")  # the reports would land inside the input: refused
    assert inside.exit_code == 2 and "inside the input" in inside.stderr
    result = invoke(runner, "eval", "--gt", gt, "--out", tmp_path / "ev", "--json")
    assert result.exit_code == 0
    assert json.loads(result.stdout)["predictions"][0]["metrics"]["w_mpjpe"] == pytest.approx(100.0)
    assert (tmp_path / "ev" / "metrics.md").exists() and sorted(p.name for p in pred.iterdir()) == before


def test_ground_aware_metrics_and_camera_errors(tmp_path):
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=3, frames=2, people=4))
    gt_cam = Camera((1280, 720), 1000.0, None, 0.3, 0.0, 5.0)
    r_self = evaluate(open_sequence(tmp_path / "s" / "gt"), open_sequence(tmp_path / "s" / "gt"))
    assert r_self.metrics["w_mpjpe"] == 0.0 and r_self.metrics["foot_height"] < 10.0
    assert r_self.metrics["stature_err"] == 0.0 and r_self.metrics["lean_deg"] < 5.0
    assert r_self.camera["cam_focal_pct"] == 0.0
    write_camera_yaml(tmp_path / "s" / "pred" / "camera.yaml", gt_cam)
    r = evaluate(open_sequence(tmp_path / "s" / "pred"), open_sequence(tmp_path / "s" / "gt"))
    assert np.isfinite(r.metrics["w_mpjpe_spec"]) and "cam_pitch_deg" in r.camera


def test_paper_point_on_synth(tmp_path, runner):
    """PA-MPJPE nearly unchanged, W-MPJPE far lower after RotAvat: the paper's argument in numbers."""
    s = tmp_path / "s"
    assert invoke(runner, "synth", s, "--seed", "21", "--frames", "4", "--people", "6", "-q").exit_code == 0
    assert invoke(runner, "align", "--in", s / "pred", "--camera", s / "gt" / "camera.yaml", "--out", s / "al", "-q").exit_code == 0
    result = invoke(runner, "eval", s / "pred", s / "al", "--gt", s / "gt", "--out", tmp_path, "--json")
    before, after = (p["metrics"] for p in json.loads(result.stdout)["predictions"])
    assert after["pa_mpjpe"] == pytest.approx(before["pa_mpjpe"], rel=0.02)
    assert after["w_mpjpe"] < 0.2 * before["w_mpjpe"]
    assert after["foot_height"] < 5.0 < before["foot_height"]
    md = (tmp_path / "metrics.md").read_text()
    assert "## Headline\n\n| metric | `pred` | `al` | change |" in md and "`" + str(s / "al") + "`" in md


def test_frame_ranges_merge_into_the_whole_result(tmp_path):
    """evaluate(frames=(a, b)) over consecutive ranges + merge_results == one evaluate call, exactly."""
    from rotavat_cli.metrics.evaluate import merge_results
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=5, frames=5, people=3))
    pred, gt = tmp_path / "s" / "pred", tmp_path / "s" / "gt"
    (pred / "000004.npz").unlink()  # a frame on the ground-truth side only: counted in its range
    whole = evaluate(open_sequence(pred), open_sequence(gt))
    parts = [evaluate(open_sequence(pred), open_sequence(gt), frames=(0, 2)), evaluate(open_sequence(pred), open_sequence(gt), frames=(2, 5))]
    assert [p.frames for p in parts] == [2, 2] and [p.frames_gt_only for p in parts] == [0, 1]
    merged = merge_results(parts)
    assert json.dumps(merged.as_dict(per_person=True)) == json.dumps(whole.as_dict(per_person=True))  # NaN-safe
    assert whole.matched == 12 and whole.missed == 3
    with pytest.raises(ValueError):
        merge_results([])


def test_engine_option_over_config_and_its_errors(tmp_path, runner, monkeypatch):
    """--engine numpy / numba score the same; a bad engine, or numba when missing, exits 2 in one line."""
    from rotavat_cli.metrics import compiled_kernels
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=9, frames=2, people=3))
    pred, gt = tmp_path / "s" / "pred", tmp_path / "s" / "gt"
    engines = ["numpy"] + (["numba"] if compiled_kernels() is not None else [])
    scores = {}
    for engine in engines:
        result = invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / engine, "--engine", engine, "--json")
        assert result.exit_code == 0, result.stderr
        scores[engine] = json.loads(result.stdout)["predictions"][0]["metrics"]
        assert json.loads((tmp_path / engine / "metrics.json").read_text())["options"]["engine"] == engine
    assert scores["numpy"]["pve"] > 1.0
    for key in ("w_pve", "pve", "pa_pve"):
        assert scores[engines[-1]][key] == pytest.approx(scores["numpy"][key], abs=1e-5)
    bad = invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / "bad", "--engine", "cuda")
    assert bad.exit_code == 2 and "--engine: must be one of" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad" / "metrics.json").exists()
    monkeypatch.setattr("rotavat_cli.metrics.fused.compiled_kernels", lambda: None)  # as if numba were missing
    missing = invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / "bad", "--engine", "numba")
    assert missing.exit_code == 2 and "rotavat[fast]" in missing.stderr
    with pytest.raises(ValueError, match="engine must be one of auto, numpy, numba, got 'gpu'"):
        EvalOptions(engine="gpu")  # the Python API refuses it where the options are made


def test_pairs_are_scored_in_batches_across_frames(tmp_path, monkeypatch):
    """Scoring frame by frame or many frames per call gives the same rows, in frame order, also when
    one frame lacks vertices (a different kind of arrays: scored in its own call)."""
    import importlib

    from rotavat_cli.synth import SynthOptions, write_synth_scene

    ev = importlib.import_module("rotavat_cli.metrics.evaluate")  # the package exports a function of that name
    write_synth_scene(tmp_path / "s", SynthOptions(seed=4, frames=5, people=3))
    pred, gt = tmp_path / "s" / "pred", tmp_path / "s" / "gt"
    frame = dict(np.load(pred / "000002.npz", allow_pickle=False))
    del frame["vertices"], frame["faces"]
    np.savez(pred / "000002.npz", **frame)
    calls = []
    real = ev._pair_metrics
    monkeypatch.setattr(ev, "_pair_metrics", lambda pairs, n, *a: calls.append(n) or real(pairs, n, *a))
    batched = evaluate(open_sequence(pred), open_sequence(gt))
    assert calls == [6, 3, 6]  # frames 0-1, frame 2 alone (no vertices), frames 3-4
    monkeypatch.setattr(ev, "SCORE_BATCH_PEOPLE", 1)
    calls.clear()
    per_frame = evaluate(open_sequence(pred), open_sequence(gt))
    assert calls == [3] * 5
    assert json.dumps(batched.as_dict(per_person=True)) == json.dumps(per_frame.as_dict(per_person=True))
    rows = batched.per_person
    assert rows["frame"] == [f"00000{i}" for i in range(5) for _ in range(3)]
    pve = np.array(rows["pve"])
    assert np.isnan(pve[6:9]).all() and np.isfinite(pve[:6]).all() and np.isfinite(pve[9:]).all()
    assert np.isfinite(rows["mpjpe"]).all()


def test_default_out_is_beside_the_first_prediction_even_from_inside_it(tmp_path, monkeypatch, runner):
    """Run from inside the prediction folder with no --out: metrics go to ../<pred>_eval, never into the input."""
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=5, frames=2, people=3))
    before = tree_hash(tmp_path / "s" / "pred")
    monkeypatch.chdir(tmp_path / "s" / "pred")
    result = invoke(runner, "eval", "--gt", "../gt", "-q")
    assert result.exit_code == 0, result.stderr
    assert (tmp_path / "s" / "pred_eval" / "metrics.json").exists() and tree_hash(tmp_path / "s" / "pred") == before
    monkeypatch.chdir(tmp_path / "s")
    assert invoke(runner, "eval", "pred", "--gt", "gt", "-q").exit_code == 0  # replaces its own output
    assert sorted(p.name for p in (tmp_path / "s" / "pred_eval").iterdir()) == ["metrics.json", "metrics.md"]


def test_a_note_every_row_shares_is_said_once(tmp_path, runner):
    """foot_sliding's "no value" note was printed once per row on every synthetic run: now once, naming the rows."""
    scene = Path(__file__).resolve().parents[1] / "sample_data" / "scene"
    result = invoke(runner, "eval", scene / "pred", scene / "gt", "--gt", scene / "gt", "--out", tmp_path / "ev")
    said = " ".join(result.stderr.split())
    assert result.exit_code == 0 and said.count("foot_sliding: no value") == 1
    assert "pred (paper), gt (paper): foot_sliding: no value" in said
