"""PyMAF-X and TRACE importers: each tool's conventions undone on hand-written files (a known person comes
out at its camera-frame position with the tool's focal and focal kind), refusals as one line, and the
real files of other tools not claimed (skipped when ../shared/realfiles is absent)."""

from __future__ import annotations

from pathlib import Path

import _body_models as B
import _fixtures_pymafx_trace as PT
import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle
from rotavat_cli.errors import InputError
from rotavat_cli.formats import detect_format, import_sequence, imported_sequence, pymafx, trace
from rotavat_cli.formats.keypoints import recipe_for
from rotavat_cli.formats.smpl import SMPLX_TO_SMPL24
from rotavat_cli.sequence import open_sequence

W, H = 640, 480
TOL_M = 1e-4  # float32 storage of metre-scale coordinates plus LBS round-off
TOL_PX = 0.02  # float32 pixels
REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"


@pytest.fixture(scope="module")
def smplx_path(tmp_path_factory) -> Path:
    return B.write_synthetic_smplx(tmp_path_factory.mktemp("model") / "SMPLX_SYNTH.npz")


@pytest.fixture(scope="module")
def smplx_model(smplx_path):
    return F.load_model(smplx_path)


def _one_line_error(result) -> str:
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def _people_frames(out: Path):
    return [f for f in open_sequence(out).frames() if f.n_people]


# ---- PyMAF-X ---------------------------------------------------------------------------------------
def test_pymafx_known_person_with_an_smpl_model(tmp_path, scene, model_path):
    """SMPL model: the SMPL-topology mesh + orig_cam_t, joints regressed from it; 5000 px at the image centre."""
    (tmp_path / "dancer").mkdir()
    src = PT.write_pymafx(tmp_path / "dancer" / "output.pkl", scene, (W, H), offsets={"smplx_verts": 1.0})
    assert detect_format(src) == "pymafx" and detect_format(src.parent) == "pymafx"
    summary = import_sequence(src.parent, tmp_path / "out", "pymafx", smpl_model=model_path)  # the demo's folder
    seq = open_sequence(tmp_path / "out")
    intr = seq.intrinsics.with_defaults()
    assert seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "pymafx"
    assert intr.focal_px == 5000.0 and intr.principal_point == (320.0, 240.0)
    assert intr.image_size == (W, H) and seq.meta["import"]["image_size_from"].startswith("recovered from orig_cam")
    *warnings, fit = summary["warnings"]  # people 7-9 m away drawn with PyMAF-X's 5000 px: outside the image
    assert summary["joints_layout"].startswith("smpl24") and warnings == [] and "outside the 640x480 image" in fit
    assert list(seq.frame_names) == ["000000", "000001"]  # a video: frames by index, up to the last detection
    for frame, truth in zip(_people_frames(tmp_path / "out"), [f for f in scene if f]):
        np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in truth]), atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in truth]), atol=TOL_M)
        assert frame.data["faces"].shape[1] == 3 and frame.get("person_ids") is None  # detections are not tracked
        kp = frame.data["keypoints_2d"]
        expected = F.project(np.stack([p.joints_cam[:17] for p in truth]), 5000.0, (W / 2, H / 2))
        np.testing.assert_allclose(kp[..., :2], expected, atol=TOL_PX * 5)
        np.testing.assert_array_equal(kp[..., 2], 1.0)
        assert np.all(frame.data["joints"][:, 0, 2] > 6.0)  # 7-10 m in front, z forward


def test_pymafx_smplx_model_poses_kinematic_joints_on_the_smplx_mesh(tmp_path, smplx_model, smplx_path, camera):
    spots = [(-1.0, -7.0), (1.5, -9.0)]
    people = [F.standing_person(smplx_model, camera, x, z, pid) for pid, (x, z) in enumerate(spots)]
    src = PT.write_pymafx(tmp_path / "output.pkl", [people], (W, H), offsets={"verts": 1.0})
    summary = import_sequence(src, tmp_path / "out", "pymafx", smpl_model=smplx_path)
    (frame,) = _people_frames(tmp_path / "out")
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in people]), atol=TOL_M)
    expected = np.stack([p.joints_cam[list(SMPLX_TO_SMPL24)] for p in people])  # (2, 24, 3): hands = middle1
    np.testing.assert_allclose(frame.data["joints"], expected, atol=TOL_M)
    assert frame.data["faces"].max() < smplx_model.n_verts
    *warnings, fit = summary["warnings"]  # people 7-9 m away drawn with PyMAF-X's 5000 px: outside the image
    assert summary["joints_layout"].startswith("smpl24 (posed") and warnings == [] and "outside the 640x480 image" in fit


