"""The camera's lens (issue 35, point 1): the division model of rotavat_cli.geometry.lens, carried by the Camera,
read and written in camera.yaml, and applied by the measurement."""

from __future__ import annotations

import csv
import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml
from _cli import invoke
from scipy.optimize import brentq

from rotavat_cli.bodies.measure import statures_from_camera_m
from rotavat_cli.calibration.model import undistort
from rotavat_cli.geometry.camera import Camera, camera_from_yaml_dict, camera_to_yaml_dict
from rotavat_cli.geometry.lens import distort_px, lens_radius_px, undistort_px
from rotavat_cli.sequence import Frame, write_camera_yaml, write_frame, write_meta

SIZE = (1280, 720)
PP = (610.0, 380.0)  # off the image centre: the lens is about the principal point
R = lens_radius_px(SIZE)


def _lens_camera(distortion: float) -> Camera:
    return Camera(SIZE, 1000.0, PP, np.deg2rad(24.0), np.deg2rad(3.0), 6.0, distortion=distortion)


# ---- lens.py ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("lam", [-0.5, -0.25, -0.03, 0.0, 0.1, 0.2, 0.5])
def test_distort_undistort_round_trip(lam):
    rng = np.random.default_rng(35)
    pts = np.stack([rng.uniform(0, SIZE[0], 2000), rng.uniform(0, SIZE[1], 2000)], axis=-1)  # image pixels
    back = distort_px(undistort_px(pts, lam, PP, R), lam, PP, R)
    assert np.abs(back - pts).max() < 1e-9
    # and the other way round, for pinhole pixels the lens can image
    pinhole = undistort_px(pts, lam, PP, R)
    assert np.abs(undistort_px(distort_px(pinhole, lam, PP, R), lam, PP, R) - pinhole).max() < 1e-9


def test_the_closed_form_inverse_is_the_numeric_root():
    rng = np.random.default_rng(7)
    for lam in (-0.4, -0.1, 0.15, 0.45):
        for r_u in rng.uniform(0.0, 1.0, 20) * (R if lam < 0 else R / (2 * np.sqrt(lam))):
            # the root of r_d / (1 + lam r_d^2 / R^2) = r_u on the branch through 0 (r_d below the turning point)
            r_max = R / np.sqrt(-lam) * (1 - 1e-12) if lam < 0 else R / np.sqrt(lam)
            numeric = brentq(lambda r: r / (1 + lam * r * r / R**2) - r_u, 0.0, r_max, xtol=1e-14, rtol=1e-15)
            closed = distort_px(np.array([PP[0] + r_u, PP[1]]), lam, PP, R)[0] - PP[0]
            assert closed == pytest.approx(numeric, abs=1e-9)


def test_no_real_inverse_is_nan_and_lam_zero_is_the_identity():
    lam = 0.2  # the undistorted radius peaks at R / (2 sqrt(lam))
    beyond = np.array([PP[0] + 1.01 * R / (2 * np.sqrt(lam)), PP[1]])
    assert np.isnan(distort_px(beyond, lam, PP, R)).all()
    assert np.isnan(undistort_px(np.array([PP[0] + 1.5 * R, PP[1]]), -0.5, PP, R)).all()  # past 1 + lam r^2 = 0
    pts = np.random.default_rng(0).uniform(0, 700, (50, 2))
    for f in (undistort_px, distort_px):  # about the principal point: within rounding (the Camera skips a zero lens)
        np.testing.assert_allclose(f(pts, 0.0, PP, R), pts, rtol=0, atol=1e-12)


def test_the_calibration_model_uses_the_same_formula():
    rng = np.random.default_rng(3)
    feet, diff = rng.uniform(-500, 500, (30, 2)), rng.uniform(-80, 80, (30, 2))  # pixels in reach of the lens
    lam = np.array([[-0.3], [0.0], [0.2]])
    got_feet, got_diff = undistort(feet, diff, lam, R)
    for q in range(3):
        f_u = undistort_px(feet + PP, lam[q, 0], PP, R) - PP
        h_u = undistort_px(feet - diff + PP, lam[q, 0], PP, R) - PP
        np.testing.assert_allclose(got_feet[q], f_u, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got_diff[q], f_u - h_u, rtol=0, atol=1e-9)


