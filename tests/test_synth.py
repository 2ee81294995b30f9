"""Synthetic scenes: determinism, truth of the landmarks, the prediction's failure modes."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.bodies.landmarks import _points_by_geometry, foot_head_points, ground_contact
from rotavat_cli.sequence import open_sequence
from rotavat_cli.synth.bodies import load_bodies
from rotavat_cli.synth.scene import SynthOptions, _pose_bodies, random_camera, synth_frames


def test_synth_is_deterministic(tmp_path, runner):
    for name in ("a", "b"):
        assert invoke(runner, "synth", tmp_path / name, "--seed", "3", "--frames", "2", "--people", "3", "-q").exit_code == 0
    assert tree_hash(tmp_path / "a") == tree_hash(tmp_path / "b")
    invoke(runner, "synth", tmp_path / "c", "--seed", "4", "--frames", "2", "--people", "3", "-q")
    assert tree_hash(tmp_path / "a") != tree_hash(tmp_path / "c")


def test_synth_layout_and_contract(tmp_path, runner):
    result = invoke(runner, "synth", tmp_path / "s", "--frames", "3", "--people", "4", "--image-size", "640", "480", "--json")
    assert result.exit_code == 0
    gt, pred = open_sequence(tmp_path / "s" / "gt"), open_sequence(tmp_path / "s" / "pred")
    assert gt.camera is not None and pred.camera is None
    assert len(gt) == len(pred) == 3 and gt.image_size == (640, 480)
    frame = pred.read_frame("000001")
    assert frame.data["vertices"].dtype == np.float32 and frame.data["joints"].shape == (4, 24, 3)
    np.testing.assert_array_equal(frame.person_ids, np.arange(4))
    # the prediction is made with CLIFF's focal guess (the default), and says it is a guess
    assert pred.intrinsics.focal_px == pytest.approx(800.0) and pred.focal_kind == "assumed"
    assert pred.meta["focal_rule"] == "cliff"
    assert gt.intrinsics.focal_px == gt.camera.focal_px and gt.focal_kind == "camera"
    hfov = np.degrees(2 * np.arctan(320 / gt.camera.focal_px))
    assert 45.0 <= hfov <= 100.0


@pytest.mark.parametrize("rule,focal", [("cliff", np.hypot(1280, 720)), ("bev", 443.4 / 512 * 1280),
                                        ("romp", 640 / np.tan(np.radians(30))), ("4dhumans", 5000 / 256 * 1280),
                                        ("2000", 2000.0), ("true", None)])
def test_hps_focal_rules_place_a_rigid_body_on_its_pixels(rule, focal):
    opts = SynthOptions(seed=1, frames=1, people=5, hps_focal=rule, depth_sd=0.0, lean=0.0, noise_3d_m=0.0)
    camera, hps_focal, frames = synth_frames(opts)
    assert hps_focal == pytest.approx(camera.focal_px if focal is None else focal)
    gt, pred = next(frames)
    hps_camera = camera.replace(focal_px=hps_focal)
    verts_gt, verts_pred = (f.data["vertices"].astype(np.float64) for f in (gt, pred))
    (feet_gt, heads_gt), (feet_p, heads_p) = foot_head_points(verts_gt), foot_head_points(verts_pred)
    # the method draws the true foot and crown pixels (it is fitted to the image) ...
    np.testing.assert_allclose(hps_camera.project(feet_p), camera.project(feet_gt), atol=0.02)
    np.testing.assert_allclose(hps_camera.project(heads_p), camera.project(heads_gt), atol=0.02)
    # ... with a rigid, undistorted body: every distance is the true one times one size per person
    def distances(v):
        return np.linalg.norm(v[:, ::400, None] - v[:, None, ::400], axis=-1)
    size = np.linalg.norm(heads_p - feet_p, axis=-1) / np.linalg.norm(heads_gt - feet_gt, axis=-1)
    np.testing.assert_allclose(distances(verts_pred), size[:, None, None] * distances(verts_gt), atol=5e-6 * hps_focal / 100)
    # ... at F / f times the (size-scaled) depth (the root's, moved along with the body: ~1%)
    mid = lambda f, h: 0.5 * (f[:, 2] + h[:, 2])  # noqa: E731
    np.testing.assert_allclose(mid(feet_p, heads_p) / mid(feet_gt, heads_gt), size * hps_focal / camera.focal_px, rtol=1e-2)


def test_hps_focal_bad_values_exit_2(tmp_path, runner):
    for bad in ("-5", "nosuchrule", "0"):
        result = invoke(runner, "synth", tmp_path / "s", "--hps-focal", bad)
        assert result.exit_code == 2 and "hps-focal" in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_ground_truth_people_stand_on_the_ground():
    opts = SynthOptions(seed=2, frames=2, people=10)
    camera, _, frames = synth_frames(opts)
    for gt, _ in frames:
        feet, heads = foot_head_points(gt.data["vertices"].astype(np.float64))
        assert np.all(np.abs(camera.height_above_ground(feet)) < 0.01)
        statures = camera.height_above_ground(heads)
        assert np.all((statures > 1.4) & (statures < 2.1))


def test_prediction_leans_and_errs_in_depth():
    opts = SynthOptions(seed=5, frames=1, people=20, depth_sd=0.1, hps_focal="true")
    camera, _, frames = synth_frames(opts)
    gt, pred = next(frames)
    feet_gt, heads_gt = foot_head_points(gt.data["vertices"].astype(np.float64))
    feet_p, heads_p = foot_head_points(pred.data["vertices"].astype(np.float64))
    lean = np.degrees(np.arccos(np.sum((heads_p - feet_p) * camera.up_cam, -1) / np.linalg.norm(heads_p - feet_p, axis=-1)))
    assert np.median(lean) > 3.0  # leaning toward the image plane
    assert np.median(np.abs(camera.height_above_ground(feet_p))) > 0.05  # floating or sunk
    # image right: foot and crown pixels move by the 3D noise only
    body_px = np.linalg.norm(camera.project(heads_gt) - camera.project(feet_gt), axis=-1)
    for pred_cam, gt_cam in ((feet_p, feet_gt), (heads_p, heads_gt)):
        shift = np.linalg.norm(camera.project(pred_cam) - camera.project(gt_cam), axis=-1)
        assert np.all(shift < 0.03 * body_px)


@pytest.mark.parametrize("geometry", [False, True])
def test_landmarks_match_generator_truth(geometry):
    library = load_bodies()
    rng = np.random.default_rng(0)
    camera = random_camera(rng, (1280, 720))
    P = len(library)
    pos = camera.world_from_cam(camera.backproject_px_to_ground(np.stack([np.linspace(200, 1000, P), np.full(P, 650.0)], -1)))
    scale = rng.uniform(0.95, 1.05, P)
    verts, _ = _pose_bodies(library, np.arange(P), scale, rng.uniform(-np.pi, np.pi, P), pos, camera)
    if geometry:
        left, right, heads, ok = _points_by_geometry(verts, np.tile(camera.up_cam, (P, 1)))
        assert np.all(ok)
        feet = ground_contact(left, right, heads)
    else:
        feet, heads = foot_head_points(verts)
    truth_feet = camera.cam_from_world(pos)
    heights = camera.height_above_ground(verts)
    truth_heads = verts[np.arange(P), np.argmax(heights, axis=1)]
    # the registered topology meets the 1 cm; geometry mode (any mesh) takes the centre of
    # the footprint / head-top patch, within 2 cm of the generator's vertex definitions
    tol = 0.02 if geometry else 0.01
    np.testing.assert_array_less(np.linalg.norm(feet - truth_feet, axis=-1), tol)
    np.testing.assert_array_less(np.linalg.norm(heads - truth_heads, axis=-1), tol)


def test_make_sample_rebuilds_the_committed_sample_byte_for_byte(tmp_path, runner):
    """The Makefile's `make sample` command, run into a fresh folder, writes exactly sample_data/scene."""
    import re
    import shlex

    root = Path(__file__).resolve().parents[1]
    recipe = re.search(r"^sample:.*\n(?:\t.*\n)*?\t\$\(BIN\)/rotavat synth \$\(SAMPLE\)/scene (.*)$",
                       (root / "Makefile").read_text(), re.MULTILINE)
    assert recipe, "the Makefile's sample target"
    result = invoke(runner, "synth", tmp_path / "scene", *shlex.split(recipe.group(1)))
    assert result.exit_code == 0, result.stderr
    committed = root / "sample_data" / "scene"
    made = sorted(p.relative_to(tmp_path / "scene") for p in (tmp_path / "scene").rglob("*") if p.is_file())
    assert made == sorted(p.relative_to(committed) for p in committed.rglob("*") if p.is_file())
    for rel in made:
        assert (tmp_path / "scene" / rel).read_bytes() == (committed / rel).read_bytes(), rel


