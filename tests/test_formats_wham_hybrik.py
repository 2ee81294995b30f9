"""WHAM and HybrIK importers: each tool's conventions undone on hand-written files (a known person
comes out at its camera-frame position with the tool's focal), refusals as one line, and the
real files the tools wrote (skipped when ../shared/realfiles is absent)."""

from __future__ import annotations

import pickle
from pathlib import Path

import _fixtures_wham_hybrik as WH
import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle
from rotavat_cli.errors import InputError
from rotavat_cli.formats import detect_format, import_sequence, imported_sequence
from rotavat_cli.formats.hybrik import HYBRIK29_JOINT_NAMES, fitted_depth_factor_m, uvd_to_px
from rotavat_cli.bodies.landmarks import SMPL_JOINT_NAMES
from rotavat_cli.sequence import open_sequence, read_camera_yaml

W, H = 640, 480
TOL_M = 1e-4  # float32 storage of metre-scale coordinates plus LBS round-off
TOL_PX = 0.02  # float32 pixels
REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"


def _one_line_error(result) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert lines and lines[0].startswith("error:")
    return " ".join(lines)


def _real(name: str) -> Path:
    path = REALFILES / name
    if not path.exists():
        pytest.skip(f"../shared/realfiles/{name} not present")
    return path


# ---- WHAM ---------------------------------------------------------------------------------------
def test_wham_known_people_come_out_in_the_camera_frame(tmp_path, scene, model_path):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    assert detect_format(src) == "wham"
    summary = import_sequence(src, tmp_path / "out", "wham", smpl_model=model_path, image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    assert seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "cliff"
    intr = seq.intrinsics.with_defaults()
    assert intr.focal_px == pytest.approx(800.0)  # sqrt(640^2 + 480^2), WHAM's compute_cam_intrinsics
    assert intr.principal_point == (320.0, 240.0) and intr.image_size == (W, H)
    frames = list(seq.frames())
    assert [f.name for f in frames] == ["000000", "000001"]  # frame 2 had nobody: WHAM has no row for it
    assert frames[0].data["person_ids"].tolist() == [3, 5] and frames[1].data["person_ids"].tolist() == [3]
    for frame, truth in zip(frames, scene):
        np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in truth]), atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in truth]), atol=TOL_M)
        assert frame.data["faces"].shape[1] == 3
    assert np.all(frames[0].data["joints"][:, 0, 2] > 6.0)  # 7-10 m in front of the camera, not in WHAM's world
    info = seq.meta["import"]
    assert info["joints_layout"] == "smpl24" and info["model_vs_wham_verts_max_m"] < 1e-4
    assert seq.meta["tool_world"]["tool"] == "wham" and info["source_frames"] == [0, 1]  # its world: tests/test_tool_world.py
    assert summary["warnings"] == []


def test_wham_without_a_model_imports_its_meshes(tmp_path, scene):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    summary = import_sequence(src, tmp_path / "out", "wham", image_size=(W, H))
    frame = next(open_sequence(tmp_path / "out").frames())
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)
    assert "joints" not in frame.data and "faces" not in frame.data
    assert summary["has_vertices"] and any("no joints" in w for w in summary["warnings"])


def test_wham_warns_when_the_model_does_not_reproduce_its_meshes(tmp_path, scene, model_path):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    data = unpickle.load_file(src)
    data[np.int64(3)]["verts"] = data[np.int64(3)]["verts"] + np.float32(0.05)  # 5 cm off the posed model
    src.write_bytes(F.joblib_bytes(data))
    summary = import_sequence(src, tmp_path / "out", "wham", smpl_model=model_path, image_size=(W, H))
    assert any("8.7 cm from WHAM's own meshes" in w for w in summary["warnings"])  # |(5, 5, 5)| cm


def test_wham_needs_the_image_size(tmp_path, scene, runner):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out"))
    assert "wham_output.pkl" in text and "--image-size W H" in text


def _wham_damaged(path: Path, scene, damage: str) -> Path:
    WH.write_wham(path, scene)
    data = dict(unpickle.load_file(path))
    track = data[np.int64(3)]
    if damage == "no frame_ids":
        del track["frame_ids"]
    elif damage == "flat verts":
        track["verts"] = track["verts"][..., :2]
    elif damage == "short frame_ids":
        track["frame_ids"] = track["frame_ids"][:1]
    elif damage == "text key":
        data["person"] = data.pop(np.int64(5))
    elif damage == "short pose":
        track["pose"] = track["pose"][:, :69]
    path.write_bytes(F.joblib_bytes(data))
    return path


