"""Tests for rotavat_cli.metrics: hand-computed cases, cardinality, dtypes, errors."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from _reference_metrics import reference_pa_errors_mm

from rotavat_cli.geometry.camera import height_above_ground
from rotavat_cli.metrics import (JOINT_ERROR_KEYS, VERTEX_ERROR_KEYS, camera_errors, compiled_kernels, detection_scores,
                                 lean_deg, mpjpe, normalize_by_f1, person_errors_mm, point_errors_mm, procrustes_align,
                                 pve, root_err_mm, stature_err_mm, stature_m, to_gravity_frame, umeyama,
                                 w_spec_errors_mm, w_spec_mpjpe, w_spec_pve)

# Hand-computed cases are exact up to float64 rounding of a few operations on metre-scale
# numbers, then x1000 to mm: 1e-6 mm (1 nm) is far above that noise and far below any error.
ATOL_MM = 1e-6

# Pelvis (root, index 0) and three joints 0.1 / 0.2 / 0.3 m from it along x, y, z.
OFFSETS_M = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.3]])
PELVIS_CAM = np.array([0.4, -0.2, 5.0])


def _skeleton() -> np.ndarray:
    """One person, (1, 4, 3): the joint set above placed 5 m in front of the camera."""
    return (PELVIS_CAM + OFFSETS_M)[None]


def _rot_x(angle_deg: float) -> np.ndarray:
    """Rotation about the x axis, (3, 3)."""
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(angle_deg: float) -> np.ndarray:
    """Rotation about the z axis, (3, 3)."""
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """n random proper rotations, (n, 3, 3)."""
    q, r = np.linalg.qr(rng.standard_normal((n, 3, 3)))
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    q[np.linalg.det(q) < 0, :, 0] *= -1.0
    return q


# --------------------------------------------------------------------------- hand-computed


def test_translation_only_offset():
    gt = _skeleton()
    pred = gt + np.array([0.3, 0.4, 1.2])  # |offset| = 1.3 m
    assert mpjpe(pred, gt, "none") == pytest.approx([1300.0], abs=ATOL_MM)
    assert mpjpe(pred, gt, "root") == pytest.approx([0.0], abs=ATOL_MM)
    assert mpjpe(pred, gt, "procrustes") == pytest.approx([0.0], abs=ATOL_MM)


def test_rotation_about_pelvis():
    # 60 deg about the camera z axis through the pelvis: a joint at distance r from the axis
    # moves by the chord 2 r sin(30 deg) = r; the z-offset joint lies on the axis.
    gt = _skeleton()
    pred = PELVIS_CAM + OFFSETS_M @ _rot_z(60.0).T
    expected_per_joint = [0.0, 100.0, 200.0, 0.0]
    assert point_errors_mm(pred[None], gt, "none")[0] == pytest.approx(
        expected_per_joint, abs=ATOL_MM
    )
    assert mpjpe(pred[None], gt, "none") == pytest.approx([75.0], abs=ATOL_MM)
    assert mpjpe(pred[None], gt, "root") == pytest.approx([75.0], abs=ATOL_MM)
    assert mpjpe(pred[None], gt, "procrustes") == pytest.approx([0.0], abs=ATOL_MM)


def test_rotation_about_camera_moves_pelvis_too():
    # 90 deg about the camera y axis: every joint X maps to (z, y, -x); W counts the swing.
    gt = _skeleton()[0]
    rot_y90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    pred = gt @ rot_y90.T
    expected = np.linalg.norm(pred - gt, axis=1).mean() * 1000.0
    assert mpjpe(pred[None], gt[None], "none") == pytest.approx([expected], abs=ATOL_MM)
    # Pelvis at (0.4, -0.2, 5): chord of a 90 deg turn about y is sqrt(2) * sqrt(0.4^2 + 5^2).
    assert point_errors_mm(pred[None], gt[None])[0, 0] == pytest.approx(
        1000.0 * np.sqrt(2.0) * np.hypot(0.4, 5.0), abs=ATOL_MM
    )
    assert mpjpe(pred[None], gt[None], "procrustes") == pytest.approx([0.0], abs=ATOL_MM)


def test_scale_only_about_pelvis():
    gt = _skeleton()
    pred = PELVIS_CAM + 1.5 * OFFSETS_M  # joints 0/0.1/0.2/0.3 m out -> errors 0/50/100/150 mm
    assert mpjpe(pred[None], gt, "root") == pytest.approx([75.0], abs=ATOL_MM)
    assert mpjpe(pred[None], gt, "none") == pytest.approx([75.0], abs=ATOL_MM)
    assert mpjpe(pred[None], gt, "procrustes") == pytest.approx([0.0], abs=ATOL_MM)


def test_pelvis_offset_spreads_to_every_other_joint_after_root_alignment():
    gt = _skeleton()
    pred = gt.copy()
    pred[0, 0] += [0.0, 0.04, 0.03]  # 50 mm pelvis error only
    assert mpjpe(pred, gt, "none") == pytest.approx([50.0 / 4], abs=ATOL_MM)
    assert mpjpe(pred, gt, "root") == pytest.approx([50.0 * 3 / 4], abs=ATOL_MM)


def test_reflection_is_not_undone_by_procrustes():
    # Six points +-a x, +-b y, +-c z (a, b, c = 0.3, 0.2, 0.1 m), mirrored in x. Umeyama with
    # det(R) = +1 flips the smallest axis (z): R = diag(-1, 1, -1), s = (a²+b²-c²)/(a²+b²+c²)
    # = 6/7. Errors: x pair (1-s)a, y pair (1-s)b, z pair (1+s)c; mean = ((1-s)(a+b) +
    # (1+s)c) / 3 = (0.5/7 + 1.3/7) / 3 m = 600/7 mm. An unconstrained (reflecting) fit gives 0.
    a, b, c = 0.3, 0.2, 0.1
    base = np.array([[a, 0, 0], [-a, 0, 0], [0, b, 0], [0, -b, 0], [0, 0, c], [0, 0, -c]])
    gt = (base + PELVIS_CAM)[None]
    mirror = np.diag([-1.0, 1.0, 1.0])
    pred = (base @ mirror.T + [2.0, 1.0, 7.0])[None]
    assert mpjpe(pred, gt, "procrustes") == pytest.approx([600.0 / 7.0], abs=ATOL_MM)
    scale, rot, _ = umeyama(pred, gt)
    assert scale == pytest.approx([6.0 / 7.0])
    assert np.linalg.det(rot) == pytest.approx([1.0])
    np.testing.assert_allclose(rot[0], np.diag([-1.0, 1.0, -1.0]), atol=1e-12)


def test_planar_mirror_is_a_rotation_in_3d():
    # A mirror image of a planar set is a 180 deg turn about an in-plane axis: PA error 0.
    gt = np.array([[[0.0, 0.0, 4.0], [0.3, 0.0, 4.0], [0.0, 0.5, 4.0], [0.2, 0.7, 4.0]]])
    pred = gt * np.array([-1.0, 1.0, 1.0])
    assert mpjpe(pred, gt, "procrustes") == pytest.approx([0.0], abs=ATOL_MM)


def test_procrustes_align_recovers_a_similarity():
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(3, 24, 3))
    rot = _random_rotations(rng, 3)
    scale = np.array([0.5, 1.0, 2.0])
    pred = scale[:, None, None] * gt @ np.swapaxes(rot, 1, 2) + rng.normal(size=(3, 1, 3))
    np.testing.assert_allclose(procrustes_align(pred, gt), gt, atol=1e-12)
    s_fit, r_fit, t_fit = umeyama(gt, pred)
    np.testing.assert_allclose(s_fit, scale, rtol=1e-12)
    np.testing.assert_allclose(r_fit, rot, atol=1e-12)


@pytest.mark.parametrize("n_people", [1, 2, 3])
@pytest.mark.parametrize("n_points", [3, 4, 24, 67, 6890])  # 67: prime, 6890 = 130 x 53
def test_procrustes_matches_per_person_reference(n_people, n_points):
    # N = 3 and P = 3 together catch code that picks a transpose from the array shape.
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(n_people, n_points, 3))
    pred = gt + 0.3 * rng.normal(size=gt.shape)
    pred[0] = pred[0] @ np.diag([1.0, -1.0, 1.0])  # one reflected person in every batch
    expected = np.stack([reference_pa_errors_mm(p, g) for p, g in zip(pred, gt)])
    np.testing.assert_allclose(point_errors_mm(pred, gt, "procrustes"), expected, atol=1e-9)


@pytest.mark.parametrize("distance_m", [0.0, 100.0, 1e4, 1e6])
def test_procrustes_far_from_the_origin(distance_m):
    # Moments are taken about the origin unless a person is far relative to its spread
    # (1e4 m and 1e6 m here); either way the result matches the centred reference.
    rng = np.random.default_rng(0)
    gt = rng.normal(0.0, 0.3, size=(2, 24, 3)) + [0.0, 0.0, distance_m]
    pred = gt + 0.02 * rng.normal(size=gt.shape)
    expected = np.stack([reference_pa_errors_mm(p, g) for p, g in zip(pred, gt)])
    np.testing.assert_allclose(point_errors_mm(pred, gt, "procrustes"), expected, atol=1e-6)
    exact = 1.2 * (gt - gt.mean(axis=1, keepdims=True)) @ _rot_z(30.0).T + [1.0, 2.0, 3.0]
    assert mpjpe(exact, gt, "procrustes") == pytest.approx([0.0, 0.0], abs=1e-6)


def test_procrustes_mixed_near_and_far_batch_equals_single_calls():
    rng = np.random.default_rng(0)
    gt = rng.normal(0.0, 0.3, size=(2, 24, 3)) + [[[0.0, 0.0, 5.0]], [[0.0, 0.0, 1e5]]]
    pred = gt + 0.02 * rng.normal(size=gt.shape)
    batch = mpjpe(pred, gt, "procrustes")
    singles = [mpjpe(pred[i : i + 1], gt[i : i + 1], "procrustes")[0] for i in range(2)]
    np.testing.assert_allclose(batch, singles, atol=1e-9)


def test_procrustes_collapsed_prediction_lands_on_gt_centroid():
    gt = _skeleton()
    pred = np.broadcast_to(PELVIS_CAM + 1.0, gt.shape)
    aligned = procrustes_align(pred, gt)
    np.testing.assert_allclose(aligned, np.broadcast_to(gt.mean(axis=1, keepdims=True), gt.shape))
    expected = np.linalg.norm(gt[0] - gt[0].mean(axis=0), axis=1).mean() * 1000.0
    assert mpjpe(pred, gt, "procrustes") == pytest.approx([expected], abs=ATOL_MM)


@pytest.mark.parametrize("n_points", [1, 7, 67, 6890])
def test_root_alignment_for_any_point_count(n_points):
    rng = np.random.default_rng(0)
    pred, gt = rng.normal(size=(2, 3, n_points, 3))
    pred_root, gt_root = rng.normal(size=(2, 3, 3))
    expected = np.linalg.norm((pred - pred_root[:, None]) - (gt - gt_root[:, None]), axis=-1)
    got = point_errors_mm(pred, gt, "root", pred_root, gt_root)
    np.testing.assert_allclose(got, expected * 1000.0, rtol=1e-12)


def test_pve_root_uses_the_given_pelvis_joint():
    rng = np.random.default_rng(0)
    gt_verts = rng.normal(size=(2, 50, 3))
    gt_pelvis = rng.normal(size=(2, 3))
    offset = np.array([[0.3, 0.4, 1.2], [0.0, 0.0, -0.5]])
    pred_verts, pred_pelvis = gt_verts + offset[:, None], gt_pelvis + offset
    assert pve(pred_verts, gt_verts, "root", pred_pelvis, gt_pelvis) == pytest.approx(
        [0.0, 0.0], abs=ATOL_MM
    )
    assert pve(pred_verts, gt_verts, "none") == pytest.approx([1300.0, 500.0], abs=ATOL_MM)
    # A pelvis that is off by 50 mm moves every vertex by 50 mm after root alignment.
    shifted = pred_pelvis + [0.0, 0.03, 0.04]
    assert pve(pred_verts, gt_verts, "root", shifted, gt_pelvis) == pytest.approx(
        [50.0, 50.0], abs=ATOL_MM
    )
    assert pve(pred_verts, gt_verts, "procrustes") == pytest.approx([0.0, 0.0], abs=ATOL_MM)


# --------------------------------------------------------------------------- cardinality


def _all_metrics(pred_j, gt_j, pred_v, gt_v, r_pred, r_gt):
    """Every per-person metric of the module on one batch, as a dict of (P,) arrays."""
    out = {f"mpjpe_{a}": mpjpe(pred_j, gt_j, a) for a in ("none", "root", "procrustes")}
    for a in ("none", "root", "procrustes"):
        out[f"pve_{a}"] = pve(pred_v, gt_v, a, pred_j[:, 0], gt_j[:, 0])
    out["w_spec_mpjpe"] = w_spec_mpjpe(pred_j, gt_j, r_pred, r_gt)
    out["w_spec_pve"] = w_spec_pve(pred_v, gt_v, r_pred, r_gt, pred_j[:, 0], gt_j[:, 0])
    return out


@pytest.mark.parametrize("n_people", [0, 1, 2, 3])
def test_batches_equal_single_person_calls(n_people):
    rng = np.random.default_rng(0)
    gt_j = rng.normal(size=(n_people, 24, 3))
    pred_j = gt_j + 0.05 * rng.normal(size=gt_j.shape)
    gt_v = rng.normal(size=(n_people, 40, 3))
    pred_v = gt_v + 0.05 * rng.normal(size=gt_v.shape)
    r_pred, r_gt = _rot_x(25.0), _rot_x(20.0)
    batch = _all_metrics(pred_j, gt_j, pred_v, gt_v, r_pred, r_gt)
    for name, values in batch.items():
        assert values.shape == (n_people,), name
        assert values.dtype == np.float64, name
    for i in range(n_people):
        single = _all_metrics(
            pred_j[i : i + 1], gt_j[i : i + 1], pred_v[i : i + 1], gt_v[i : i + 1], r_pred, r_gt
        )
        for name, values in single.items():
            np.testing.assert_allclose(batch[name][i], values[0], rtol=1e-12, err_msg=name)


def test_empty_batch_shapes():
    empty = np.zeros((0, 24, 3))
    assert procrustes_align(empty, empty).shape == (0, 24, 3)
    assert point_errors_mm(empty, empty, "procrustes").shape == (0, 24)
    assert point_errors_mm(empty, empty, "root", np.zeros((0, 3)), np.zeros((0, 3))).shape == (
        0,
        24,
    )
    assert [x.shape for x in umeyama(empty, empty)] == [(0,), (0, 3, 3), (0, 3)]


def test_float32_input_is_computed_in_float64():
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(3, 24, 3)).astype(np.float32)
    pred = (gt + 0.05 * rng.normal(size=gt.shape)).astype(np.float32)
    for alignment in ("none", "root", "procrustes"):
        got = mpjpe(pred, gt, alignment)
        assert got.dtype == np.float64
        np.testing.assert_array_equal(
            got, mpjpe(pred.astype(np.float64), gt.astype(np.float64), alignment)
        )


def test_non_finite_person_does_not_poison_the_batch():
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(3, 10, 3))
    pred = gt + 0.01 * rng.normal(size=gt.shape)
    pred[1, 4] = np.nan
    pa = mpjpe(pred, gt, "procrustes")
    assert np.isnan(pa[1])
    np.testing.assert_allclose(pa[[0, 2]], mpjpe(pred[[0, 2]], gt[[0, 2]], "procrustes"))


def test_inputs_are_not_modified():
    rng = np.random.default_rng(0)
    gt, pred = rng.normal(size=(2, 2, 24, 3))
    roots = rng.normal(size=(2, 2, 3))
    before = [x.copy() for x in (gt, pred, roots)]
    for alignment in ("none", "root", "procrustes"):
        point_errors_mm(pred, gt, alignment, roots[0], roots[1])
    w_spec_errors_mm(pred, gt, _rot_x(10.0), _rot_x(20.0), roots[0], roots[1])
    for x, x0 in zip((gt, pred, roots), before):
        np.testing.assert_array_equal(x, x0)


# --------------------------------------------------------------------------- errors


def test_shape_and_argument_errors():
    a = np.zeros((2, 24, 3))
    with pytest.raises(ValueError, match=r"differ in shape"):
        mpjpe(a, np.zeros((2, 23, 3)))
    with pytest.raises(ValueError, match=r"\(P, N, 3\)"):
        point_errors_mm(np.zeros((24, 3)), np.zeros((24, 3)))
    with pytest.raises(ValueError, match="alignment must be one of"):
        mpjpe(a, a, "scale")
    with pytest.raises(ValueError, match="pelvis"):
        pve(a, a, "root")
    with pytest.raises(ValueError, match=r"gt_root must have shape \(2, 3\)"):
        pve(a, a, "root", np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="root_index 24 is out of range"):
        mpjpe(a, a, root_index=24)
    with pytest.raises(ValueError, match="rotation matrix"):
        to_gravity_frame(a, 2.0 * np.eye(3))
    with pytest.raises(ValueError, match="N = 0"):
        point_errors_mm(np.zeros((1, 0, 3)), np.zeros((1, 0, 3)), "procrustes")


# --------------------------------------------------------------------------- SPEC variant


def test_w_spec_with_equal_cameras_is_root_aligned_error():
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(3, 24, 3))
    pred = gt + 0.05 * rng.normal(size=gt.shape)
    rot = _random_rotations(rng, 1)[0]
    got = w_spec_errors_mm(pred, gt, rot, rot, pred[:, 0], gt[:, 0])
    np.testing.assert_allclose(got, point_errors_mm(pred, gt, "root", pred[:, 0], gt[:, 0]))


def test_w_spec_with_per_person_cameras_matches_its_definition():
    # Literal SPEC definition: rotate each side into its own gravity frame, subtract pelvis.
    rng = np.random.default_rng(0)
    gt = rng.normal(size=(3, 30, 3))
    pred = gt + 0.05 * rng.normal(size=gt.shape)
    r_pred, r_gt = _random_rotations(rng, 3), _random_rotations(rng, 1)[0]
    pr, gr = pred[:, 0], gt[:, 0]
    expected = np.linalg.norm(
        to_gravity_frame(pred - pr[:, None], r_pred) - to_gravity_frame(gt - gr[:, None], r_gt),
        axis=-1,
    )
    got = w_spec_errors_mm(pred, gt, r_pred, r_gt, pr, gr)
    np.testing.assert_allclose(got, expected * 1000.0, rtol=1e-10, atol=1e-9)


def test_w_spec_counts_camera_pitch_error():
    # Perfect camera-frame body, but the predicted pitch is 10 deg off: in the gravity frame a
    # joint at distance r from the x (pitch) axis through the pelvis is off by 2 r sin(5 deg).
    gt = _skeleton()
    got = w_spec_errors_mm(gt, gt, _rot_x(40.0), _rot_x(30.0), gt[:, 0], gt[:, 0])
    chord = 2.0 * np.sin(np.radians(5.0))
    np.testing.assert_allclose(got[0], [0.0, 0.0, 200.0 * chord, 300.0 * chord], atol=ATOL_MM)
    per_person_r = np.stack([_rot_x(40.0)])
    assert w_spec_mpjpe(gt, gt, per_person_r, _rot_x(30.0)) == pytest.approx(
        [125.0 * chord], abs=ATOL_MM
    )


def _camera(pitch_deg: float, roll_deg: float, height_m: float):
    """Contract camera: up_cam n, R_cam_from_world (columns X, Y, Z), t_cam_from_world."""
    th, ph = np.radians(pitch_deg), np.radians(roll_deg)
    up = np.array([-np.sin(ph) * np.cos(th), -np.cos(ph) * np.cos(th), -np.sin(th)])
    x_axis = np.array([1.0, 0.0, 0.0]) - up[0] * up
    x_axis /= np.linalg.norm(x_axis)
    rot = np.stack([x_axis, up, np.cross(x_axis, up)], axis=1)
    return up, rot, -height_m * up


def test_to_gravity_frame_matches_contract_world_frame():
    rng = np.random.default_rng(0)
    up, r_cam_from_world, t_cam_from_world = _camera(25.0, 3.0, 6.0)
    points_world = rng.normal(size=(2, 5, 3))
    points_cam = points_world @ r_cam_from_world.T + t_cam_from_world
    back = to_gravity_frame(points_cam, r_cam_from_world.T, -r_cam_from_world.T @ t_cam_from_world)
    np.testing.assert_allclose(back, points_world, atol=1e-12)
    # World Y is the height above ground.
    np.testing.assert_allclose(height_above_ground(points_cam, up, 6.0), back[..., 1], atol=1e-12)


# --------------------------------------------------------------------------- all at once

# person_errors_mm's vertex pass rounds body-centred coordinates to float32 (module docstring):
# its means must stay within 1e-3 mm of float64; in practice they are within ~1e-4 mm.
FUSED_ATOL_MM = 1e-3


@pytest.fixture(params=["numpy", "numba"])
def fused(request):
    """person_errors_mm with each vertex engine (the numba one skipped when numba is missing)."""
    if request.param == "numba" and compiled_kernels() is None:
        pytest.skip("numba is not installed (pip install 'rotavat[fast]')")
    return functools.partial(person_errors_mm, engine=request.param)


def _bodies(rng, n_people, n_points, depth_m=(4.0, 20.0), placement_sd_m=0.2):
    """Random float32 pred/gt bodies (P, N, 3), 0.3 m spread, placed ``depth_m`` away."""
    place = rng.uniform([-3.0, 0.5, depth_m[0]], [3.0, 2.0, depth_m[1]], (n_people, 1, 3))
    gt = place + rng.normal(0.0, 0.3, (n_people, n_points, 3))
    pred = gt + rng.normal(0.0, placement_sd_m, (n_people, 1, 3))
    pred = pred + rng.normal(0.0, 0.03, gt.shape)
    return pred.astype(np.float32), gt.astype(np.float32)


def _loop_vertex_errors(pred_v, gt_v, pred_root, gt_root, r_pred, r_gt):
    """Per-person float64 reference, one person at a time: dict of (P,) mm."""
    rows = []
    for i in range(len(pred_v)):
        p, g = pred_v[i].astype(np.float64), gt_v[i].astype(np.float64)
        pr, gr = pred_root[i].astype(np.float64), gt_root[i].astype(np.float64)
        rp = r_pred if r_pred.ndim == 2 else r_pred[i]
        rg = r_gt if r_gt.ndim == 2 else r_gt[i]
        diffs = (p - g, (p - pr) - (g - gr), (p - pr) @ rp.T - (g - gr) @ rg.T)
        w, root, spec = (np.linalg.norm(d, axis=1).mean() * 1000.0 for d in diffs)
        rows.append((w, root, reference_pa_errors_mm(p, g).mean(), spec))
    return dict(zip(VERTEX_ERROR_KEYS, np.array(rows, ndmin=2).reshape(-1, 4).T))


def test_person_errors_hand_computed(fused):
    # Joints and vertices moved by (0.3, 0.4, 1.2) m (|.| = 1.3 m) with equal cameras: W sees
    # 1300 mm, every aligned error is 0, and SPEC (pelvis-aligned) equals the root-aligned.
    gt = _skeleton()
    pred = gt + np.array([0.3, 0.4, 1.2])
    rot = _rot_x(20.0)
    got = fused(pred, gt, pred, gt, rot, rot)
    assert set(got) == set(JOINT_ERROR_KEYS + VERTEX_ERROR_KEYS)
    for key in ("w_mpjpe", "w_pve"):
        assert got[key] == pytest.approx([1300.0], abs=FUSED_ATOL_MM)
    for key in ("mpjpe", "pa_mpjpe", "w_mpjpe_spec", "pve", "pa_pve", "w_pve_spec"):
        assert got[key] == pytest.approx([0.0], abs=FUSED_ATOL_MM), key


def test_person_errors_pelvis_and_camera_errors(fused):
    # Vertices = the gt joints on both sides (0.1/0.2/0.3 m from the pelvis): a 50 mm error of
    # the predicted pelvis *joint* moves every vertex by 50 mm after root alignment, and a 10 deg pitch error moves a vertex at distance r from the
    # pitch axis through the pelvis by 2 r sin(5 deg) in SPEC's gravity frame.
    gt_joints = _skeleton()
    pred_joints = gt_joints.copy()
    pred_joints[0, 0] += [0.0, 0.04, 0.03]
    got = fused(pred_joints, gt_joints, gt_joints, gt_joints, _rot_x(40.0),
                           _rot_x(30.0))
    chord = 2.0 * np.sin(np.radians(5.0))
    assert got["w_pve"] == pytest.approx([0.0], abs=FUSED_ATOL_MM)
    assert got["pve"] == pytest.approx([50.0], abs=FUSED_ATOL_MM)  # every vertex, pelvis too
    assert got["pa_pve"] == pytest.approx([0.0], abs=FUSED_ATOL_MM)
    spec_pelvis_ok = fused(
        pred_verts=gt_joints, gt_verts=gt_joints, R_world_from_cam_pred=_rot_x(40.0),
        R_world_from_cam_gt=_rot_x(30.0), pred_verts_root=gt_joints[:, 0],
        gt_verts_root=gt_joints[:, 0],
    )
    assert spec_pelvis_ok["w_pve_spec"] == pytest.approx([125.0 * chord], abs=FUSED_ATOL_MM)


@pytest.mark.parametrize("n_people", [0, 1, 2, 3, 19])  # 19: two full blocks and a partial one
def test_person_errors_match_per_person_reference(fused, n_people):
    rng = np.random.default_rng(n_people)
    pred_j, gt_j = _bodies(rng, n_people, 24)
    pred_v, gt_v = _bodies(rng, n_people, 6890)
    if n_people:
        pred_v[0] = pred_v[0] @ np.diag([1.0, -1.0, 1.0]).astype(np.float32)  # reflected
    r_pred, r_gt = _random_rotations(rng, n_people), _rot_x(25.0)  # per person / shared
    got = fused(pred_j, gt_j, pred_v, gt_v, r_pred, r_gt)
    expected = _loop_vertex_errors(pred_v, gt_v, pred_j[:, 0], gt_j[:, 0], r_pred, r_gt)
    for key in VERTEX_ERROR_KEYS:
        assert got[key].shape == (n_people,) and got[key].dtype == np.float64
        np.testing.assert_allclose(got[key], expected[key], atol=FUSED_ATOL_MM, err_msg=key)
    # Joint errors are the single-metric functions, exactly.
    np.testing.assert_array_equal(got["pa_mpjpe"], mpjpe(pred_j, gt_j, "procrustes"))
    np.testing.assert_array_equal(got["w_mpjpe_spec"], w_spec_mpjpe(pred_j, gt_j, r_pred, r_gt))


def test_person_errors_far_bodies_stay_within_a_micrometre(fused):
    # Bodies 25-30 m from the camera, predictions placed ~1 m (up to 3 m) off: float32
    # per-vertex arithmetic still agrees with float64 to well under 1e-3 mm.
    rng = np.random.default_rng(7)
    pred_j, gt_j = _bodies(rng, 12, 24, depth_m=(25.0, 30.0), placement_sd_m=1.0)
    pred_v, gt_v = _bodies(rng, 12, 6890, depth_m=(25.0, 30.0), placement_sd_m=1.0)
    r_pred, r_gt = _rot_x(22.0), _rot_x(25.0)
    got = fused(pred_j, gt_j, pred_v, gt_v, r_pred, r_gt)
    roots = pred_j[:, 0].astype(np.float64), gt_j[:, 0].astype(np.float64)
    exact = {
        "w_pve": pve(pred_v, gt_v, "none"),
        "pve": pve(pred_v, gt_v, "root", *roots),
        "pa_pve": pve(pred_v, gt_v, "procrustes"),
        "w_pve_spec": w_spec_pve(pred_v, gt_v, r_pred, r_gt, *roots),
    }
    for key, values in exact.items():
        np.testing.assert_allclose(got[key], values, atol=FUSED_ATOL_MM, err_msg=key)
        assert np.abs(got[key] - values).max() < 2e-4, key


def test_person_errors_float64_input_far_from_origin(fused):
    # float64 input 1 km away: the points are centred in float64 before rounding to float32.
    rng = np.random.default_rng(3)
    gt = rng.normal(0.0, 0.3, (2, 500, 3)) + [0.0, 0.0, 1000.0]
    pred = gt + 0.02 * rng.normal(size=gt.shape)
    got = fused(pred_verts=pred, gt_verts=gt)
    np.testing.assert_allclose(got["pa_pve"], pve(pred, gt, "procrustes"), atol=FUSED_ATOL_MM)
    centroids = pred.mean(axis=1), gt.mean(axis=1)  # the default root without joints
    np.testing.assert_allclose(got["pve"], pve(pred, gt, "root", *centroids), atol=FUSED_ATOL_MM)


def test_person_errors_inconsistent_root_keeps_procrustes_exact(fused):
    # A root 100 m from its vertices (bad joints): the float32 origin falls back to a vertex,
    # so PA stays at float64 accuracy; the root-aligned error is ~100 m, right to ~1e-7.
    rng = np.random.default_rng(4)
    pred_v, gt_v = _bodies(rng, 3, 300)
    pred_root = pred_v[:, 0].astype(np.float64) + [100.0, 0.0, 0.0]
    gt_root = gt_v[:, 0].astype(np.float64)
    got = fused(pred_verts=pred_v, gt_verts=gt_v, pred_verts_root=pred_root,
                           gt_verts_root=gt_root)
    np.testing.assert_allclose(got["pa_pve"], pve(pred_v, gt_v, "procrustes"),
                               atol=FUSED_ATOL_MM)
    np.testing.assert_allclose(got["pve"], pve(pred_v, gt_v, "root", pred_root, gt_root),
                               rtol=1e-7)


def test_person_errors_tiny_body_uses_centred_moments(fused):
    # A 0.1 mm body 1.5 m from its root: moments about the root lose everything to
    # cancellation, so the block is centred first; PA still matches the reference.
    rng = np.random.default_rng(5)
    gt = 1e-4 * rng.normal(size=(2, 50, 3)) + [0.0, 0.0, 5.0]
    pred = gt + 1e-5 * rng.normal(size=gt.shape)
    roots = gt[:, 0] + [0.0, 1.5, 0.0]
    got = fused(pred_verts=pred, gt_verts=gt, pred_verts_root=roots,
                           gt_verts_root=roots)
    expected = [reference_pa_errors_mm(p, g).mean() for p, g in zip(pred, gt)]
    np.testing.assert_allclose(got["pa_pve"], expected, atol=1e-4)


def test_person_errors_collapsed_and_nan_people(fused):
    rng = np.random.default_rng(6)
    pred_v, gt_v = _bodies(rng, 3, 200)
    pred_v[1] = pred_v[1, :1]  # collapsed: every vertex at one point -> lands on gt centroid
    clean = fused(pred_verts=pred_v, gt_verts=gt_v)
    spread = np.linalg.norm(gt_v[1] - gt_v[1].astype(np.float64).mean(axis=0), axis=1)
    assert clean["pa_pve"][1] == pytest.approx(spread.mean() * 1000.0, abs=FUSED_ATOL_MM)
    pred_v[2, 7] = np.nan
    got = fused(pred_verts=pred_v, gt_verts=gt_v, R_world_from_cam_pred=np.eye(3),
                           R_world_from_cam_gt=np.eye(3))
    for key in VERTEX_ERROR_KEYS:
        assert np.isnan(got[key][2]), key
    for key in ("w_pve", "pve", "pa_pve"):  # the NaN person does not touch the others
        np.testing.assert_array_equal(got[key][:2], clean[key][:2])
    np.testing.assert_allclose(got["w_pve_spec"][:2], clean["pve"][:2], atol=FUSED_ATOL_MM)


def test_person_errors_keys_inputs_and_errors(fused):
    rng = np.random.default_rng(8)
    pred_j, gt_j = _bodies(rng, 2, 24)
    pred_v, gt_v = _bodies(rng, 2, 40)
    before = [x.copy() for x in (pred_j, gt_j, pred_v, gt_v)]
    assert set(fused(pred_j, gt_j)) == {"w_mpjpe", "mpjpe", "pa_mpjpe"}
    assert set(fused(pred_verts=pred_v, gt_verts=gt_v)) == {"w_pve", "pve", "pa_pve"}
    assert fused() == {}
    for x, x0 in zip((pred_j, gt_j, pred_v, gt_v), before):
        np.testing.assert_array_equal(x, x0)
    with pytest.raises(ValueError, match="both pred and gt"):
        fused(pred_j)
    with pytest.raises(ValueError, match="both R_world_from_cam_pred"):
        fused(pred_j, gt_j, R_world_from_cam_pred=np.eye(3))
    with pytest.raises(ValueError, match="differ in shape"):
        fused(pred_verts=pred_v, gt_verts=gt_v[:, :30])
    with pytest.raises(ValueError, match="2 people have joints but 1"):
        fused(pred_j, gt_j, pred_v[:1], gt_v[:1])
    with pytest.raises(ValueError, match="N = 0"):
        fused(pred_verts=np.zeros((1, 0, 3)), gt_verts=np.zeros((1, 0, 3)))
    with pytest.raises(ValueError, match="rotation matrix"):
        fused(pred_verts=pred_v, gt_verts=gt_v, R_world_from_cam_pred=2 * np.eye(3),
                         R_world_from_cam_gt=np.eye(3))


def test_vertex_engines_agree_to_a_hundred_thousandth_of_a_mm():
    # The compiled pass does the numpy pass's arithmetic (float32 per vertex, float64 moments and
    # sums): same numbers up to summation order, for float32 and float64 input, one rotation
    # pair or one per person, with and without SPEC.
    if compiled_kernels() is None:
        pytest.skip("numba is not installed (pip install 'rotavat[fast]')")
    rng = np.random.default_rng(11)
    pred_j, gt_j = _bodies(rng, 9, 24)
    pred_v, gt_v = _bodies(rng, 9, 6890)
    per_person = np.stack([_rot_x(a) for a in rng.uniform(10.0, 40.0, 9)])
    cases = [
        (pred_v, gt_v, None, None),
        (pred_v, gt_v, _rot_x(22.0), _rot_x(25.0)),
        (pred_v.astype(np.float64), gt_v.astype(np.float64), per_person, per_person[::-1]),
        (pred_v.astype(np.float16), gt_v, None, None),  # half precision widens exactly
        (pred_v[:, ::2], gt_v[:, ::2], None, None),  # strided views
    ]
    for pv, gv, r_pred, r_gt in cases:
        got = {e: person_errors_mm(pred_j, gt_j, pv, gv, r_pred, r_gt, engine=e) for e in ("numpy", "numba")}
        assert got["numpy"].keys() == got["numba"].keys()
        for key in VERTEX_ERROR_KEYS:
            if key in got["numpy"]:
                np.testing.assert_allclose(got["numba"][key], got["numpy"][key], rtol=0, atol=1e-5, err_msg=key)
                assert got["numpy"][key].min() > 1.0, key  # real errors, not zeros agreeing


def test_vertex_engine_choice(monkeypatch):
    rng = np.random.default_rng(12)
    pred_v, gt_v = _bodies(rng, 3, 100)
    numpy_pass = person_errors_mm(pred_verts=pred_v, gt_verts=gt_v, engine="numpy")
    with pytest.raises(ValueError, match="engine must be one of"):
        person_errors_mm(pred_verts=pred_v, gt_verts=gt_v, engine="cuda")
    # Without numba, "auto" is the numpy pass and "numba" says how to get it.
    monkeypatch.setattr("rotavat_cli.metrics.fused.compiled_kernels", lambda: None)
    auto = person_errors_mm(pred_verts=pred_v, gt_verts=gt_v)
    for key in numpy_pass:
        np.testing.assert_array_equal(auto[key], numpy_pass[key])
    with pytest.raises(ValueError, match=r"rotavat\[fast\]"):
        person_errors_mm(pred_verts=pred_v, gt_verts=gt_v, engine="numba")


def test_broken_numba_falls_back_with_a_warning(monkeypatch):
    # numba installed but unable to load the kernels (e.g. no writable cache): numpy, and a reason.
    from rotavat_cli.metrics import fused

    def fail(name, package=None):
        raise RuntimeError("cannot cache function: no locator available")

    monkeypatch.setattr(fused.importlib, "import_module", fail)
    fused.compiled_kernels.cache_clear()
    try:
        with pytest.warns(UserWarning, match="no locator available"):
            assert fused.compiled_kernels() is None
    finally:
        monkeypatch.undo()
        fused.compiled_kernels.cache_clear()  # the next caller imports the real kernels again


# --------------------------------------------------------------------------- ground-aware


def test_lean_and_stature():
    up, _, _ = _camera(20.0, 0.0, 5.0)
    side = np.array([1.0, 0.0, 0.0])  # horizontal, perpendicular to up (roll 0)
    feet = np.array([[0.0, 1.0, 8.0], [1.0, 1.0, 9.0], [2.0, 1.0, 7.0], [0.0, 0.0, 5.0]])
    lean = np.radians(10.0)
    heads = feet + 1.7 * np.array(
        [up, np.cos(lean) * up + np.sin(lean) * side, -up, np.zeros(3)]
    )
    got = lean_deg(feet, heads, up)
    np.testing.assert_allclose(got[:3], [0.0, 10.0, 180.0], atol=1e-9)
    assert np.isnan(got[3])
    assert stature_m(feet[:3], heads[:3]) == pytest.approx([1.7, 1.7, 1.7])
    assert stature_err_mm(feet[:1], feet[:1] + 1.8 * up, feet[:1], heads[:1]) == pytest.approx(
        [100.0], abs=ATOL_MM
    )


def test_root_error():
    got = root_err_mm([[0.0, 0.0, 5.0]], [[0.3, 0.4, 6.2]])
    assert got == pytest.approx([1300.0], abs=ATOL_MM)


# --------------------------------------------------------------------------- detection


@pytest.mark.parametrize(
    ("counts", "expected"),
    [
        ((8, 2, 2), (0.8, 0.8, 0.8)),
        ((3, 1, 0), (1.0, 0.75, 6.0 / 7.0)),
        ((0, 0, 0), (1.0, 1.0, 1.0)),  # empty frame: nothing to find, nothing wrong
        ((0, 4, 0), (1.0, 0.0, 0.0)),  # no predictions at all
        ((0, 0, 3), (0.0, 1.0, 0.0)),  # predictions on an empty scene
    ],
)
def test_detection_scores(counts, expected):
    got = detection_scores(*counts)
    assert (got["precision"], got["recall"], got["f1"]) == pytest.approx(expected)


def test_detection_scores_rejects_bad_counts():
    with pytest.raises(ValueError, match="missed must be a non-negative integer"):
        detection_scores(1, -1, 0)


def test_normalize_by_f1():
    assert normalize_by_f1(80.0, 0.8) == pytest.approx(100.0)
    assert normalize_by_f1(80.0, 0.0) == np.inf
    assert np.isnan(normalize_by_f1(np.nan, 0.5))
    np.testing.assert_allclose(normalize_by_f1(np.array([10.0, 20.0]), 0.5), [20.0, 40.0])


# --------------------------------------------------------------------------- camera


def test_camera_errors_wraps_angles_and_reports_percentages():
    gt = {"focal_px": 1400.0, "pitch_deg": 25.0, "roll_deg": -179.0, "height_m": 6.0}
    pred = {"focal_px": 1330.0, "pitch_deg": 27.5, "roll_deg": 179.0, "height_m": 6.3}
    got = camera_errors(pred, gt)
    assert got["focal_pct_signed"] == pytest.approx(-5.0)
    assert got["focal_pct"] == pytest.approx(5.0)
    assert got["pitch_deg_signed"] == pytest.approx(2.5)
    assert got["roll_deg_signed"] == pytest.approx(-2.0)
    assert got["roll_deg"] == pytest.approx(2.0)
    assert got["height_pct"] == pytest.approx(5.0)
    with pytest.raises(ValueError, match="pred camera is missing roll_deg"):
        camera_errors({k: v for k, v in pred.items() if k != "roll_deg"}, gt)


# --------------------------------------------------------------------------- memory layout (issue 18, bug 1)


def _layouts(points: np.ndarray) -> dict[str, np.ndarray]:
    """The same (P, N, 3) values in C order, Fortran order, a fancy-indexed subset's layout, a strided view."""
    reordered = points[:, [1, 0, *range(2, points.shape[1])]]  # non-contiguous, like pj[:, list(--joints)]
    strided = np.repeat(points, 2, axis=1)[:, ::2]
    return {"C": np.ascontiguousarray(points), "F": np.asfortranarray(points),
            "fancy": reordered[:, [1, 0, *range(2, points.shape[1])]], "strided": strided}


