"""Importers of HPS tools' own outputs: conventions (frame, units, focal, translation), round trips
into contract sequences the other commands accept, and hostile / corrupt inputs (exit 2, one line)."""

from __future__ import annotations

import csv

import hashlib
import json
import pickle
import tempfile
from dataclasses import dataclass
from pathlib import Path

import _format_fixtures as F
import _fixtures_comotion_prompthmr as CP
import _fixtures_torch as T
import _fixtures_wham_hybrik as WH
import _fixtures_pymafx_trace as PT
import _fixtures_slahmr_glamr as SG
import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli import unpickle
from rotavat_cli.geometry.camera import horizon_v_px
from rotavat_cli.errors import InputError
from rotavat_cli.formats import available_formats, detect_format, import_sequence, imported_sequence
from rotavat_cli.formats.agora import focal_mm
from rotavat_cli.formats.source import ImporterSource, forget, recipe_cached
from rotavat_cli.geometry.focal import focal_from_rule
from rotavat_cli.bodies.landmarks import foot_head_points
from rotavat_cli.sequence import open_sequence, read_camera_yaml, write_camera_yaml

W, H = 640, 480
TOL_M = 1e-4  # float32 storage of metre-scale coordinates (~1e-6) plus LBS round-off
TOL_PX = 0.02  # float32 pixels


_FIXED_FOCAL_RULES = ("4dhumans", "pymafx")  # tools whose one focal is far from any real lens's


def _as_the_tool_places_it(fmt: str, scene, camera):
    """The scene as ``fmt`` would write it (:func:`F.seen_with_focal`): through a fixed focal far from the camera's,
    people stand where they draw the camera's pixels (tens of metres away), not where the camera sees them, which
    through that focal would be metres beyond the image."""
    if fmt not in _FIXED_FOCAL_RULES:
        return scene
    factor = focal_from_rule(fmt, (W, H)) / camera.focal_px
    return [[F.seen_with_focal(person, factor) for person in frame] for frame in scene]


def _write(fmt: str, folder: Path, scene, model, camera) -> Path:
    """A fixture of ``fmt`` for the default scene."""
    if fmt == "cliff":
        return F.write_cliff(folder / "demo_cliff_hr48.npz", scene, (W, H))
    if fmt in ("bev", "romp"):
        return F.write_bev(folder / fmt, scene, (W, H), fmt=fmt)
    if fmt == "4dhumans":
        return F.write_phalp(folder / "demo_video.pkl", scene, (W, H))
    if fmt == "multihmr":
        return F.write_multihmr(folder / "mh", scene, image_size=(W, H))
    if fmt == "spec":
        return F.write_spec(folder / "spec_out", scene, (W, H), model, camera.focal_px, camera.pitch_rad)
    if fmt == "agora":
        return F.write_agora(folder / "agora", scene)
    if fmt == "bedlam":
        return F.write_bedlam(folder / "scene.npz", scene)
    if fmt == "gvhmr":  # one tracked person per frame: the scene's people one after another
        return T.write_gvhmr(folder / "gvhmr", [p for frame in scene for p in frame], (W, H))
    if fmt == "tram":
        return T.write_tram(folder / "tram", scene, (W, H))
    if fmt == "wham":
        return WH.write_wham(folder / "wham_output.pkl", scene)
    if fmt == "hybrik":  # rows of one image are its people (the demo writes one per image)
        return WH.write_hybrik(folder / "res.pk", scene, (W, H))
    if fmt == "pymafx":
        return PT.write_pymafx(folder / "output.pkl", scene, (W, H))
    if fmt == "trace":
        return PT.write_trace(folder / "trace_demo.npz", scene, (W, H))
    if fmt == "slahmr":  # the run folder: motion_chunks/<seq>_<iteration>_world_results.npz + track_info.json
        return SG.write_slahmr(folder / "slahmr_run", scene, model)
    if fmt == "glamr":
        return SG.write_glamr(folder / "glamr_out" / "grecon" / "demo_seed1.pkl", scene)
    if fmt == "comotion":  # demo.py -i demo.mp4 -o comotion_out: <output-dir>/<input>.pt
        return CP.write_comotion(folder / "comotion_out" / "demo.pt", scene)
    if fmt == "prompthmr":  # scripts/demo_video.py --static_camera: results/<video>/results.pkl
        return CP.write_prompthmr(folder / "results" / "demo", scene, camera, (W, H))
    raise AssertionError(fmt)