# ---- Camera ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("lam", [-0.3, 0.2])
def test_project_then_backproject_to_the_ground_round_trip(lam):
    cam = _lens_camera(lam)
    rng = np.random.default_rng(11)
    px = np.stack([rng.uniform(0, SIZE[0], 500), rng.uniform(0.45 * SIZE[1], SIZE[1], 500)], axis=-1)
    ground = cam.backproject_px_to_ground(px)
    assert np.isfinite(ground).all()
    np.testing.assert_allclose(cam.height_above_ground(ground), 0.0, atol=1e-9)
    np.testing.assert_allclose(cam.project(ground), px, rtol=0, atol=1e-9)
    pinhole_px = cam.pinhole.project(ground)  # the lens moves the image points (more at the edges)
    assert np.abs(pinhole_px - px).max() > 20.0
    rays = cam.pixel_rays_cam(px)
    np.testing.assert_allclose(np.cross(rays, ground), 0.0, atol=1e-9)  # the ray through the pixel holds the point
    # the horizon: pixels on it see level rays
    u = np.linspace(0, SIZE[0], 9)
    v = cam.horizon_v_px(u)
    np.testing.assert_allclose(cam.pixel_rays_cam(np.stack([u, v], -1)) @ cam.up_cam, 0.0, atol=1e-12)


def test_distortion_zero_is_the_pinhole_bit_for_bit():
    lens = _lens_camera(0.0)
    rng = np.random.default_rng(5)
    px = rng.uniform(0, 700, (40, 2))
    pts = rng.normal(0, 2, (40, 3)) + [0, 0, 10]
    from rotavat_cli.geometry.camera import backproject_px_to_plane, horizon_v_px, pixel_rays_cam, project_cam_to_px

    assert np.array_equal(lens.project(pts), project_cam_to_px(pts, lens.focal_px, lens.principal_point))
    assert np.array_equal(lens.pixel_rays_cam(px), pixel_rays_cam(px, lens.focal_px, lens.principal_point))
    assert np.array_equal(lens.backproject_px_to_ground(px), backproject_px_to_plane(
        px, lens.focal_px, lens.principal_point, lens.up_cam, lens.height_m), equal_nan=True)
    assert np.array_equal(lens.horizon_v_px(px[:, 0]), horizon_v_px(px[:, 0], lens.focal_px, lens.principal_point, lens.up_cam))
    assert lens.pinhole is lens


def test_matches_pickle_and_validation():
    cam = _lens_camera(-0.2)
    assert cam.matches(cam.replace(distortion=-0.2 + 1e-15)) and not cam.matches(cam.replace(distortion=-0.21))
    assert not cam.matches(cam.pinhole)
    copy = pickle.loads(pickle.dumps(cam))
    assert copy == cam and copy.distortion == -0.2
    for bad in (np.inf, np.nan, 0.9, -0.51):
        with pytest.raises(ValueError, match="distortion"):
            cam.replace(distortion=bad)


# ---- camera.yaml -----------------------------------------------------------------------------------------
def test_camera_yaml_round_trip_of_the_lens():
    cam = _lens_camera(-0.125)
    d = camera_to_yaml_dict(cam, {"method": "refine", "distortion": -0.125})
    assert d["distortion"] == -0.125
    back = camera_from_yaml_dict(yaml.safe_load(yaml.safe_dump(d)))
    assert back.matches(cam) and back.distortion == -0.125
    assert "distortion" not in camera_to_yaml_dict(cam.pinhole)  # a pinhole's file is what it always was
    assert camera_from_yaml_dict(camera_to_yaml_dict(cam.pinhole)).distortion == 0.0


def test_a_legacy_camera_yaml_with_only_fit_distortion_has_that_lens():
    d = camera_to_yaml_dict(_lens_camera(0.0), {"method": "refine", "distortion": -0.07, "std": {"distortion": 0.01}})
    assert "distortion" not in d
    assert camera_from_yaml_dict(d).distortion == -0.07
    d["fit"]["distortion"] = None  # not fitted
    assert camera_from_yaml_dict(d).distortion == 0.0
    d["distortion"] = 0.03  # the camera's own key wins
    d["fit"]["distortion"] = -0.07
    assert camera_from_yaml_dict(d).distortion == 0.03


