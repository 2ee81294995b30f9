"""Their world and ours (issue 32, point 5): WHAM's and GVHMR's own worlds kept on import (``tool_*`` keys,
meta.yaml ``tool_world``) with the body-model parameters of the posed people, and compared with rotavat's up
vector and aligned people (``rotavat_cli.metrics.tool_world``): synthetic cases with a known tilt and a known
heading, offset and scale, and the real files of ../shared/realfiles (skipped when absent)."""

from __future__ import annotations

import json
from pathlib import Path

import _body_models as B
import _fixtures_torch as T
import _fixtures_wham_hybrik as WH
import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle

from rotavat_cli.alignment.align import align_sequence
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.formats import import_sequence
from rotavat_cli.formats.smpl import lbs, load_body_model
from rotavat_cli.metrics.tool_world import (FIT, TOOL_WORLD_KEYS, angles_deg, heading_fit, path_lengths_m,
                                            their_up_cam, tool_world_report, tool_world_tracks, wander_deg)
from rotavat_cli.geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from rotavat_cli.sequence import SMPL_PARAM_KEYS, open_sequence, read_camera_yaml, write_camera_yaml

W, H = 640, 480
TOL_M = 1e-4  # float32 files of metre-scale coordinates, plus LBS round-off
POSE_TOL_M = 1e-6  # stored float32 vertices within 16 m of the camera round to 0.5 um; parameters are float64
REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"
SMPLX_REST_PELVIS_M = np.array([0.0, -0.35, 0.01])  # where SMPL-X's pelvis rests (tests/test_model_fit.py)


def _rot(rotvec) -> np.ndarray:
    rotvec = np.asarray(rotvec, dtype=np.float64)
    return axis_angle_to_matrix(rotvec, np.linalg.norm(rotvec, axis=-1))


def _yaw(deg: float) -> np.ndarray:
    return _rot([0.0, np.radians(deg), 0.0])


def _real(*parts: str) -> Path:
    path = REALFILES.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} absent (../shared/realfiles)")
    return path


# ---- the pure functions ------------------------------------------------------------------------------------
def test_their_gravity_7_degrees_off_ours_measures_7_degrees():
    rng = np.random.default_rng(7)
    camera = Camera((W, H), 500.0, None, np.radians(20.0), np.radians(2.0), 3.0)
    tilt = _rot(np.radians(7.0) * np.array([0.6, 0.0, 0.8]))  # their world: ours turned 7 deg about a level axis
    root_cam = rng.normal(size=(50, 3))  # any body orientations, seen by the camera
    theirworld_from_cam = _yaw(40.0) @ tilt @ camera.R_cam_from_world.T  # and any heading of theirs
    root_world = matrix_to_axis_angle(theirworld_from_cam @ _rot(root_cam))
    up = their_up_cam(root_cam, root_world, (0.0, 1.0, 0.0))
    np.testing.assert_allclose(angles_deg(up, camera.up_cam), 7.0, atol=1e-9)
    np.testing.assert_allclose(wander_deg(up), 0.0, atol=1e-9)  # one camera, one up: no wander


def test_their_up_wanders_with_the_camera_they_believe_in():
    """Frames whose camera-in-their-world turns by 0, 2, 4 deg about x: their up wanders 2 deg about its mean."""
    root_cam = np.zeros((3, 3))
    root_world = np.array([[np.radians(a), 0.0, 0.0] for a in (0.0, 2.0, 4.0)])
    up = their_up_cam(root_cam, root_world, (0.0, 1.0, 0.0))
    np.testing.assert_allclose(wander_deg(up), [2.0, 0.0, 2.0], atol=1e-9)
    np.testing.assert_allclose(wander_deg(up, np.array([0, 0, 1])), [1.0, 1.0, 0.0], atol=1e-9)  # per track