# Expected intrinsics of each tool (the formulas of docs/formats.md), and which frames survive.
def _expected(fmt: str, camera):
    side = max(W, H)
    if fmt == "cliff":
        return np.hypot(W, H), (W / 2, H / 2), (W, H)
    if fmt == "bev":
        return 443.4 / 512 * side, (side / 2, side / 2 - (side - H) // 2), (W, H)
    if fmt == "romp":
        return side / (2 * np.tan(np.radians(30))), (side / 2, side / 2 - (side - H) // 2), (W, H)
    if fmt == "4dhumans":
        return 5000 * side / 256, (side / 2, side / 2 - (side - H) // 2), (W, H)
    if fmt == "multihmr":
        return side / (2 * np.tan(np.radians(30))), (W / 2, H / 2), (W, H)
    if fmt == "spec":
        return camera.focal_px, (W / 2, H / 2), (W, H)
    if fmt == "agora":
        return 18.0 / 36.0 * 3840, (1920, 1080), (3840, 2160)
    if fmt == "bedlam":
        return 28.0 / 36.0 * 1280, (640, 360), (1280, 720)
    if fmt == "gvhmr":
        return np.hypot(W, H), (W / 2, H / 2), (W, H)
    if fmt == "tram":
        return float(side), (W / 2, H / 2), (W, H)
    if fmt == "wham":  # compute_cam_intrinsics: the image diagonal at the image centre
        return np.hypot(W, H), (W / 2, H / 2), (W, H)
    if fmt == "hybrik":  # no sequence focal: one per person in each frame, 1000 / 256 * box width
        return None, (W / 2, H / 2), (W, H)
    if fmt == "pymafx":
        return 5000.0, (W / 2, H / 2), (W, H)
    if fmt == "trace":
        return 548.0 / 512 * side, (side / 2, side / 2 - (side - H) // 2), (W, H)
    if fmt == "slahmr":  # SLAHMR's default intrinsics: (W + H) / 2 at the image centre
        return (W + H) / 2, (W / 2, H / 2), (W, H)
    if fmt == "glamr":  # GLAMR's HybrIK: 1000 px at the image centre
        return 1000.0, (W / 2, H / 2), (W, H)
    if fmt == "comotion":  # get_default_K: 2 max(W, H) at the image centre
        return 2.0 * side, (W / 2, H / 2), (W, H)
    if fmt == "prompthmr":  # est_calib (--static_camera): max(W, H) at the centre of its frames
        return float(side), (W / 2, H / 2), (W, H)
    raise AssertionError(fmt)


def _model_for(fmt: str, model_path: Path, smplx_path: Path) -> Path:
    """The model file a format's parameters need: GVHMR's and PromptHMR's are SMPL-X (the synthetic SMPL-X on the
    same mesh)."""
    return smplx_path if fmt in ("gvhmr", "prompthmr") else model_path


def _import(fmt, tmp_path, scene, model, camera, model_path, **kw):
    """``fmt``'s files of ``scene`` imported with the model file ``model_path`` (GVHMR's: SMPL-X)."""
    src = _write(fmt, tmp_path, scene, model, camera)
    if fmt in ("cliff", "multihmr", "wham", "comotion"):
        kw.setdefault("image_size", (W, H))
    out = tmp_path / "out"
    summary = import_sequence(src, out, fmt, smpl_model=model_path, **kw)
    return src, out, summary


ALL = ["cliff", "bev", "romp", "4dhumans", "multihmr", "spec", "agora", "bedlam", "pymafx", "trace", "slahmr", "glamr", "gvhmr", "tram",
       "wham", "hybrik", "comotion", "prompthmr"]


def test_available_formats():
    assert available_formats() == sorted(ALL)


@pytest.mark.parametrize("fmt", ALL)
def test_known_person_comes_out_in_the_camera_frame(fmt, tmp_path, scene, model, camera, model_path, smplx_on_smpl_path,
                                                    runner):
    """People placed at known camera-frame positions come out there: OpenCV axes, metres, right focal."""
    src, out, summary = _import(fmt, tmp_path, scene, model, camera, _model_for(fmt, model_path, smplx_on_smpl_path))
    assert detect_format(src) == fmt
    seq = open_sequence(out)
    focal, pp, size = _expected(fmt, camera)
    intr = seq.intrinsics.with_defaults()
    assert seq.meta["source"] == fmt
    # ground truth knows the camera; every HPS tool guessed its focal (by its documented rule)
    assert seq.focal_kind == ("camera" if fmt in ("agora", "bedlam") else "assumed")
    assert seq.meta.get("focal_rule") == {"cliff": "cliff", "bev": "bev", "romp": "romp", "4dhumans": "4dhumans",
                                          "pymafx": "pymafx", "trace": "trace", "slahmr": "slahmr",
                                          "gvhmr": "cliff", "tram": "tram", "wham": "cliff",
                                          "glamr": "glamr", "comotion": "comotion", "prompthmr": "tram"}.get(fmt)
    assert intr.image_size == size
    assert intr.focal_px == (None if focal is None else pytest.approx(focal, rel=1e-9))
    assert intr.principal_point == pytest.approx(pp, abs=1e-9)
    people = [[p] for frame in scene for p in frame] if fmt == "gvhmr" else [frame for frame in scene if frame]
    frames = [f for f in seq.frames() if f.n_people]
    assert len(frames) == len(people)
    for frame, truth in zip(frames, people):
        if fmt == "hybrik":  # each person's own focal, from its box
            focal = frame.intrinsics.focals_px(len(truth))
            assert focal == pytest.approx([1000 / 256 * WH.hybrik_box_width(p) for p in truth], rel=1e-9)
            focal = focal[:, None, None]
        expected_verts = np.stack([p.verts_cam for p in truth])
        expected_joints = np.stack([p.joints_cam for p in truth])
        np.testing.assert_allclose(frame.data["vertices"], expected_verts, atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"], expected_joints, atol=TOL_M)
        assert frame.data["vertices"].dtype == np.float32
        assert frame.data["faces"].shape[1] == 3  # faces come from --smpl-model
        # A person 7-10 m in front of a camera 3 m up, looking 15 deg down: z forward, y down.
        assert np.all(frame.data["joints"][:, 0, 2] > 6.0)
        feet_y = frame.data["vertices"][..., 1].max(axis=1)
        heads_y = frame.data["vertices"][..., 1].min(axis=1)
        assert np.all(feet_y > heads_y)
        kp = frame.get("keypoints_2d")
        if kp is not None and fmt != "romp":  # ROMP's 2D are weak-perspective
            proj = F.project(expected_joints, focal, pp)
            idx = {"spec": slice(25, 49), "4dhumans": slice(None, 24), "bedlam": slice(None, 24),
                   "agora": slice(None, 24), "bev": slice(None, 24), "trace": slice(None, 24),
                   "hybrik": slice(None, 24)}.get(fmt)
            if fmt == "multihmr":
                proj = proj[:, :22]
                idx = slice(None, 22)
            if fmt == "pymafx":  # COCO-17 detections: the fixture puts them on the first 17 joints
                proj = proj[:, :17]
                idx = slice(None, 17)
            if fmt == "glamr":  # body26fk: SMPL's joints at some of its slots only
                proj = proj[:, list(SG.BODY26FK_SMPL.values())]
                idx = list(SG.BODY26FK_SMPL)
            np.testing.assert_allclose(kp[:, idx, :2], proj, atol=TOL_PX * max(1, np.max(focal) / 1000))
    assert summary["has_vertices"] and summary["joints_layout"].startswith("smpl24")
    assert invoke(runner, "info", out).exit_code == 0


@pytest.mark.parametrize("fmt", ["bev", "4dhumans", "bedlam", "slahmr", "glamr"])
def test_track_ids_are_kept(fmt, tmp_path, scene, model, camera, model_path):
    _, out, _ = _import(fmt, tmp_path, scene, model, camera, model_path)
    frames = [f for f in open_sequence(out).frames() if f.n_people]
    if fmt == "bedlam":  # subject names -> integers in sorted order (rp_subject_03, rp_subject_05)
        assert frames[0].data["person_ids"].tolist() == [0, 1] and frames[1].data["person_ids"].tolist() == [0]
        # the legend names the subjects, not the frames (the two lists once shared a variable)
        legend = open_sequence(out).meta["import"]["person_ids"]
        assert legend == "subject names in sorted order: rp_subject_03, rp_subject_05"
    else:
        assert frames[0].data["person_ids"].tolist() == [3, 5] and frames[1].data["person_ids"].tolist() == [3]


def test_imported_sequence_feeds_align_eval_and_render(tmp_path, scene, model, camera, model_path, runner):
    _, out, _ = _import("bev", tmp_path, scene, model, camera, model_path)
    cam_yaml = tmp_path / "camera.yaml"
    write_camera_yaml(cam_yaml, camera.replace(focal_px=F.BEV_FOCAL_PX))
    aligned = tmp_path / "aligned"
    result = invoke(runner, "align", "--in", out, "--camera", cam_yaml, "--out", aligned, "--quiet")
    assert result.exit_code == 0, result.output
    result = invoke(runner, "eval", aligned, out, "--gt", out, "--out", tmp_path / "metrics", "--quiet")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "metrics" / "metrics.json").exists()
    result = invoke(runner, "render", out, "--camera", cam_yaml, "--renderer", "fallback", "--size", "160", "120", "--out",
                    tmp_path / "render", "--no-gif", "--no-glb")
    assert result.exit_code == 0, result.output


def test_bedlam_and_agora_ground_truth_serve_eval(tmp_path, scene, model, camera, model_path, runner):
    """Ground truth imported from BEDLAM scores a SPEC prediction of the same people at ~0 mm."""
    size = (640, 360)  # BEDLAM renders are 16:9 with square pixels
    gt = tmp_path / "gt"
    import_sequence(F.write_bedlam(tmp_path / "scene.npz", scene, size, focal_mm=500 * 36 / 640), gt, "bedlam",
                    smpl_model=model_path)
    pred = tmp_path / "pred"  # SPEC run on the BEDLAM images: same image names, so frames line up
    spec = F.write_spec(tmp_path / "spec", scene, size, model, 500.0, camera.pitch_rad,
                        names=[f"seq_000001_{i:04d}" for i in range(len(scene))])
    import_sequence(spec, pred, "spec", smpl_model=model_path)
    assert invoke(runner, "eval", pred, "--gt", gt, "--out", tmp_path / "m", "--quiet").exit_code == 0
    result = json.loads((tmp_path / "m" / "metrics.json").read_text())["predictions"][0]
    assert result["matched"] == 3 and result["missed"] == 0 and result["false_positives"] == 0
    assert result["metrics"]["w_mpjpe"] < 0.01 and result["metrics"]["w_pve"] < 0.01  # mm
    agora = tmp_path / "agora_gt"
    import_sequence(F.write_agora(tmp_path / "agora", scene), agora, "agora")
    assert invoke(runner, "eval", agora, "--gt", agora, "--out", tmp_path / "m2", "--quiet").exit_code == 0


def test_calibrate_accepts_an_imported_sequence(tmp_path, bev_scene, model_path, runner):
    """A larger scene imported from BEV calibrates close to the true camera."""
    src = F.write_bev(tmp_path / "bev", bev_scene, (W, H))
    out = tmp_path / "out"
    import_sequence(src, out, "bev", smpl_model=model_path, image_size=(W, H))
    result = invoke(runner, "calibrate", out, "--quiet")
    assert result.exit_code == 0, result.output
    est, _ = read_camera_yaml(out / "camera.yaml")
    assert np.rad2deg(est.pitch_rad) == pytest.approx(15.0, abs=1.5)
    assert est.height_m == pytest.approx(3.0, rel=0.15)


def test_imported_sequence_context_manager(tmp_path, scene, model, camera, model_path):
    src = _write("agora", tmp_path, scene, model, camera)
    before = _files_under(tmp_path)
    with imported_sequence(src, "agora") as seq:
        assert len(seq) == 2 and seq.meta["source"] == "agora"
        folder = seq.path
        # named by the tool's own output (no converted copy anywhere); frames converted when read
        assert folder == src and seq.label == str(src) and seq.form == "npz" and seq.origin == str(src)
        assert [f.n_people for f in seq.frames()] == [2, 1]
        assert recipe_cached(seq.frame_source.recipe)
    assert not recipe_cached(seq.frame_source.recipe)  # what the reader loaded is let go at the end
    assert folder.exists() and _files_under(tmp_path) == before  # nothing written, nothing left to delete


# ---- conventions, format by format ---------------------------------------------------------------
def test_spec_camera_yaml(tmp_path, scene, model, camera, model_path):
    """CamCalib focal/pitch/roll plus the people's ground give the true camera."""
    _, out, summary = _import("spec", tmp_path, scene, model, camera, model_path)
    assert summary["camera_yaml"]
    est, fit = read_camera_yaml(out / "camera.yaml")
    assert est.focal_px == pytest.approx(camera.focal_px)
    assert np.rad2deg(est.pitch_rad) == pytest.approx(15.0, abs=1e-4)
    assert np.rad2deg(est.roll_rad) == pytest.approx(0.0, abs=1e-4)
    assert est.height_m == pytest.approx(camera.height_m, abs=0.02)
    assert fit["method"] == "spec-camcalib" and fit["people"] == 3


def test_spec_roll_sign_matches_its_horizon(tmp_path, scene, model, camera):
    """SPEC's horizon (camcalib/vis_utils.py): positive roll puts the right end of the horizon lower."""
    src = F.write_spec(tmp_path / "spec", scene, (W, H), model, 500.0, np.deg2rad(10.0), np.deg2rad(8.0))
    import_sequence(src, tmp_path / "out", "spec")
    est, _ = read_camera_yaml(tmp_path / "out" / "camera.yaml")
    left, right = horizon_v_px(np.array([0.0, W]), est.focal_px, est.principal_point, est.up_cam)
    assert right > left
    ctr = H * (0.5 - 0.5 * np.tan(np.deg2rad(10.0)) / (H / 2 / 500.0))  # SPEC's horizon row at the centre
    assert horizon_v_px(W / 2, est.focal_px, est.principal_point, est.up_cam) == pytest.approx(ctr, abs=2.0)


def test_spec_image_size_recovered_from_2d(tmp_path, scene, model, camera, model_path):
    src = F.write_spec(tmp_path / "spec", scene, (W, H), model, 500.0, camera.pitch_rad)
    summary = import_sequence(src, tmp_path / "out", "spec")
    assert summary["image_size"] == [W, H]


def test_bev_principal_point_with_odd_padding(tmp_path, scene, model, camera, model_path):
    """The principal point is the centre of the padded square, not always the image centre."""
    size = (641, 480)
    src = F.write_bev(tmp_path / "bev", scene, size)
    summary = import_sequence(src, tmp_path / "out", "bev", image_size=size)
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.principal_point == (320.5, 320.5 - 80)
    assert summary["focal_px"] == pytest.approx(443.4 / 512 * 641)


def test_bev_video_results_and_image_size_inference(tmp_path, scene):
    src = F.write_bev(tmp_path / "bev", scene, (W, H), video=True)
    summary = import_sequence(src, tmp_path / "out", "bev")  # no --image-size, no model
    assert summary["image_size"] == [W, H] and summary["frames"] == 2 and summary["has_vertices"]
    assert any("inferred" in w for w in summary["warnings"])


def test_romp_without_vertices_poses_its_parameters(tmp_path, scene, model, model_path):
    src = F.write_bev(tmp_path / "romp", scene, (W, H), fmt="romp")
    for file in src.glob("*.npz"):  # as if run without --calc_smpl: parameters + cam_trans only
        results = unpickle.load_npz(file)["results"].item()  # the importer's own restricted reader
        for key in ("verts", "joints", "pj2d_org"):
            results.pop(key)
        np.savez(file, results=results)
    import_sequence(src, tmp_path / "out", "romp", smpl_model=model_path, image_size=(W, H))
    frame = next(open_sequence(tmp_path / "out").frames())
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)


def test_cliff_rotmat_pose_and_fork_track_ids(tmp_path, scene, model_path):
    src = F.write_cliff(tmp_path / "r.npz", scene, (W, H), pose_format="rotmat", fork=True)
    import_sequence(src, tmp_path / "out", "cliff", smpl_model=model_path, image_size=(W, H))
    frames = list(open_sequence(tmp_path / "out").frames())
    assert [f.n_people for f in frames] == [2, 1, 0]
    assert frames[0].data["person_ids"].tolist() == [3, 5]
    np.testing.assert_allclose(frames[1].data["vertices"][0], scene[1][0].verts_cam, atol=TOL_M)


def test_cliff_image_size_from_image_headers(tmp_path, scene):
    src = F.write_cliff(tmp_path / "r.npz", scene, (W, H))
    data = dict(np.load(src, allow_pickle=False))
    data["imgname"] = np.array([f"imgs/{i:06d}.png" for i in range(3)])
    np.savez(src, **data)
    (tmp_path / "imgs").mkdir()
    png = b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\rIHDR" + W.to_bytes(4, "big") + H.to_bytes(4, "big") + b"\x08\x02\x00\x00\x00"
    for i in range(3):
        (tmp_path / "imgs" / f"{i:06d}.png").write_bytes(png)
    summary = import_sequence(src, tmp_path / "out", "cliff")
    assert summary["image_size"] == [W, H] and summary["focal_px"] == pytest.approx(np.hypot(W, H))


def test_fourdhumans_skips_undetected_tracks_and_reads_plain_pickles(tmp_path, scene, model_path):
    src = F.write_phalp(tmp_path / "r.pkl", scene, (W, H), compress=0, protocol=2)
    import_sequence(src, tmp_path / "out", "4dhumans", smpl_model=model_path)
    assert [f.n_people for f in open_sequence(tmp_path / "out").frames()] == [2, 1, 0]


def test_multihmr_forms_and_fov(tmp_path, scene, model, camera):
    for form in ("npy", "pkl"):
        src = F.write_multihmr(tmp_path / form, scene, form=form)
        summary = import_sequence(src, tmp_path / f"out_{form}", "multihmr", image_size=(W, H), fov_deg=40.0)
        assert summary["focal_px"] == pytest.approx(640 / (2 * np.tan(np.radians(20))))
        frame = next(open_sequence(tmp_path / f"out_{form}").frames())
        np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)
        assert (frame.get("joints") is None) == (form == "npy")


def test_agora_focal_rule_params_and_small_images(tmp_path, scene, model_path):
    assert [focal_mm(n) for n in ("x_hdri_y", "a_cam00_b", "a_cam03_b", "ag2_x", "archviz_x")] == [50, 18, 18, 28, 28]
    src = F.write_agora(tmp_path / "agora", scene, params=True, scene_tag="hdri")
    import_sequence(src, tmp_path / "out", "agora", smpl_model=model_path, image_size=(1280, 720))
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.focal_px == pytest.approx(50.0 / 36.0 * 1280)
    frame = next(seq.frames())
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)
    kp4k = F.project(np.stack([p.joints_cam for p in scene[0]]), 28.0 / 36.0 * 3840, (1920, 1080))
    np.testing.assert_allclose(frame.data["keypoints_2d"], kp4k / 3, atol=TOL_PX)  # written at 4K, read at 720p


def test_parameter_formats_without_a_model_import_joints_only(tmp_path, scene, model, camera):
    for fmt in ("cliff", "4dhumans", "bedlam"):
        (tmp_path / fmt).mkdir()
        src = _write(fmt, tmp_path / fmt, scene, model, camera)
        summary = import_sequence(src, tmp_path / f"out_{fmt}", fmt, image_size=(W, H) if fmt == "cliff" else None)
        assert not summary["has_vertices"]
        assert any("smpl-model" in w for w in summary["warnings"])
    cliff = next(open_sequence(tmp_path / "out_cliff").frames())
    np.testing.assert_allclose(cliff.data["joints"], np.stack([p.joints_cam for p in scene[0]]), atol=TOL_M)
    phalp = open_sequence(tmp_path / "out_4dhumans")
    assert phalp.meta["import"]["joints_layout"].startswith("phalp44") and phalp.meta["import"]["root_joint"] == 8
    assert "keypoints_2d" in next(open_sequence(tmp_path / "out_bedlam").frames()).data


def test_wrong_model_family_is_refused(tmp_path, scene, model, camera, model_path):
    model_file = tmp_path / "x.npz"
    data = dict(np.load(model_path, allow_pickle=False))
    data["kintree_table"] = data["kintree_table"][:, :23]
    data["J_regressor"] = data["J_regressor"][:23]
    data["weights"] = data["weights"][:, :23]
    data["posedirs"] = data["posedirs"][:, :, : 9 * 22]
    np.savez(model_file, **data)
    src = F.write_cliff(tmp_path / "r.npz", scene, (W, H))
    with pytest.raises(InputError, match="24"):
        import_sequence(src, tmp_path / "out", "cliff", smpl_model=model_file, image_size=(W, H))


# ---- CLI: errors are one line with exit 2 --------------------------------------------------------
def _one_line_error(result) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert len(lines) >= 1 and lines[0].startswith("error:")
    return " ".join(lines)


def test_cli_import_and_json(tmp_path, scene, model, camera, model_path, runner):
    src = _write("4dhumans", tmp_path, scene, model, camera)
    result = invoke(runner, "import", src, tmp_path / "out", "--smpl-model", model_path, "--json")
    assert result.exit_code == 0, result.output
    assert '"frames": 3' in result.stdout
    result = invoke(runner, "import", src, tmp_path / "out2", "--from", "4dhumans", "--quiet")
    assert result.exit_code == 0 and not (tmp_path / "out2" / "camera.yaml").exists()


@pytest.mark.parametrize("args, needle", [
    (["--from", "nope"], "unknown format"),
    ([], "cannot tell its format"),
])
def test_cli_format_errors(args, needle, tmp_path, runner):
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "x.txt").write_text("hello")
    text = _one_line_error(invoke(runner, "import", tmp_path / "src", tmp_path / "out", *args))
    assert needle in text