@pytest.mark.parametrize("damage, needle", [
    ("no frame_ids", "missing key 'frame_ids'"),
    ("flat verts", "'verts' must end with shape [3]"),
    ("short frame_ids", "'frame_ids' has 1 rows but 'verts' has 2"),
    ("text key", "track key 'person' is not an integer track id"),
    ("short pose", "'pose' must end with shape [72]"),
])
def test_wham_malformed_files_are_refused_in_one_line(damage, needle, tmp_path, scene, model_path, runner):
    src = _wham_damaged(tmp_path / "wham_output.pkl", scene, damage)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "wham", "--image-size", W, H,
                                  "--smpl-model", model_path))
    assert needle in text and "wham_output.pkl" in text


def test_wham_refuses_a_non_smpl_model(tmp_path, scene, model_path):
    model_file = tmp_path / "x.npz"
    data = dict(np.load(model_path, allow_pickle=False))
    data["kintree_table"], data["J_regressor"] = data["kintree_table"][:, :23], data["J_regressor"][:23]
    data["weights"], data["posedirs"] = data["weights"][:, :23], data["posedirs"][:, :, : 9 * 22]
    np.savez(model_file, **data)
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    with pytest.raises(InputError, match="WHAM uses SMPL"):
        import_sequence(src, tmp_path / "out", "wham", smpl_model=model_file, image_size=(W, H))


def test_sniffers_tell_wham_hybrik_phalp_and_agora_apart(tmp_path, scene):
    (tmp_path / "a").mkdir()
    assert detect_format(WH.write_wham(tmp_path / "wham_output.pkl", scene)) == "wham"
    assert detect_format(WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))) == "hybrik"
    assert detect_format(F.write_phalp(tmp_path / "demo.pkl", scene, (W, H))) == "4dhumans"
    agora = F.write_agora(tmp_path / "a", scene)
    assert detect_format(sorted(agora.glob("*.pkl"))[0]) == "agora"


def test_wham_from_reads_what_import_writes(tmp_path, scene, model_path):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    import_sequence(src, tmp_path / "out", "wham", smpl_model=model_path, image_size=(W, H))
    written = list(open_sequence(tmp_path / "out").frames())
    with imported_sequence(src, "wham", smpl_model=model_path, image_size=(W, H)) as seq:
        for frame, again in zip(written, seq.frames()):
            assert frame.name == again.name
            np.testing.assert_array_equal(frame.data["vertices"], again.data["vertices"])


def test_wham_real_output_imports(tmp_path, runner):
    """WHAM demo.py on a UTD-MHAD clip (640x480, one track, 42 frames): one person ~4.4 m away, in the image."""
    src = _real("wham_lalasray/wham_output.pkl")
    assert detect_format(src) == "wham"
    out = tmp_path / "seq"
    summary = import_sequence(src, out, "wham", image_size=(640, 480))
    assert summary["frames"] == 42 and summary["people"] == 42 and summary["focal_px"] == pytest.approx(800.0)
    frames = list(open_sequence(out).frames())
    verts = np.stack([f.data["vertices"][0] for f in frames]).astype(np.float64)
    depth = verts[..., 2].mean(axis=1)
    assert np.all((depth > 4.0) & (depth < 4.8))
    px = 800.0 * verts[..., :2] / verts[..., 2:3] + [320.0, 240.0]
    assert px.min() > 0 and px[..., 0].max() < 640 and px[..., 1].max() < 480  # WHAM's meshes lie on its image
    assert np.all(verts[:, 412, 1] < verts[:, [3216, 6617], 1].min(axis=1))  # SMPL crown above the toes: y down
    stature = verts[..., 1].max(axis=1) - verts[..., 1].min(axis=1)
    assert np.all((stature > 1.5) & (stature < 1.9))
    assert all(f.data["person_ids"].tolist() == [0] for f in frames)
    # One person standing at one depth cannot fix a camera: calibrate either refuses in one line or says so.
    result = invoke(runner, "calibrate", out, "--out", tmp_path / "cam.yaml")
    if result.exit_code == 2:
        _one_line_error(result)
    else:
        assert result.exit_code == 0 and "poorly determined" in result.output, result.output
        assert read_camera_yaml(tmp_path / "cam.yaml")[0].focal_px > 0