# ---- layouts: one-depth scenes (walk, row) and the camera's height/pitch ranges ----------------------
HANDHELD = {"camera_height_range_m": (1.2, 2.0), "pitch_range_deg": (-5.0, 15.0)}


def _gt_feet_heads(opts: SynthOptions):
    """The true camera and, over every frame, the gt's feet (N, 3) world frame and foot/crown pixels (N, 2)."""
    camera, _, frames = synth_frames(opts)
    feet, feet_px, heads_px = [], [], []
    for gt, _ in frames:
        f, _ = foot_head_points(gt.data["vertices"].astype(np.float64))
        feet.append(camera.world_from_cam(f))
        feet_px.append(gt.data["feet_2d"])
        heads_px.append(gt.data["heads_2d"])
    return camera, np.concatenate(feet), np.concatenate(feet_px), np.concatenate(heads_px)


def _assert_in_view(camera, *points_px):
    W, H = camera.image_size
    for px in points_px:
        assert np.all((px[:, 0] >= 0) & (px[:, 0] <= W) & (px[:, 1] >= 0) & (px[:, 1] <= H))


@pytest.mark.parametrize("camera_kind", ["surveillance", "handheld"])
@pytest.mark.parametrize("seed", [1, 2])
def test_row_stands_at_one_depth_in_view(seed, camera_kind):
    from rotavat_cli.synth.layouts import view_axes_world

    opts = SynthOptions(seed=seed, frames=2, people=8, layout="row", image_size=(1920, 1080),
                        **(HANDHELD if camera_kind == "handheld" else {}))
    camera, feet, feet_px, heads_px = _gt_feet_heads(opts)
    along, across = view_axes_world(camera)
    assert np.ptp(feet @ along) < 0.3  # one depth (jitter of a few cm)
    side = np.sort(feet[:8] @ across)
    np.testing.assert_allclose(np.diff(side), 0.6, atol=0.25)  # side by side, ~0.6 m apart
    np.testing.assert_allclose(feet[:8], feet[8:], atol=1e-9)  # standing still
    _assert_in_view(camera, feet_px, heads_px)
    size_h = np.median(np.linalg.norm(heads_px - feet_px, axis=-1)) / camera.image_size[1]
    if camera_kind == "handheld":  # a surveillance camera high up sees people smaller than that wherever they stand
        assert 0.25 <= size_h <= 0.75
    hfov = np.degrees(camera.horizontal_fov_rad)
    assert 45.0 <= hfov <= 100.0
    assert 1.2 <= camera.height_m <= 2.0 if camera_kind == "handheld" else 2.5 <= camera.height_m <= 15.0