def test_another_lens_models_description_is_not_read():
    d = camera_to_yaml_dict(_lens_camera(0.0))
    d["distortion"] = {"model": "opencv_k1_k2_p1_p2", "params": {"k1": -0.6}}  # the real-data answer keys
    assert camera_from_yaml_dict(d).distortion == 0.0


@pytest.mark.parametrize("bad", [float("inf"), 0.9, -0.7, "barrel"])
def test_a_bad_distortion_names_the_key(bad):
    d = camera_to_yaml_dict(_lens_camera(0.0))
    with pytest.raises(ValueError, match="'distortion'"):
        camera_from_yaml_dict({**d, "distortion": bad})
    with pytest.raises(ValueError, match="'fit.distortion'"):
        camera_from_yaml_dict({**d, "fit": {"distortion": bad}})


# ---- measurement -----------------------------------------------------------------------------------------
def _people_over_the_image(cam: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot and crown pixels (N, 2) (distorted: made by Camera.project) of people of statures (N,) 1.55-1.95 m
    standing on a grid of ground points whose feet cover the lower image, out to its corners."""
    u, v = np.meshgrid(np.linspace(20, SIZE[0] - 20, 9), np.linspace(0.5 * SIZE[1], SIZE[1] - 10, 5))
    grid_px = np.stack([u.ravel(), v.ravel()], axis=-1)
    ground = cam.backproject_px_to_ground(grid_px)
    statures = np.linspace(1.55, 1.95, len(ground))
    return cam.project(ground), cam.project(ground + statures[:, None] * cam.up_cam), statures


def test_statures_through_a_barrel_lens_are_recovered():
    cam = _lens_camera(-0.25)
    feet, heads, statures = _people_over_the_image(cam)
    assert np.isfinite(heads).all() and (heads[:, 1] > 0).mean() > 0.9  # crowns (nearly all) in the image
    np.testing.assert_allclose(statures_from_camera_m(feet, heads, cam), statures, rtol=0, atol=1e-6)
    # the pinhole measurement of the same pixels (what rotavat did before the camera carried its lens): cm off
    pinhole = statures_from_camera_m(feet, heads, cam.replace(distortion=0.0))
    assert np.nanmax(np.abs(pinhole - statures)) > 0.03


STATURES = {3: 1.55, 8: 1.74, 21: 1.95}


@pytest.fixture
def lens_seq(tmp_path: Path) -> tuple[Path, Path]:
    """A 2D sequence of three tracked people seen through a barrel lens (pixels from Camera.project), and the
    camera's camera.yaml (beside it, with its top-level distortion)."""
    cam = _lens_camera(-0.25)
    out = tmp_path / "walk"
    out.mkdir()
    for t in range(4):
        ids = np.array(list(STATURES))
        feet_px = np.array([[40.0 + 30 * t, 700.0 - 10 * t], [1240.0 - 20 * t, 690.0], [640.0 + 50 * t, 420.0 + 40 * t]])
        ground = cam.backproject_px_to_ground(feet_px)
        heads = cam.project(ground + np.array([STATURES[i] for i in ids])[:, None] * cam.up_cam)
        write_frame(out, Frame(f"{t:06d}", {"feet_2d": cam.project(ground), "heads_2d": heads, "person_ids": ids}),
                    "npz")
    write_meta(out, {"image_size": list(SIZE)})
    camera_yaml = tmp_path / "cam.yaml"
    write_camera_yaml(camera_yaml, cam, {"implausible": []})
    return out, camera_yaml


def test_measure_cli_applies_the_cameras_lens(lens_seq, tmp_path, runner):
    seq, camera_yaml = lens_seq
    assert yaml.safe_load(camera_yaml.read_text())["distortion"] == -0.25
    out = tmp_path / "statures.csv"
    result = invoke(runner, "measure", seq, "--camera", camera_yaml, "--out", out)
    assert result.exit_code == 0, result.stderr
    with open(out, newline="") as handle:
        rows = {int(r["track_id"]): float(r["median_stature_m"]) for r in csv.DictReader(handle)}
    assert rows == pytest.approx(STATURES, abs=1e-6)