# ---- HybrIK -------------------------------------------------------------------------------------
def test_hybrik_joint_names_extend_smpl24():
    """SMPL's 24 in SMPL's order (HybrIK calls SMPL's 'head' joint 'jaw' and its hands 'thumb'), then the leaves."""
    renamed = {15: ("head", "jaw"), 22: ("left_hand", "left_thumb"), 23: ("right_hand", "right_thumb")}
    for i, name in enumerate(SMPL_JOINT_NAMES):
        assert HYBRIK29_JOINT_NAMES[i] == renamed.get(i, (name, name))[1] and renamed.get(i, (name,))[0] == name
    assert HYBRIK29_JOINT_NAMES[24:] == ("head", "left_middle", "right_middle", "left_bigtoe", "right_bigtoe")


def test_hybrik_known_person_with_its_own_focal(tmp_path, model, camera, model_path):
    """The demo's case: one tracked person per image, each image with its own box and so its own focal."""
    scene = WH.single_person_scene(model, camera)
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    assert detect_format(src) == "hybrik"
    summary = import_sequence(src, tmp_path / "out", "hybrik", smpl_model=model_path)
    seq = open_sequence(tmp_path / "out")
    assert seq.focal_kind == "assumed" and "focal_rule" not in seq.meta and "focal_length" not in seq.meta
    assert seq.intrinsics.image_size == (W, H) and seq.intrinsics.principal_point == (320.0, 240.0)
    assert seq.meta["import"]["depth_factor_m"] == 2.2 and seq.meta["import"]["joints_layout"] == "smpl24"
    frames = list(seq.frames())
    assert [f.name for f in frames] == ["walk-000001", "walk-000002", "walk-000003"]
    for frame, truth in zip(frames, scene):
        person = truth[0]
        focal = frame.intrinsics.focals_px(1)
        assert focal == pytest.approx([1000.0 / 256.0 * WH.hybrik_box_width(person)], rel=1e-9)  # 585.9 px
        np.testing.assert_allclose(frame.data["vertices"][0], person.verts_cam, atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"][0], person.joints_cam, atol=TOL_M)
        expected_px = F.project(WH.hybrik_joints29(person), focal[0], (W / 2, H / 2))
        np.testing.assert_allclose(frame.data["keypoints_2d"][0], expected_px, atol=TOL_PX)
        assert frame.data["person_ids"].tolist() == [0] and frame.data["faces"].shape[1] == 3
    assert summary["has_vertices"] and summary["warnings"] == []


def test_hybrik_without_a_model_gives_its_network_joints(tmp_path, model, camera):
    scene = WH.single_person_scene(model, camera)
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    summary = import_sequence(src, tmp_path / "out", "hybrik")
    frame = next(open_sequence(tmp_path / "out").frames())
    np.testing.assert_allclose(frame.data["joints"][0], scene[0][0].joints_cam, atol=TOL_M)  # first 24 of 29
    assert frame.data["keypoints_2d"].shape == (1, 29, 2) and "vertices" not in frame.data
    np.testing.assert_allclose(frame.data["heads_2d"], frame.data["keypoints_2d"][:, 24], atol=1e-4)  # head top
    assert frame.data["feet_2d"][0, 1] > frame.data["keypoints_2d"][0, 7:9, 1].max()  # below the ankles
    assert not summary["has_vertices"] and any("smpl-model" in w for w in summary["warnings"])


def test_hybrik_rows_of_one_image_are_one_frame(tmp_path, scene, model_path):
    """Two rows with the same img_path (two people): one frame, one focal per person, no track ids."""
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    import_sequence(src, tmp_path / "out", "hybrik", smpl_model=model_path)
    frames = list(open_sequence(tmp_path / "out").frames())
    assert [f.n_people for f in frames] == [2, 1]
    assert frames[0].intrinsics.focals_px(2) == pytest.approx([1000 / 256 * 180, 1000 / 256 * 200])
    assert "person_ids" not in frames[0].data
    np.testing.assert_allclose(frames[0].data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)


def test_hybrik_person_with_non_finite_joints_is_dropped_with_its_focal(tmp_path, scene):
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    data = unpickle.load_file(src)
    data["pred_xyz_29"][0, 5] = np.nan  # first image, first person (pid 3)
    src.write_bytes(pickle.dumps(data))
    summary = import_sequence(src, tmp_path / "out", "hybrik")
    frame = next(open_sequence(tmp_path / "out").frames())
    assert frame.n_people == 1 and frame.intrinsics.focals_px(1) == pytest.approx([1000 / 256 * 200])  # pid 5's
    np.testing.assert_allclose(frame.data["joints"][0], scene[0][1].joints_cam, atol=TOL_M)
    assert any("dropped 1 person" in w for w in summary["warnings"])


def test_hybrik_keeps_its_stored_image_size(tmp_path, model, camera):
    src = WH.write_hybrik(tmp_path / "res.pk", WH.single_person_scene(model, camera), (W, H))
    summary = import_sequence(src, tmp_path / "out", "hybrik", image_size=(1280, 960))
    assert summary["image_size"] == [W, H] and any("--image-size 1280x960 ignored" in w for w in summary["warnings"])


@pytest.mark.parametrize("depth_factor", [2.0, 2.5])
def test_hybrik_depth_factor_is_read_from_the_file(depth_factor, tmp_path, model, camera):
    """2.0 m: configs without BBOX_3D_SHAPE; any other value is used as fitted, with a warning."""
    scene = WH.single_person_scene(model, camera)
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H), depth_factor_m=depth_factor)
    summary = import_sequence(src, tmp_path / "out", "hybrik")
    seq = open_sequence(tmp_path / "out")
    assert seq.meta["import"]["depth_factor_m"] == pytest.approx(depth_factor, rel=1e-6)
    np.testing.assert_allclose(next(seq.frames()).data["joints"][0], scene[0][0].joints_cam, atol=TOL_M)
    assert any("none of HybrIK's configs" in w for w in summary["warnings"]) == (depth_factor == 2.5)


