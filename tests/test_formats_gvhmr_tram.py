"""GVHMR (``hmr4d_results.pt``, a torch archive) and TRAM (``camera.npy`` + ``hps/hps_track_{k}.npy``,
dicts of torch tensors) imported without torch: people at their known camera-frame positions, the
method's focal declared as its guess, and hostile or broken files refused in one line (exit 2).

The files are written by hand in each tool's structure (``tests/_fixtures_torch.py``); the real
GVHMR output in ``../shared/realfiles`` is imported when present."""

from __future__ import annotations

from pathlib import Path

import _fixtures_torch as T
import _format_fixtures as F
import numpy as np
import pytest
from _cli import error_text, invoke

from rotavat_cli.errors import InputError
from rotavat_cli.formats import detect_format, import_sequence, imported_sequence
from rotavat_cli.formats.smpl import lbs
from rotavat_cli.sequence import open_sequence

W, H = 640, 480
TOL_M = 1e-4  # float32 parameters and storage of metre-scale coordinates, plus LBS round-off
REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"


@pytest.fixture(scope="module")
def track(scene):
    """GVHMR's one person per frame: three placements of the scene's people."""
    return [scene[0][0], scene[1][0], scene[0][1]]


# ---- GVHMR ---------------------------------------------------------------------------------------
def test_gvhmr_person_comes_out_in_the_camera_frame(tmp_path, smplx_on_smpl_path, track, runner):
    src = T.write_gvhmr(tmp_path / "outputs" / "demo" / "tennis", track, (W, H))
    assert detect_format(src) == "gvhmr" and detect_format(src.parent) == "gvhmr"
    summary = import_sequence(src.parent, tmp_path / "out", "gvhmr", smpl_model=smplx_on_smpl_path)
    seq = open_sequence(tmp_path / "out")
    intr = seq.intrinsics.with_defaults()
    assert seq.meta["source"] == "gvhmr" and seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "cliff"
    assert intr.image_size == (W, H)  # twice K_fullimg's principal point
    assert intr.focal_px == pytest.approx(np.hypot(W, H), rel=1e-7)  # estimate_K, stored in float32
    assert intr.principal_point == pytest.approx((W / 2, H / 2), abs=1e-9)
    frames = list(seq.frames())
    assert len(frames) == 3 and summary["has_vertices"] and summary["joints_layout"].startswith("smpl24 (from SMPL-X")
    for frame, person in zip(frames, track):
        assert frame.data["person_ids"].tolist() == [0]
        np.testing.assert_allclose(frame.data["vertices"][0], person.verts_cam, atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"][0], person.joints_cam, atol=TOL_M)  # SMPL-24, hands = middle1
        assert frame.data["faces"].shape[1] == 3 and frame.data["joints"][0, 0, 2] > 6.0  # 7-10 m ahead, z forward
    assert invoke(runner, "info", tmp_path / "out").exit_code == 0


def test_gvhmr_body_pose_is_the_21_body_joints_after_the_root(tmp_path, smplx_on_smpl_path, track):
    """body_pose (63) poses SMPL-X joints 1-21; the bent elbow moves the arm and nothing is read from elsewhere."""
    model = F.load_model(smplx_on_smpl_path)
    bent = T.bent_elbow_pose(len(track))
    src = T.write_gvhmr(tmp_path / "g", track, (W, H), body_pose=bent)
    with imported_sequence(src, "gvhmr", smpl_model=smplx_on_smpl_path) as seq:
        frame = seq.read_frame(seq.frame_names[1])
    full = np.zeros((1, 55, 3))
    full[0, 0], full[0, 1:22] = track[1].pose[0], bent[1]
    verts, _ = lbs(model, track[1].betas[None], full, track[1].transl[None])
    np.testing.assert_allclose(frame.data["vertices"][0], verts[0], atol=TOL_M)
    moved = np.linalg.norm(frame.data["vertices"][0] - track[1].verts_cam, axis=1)
    assert moved.max() > 0.05 and np.median(moved) < 1e-4  # the forearm moved, the body did not


def test_gvhmr_focal_not_from_its_rule_is_kept_without_a_rule(tmp_path, smplx_on_smpl_path, track):
    K = np.array([[700.0, 0, W / 2], [0, 700.0, H / 2], [0, 0, 1]])
    src = T.write_gvhmr(tmp_path / "g", track, (W, H), K=K)
    summary = import_sequence(src, tmp_path / "out", "gvhmr", smpl_model=smplx_on_smpl_path, image_size=(W + 2, H))
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.focal_px == 700.0 and "focal_rule" not in seq.meta and seq.focal_kind == "assumed"
    assert seq.intrinsics.image_size == (W + 2, H) and seq.intrinsics.principal_point == (W / 2, H / 2)
    assert any("not GVHMR's estimate_K" in w for w in summary["warnings"])
    assert any("differs from the 640x480 of K_fullimg" in w for w in summary["warnings"])


def test_gvhmr_needs_an_smplx_model(tmp_path, model_path, track):
    src = T.write_gvhmr(tmp_path / "g", track, (W, H))
    with pytest.raises(InputError, match=r"hmr4d_results\.pt: GVHMR stores SMPL-X parameters only \(no joints, no 2D "
                                         r"keypoints\): pass --smpl-model"):
        import_sequence(src, tmp_path / "out", "gvhmr")
    with pytest.raises(InputError, match=r"SMPL-X; --smpl-model SMPL_SYNTH\.npz has 24 joints \(need 55\)"):
        import_sequence(src, tmp_path / "out", "gvhmr", smpl_model=model_path)


def test_gvhmr_hostile_archive_exits_2_without_running_code(tmp_path, smplx_on_smpl_path, track, runner):
    marker = tmp_path / "pwned"
    results = T.gvhmr_results(track, (W, H))
    results["net_outputs"] = T.Call(T.Global("os", "system"), (f"touch {marker}",))
    src = tmp_path / "hmr4d_results.pt"
    src.write_bytes(T.torch_zip_bytes(results, name="hmr4d_results"))
    text = error_text(invoke(runner, "import", src, tmp_path / "out", "--from", "gvhmr", "--smpl-model", smplx_on_smpl_path))
    assert "torch archive: refused to unpickle global 'os.system'" in text
    assert not marker.exists() and not (tmp_path / "out").exists()


@pytest.mark.parametrize("damage", ["truncate", "garbage", "drop_storage"])
def test_gvhmr_broken_archive_exits_2_with_one_line(tmp_path, smplx_on_smpl_path, track, runner, damage):
    src = T.write_gvhmr(tmp_path / "g", track, (W, H))
    if damage == "truncate":
        F.truncate(src, 0.6)
    elif damage == "garbage":
        src.write_bytes(np.random.default_rng(1).bytes(300))
    else:
        src.write_bytes(T.torch_zip_bytes(T.gvhmr_results(track, (W, H)), name="hmr4d_results", drop=("data/3",)))
    text = error_text(invoke(runner, "import", src, tmp_path / "out", "--from", "gvhmr", "--smpl-model", smplx_on_smpl_path))
    assert str(src) in text
    if damage != "garbage":
        assert "torch archive" in text


@pytest.mark.skipif(not (REALFILES / "gvhmr").is_dir(), reason="shared real files absent")
def test_real_gvhmr_output_imports(tmp_path, smplx_on_smpl_path):
    """GVHMR's own demo output (812x720 video, 312 frames, one person), posed on the synthetic SMPL-X body."""
    src = REALFILES / "gvhmr" / "tennis" / "hmr4d_results.pt"
    assert detect_format(src) == "gvhmr"
    summary = import_sequence(src, tmp_path / "out", "gvhmr", smpl_model=smplx_on_smpl_path)
    assert summary["frames"] == 312 and summary["people"] == 312
    # the synthetic body stands on its soles at its origin, SMPL-X hangs 0.35 m below its own: 1.3 m low, named
    # against GVHMR's own crops (tests/test_model_fit.py)
    (finding,) = summary["warnings"]
    assert "the meshes project 399 px (0.74 person heights) below their own person boxes" in finding
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.image_size == (812, 720) and seq.meta["focal_rule"] == "cliff"
    assert seq.intrinsics.focal_px == pytest.approx(np.hypot(812, 720), rel=1e-7)
    first = seq.read_frame(seq.frame_names[0])
    transl = np.array([-0.0539887, 0.41385126, 4.1407447])  # smpl_params_incam.transl[0] (torch.load agrees)
    assert abs(first.data["joints"][0, 0, 2] - transl[2]) < 0.3  # the pelvis ~4 m ahead, where GVHMR put it


# ---- TRAM ----------------------------------------------------------------------------------------
def test_tram_people_come_out_in_the_camera_frame(tmp_path, model_path, scene, runner):
    src = T.write_tram(tmp_path / "results" / "demo", scene, (W, H))
    assert detect_format(src) == "tram" and detect_format(src / "hps") == "tram"
    summary = import_sequence(src, tmp_path / "out", "tram", smpl_model=model_path)
    seq = open_sequence(tmp_path / "out")
    intr = seq.intrinsics.with_defaults()
    assert seq.meta["source"] == "tram" and seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "tram"
    assert intr.image_size == (W, H) and intr.focal_px == max(W, H) and intr.principal_point == (W / 2, H / 2)
    frames = list(seq.frames())
    assert [f.n_people for f in frames] == [2, 1, 0] and summary["empty_frames"] == 1
    # tracks are numbered longest first: person 3 (two frames) is k = 0, person 5 is k = 1
    assert frames[0].data["person_ids"].tolist() == [0, 1] and frames[1].data["person_ids"].tolist() == [0]
    for frame, truth in zip(frames[:2], scene[:2]):
        np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in truth]), atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in truth]), atol=TOL_M)
    assert summary["warnings"] == [] and seq.meta["import"]["camera_motion"] == {"max_translation_m": 0.0,
                                                                                  "max_rotation_deg": 0.0}
    assert invoke(runner, "info", tmp_path / "out").exit_code == 0


