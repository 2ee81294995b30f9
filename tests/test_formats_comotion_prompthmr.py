"""CoMotion (``<input>.pt``, a torch archive of SMPL rows per tracked person-frame) and PromptHMR (``results.pkl``,
a joblib pickle of SMPL-X tracks, their camera and one shared world) imported without torch or joblib: people at
their known camera-frame positions with their track ids, the method's focal declared as its guess (rules
``comotion`` and ``tram``), PromptHMR's own world kept beside the camera frame, and bad input refused in one line.

The files are written in each tool's structure (``tests/_fixtures_comotion_prompthmr.py``); the generic tests of
every format (``tests/test_formats.py``) cover them too."""

from __future__ import annotations

import _fixtures_comotion_prompthmr as CP
import _fixtures_torch as T
import _format_fixtures as F
import numpy as np
import pytest
from _cli import error_text, invoke

from rotavat_cli.errors import InputError
from rotavat_cli.formats import detect_format, import_sequence, imported_sequence
from rotavat_cli.formats.smpl import lbs
from rotavat_cli.metrics.tool_world import angles_deg, their_up_cam
from rotavat_cli.sequence import open_sequence

W, H = 640, 480
TOL_M = 1e-4  # float32 parameters and storage of metre-scale coordinates, plus LBS round-off
TOL_PX = 1e-3  # float32 boxes of a few hundred pixels


def _elbow(n: int, joints: int) -> np.ndarray:
    """(n, joints - 1, 3) body pose: the left elbow (joint 18) bent 60 degrees, the rest at rest."""
    pose = np.zeros((n, joints - 1, 3))
    pose[:, 17] = [0.0, 0.0, np.deg2rad(60.0)]
    return pose