def test_fitted_depth_factor_recovers_the_scale():
    rng = np.random.default_rng(4)
    joints = rng.uniform(-0.8, 0.8, (3, 29, 3)) + [0.2, -0.1, 6.0]
    root = joints[:, 0]
    focal = np.array([500.0, 700.0, 900.0])
    uv = F.project(joints, focal[:, None, None], (320.0, 240.0))
    assert fitted_depth_factor_m((joints - root[:, None]) / 2.2, uv, root, focal, (320.0, 240.0)) == pytest.approx(2.2)


def test_uvd_to_px_is_the_demos_vis_2d():
    """demo_video.py: pts = uv * w + (cx, cy) with xyxy2xywh's centre and width."""
    uvd = np.array([[[0.0, 0.0, 0.1], [0.5, -0.25, 0.0]]])
    bbox = np.array([[100.0, 50.0, 300.0, 250.0]])
    assert uvd_to_px(uvd, bbox).tolist() == [[[200.0, 150.0], [300.0, 100.0]]]


def _hybrik_damaged(path: Path, scene, damage: str) -> Path:
    WH.write_hybrik(path, scene, (W, H))
    data = unpickle.load_file(path)
    if damage == "no transl":
        del data["transl"]
    elif damage == "24 joints":
        data["pred_xyz_29"] = data["pred_xyz_29"][:, :24]
    elif damage == "flat box":
        data["bbox"][:, 2] = data["bbox"][:, 0]
    elif damage == "moved uvd":
        data["pred_uvd"][..., 0] += 0.05
    elif damage == "hybrik-x":
        del data["pred_xyz_29"]
        data["f"] = np.full(len(data["transl"]), 1000.0)
    elif damage == "two sizes in one image":
        data["width"][0] = 800  # the first image's first person only
    elif damage == "zero width":
        data["width"][:] = 0
    elif damage == "bad thetas":
        data["pred_thetas"] = data["pred_thetas"][:, :100]
    path.write_bytes(pickle.dumps(data))
    return path


@pytest.mark.parametrize("damage, needle", [
    ("no transl", "missing key 'transl'"),
    ("24 joints", "'pred_xyz_29' must end with shape [29, 3]"),
    ("flat box", "'bbox' must hold boxes"),
    ("moved uvd", "does not reproject onto pred_uvd"),
    ("hybrik-x", "HybrIK-X (SMPL-X, demo_video_x.py)"),
    ("two sizes in one image", "the rows of image 'res_walk/raw_images/walk-000001.png' state different image sizes"),
    ("zero width", "'width'/'height' must be image sizes of 1 to 100000 px, got [0, 480]"),
    ("bad thetas", "'pred_thetas' must be 24 rotation matrices"),
])
def test_hybrik_malformed_files_are_refused_in_one_line(damage, needle, tmp_path, scene, model_path, runner):
    src = _hybrik_damaged(tmp_path / "res.pk", scene, damage)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "hybrik", "--smpl-model", model_path))
    assert needle in text and "res.pk" in text


