"""SLAHMR and GLAMR importers: people stored in a world frame with a camera pose per frame come out in
each frame's camera (OpenCV, metres) with the tool's focal and its rule; visibility, track ids, the
files a run leaves, and refusals (one line naming the file)."""

from __future__ import annotations

import json
import pickle
import shutil

import _fixtures_slahmr_glamr as G
import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle
from rotavat_cli.geometry.camera import world_to_cam
from rotavat_cli.errors import InputError
from rotavat_cli.formats import detect_format, import_sequence
from rotavat_cli.formats import glamr as glamr_module
from rotavat_cli.formats import slahmr as slahmr_module
from rotavat_cli.formats.smpl import pose_from_body
from rotavat_cli.sequence import open_sequence

W, H = G.W, G.H
TOL_M = 1e-4  # float32 storage (~1e-6 m at 10 m) plus LBS round-off
TOL_PX = 0.02  # float32 pixels


def _assert_people(frame, truth, tol=TOL_M):
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in truth]), atol=tol)
    np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in truth]), atol=tol)
    assert frame.data["person_ids"].tolist() == [p.pid for p in truth]


def _one_line_error(result) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:")
    return lines[0]


# ---- the shared geometry ------------------------------------------------------------------------------
def test_world_to_cam_is_R_X_plus_t():
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z
    points = np.array([[[1.0, 2.0, 3.0]]])
    assert world_to_cam(points, R, np.array([0.5, 0.0, -1.0])).tolist() == [[[-1.5, 1.0, 2.0]]]


def test_pose_from_body_puts_the_root_first_and_rests_the_rest():
    pose = pose_from_body(np.array([[0.1, 0.2, 0.3]]), np.arange(63.0)[None], 52)
    assert pose.shape == (1, 52, 3) and pose[0, 0].tolist() == [0.1, 0.2, 0.3]
    assert pose[0, 21].tolist() == [60.0, 61.0, 62.0] and not pose[0, 22:].any()
    assert pose_from_body(np.zeros((0, 3)), np.zeros((0, 63)), 24).shape == (0, 24, 3)