@pytest.mark.parametrize("camera_kind", ["surveillance", "handheld"])
@pytest.mark.parametrize("seed", [3, 4])
def test_walk_crosses_the_view_at_one_image_row(seed, camera_kind):
    kind = HANDHELD if camera_kind == "handheld" else {}
    opts = SynthOptions(seed=seed, frames=24, people=1, layout="walk", image_size=(1920, 1080), roll_deg=0.0, **kind)
    camera, feet, feet_px, heads_px = _gt_feet_heads(opts)
    person_px = np.median(np.linalg.norm(heads_px - feet_px, axis=-1))
    assert np.ptp(feet_px[:, 1]) < 0.05 * person_px  # roll 0: every foot on one image row
    assert np.ptp(feet_px[:, 0]) > 2 * person_px  # walking across the view
    _assert_in_view(camera, feet_px, heads_px)
    # with a roll, the track is still at one depth: its feet on a line parallel to the horizon
    from rotavat_cli.synth.layouts import view_axes_world

    camera, feet, feet_px, heads_px = _gt_feet_heads(dataclasses.replace(opts, roll_deg=None))
    assert abs(np.degrees(camera.roll_rad)) > 0.1
    along, _ = view_axes_world(camera)
    assert np.ptp(feet @ along) < 0.05
    _assert_in_view(camera, feet_px, heads_px)