def test_every_metric_is_the_same_for_any_memory_layout(fused):
    """The root shift wrote through a reshape of a non-contiguous array (a copy), so mpjpe turned into
    w_mpjpe (~2000 mm instead of ~100 here). Every metric must give the same numbers for any layout."""
    rng = np.random.default_rng(18)
    gt = rng.normal(scale=0.3, size=(3, 24, 3)) + [0.0, 0.0, 5.0]
    pred = gt + rng.normal(scale=0.05, size=gt.shape) + [0.3, 0.1, 2.0]
    by_hand = np.linalg.norm((pred - pred[:, :1]) - (gt - gt[:, :1]), axis=-1).mean(axis=1) * 1000.0
    assert np.all(by_hand < 200.0) and np.all(mpjpe(pred, gt, "none") > 1900.0)  # the two differ by far
    rot = _rot_x(10.0)
    for name, (p, g) in {k: (v, _layouts(gt)[k]) for k, v in _layouts(pred).items()}.items():
        assert p.tolist() == pred.tolist(), name
        np.testing.assert_allclose(mpjpe(p, g, "root"), by_hand, rtol=1e-12, err_msg=name)
        np.testing.assert_allclose(pve(p, g, "root", p[:, 0], g[:, 0]), by_hand, rtol=1e-12, err_msg=name)
        np.testing.assert_allclose(point_errors_mm(p, g, "root", p[:, 0], g[:, 0]).mean(1), by_hand, rtol=1e-12)
        np.testing.assert_allclose(mpjpe(p, g, "procrustes"), mpjpe(pred, gt, "procrustes"), rtol=1e-12)
        np.testing.assert_allclose(w_spec_mpjpe(p, g, rot, rot), by_hand, rtol=1e-10, err_msg=name)
        errs = fused(p, g, pred_verts=p, gt_verts=g)
        np.testing.assert_allclose(errs["mpjpe"], by_hand, rtol=1e-12, err_msg=name)
        np.testing.assert_allclose(errs["pve"], by_hand, rtol=1e-6, err_msg=name)
        np.testing.assert_allclose(errs["pa_pve"], mpjpe(pred, gt, "procrustes"), rtol=1e-5, err_msg=name)