def test_pymafx_without_a_model_keeps_the_smplx_mesh_and_spin_joints(tmp_path, scene):
    src = PT.write_pymafx(tmp_path / "output.pkl", scene, (W, H), stems="images", offsets={"verts": 1.0})
    summary = import_sequence(src, tmp_path / "out", "pymafx")
    seq = open_sequence(tmp_path / "out")
    assert list(seq.frame_names) == ["img_0000", "img_0001"]  # an image folder: frames by image stem
    assert seq.meta["import"]["joints_layout"].startswith("spin49") and seq.meta["import"]["root_joint"] == 8
    assert any("SPIN joints" in w for w in summary["warnings"])
    frame = seq.read_frame("img_0000")
    truth = scene[0]
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in truth]), atol=TOL_M)
    np.testing.assert_allclose(frame.data["joints"][:, 8], np.stack([p.joints_cam[0] for p in truth]), atol=TOL_M)
    assert frame.data["joints"].shape == (2, 49, 3) and "faces" not in frame.data


def test_pymafx_image_size_given_needed_or_disputed(tmp_path, scene):
    src = PT.write_pymafx(tmp_path / "output.pkl", scene, (W, H), with_cams=False)
    with pytest.raises(InputError, match="pass --image-size W H"):
        import_sequence(src, tmp_path / "out", "pymafx")
    summary = import_sequence(src, tmp_path / "out", "pymafx", image_size=(W, H))
    assert summary["image_size"] == [W, H]
    src = PT.write_pymafx(tmp_path / "cams.pkl", scene, (W, H))
    summary = import_sequence(src, tmp_path / "out2", "pymafx", image_size=(800, 600))
    assert open_sequence(tmp_path / "out2").intrinsics.principal_point == (400.0, 300.0)
    assert any("differs from the 640x480 of 'orig_cam'" in w for w in summary["warnings"])


def test_pymafx_reads_files_whose_smplx_params_are_cuda_tensors(tmp_path, scene, model_path):
    """The demo pickles its smplx_params as torch (CUDA) tensors: read inertly, unused, the rest imported."""
    src = PT.write_pymafx(tmp_path / "output.pkl", scene, (W, H), torch_params=True)
    assert pymafx.sniff(src) == "pymafx" and b"torch._utils" in src.read_bytes()
    shapes = _load_pymafx(src)["smplx_params"][0]["shape"]  # (3, 10) numpy, from the pickled tensor
    np.testing.assert_allclose(shapes, np.stack([p.betas for p in scene[0] + scene[1]]))
    import_sequence(src, tmp_path / "out", "pymafx", smpl_model=model_path)
    frame = _people_frames(tmp_path / "out")[0]
    np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=TOL_M)


def test_pymafx_refusals(tmp_path, scene, runner):
    src = PT.write_pymafx(tmp_path / "output.pkl", scene, (W, H))
    marker = tmp_path / "pwned"
    src.write_bytes(F.evil_pickle(marker))
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o2", "--from", "pymafx"))
    assert "refused to unpickle global" in text and not marker.exists()
    src.write_bytes(F.joblib_bytes({"orig_cam_t": np.zeros((0, 3))}, compress=0))
    assert "holds no detections" in _one_line_error(invoke(runner, "import", src, tmp_path / "o3", "--from", "pymafx"))
    (tmp_path / "d").mkdir()
    text = _one_line_error(invoke(runner, "import", tmp_path / "d", tmp_path / "o4", "--from", "pymafx"))
    assert "no PyMAF-X output.pkl" in text