def test_cli_missing_image_size_says_to_pass_it(tmp_path, scene, model, camera, runner):
    src = _write("multihmr", tmp_path, scene, model, camera)
    assert "--image-size W H" in _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "multihmr"))
    src = F.write_cliff(tmp_path / "r.npz", scene, (W, H))
    assert "--image-size W H" in _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "cliff"))


def test_cli_refuses_a_non_empty_out_and_force_replaces(tmp_path, scene, model, camera, model_path, runner):
    src = _write("agora", tmp_path, scene, model, camera)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    (out / "000099.npz").write_bytes(b"stale")
    assert "not empty" in _one_line_error(invoke(runner, "import", src, out))
    assert (out / "notes.txt").read_text() == "keep me"  # refused: nothing touched
    result = invoke(runner, "import", src, out, "--force", "--quiet")  # said explicitly: replaced whole
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in out.iterdir())
    assert "notes.txt" not in names and "000099.npz" not in names and names[0] == ".rotavat-output"
    assert len(open_sequence(out)) == 2
    again = invoke(runner, "import", src, out, "--quiet")  # rotavat's own output: replaced without --force
    assert again.exit_code == 0, again.output


def test_failed_import_leaves_out_untouched(tmp_path, scene, model, camera, runner):
    src = _write("agora", tmp_path, scene, model, camera)
    out = tmp_path / "out"
    assert invoke(runner, "import", src, out, "--quiet").exit_code == 0
    before = tree_hash(out)
    bad = sorted(src.glob("*.pkl"))[-1]
    F.truncate(bad)
    _one_line_error(invoke(runner, "import", src, out, "--force"))
    assert tree_hash(out) == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]


