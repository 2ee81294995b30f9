"""rotavat view: the recording's geometry (pure, always run) and a whole recording of a synthetic scene read
back with Rerun's own reader (the optional extra rotavat[view]: skipped cleanly without it; CI installs it)."""

from __future__ import annotations

import math
import shutil
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from _cli import invoke

from rotavat_cli.alignment import AlignOptions, align_sequence
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.metrics.evaluate import EvalOptions, evaluate
from rotavat_cli.files.outputs import written_by_rotavat
from rotavat_cli.sequence import open_sequence, read_camera_yaml, write_camera_yaml
from rotavat_cli.synth import SynthOptions, write_synth_scene
from rotavat_cli.view import (camera_label, grid_lines_world, grid_step_m, grid_ticks_world, ground_extent_m,
                              label_anchors_world, plane_quad_world, track_strips, uncertainty_cameras, world_points_f32)

CAM = Camera((640, 360), 500.0, None, math.radians(15.0), math.radians(1.5), 3.0)


# ---- geometry (no Rerun) ---------------------------------------------------------------------------------
def test_ground_extent_holds_every_point_with_its_margin_on_whole_metres():
    points = np.array([[0.3, 0.0, -7.6], [-2.2, 1.8, -1.1], [np.nan, 0.0, 0.0]])
    lo, hi = ground_extent_m(points, margin_m=2.0)
    assert lo.tolist() == [-5.0, -10.0] and hi.tolist() == [3.0, 1.0]  # floor(-2.2-2), floor(-7.6-2), ceil(0.3+2), ceil(-1.1+2)
    assert [v.tolist() for v in ground_extent_m(np.full((2, 3), np.nan))] == [[-5.0, -10.0], [5.0, 0.0]]


def test_grid_lines_lie_on_the_ground_one_per_metre_and_thin_out_for_a_wide_scene():
    lo, hi = np.array([-3.0, -12.0]), np.array([4.0, 0.0])
    lines = grid_lines_world(lo, hi, grid_step_m(lo, hi))
    assert lines.shape == (8 + 13, 2, 3) and np.all(lines[..., 1] == 0.0)
    xs = sorted({float(x) for x in lines[:8, :, 0].ravel()})
    assert xs == [-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 4.0]
    assert grid_step_m(np.array([0.0, 0.0]), np.array([60.0, 5.0])) == 1.0
    assert grid_step_m(np.array([0.0, 0.0]), np.array([61.0, 5.0])) == 2.0
    assert grid_step_m(np.array([0.0, -400.0]), np.array([10.0, 0.0])) == 10.0


def test_tick_labels_name_the_metres_they_sit_at():
    points, labels = grid_ticks_world(np.array([-30.0, -40.0]), np.array([30.0, 0.0]), 1.0)
    assert len(labels) == len(points) and len(labels) <= 2 * 8
    for (x, y, z), text in zip(points, labels):
        assert y == 0.0
        value = float(text.split()[1]) if text.startswith("x ") else float(text.split()[0])
        assert value == (x if text.startswith("x ") else -z)


@pytest.mark.parametrize("change", [{"height_m": 3.4}, {"pitch_rad": math.radians(18.0)}, {"roll_rad": math.radians(-3.0)}])
def test_another_cameras_ground_is_drawn_where_that_camera_puts_it(change):
    other = CAM.replace(**change)
    quad = plane_quad_world(other, CAM, np.array([-4.0, -15.0]), np.array([4.0, 0.0]))
    heights = other.height_above_ground(CAM.cam_from_world(quad))  # each corner on the other camera's ground
    np.testing.assert_allclose(heights, 0.0, atol=1e-9)
    np.testing.assert_array_equal(quad[:, [0, 2]], [[-4, -15], [4, -15], [4, 0], [-4, 0]])
    if "height_m" in change:  # a camera 0.4 m higher sees the ground 0.4 m lower
        np.testing.assert_allclose(quad[:, 1], -0.4, atol=1e-9)


def test_a_ground_standing_on_its_edge_is_not_drawn():
    assert plane_quad_world(CAM.replace(pitch_rad=math.radians(-80.0)), CAM, np.array([-1.0, -5.0]), np.array([1.0, 0.0])) is None