def test_heading_fit_removes_heading_and_origin_and_keeps_scale_in_the_residual():
    t = np.linspace(0.0, 2.0, 40)
    ours = np.stack([3.0 * np.cos(t), 0.95 + 0.02 * np.sin(5 * t), -6.0 + 3.0 * np.sin(t)], axis=1)
    theirs = ours @ _yaw(-35.0).T + [4.0, 0.2, -1.0]  # their world: another heading and origin
    R, shift = heading_fit(theirs, ours)
    np.testing.assert_allclose(R[0], _yaw(35.0), atol=1e-12)
    np.testing.assert_allclose(theirs @ R[0].T + shift[0], ours, atol=1e-12)
    scaled = 1.1 * (ours - ours.mean(axis=0)) @ _yaw(-35.0).T + [4.0, 0.2, -1.0]  # their path 10 % longer
    R, shift = heading_fit(scaled, ours)
    rms = np.sqrt(np.mean(np.sum((scaled @ R[0].T + shift[0] - ours) ** 2, axis=1)))
    spread = np.sqrt(np.mean(np.sum((ours - ours.mean(axis=0)) ** 2, axis=1)))
    assert rms == pytest.approx(0.1 * spread, rel=1e-12)  # no scale fitted: the 10 % stays, and only it
    assert path_lengths_m(scaled)[0] / path_lengths_m(ours)[0] == pytest.approx(1.1, rel=1e-12)


def test_heading_fit_per_track_and_their_up_along_minus_y():
    ours = np.array([[0.0, 1.0, -5.0], [1.0, 1.0, -5.0], [1.0, 1.0, -7.0], [0.0, 0.9, -3.0], [0.0, 0.9, -4.0]])
    group = np.array([0, 0, 0, 1, 1])
    flip = np.diag([1.0, -1.0, -1.0])  # a Y-down world
    theirs = np.concatenate([ours[:3] @ (flip @ _yaw(10.0)).T, ours[3:] @ (flip @ _yaw(-80.0)).T + [0.0, 0.0, 2.0]])
    R, shift = heading_fit(theirs, ours, group, up_axis=(0.0, -1.0, 0.0))
    fitted = np.einsum("nij,nj->ni", R[group], theirs) + shift[group]
    np.testing.assert_allclose(fitted, ours, atol=1e-12)


# ---- a whole sequence: known tilt, heading, offset and scale -----------------------------------------------------
def _write_frames(folder: Path, frames: list[dict], meta: str, camera: Camera | None = None) -> Path:
    folder.mkdir()
    for i, data in enumerate(frames):
        np.savez(folder / f"{i:06d}.npz", **data)
    (folder / "meta.yaml").write_text(meta)
    if camera is not None:
        write_camera_yaml(folder / "camera.yaml", camera)
    return folder


def _synthetic_pair(tmp_path: Path, tilt_deg: float, scale: float):
    """An input and an 'aligned' sequence of two tracks walking arcs (pelvis 0.95 m up, a foot vertex 0.95 m
    below it), and the tool's world: each track's own heading and origin, tilted ``tilt_deg`` from rotavat's
    up and its path ``scale`` times as long."""
    camera = Camera((W, H), 500.0, None, np.radians(18.0), np.radians(-3.0), 2.5)
    rng = np.random.default_rng(32)
    n = 30
    s = np.linspace(0.0, 1.5, n)
    paths = {4: np.stack([2.0 * np.cos(s) - 1.0, np.full(n, 0.95), -7.0 + 2.0 * np.sin(s)], axis=1),
             9: np.stack([1.5 - 0.8 * s, np.full(n, 0.95), -4.0 - 1.2 * s], axis=1)}
    worlds = {4: (_yaw(30.0), np.array([5.0, 0.1, 2.0])), 9: (_yaw(-120.0), np.array([-1.0, 0.0, 0.5]))}
    tilt = _rot(np.radians(tilt_deg) * np.array([1.0, 0.0, 0.0]))
    inputs, aligned = [], []
    for i in range(n):
        ids = np.array(sorted(paths), dtype=np.int64)
        ours_world = np.stack([paths[pid][i] for pid in ids])
        pelvis_cam = camera.cam_from_world(ours_world)
        foot_cam = camera.cam_from_world(ours_world - [0.0, 0.95, 0.0])
        root_cam = rng.normal(size=(len(ids), 3))
        theirs, root_world = [], []
        for k, pid in enumerate(ids):
            R, t = worlds[pid]
            centre = paths[pid].mean(axis=0)
            theirs.append(tilt @ R @ (centre + scale * (ours_world[k] - centre)) + t)
            root_world.append(matrix_to_axis_angle(tilt @ R @ camera.R_cam_from_world.T @ _rot(root_cam[k])))
        verts = np.stack([pelvis_cam, foot_cam], axis=1)
        inputs.append({"vertices": verts, "joints": pelvis_cam[:, None], "person_ids": ids,
                       "tool_cam_global_orient": root_cam, "tool_world_global_orient": np.stack(root_world),
                       "tool_world_transl": np.stack(theirs), "tool_world_pelvis": np.stack(theirs)})
        aligned.append({"vertices": verts, "joints": pelvis_cam[:, None], "person_ids": ids})
    meta = "image_size: [640, 480]\nfocal_length: 500.0\ntool_world: {tool: synth, up_axis: [0, 1, 0], units: m}\n"
    seq_in = open_sequence(_write_frames(tmp_path / "in", inputs, meta))
    seq_al = open_sequence(_write_frames(tmp_path / "al", aligned, meta + "aligned_from: {focal_length: 500.0}\n", camera))
    return seq_in, seq_al, camera


