"""Camera model: signs, hand-checked numbers and round trips."""

import numpy as np
import pytest

from rotavat_cli.geometry.camera import (Camera, backproject_px_to_plane, camera_from_yaml_dict, camera_to_yaml_dict,
                                pitch_roll_from_up, project_cam_to_px, up_vector_cam)


def make_camera(pitch_deg=30.0, roll_deg=0.0, height=5.0, focal=1000.0, size=(1920, 1080), pp=None):
    return Camera(size, focal, pp, np.deg2rad(pitch_deg), np.deg2rad(roll_deg), height)


def test_up_vector_level_camera_is_minus_y():
    np.testing.assert_allclose(up_vector_cam(0.0, 0.0), [0.0, -1.0, 0.0], atol=1e-15)


def test_up_vector_pitched_down_points_back():
    n = up_vector_cam(np.deg2rad(30.0), 0.0)
    np.testing.assert_allclose(n, [0.0, -np.cos(np.deg2rad(30)), -0.5], atol=1e-15)


def test_optical_axis_hits_ground_at_h_over_tan_pitch():
    cam = make_camera(30.0, 0.0, 5.0)
    ground_cam = cam.backproject_px_to_ground(np.array(cam.principal_point))
    ground_world = cam.world_from_cam(ground_cam)
    # straight ahead of the camera: world -Z, horizontal distance h / tan(pitch)
    np.testing.assert_allclose(ground_world, [0.0, 0.0, -5.0 / np.tan(np.deg2rad(30.0))], atol=1e-12)
    np.testing.assert_allclose(ground_cam, [0.0, 0.0, 10.0], atol=1e-12)


def test_camera_centre_height_and_world_origin():
    cam = make_camera(20.0, 4.0, 7.5)
    assert cam.height_above_ground(np.zeros(3)) == pytest.approx(7.5)
    np.testing.assert_allclose(cam.cam_from_world(cam.center_world), 0.0, atol=1e-12)
    np.testing.assert_allclose(cam.height_above_ground(cam.t_cam_from_world), 0.0, atol=1e-12)


def test_world_axes_follow_the_contract():
    cam = make_camera(25.0, 3.0, 6.0)
    R = cam.R_cam_from_world
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 1], cam.up_cam, atol=1e-15)  # world Y = up
    assert R[0, 0] > 0.99  # world X ~ camera x
    assert R[2, 2] < 0  # camera looks along world -Z


def test_pitch_roll_round_trip():
    rng = np.random.default_rng(0)
    pitch = rng.uniform(-1.2, 1.5, 100)
    roll = rng.uniform(-0.5, 0.5, 100)
    p2, r2 = pitch_roll_from_up(up_vector_cam(pitch, roll) * 3.0)
    np.testing.assert_allclose(p2, pitch, atol=1e-12)
    np.testing.assert_allclose(r2, roll, atol=1e-12)


def test_positive_roll_sign():
    # roll > 0 tilts world up toward camera -x, so a vertical line leans left in the image
    n = up_vector_cam(0.0, np.deg2rad(10.0))
    assert n[0] < 0 and n[1] < 0


def test_project_backproject_round_trip():
    rng = np.random.default_rng(1)
    cam = make_camera(35.0, -2.0, 8.0, pp=(950.0, 530.0))
    px = np.stack([rng.uniform(0, 1920, 500), rng.uniform(700, 1080, 500)], axis=-1)
    ground = cam.backproject_px_to_ground(px)
    assert np.all(np.isfinite(ground))
    np.testing.assert_allclose(cam.height_above_ground(ground), 0.0, atol=1e-9)
    np.testing.assert_allclose(cam.project(ground), px, atol=1e-9)


def test_backproject_onto_plane_at_height():
    cam = make_camera(30.0, 0.0, 5.0)
    px = np.array([[960.0, 900.0], [100.0, 1000.0]])
    pts = cam.backproject_px_to_ground(px, plane_height_m=1.7)
    np.testing.assert_allclose(cam.height_above_ground(pts), 1.7, atol=1e-12)
    np.testing.assert_allclose(cam.project(pts), px, atol=1e-9)