def _hostile(fmt: str, tmp_path: Path, marker: Path, scene, model, camera) -> Path:
    """A fixture of ``fmt`` with a code-executing pickle where the tool stores a pickle."""
    src = _write(fmt, tmp_path, scene, model, camera)
    if fmt in ("bev", "romp"):
        F.evil_npz(sorted(src.glob("*.npz"))[0], marker)
    elif fmt in ("4dhumans", "pymafx", "wham", "hybrik", "prompthmr"):
        src.write_bytes(F.evil_pickle(marker))
    elif fmt == "trace":  # npz: the 'outputs' object member pickles a code-executing object
        obj = np.empty((), dtype=object)
        obj[()] = {"cam_trans": F.Evil(marker)}
        np.savez(src, outputs=obj, imgpaths=np.array(["/data/00000000.jpg"]))
    elif fmt == "spec":
        (src / "spec_results" / "000000.pkl").write_bytes(F.evil_pickle(marker, protocol=2))
    elif fmt == "agora":
        sorted(src.glob("*.pkl"))[0].write_bytes(F.evil_pickle(marker, protocol=0))
    elif fmt == "multihmr":
        for p in src.iterdir():
            p.unlink()
        (src / "img_000.pkl").write_bytes(F.evil_pickle(marker))
    elif fmt == "slahmr":  # npz: an object member where arrays are expected
        results = next((src / "motion_chunks").glob("*_world_results.npz"))
        data = dict(np.load(results, allow_pickle=False))
        obj = np.empty((), dtype=object)
        obj[()] = F.Evil(marker)
        data["trans"] = obj
        np.savez(results, **data)
    elif fmt == "glamr":
        src.write_bytes(F.evil_pickle(marker))
    elif fmt == "gvhmr":  # torch archive: a code-running global in data.pkl
        src.write_bytes(T.torch_zip_bytes({"smpl_params_incam": T.Call(T.Global("os", "system"), (f"touch {marker}",))},
                                          name="hmr4d_results"))
    elif fmt == "comotion":  # torch archive: a code-running global where the parameters are
        src.write_bytes(T.torch_zip_bytes({"pose": T.Call(T.Global("os", "system"), (f"touch {marker}",))}, name="demo"))
    elif fmt == "tram":  # np.save of a dict: a code-running global beside the tensors
        T.np_save_tensors(src / "hps" / "hps_track_0.npy",
                          {"pred_rotmat": T.Call(T.Global("os", "system"), (f"touch {marker}",))})
    elif fmt in ("cliff", "bedlam"):  # npz: an object member where arrays are expected
        data = dict(np.load(src, allow_pickle=False))
        obj = np.empty((), dtype=object)
        obj[()] = F.Evil(marker)
        data["imgname"] = obj
        np.savez(src, **data)
    return src