def _jpeg_header(width: int, height: int) -> bytes:
    """The start of a baseline JPEG: SOI, then an SOF0 segment with the image size."""
    return b"\xff\xd8\xff\xc0\x00\x11\x08" + height.to_bytes(2, "big") + width.to_bytes(2, "big") + b"\x03" + bytes(9)


def test_tram_searched_focal_moving_camera_and_images(tmp_path, model_path, scene):
    src = T.write_tram(tmp_path / "demo", scene, (W, H), focal=900.0, moving=True)
    (src / "images").mkdir()
    for i in range(3):
        (src / "images" / f"{i:04d}.jpg").write_bytes(_jpeg_header(W, H))
    summary = import_sequence(src, tmp_path / "out", "tram", smpl_model=model_path)
    seq = open_sequence(tmp_path / "out")
    assert seq.intrinsics.focal_px == 900.0 and "focal_rule" not in seq.meta and seq.focal_kind == "assumed"
    assert "SLAM reprojection search" in seq.meta["import"]["focal_from"]
    assert seq.frame_names == ("0000", "0001", "0002") and seq.meta["import"]["image_size_from"] == "images/ header"
    assert any("camera moving (up to 0.50 m, 0.0 deg)" in w for w in summary["warnings"])


def test_tram_needs_an_smpl_model(tmp_path, smplx_on_smpl_path, scene):
    src = T.write_tram(tmp_path / "demo", scene, (W, H))
    with pytest.raises(InputError, match=r"demo: TRAM stores SMPL parameters only \(no joints, no 2D keypoints\)"):
        import_sequence(src, tmp_path / "out", "tram")
    with pytest.raises(InputError, match=r"SMPL; --smpl-model SMPLX_SYNTH\.npz has 55 joints \(need 24\)"):
        import_sequence(src, tmp_path / "out", "tram", smpl_model=smplx_on_smpl_path)