def test_ray_above_horizon_gives_nan():
    cam = make_camera(10.0, 0.0, 5.0)
    assert np.all(np.isnan(cam.backproject_px_to_ground(np.array([960.0, 0.0]))))
    v = cam.horizon_v_px(960.0)
    assert v == pytest.approx(540.0 - 1000.0 * np.tan(np.deg2rad(10.0)))
    below = cam.backproject_px_to_ground(np.array([960.0, v + 1.0]))
    above = cam.backproject_px_to_ground(np.array([960.0, v - 1.0]))
    assert np.all(np.isfinite(below)) and np.all(np.isnan(above))


def test_project_behind_camera_is_nan():
    uv = project_cam_to_px(np.array([[0.0, 0.0, -1.0], [1.0, 2.0, 4.0]]), 100.0, (50.0, 40.0))
    assert np.all(np.isnan(uv[0]))
    np.testing.assert_allclose(uv[1], [75.0, 90.0])


def test_broadcasting_over_parameter_grid():
    f = np.array([500.0, 1000.0])[:, None]
    up = up_vector_cam(np.deg2rad([20.0, 40.0]), 0.0)[:, None, :]
    px = np.array([[[320.0, 400.0], [100.0, 470.0], [600.0, 300.0]]])
    pts = backproject_px_to_plane(px, f, (320.0, 240.0), up, np.array([3.0, 6.0])[:, None])
    assert pts.shape == (2, 3, 3)


def test_yaml_round_trip_and_extrinsics():
    cam = make_camera(22.0, 1.5, 6.3, focal=1234.5, pp=(955.0, 541.0))
    d = camera_to_yaml_dict(cam, fit={"method": "grid"})
    cam2 = camera_from_yaml_dict(d)
    for name in ("focal_px", "pitch_rad", "roll_rad", "height_m"):
        assert getattr(cam2, name) == pytest.approx(getattr(cam, name), abs=1e-12)
    assert cam2.principal_point == cam.principal_point
    # from extrinsics only
    only_rt = {k: d[k] for k in ("image_size", "focal_px", "principal_point", "R_world_to_cam", "t_world_to_cam")}
    cam3 = camera_from_yaml_dict(only_rt)
    assert cam3.pitch_rad == pytest.approx(cam.pitch_rad) and cam3.height_m == pytest.approx(cam.height_m)
    assert cam3.roll_rad == pytest.approx(cam.roll_rad)


def test_yaml_errors_name_the_key():
    with pytest.raises(ValueError, match="focal_px"):
        camera_from_yaml_dict({"image_size": [10, 10], "pitch_deg": 1, "height_m": 2})
    with pytest.raises(ValueError, match="up_cam"):
        camera_from_yaml_dict({"image_size": [10, 10], "focal_px": 5, "pitch_deg": 10, "height_m": 2, "up_cam": [0, 1, 0]})
    with pytest.raises(ValueError, match="height"):
        camera_from_yaml_dict({"image_size": [10, 10], "focal_px": 5, "pitch_deg": 10, "height_m": -2})


def test_realdata_camera_gt_is_self_consistent():
    from pathlib import Path

    import yaml

    path = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "towncentre" / "camera_gt.yaml"
    if not path.exists():
        pytest.skip("shared/realdata not present")
    d = yaml.safe_load(path.read_text())
    cam = camera_from_yaml_dict(d)
    np.testing.assert_allclose(cam.R_cam_from_world, d["R_world_to_cam"], atol=1e-9)
    np.testing.assert_allclose(cam.t_cam_from_world, d["t_world_to_cam"], atol=1e-9)


def test_derived_arrays_are_cached_read_only_also_in_a_worker():
    """K, up, R, t are derived once and shared read-only; a pickled camera (a worker's copy) re-derives them."""
    import pickle

    cam = Camera((640, 480), 500.0, None, 0.3, 0.1, 5.0)
    for name in ("K", "up_cam", "R_cam_from_world", "t_cam_from_world"):
        first = getattr(cam, name)
        assert getattr(cam, name) is first and not first.flags.writeable, name
        with pytest.raises(ValueError):
            first[0] = 0.0
    copy = pickle.loads(pickle.dumps(cam))
    assert copy == cam and "K" not in vars(copy)
    for name in ("K", "up_cam", "R_cam_from_world", "t_cam_from_world"):
        assert not getattr(copy, name).flags.writeable, name
        np.testing.assert_array_equal(getattr(copy, name), getattr(cam, name))