def test_report_on_known_worlds(tmp_path):
    seq_in, seq_al, camera = _synthetic_pair(tmp_path, tilt_deg=0.0, scale=1.0)
    report = tool_world_report(seq_in, seq_al, camera)
    assert report["tool"] == "synth" and report["person_frames"] == 60 and report["tracks"] == 2
    assert report["up_angle_deg"]["max"] == pytest.approx(0.0, abs=1e-6)
    assert report["up_wander_deg"]["max"] == pytest.approx(0.0, abs=1e-6)
    assert report["trajectory"]["fit"] == FIT and report["trajectory"]["person_frames"] == 60
    assert report["trajectory"]["rms_m"] == pytest.approx(0.0, abs=1e-9)
    rows = {row["person_id"]: row for row in report["per_track"]}
    assert rows[4]["heading_deg"] == pytest.approx(-30.0, abs=1e-9) and rows[9]["heading_deg"] == pytest.approx(120.0, abs=1e-9)
    assert rows[4]["path_length_ratio"] == pytest.approx(1.0, abs=1e-12) and rows[9]["spread_ratio"] == pytest.approx(1.0, abs=1e-12)
    assert report["pelvis_height_m"]["theirs"] == pytest.approx(0.95, abs=1e-9)  # above their lowest vertex
    assert report["pelvis_height_m"]["ours"] == pytest.approx(0.95, abs=1e-9)  # above rotavat's ground
    assert report["notes"] == []


def test_report_on_a_tilted_longer_world(tmp_path):
    seq_in, seq_al, camera = _synthetic_pair(tmp_path, tilt_deg=7.0, scale=1.2)
    report = tool_world_report(seq_in, seq_al)  # the camera: the aligned sequence's camera.yaml
    assert report["up_angle_deg"]["median"] == pytest.approx(7.0, abs=1e-9)
    assert report["up_angle_deg"]["max"] == pytest.approx(7.0, abs=1e-9)
    assert report["trajectory"]["path_length_ratio"] == pytest.approx(1.2, rel=1e-9)
    assert report["trajectory"]["spread_ratio"] == pytest.approx(1.2, rel=1e-9)
    assert 0.05 < report["trajectory"]["rms_m"] < 0.5  # the scale and the tilt stay in the residual
    assert tool_world_report(seq_al, seq_al) is None  # no tool world: no report


# ---- the imports keep their worlds ---------------------------------------------------------------------------
def _posed_from_params(model, frame) -> np.ndarray:
    """The frame's people posed from its smpl_* keys alone."""
    d = frame.data
    P = frame.n_people
    pose = np.concatenate([d["smpl_global_orient"][:, None], d["smpl_body_pose"].reshape(P, -1, 3)], axis=1)
    return lbs(model, d["smpl_betas"], pose, d["smpl_transl"])[0]