def test_tram_track_with_repeated_frames_is_refused(tmp_path, model_path, scene):
    src = T.write_tram(tmp_path / "demo", scene, (W, H))
    eye = np.broadcast_to(np.eye(3, dtype=np.float32), (2, 24, 3, 3)).copy()
    T.np_save_tensors(src / "hps" / "hps_track_1.npy", {
        "pred_rotmat": T.tensor(eye), "pred_shape": T.tensor(np.zeros((2, 10), np.float32)),
        "pred_trans": T.tensor(np.ones((2, 1, 3), np.float32)), "frame": T.tensor(np.array([1, 1]))})
    with pytest.raises(InputError, match=r"hps_track_1\.npy: 'frame' must hold distinct, non-negative image indices"):
        import_sequence(src, tmp_path / "out", "tram", smpl_model=model_path)


def test_tram_hostile_track_exits_2_without_running_code(tmp_path, model_path, scene, runner):
    marker = tmp_path / "pwned"
    src = T.write_tram(tmp_path / "demo", scene, (W, H))
    T.np_save_tensors(src / "hps" / "hps_track_0.npy", {"pred_rotmat": T.Call(T.Global("os", "system"), (f"touch {marker}",))})
    text = error_text(invoke(runner, "import", src, tmp_path / "out", "--from", "tram", "--smpl-model", model_path))
    assert "hps_track_0.npy: refused to unpickle global 'os.system'" in text
    assert not marker.exists() and not (tmp_path / "out").exists()


@pytest.mark.parametrize("damage", ["truncate", "garbage"])
def test_tram_broken_files_exit_2_with_one_line(tmp_path, model_path, scene, runner, damage):
    for name in ("camera.npy", "hps/hps_track_1.npy"):
        src = T.write_tram(tmp_path / name.replace("/", "_"), scene, (W, H))
        file = src / name
        if damage == "truncate":
            F.truncate(file, 0.6)
        else:
            file.write_bytes(np.random.default_rng(1).bytes(300))
        text = error_text(invoke(runner, "import", src, tmp_path / "out", "--from", "tram", "--smpl-model", model_path))
        assert file.name in text