def test_hybrik_quaternion_thetas_import_joints_only(tmp_path, model, camera, model_path):
    scene = WH.single_person_scene(model, camera)
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    data = unpickle.load_file(src)
    data["pred_thetas"] = np.zeros((len(data["transl"]), 96), np.float32)  # older HybrIK: 24 quaternions
    src.write_bytes(pickle.dumps(data))
    summary = import_sequence(src, tmp_path / "out", "hybrik", smpl_model=model_path)
    assert not summary["has_vertices"] and any("quaternions" in w for w in summary["warnings"])
    frame = next(open_sequence(tmp_path / "out").frames())
    np.testing.assert_allclose(frame.data["joints"][0], scene[0][0].joints_cam, atol=TOL_M)


def test_hybrik_without_pred_uvd_projects_its_joints(tmp_path, model, camera):
    scene = WH.single_person_scene(model, camera)
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H), drop=("pred_uvd",))
    summary = import_sequence(src, tmp_path / "out", "hybrik")
    frame = next(open_sequence(tmp_path / "out").frames())
    person = scene[0][0]
    expected = F.project(WH.hybrik_joints29(person), 1000 / 256 * WH.hybrik_box_width(person), (W / 2, H / 2))
    np.testing.assert_allclose(frame.data["keypoints_2d"][0], expected, atol=TOL_PX)
    assert any("no 'pred_uvd'" in w for w in summary["warnings"])


def test_hybrik_feeds_calibrate_and_align(tmp_path, model, camera, model_path, runner):
    """Per-person focals through the chain: the aligned feet end up on the calibrated ground."""
    rng = np.random.default_rng(5)
    scene = [[F.standing_person(model, camera, rng.uniform(-3, 3), -rng.uniform(6, 14), pid) for pid in range(5)]
             for _ in range(4)]
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    seq, cam_yaml, aligned = tmp_path / "seq", tmp_path / "camera.yaml", tmp_path / "aligned"
    import_sequence(src, seq, "hybrik", smpl_model=model_path)
    assert invoke(runner, "calibrate", seq, "--out", cam_yaml, "--quiet").exit_code == 0
    result = invoke(runner, "align", "--in", seq, "--camera", cam_yaml, "--out", aligned, "--quiet")
    assert result.exit_code == 0, result.output
    assert sum(f.n_people for f in open_sequence(aligned).frames()) == 20


# ---- HybrIK: one res.pk, several videos ----------------------------------------------------------
def _videos(model, camera, sizes=((384, 640), (1280, 720)), names=("IMG_6412", "dance")) -> list:
    """Two videos' (name, scene, image size), in the name order demo_video.py processes them: five people
    per image (rows of one image are its people), 4 and 3 images."""
    rng = np.random.default_rng(7)

    def scene(n_frames):
        return [[F.standing_person(model, camera, rng.uniform(-3, 3), -rng.uniform(6, 14), pid) for pid in range(5)]
                for _ in range(n_frames)]
    return [(names[0], scene(4), sizes[0]), (names[1], scene(3), sizes[1])]