def test_uncertainty_cameras_move_one_parameter_by_one_std():
    cams = uncertainty_cameras(CAM, {"height_m": 0.25, "pitch_deg": 2.0, "focal_px": 80.0})
    assert sorted(cams) == ["height_minus_1sd", "height_plus_1sd", "pitch_minus_1sd", "pitch_plus_1sd"]
    assert cams["height_minus_1sd"].height_m == pytest.approx(2.75) and cams["height_minus_1sd"].pitch_rad == CAM.pitch_rad
    assert math.degrees(cams["pitch_plus_1sd"].pitch_rad) == pytest.approx(17.0) and cams["pitch_plus_1sd"].height_m == 3.0
    assert uncertainty_cameras(CAM, {"height_m": float("nan"), "pitch_deg": 0.0}) == {}
    assert uncertainty_cameras(CAM, None) == {}
    assert sorted(uncertainty_cameras(CAM, {"height_m": 5.0})) == ["height_plus_1sd"]  # a camera under the ground is no camera


def test_camera_label_gives_the_focal_range_of_one_std():
    text = camera_label(CAM, {"method": "grid", "std": {"focal_px": 40.0, "height_m": 0.1}}, "c.yaml")
    assert "f 500 ± 40 px (460-540)" in text and "height 3.00 ± 0.10 m" in text and "pitch 15.0°" in text
    assert text.startswith("camera (grid fit, c.yaml)")


def test_track_strips_break_at_gaps_and_drop_lone_points():
    strips = track_strips(np.array([3, 4, 5, 7, 9, 10]), np.array([[i, 0, -i] for i in range(6)], float))
    assert [s[:, 0].tolist() for s in strips] == [[0.0, 1.0, 2.0], [4.0, 5.0]]
    assert [len(s) for s in track_strips(np.arange(4), np.array([[0, 0, 0], [np.nan] * 3, [1, 0, 0], [2, 0, 0]], float))] == [2]  # a NaN cuts too


def test_label_anchors_float_above_each_person():
    people = np.zeros((2, 1000, 3))
    people[0, :, 1] = np.linspace(0.0, 1.7, 1000)
    people[0, :, 0], people[0, :, 2] = 2.0, -5.0
    people[1] = np.nan
    anchors = label_anchors_world(people)
    assert anchors[0, 0] == pytest.approx(2.0) and anchors[0, 2] == pytest.approx(-5.0)
    assert 1.7 + 0.14 < anchors[0, 1] < 1.7 + 0.16
    assert np.isnan(anchors[1]).all()


def test_world_points_in_float32_match_the_cameras_own_transform():
    pts = np.random.default_rng(0).normal([0, 1, 8], 2.0, (4, 50, 3))
    got = world_points_f32(CAM, pts)
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, CAM.world_from_cam(pts), atol=5e-6)


# ---- a whole recording, read back with Rerun's own reader ------------------------------------------------
def _read(path: Path) -> dict[str, list[tuple[int | None, dict]]]:
    """``{entity path: [(frame or None for static, {component: value}), ...]}`` through rerun.chunk.RrdReader."""
    from rerun.chunk import RrdReader

    out: dict[str, list] = defaultdict(list)
    for chunk in RrdReader(path).stream():
        columns = chunk.to_record_batch().to_pydict()
        frames = columns.get("frame", [None] * chunk.num_rows)
        for r in range(chunk.num_rows):
            out[chunk.entity_path].append((frames[r], {k: v[r] for k, v in columns.items() if ":" in k}))
    return out