# ---- SLAHMR --------------------------------------------------------------------------------------------
def test_slahmr_known_people_land_in_each_frames_camera(tmp_path, scene, model, smplh_path):
    run = G.write_slahmr(tmp_path / "run", scene, model)
    assert detect_format(run) == detect_format(run / "motion_chunks") == "slahmr"
    summary = import_sequence(run, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    seq = open_sequence(tmp_path / "out")
    # SLAHMR's default intrinsics (data/dataset.py CameraData): F = (W + H) / 2, principal point at the centre
    assert seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "slahmr"
    intr = seq.intrinsics.with_defaults()
    assert intr.focal_px == pytest.approx(560.0)
    assert intr.principal_point == (320.0, 240.0) and intr.image_size == (W, H)
    # frames named by image index: data_interval start 10 + seq_interval start 2
    assert seq.frame_names == ("000012", "000013", "000014")
    frames = list(seq.frames())
    assert [f.n_people for f in frames] == [2, 1, 0]
    for frame, truth in zip(frames[:2], scene[:2]):
        _assert_people(frame, truth)
        assert np.all(frame.data["joints"][:, 0, 2] > 6.0)  # 7-10 m in front of the camera, not in the world
    assert summary["joints_layout"] == "smpl24 (from SMPL-H: hands = middle1 joints)" and not summary["warnings"]
    assert frames[0].data["faces"].shape[1] == 3


def test_slahmr_takes_the_last_iteration_of_the_last_phase(tmp_path, scene, model, smplh_path):
    """A run folder also holds earlier iterations and phases (other people), phalp/ inputs and the prior."""
    run = G.write_slahmr(tmp_path / "run", scene, model, extras=True)
    chosen = run / "motion_chunks" / "demo_000060_world_results.npz"
    assert slahmr_module.find_results(run) == slahmr_module.find_results(run / "motion_chunks") == chosen
    for src in (run, run / "motion_chunks", chosen):
        out = tmp_path / f"out_{src.name}"
        import_sequence(src, out, "slahmr", smpl_model=smplh_path)
        _assert_people(next(open_sequence(out).frames()), scene[0])
    assert detect_format(run / "phalp") is None  # SLAHMR's inputs: no cameras
    prior = run / "motion_chunks" / "demo_000060_prior_results.npz"
    assert detect_format(prior) is None
    with pytest.raises(InputError, match="prior_results.npz: SLAHMR's motion-prior results are in the prior's"):
        import_sequence(prior, tmp_path / "out_prior", "slahmr", smpl_model=smplh_path)


def test_slahmr_leaves_out_occluded_frames_and_falls_back_to_track_mask(tmp_path, scene, model, smplh_path):
    run = G.write_slahmr(tmp_path / "run", scene, model, occluded=[(3, 1)])
    import_sequence(run, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    assert [f.n_people for f in open_sequence(tmp_path / "out").frames()] == [2, 0, 0]
    (run / "track_info.json").unlink()  # without it: each track over its interval, rows as ids
    summary = import_sequence(run, tmp_path / "out2", "slahmr", smpl_model=smplh_path)
    frames = list(open_sequence(tmp_path / "out2").frames())
    assert [f.name for f in frames] == ["000000", "000001", "000002"]
    assert [f.data["person_ids"].tolist() for f in frames] == [[0, 1], [0], []]
    np.testing.assert_allclose(frames[1].data["vertices"][0], scene[1][0].verts_cam, atol=TOL_M)
    assert any("track_mask" in w for w in summary["warnings"])


def test_slahmr_with_an_smpl_model_is_an_approximation_said_once(tmp_path, scene, model, model_path):
    run = G.write_slahmr(tmp_path / "run", scene, model)
    summary = import_sequence(run, tmp_path / "out", "slahmr", smpl_model=model_path)
    assert [w for w in summary["warnings"] if "approximation" in w] == [
        ("SLAHMR fits SMPL-H; --smpl-model SMPL_SYNTH.npz is SMPL: posed with its first 10 betas and hand joints "
         "at rest (an approximation)")]
    _assert_people(next(open_sequence(tmp_path / "out").frames()), scene[0])  # a body at rest: the same mesh
    assert summary["joints_layout"] == "smpl24"


def test_slahmr_given_intrinsics_are_assumed_without_a_rule(tmp_path, scene, model, smplh_path):
    run = G.write_slahmr(tmp_path / "run", scene, model, intrins=[900.0, 900.0, 320.0, 240.0])
    summary = import_sequence(run, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.focal_px == pytest.approx(900.0) and "focal_rule" not in seq.meta
    assert seq.focal_kind == "assumed"
    assert any("not SLAHMR's default (W + H) / 2 = 560.0 px" in w and "calibrate --focal" in w
               for w in summary["warnings"])


def test_slahmr_optimised_focal_is_written_per_frame(tmp_path, scene, model, smplh_path):
    """With opt_cams SLAHMR saves its per-frame focal ('cam_f', (T, 2)): each frame states its own."""
    run = G.write_slahmr(tmp_path / "run", scene, model)
    results = run / "motion_chunks" / "demo_000060_world_results.npz"
    data = dict(np.load(results, allow_pickle=False))
    data["cam_f"] = np.array([[600.0, 602.0], [610.0, 612.0], [620.0, 622.0]], np.float32)
    np.savez(results, **data)
    summary = import_sequence(run, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    seq = open_sequence(tmp_path / "out")
    assert "focal_length" not in seq.meta and "focal_rule" not in seq.meta and seq.focal_kind == "assumed"
    assert [float(f.data["focal_length"]) for f in seq.frames()] == [601.0, 611.0, 621.0]
    assert any("optimised per frame (opt_cams: 'cam_f')" in w for w in summary["warnings"])
    _assert_people(next(seq.frames()), scene[0])


def test_slahmr_refusals_name_the_file(tmp_path, scene, model, smplh_path, runner):
    run = G.write_slahmr(tmp_path / "run", scene, model)
    results = run / "motion_chunks" / "demo_000060_world_results.npz"
    text = _one_line_error(invoke(runner, "import", run, tmp_path / "out", "--from", "slahmr"))
    assert f"{results}: SLAHMR stores SMPL-H parameters only" in text and "--smpl-model" in text
    model23 = tmp_path / "m23.npz"
    data = dict(np.load(smplh_path, allow_pickle=False))
    data.update(kintree_table=data["kintree_table"][:, :23], J_regressor=data["J_regressor"][:23],
                weights=data["weights"][:, :23], posedirs=data["posedirs"][:, :, :9 * 22])
    np.savez(model23, **data)
    with pytest.raises(InputError, match="SLAHMR uses SMPL-H; --smpl-model m23.npz has 23 joints"):
        import_sequence(run, tmp_path / "out", "slahmr", smpl_model=model23)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty: no SLAHMR \\*_world_results.npz with cameras"):
        import_sequence(tmp_path / "empty", tmp_path / "out", "slahmr", smpl_model=smplh_path)
    info = json.loads((run / "track_info.json").read_text())
    info["tracks"]["9"] = {"index": 2, "vis_mask": [True] * 20}
    (run / "track_info.json").write_text(json.dumps(info))
    with pytest.raises(InputError, match="track_info.json: lists tracks \\[0, 1, 2\\], the results hold 2"):
        import_sequence(run, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    data = dict(np.load(results, allow_pickle=False))
    del data["cam_R"]
    np.savez(results, **data)
    with pytest.raises(InputError, match="missing cam_R"):
        import_sequence(results, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    assert not (tmp_path / "out").exists()


def test_slahmr_hostile_member_is_refused_without_running_code(tmp_path, scene, model, smplh_path):
    run = G.write_slahmr(tmp_path / "run", scene, model)
    results = run / "motion_chunks" / "demo_000060_world_results.npz"
    marker = tmp_path / "pwned"
    data = dict(np.load(results, allow_pickle=False))
    obj = np.empty((), dtype=object)
    obj[()] = F.Evil(marker)
    data["trans"] = obj
    np.savez(results, **data)
    with pytest.raises(InputError, match="refused to unpickle global"):
        import_sequence(results, tmp_path / "out", "slahmr", smpl_model=smplh_path)
    assert not marker.exists()


# ---- GLAMR ---------------------------------------------------------------------------------------------
def _glamr_keypoints(truth, focal=1000.0):
    return np.stack([F.project(G.body26fk_points(p), focal, (W / 2, H / 2)) for p in truth])


def test_glamr_known_people_land_in_each_frames_camera(tmp_path, scene, model_path):
    src = G.write_glamr(tmp_path / "out_dir" / "grecon" / "basketball_seed1.pkl", scene)
    assert detect_format(src) == detect_format(tmp_path / "out_dir") == "glamr"
    summary = import_sequence(tmp_path / "out_dir", tmp_path / "out", "glamr", smpl_model=model_path)
    seq = open_sequence(tmp_path / "out")
    # GLAMR's HybrIK (pose_est/hybrik_demo/demo.py): focal 1000 px on the full image, principal point at its centre
    assert seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "glamr"
    intr = seq.intrinsics.with_defaults()
    assert intr.focal_px == pytest.approx(1000.0)
    assert intr.principal_point == (320.0, 240.0) and intr.image_size == (W, H)
    assert seq.frame_names == ("000000", "000001", "000002")
    frames = list(seq.frames())
    assert [f.n_people for f in frames] == [2, 1, 0]
    for frame, truth in zip(frames[:2], scene[:2]):
        _assert_people(frame, truth)
        np.testing.assert_allclose(frame.data["keypoints_2d"], _glamr_keypoints(truth), atol=TOL_PX)
    assert summary["joints_layout"] == "smpl24" and not summary["warnings"]
    assert seq.meta["import"]["keypoints_2d_layout"].startswith("body26fk")


def test_glamr_keeps_detections_only_and_applies_the_root_scale(tmp_path, scene, model_path):
    src = G.write_glamr(tmp_path / "r_seed1.pkl", scene, occluded=[(3, 1)], scale={5: 1.1})
    import_sequence(src, tmp_path / "out", "glamr", smpl_model=model_path)
    frames = list(open_sequence(tmp_path / "out").frames())
    assert [f.n_people for f in frames] == [2, 0, 0]  # track 3 infilled in frame 1: not a detection
    p5 = scene[0][1]
    pelvis = p5.joints_cam[0]
    np.testing.assert_allclose(frames[0].data["vertices"][1], (p5.verts_cam - pelvis) * 1.1 + pelvis, atol=TOL_M)
    np.testing.assert_allclose(frames[0].data["vertices"][0], scene[0][0].verts_cam, atol=TOL_M)


@pytest.mark.parametrize("scale", [0.0, -1.1, float("nan")])
def test_glamr_root_scale_that_collapses_the_meshes_is_refused(tmp_path, scene, model_path, runner, scale):
    """scale = 0 would import every mesh collapsed onto its root (a negative one, turned inside out):
    one line naming the file, the person, the key and the frame; without a model the scale is unused."""
    src = G.write_glamr(tmp_path / "r_seed1.pkl", scene, scale={5: scale})
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "glamr",
                                  "--smpl-model", model_path))
    assert f"r_seed1.pkl [person 5]: 'scale' is {scale:g} in frame 0: GLAMR's root scale must be positive" in text
    assert not (tmp_path / "out").exists()
    assert import_sequence(src, tmp_path / "out", "glamr")["joints_layout"].startswith("pelvis")


def test_glamr_without_a_model_gives_the_pelvis_and_its_2d(tmp_path, scene):
    src = G.write_glamr(tmp_path / "r_seed1.pkl", scene)
    summary = import_sequence(src, tmp_path / "out", "glamr")
    assert not summary["has_vertices"] and summary["joints_layout"] == "pelvis (SMPL joint 0, root_trans_world)"
    assert any("--smpl-model" in w and "pelvis only" in w for w in summary["warnings"])
    frame = next(open_sequence(tmp_path / "out").frames())
    np.testing.assert_allclose(frame.data["joints"], np.stack([[p.joints_cam[0]] for p in scene[0]]), atol=TOL_M)
    np.testing.assert_allclose(frame.data["keypoints_2d"], _glamr_keypoints(scene[0]), atol=TOL_PX)


def test_glamr_other_intrinsics_are_assumed_without_a_rule(tmp_path, scene, model_path):
    src = G.write_glamr(tmp_path / "r_seed1.pkl", scene, focal=1200.0)
    summary = import_sequence(src, tmp_path / "out", "glamr", smpl_model=model_path)
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.focal_px == pytest.approx(1200.0) and "focal_rule" not in seq.meta
    assert any("not GLAMR's 1000 px" in w for w in summary["warnings"])
    _assert_people(next(seq.frames()), scene[0])  # the people are where GLAMR put them, whatever the focal


def test_glamr_refusals_name_the_file(tmp_path, scene, model_path, smplh_path, runner):
    out_dir = tmp_path / "out_dir"
    src = G.write_glamr(out_dir / "grecon" / "demo_seed1.pkl", scene)
    with pytest.raises(InputError, match="demo_seed1.pkl: GLAMR uses SMPL; --smpl-model SMPLH_SYNTH.npz has 52 joints"):
        import_sequence(src, tmp_path / "out", "glamr", smpl_model=smplh_path)
    shutil.copy(src, out_dir / "grecon" / "demo_seed2.pkl")
    text = _one_line_error(invoke(runner, "import", out_dir, tmp_path / "out", "--from", "glamr"))
    assert "expected one GLAMR result '*_seed*.pkl' in the folder or its grecon/, found 2 (one per seed" in text
    other = tmp_path / "list_seed1.pkl"
    other.write_bytes(pickle.dumps([1, 2, 3]))
    with pytest.raises(InputError, match="list_seed1.pkl: not a GLAMR result"):
        import_sequence(other, tmp_path / "out", "glamr")
    data = unpickle.load_file(src)
    data["person_data"][3]["smpl_pose"] = data["person_data"][3]["smpl_pose"][:, :60]
    src.write_bytes(pickle.dumps(data))
    with pytest.raises(InputError, match=r"\[person 3\]: 'smpl_pose' must be \[3, 69\]"):
        import_sequence(src, tmp_path / "out", "glamr", smpl_model=model_path)
    marker = tmp_path / "pwned"
    src.write_bytes(F.evil_pickle(marker))
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "glamr"))
    assert "refused to unpickle global" in text and not marker.exists()
    assert not (tmp_path / "out").exists()


def test_sniffers_claim_only_their_own_files(tmp_path, scene, model):
    """GLAMR's pickle is not a PHALP one and the reverse; SLAHMR's results are not BEDLAM or CLIFF npz."""
    glamr = G.write_glamr(tmp_path / "g_seed1.pkl", scene)
    phalp = F.write_phalp(tmp_path / "demo_video.pkl", scene, (W, H))
    assert detect_format(glamr) == "glamr" and detect_format(phalp) == "4dhumans"
    assert glamr_module.sniff(phalp) is None and slahmr_module.sniff(glamr) is None
    bedlam = F.write_bedlam(tmp_path / "scene.npz", scene)
    cliff = F.write_cliff(tmp_path / "demo_cliff_hr48.npz", scene, (W, H))
    assert slahmr_module.sniff(bedlam) is None and slahmr_module.sniff(cliff) is None
    assert glamr_module.sniff(bedlam) is None and glamr_module.sniff(tmp_path) == "glamr"  # the folder of one result
    run = G.write_slahmr(tmp_path / "run", scene, model)
    assert detect_format(run) == "slahmr" and glamr_module.sniff(run) is None
