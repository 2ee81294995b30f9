"""`rotavat calibrate` and calibrate-then-align through the command line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from _cli import invoke
from conftest import tree_hash


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    out = tmp_path_factory.mktemp("calscene")
    write_synth_scene(out, SynthOptions(seed=5, frames=12, people=8, noise_px=2.0, outliers=0.1))
    return out


def pairs_seq(path: Path, feet, heads, size=(640, 480)) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    np.savez(path / "000000.npz", feet_2d=np.asarray(feet, float), heads_2d=np.asarray(heads, float))
    (path / "meta.yaml").write_text(f"image_size: [{size[0]}, {size[1]}]\n")
    return path


def test_calibrate_recovers_the_true_camera(scene, tmp_path, runner):
    before = tree_hash(scene / "pred")
    result = invoke(runner, "calibrate", scene / "pred", "--out", tmp_path / "cam.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    assert tree_hash(scene / "pred") == before
    est = json.loads(result.stdout)
    true = yaml.safe_load((scene / "gt" / "camera.yaml").read_text())
    # the prediction's focal is CLIFF's guess (the image diagonal), not the camera's: it is estimated
    assert est["fit"]["focal_policy"] == "estimated" and est["fit"]["mesh_focal_kind"] == "assumed"
    assert est["fit"]["mesh_focal_px"] == pytest.approx(np.hypot(1280, 720)) != pytest.approx(true["focal_px"], rel=0.5)
    assert "focal_px" not in est["fit"]["fixed"]
    # 8 people: each one's crown sits a few cm off the vertical through the mid-sole (real posture),
    # so the error is statistical; the reported std must cover it and stay small (with 8 people the
    # cluster jackknife, not the optimistic Gauss-Newton, sets the pitch std: ~1 deg, error ~1.5 deg)
    std = est["fit"]["std"]
    for key, limit in (("focal_px", 0.1 * true["focal_px"]), ("pitch_deg", 1.5), ("roll_deg", 1.8), ("height_m", 0.4)):
        assert std[key] < limit
        assert abs(est[key] - true[key]) < 3.0 * std[key], key
    assert est["fit"]["inliers"] < est["fit"]["pairs"]  # the 10% gross outliers were rejected
    written = yaml.safe_load((tmp_path / "cam.yaml").read_text())
    assert written["fit"]["pairs"] == 96 and written["fit"]["frames"] == 12


def test_a_sequence_whose_focal_is_the_cameras_keeps_it(scene, tmp_path, runner):
    result = invoke(runner, "calibrate", scene / "gt", "--out", tmp_path / "cam.yaml", "--json")
    est = json.loads(result.stdout)
    true = yaml.safe_load((scene / "gt" / "camera.yaml").read_text())
    assert est["fit"]["focal_policy"] == "declared" and est["focal_px"] == true["focal_px"]
    assert est["fit"]["fixed"]["focal_px"] == "declared" and est["fit"]["std"]["focal_px"] is None
    forced = json.loads(invoke(runner, "calibrate", scene / "gt", "--estimate-focal", "--out", tmp_path / "c2.yaml",
                               "--json").stdout)
    assert forced["fit"]["focal_policy"] == "estimated" and forced["focal_px"] != true["focal_px"]


def test_paper_grid_mode(scene, tmp_path, runner):
    result = invoke(runner, "calibrate", scene / "gt", "--method", "grid", "--out", tmp_path / "g.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    est = json.loads(result.stdout)
    assert est["fit"]["method"] == "grid" and est["roll_deg"] == 0.0
    true = yaml.safe_load((scene / "gt" / "camera.yaml").read_text())
    assert abs(est["height_m"] / true["height_m"] - 1.0) < 0.25  # one grid step is ~0.8 m


def test_align_without_camera_calibrates_first(scene, tmp_path, runner):
    result = invoke(runner, "align", "--in", scene / "pred", "--out", tmp_path / "al", "--json")
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["camera"] == "calibrated from the people"
    assert (tmp_path / "al" / "camera.yaml").exists()
    res = invoke(runner, "eval", scene / "pred", tmp_path / "al", "--gt", scene / "gt", "--out", tmp_path, "--json")
    before, after = (p["metrics"] for p in json.loads(res.stdout)["predictions"])
    assert after["w_mpjpe"] < 0.4 * before["w_mpjpe"]  # > 60% drop with the estimated camera


@pytest.mark.parametrize("feet,heads,size,message,flags", [
    ([[100, 400], [200, 420]], [[100, 300], [200, 310]], (640, 480), "need >= 3", ("--focal-prior", "none")),
    # a NaN row is a person whose keypoints lack the point (contract): the pair is dropped, leaving 2
    ([[100, 400], [200, np.nan], [300, 430]], [[100, 300], [200, 310], [300, 320]], (640, 480), "only 2 usable",
     ("--focal-prior", "none")),
    ([[100, 300], [200, 310], [300, 320], [400, 330]], [[100, 400], [200, 420], [300, 430], [400, 440]], (640, 480),
     "below|swapped", ()),
])
def test_calibrate_bad_pairs_exit_2(tmp_path, runner, feet, heads, size, message, flags):
    seq = pairs_seq(tmp_path / "s", feet, heads, size)
    result = invoke(runner, "calibrate", seq, "--out", tmp_path / "c.yaml", *flags)
    assert result.exit_code == 2, result.stderr
    import re

    assert re.search(message, result.stderr) and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "c.yaml").exists()


def test_calibrate_missing_image_size_exit_2(tmp_path, runner):
    seq = tmp_path / "s"
    seq.mkdir()
    np.savez(seq / "000000.npz", feet_2d=np.ones((4, 2)), heads_2d=np.zeros((4, 2)))
    result = invoke(runner, "calibrate", seq)
    assert result.exit_code == 2 and "image size" in result.stderr


def test_calibrate_meshes_without_focal_exit_2(tmp_path, runner):
    seq = tmp_path / "s"
    seq.mkdir()
    np.savez(seq / "000000.npz", vertices=np.random.default_rng(0).normal(size=(2, 50, 3)) + [0, 0, 5])
    (seq / "meta.yaml").write_text("image_size: [640, 480]\n")
    result = invoke(runner, "calibrate", seq)
    assert result.exit_code == 2 and "focal" in result.stderr


def test_per_frame_reports_spread(scene, tmp_path, runner):
    result = invoke(runner, "calibrate", scene / "gt", "--per-frame", "--out", tmp_path / "c.yaml", "--json")
    per_frame = json.loads(result.stdout)["per_frame"]
    assert per_frame["frames_fitted"] + per_frame["frames_skipped"] == 12
    assert set(per_frame["iqr"]) >= {"pitch_deg", "height_m"}
    fit = yaml.safe_load((tmp_path / "c.yaml").read_text())["fit"]  # the spread is kept with the camera
    assert fit["per_frame"]["median"]["pitch_deg"] == pytest.approx(per_frame["median"]["pitch_deg"])
    table = invoke(runner, "calibrate", scene / "gt", "--per-frame", "--out", tmp_path / "d.yaml")
    pitch_row = next(line for line in table.stdout.splitlines() if "pitch_deg" in line)
    median, iqr = per_frame["median"]["pitch_deg"], per_frame["iqr"]["pitch_deg"]
    assert f"{median:.3f} ({iqr:.3f}) °" in pitch_row and "alone: median (IQR)" in table.stdout


def test_config_file_sets_options(scene, tmp_path, runner):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("calibrate:\n  estimate_roll: false\n")
    result = invoke(runner, "calibrate", scene / "gt", "--config", cfg, "--out", tmp_path / "cam.yaml", "--json")
    assert json.loads(result.stdout)["roll_deg"] == 0.0


def box_seq(path: Path) -> tuple[Path, dict]:
    """A sequence of box-derived foot/head points (with track ids) and its true camera."""
    import math

    from _synthetic_pairs import synthetic_pairs

    from rotavat_cli.geometry.camera import Camera

    cam = Camera((1280, 720), 1800.0, None, math.radians(18.0), math.radians(1.0), 6.5)
    data = synthetic_pairs(np.random.default_rng(51), camera=cam, frames=40, people=15, points="boxes",
                           distortion=-0.04)
    path.mkdir(parents=True)
    for t in range(40):
        sel = data.frame_index == t
        np.savez(path / f"{t:06d}.npz", feet_2d=data.feet_px[sel], heads_2d=data.heads_px[sel],
                 person_ids=data.track_id[sel])
    (path / "meta.yaml").write_text("image_size: [1280, 720]\n")
    return path, {"focal_px": cam.focal_px, "height_m": cam.height_m}


def test_calibrate_box_points_with_distortion(tmp_path, runner):
    seq, true = box_seq(tmp_path / "boxes")
    result = invoke(runner, "calibrate", seq, "--points", "boxes", "--distortion", "--focal", true["focal_px"],
                    "--out", tmp_path / "cam.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    fit = json.loads(result.stdout)["fit"]
    assert fit["points"] == "boxes" and fit["box_depth_m"] == 0.25 and fit["residual"] == "vertical"
    assert fit["distortion"] < 0 and "distortion" in fit["std"]  # barrel
    assert abs(json.loads(result.stdout)["height_m"] / true["height_m"] - 1) < 0.05
    cfg = tmp_path / "c.yaml"
    cfg.write_text("calibrate:\n  points: boxes\n  box_depth_m: 0.0\n")
    result = invoke(runner, "calibrate", seq, "--config", cfg, "--focal", true["focal_px"],
                    "--out", tmp_path / "cam2.yaml", "--json")
    fit = json.loads(result.stdout)["fit"]
    assert fit["box_depth_m"] == 0.0 and "distortion" not in fit


def test_box_depth_flag_overrides_the_config_and_bad_values_exit_2(tmp_path, runner):
    seq, true = box_seq(tmp_path / "boxes")
    cfg = tmp_path / "c.yaml"
    cfg.write_text("calibrate:\n  points: boxes\n  box_depth_m: 0.0\n")
    result = invoke(runner, "calibrate", seq, "--config", cfg, "--box-depth", "0.15", "--focal", true["focal_px"],
                    "--out", tmp_path / "cam.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["fit"]["box_depth_m"] == 0.15
    result = invoke(runner, "calibrate", seq, "--points", "boxes", "--box-depth", "nan",
                    "--out", tmp_path / "bad.yaml")
    assert result.exit_code == 2 and "--box-depth" in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad.yaml").exists()


def test_calibrate_never_replaces_a_camera_no_fit_produced(tmp_path, runner):
    """The truth synth wrote (scene/gt: focal_kind camera) and a hand-written camera.yaml are never replaced,
    not even with --force; the one-line refusal names where the estimate goes, and that step runs."""
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=2, frames=3, people=6))
    gt, pred = tmp_path / "s" / "gt", tmp_path / "s" / "pred"
    truth = (gt / "camera.yaml").read_bytes()
    for args in ([gt], [gt, "--force"]):
        result = invoke(runner, "calibrate", *args)
        assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1
        assert "never replaces it" in result.stderr and (gt / "camera.yaml").read_bytes() == truth
    step = result.stderr.strip().rsplit("write the estimate beside it: ", 1)[1].split()
    ran = invoke(runner, *step[1:])
    assert step[:2] == ["rotavat", "calibrate"] and ran.exit_code == 0, (step, ran.stderr)
    assert (tmp_path / "s" / "gt_camera.yaml").is_file()
    hand = yaml.safe_dump({k: v for k, v in yaml.safe_load(truth).items() if k in ("image_size", "focal_px",
                                                                                 "pitch_deg", "height_m")})
    (pred / "camera.yaml").write_text(hand)
    refused = invoke(runner, "calibrate", pred, "--force")
    assert refused.exit_code == 2 and "no fit produced" in refused.stderr and (pred / "camera.yaml").read_text() == hand
    (pred / "camera.yaml").unlink()
    assert invoke(runner, "calibrate", pred, "-q").exit_code == 0  # its own estimate ...
    assert invoke(runner, "calibrate", pred, "-q").exit_code == 0  # ... is replaced by the next one
