"""Synthetic scenes: determinism, truth of the landmarks, the prediction's failure modes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import invoke, tree_hash

from rotavat_cli.landmarks import _points_by_geometry, foot_head_points
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
        feet, heads, ok = _points_by_geometry(verts, np.tile(camera.up_cam, (P, 1)))
        assert np.all(ok)
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