@pytest.mark.parametrize("fmt", ALL)
def test_hostile_pickles_exit_2_without_running_code(fmt, tmp_path, scene, model, camera, runner):
    marker = tmp_path / "pwned"
    src = _hostile(fmt, tmp_path, marker, scene, model, camera)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", fmt, "--image-size", W, H))
    assert "refused to unpickle global" in text and "system" in text
    assert not marker.exists()
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("fmt", ALL)
@pytest.mark.parametrize("damage", ["truncate", "garbage"])
def test_corrupt_files_exit_2_with_one_line(fmt, damage, tmp_path, scene, model, camera, runner):
    src = _write(fmt, tmp_path, scene, model, camera)
    files = [src] if src.is_file() else sorted(p for p in src.rglob("*") if p.is_file())
    for file in files[:2]:
        if damage == "truncate":
            F.truncate(file, 0.6)
        else:
            file.write_bytes(np.random.default_rng(1).bytes(300))
    _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", fmt, "--image-size", W, H))


def test_wrong_types_inside_a_valid_pickle_exit_2(tmp_path, runner):
    src = tmp_path / "x_personId_0.pkl"
    src.write_bytes(pickle.dumps({"verts": "not an array", "joints": [[1, 2]]}))
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "agora"))
    assert "verts" in text


