"""Sequence-level align: the paper's effect in numbers, flags, forms, inputs untouched, CLI."""

from __future__ import annotations

import csv
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.alignment import AlignOptions, align_frame, align_sequence, aligned_meta
from rotavat_cli.geometry.camera import Camera, camera_parameters
from rotavat_cli.sequence import Frame, open_sequence, read_camera_yaml, write_frame


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
    assert out.meta == aligned_meta(seq.meta, cam)  # the input's, in the camera's intrinsics
    assert out.meta["focal_length"] == cam.focal_px and out.focal_kind == "camera"
    assert out.meta["aligned_from"] == {"focal_length": seq.intrinsics.focal_px, "focal_kind": "assumed", "focal_rule": "cliff"}
    f_in, f_out = seq.read_frame("000002"), out.read_frame("000002")
    assert set(f_in.data) == set(f_out.data)
    for key in f_in.data:
        assert f_out.data[key].dtype == f_in.data[key].dtype, key
        if key == "focal_length":  # the frame now says its meshes are in the camera
            assert float(f_out.data[key]) == cam.focal_px != float(f_in.data[key])
        elif key not in ("vertices", "joints"):
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
    from rotavat_cli.bodies.landmarks import foot_head_points

    f0, h0 = foot_head_points(frame.data["vertices"])
    f1, h1 = foot_head_points(new.data["vertices"])
    drawn = cam.replace(focal_px=seq.intrinsics.focal_px)  # the method's camera: its focal, not the camera's
    assert np.all(np.abs(cam.height_above_ground(f1)) < 1e-4)  # float32 output
    np.testing.assert_allclose(cam.project(f1), drawn.project(f0), atol=0.05)
    np.testing.assert_allclose(cam.project(h1), drawn.project(h0), atol=0.05)
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
    frame = seq.read_frame("000001")
    npz_aligned, _ = align_frame(frame, open_sequence(scene / "gt").camera, intrinsics=seq.frame_intrinsics(frame))
    np.testing.assert_allclose(out.read_frame("000001").data["vertices"], npz_aligned.data["vertices"], atol=1e-5)


def test_height_from_track_gives_one_stature_per_person(scene, tmp_path):
    cam = open_sequence(scene / "gt").camera
    align_sequence(open_sequence(scene / "pred"), cam, tmp_path / "t", AlignOptions(height_from="track"))
    rows = list(csv.DictReader(open(tmp_path / "t" / "people.csv")))
    by_id: dict[str, set] = {}
    for r in rows:
        by_id.setdefault(r["person_id"], set()).add(round(float(r["stature_m"]), 4))
    assert all(len(v) == 1 for v in by_id.values())


def test_align_refuses_to_write_into_its_input(scene, runner):
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml", "--out", scene / "pred")
    assert result.exit_code == 2 and "the output is the input" in result.stderr


def test_bad_option_value_exits_2(scene, tmp_path, runner):
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml",
                    "--out", tmp_path / "x", "--upright", "sideways")
    assert result.exit_code == 2 and "upright" in result.stderr


def test_worker_count_does_not_change_the_output(scene, tmp_path):
    cam = open_sequence(scene / "gt").camera
    seq = open_sequence(scene / "pred")
    align_sequence(seq, cam, tmp_path / "one", AlignOptions(jobs=1))
    align_sequence(seq, cam, tmp_path / "two", AlignOptions(jobs=2))
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