@pytest.fixture(scope="module")
def view_scene(tmp_path_factory):
    """A synthetic scene: pred (meshes, HPS-like), pred_aligned (align's output; people.csv flags person 1 sitting in
    frame 0), joints (joints only, person 1 gone in frame 2), cloud (vertices without faces), gt (truth), and video
    frames; the scene camera: the true one, 0.3 m higher, with a fit's std."""
    pytest.importorskip("rerun")
    root = tmp_path_factory.mktemp("view")
    write_synth_scene(root, SynthOptions(seed=4, frames=4, people=3, image_size=(320, 180)))
    gt = open_sequence(root / "gt")
    align_sequence(open_sequence(root / "pred"), gt.camera, root / "pred_aligned", AlignOptions(jobs=1))
    joints = root / "joints"
    joints.mkdir()
    shutil.copy(root / "pred" / "meta.yaml", joints / "meta.yaml")
    pred = open_sequence(root / "pred")
    for k, name in enumerate(pred.frame_names):
        frame = pred.read_frame(name)
        keep = np.array([pid != 1 or k != 2 for pid in frame.person_ids])
        np.savez(joints / f"{name}.npz", joints=frame.data["joints"][keep], person_ids=frame.person_ids[keep],
                 **{key: frame.data[key][keep] for key in ("focal_length",) if key in frame.data and np.ndim(frame.data[key])})
    people_csv = root / "pred_aligned" / "people.csv"
    lines = people_csv.read_text().splitlines()
    header = lines[0].split(",")
    first = gt.frame_names[0]
    for i, line in enumerate(lines[1:], 1):
        cells = line.split(",")
        if cells[header.index("frame")] == first and int(float(cells[header.index("person_id")])) == 1:
            cells[header.index("flag")] = "sitting"
            lines[i] = ",".join(cells)
    people_csv.write_text("\n".join(lines) + "\n")
    cloud = root / "cloud"
    cloud.mkdir()
    shutil.copy(root / "pred" / "meta.yaml", cloud / "meta.yaml")
    for name in pred.frame_names:
        frame = pred.read_frame(name)
        np.savez(cloud / f"{name}.npz", vertices=frame.data["vertices"], person_ids=frame.person_ids)
    images = root / "images"
    images.mkdir()
    from PIL import Image

    for k, name in enumerate(gt.frame_names):
        Image.new("RGB", (320, 180), (10 * k, 0, 0)).save(images / f"{name}.png")
    scene_camera = gt.camera.replace(height_m=gt.camera.height_m + 0.3)
    write_camera_yaml(root / "scene_camera.yaml", scene_camera,
                      {"method": "refine", "std": {"focal_px": 30.0, "pitch_deg": 1.0, "roll_deg": 0.5, "height_m": 0.2}})
    return root, scene_camera


@pytest.fixture(scope="module")
def recorded(view_scene):
    from rotavat_cli.view import ViewOptions, record_sequences

    root, _ = view_scene
    seqs = [open_sequence(root / name) for name in ("pred", "pred_aligned", "joints", "cloud")]
    calls = []
    summary = record_sequences(seqs, root / "scene.rrd", open_sequence(root / "gt"),
                               ViewOptions(camera_path=root / "scene_camera.yaml", image_dir=root / "images"),
                               lambda: calls.append(1))
    return summary, _read(root / "scene.rrd"), len(calls)


def test_the_recording_holds_every_row_as_its_own_entity_tree(recorded):
    summary, data, calls = recorded
    assert summary.rows == ["pred", "pred_aligned", "joints", "cloud", "gt"] and summary.gt == "gt"
    assert summary.frames == 4 == calls
    for row in ("pred", "pred_aligned", "gt"):
        for pid in (0, 1, 2):
            assert f"/world/{row}/people/{pid}/mesh" in data
    for pid in (0, 1, 2):
        assert f"/world/joints/people/{pid}/skeleton" in data and f"/world/joints/people/{pid}/joints" in data
        assert f"/world/joints/people/{pid}/mesh" not in data
        assert f"/world/cloud/people/{pid}/points" in data and f"/world/cloud/people/{pid}/mesh" not in data
    for path in ("/world", "/world/camera", "/world/camera/image", "/world/ground", "/world/ground/ticks",
                 "/world/gt/ground", "/world/ground/uncertainty/height_minus_1sd",
                 "/world/ground/uncertainty/pitch_plus_1sd",
                 "/world/pred/tracks/0", "/plots/foot_height_m/pred/0", "/plots/lean_deg/pred_aligned/2",
                 "/plots/stature_m/joints/1", "/plots/w_mpjpe_mm/pred/0"):
        assert path in data, path
    assert "/plots/w_mpjpe_mm/gt/0" not in data  # the truth is not scored against itself