def test_pymafx_mesh_of_another_topology_than_the_model_is_refused(tmp_path, scene, smplx_path, runner):
    src = PT.write_pymafx(tmp_path / "output.pkl", scene, (W, H))
    data = _load_pymafx(src)
    data["smplx_verts"] = data["smplx_verts"][:, :100]
    src.write_bytes(F.joblib_bytes(data, compress=0))
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o", "--from", "pymafx", "--smpl-model",
                                  smplx_path))
    assert "has 6591 vertices but 'smplx_verts' has 100" in text


def _load_pymafx(path: Path) -> dict:
    from rotavat_cli import unpickle

    return dict(unpickle.load_file(path))


# ---- TRACE -----------------------------------------------------------------------------------------
def test_trace_known_person_with_an_smpl_model(tmp_path, scene, model_path):
    """j3d + cam_trans in the camera frame, meshes posed onto them, 548/512 S on the padded square, track ids."""
    results = tmp_path / "TRACE_results"
    results.mkdir()
    src = PT.write_trace(results / "trace_demo.npz", scene, (W, H))
    np.savez(results / "trace_demo_tracking.npz", tracking={}, kp3ds={})  # trace2 writes it beside; never read
    (results / "notes.npz").write_bytes(b"not a zip")  # an unrelated broken file does not stop detection
    assert detect_format(src) == "trace" and detect_format(results) == "trace"
    summary = import_sequence(results, tmp_path / "out", "trace", smpl_model=model_path)
    seq = open_sequence(tmp_path / "out")
    intr = seq.intrinsics.with_defaults()
    focal, pp = 548.0 / 512 * 640, (320.0, 320.0 - 80)
    assert seq.focal_kind == "assumed" and seq.meta["focal_rule"] == "trace"
    assert intr.focal_px == pytest.approx(focal) and intr.principal_point == pp and intr.image_size == (W, H)
    assert any("fitted from pj2d" in w for w in summary["warnings"])
    assert list(seq.frame_names) == ["00000000", "00000001", "00000002"]  # every frame of imgpaths, the last empty
    frames = _people_frames(tmp_path / "out")
    assert [f.data["person_ids"].tolist() for f in frames] == [[3, 5], [3]]
    for frame, truth in zip(frames, [f for f in scene if f]):
        np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in truth]), atol=TOL_M)
        np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in truth]), atol=TOL_M)
        proj = F.project(np.stack([p.joints_cam for p in truth]), focal, pp)
        np.testing.assert_allclose(frame.data["keypoints_2d"][:, :24], proj, atol=TOL_PX)
        assert frame.data["faces"].shape[1] == 3


def test_trace_image_size_from_the_frames_headers_with_odd_padding(tmp_path, model, camera):
    size = (641, 480)  # S = 641: 161 rows of padding, 80 on top, 81 below
    scene = [[F.standing_person(model, camera, 0.5, -8.0, 1)]]
    src = PT.write_trace(tmp_path / "clip.npz", scene, size, frame_dir=str(tmp_path / "frames"))
    PT.png_header(tmp_path / "frames" / "00000000.jpg", size)
    summary = import_sequence(src, tmp_path / "out", "trace")
    seq = open_sequence(tmp_path / "out")
    assert seq.meta["import"]["image_size_from"].startswith("header of") and summary["image_size"] == [641, 480]
    assert seq.intrinsics.principal_point == (320.5, 320.5 - 80)
    (frame,) = _people_frames(tmp_path / "out")
    proj = F.project(scene[0][0].joints_cam, 548.0 / 512 * 641, (320.5, 240.5))
    np.testing.assert_allclose(frame.data["keypoints_2d"][0, :24], proj, atol=TOL_PX)