def test_wham_import_keeps_its_world_and_body_parameters(tmp_path, scene, model_path, model):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    import_sequence(src, tmp_path / "out", "wham", smpl_model=model_path, image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    assert seq.meta["tool_world"]["tool"] == "wham" and seq.meta["tool_world"]["up_axis"] == [0.0, 1.0, 0.0]
    assert "ignored" not in seq.meta["import"]
    assert seq.meta["body_model"] == {"kind": "smpl", "file": model_path.name, "joints": 24}
    for frame, truth in zip(seq.frames(), scene):
        d = frame.data
        assert set(TOOL_WORLD_KEYS) | set(SMPL_PARAM_KEYS) <= set(d)
        np.testing.assert_allclose(d["tool_cam_global_orient"], np.stack([p.pose[0] for p in truth]), atol=1e-6)
        np.testing.assert_allclose(d["tool_world_global_orient"], [[np.pi / 2, 0.0, 0.0]] * len(truth), atol=1e-6)
        trans_world = np.stack([p.transl for p in truth]) + [5.0, 1.0, -2.0]  # the fixture's world_offset
        np.testing.assert_allclose(d["tool_world_transl"], trans_world, atol=TOL_M)
        joints = np.stack([p.joints_cam for p in truth])
        world_from_cam = _rot([np.pi / 2, 0.0, 0.0]) @ np.swapaxes(_rot(np.stack([p.pose[0] for p in truth])), 1, 2)
        offset = joints[:, 0] - (joints[:, 1] + joints[:, 2]) / 2.0
        np.testing.assert_allclose(d["tool_world_pelvis"], trans_world + np.einsum("pij,pj->pi", world_from_cam, offset),
                                   atol=TOL_M)
        assert all(d[key].dtype == np.float64 for key in TOOL_WORLD_KEYS)
        np.testing.assert_allclose(_posed_from_params(model, frame), d["vertices"], atol=POSE_TOL_M, rtol=0)


def test_wham_without_a_model_keeps_its_orientations_and_path_only(tmp_path, scene):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    import_sequence(src, tmp_path / "out", "wham", image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    frame = next(seq.frames())
    assert {"tool_cam_global_orient", "tool_world_global_orient", "tool_world_transl"} <= set(frame.data)
    assert "tool_world_pelvis" not in frame.data and "smpl_pelvis" not in frame.data
    assert seq.meta["tool_world"]["pelvis"] is None and "body_model" not in seq.meta
    report = tool_world_report(seq)
    assert report["trajectory"] is None and any("--smpl-model" in note for note in report["notes"])


@pytest.mark.parametrize("damage", ["no trans_world", "nan pose_world", "short trans_world", "one track without"])
def test_a_broken_wham_world_is_one_line_naming_the_file(tmp_path, scene, runner, damage):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    data = dict(unpickle.load_file(src))
    track = data[np.int64(3)]
    if damage == "no trans_world":
        del track["trans_world"]
    elif damage == "nan pose_world":
        track["pose_world"][0, 1] = np.nan
    elif damage == "short trans_world":
        track["trans_world"] = track["trans_world"][:1]
    else:
        del data[np.int64(5)]["pose_world"], data[np.int64(5)]["trans_world"]
    src.write_bytes(F.joblib_bytes(data))
    result = invoke(runner, "import", src, tmp_path / "out", "--image-size", W, H)
    assert result.exit_code == 2 and "Traceback" not in result.output
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and "wham_output.pkl" in lines[0]
    assert {"no trans_world": "has 'pose_world' but not 'trans_world'", "nan pose_world": "'tool_world_global_orient' has non-finite",
            "short trans_world": "'trans_world' has 1 rows", "one track without": "some tracks have WHAM's world"}[damage] in lines[0]


def test_gvhmr_import_keeps_its_world_and_body_parameters(tmp_path, scene, smplx_on_smpl_path):
    track = [scene[0][0], scene[1][0], scene[0][1]]
    src = T.write_gvhmr(tmp_path / "g", track, (W, H))
    import_sequence(src, tmp_path / "out", "gvhmr", smpl_model=smplx_on_smpl_path)
    seq = open_sequence(tmp_path / "out")
    model = load_body_model(smplx_on_smpl_path)
    assert seq.meta["tool_world"]["tool"] == "gvhmr" and seq.meta["tool_world"]["up_axis"] == [0.0, 1.0, 0.0]
    assert seq.meta["body_model"] == {"kind": "smplx", "file": smplx_on_smpl_path.name, "joints": 55}
    for frame, person in zip(seq.frames(), track):
        d = frame.data
        assert set(TOOL_WORLD_KEYS) | set(SMPL_PARAM_KEYS) <= set(d)
        np.testing.assert_allclose(d["tool_cam_global_orient"][0], person.pose[0], atol=1e-6)
        np.testing.assert_allclose(d["tool_world_global_orient"][0], person.pose[0][::-1], atol=1e-6)  # the fixture's
        np.testing.assert_allclose(d["tool_world_transl"][0], person.transl + [0.0, 1.0, -5.0], atol=TOL_M)
        np.testing.assert_allclose(d["tool_world_pelvis"][0], person.joints_cam[0] + [0.0, 1.0, -5.0], atol=TOL_M)
        np.testing.assert_allclose(d["smpl_pelvis"][0], person.joints_cam[0], atol=TOL_M)
        np.testing.assert_allclose(_posed_from_params(model, frame), d["vertices"], atol=POSE_TOL_M, rtol=0)


def test_align_copies_the_tool_world_through(tmp_path, scene, model_path, camera):
    src = WH.write_wham(tmp_path / "wham_output.pkl", scene)
    import_sequence(src, tmp_path / "out", "wham", smpl_model=model_path, image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    align_sequence(seq, camera, tmp_path / "aligned")
    aligned = open_sequence(tmp_path / "aligned")
    assert aligned.meta["tool_world"] == seq.meta["tool_world"]
    for name in seq.frame_names:
        before, after = seq.read_frame(name).data, aligned.read_frame(name).data
        for key in TOOL_WORLD_KEYS:
            np.testing.assert_array_equal(after[key], before[key])
    report = tool_world_report(seq, aligned, camera)
    assert report["trajectory"]["person_frames"] == 3 and report["tracks"] == 2


# ---- the real files: measurements (docs/formats.md, WHAM and GVHMR) ---------------------------------------------
def _camera_yaml(path: Path, size, focal, pitch_deg, roll_deg, height_m) -> Path:
    path.write_text(f"image_size: [{size[0]}, {size[1]}]\nfocal_px: {focal}\npitch_deg: {pitch_deg}\n"
                    f"roll_deg: {roll_deg}\nheight_m: {height_m}\n")
    return path


def test_real_wham_up_is_its_first_camera_level(tmp_path):
    """WHAM's demo starts each track's world at the camera-frame root: its up stays the camera's -y (1.3 deg),
    11.6 deg from the up rotavat calibrates (pitch 10.5 deg, roll 1.1 deg, 2026-12-07)."""
    src = _real("wham_lalasray", "wham_output.pkl")
    import_sequence(src, tmp_path / "wham", "wham", image_size=(W, H))
    seq = open_sequence(tmp_path / "wham")
    camera = _read_camera(_camera_yaml(tmp_path / "camera.yaml", (W, H), 614.87, 10.506, 1.097, 1.769))
    align_sequence(seq, camera, tmp_path / "aligned")
    report = tool_world_report(seq, open_sequence(tmp_path / "aligned"), camera)
    assert report["tool"] == "wham" and report["person_frames"] == 42
    assert report["up_angle_deg"]["median"] == pytest.approx(11.57, abs=0.02)
    assert report["up_angle_deg"]["max"] == pytest.approx(12.09, abs=0.02)
    assert report["up_wander_deg"]["max"] == pytest.approx(1.14, abs=0.02)
    assert np.median(angles_deg(_their_up(seq), np.array([0.0, -1.0, 0.0]))) == pytest.approx(1.34, abs=0.02)
    assert report["trajectory"] is None  # no --smpl-model (WHAM's SMPL is not here): no pelvis in its world


def test_real_gvhmr_world_against_ours(tmp_path, smplx_on_smpl_path):
    """GVHMR's tennis player on the stand-in SMPL-X (moved to SMPL-X's pelvis), aligned in the camera rotavat
    calibrates (2026-12-07): its up 13.2 deg from ours; after the heading fit its path 0.20 m RMS from ours,
    0.72 times as long and spread 1.25 times as wide."""
    src = _real("gvhmr", "tennis", "hmr4d_results.pt")
    with np.load(smplx_on_smpl_path) as stand_in:
        pelvis = (stand_in["J_regressor"] @ stand_in["v_template"].astype(np.float64))[0]
    moved = B.write_moved_model(tmp_path / "SMPLX_AT_PELVIS.npz", smplx_on_smpl_path, SMPLX_REST_PELVIS_M - pelvis)
    import_sequence(src, tmp_path / "g", "gvhmr", smpl_model=moved)
    seq = open_sequence(tmp_path / "g")
    camera = _read_camera(_camera_yaml(tmp_path / "camera.yaml", (812, 720), 733.12, 17.020, -0.748, 1.811))
    align_sequence(seq, camera, tmp_path / "aligned")
    report = tool_world_report(seq, open_sequence(tmp_path / "aligned"), camera)
    assert report["tool"] == "gvhmr" and report["person_frames"] == 312
    assert report["up_angle_deg"]["median"] == pytest.approx(13.24, abs=0.02)
    assert report["up_angle_deg"]["p90"] == pytest.approx(17.48, abs=0.02)
    assert report["up_wander_deg"]["max"] == pytest.approx(6.88, abs=0.02)
    assert np.median(angles_deg(_their_up(seq), np.array([0.0, -1.0, 0.0]))) == pytest.approx(4.85, abs=0.02)
    assert report["trajectory"]["rms_m"] == pytest.approx(0.200, abs=0.005)
    assert report["trajectory"]["path_length_ratio"] == pytest.approx(0.718, abs=0.005)  # ours jitters more
    assert report["trajectory"]["spread_ratio"] == pytest.approx(1.254, abs=0.005)  # theirs spans more
    assert report["pelvis_height_m"]["theirs"] == pytest.approx(1.007, abs=0.005)
    assert report["pelvis_height_m"]["ours"] == pytest.approx(0.923, abs=0.005)


def _read_camera(path: Path) -> Camera:
    return read_camera_yaml(path)[0]


def _their_up(seq) -> np.ndarray:
    cols = tool_world_tracks(seq)
    return their_up_cam(cols["root_cam"], cols["root_world"], seq.meta["tool_world"]["up_axis"])


# ---- rotavat view draws their world -----------------------------------------------------------------------------
def _read_rrd(path: Path) -> dict[str, list[dict]]:
    """``{entity path: [{component: value}, ...]}`` of a recording, through Rerun's own reader."""
    from rerun.chunk import RrdReader  # lazy: the optional extra rotavat[view]

    out: dict[str, list[dict]] = {}
    for chunk in RrdReader(path).stream():
        columns = chunk.to_record_batch().to_pydict()
        for r in range(chunk.num_rows):
            out.setdefault(chunk.entity_path, []).append({k: v[r] for k, v in columns.items() if ":" in k})
    return out


@pytest.mark.parametrize("tilt_deg", [0.0, 7.0])
def test_view_draws_their_paths_up_and_ground(tmp_path, tilt_deg):
    pytest.importorskip("rerun")
    from rotavat_cli.view import ViewOptions, record_sequences

    seq_in, seq_al, camera = _synthetic_pair(tmp_path, tilt_deg=tilt_deg, scale=1.0)
    write_camera_yaml(tmp_path / "camera.yaml", camera)
    summary = record_sequences([seq_in], tmp_path / "view.rrd", opts=ViewOptions(camera_path=tmp_path / "camera.yaml"),
                               labels=["in"])
    data = _read_rrd(Path(summary.out))
    for pid in (4, 9):
        (up,) = [row for row in data[f"/world/in/their_world/up/{pid}"] if "Arrows3D:vectors" in row]
        assert up["Arrows3D:labels"] == [f"{pid}: their up, {tilt_deg:.1f}° from ours"]
        assert f"/world/in/their_world/ground/{pid}" in data
        (path,) = [row for row in data[f"/world/in/their_world/paths/{pid}"] if "LineStrips3D:strips" in row]
        drawn = np.concatenate([np.asarray(strip) for strip in path["LineStrips3D:strips"]])
        row = (4, 9).index(pid)  # person ids sort 4, 9 in every frame
        ours = np.stack([camera.world_from_cam(seq_in.read_frame(n).data["joints"][row, 0]) for n in seq_in.frame_names])
        if tilt_deg == 0.0:  # their world is ours turned and moved: the fit puts their path on ours
            np.testing.assert_allclose(drawn, ours, atol=1e-5)


def test_eval_reports_their_world_beside_the_measures(tmp_path, runner):
    """`rotavat eval IN ALIGNED` (no truth) pairs the import with its aligned output and reports their world:
    the 7 deg tilt in JSON, a table in metrics.md, a line on the terminal."""
    seq_in, seq_al, _ = _synthetic_pair(tmp_path, tilt_deg=7.0, scale=1.2)
    result = invoke(runner, "eval", tmp_path / "in", tmp_path / "al", "--out", tmp_path / "ev", "--json")
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)["predictions"]
    assert rows[0]["tool_world"]["up_angle_deg"]["median"] == pytest.approx(7.0, abs=1e-6)
    assert rows[0]["tool_world"]["camera_from"] == "aligned"
    assert rows[0]["tool_world"]["trajectory"]["spread_ratio"] == pytest.approx(1.2, rel=1e-6)
    assert rows[1]["tool_world"] is None  # the aligned copy here holds no tool keys
    md = (tmp_path / "ev" / "metrics.md").read_text()
    assert "| `" + str(tmp_path / "in") + "` | synth | aligned | 7.00 | 7.00 |" in md