def test_each_entity_has_one_row_per_frame_its_person_is_in(recorded):
    _, data, _ = recorded
    def frames(path, component):
        return sorted(f for f, row in data[path] if f is not None and row.get(component) is not None)
    assert frames("/world/pred/people/0/mesh", "Mesh3D:vertex_positions") == [0, 1, 2, 3]
    assert frames("/world/joints/people/0/skeleton", "LineStrips3D:strips") == [0, 1, 2, 3]
    assert frames("/world/joints/people/1/skeleton", "LineStrips3D:strips") == [0, 1, 3]
    assert frames("/world/joints/people/1", "Clear:is_recursive") == [2]  # gone in frame 2: nothing of it drawn
    assert frames("/plots/foot_height_m/joints/1", "Scalars:scalars") == [0, 1, 3]
    static = [row for f, row in data["/world/pred/people/0/mesh"] if f is None]
    assert len(static) == 1 and len(static[0]["Mesh3D:triangle_indices"]) > 1000  # faces once, for every frame


def test_people_have_renders_colours_their_paths_lie_on_the_ground_and_the_video_frames_are_under_the_camera(
        view_scene, recorded):
    from rotavat_cli.render import person_colors
    from rotavat_cli.render.style import RenderStyle, rgb8
    from rotavat_cli.view.roles import row_tint, row_tones

    root, _ = view_scene
    _, data, _ = recorded
    palette = RenderStyle().palette
    raw_tone = row_tones(["raw"])[0]
    for pid in (0, 1, 2):
        for row, tone in (("pred_aligned", ()), ("pred", raw_tone)):  # the aligned row in the palette's colours
            static = next(row for f, row in data[f"/world/{row}/people/{pid}/mesh"] if f is None)
            rgba = static["Mesh3D:albedo_factor"][0]
            want = rgb8(tuple(row_tint(person_colors(np.array([pid]), palette), tone)[0]))
            assert [(rgba >> s) & 255 for s in (24, 16, 8)] == list(want)
        path = next(row for f, row in data[f"/world/pred_aligned/tracks/{pid}"] if row.get("LineStrips3D:strips"))
        strip = np.array(path["LineStrips3D:strips"][0])
        assert strip.shape == (4, 3) and np.all(strip[:, 1] == 0.0)  # 4 frames, on the ground
    # the truth's feet are on its own ground, 0.3 m above the scene camera's
    heights = [row["Scalars:scalars"][0] for f, row in data["/plots/foot_height_m/gt/0"] if f is not None]
    assert len(heights) == 4 and all(abs(h - 0.3) < 0.03 for h in heights)
    images = [row for f, row in data["/world/camera/image/video"] if row.get("EncodedImage:blob")]
    assert len(images) == 4  # 320 x 180, within view.image_max_px: the files as they are, on the 320 x 180 pinhole
    assert bytes(images[2]["EncodedImage:blob"][0]) == (root / "images" / f"{open_sequence(root / 'gt').frame_names[2]}.png").read_bytes()
    assert all(np.allclose(row["Transform3D:scale"], [[1.0, 1.0, 1.0]]) for row in images)


def test_a_vertex_lands_at_its_world_position_in_metres(view_scene, tmp_path):
    from rotavat_cli.view import ViewOptions, record_sequences

    root, scene_camera = view_scene
    gt = open_sequence(root / "gt")
    record_sequences([gt], tmp_path / "full.rrd", opts=ViewOptions(camera_path=root / "scene_camera.yaml", mesh_vertices=0))
    data = _read(tmp_path / "full.rrd")  # every vertex, as the file has it
    frame = gt.read_frame(gt.frame_names[1])
    p = int(np.flatnonzero(frame.person_ids == 2)[0])
    expected = scene_camera.world_from_cam(frame.data["vertices"][p, 1234])
    row = next(row for f, row in data["/world/gt/people/2/mesh"] if f == 1 and row.get("Mesh3D:vertex_positions"))
    np.testing.assert_allclose(row["Mesh3D:vertex_positions"][1234], expected, atol=2e-5)
    # the truth stands on its own ground: 0.3 m above the scene camera's, which puts the camera 0.3 m too high
    feet_y = min(v[1] for v in row["Mesh3D:vertex_positions"])
    assert feet_y == pytest.approx(0.3, abs=0.03)
    quad = next(row for f, row in data["/world/gt/ground"] if row.get("Mesh3D:vertex_positions"))["Mesh3D:vertex_positions"]
    np.testing.assert_allclose(np.array(quad)[:, 1], 0.3, atol=1e-5)