def test_still_people_stand_about_their_places_at_many_depths():
    """The ``still`` layout: each person sways a few centimetres about one place (STILL_SWAY_M per frame and ground
    axis), and the places spread over the depths the camera sees (not one row: the calibration's hard case)."""
    from rotavat_cli.synth.layouts import STILL_SWAY_M

    opts = SynthOptions(seed=3, frames=30, people=10, layout="still", image_size=(1920, 1080))
    camera, feet, feet_px, heads_px = _gt_feet_heads(opts)
    places = feet.reshape(30, 10, 3)
    sway = places - places.mean(axis=0)
    assert 0.6 * STILL_SWAY_M < sway[..., [0, 2]].std() < 1.4 * STILL_SWAY_M and np.abs(sway).max() < 6 * STILL_SWAY_M
    depth = np.linalg.norm(places.mean(axis=0)[:, [0, 2]], axis=-1)
    assert depth.max() > 1.5 * depth.min()


@pytest.mark.parametrize("layout", ["walk", "row", "still"])
def test_layouts_are_deterministic_and_keep_the_rest(tmp_path, runner, layout):
    args = ["--seed", "5", "--frames", "2", "--people", "3", "--layout", layout, "--camera-height-range", "1.2", "2",
            "--pitch-range", "-5", "15", "-q"]
    for name in ("a", "b"):
        assert invoke(runner, "synth", tmp_path / name, *args).exit_code == 0
    assert tree_hash(tmp_path / "a") == tree_hash(tmp_path / "b")
    # the layout and camera ranges are recorded; the prediction is the usual one (CLIFF's focal, leaning)
    params = (tmp_path / "a" / "synth.yaml").read_text()
    assert f"layout: {layout}" in params and "camera_height_range_m: [1.2, 2.0]" in params
    assert "pitch_range_deg: [-5.0, 15.0]" in params
    pred = open_sequence(tmp_path / "a" / "pred")
    assert pred.meta["focal_rule"] == "cliff" and len(pred) == 2
    assert 1.2 <= open_sequence(tmp_path / "a" / "gt").camera.height_m <= 2.0


def test_crowd_is_the_default_and_unchanged():
    assert SynthOptions().layout == "crowd"
    opts = SynthOptions(seed=2, frames=2, people=4)
    camera, _, frames = synth_frames(opts)
    explicit = SynthOptions(seed=2, frames=2, people=4, layout="crowd", camera_height_range_m=(2.5, 15.0),
                            pitch_range_deg=(10.0, 60.0))
    camera2, _, frames2 = synth_frames(explicit)
    assert camera == camera2
    for (gt, _), (gt2, _) in zip(frames, frames2):
        np.testing.assert_array_equal(gt.data["vertices"], gt2.data["vertices"])


@pytest.mark.parametrize("args,where", [(["--layout", "circle"], "layout"),
                                        (["--pitch-range", "30", "10"], "pitch"),
                                        (["--camera-height-range", "0", "2"], "camera"),
                                        (["--pitch-range", "-95", "10"], "pitch")])
def test_bad_layout_options_exit_2(tmp_path, runner, args, where):
    result = invoke(runner, "synth", tmp_path / "s", *args)
    assert result.exit_code == 2 and where in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists()
