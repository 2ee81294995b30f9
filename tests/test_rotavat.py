"""RotAvat invariants on random cameras and meshes, flags, and the sequence-level align."""

from __future__ import annotations

import numpy as np
import pytest

from rotavat_cli.alignment.transform import FLAGS, apply_transforms, rotavat_transforms
from rotavat_cli.geometry.camera import Camera

TOL = 1e-6  # relative, per the issue: geometry is float64, errors are ~1e-12 in practice


def random_camera(rng) -> Camera:
    return Camera((1280, 720), rng.uniform(500, 2000), None, np.deg2rad(rng.uniform(5, 70)),
                  np.deg2rad(rng.uniform(-5, 5)), rng.uniform(2, 15))


def random_people(rng, cam: Camera, P: int):
    """Foot/head points of people in view, at a wrong depth and leaning at random."""
    px = np.stack([rng.uniform(100, 1180, P), rng.uniform(cam.horizon_v_px(640) + 60, 700, P)], axis=-1)
    feet = cam.backproject_px_to_ground(px) * rng.uniform(0.6, 1.5, (P, 1))
    lean = rng.normal(0, 0.3, (P, 3))
    heads = feet + 1.7 * (cam.up_cam + lean) / np.linalg.norm(cam.up_cam + lean, axis=-1, keepdims=True)
    return feet, heads


@pytest.mark.parametrize("seed", range(5))
def test_paper_invariants(seed):
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    feet, heads = random_people(rng, cam, 7)
    T = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m)
    assert np.all(T.ok), [FLAGS[f] for f in T.flag]
    pts = apply_transforms(np.stack([feet, heads], axis=1), T)
    new_feet, new_heads = pts[:, 0], pts[:, 1]
    # mid-sole on the ground
    np.testing.assert_allclose(cam.height_above_ground(new_feet) / cam.height_m, 0.0, atol=TOL)
    # foot and crown pixels unchanged
    np.testing.assert_allclose(cam.project(new_feet), cam.project(feet), atol=TOL * 1000)
    np.testing.assert_allclose(cam.project(new_heads), cam.project(heads), atol=TOL * 1000)
    # the final axis lies in the camera-foot-head plane and along the projected normal
    axis = new_heads - new_feet
    normal = np.cross(feet, heads)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    np.testing.assert_allclose(np.sum(axis * normal, axis=-1) / np.linalg.norm(axis, axis=-1), 0.0, atol=TOL)
    n_proj = cam.up_cam - (normal @ cam.up_cam)[:, None] * normal
    cos = np.sum(axis * n_proj, axis=-1) / np.linalg.norm(axis, axis=-1) / np.linalg.norm(n_proj, axis=-1)
    np.testing.assert_allclose(cos, 1.0, atol=TOL)
    # rigid apart from the two scales: distances scale by s1 * s3
    mesh = rng.normal(0, 0.3, (7, 50, 3)) + feet[:, None]
    out = apply_transforms(mesh, T)
    d_in = np.linalg.norm(mesh[:, 1:] - mesh[:, :1], axis=-1)
    d_out = np.linalg.norm(out[:, 1:] - out[:, :1], axis=-1)
    np.testing.assert_allclose(d_out, d_in * (T.depth_scale * T.final_scale)[:, None], rtol=1e-9)


def test_upright_person_on_ground_is_unchanged():
    cam = Camera((1280, 720), 1000, None, np.deg2rad(30), 0.0, 6.0)
    feet = cam.backproject_px_to_ground(np.array([[400.0, 600.0], [900.0, 500.0]]))
    heads = feet + 1.8 * cam.up_cam
    T = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m)
    np.testing.assert_allclose(T.depth_scale, 1.0, atol=1e-12)
    np.testing.assert_allclose(T.rotation_deg, 0.0, atol=1e-9)
    np.testing.assert_allclose(T.final_scale, 1.0, atol=1e-12)
    np.testing.assert_allclose(T.stature_m, 1.8, atol=1e-12)


def test_hand_checked_depth_scale():
    # level camera 2 m high; a foot 1 m below the camera at 5 m depth must move to 2 m below: s1 = 2
    cam = Camera((640, 480), 500, None, 0.0, 0.0, 2.0)
    T = rotavat_transforms(np.array([[0.0, 1.0, 5.0]]), np.array([[0.0, 0.2, 5.0]]), cam.up_cam, cam.height_m)
    assert T.depth_scale[0] == pytest.approx(2.0)
    assert T.rotation_deg[0] == pytest.approx(0.0, abs=1e-9)
    assert T.stature_m[0] == pytest.approx(1.6)