def test_the_camera_carries_its_intrinsics_pose_and_uncertainty(view_scene, recorded):
    _, scene_camera = view_scene
    _, data, _ = recorded
    pinhole = next(row for f, row in data["/world/camera/image"] if f is None and row.get("Pinhole:image_from_camera"))
    K = np.array(pinhole["Pinhole:image_from_camera"]).reshape(3, 3).T  # stored column-major
    np.testing.assert_allclose(K, scene_camera.K, atol=1e-4)
    assert pinhole["Pinhole:resolution"] == [[320.0, 180.0]]
    pose = next(row for _, row in data["/world/camera"] if row.get("Transform3D:translation"))
    np.testing.assert_allclose(pose["Transform3D:translation"], [[0.0, scene_camera.height_m, 0.0]], atol=1e-6)
    R = np.array(pose["Transform3D:mat3x3"]).reshape(3, 3).T
    np.testing.assert_allclose(R, scene_camera.R_cam_from_world.T, atol=1e-6)  # world from camera
    label = next(row for _, row in data["/world/camera"] if row.get("Points3D:labels"))["Points3D:labels"][0]
    f = scene_camera.focal_px
    assert f"± 30 px ({f - 30:.0f}-{f + 30:.0f})" in label and "± 0.20 m" in label
    low = next(row for _, row in data["/world/ground/uncertainty/height_minus_1sd"] if row.get("Mesh3D:vertex_positions"))
    np.testing.assert_allclose(np.array(low["Mesh3D:vertex_positions"])[:, 1], 0.2, atol=1e-5)  # 0.2 m lower camera


def test_per_person_w_mpjpe_series_equal_evals_numbers(view_scene, recorded):
    root, _ = view_scene
    _, data, _ = recorded
    result = evaluate(open_sequence(root / "pred"), open_sequence(root / "gt"), EvalOptions(engine="numpy"))
    cols = result.per_person
    names = open_sequence(root / "gt").frame_names
    want = {(names.index(n), int(pid)): w for n, pid, w in zip(cols["frame"], cols["person_id"], cols["w_mpjpe"])}
    got = {}
    for pid in (0, 1, 2):
        for f, row in data[f"/plots/w_mpjpe_mm/pred/{pid}"]:
            if f is not None and row.get("Scalars:scalars") is not None:
                got[(f, pid)] = row["Scalars:scalars"][0]
    assert got.keys() == want.keys()
    for key, value in want.items():
        assert got[key] == pytest.approx(value, rel=1e-9)


def test_flagged_people_are_marked_in_their_labels(recorded):
    _, data, _ = recorded
    by_frame = {f: row for f, row in data["/world/pred_aligned/labels"] if f is not None}
    assert sorted(by_frame[0]["Points3D:labels"]) == ["0", "1 sitting", "2"]  # people.csv flags 1 sitting in frame 0
    assert sorted(by_frame[1]["Points3D:labels"]) == ["0", "1", "2"]
    colors = dict(zip(by_frame[0]["Points3D:labels"], by_frame[0]["Points3D:colors"]))
    assert [(colors["1 sitting"] >> s) & 255 for s in (24, 16, 8)] == [217, 26, 26]  # red
    radii = dict(zip(by_frame[0]["Points3D:labels"], by_frame[0]["Points3D:radii"]))
    assert radii["1 sitting"] == pytest.approx(2 * radii["0"])