def test_hybrik_two_videos_import_as_one_sequence_each_frame_with_its_size(tmp_path, model, camera, runner):
    """demo_video.py run on two videos with one --out-dir: one sequence, frame names keeping each video's
    name, each frame its own image_size and principal_point, and a note naming --video; calibrate and
    align refuse the mix of cameras in one line (was: the import refused, 'expected one positive image size')."""
    videos = _videos(model, camera)
    src = WH.write_hybrik_videos(tmp_path / "res.pk", videos)
    summary = import_sequence(src, tmp_path / "seq", "hybrik")
    seq = open_sequence(tmp_path / "seq")
    assert summary["frames"] == 7 and summary["people"] == 35 and summary["image_size"] is None
    assert "image_size" not in seq.meta and "principal_point" not in seq.meta
    assert seq.frame_names == ("IMG_6412-000001", "IMG_6412-000002", "IMG_6412-000003", "IMG_6412-000004",
                               "dance-000001", "dance-000002", "dance-000003")
    truths = [(frame, size) for _, scene, size in videos for frame in scene]
    for frame, (truth, size) in zip(seq.frames(), truths):
        assert frame.data["image_size"].tolist() == list(size)
        assert frame.data["principal_point"].tolist() == [size[0] / 2, size[1] / 2]
        np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in truth]), atol=TOL_M)
        focals = frame.intrinsics.focals_px(5)
        assert focals == pytest.approx([1000 / 256 * WH.hybrik_box_width(p) for p in truth], rel=1e-9)
        expected_px = F.project(np.stack([WH.hybrik_joints29(p) for p in truth]), focals[:, None, None],
                                (size[0] / 2, size[1] / 2))
        np.testing.assert_allclose(frame.data["keypoints_2d"], expected_px, atol=TOL_PX)
    assert seq.meta["import"]["videos"] == {"IMG_6412": "4 frames, 384x640", "dance": "3 frames, 1280x720"}
    (note,) = [w for w in summary["warnings"] if "videos" in w]
    assert note.startswith(f"{src}: holds 2 videos (IMG_6412: 4 frames, 384x640; dance: 3 frames, 1280x720; ")
    assert note.endswith(f"rotavat import {src} OUT --video NAME (IMG_6412, dance)")
    videos_said = "its frames come from 2 videos of one file (IMG_6412: 4 frames, 384x640; dance: 3 frames, 1280x720)"
    text = _one_line_error(invoke(runner, "calibrate", tmp_path / "seq", "--out", tmp_path / "cam.yaml"))
    assert f"seq: {videos_said}" in text and "res.pk res_dance --video dance" in text and "mkdir" not in text
    text = _one_line_error(invoke(runner, "calibrate", src, "--from", "hybrik", "--out", tmp_path / "cam.yaml"))
    assert f"res.pk: {videos_said}" in text and "res.pk res_dance --video dance" in text


def test_hybrik_video_option_gives_each_video_a_sequence_that_calibrates(tmp_path, model, camera, runner):
    videos = _videos(model, camera)
    src = WH.write_hybrik_videos(tmp_path / "res.pk", videos)
    for index, (name, scene, size) in enumerate(videos):
        out = tmp_path / name
        result = invoke(runner, "import", src, out, "--video", name, "--json")
        assert result.exit_code == 0, result.output
        seq = open_sequence(out)
        assert seq.intrinsics.image_size == size and seq.intrinsics.principal_point == (size[0] / 2, size[1] / 2)
        assert len(seq) == len(scene) and all(n.startswith(f"{name}-") for n in seq.frame_names)
        assert seq.meta["import"]["video"] == name and not any("videos" in w for w in seq.meta["import"]["warnings"])
        np.testing.assert_allclose(next(seq.frames()).data["joints"], np.stack([p.joints_cam for p in scene[0]]),
                                   atol=TOL_M)
        result = invoke(runner, "calibrate", out, "--out", tmp_path / f"{name}.yaml", "--quiet")
        assert result.exit_code == 0, result.output
        assert read_camera_yaml(tmp_path / f"{name}.yaml")[0].image_size == size
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "none", "--video", "IMG"))
    assert ("res.pk: holds no video named 'IMG' (--video); its videos: IMG_6412: 4 frames, 384x640; "
            "dance: 3 frames, 1280x720") in text


def test_hybrik_two_videos_of_one_size_are_named_too(tmp_path, model, camera):
    """Same image size: no per-frame keys, but the note still says two cameras and how to split them."""
    src = WH.write_hybrik_videos(tmp_path / "res.pk", _videos(model, camera, sizes=((W, H), (W, H)), names=("a", "b")))
    summary = import_sequence(src, tmp_path / "seq", "hybrik")
    seq = open_sequence(tmp_path / "seq")
    assert seq.intrinsics.image_size == (W, H) and "image_size" not in next(seq.frames()).data
    assert any("holds 2 videos" in w and "--video NAME (a, b)" in w for w in summary["warnings"])
    assert len(open_sequence(import_sequence(src, tmp_path / "b", "hybrik", video="b")["out"])) == 3


def test_video_option_is_refused_where_a_file_holds_one_video(tmp_path, scene, runner):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "wham", "--image-size", W, H,
                                  "--video", "a"))
    assert "--video selects one video of a file that holds several (hybrik); a WHAM output holds one" in text
    assert "--video" in invoke(runner, "import", "--help").output