def test_trace_without_a_model_imports_joints_and_2d(tmp_path, scene):
    src = PT.write_trace(tmp_path / "trace_demo.npz", scene, (W, H))
    summary = import_sequence(src, tmp_path / "out", "trace", image_size=(W, H))
    assert not summary["has_vertices"] and any("--smpl-model" in w for w in summary["warnings"])
    (frame, _) = _people_frames(tmp_path / "out")
    np.testing.assert_allclose(frame.data["joints"], np.stack([p.joints_cam for p in scene[0]]), atol=TOL_M)
    kp = frame.data["keypoints_2d"]
    if recipe_for("trace44") is None:
        pytest.skip("keypoints.py has no trace44 recipe yet: feet_2d / heads_2d come with it")
    np.testing.assert_allclose(frame.data["feet_2d"], kp[:, list(PT.TRACE_FEET)].mean(axis=1), atol=TOL_PX)
    np.testing.assert_allclose(frame.data["heads_2d"], kp[:, PT.TRACE_HEAD_TOP], atol=TOL_PX)


def test_trace_refusals(tmp_path, scene, smplx_path, runner):
    src = PT.write_trace(tmp_path / "t.npz", scene, (W, H))
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o1", "--from", "trace", "--smpl-model",
                                  smplx_path))
    assert "TRACE uses SMPL" in text
    content = unpickle.load_npz(src)
    outputs = content["outputs"].item()
    outputs["reorganize_idx"] = outputs["reorganize_idx"] + 5
    np.savez(src, outputs=outputs, imgpaths=content["imgpaths"])
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o2", "--from", "trace", "--image-size", W, H))
    assert "'reorganize_idx' refers to frames outside 'imgpaths'" in text
    outputs["reorganize_idx"] = outputs["reorganize_idx"] - 5
    del outputs["j3d"]
    np.savez(src, outputs=outputs, imgpaths=content["imgpaths"])
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o3", "--from", "trace", "--image-size", W, H))
    assert "missing key 'j3d'" in text
    marker = tmp_path / "pwned"
    obj = np.empty((), dtype=object)
    obj[()] = {"cam_trans": F.Evil(marker)}
    np.savez(src, outputs=obj, imgpaths=content["imgpaths"])
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o4", "--from", "trace", "--image-size", W, H))
    assert "refused to unpickle global" in text and not marker.exists()
    np.savez(src, outputs=outputs)
    assert trace.sniff(src) is None
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "o5", "--from", "trace", "--image-size", W, H))
    assert "missing imgpaths" in text


def test_trace_from_reads_what_import_writes(tmp_path, scene, model_path):
    src = PT.write_trace(tmp_path / "trace_demo.npz", scene, (W, H))
    import_sequence(src, tmp_path / "out", "trace", smpl_model=model_path)
    written = open_sequence(tmp_path / "out")
    with imported_sequence(src, "trace", smpl_model=model_path) as seq:
        assert seq.frame_names == written.frame_names and seq.intrinsics == written.intrinsics
        for name in seq.frame_names:
            for key, value in written.read_frame(name).data.items():
                np.testing.assert_array_equal(seq.read_frame(name).data[key], value)


# ---- what each sniff claims ------------------------------------------------------------------------
def test_sniffs_claim_only_their_tool(tmp_path, scene, model, camera):
    bev = F.write_bev(tmp_path / "bev", scene, (W, H))
    phalp = F.write_phalp(tmp_path / "demo_video.pkl", scene, (W, H), compress=0)
    cliff = F.write_cliff(tmp_path / "demo_cliff_hr48.npz", scene, (W, H))
    trace_file = PT.write_trace(tmp_path / "trace_demo.npz", scene, (W, H))
    pymafx_file = PT.write_pymafx(tmp_path / "output.pkl", scene, (W, H))
    for other in (bev, *bev.glob("*.npz"), phalp, cliff, pymafx_file):
        assert trace.sniff(other) is None, other
    for other in (bev, phalp, cliff, trace_file):
        assert pymafx.sniff(other) is None, other
    assert detect_format(bev) == "bev" and detect_format(phalp) == "4dhumans" and detect_format(cliff) == "cliff"


@pytest.mark.skipif(not REALFILES.is_dir(), reason="../shared/realfiles is absent")
def test_real_files_of_other_tools_are_not_claimed():
    files = [p for p in REALFILES.rglob("*") if p.is_file() and p.suffix in (".npz", ".pkl", ".pk", ".pt")]
    assert files
    for path in files:
        assert pymafx.sniff(path) is None and trace.sniff(path) is None, path