# ---- the command ------------------------------------------------------------------------------------------
def test_view_writes_a_recording_rotavat_may_replace_and_refuses_a_strangers_file(view_scene, runner, tmp_path):
    root, _ = view_scene
    out = tmp_path / "cli.rrd"
    args = ["view", str(root / "pred"), "--gt", str(root / "gt"), "--camera", str(root / "scene_camera.yaml"),
            "--out", str(out), "--quiet"]
    result = invoke(runner, *args)
    assert result.exit_code == 0, result.output
    assert written_by_rotavat(out)
    assert invoke(runner, *args).exit_code == 0  # its own file: replaced without --force
    stranger = tmp_path / "stranger.rrd"
    stranger.write_bytes(b"RRF2" + b"\0" * 100)
    result = invoke(runner, *args[:-3], "--out", str(stranger), "--quiet")
    assert result.exit_code == 2 and "rotavat did not write it" in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cli.rrd", "stranger.rrd"]  # no temporary left


def test_view_without_a_camera_names_the_command_that_makes_one(view_scene, runner):
    root, _ = view_scene
    result = invoke(runner, "view", root / "pred", "--out", root / "x.rrd")
    assert result.exit_code == 2
    assert f"run `rotavat calibrate {root / 'pred'}`" in result.output and not (root / "x.rrd").exists()


def test_a_missing_video_frame_leaves_no_file_half_written(view_scene, runner, tmp_path):
    root, _ = view_scene
    from PIL import Image

    images = tmp_path / "images"
    images.mkdir()
    Image.new("RGB", (32, 18)).save(images / "000000.png")
    out = tmp_path / "v.rrd"
    result = invoke(runner, "view", root / "gt", "--image", images, "--out", out)
    assert result.exit_code == 2 and "no image named 000001" in result.output
    assert list(tmp_path.iterdir()) == [images]
    (images / "000000.png").write_bytes(b"not an image")  # refused, naming the file, as render does
    result = invoke(runner, "view", root / "gt", "--image", images, "--frames", "0", "--out", out)
    assert result.exit_code == 2 and result.stderr.strip() == f"error: {images / '000000.png'}: not a readable image (not a format Pillow reads)"
    assert list(tmp_path.iterdir()) == [images]


def test_view_without_the_extra_says_which_pip_command_installs_it(runner, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun fails as if not installed
    result = invoke(runner, "view", tmp_path, "--out", tmp_path / "x.rrd")
    assert result.exit_code == 2
    assert result.output.strip().splitlines() == ["error: rotavat view needs the Rerun SDK, which is not installed: "
                                                  "pip install 'rotavat[view]'"]


def test_view_config_section_is_checked(runner, tmp_path):
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump({"view": {"image_plane_m": -1}}))
    result = invoke(runner, "view", tmp_path, "--config", config)
    assert result.exit_code == 2 and "image_plane_m" in result.output


def test_batch_view_writes_one_recording_per_sequence_beside_its_figures(runner, tmp_path):
    pytest.importorskip("rerun")
    import json

    for name, seed in (("a", 1), ("b", 2)):
        write_synth_scene(tmp_path / "synth" / name, SynthOptions(seed=seed, frames=3, people=2, image_size=(320, 180)))
        for side, root in (("pred", "P"), ("gt", "G")):
            (tmp_path / root).mkdir(exist_ok=True)
            shutil.move(tmp_path / "synth" / name / side, tmp_path / root / name)
    out = tmp_path / "out"
    args = ["batch", tmp_path / "P", "--gt-root", tmp_path / "G", "--view", "--jobs", "1", "--out", out, "--quiet"]
    result = invoke(runner, *args)
    assert result.exit_code == 0, result.output
    report = json.loads((out / "batch_report.json").read_text())
    for name in ("a", "b"):
        assert (out / name / "render").is_dir()
        data = _read(out / name / "view.rrd")
        for row in ("input", "aligned", "gt"):
            assert f"/world/{row}/people/0/mesh" in data and f"/world/{row}/people/1/mesh" in data
        assert "/plots/w_mpjpe_mm/aligned/0" in data
    assert {row["sequence"]: row["view"]["frames"] for row in report["rows"]} == {"a": 3, "b": 3}
    again = invoke(runner, *args[:-1])
    assert again.exit_code == 0 and "2 skipped" in again.output