def test_from_converts_on_the_fly_for_calibrate_align_eval(tmp_path, bev_scene, model_path, runner):
    """`--from bev` reads the tool's own files directly: same results as importing first."""
    src = F.write_bev(tmp_path / "bev", bev_scene, (W, H))
    common = ["--from", "bev", "--smpl-model", model_path, "--image-size", str(W), str(H)]
    result = invoke(runner, "calibrate", src, *common, "--out", tmp_path / "cam.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["pitch_deg"] == pytest.approx(15.0, abs=1.5)
    assert invoke(runner, "calibrate", src, *common).exit_code == 2  # needs --out: the input is not a sequence
    result = invoke(runner, "align", "--in", src, *common, "--camera", tmp_path / "cam.yaml", "--out", tmp_path / "al", "-q")
    assert result.exit_code == 0, result.stderr
    assert len(open_sequence(tmp_path / "al")) == 6
    imported = tmp_path / "imported"
    import_sequence(src, imported, "bev", smpl_model=model_path, image_size=(W, H))
    result = invoke(runner, "eval", src, *common, "--gt", imported, "--out", tmp_path / "m", "--json")
    assert result.exit_code == 0, result.stderr
    row = json.loads(result.stdout)["predictions"][0]
    assert row["pred"] == str(src) and row["metrics"]["w_mpjpe"] == pytest.approx(0.0, abs=1e-6)
    assert invoke(runner, "eval", src, "--from", "nope", "--gt", imported).exit_code == 2


def _accept(fmt: str) -> list[str]:
    """``--accept-camera`` for the fixtures whose 2D points are drawn through their tool's own focal rule
    (4D-Humans 5000/256 x 640 = 12,500 px, PyMAF-X 5,000 px, on a 640-px image): the camera those pixels
    imply is no real lens, so calibrate flags it, and these tests of the chain's plumbing accept it."""
    return ["--accept-camera"] if fmt in ("4dhumans", "pymafx") else []


def _files_under(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (or the file itself) with the hash of its bytes."""
    files = [folder] if folder.is_file() else sorted(p for p in folder.rglob("*") if p.is_file())
    return {str(p.relative_to(folder) if p != folder else p.name): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in files}


def _refuse_temporary_dirs(monkeypatch) -> None:
    """Make creating a temporary directory (or file) outside a named output's folder fail the test."""
    real_mkdtemp, real_mkstemp = tempfile.mkdtemp, tempfile.mkstemp

    def mkdtemp(suffix=None, prefix=None, dir=None):
        if dir is None:
            raise AssertionError("a temporary directory was created")
        return real_mkdtemp(suffix, prefix, dir)  # beside an output: staging it (atomic writes)

    def mkstemp(suffix=None, prefix=None, dir=None, text=False):
        if dir is None:
            raise AssertionError("a temporary file was created")
        return real_mkstemp(suffix, prefix, dir, text)

    def temporary_directory(*args, **kwargs):
        raise AssertionError("a temporary directory was created")

    monkeypatch.setattr(tempfile, "mkdtemp", mkdtemp)
    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    monkeypatch.setattr(tempfile, "TemporaryDirectory", temporary_directory)


def _from_scene(model, camera, n_frames: int = 10):
    """Four people per frame, the third frame empty; ten frames make two chunks for align's workers."""
    rng = np.random.default_rng(7)
    return [[F.standing_person(model, camera, rng.uniform(-3, 3), -rng.uniform(6, 14), pid) for pid in range(4)]
            if i != 2 else [] for i in range(n_frames)]


def _ok(result):
    assert result.exit_code == 0, result.output
    return result


def _report(result) -> dict:
    """A --json eval result without the prediction's name (a path, which differs by design) and the tool's own
    world (WHAM's, GVHMR's: compared with the aligned sequence given alongside, which differs by design)."""
    rows = json.loads(result.stdout)["predictions"]
    return [{k: v for k, v in row.items() if k not in ("pred", "gt", "tool_world")} for row in rows]


# ---- each format imported once, then through the chain, as a sequence and with --from --------------
@dataclass(frozen=True)
class ImportedRun:
    """One format's files of :func:`_from_scene` and what rotavat made of them, all under ``root``."""

    root: Path
    src: Path  # the tool's files (under in/)
    imported: Path  # their import
    camera: Path  # calibrate of the import
    aligned: Path  # align --jobs 1 of the import with that camera
    metrics: Path  # eval of the import and the aligned import against the import
    report: list  # that eval's --json rows without their paths (_report): import, aligned
    model_path: Path  # the --smpl-model the format's parameters need
    size: list  # --image-size W H for the formats that do not store it, else []


def _per_format(fmts: list[str]) -> list:
    """``fmts`` as parameters whose tests run on one pytest-xdist worker per format (``make test`` runs
    ``--dist loadgroup``), where that format's :func:`imported_runs` entry is built once."""
    return [pytest.param(fmt, marks=pytest.mark.xdist_group(f"formats-{fmt}")) for fmt in fmts]


@pytest.fixture(scope="module")
def imported_runs(tmp_path_factory, model, camera, model_path, smplx_on_smpl_path, runner):
    """``imported_runs(fmt)``: that format's :class:`ImportedRun`, made on first use (one import and one
    calibrate, align and eval per format for the module's tests; none of them may make a temporary
    directory or file)."""
    built: dict[str, ImportedRun] = {}

    def imported_run(fmt: str) -> ImportedRun:
        if fmt not in built:
            built[fmt] = _imported_run(fmt, tmp_path_factory.mktemp(fmt), model, camera,
                                       _model_for(fmt, model_path, smplx_on_smpl_path), runner)
        return built[fmt]

    return imported_run


def _imported_run(fmt: str, root: Path, model, camera, model_path: Path, runner) -> ImportedRun:
    (root / "in").mkdir()
    src = _write(fmt, root / "in", _as_the_tool_places_it(fmt, _from_scene(model, camera), camera), model, camera)
    size = ["--image-size", W, H] if fmt in ("cliff", "multihmr", "wham", "comotion") else []
    imported, cam_yaml, aligned = root / "imported", root / "cam_imported.yaml", root / "al_imported"
    import_sequence(src, imported, fmt, smpl_model=model_path, image_size=(W, H) if size else None)
    with pytest.MonkeyPatch.context() as monkeypatch:
        _refuse_temporary_dirs(monkeypatch)
        _ok(invoke(runner, "calibrate", imported, "--out", cam_yaml, "--quiet"))
        _ok(invoke(runner, "align", "--in", imported, "--camera", cam_yaml, "-q", *_accept(fmt), "--out", aligned,
                   "--jobs", 1))
        report = _report(_ok(invoke(runner, "eval", imported, aligned, "--gt", imported, "--out", root / "m_imported",
                                    "--json")))
    return ImportedRun(root, src, imported, cam_yaml, aligned, root / "m_imported", report, model_path, size)


def _tree(root: Path) -> dict[str, str]:
    """Every path under ``root``: a file's hash, or 'dir'."""
    return {**{str(p.relative_to(root)): "dir" for p in root.rglob("*") if p.is_dir()}, **_files_under(root)}


@pytest.mark.parametrize("fmt", _per_format(ALL))
def test_every_format_goes_through_calibrate_align_eval_render(fmt, tmp_path, imported_runs, runner):
    """Each imported format is accepted by the whole chain (calibrate, align and eval of its
    :class:`ImportedRun`, then render); aligned feet end up on the calibrated ground, bodies moved rigidly."""
    run = imported_runs(fmt)
    seq, cam_yaml, aligned = run.imported, run.camera, run.aligned
    est, _ = read_camera_yaml(cam_yaml)
    with open(aligned / "people.csv") as rows:  # people align left unchanged (e.g. foot_above_horizon) say why there
        flagged = {(r["frame"], int(r["person_id"])) for r in csv.DictReader(rows) if r["flag"] and
                   r["flag"] != "implausible_stature"}
    seated_people = 0
    for frame in (f for f in open_sequence(aligned).frames() if f.n_people):  # the scene's third frame has no one
        feet, _ = foot_head_points(frame.data["vertices"])
        seated = np.array([(frame.name, int(i)) not in flagged for i in frame.person_ids], bool).reshape(-1)
        seated_people += int(seated.sum())
        np.testing.assert_allclose(est.height_above_ground(feet[seated]), 0.0, atol=1e-4)  # float32 storage
    assert seated_people >= 10
    before, after = json.loads((run.metrics / "metrics.json").read_text())["predictions"]
    people = sum(frame.n_people for frame in open_sequence(seq).frames())  # 4D-Humans skips its ghost track
    assert people >= 15 and before["matched"] == after["matched"] == people and before["metrics"]["w_mpjpe"] < 1e-3
    assert after["metrics"]["pa_mpjpe"] < 1.0  # RotAvat moves bodies rigidly (plus one scale)
    result = invoke(runner, "render", seq, aligned, "--camera", cam_yaml, "--renderer", "fallback", "--size", "160", "120",
                    "--out", tmp_path / "render", "--no-gif", "--no-glb", *_accept(fmt))
    assert result.exit_code == 0, result.output
    assert len(list((tmp_path / "render").glob("*.png"))) == 1


# ---- --from: the tool's output read as a sequence, each frame converted when read -----------------
@pytest.mark.parametrize("fmt", _per_format(ALL))
def test_from_gives_what_import_then_run_gives(fmt, tmp_path, imported_runs, runner, monkeypatch):
    """calibrate/align/eval --from FMT give byte for byte the camera.yaml, aligned sequence and metrics
    of importing first (:class:`ImportedRun`); no temporary directory or file is made, the input is never
    touched."""
    run = imported_runs(fmt)
    opts = ["--from", fmt, "--smpl-model", run.model_path, *run.size]
    before = _tree(run.root)  # the tool's files, their import and its results
    _refuse_temporary_dirs(monkeypatch)

    cam_from = tmp_path / "cam_from.yaml"
    _ok(invoke(runner, "calibrate", run.src, *opts, "--out", cam_from, "--quiet"))
    assert run.camera.read_bytes() == cam_from.read_bytes()

    camera_given = ["--camera", run.camera, "-q", *_accept(fmt)]
    _ok(invoke(runner, "align", "--in", run.src, *opts, *camera_given, "--out", tmp_path / "al_from", "--jobs", 2))
    aligned = _files_under(run.aligned)  # align --jobs 1 of the import
    assert len(aligned) >= 9 + 4 and _files_under(tmp_path / "al_from") == aligned  # frames, people.csv, meta, camera
    if fmt == "spec":  # the camera SPEC carries, used when no --camera is given
        _ok(invoke(runner, "align", "--in", run.imported, "--out", tmp_path / "al2_imported", "-q"))
        _ok(invoke(runner, "align", "--in", run.src, *opts, "--out", tmp_path / "al2_from", "-q"))
        assert _files_under(tmp_path / "al2_from") == _files_under(tmp_path / "al2_imported")

    gt = ["--gt", run.imported]
    report = _report(_ok(invoke(runner, "eval", run.src, *opts, *gt, "--out", tmp_path / "m_from", "--json")))
    assert run.report[:1] == report and report[0]["matched"] == 36  # the import's row
    if fmt in ("agora", "bedlam"):  # ground truth read with --gt-from
        gt_from = ["--gt", run.src, "--gt-from", fmt, "--smpl-model", run.model_path]
        again = _report(_ok(invoke(runner, "eval", run.imported, *gt_from, "--out", tmp_path / "m_gt_from", "--json")))
        assert again == run.report[:1]
    assert _tree(run.root) == before  # the input, the import and its results untouched, nothing added there
    outputs = ["cam_from.yaml", "al_from", "m_from"]
    outputs += ["al2_imported", "al2_from"] if fmt == "spec" else []
    outputs += ["m_gt_from"] if fmt in ("agora", "bedlam") else []
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(outputs)  # nothing else was written


@pytest.mark.parametrize("fmt", _per_format(ALL))
def test_imported_sequence_is_what_import_writes(fmt, imported_runs):
    """Frame by frame (in any order, twice), meta.yaml content and camera: those of import + open_sequence."""
    run = imported_runs(fmt)
    options = {"smpl_model": run.model_path, "image_size": (W, H) if run.size else None}
    written = open_sequence(run.imported)
    with imported_sequence(run.src, fmt, **options) as seq:
        assert seq.frame_names == written.frame_names and seq.image_size == written.image_size
        assert seq.intrinsics == written.intrinsics and seq.focal_kind == written.focal_kind
        assert seq.camera == written.camera and seq.camera_fit == written.camera_fit
        for name in [*reversed(seq.frame_names), *seq.frame_names]:
            ours, theirs = seq.read_frame(name), written.read_frame(name)
            assert ours.name == theirs.name and sorted(ours.data) == sorted(theirs.data)
            for key, value in theirs.data.items():
                assert type(ours.data[key]) is type(value) and ours.data[key].dtype == value.dtype, key
                np.testing.assert_array_equal(ours.data[key], value)
        assert seq.meta == written.meta  # complete once every frame was read (joints layout, warnings)
        assert list(seq.warnings) == written.meta["import"]["warnings"]


def test_from_shows_the_import_warnings_once_also_from_workers(tmp_path, model, camera, model_path, runner):
    """A person dropped while a worker builds its frame is reported once, after the command, as import reports it."""
    scene = _from_scene(model, camera)
    src = F.write_bev(tmp_path / "bev", scene, (W, H))
    bad = sorted(src.glob("*.npz"))[8]  # the tenth frame (the third is empty: no file), in align's second chunk
    results = unpickle.load_npz(bad)["results"].item()
    results["verts"][1, 5] = np.nan
    np.savez(bad, results=results)
    cam_yaml = tmp_path / "camera.yaml"
    write_camera_yaml(cam_yaml, camera.replace(focal_px=F.BEV_FOCAL_PX))
    imported = invoke(runner, "import", src, tmp_path / "imported", "--from", "bev")
    summary = invoke(runner, "import", src, tmp_path / "imp2", "--from", "bev", "--json")
    expected = json.loads(summary.stdout)["warnings"]
    assert any("inferred" in w for w in expected) and any("dropped 1 person" in w for w in expected)
    for args in (["align", "--in", src, "--camera", cam_yaml, "--out", tmp_path / "al", "--jobs", 2],
                 ["calibrate", src, "--out", tmp_path / "cam.yaml"]):
        result = _ok(invoke(runner, *args, "--from", "bev"))
        text = " ".join(result.stderr.split())
        for warning in expected:
            assert text.count(" ".join(f"warning: {warning}".split())) == 1, (warning, text)
        assert text.count("warning:") == len(expected) == " ".join(imported.stderr.split()).count("warning:")
    meta = open_sequence(tmp_path / "al").meta["import"]
    assert meta["warnings"] == expected  # the aligned sequence's meta.yaml keeps them, as after an import
    quiet = invoke(runner, "align", "--in", src, "--from", "bev", "--camera", cam_yaml, "--out", tmp_path / "al3",
                   "--quiet").stderr  # --quiet keeps warnings (stderr): each once
    assert " ".join(quiet.split()).count("warning:") == len(expected)


def test_imported_sequence_pickles_as_its_recipe(tmp_path, model, camera, model_path):
    """Sent to a worker, an imported sequence is a few kB (its recipe, not what was loaded); a process
    without the loaded source reads it again, once, and builds the same frames."""
    scene = _from_scene(model, camera, 5)
    src = F.write_phalp(tmp_path / "r.pkl", scene, (W, H), ghost=False)
    with imported_sequence(src, "4dhumans", smpl_model=model_path) as seq:
        blob = pickle.dumps(seq)
        assert len(blob) < 4000 < src.stat().st_size
        name = seq.frame_names[3]
        frame = seq.read_frame(name)
        recipe = seq.frame_source.recipe
        forget(recipe)  # as in a spawned worker: nothing loaded in this process
        assert not recipe_cached(recipe)
        copy = pickle.loads(blob)
        assert isinstance(copy.frame_source, ImporterSource) and copy.frame_source.recipe == recipe
        again = copy.read_frame(name)
        assert recipe_cached(recipe) and copy.frame_source.imported is pickle.loads(blob).frame_source.imported
        for key, value in frame.data.items():
            np.testing.assert_array_equal(again.data[key], value)
        assert copy.meta == seq.meta and copy.camera == seq.camera
        notes = copy.frame_notes([name])
        assert list(notes) == [3]
        seq.add_frame_notes(notes)  # what a worker found comes back (here: nothing to report)
        assert seq.warnings == ()
    assert not recipe_cached(recipe)


def test_from_errors_in_a_frame_exit_2_with_one_line(tmp_path, scene, model, camera, model_path, runner):
    """Malformed content met while a frame is converted (not when the source is opened) is one line, exit 2,
    and leaves no output."""
    src = F.write_bev(tmp_path / "bev", scene, (W, H))
    bad = sorted(src.glob("*.npz"))[1]
    results = unpickle.load_npz(bad)["results"].item()
    results["verts"] = "not an array"
    np.savez(bad, results=results)
    cam_yaml = tmp_path / "camera.yaml"
    write_camera_yaml(cam_yaml, camera.replace(focal_px=F.BEV_FOCAL_PX))
    for jobs in (1, 2):
        text = _one_line_error(invoke(runner, "align", "--in", src, "--from", "bev", "--image-size", W, H, "--camera",
                                      cam_yaml, "--out", tmp_path / "al", "--jobs", jobs))
        assert f"[{bad.stem}]" in text and "verts" in text
        assert not (tmp_path / "al").exists()


def test_a_spawned_worker_reads_the_source_once(tmp_path, model, camera, model_path):
    """Where workers are spawned (no inherited memory), each reads the source from its recipe once."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    scene = _from_scene(model, camera, 4)
    scene[1][0].verts_cam[3] = np.nan  # dropped with a warning when frame 1 is built
    src = F.write_multihmr(tmp_path / "mh", scene, image_size=(W, H))
    with imported_sequence(src, "multihmr", image_size=(W, H)) as seq:
        expected = [dict(seq.read_frame(name).data) for name in seq.frame_names]
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            first = pool.submit(F.read_in_worker, seq, seq.frame_names[:2]).result()
            second = pool.submit(F.read_in_worker, seq, seq.frame_names[2:]).result()
    assert first[0] is False and second[0] is True  # read by the first task, kept for the next
    assert first[1] == second[1] and first[2] == second[2]
    for got, want in zip(first[3] + second[3], expected):
        assert sorted(got) == sorted(want)
        for key in want:
            np.testing.assert_array_equal(got[key], want[key])
    dropped = [w for w in seq.warnings if "dropped 1 person" in w]
    assert len(dropped) == 1 and [w for notes in first[4].values() for w in notes.warnings] == dropped


def test_agora_sample_predictions_with_a_batch_axis_import_like_the_others(tmp_path, scene):
    """AGORA's own sample predictions carry 'joints' (1, 45, 2) and 'verts' (1, 6890, 3): the batch axis of one
    is dropped (they were refused: "'joints' must have 2 dimensions"); other shapes still are."""
    plain = import_sequence(F.write_agora(tmp_path / "a", scene, joints_2d=45), tmp_path / "plain", "agora")
    batched = import_sequence(F.write_agora(tmp_path / "b", scene, joints_2d=45, batch_axis=True), tmp_path / "batch",
                              "agora")
    assert batched["people"] == plain["people"] > 0
    for x, y in zip(open_sequence(tmp_path / "plain").frames(), open_sequence(tmp_path / "batch").frames()):
        for key in ("vertices", "keypoints_2d", "feet_2d"):
            if x.get(key) is not None:
                np.testing.assert_array_equal(x.data[key], y.data[key])
    bad = tmp_path / "c"
    F.write_agora(bad, scene[:1])
    victim = sorted(bad.glob("*.pkl"))[0]
    data = unpickle.load_file(victim)
    victim.write_bytes(pickle.dumps({**data, "joints": np.repeat(data["joints"][None], 2, axis=0)}, protocol=2))
    with pytest.raises(InputError, match=r"'joints' must have 2 dimensions \(or a leading batch axis of 1\)"):
        import_sequence(bad, tmp_path / "bad", "agora")