def test_hybrik_real_output_imports(tmp_path, runner):
    """HybrIK demo_video.py on a 384x640 walking video (135 frames, one person)."""
    src = _real("hybrik/res.pk")
    assert detect_format(src) == "hybrik"
    out = tmp_path / "seq"
    summary = import_sequence(src, out, "hybrik")
    assert summary["frames"] == 135 and summary["people"] == 135 and summary["image_size"] == [384, 640]
    seq = open_sequence(out)
    assert seq.meta["import"]["depth_factor_m"] == 2.2  # the demo's hrw48 config (BBOX_3D_SHAPE 2200)
    raw = unpickle.load_file(src)
    frames = list(seq.frames())
    box_width = raw["bbox"][:, 2] - raw["bbox"][:, 0]
    focals = np.array([f.intrinsics.focals_px(1)[0] for f in frames])
    np.testing.assert_allclose(focals, 1000.0 / 256.0 * box_width)  # 1000 px per 256 px of box, per frame
    joints = np.stack([f.data["joints"][0] for f in frames]).astype(np.float64)
    kp = np.stack([f.data["keypoints_2d"][0] for f in frames]).astype(np.float64)
    np.testing.assert_allclose(focals[:, None, None] * joints[..., :2] / joints[..., 2:3] + [192.0, 320.0],
                               kp[:, :24], atol=0.01)  # the joints reproject onto HybrIK's own 2D
    assert np.all((joints[:, 0, 2] > 7.0) & (joints[:, 0, 2] < 10.0))
    head_to_toes = np.linalg.norm(raw["pred_xyz_29"][:, 24] - raw["pred_xyz_29"][:, 27:].mean(axis=1), axis=-1) * 2.2
    assert np.median(head_to_toes) == pytest.approx(1.65, abs=0.2)
    # joints only: feet and heads from the 2D keypoints (hybrik29 recipe: head-top leaf for the crown)
    assert seq.meta["import"]["feet_heads_from"].startswith("keypoints_2d, hybrik29")
    heads = np.stack([f.data["heads_2d"][0] for f in frames])
    np.testing.assert_allclose(heads, kp[:, 24], atol=1e-3)
    assert seq.meta["import"]["videos"] == {"IMG_6412": "135 frames, 384x640"}  # one video (frames IMG_6412-*)
    assert not any("videos" in w for w in summary["warnings"])
    result = invoke(runner, "calibrate", out, "--out", tmp_path / "cam.yaml")
    assert result.exit_code == 0, result.output
    assert read_camera_yaml(tmp_path / "cam.yaml")[0].focal_px > 0


def test_hybrik_real_video_and_another_in_one_res_pk(tmp_path, model, camera, runner):
    """The real 384x640 video (IMG_6412-*) and a 1280x720 one (dance-*) in one res.pk, as demo_video.py writes
    it when run on both with one --out-dir: one sequence with per-frame sizes, and --video IMG_6412 gives
    exactly the import of the real file alone."""
    real_src = _real("hybrik/res.pk")
    real = unpickle.load_file(real_src)
    dance = WH.hybrik_res_db(_videos(model, camera)[1][1], (1280, 720), video="dance")
    src = tmp_path / "res.pk"
    src.write_bytes(pickle.dumps({key: np.concatenate([np.asarray(real[key]), dance[key]]) for key in real}))
    summary = import_sequence(src, tmp_path / "both", "hybrik")
    assert summary["frames"] == 138 and summary["image_size"] is None
    assert any(w.startswith(f"{src}: holds 2 videos (IMG_6412: 135 frames, 384x640; dance: 3 frames, 1280x720")
               for w in summary["warnings"])
    both = open_sequence(tmp_path / "both")
    sizes = {tuple(both.read_frame(n).data["image_size"].tolist()) for n in both.frame_names if n.startswith("dance")}
    assert sizes == {(1280, 720)} and both.read_frame("IMG_6412-000135").data["image_size"].tolist() == [384, 640]
    one = invoke(runner, "import", src, tmp_path / "one", "--video", "IMG_6412", "--quiet")
    assert one.exit_code == 0, one.output
    import_sequence(real_src, tmp_path / "alone", "hybrik")
    one, alone = open_sequence(tmp_path / "one"), open_sequence(tmp_path / "alone")
    assert one.frame_names == alone.frame_names and one.intrinsics == alone.intrinsics
    for a, b in zip(one.frames(), alone.frames()):
        assert sorted(a.data) == sorted(b.data)
        for key in a.data:
            np.testing.assert_array_equal(a.data[key], b.data[key])