def test_view_of_a_tools_output_without_a_camera_names_commands_that_run(runner, tmp_path, model, model_path, camera,
                                                                        monkeypatch):
    """`view --from bev FILE` without a camera names calibrate and view commands with the reading flags as given;
    both run as written, and the camera file they name lands in the current folder, not the tool's data folder."""
    pytest.importorskip("rerun")
    import shlex

    import _format_fixtures as F

    src = F.write_bev(tmp_path / "data" / "bev", F.default_scene(model, camera), camera.image_size)
    data_before = sorted(p.name for p in (tmp_path / "data").rglob("*"))
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    reader = ["--from", "bev", "--image-size", *map(str, camera.image_size), "--smpl-model", str(model_path)]
    result = invoke(runner, "view", src, *reader)
    assert result.exit_code == 2, result.output
    commands = " ".join(result.stderr.split()).split("`")[1::2]
    assert [c.split()[:2] for c in commands] == [["rotavat", "calibrate"], ["rotavat", "view"]]
    for command in commands:
        run = invoke(runner, *shlex.split(command)[1:], "-q")
        assert run.exit_code == 0, (command, run.stderr)
    assert sorted(p.name for p in (tmp_path / "work").iterdir()) == ["bev_camera.yaml", "bev_view.rrd"]
    assert sorted(p.name for p in (tmp_path / "data").rglob("*")) == data_before
    data = _read(tmp_path / "work" / "bev_view.rrd")
    assert any(path.startswith("/world/bev/people/") for path in data)


def test_spawn_without_a_display_warns_and_keeps_the_recording(view_scene, runner, tmp_path, monkeypatch):
    root, _ = view_scene
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    out = tmp_path / "s.rrd"
    result = invoke(runner, "view", root / "gt", "--out", out, "--spawn", "--quiet")
    assert result.exit_code == 0 and out.is_file()
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning: --spawn")]
    assert len(warnings) == 1 and warnings[0].endswith(f" {out}") and "open the recording where there is one" in warnings[0]


def test_batch_view_without_the_extra_stops_before_any_work(runner, tmp_path, monkeypatch):
    write_synth_scene(tmp_path / "s", SynthOptions(seed=1, frames=2, people=1, image_size=(320, 180)))
    monkeypatch.setitem(sys.modules, "rerun", None)
    result = invoke(runner, "batch", tmp_path / "s", "--view", "--out", tmp_path / "out")
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines()[-1] == ("error: rotavat view needs the Rerun SDK, which is not installed: "
                                                       "pip install 'rotavat[view]'")
    assert not (tmp_path / "out").exists()


def test_a_video_frame_over_the_file_limit_is_refused(view_scene, runner, tmp_path):
    root, _ = view_scene
    images = tmp_path / "images"
    images.mkdir()
    for name in open_sequence(root / "gt").frame_names:
        (images / f"{name}.jpg").write_bytes(b"\xff\xd8" + b"\0" * (2 << 20))  # 2 MB each
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump({"limits": {"max_file_mb": 1}}))
    out = tmp_path / "v.rrd"
    result = invoke(runner, "view", root / "gt", "--image", images, "--out", out, "--config", config)
    assert result.exit_code == 2 and "limits.max_file_mb" in result.stderr and not out.exists()


def test_spawn_opens_the_recording_in_the_viewer(view_scene, runner, tmp_path, monkeypatch):
    import time

    import rotavat_cli.cli.view as view_cli

    root, _ = view_scene
    seen = tmp_path / "viewer_args"
    stub = tmp_path / "rerun"
    stub.write_text(f"#!/bin/sh\necho \"$@\" > {seen}\n")
    stub.chmod(0o755)
    monkeypatch.setattr(view_cli, "_viewer", lambda: str(stub))
    monkeypatch.setenv("DISPLAY", ":99")
    out = tmp_path / "s.rrd"
    result = invoke(runner, "view", root / "gt", "--out", out, "--spawn")
    assert result.exit_code == 0 and f"opened {out} in the Rerun viewer" in result.stdout
    for _ in range(100):  # the viewer runs detached: wait for it
        if seen.exists() and seen.read_text().strip():
            break
        time.sleep(0.05)
    assert seen.read_text().strip() == str(out)