def test_flags_and_unchanged_people():
    cam = Camera((1280, 720), 1000, None, np.deg2rad(20), 0.0, 5.0)
    good_foot = cam.backproject_px_to_ground(np.array([640.0, 600.0]))
    feet = np.stack([good_foot, np.array([0.0, -8.0, 10.0]), good_foot, good_foot * np.nan, good_foot])
    heads = np.stack([good_foot + cam.up_cam * 1.7, np.array([0.0, -9.0, 10.0]), good_foot, good_foot, good_foot * 2.0])
    T = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m)
    assert [FLAGS[f] for f in T.flag] == ["", "foot_above_horizon", "degenerate_mesh", "degenerate_mesh", "foot_head_same_ray"]
    pts = np.random.default_rng(0).normal(size=(5, 10, 3))
    out = apply_transforms(pts, T)
    np.testing.assert_array_equal(out[1:], pts[1:])


def test_empty_frame():
    T = rotavat_transforms(np.zeros((0, 3)), np.zeros((0, 3)), np.array([0, -1.0, 0]), 3.0)
    assert apply_transforms(np.zeros((0, 5, 3)), T).shape == (0, 5, 3)


def test_upright_full_is_vertical_and_reports_drift():
    rng = np.random.default_rng(4)
    cam = random_camera(rng)
    feet, heads = random_people(rng, cam, 5)
    T = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m, upright="full")
    pts = apply_transforms(np.stack([feet, heads], axis=1), T)
    axis = pts[:, 1] - pts[:, 0]
    np.testing.assert_allclose(axis / np.linalg.norm(axis, axis=-1, keepdims=True), np.tile(cam.up_cam, (5, 1)), atol=1e-9)
    np.testing.assert_allclose(cam.height_above_ground(pts[:, 0]), 0.0, atol=1e-9)
    np.testing.assert_allclose(cam.project(pts[:, 0]), cam.project(feet), atol=1e-6)


def test_fixed_stature():
    rng = np.random.default_rng(5)
    cam = random_camera(rng)
    feet, heads = random_people(rng, cam, 3)
    T = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m, stature_m=np.array([1.6, np.nan, 1.9]))
    assert T.stature_m[0] == pytest.approx(1.6) and T.stature_m[2] == pytest.approx(1.9)
    free = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m)
    assert T.stature_m[1] == pytest.approx(free.stature_m[1])


def _leaning_people(seed: int, P: int, V: int):
    """A camera, the RotAvat transforms of P leaning people, and meshes (P, V, 3) float32 around them."""
    rng = np.random.default_rng(seed)
    cam = random_camera(rng)
    feet, heads = random_people(rng, cam, P)
    T = rotavat_transforms(feet, heads, cam.up_cam, cam.height_m)
    mesh = (feet[:, None] + rng.normal(0, 0.3, (P, V, 3))).astype(np.float32)
    return cam, T, mesh


def test_float32_points_are_transformed_in_float64_then_stored():
    _, T, mesh = _leaning_people(6, 5, 200)
    out = apply_transforms(mesh, T, np.float32)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, apply_transforms(mesh.astype(np.float64), T).astype(np.float32))
    A = (T.depth_scale * T.final_scale)[:, None, None] * T.rotation  # X' = pivot + s3 R (s1 X - pivot)
    expected = T.pivot_cam[:, None] + np.einsum("pij,pnj->pni", A, mesh.astype(np.float64)) \
        - T.final_scale[:, None, None] * np.einsum("pij,pj->pi", T.rotation, T.pivot_cam)[:, None]
    np.testing.assert_allclose(apply_transforms(mesh, T), expected, rtol=0, atol=1e-12)


def test_blocks_of_people_do_not_change_the_result(monkeypatch):
    import rotavat_cli.alignment.transform as rotavat

    _, T, mesh = _leaning_people(7, 7, 300)
    whole = apply_transforms(mesh, T, np.float32)
    monkeypatch.setattr(rotavat, "_BLOCK_BYTES", 1)  # one person per block
    assert len(rotavat.person_blocks(7, 300 * 40)) == 7
    np.testing.assert_array_equal(apply_transforms(mesh, T, np.float32), whole)
    before = np.concatenate([b for b, _ in rotavat.transformed_blocks(mesh, T)])
    np.testing.assert_array_equal(rotavat.points_from_coords([before], 300, np.float32), mesh)


def test_flagged_people_are_copied_not_multiplied():
    cam = Camera((1280, 720), 1000, None, np.deg2rad(20), 0.0, 5.0)
    feet = np.array([[0.0, -8.0, 10.0], [0.0, -8.0, 10.0]])  # above the horizon: flagged
    T = rotavat_transforms(feet, feet + [0.0, -1.0, 0.0], cam.up_cam, cam.height_m)
    pts = np.array([[[1.0, np.nan, 3.0]], [[np.inf, 2.0, 3.0]]], dtype=np.float32)
    np.testing.assert_array_equal(apply_transforms(pts, T, np.float32), pts)  # 0 * NaN would spread NaN
