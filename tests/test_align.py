"""Sequence-level align: the paper's effect in numbers, flags, forms, inputs untouched, CLI."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from conftest import invoke, tree_hash
from rotavat_cli.align import align_frame, align_sequence
from rotavat_cli.camera import Camera
from rotavat_cli.sequence import Frame, open_sequence, write_frame


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    out = tmp_path_factory.mktemp("scene")
    write_synth_scene(out, SynthOptions(seed=11, frames=6, people=8))
    return out


def w_mpjpe_mm(pred_dir: Path, gt_dir: Path) -> float:
    """Mean joint error with no alignment at all, over every person of every frame."""
    errs = [np.linalg.norm(p.data["joints"].astype(float) - g.data["joints"].astype(float), axis=-1).mean()
            for p, g in zip(open_sequence(pred_dir).frames(), open_sequence(gt_dir).frames())]
    return 1000.0 * float(np.mean(errs))


def test_true_camera_cuts_w_mpjpe_by_80_percent(scene, tmp_path, runner):
    before = tree_hash(scene / "pred")
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml",
                    "--out", tmp_path / "aligned", "-q")
    assert result.exit_code == 0, result.stderr
    assert tree_hash(scene / "pred") == before  # input untouched
    w0, w1 = w_mpjpe_mm(scene / "pred", scene / "gt"), w_mpjpe_mm(tmp_path / "aligned", scene / "gt")
    assert w1 < 0.2 * w0, (w0, w1)


def test_output_mirrors_input(scene, tmp_path):
    seq = open_sequence(scene / "pred")
    cam = open_sequence(scene / "gt").camera
    summary = align_sequence(seq, cam, tmp_path / "out")
    out = open_sequence(tmp_path / "out")
    assert out.frame_names == seq.frame_names and out.camera is not None
    assert out.meta == seq.meta
    f_in, f_out = seq.read_frame("000002"), out.read_frame("000002")
    assert set(f_in.data) == set(f_out.data)
    for key in f_in.data:
        assert f_out.data[key].dtype == f_in.data[key].dtype, key
        if key not in ("vertices", "joints"):
            np.testing.assert_array_equal(f_out.data[key], f_in.data[key])
    assert summary.aligned == summary.people == 48
    rows = list(csv.DictReader(open(tmp_path / "out" / "people.csv")))
    assert len(rows) == 48 and rows[0]["frame"] == "000000"
    assert {"x_world_m", "z_world_m", "stature_m", "depth_scale", "rotation_deg", "final_scale",
            "drift_mean_px", "drift_max_px", "flag"} <= set(rows[0])
    statures = np.array([float(r["stature_m"]) for r in rows])
    assert np.all((statures > 1.4) & (statures < 2.1))


def test_pixels_unchanged_and_feet_on_ground(scene):
    seq = open_sequence(scene / "pred")
    cam = open_sequence(scene / "gt").camera
    frame = seq.read_frame("000000")
    new, cols = align_frame(frame, cam)
    from rotavat_cli.landmarks import foot_head_points

    f0, h0 = foot_head_points(frame.data["vertices"])
    f1, h1 = foot_head_points(new.data["vertices"])
    assert np.all(np.abs(cam.height_above_ground(f1)) < 1e-4)  # float32 output
    np.testing.assert_allclose(cam.project(f1), cam.project(f0), atol=0.05)
    np.testing.assert_allclose(cam.project(h1), cam.project(h0), atol=0.05)
    assert np.all(cols["head_drift_px"] < 1e-6)


def test_people_above_horizon_are_flagged_not_dropped():
    cam = Camera((640, 480), 500, None, np.deg2rad(10), 0.0, 3.0)
    rng = np.random.default_rng(0)
    verts = rng.normal(0, 0.1, (2, 30, 3)) + np.array([0.0, 0.0, 8.0])
    verts[0, :, 1] += np.linspace(-3.0, -4.7, 30)  # a person floating far above the horizon line
    verts[1] = cam.backproject_px_to_ground(np.array([320.0, 400.0])) + verts[1] - verts[1].mean(0)
    verts[1, :, :] += np.linspace(0, 1, 30)[:, None] * 1.7 * cam.up_cam
    frame = Frame("000000", {"vertices": verts.astype(np.float32), "person_ids": np.array([4, 5])})
    new, cols = align_frame(frame, cam)
    assert list(cols["flag"]) == ["foot_above_horizon", ""]
    np.testing.assert_array_equal(new.data["vertices"][0], frame.data["vertices"][0])


def test_obj_sequence_round_trip(scene, tmp_path, runner):
    seq = open_sequence(scene / "pred")
    for frame in list(seq.frames())[:2]:
        write_frame(tmp_path / "objseq", Frame(frame.name, {k: frame.data[k] for k in ("vertices", "faces", "person_ids")}), "obj")
    (tmp_path / "objseq" / "meta.yaml").write_text(f"image_size: [1280, 720]\nfocal_length: {seq.intrinsics.focal_px}\n")
    result = invoke(runner, "align", "--in", tmp_path / "objseq", "--camera", scene / "gt" / "camera.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    out = open_sequence(tmp_path / "objseq_aligned")
    assert out.form == "obj" and len(out) == 2
    npz_aligned, _ = align_frame(seq.read_frame("000001"), open_sequence(scene / "gt").camera)
    np.testing.assert_allclose(out.read_frame("000001").data["vertices"], npz_aligned.data["vertices"], atol=1e-5)


def test_height_from_track_gives_one_stature_per_person(scene, tmp_path):
    cam = open_sequence(scene / "gt").camera
    align_sequence(open_sequence(scene / "pred"), cam, tmp_path / "t", height_from="track")
    rows = list(csv.DictReader(open(tmp_path / "t" / "people.csv")))
    by_id: dict[str, set] = {}
    for r in rows:
        by_id.setdefault(r["person_id"], set()).add(round(float(r["stature_m"]), 4))
    assert all(len(v) == 1 for v in by_id.values())


def test_align_refuses_to_write_into_its_input(scene, runner):
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml", "--out", scene / "pred")
    assert result.exit_code == 2 and "must differ" in result.stderr


def test_bad_option_value_exits_2(scene, tmp_path, runner):
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml",
                    "--out", tmp_path / "x", "--upright", "sideways")
    assert result.exit_code == 2 and "upright" in result.stderr


def test_worker_count_does_not_change_the_output(scene, tmp_path):
    cam = open_sequence(scene / "gt").camera
    seq = open_sequence(scene / "pred")
    align_sequence(seq, cam, tmp_path / "one", workers=1)
    align_sequence(seq, cam, tmp_path / "two", workers=2)
    for name in seq.frame_names:
        assert (tmp_path / "one" / f"{name}.npz").read_bytes() == (tmp_path / "two" / f"{name}.npz").read_bytes()
    assert (tmp_path / "one" / "people.csv").read_text() == (tmp_path / "two" / "people.csv").read_text()


def test_error_in_a_worker_is_one_line(scene, tmp_path, runner):
    bad = tmp_path / "bad"
    bad.mkdir()
    for name in ("000000", "000001"):
        (bad / f"{name}.npz").write_bytes((scene / "pred" / f"{name}.npz").read_bytes())
    np.savez(bad / "000002.npz", joints=np.zeros((1, 24, 3)) + [0, 0, 5])  # people without meshes
    (bad / "meta.yaml").write_text((scene / "pred" / "meta.yaml").read_text())
    result = invoke(runner, "align", "--in", bad, "--camera", scene / "gt" / "camera.yaml", "--out", tmp_path / "o", "--jobs", "2")
    assert result.exit_code == 2 and "000002.npz" in result.stderr and "vertices" in result.stderr


def test_failed_align_leaves_no_partial_output(scene, tmp_path, runner):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "000000.npz").write_bytes((scene / "pred" / "000000.npz").read_bytes())
    np.savez(bad / "000001.npz", joints=np.zeros((1, 24, 3)) + [0, 0, 5])
    (bad / "meta.yaml").write_text((scene / "pred" / "meta.yaml").read_text())
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("previous result")
    result = invoke(runner, "align", "--in", bad, "--camera", scene / "gt" / "camera.yaml", "--out", out, "--jobs", "1")
    assert result.exit_code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad", "out"]  # no staging left behind
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]  # previous output untouched