def test_frames_every_image_plane_and_normals_options_reach_the_recording(view_scene, recorded, runner, tmp_path):
    root, _ = view_scene
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump({"view": {"image_plane_m": 2.5, "normals": False}}))
    out = tmp_path / "a.rrd"
    result = invoke(runner, "view", root / "gt", "--every", "2", "--config", config, "--out", out, "--quiet")
    assert result.exit_code == 0, result.stderr
    data = _read(out)
    meshes = [(f, row) for f, row in data["/world/gt/people/0/mesh"] if f is not None]
    assert [f for f, _ in meshes] == [0, 2]  # every 2nd frame, on the frame timeline's own indices
    assert all(row.get("Mesh3D:vertex_normals") is None for _, row in meshes)  # normals: false
    pinhole = next(row for f, row in data["/world/camera/image"] if row.get("Pinhole:image_plane_distance"))
    assert pinhole["Pinhole:image_plane_distance"] == [2.5]
    result = invoke(runner, "view", root / "gt", "--frames", "-1", "--out", out, "--quiet")
    assert result.exit_code == 0 and [f for f, row in _read(out)["/world/gt/people/0/mesh"] if f is not None] == [3]
    with_normals = [row for f, row in recorded[1]["/world/gt/people/0/mesh"] if f is not None]  # the default
    assert all(len(row["Mesh3D:vertex_normals"]) == len(row["Mesh3D:vertex_positions"]) for row in with_normals)


def test_bad_view_arguments_are_one_line_and_exit_2(view_scene, runner, tmp_path):
    root, _ = view_scene
    for args, says in ((["--out", tmp_path / "x.txt"], "--out must end in .rrd"),
                       (["--frames", "0,99", "--out", tmp_path / "x.rrd"], "frame index 99 out of range"),
                       (["--every", "0", "--out", tmp_path / "x.rrd"], "--every: must be >= 1"),
                       (["--out", root / "gt" / "x.rrd"], "inside the input")):
        result = invoke(runner, "view", root / "gt", *args)
        assert result.exit_code == 2, (args, result.output)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:") and says in lines[0], (args, lines)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_an_implausible_camera_is_refused_unless_accepted(view_scene, runner, tmp_path):
    root, scene_camera = view_scene
    bad = tmp_path / "bad.yaml"
    write_camera_yaml(bad, scene_camera, {"method": "refine", "implausible": ["camera height 0.1 m is under 0.3 m"]})
    out = tmp_path / "v.rrd"
    refused = invoke(runner, "view", root / "pred", "--camera", bad, "--out", out)
    assert refused.exit_code == 2 and not out.exists()
    assert "implausible camera (camera height 0.1 m is under 0.3 m)" in refused.stderr
    assert "add --accept-camera to the view command" in refused.stderr
    accepted = invoke(runner, "view", root / "pred", "--camera", bad, "--accept-camera", "--out", out, "--quiet")
    assert accepted.exit_code == 0 and out.is_file()
    assert "used anyway (--accept-camera)" in accepted.stderr


def test_a_row_whose_camera_is_the_scene_camera_but_for_float_noise_gets_no_ground_of_its_own(view_scene, tmp_path):
    """The truth's camera.yaml and the scene camera equal but for float noise (1e-12, kept through YAML): one camera,
    so no note that its own camera gives another ground (it used to be said for cameras 1e-16 apart)."""
    from rotavat_cli.view import ViewOptions, record_sequences

    root, _ = view_scene
    gt = open_sequence(root / "gt")
    noisy = gt.camera.replace(focal_px=gt.camera.focal_px * (1 + 1e-12), pitch_rad=gt.camera.pitch_rad + 1e-12)
    write_camera_yaml(tmp_path / "same.yaml", noisy)
    summary = record_sequences([open_sequence(root / "pred_aligned")], tmp_path / "s.rrd", gt,
                               ViewOptions(camera_path=tmp_path / "same.yaml"))
    assert not [n for n in summary.notes if "gives its ground" in n]
    other = gt.camera.replace(height_m=gt.camera.height_m + 0.3)
    write_camera_yaml(tmp_path / "other.yaml", other)
    summary = record_sequences([open_sequence(root / "pred_aligned")], tmp_path / "o.rrd", gt,
                               ViewOptions(camera_path=tmp_path / "other.yaml"))
    assert [n for n in summary.notes if n.startswith("gt: placed in the scene camera")]