# ---- CoMotion ------------------------------------------------------------------------------------------------
def test_comotion_tracks_come_out_in_the_camera_frame(tmp_path, scene, model, model_path):
    """Rows at frame_idx 2 and 3 (nobody tracked before): four frames, the first two empty; ids kept; meshes are
    SMPL(pose, betas) + trans of the file's rows (the bent elbow included), in CoMotion's 2 max(W, H) camera."""
    src = CP.write_comotion(tmp_path / "comotion_out" / "walk.pt", scene[:2], body_pose=_elbow(1, 24)[0], frame_offset=2)
    assert detect_format(src) == "comotion"
    summary = import_sequence(src, tmp_path / "out", "comotion", smpl_model=model_path, image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    intr = seq.intrinsics.with_defaults()
    assert seq.meta["source"] == "comotion" and seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "comotion"
    assert intr.focal_px == 2 * 640 and intr.principal_point == (320.0, 240.0) and intr.image_size == (W, H)
    frames = list(seq.frames())
    assert [f.name for f in frames] == ["000000", "000001", "000002", "000003"] and summary["people"] == 3
    assert [f.n_people for f in frames] == [0, 0, 2, 1]
    assert [f.data["person_ids"].tolist() for f in frames[2:]] == [[3, 5], [3]]
    rows = CP.comotion_rows(scene[:2], body_pose=_elbow(1, 24)[0], frame_offset=2)
    for frame in frames[2:]:
        pick = np.flatnonzero(rows["frame_idx"] == int(frame.name))
        verts, joints = lbs(model, rows["betas"][pick], rows["pose"][pick], rows["trans"][pick])
        np.testing.assert_allclose(frame.data["vertices"], verts, atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"], joints, atol=TOL_M)
        np.testing.assert_allclose(frame.data["smpl_global_orient"], rows["pose"][pick, :3], atol=1e-6)
        np.testing.assert_allclose(frame.data["smpl_transl"], rows["trans"][pick], atol=1e-6)
        np.testing.assert_allclose(frame.data["smpl_pelvis"], joints[:, 0], atol=TOL_M)
        truth = scene[int(frame.name) - 2]  # the bent elbow moves the forearm; the rest is where the scene put it
        moved = np.linalg.norm(frame.data["vertices"] - np.stack([p.verts_cam for p in truth]), axis=-1)
        assert moved.max() > 0.05 and np.median(moved) < 1e-4


def test_comotion_one_image_is_one_frame_named_as_it(tmp_path, scene, model_path):
    """run_detection's file (detections of one image, no ids): one frame, named as the image the file is named after."""
    src = CP.write_comotion_image(tmp_path / "out_dir" / "IMG_0042.pt", scene[0], (W, H), 2 * 640)
    assert detect_format(src) == "comotion"
    with imported_sequence(src, "comotion", smpl_model=model_path, image_size=(W, H)) as seq:
        assert seq.frame_names == ("IMG_0042",) and seq.meta["import"]["person_ids"] is None
        frame = seq.read_frame("IMG_0042")
    assert "person_ids" not in frame.data
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)


def test_comotion_needs_the_image_size_and_an_smpl_model(tmp_path, scene, model_path, smplx_on_smpl_path, runner):
    src = CP.write_comotion(tmp_path / "c" / "demo.pt", scene)
    text = error_text(invoke(runner, "import", src, tmp_path / "out", "--smpl-model", model_path))
    assert "demo.pt" in text and "--image-size W H" in text
    size = ["--image-size", W, H]
    assert "--smpl-model SMPL_NEUTRAL.npz" in error_text(invoke(runner, "import", src, tmp_path / "out", *size))
    text = error_text(invoke(runner, "import", src, tmp_path / "out", *size, "--smpl-model", smplx_on_smpl_path))
    assert "CoMotion uses SMPL;" in text and "(need 24)" in text
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("change, needle", [
    ({"pose": np.zeros((3, 69), np.float32)}, "'pose' must end with shape [72]"),
    ({"frame_idx": np.array([0, -1, 1])}, "negative frame indices"),
    ({"id": np.array([3, 5], np.int64)}, "'id' has 2 rows, 'pose' 3"),
    ({"frame_idx": np.array([0.0, 0.0, 1.0])}, "'frame_idx' must be a numeric array, got float64"),
])
def test_comotion_malformed_rows_are_refused_naming_the_key(change, needle, tmp_path, scene, model_path):
    rows = {**CP.comotion_rows(scene), **change}
    src = tmp_path / "bad.pt"
    src.write_bytes(T.torch_zip_bytes({k: T.tensor(v) for k, v in rows.items()}, name="bad"))
    with pytest.raises(InputError, match="bad.pt") as error:
        import_sequence(src, tmp_path / "out", "comotion", smpl_model=model_path, image_size=(W, H))
    assert needle in str(error.value)


# ---- PromptHMR -------------------------------------------------------------------------------------------------
def test_prompthmr_people_come_out_in_the_camera_frame(tmp_path, scene, camera, smplx_on_smpl_path):
    """smplx_cam posed on SMPL-X (the bent elbow included) is the camera frame, not the image model's estimates;
    ids, the empty third frame, est_calib's focal (rule tram) and the tracker's boxes are kept."""
    body = _elbow(2, 22)
    src = CP.write_prompthmr(tmp_path / "results" / "walk", scene, camera, (W, H), body_pose=body)
    assert detect_format(src) == "prompthmr" and detect_format(src.parent) == "prompthmr"
    summary = import_sequence(src.parent, tmp_path / "out", "prompthmr", smpl_model=smplx_on_smpl_path)
    seq = open_sequence(tmp_path / "out")
    intr = seq.intrinsics.with_defaults()
    assert seq.meta["source"] == "prompthmr" and seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "tram"
    assert intr.focal_px == 640.0 and intr.principal_point == (320.0, 240.0) and intr.image_size == (W, H)
    assert summary["joints_layout"].startswith("smpl24 (from SMPL-X") and summary["warnings"] == []
    frames = list(seq.frames())
    assert [f.n_people for f in frames] == [2, 1, 0]
    assert [f.data["person_ids"].tolist() for f in frames[:2]] == [[3, 5], [3]]
    model = F.load_model(smplx_on_smpl_path)
    results = CP.prompthmr_results(scene, camera, (W, H), body_pose=body)
    for index, frame in enumerate(frames[:2]):
        tracks = [results["people"][pid] for pid in frame.data["person_ids"]]
        rows = [int(np.flatnonzero(t["frames"] == index)[0]) for t in tracks]
        cam = [{k: t["smplx_cam"][k][r] for k in ("pose", "shape", "trans")} for t, r in zip(tracks, rows)]
        pose = np.zeros((len(cam), 55, 3))
        pose[:, :22] = np.stack([c["pose"][:66] for c in cam]).reshape(-1, 22, 3)
        verts, _ = lbs(model, np.stack([c["shape"] for c in cam]), pose, np.stack([c["trans"] for c in cam]))
        np.testing.assert_allclose(frame.data["vertices"], verts, atol=TOL_M)
        np.testing.assert_allclose(frame.data["boxes_2d"], np.stack([t["bboxes"][r] for t, r in zip(tracks, rows)]),
                                   atol=TOL_PX)
        moved = np.linalg.norm(frame.data["vertices"] - np.stack([p.verts_cam for p in scene[index]]), axis=-1)
        assert moved.max() > 0.05 and np.median(moved) < 1e-4  # the forearm moved; the body is where the scene put it
        np.testing.assert_allclose(frame.data["smpl_body_pose"][:, 17 * 3:18 * 3], body[0, 17:18].reshape(1, 3)
                                   .repeat(len(cam), axis=0), atol=1e-6)


def test_prompthmr_world_is_kept_beside_the_camera_frame(tmp_path, scene, camera, smplx_on_smpl_path):
    """The fixture's world is the scene's true world (Y up, z toward the camera, as PromptHMR builds its own): the
    kept pelvis lands where the camera's world puts each person, and the tool's up in the camera frame is the
    camera's."""
    src = CP.write_prompthmr(tmp_path / "r", scene, camera, (W, H))
    import_sequence(src, tmp_path / "out", "prompthmr", smpl_model=smplx_on_smpl_path)
    seq = open_sequence(tmp_path / "out")
    world = seq.meta["tool_world"]
    assert world["tool"] == "prompthmr" and world["up_axis"] == [0.0, 1.0, 0.0] and world["units"] == "m"
    for index, frame in enumerate(list(seq.frames())[:2]):
        people = sorted(scene[index], key=lambda p: p.pid)
        np.testing.assert_allclose(frame.data["tool_world_pelvis"],
                                   np.stack([CP.world_pelvis(p, camera) for p in people]), atol=TOL_M)
        np.testing.assert_allclose(frame.data["tool_cam_global_orient"], np.stack([p.pose[0] for p in people]),
                                   atol=1e-6)
        np.testing.assert_allclose(frame.data["tool_world_global_orient"],
                                   np.stack([CP.world_root(p, camera) for p in people]), atol=1e-6)
        up = their_up_cam(frame.data["tool_cam_global_orient"], frame.data["tool_world_global_orient"], world["up_axis"])
        assert np.all(angles_deg(up, camera.up_cam) < 1e-4)
    assert frame.data["tool_world_pelvis"][0, 1] == pytest.approx(0.94, abs=0.01)  # a pelvis 0.94 m above the ground


def test_prompthmr_without_its_world_keeps_none(tmp_path, scene, camera, smplx_on_smpl_path):
    src = CP.write_prompthmr(tmp_path / "r", scene, camera, (W, H), world=False)
    import_sequence(src, tmp_path / "out", "prompthmr", smpl_model=smplx_on_smpl_path)
    seq = open_sequence(tmp_path / "out")
    assert "tool_world" not in seq.meta and seq.meta["import"]["tool_world"].startswith("none")
    assert not any(key.startswith("tool_") for key in next(seq.frames()).data)


def test_prompthmr_original_video_size_carries_its_intrinsics(tmp_path, scene, camera, smplx_on_smpl_path):
    """PromptHMR ran on half-size frames (its 896 px resize): --image-size of the original video doubles the focal,
    principal point and boxes; the 3D does not change. Another shape keeps them, and says so."""
    src = CP.write_prompthmr(tmp_path / "r", scene, camera, (W // 2, H // 2))
    small = import_sequence(src, tmp_path / "small", "prompthmr", smpl_model=smplx_on_smpl_path)
    assert small["image_size"] == [320, 240] and small["focal_px"] == 320.0
    full = import_sequence(src, tmp_path / "full", "prompthmr", smpl_model=smplx_on_smpl_path, image_size=(W, H))
    seq = open_sequence(tmp_path / "full")
    assert full["image_size"] == [W, H] and seq.intrinsics.focal_px == 640.0 and seq.meta["focal_rule"] == "tram"
    assert seq.intrinsics.principal_point == (320.0, 240.0)
    assert any("carried to --image-size 640x480 (x 2)" in w for w in full["warnings"])
    for a, b in zip(open_sequence(tmp_path / "small").frames(), seq.frames()):
        np.testing.assert_array_equal(a.data["vertices"], b.data["vertices"])
        np.testing.assert_allclose(b.data["boxes_2d"], 2 * a.data["boxes_2d"], atol=TOL_PX)
    other = import_sequence(src, tmp_path / "other", "prompthmr", smpl_model=smplx_on_smpl_path, image_size=(640, 360))
    assert other["focal_px"] == 320.0 and any("kept as the principal point" in w for w in other["warnings"])


def test_prompthmr_focal_off_its_rule_and_a_moving_camera_are_said(tmp_path, scene, camera, smplx_on_smpl_path):
    src = CP.write_prompthmr(tmp_path / "r", scene, camera, (W, H), focal=555.0, moving=True)
    summary = import_sequence(src, tmp_path / "out", "prompthmr", smpl_model=smplx_on_smpl_path)
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.focal_px == 555.0 and "focal_rule" not in seq.meta and seq.focal_kind == "assumed"
    assert any("not est_calib's max(W, H) = 640.0 px" in w for w in summary["warnings"])
    assert any("found the camera moving (up to 0.50 m" in w for w in summary["warnings"])
    assert seq.meta["import"]["camera_motion"]["max_translation_m"] == pytest.approx(0.5)


def test_prompthmr_needs_an_smplx_model(tmp_path, scene, camera, model_path, runner):
    src = CP.write_prompthmr(tmp_path / "r", scene, camera, (W, H))
    assert "--smpl-model SMPLX_NEUTRAL.npz" in error_text(invoke(runner, "import", src, tmp_path / "out"))
    text = error_text(invoke(runner, "import", src, tmp_path / "out", "--smpl-model", model_path))
    assert "results.pkl" in text and "PromptHMR uses SMPL-X;" in text and "(need 55)" in text


@pytest.mark.parametrize("damage, needle", [
    (lambda r: r["people"][3]["smplx_cam"].pop("trans"), "[track 3]: missing key 'trans'"),
    (lambda r: r["people"][5].update(frames=np.array([0, 1])), "[track 5]: 'smplx_cam.pose' has 1 rows, 'frames' 2"),
    (lambda r: r["people"][3].update(frames=np.array([0, -1])), "[track 3]: 'frames' must hold distinct, non-negative"),
    (lambda r: r["camera"].update(img_center=[0.0, 240.0]), "'camera.img_center' must be two positive pixel"),
    (lambda r: r["people"].update({"x": r["people"][3]}), "track key 'x' is not an integer track id"),
    (lambda r: r["people"][5].pop("smplx_world"), "some tracks have PromptHMR's world (smplx_world) and others not"),
])
def test_prompthmr_malformed_results_are_refused_naming_the_key(damage, needle, tmp_path, scene, camera,
                                                               smplx_on_smpl_path):
    results = CP.prompthmr_results(scene, camera, (W, H))
    damage(results)
    src = tmp_path / "results.pkl"
    src.write_bytes(F.joblib_bytes(results, compress=0))
    with pytest.raises(InputError, match="results.pkl") as error:
        import_sequence(src, tmp_path / "out", "prompthmr", smpl_model=smplx_on_smpl_path)
    assert needle in str(error.value)


def test_prompthmr_reads_a_compressed_dump_alike(tmp_path, scene, camera, smplx_on_smpl_path):
    """joblib.dump(..., compress=3) of the same results imports the same frames (the demo dumps uncompressed)."""
    results = CP.prompthmr_results(scene, camera, (W, H))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "results.pkl").write_bytes(F.joblib_bytes(results, compress=0))
    (tmp_path / "b" / "results.pkl").write_bytes(F.joblib_bytes(results, compress=3))
    for name in ("a", "b"):
        import_sequence(tmp_path / name, tmp_path / f"out_{name}", "prompthmr", smpl_model=smplx_on_smpl_path)
    for x, y in zip(open_sequence(tmp_path / "out_a").frames(), open_sequence(tmp_path / "out_b").frames()):
        np.testing.assert_array_equal(x.data["vertices"], y.data["vertices"])