def _reference_drift_px(before: np.ndarray, after: np.ndarray, mesh_focal_px: float,
                        focal_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-person mean and max drift (P,), the plain way: float32 projections (the method's focal before,
    the camera's after; same principal point), np.hypot, nanmean/nanmax."""
    a, b = before.astype(np.float32), after.astype(np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        du = np.float32(focal_px) * b[..., 0] / b[..., 2] - np.float32(mesh_focal_px) * a[..., 0] / a[..., 2]
        dv = np.float32(focal_px) * b[..., 1] / b[..., 2] - np.float32(mesh_focal_px) * a[..., 1] / a[..., 2]
    drift = np.hypot(du, dv)
    return np.nanmean(drift, axis=1), np.nanmax(drift, axis=1)


@pytest.mark.parametrize("upright", ["paper", "full"])
def test_drift_columns_equal_the_plain_computation(scene, upright):
    seq = open_sequence(scene / "pred")
    frame = seq.read_frame("000003")
    cam = open_sequence(scene / "gt").camera
    assert seq.intrinsics.focal_px != pytest.approx(cam.focal_px, rel=0.05)  # the method's focal is not the camera's
    new, cols = align_frame(frame, cam, AlignOptions(upright=upright))
    mean, peak = _reference_drift_px(frame.data["vertices"], new.data["vertices"], seq.intrinsics.focal_px, cam.focal_px)
    np.testing.assert_allclose(cols["drift_mean_px"], mean, rtol=2e-5)
    np.testing.assert_allclose(cols["drift_max_px"], peak, rtol=2e-5)
    assert np.all(cols["drift_max_px"] > 0.1)  # a real per-vertex measurement, not the foot/crown's zero
    assert np.all(cols["head_drift_px"] < (1e-6 if upright == "paper" else 50.0))  # the crown stays on its pixel


def test_hypot_f32_is_np_hypot():
    from rotavat_cli.alignment.align import _hypot_f32

    rng = np.random.default_rng(3)
    x = (rng.normal(size=20000) * 10.0 ** rng.uniform(-40, 38, 20000)).astype(np.float32)
    y = (rng.normal(size=20000) * 10.0 ** rng.uniform(-40, 38, 20000)).astype(np.float32)
    x[:6] = [np.inf, np.nan, -np.inf, np.nan, 0.0, 3e38]
    y[:6] = [np.nan, np.inf, 1.0, np.nan, -0.0, 3e38]
    with np.errstate(over="ignore"):  # 3e38 * sqrt(2) overflows float32 either way
        expected, got = np.hypot(x, y), _hypot_f32(x, y)
    np.testing.assert_array_max_ulp(got, expected, maxulp=1)
    np.testing.assert_array_equal(got[:6], expected[:6])  # inf beats NaN, as in hypot
    if sys.platform.startswith("linux"):  # glibc's hypotf computes exactly this way
        np.testing.assert_array_equal(got, expected)


def test_nan_mean_max_is_nanmean_nanmax():
    from rotavat_cli.alignment.align import _nan_mean_max

    values = np.random.default_rng(4).uniform(0, 50, (4, 6890)).astype(np.float32)
    for rows in (values, np.where(np.arange(6890) % 7 == 0, np.nan, values).astype(np.float32)):
        mean, peak = _nan_mean_max(rows)
        assert mean.dtype == np.float32
        np.testing.assert_array_equal(mean, np.nanmean(rows, axis=1))
        np.testing.assert_array_equal(peak, np.nanmax(rows, axis=1))


def test_people_csv_cells():
    from rotavat_cli.alignment.align import PEOPLE_COLUMNS, _csv_rows

    cols = {c: np.array([1.0 / 3.0, np.nan]) for c in PEOPLE_COLUMNS}
    cols.update(frame=np.array(["a,b", "000001"], dtype=object), person_id=np.array([7, 8]),
                drift_mean_px=np.array([2.5, np.inf], dtype=np.float32), flag=np.array(["", "degenerate_mesh"], dtype=object))
    rows = list(csv.reader(_csv_rows(cols).splitlines()))
    cols.update(stature_from=np.array(["prior", "prior"], dtype=object))
    rows = list(csv.reader(_csv_rows(cols).splitlines()))
    assert rows[0] == ["a,b", "7", "0.333333", "0.333333", "0.333333", "0.333333", "0.333333", "0.333333",
                       "0.333333", "0.333333", "2.5", "0.333333", "0.333333", "", "prior"]
    assert rows[1] == ["000001", "8"] + [""] * 11 + ["degenerate_mesh", "prior"]


def test_one_rule_picks_the_camera_align_uses():
    """Given > the sequence's own > calibrated now; calibration runs only in the last case."""
    from dataclasses import replace

    from rotavat_cli.alignment import CALIBRATED, GIVEN, AlignCamera, camera_for_align
    from rotavat_cli.sequence import Sequence

    own_cam = Camera((640, 480), 500.0, None, 0.3, 0.0, 4.0)
    given = AlignCamera(Camera((640, 480), 700.0, None, 0.2, 0.0, 6.0), {"method": "grid"}, GIVEN, "cam.yaml")
    calls = []

    def calibrate(seq):
        calls.append(seq.label)
        return AlignCamera(Camera((640, 480), 900.0, None, 0.1, 0.0, 2.0), {}, CALIBRATED, "from the people")

    bare = Sequence(Path("/data/seq"), "npz", ("000000",))
    with_own = replace(bare, camera=own_cam, camera_fit={"pairs": 12})
    assert camera_for_align(with_own, given, calibrate) is given
    chosen = camera_for_align(with_own, None, calibrate)
    assert chosen.camera is own_cam and chosen.fit == {"pairs": 12} and chosen.origin == GIVEN
    assert chosen.source == str(Path("/data/seq/camera.yaml"))
    assert calls == []
    chosen = camera_for_align(bare, None, calibrate)
    assert chosen.origin == CALIBRATED and chosen.camera.focal_px == 900.0 and calls == ["/data/seq"]


def test_align_options_read_their_config_section_and_refuse_bad_values():
    options = AlignOptions.from_config({"upright": "full", "height_from": "track", "jobs": 3, "stature_range_m": [0.5, 2.5]})
    assert (options.upright, options.height_from, options.jobs, options.stature_range_m) == ("full", "track", 3, (0.5, 2.5))
    for bad, message in [({"upright": "tilted"}, "upright must be one of paper, full"),
                         ({"height_from": "mean"}, "height_from must be one of frame, track"),
                         ({"jobs": -1}, "jobs must be >= 0, got -1"),
                         ({"stature_range_m": (2.0, 1.0)}, "stature_range_m must be [low, high]")]:
        with pytest.raises(ValueError, match=re.escape(message)):
            AlignOptions(**bad)


def _joints_only(frame: Frame, intrinsics) -> Frame:
    """The frame as a joints-only import has it: no meshes; feet_2d/heads_2d = the mesh landmarks' pixels."""
    from rotavat_cli.geometry.camera import project_cam_to_px
    from rotavat_cli.bodies.landmarks import foot_head_points

    feet, heads = foot_head_points(frame.data["vertices"])
    focal = intrinsics.focals_px(frame.n_people)
    data = {k: v for k, v in frame.data.items() if k not in ("vertices", "faces")}
    data["feet_2d"] = project_cam_to_px(feet, focal, intrinsics.principal_point).astype(np.float32)
    data["heads_2d"] = project_cam_to_px(heads, focal, intrinsics.principal_point).astype(np.float32)
    return Frame(frame.name, data, frame.source)


def test_joint_level_alignment_matches_the_mesh_alignment(scene):
    """Without meshes, the joints are aligned from feet_2d/heads_2d at their nearest joints' depth: within
    2% of what the mesh alignment puts them at, far nearer the truth than the prediction."""
    seq, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    cam = gt.camera
    for name in seq.frame_names[:3]:
        frame = seq.read_frame(name)
        intrinsics = seq.frame_intrinsics(frame)
        with_mesh, cols_mesh = align_frame(frame, cam, intrinsics=intrinsics)
        joints_only, cols = align_frame(_joints_only(frame, intrinsics), cam, intrinsics=intrinsics)
        assert set(joints_only.data) == set(_joints_only(frame, intrinsics).data)  # joints moved, nothing added
        assert (cols["flag"] == "").all()
        depth = np.linalg.norm(with_mesh.data["joints"], axis=-1).mean()
        gap = np.linalg.norm(joints_only.data["joints"] - with_mesh.data["joints"], axis=-1)
        assert gap.max() < 0.02 * depth, (gap.max(), depth)
        np.testing.assert_allclose(cols["stature_m"], cols_mesh["stature_m"], rtol=0.03)
        truth = gt.read_frame(name).data["joints"]
        assert np.linalg.norm(joints_only.data["joints"] - truth, axis=-1).mean() < \
            0.2 * np.linalg.norm(frame.data["joints"] - truth, axis=-1).mean()


def test_a_frame_without_meshes_or_2d_points_is_refused(scene):
    seq = open_sequence(scene / "pred")
    frame = seq.read_frame("000000")
    bare = Frame(frame.name, {k: v for k, v in frame.data.items() if k not in ("vertices", "faces", "feet_2d", "heads_2d")},
                 frame.source)
    with pytest.raises(Exception, match="'joints' with 'feet_2d' and 'heads_2d'"):
        align_frame(bare, open_sequence(scene / "gt").camera, intrinsics=seq.frame_intrinsics(frame))


def test_track_plots_of_joints_only_people_measure_them_as_align_does(scene, tmp_path):
    """A joints-only person's per-track stature is the one of align's mid-sole and crown (feet_2d/heads_2d at the
    joints' depth: frame_points.frame_foot_head_cam), not another estimate."""
    from rotavat_cli.bodies.frame_points import MeshIntrinsics, frame_foot_head_cam
    from rotavat_cli.render import sequence_tracks

    seq, cam = open_sequence(scene / "pred"), open_sequence(scene / "gt").camera
    for name in seq.frame_names[:2]:
        frame = seq.read_frame(name)
        write_frame(tmp_path / "joints", _joints_only(frame, seq.frame_intrinsics(frame)), "npz")
    (tmp_path / "joints" / "meta.yaml").write_text((scene / "pred" / "meta.yaml").read_text())
    joints = open_sequence(tmp_path / "joints")
    tracks = sequence_tracks(joints, cam, "joints")
    for index, frame in enumerate(joints.frames()):
        feet, heads = frame_foot_head_cam(frame, MeshIntrinsics.of_frame(frame, joints.frame_intrinsics(frame), cam))
        for pid, stature in zip(frame.person_ids, np.linalg.norm(heads - feet, axis=1)):
            assert dict(tracks.values["stature_m"][int(pid)])[index] == pytest.approx(stature, rel=1e-9)


# ---- the camera gate ------------------------------------------------------------------------------
def _copy_sequence(src: Path, dst: Path, frames: int = 2) -> Path:
    """The first ``frames`` frames of ``src`` and its meta.yaml in a folder of their own (no camera.yaml)."""
    dst.mkdir(parents=True)
    for name in open_sequence(src).frame_names[:frames]:
        (dst / f"{name}.npz").write_bytes((src / f"{name}.npz").read_bytes())
    (dst / "meta.yaml").write_text((src / "meta.yaml").read_text())
    return dst


def test_align_refuses_an_implausible_camera_and_its_advice_runs_as_written(scene, tmp_path, runner):
    """One line: the camera, its findings, and what to give; each suggested command then runs as written."""
    import shlex

    from _camera_gate import FINDINGS, assert_doc_link_exists, assert_named_flags_exist, error_line, implausible

    seq = _copy_sequence(scene / "pred", tmp_path / "pred")
    true_yaml = scene / "gt" / "camera.yaml"
    implausible(true_yaml, seq / "camera.yaml")  # as calibrate writes a camera it found implausible
    result = invoke(runner, "align", seq)
    assert result.exit_code == 2
    message = error_line(result.stderr)
    assert message.startswith(f"{seq / 'camera.yaml'}: implausible camera ({FINDINGS[0]}; {FINDINGS[1]}); give what you know:")
    assert f"rotavat calibrate {seq} --focal PX --camera-height M [--pitch DEG] (then rotavat align {seq})" in message
    assert f"rotavat align {seq} --camera FILE (a camera.yaml you wrote: docs/conventions.md#camerayaml)" in message
    assert message.endswith(f"rotavat align {seq} --accept-camera to use it anyway")
    assert_named_flags_exist(message)
    assert_doc_link_exists(message)
    assert not (tmp_path / "pred_aligned").exists()  # refused before anything was written

    accept = shlex.split(re.search(r"rotavat (align \S+ --accept-camera)", message).group(1))
    result = invoke(runner, *accept)
    assert result.exit_code == 0, result.stderr
    assert "implausible camera" in result.stderr and FINDINGS[0] in result.stderr and "--accept-camera" in result.stderr
    fit = read_camera_yaml(tmp_path / "pred_aligned" / "camera.yaml")[1]
    assert fit["implausible"] == list(FINDINGS) and fit["accepted"] is True  # the consent travels with the output

    given = shlex.split(re.search(r"rotavat (align \S+ --camera FILE)", message).group(1).replace("FILE", str(true_yaml)))
    result = invoke(runner, *given)
    assert result.exit_code == 0 and "implausible" not in result.stderr, result.stderr

    cam = camera_parameters(open_sequence(scene / "gt").camera)
    known = {"PX": f"{cam['focal_px']:.1f}", "M": f"{cam['height_m']:.3f}", "DEG": f"{cam['pitch_deg']:.2f}"}
    calibrate = re.search(r"rotavat (calibrate \S+ --focal PX --camera-height M \[--pitch DEG\])", message).group(1)
    result = invoke(runner, *(known.get(a, a) for a in shlex.split(calibrate.replace("[", "").replace("]", ""))))
    assert result.exit_code == 0, result.stderr
    assert not read_camera_yaml(seq / "camera.yaml")[1].get("implausible")
    result = invoke(runner, *shlex.split(re.search(r"\(then rotavat (align \S+)\)", message).group(1)))
    assert result.exit_code == 0 and "implausible" not in result.stderr, result.stderr


def test_align_names_the_camera_it_calibrated_itself(scene, tmp_path, runner, monkeypatch):
    from dataclasses import replace

    import rotavat_cli.cli.align as align_cli
    from _camera_gate import FINDINGS, error_line

    calibrate = align_cli.run_calibration

    def implausible_calibration(*args, **kwargs):
        calib = calibrate(*args, **kwargs)
        return replace(calib, result=replace(calib.result, implausible=FINDINGS))

    monkeypatch.setattr(align_cli, "run_calibration", implausible_calibration)
    seq = _copy_sequence(scene / "pred", tmp_path / "pred")
    result = invoke(runner, "align", seq, "--out", tmp_path / "out", "-q")
    assert result.exit_code == 2
    assert error_line(result.stderr).startswith(f"the camera calibrated from {seq}: implausible camera ({FINDINGS[0]};")
    assert f"rotavat align {seq} --out {tmp_path / 'out'} --accept-camera" in result.stderr
    result = invoke(runner, "align", seq, "--out", tmp_path / "out", "--accept-camera", "--json")
    assert result.exit_code == 0 and json.loads(result.stdout)["camera_implausible"] == list(FINDINGS)


@pytest.mark.parametrize("fit", [None, {"method": "refine", "implausible": []}, {"implausible": None, "warnings": ["x"]}])
def test_a_camera_without_findings_is_used_silently(scene, tmp_path, runner, fit):
    from _camera_gate import write_camera

    camera = write_camera(scene / "gt" / "camera.yaml", tmp_path / "camera.yaml", fit)
    result = invoke(runner, "align", scene / "pred", "--camera", camera, "--out", tmp_path / "out")
    assert result.exit_code == 0 and "implausible" not in result.stderr + result.stdout, result.stderr


def test_the_gate_passes_a_camera_accepted_earlier_with_a_warning(scene, tmp_path, runner):
    from _camera_gate import FINDINGS, implausible

    camera = implausible(scene / "gt" / "camera.yaml", tmp_path / "camera.yaml", accepted=True)
    result = invoke(runner, "align", scene / "pred", "--camera", camera, "--out", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    assert "accepted earlier" in result.stderr and FINDINGS[1][:20] in result.stderr


def test_people_cut_by_the_border_are_not_reseated_by_an_invisible_foot():
    """A person whose foot, as the tool drew it, lies below the image is left where the tool put it, flagged
    cut_by_border; the whole person next to them is aligned."""
    cam = Camera((640, 480), 500, None, np.deg2rad(20), 0.0, 3.0)
    ground = cam.backproject_px_to_ground(np.array([[200.0, 400.0], [420.0, 560.0]]))  # the second foot: 80 px below
    rng = np.random.default_rng(0)
    blob = rng.normal(0, 0.1, (30, 3))
    verts = np.stack([g + blob - blob.mean(0) + np.linspace(0, 1, 30)[:, None] * 1.7 * cam.up_cam
                      for g in ground]).astype(np.float32)
    frame = Frame("000000", {"vertices": verts, "person_ids": np.array([1, 2])})
    new, cols = align_frame(frame, cam)
    assert list(cols["flag"]) == ["", "cut_by_border"] and np.isnan(cols["stature_m"][1])
    np.testing.assert_array_equal(new.data["vertices"][1], verts[1])
    assert 1.4 < cols["stature_m"][0] < 2.0 and list(cols["stature_from"]) == ["given_camera"] * 2


def test_align_says_where_its_statures_come_from(scene, tmp_path, runner):
    """people.csv's stature_from and the summary line follow the camera's scale: a calibration from the people
    gives the stature prior back; ground truth's camera (no fit block) measures."""
    pred = scene / "pred"
    cal = tmp_path / "cal.yaml"
    assert invoke(runner, "calibrate", pred, "--out", cal, "-q").exit_code == 0
    for camera, source, words in ((cal, "prior", "1.70 m stature prior given back"),
                                  (scene / "gt" / "camera.yaml", "given_camera", "measured with a given camera")):
        out = tmp_path / source
        result = invoke(runner, "align", pred, "--camera", camera, "--out", out)
        assert result.exit_code == 0, result.stderr
        assert words in " ".join(result.stdout.split())
        with open(out / "people.csv", newline="") as handle:
            assert {row["stature_from"] for row in csv.DictReader(handle)} == {source}


def test_the_camera_is_wrong_advice_never_repeats_what_was_given(scene, tmp_path, runner):
    """The people of a given camera measuring 3.4 m: align's warning names what else is wrong, not the focal and
    height the calibration was given (the advice used to loop: 'give --focal PX --camera-height M' to a user
    who had)."""
    pred = scene / "pred"
    truth = read_camera_yaml(scene / "gt" / "camera.yaml")[0]
    cal = tmp_path / "cal.yaml"
    result = invoke(runner, "calibrate", pred, "--out", cal, "--focal", str(truth.focal_px), "--camera-height",
                    str(2.0 * truth.height_m), "--pitch", str(np.rad2deg(truth.pitch_rad)), "-q")
    assert result.exit_code == 0, result.stderr
    aligned = invoke(runner, "align", pred, "--camera", cal, "--out", tmp_path / "al", "--accept-camera")
    (line,) = [w for w in aligned.stderr.splitlines() if "median stature" in w]
    assert "the people do not fit the model" in line and "--focal" not in line and "--camera-height" not in line
