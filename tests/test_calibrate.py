"""Calibration from foot/head pixels: the paper's grid, the robust refinement, errors and diagnostics."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from _synthetic_pairs import box_points_px, synthetic_pairs  # tests/ is on sys.path (pytest rootdir-less import)

from rotavat_cli.calibration import (RESIDUAL_KINDS, RESIDUALS, CalibrateOptions, CalibrationResult, GridSpec,
                                     calibrate, fit_camera, fit_per_frame, grid_costs, paper_grid_search,
                                     predict_heads_px, reference_cell_costs, residual_kind)
from rotavat_cli.calibration.objective import make_problem, profiled, whitened
from rotavat_cli.calibration.params import FOCAL, HEIGHT, PITCH, ROLL, param_vector
from rotavat_cli.calibration.uncertainty import jackknife_cov
from rotavat_cli.geometry.camera import Camera, backproject_px_to_plane, project_cam_to_px, up_vector_cam
from rotavat_cli.settings.config import default_config
from rotavat_cli.errors import DegenerateSceneError, InputError

# Tolerances (why): 100 frames x 20 walking people, 2 px noise, stature sd 0.07 m -> the camera is
# limited by the 20 statures' sampling; the benchmark's medians are ~5x below these.
TOL_FOCAL_REL = 0.03
TOL_PITCH_DEG = 0.5
TOL_ROLL_DEG = 0.5
TOL_HEIGHT_REL = 0.04


def assert_close_camera(est: Camera, true: Camera, focal=TOL_FOCAL_REL, pitch=TOL_PITCH_DEG, roll=TOL_ROLL_DEG,
                        height=TOL_HEIGHT_REL) -> None:
    """Estimated camera within the given relative / degree tolerances of the truth."""
    assert abs(est.focal_px / true.focal_px - 1) < focal, (est, true)
    assert abs(math.degrees(est.pitch_rad - true.pitch_rad)) < pitch, (est, true)
    assert abs(math.degrees(est.roll_rad - true.roll_rad)) < roll, (est, true)
    assert abs(est.height_m / true.height_m - 1) < height, (est, true)


# ---- the model and the paper's grid --------------------------------------------------------------------
def test_predict_heads_matches_camera_methods():
    cam = Camera((1280, 720), 900.0, (630.0, 370.0), math.radians(25), math.radians(3), 6.0)
    feet_px = np.array([[100.0, 600.0], [640.0, 500.0], [1200.0, 700.0]])
    ground_cam = cam.backproject_px_to_ground(feet_px)
    expected = cam.project(ground_cam + 1.7 * cam.up_cam)
    got = predict_heads_px(feet_px, cam.focal_px, cam.pitch_rad, cam.roll_rad, cam.height_m, cam.principal_point, 1.7)
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_grid_spec_defaults_are_the_papers():
    spec = GridSpec()
    np.testing.assert_allclose(spec.focal_values_px(1000)[[0, -1]], [100.0, 6000.0])
    np.testing.assert_allclose(np.rad2deg(spec.pitch_values_rad()[[0, -1]]), [-45.0, 90.0])
    np.testing.assert_allclose(spec.height_values_m()[[0, -1]], [0.5, 40.0])
    assert spec.steps == (50, 50, 50)
    assert GridSpec(steps=[4, 5, 6]).steps == (4, 5, 6)  # lists from YAML
    with pytest.raises(ValueError, match="steps"):
        GridSpec(steps=(3, 0, 3))


def heads_by_camera_functions(feet_px, focal_px, pitch_rad, roll_rad, height_m, principal_point, stature_m):
    """The person model written plainly with camera.py: back-project the foot, add the stature along up, project."""
    up = up_vector_cam(pitch_rad, roll_rad)
    ground = backproject_px_to_plane(feet_px, focal_px, principal_point, up, height_m)
    return project_cam_to_px(ground + stature_m * up, focal_px, principal_point)


@pytest.mark.parametrize("residual", ["full", "vertical"])
def test_grid_result_is_the_brute_force_best_cell(residual):
    rng = np.random.default_rng(3)
    data = synthetic_pairs(rng, frames=3, people=12, outlier_fraction=0.1, roll_deg=2.0)
    W, H = data.camera.image_size
    spec = GridSpec(steps=(9, 11, 10))
    focal, pitch, height = spec.focal_values_px(H), spec.pitch_values_rad(), spec.height_values_m()
    pp = (W / 2, H / 2)
    best, best_cell = math.inf, None
    for i, f in enumerate(focal):  # brute force: camera.py functions, one cell at a time
        for j, p in enumerate(pitch):
            for k, c in enumerate(height):
                e = heads_by_camera_functions(data.feet_px, f, p, 0.0, c, pp, 1.7) - data.heads_px
                cost = float(np.sum(e[:, 1] ** 2 if residual == "vertical" else e**2))
                if math.isfinite(cost) and cost < best:
                    best, best_cell = cost, (i, j, k)
    fit = paper_grid_search(data.feet_px, data.heads_px, pp, focal, pitch, height, 1.7, residual)
    assert fit.index == best_cell
    assert fit.cost == pytest.approx(best, rel=1e-12)
    res = fit_camera(data.feet_px, data.heads_px, (W, H), method="grid", grid=spec, residual=residual)
    assert (res.camera.focal_px, res.camera.pitch_rad, res.camera.height_m) == (fit.focal_px, fit.pitch_rad,
                                                                                fit.height_m)


def test_grid_costs_match_reference_and_skip_invalid_cells():
    rng = np.random.default_rng(5)
    data = synthetic_pairs(rng, frames=2, people=15)
    W, H = data.camera.image_size
    spec = GridSpec(steps=(7, 12, 6))
    focal, pitch, height = spec.focal_values_px(H), spec.pitch_values_rad(), spec.height_values_m()
    fast = grid_costs(data.feet_px, data.heads_px, (W / 2, H / 2), focal, pitch, height, 1.7, workers=2)
    ff, pp_, cc = (a.ravel() for a in np.meshgrid(focal, pitch, height, indexing="ij"))
    ref = reference_cell_costs(data.feet_px, data.heads_px, ff, pp_, cc, (W / 2, H / 2), 1.7).reshape(fast.shape)
    assert np.array_equal(np.isinf(fast), np.isinf(ref))
    assert np.isinf(ref).any() and np.isfinite(ref).any()  # pitch -45 deg: feet above the horizon
    finite = np.isfinite(ref)
    np.testing.assert_allclose(fast[finite], ref[finite], rtol=1e-4)


def test_grid_recovers_camera_on_the_papers_model():
    rng = np.random.default_rng(11)
    cam = Camera((1920, 1080), 1512.0, None, math.radians(24.0), 0.0, 6.5)
    data = synthetic_pairs(rng, camera=cam, frames=5, people=20, noise_px=0.5, stature_sd_m=0.0)
    res = fit_camera(data.feet_px, data.heads_px, cam.image_size, method="grid")
    spec = GridSpec()
    # the best cell is next to the truth (steps: 0.12 H, 2.76 deg, 0.81 m; off-grid values trade off)
    assert abs(res.camera.focal_px - cam.focal_px) <= np.diff(spec.focal_values_px(1080))[0] + 1e-6
    assert abs(math.degrees(res.camera.pitch_rad - cam.pitch_rad)) <= 135 / 49 + 1e-6
    assert abs(res.camera.height_m - cam.height_m) <= 39.5 / 49 + 1e-6
    assert res.method == "grid" and res.camera.roll_rad == 0.0 and res.inliers == res.pairs


# ---- refinement ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed,outliers,roll", [(1, 0.1, None), (2, 0.3, None), (4, 0.0, 0.0)])
def test_refine_recovers_known_camera(seed, outliers, roll):
    data = synthetic_pairs(np.random.default_rng(seed), frames=100, people=20, outlier_fraction=outliers,
                           roll_deg=roll)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, frame_index=data.frame_index,
                     track_id=data.track_id)
    assert_close_camera(res.camera, data.camera)
    assert res.frames == 100 and res.pairs == len(data.feet_px)
    flagged = ~res.inlier_mask
    assert not data.is_outlier.any() or flagged[data.is_outlier].mean() > 0.6  # most gross outliers rejected
    assert flagged[~data.is_outlier].mean() < 0.05  # few good pairs lost


def test_refine_without_tracks_and_with_focal_fixed():
    data = synthetic_pairs(np.random.default_rng(6), frames=50, people=20, outlier_fraction=0.1, roll_deg=None)
    cam = data.camera
    res = fit_camera(data.feet_px, data.heads_px, cam.image_size, focal_px=cam.focal_px)
    assert res.camera.focal_px == cam.focal_px and math.isnan(res.std["focal_px"])
    assert math.isnan(res.corr_focal_pitch)
    assert_close_camera(res.camera, cam, pitch=0.7, height=0.05)


def test_refine_no_roll_and_vertical_residual():
    data = synthetic_pairs(np.random.default_rng(7), frames=60, people=20, outlier_fraction=0.1, roll_deg=0.0)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, estimate_roll=False,
                     residual="vertical", track_id=data.track_id)
    assert res.camera.roll_rad == 0.0 and math.isnan(res.std["roll_deg"])
    # head rows only: a steep camera (55 deg) loses the sideways lean of people; the std says so
    assert_close_camera(res.camera, data.camera, focal=0.06, pitch=0.7, height=0.06)
    assert abs(res.camera.focal_px - data.camera.focal_px) < 3 * res.std["focal_px"]
    assert abs(res.camera.height_m - data.camera.height_m) < 3 * res.std["height_m"]
    assert res.residual == "vertical"


def test_refine_is_exact_on_noise_free_data_with_outliers():
    data = synthetic_pairs(np.random.default_rng(8), frames=30, people=15, noise_px=0.0, stature_sd_m=0.0,
                           outlier_fraction=0.2, roll_deg=None)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size)
    # An outlier may land within the noise floor of the true head (MIN_NOISE_PX): it is then not an
    # outlier to any fit. Every outlier the fit kept must be such a one, and the camera exact to it.
    cam = data.camera
    kept = res.inlier_mask & data.is_outlier
    true_heads = predict_heads_px(data.feet_px[kept], cam.focal_px, cam.pitch_rad, cam.roll_rad, cam.height_m,
                                  cam.principal_point, 1.70)
    assert np.all(np.linalg.norm(true_heads - data.heads_px[kept], axis=-1) < 2.0)
    assert res.inliers >= (~data.is_outlier).sum()
    assert_close_camera(res.camera, data.camera, focal=5e-4, pitch=1e-2, roll=1e-2, height=5e-4)
    assert res.rmse_px < 0.1 + 1e-3 * kept.sum()


def test_result_does_not_depend_on_the_order_of_people():
    data = synthetic_pairs(np.random.default_rng(9), frames=40, people=15, outlier_fraction=0.1, roll_deg=None)
    perm = np.random.default_rng(0).permutation(len(data.feet_px))
    kw = dict(image_size=data.camera.image_size)
    a = fit_camera(data.feet_px, data.heads_px, frame_index=data.frame_index, track_id=data.track_id, **kw)
    b = fit_camera(data.feet_px[perm], data.heads_px[perm], frame_index=data.frame_index[perm],
                   track_id=data.track_id[perm], **kw)
    for name in ("focal_px", "pitch_rad", "roll_rad", "height_m"):
        assert getattr(b.camera, name) == pytest.approx(getattr(a.camera, name), rel=1e-7, abs=1e-9)
    assert np.array_equal(a.inlier_mask[perm], b.inlier_mask)


def test_ambiguous_focal_is_reported_not_hidden():
    # one frame of ten people: focal and pitch slide along a valley
    data = synthetic_pairs(np.random.default_rng(21), frames=1, people=10, roll_deg=0.0)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size)
    assert all(math.isfinite(v) and v > 0 for v in res.std.values())
    rel_sd = res.std["focal_px"] / res.camera.focal_px
    assert abs(res.camera.focal_px - data.camera.focal_px) < 3 * res.std["focal_px"]
    if rel_sd > 0.1:
        assert any("focal length poorly determined" in w for w in res.warnings)
    assert -1.0 <= res.corr_focal_pitch <= 1.0


def test_fov_prior_pulls_an_undetermined_focal():
    data = synthetic_pairs(np.random.default_rng(22), frames=1, people=6, roll_deg=0.0)
    size = data.camera.image_size
    true_fov = math.degrees(data.camera.vertical_fov_rad)
    loose = fit_camera(data.feet_px, data.heads_px, size)
    tight = fit_camera(data.feet_px, data.heads_px, size, fov_prior_deg=true_fov, fov_prior_sd_deg=0.5)
    assert abs(math.degrees(tight.camera.vertical_fov_rad) - true_fov) < 1.5
    assert tight.std["focal_px"] <= loose.std["focal_px"]


# ---- box-derived points, lens distortion, honest std --------------------------------------------------------
TC_LIKE = Camera((1920, 1080), 2700.0, None, math.radians(20.0), math.radians(1.4), 7.8)  # a street camera


def test_box_points_are_the_box_bottom_and_top_centres():
    cam = TC_LIKE
    ground = cam.world_from_cam(cam.backproject_px_to_ground(np.array([[500.0, 900.0], [1400.0, 600.0]])))
    crown = ground + [0.0, 1.7, 0.0]
    feet, heads = box_points_px(cam, ground, crown, np.array([0.3, 2.0]), np.array([1.0, 0.0]))
    np.testing.assert_array_equal(feet[:, 0], heads[:, 0])  # one column: the box's centre
    assert np.all(feet[:, 1] > cam.project(cam.cam_from_world(ground))[:, 1])  # nearest toe: lower than mid-sole
    assert np.all(heads[:, 1] <= cam.project(cam.cam_from_world(crown))[:, 1] + 1e-9)  # head top: at or above crown


def test_boxes_point_model_removes_the_box_height_bias():
    # box-derived points (nearest toe, head silhouette) read as mid-sole/crown put the camera ~6% low;
    # the box model (box top 0.25 m beyond the bottom, head row) recovers it
    data = synthetic_pairs(np.random.default_rng(31), camera=TC_LIKE, frames=100, people=20, points="boxes",
                           outlier_fraction=0.05)
    kw = dict(frame_index=data.frame_index, track_id=data.track_id, focal_px=TC_LIKE.focal_px)
    naive = fit_camera(data.feet_px, data.heads_px, TC_LIKE.image_size, residual="vertical", **kw)
    boxes = fit_camera(data.feet_px, data.heads_px, TC_LIKE.image_size, points="boxes", **kw)
    assert naive.camera.height_m / TC_LIKE.height_m - 1 < -0.03
    assert_close_camera(boxes.camera, TC_LIKE, pitch=0.4, roll=0.5, height=0.03)
    assert boxes.residual == "vertical" and boxes.points == "boxes" and boxes.box_depth_m == 0.25
    assert boxes.std["height_m"] > naive.std["height_m"]  # the box depth's uncertainty is in the std
    fit = boxes.fit_dict()
    assert fit["points"] == "boxes" and fit["box_depth_m"] == 0.25 and "distortion" not in fit


def test_distortion_is_fitted_when_asked():
    data = synthetic_pairs(np.random.default_rng(32), camera=TC_LIKE, frames=100, people=20, distortion=-0.03)
    kw = dict(frame_index=data.frame_index, track_id=data.track_id, focal_px=TC_LIKE.focal_px)
    plain = fit_camera(data.feet_px, data.heads_px, TC_LIKE.image_size, **kw)
    lens = fit_camera(data.feet_px, data.heads_px, TC_LIKE.image_size, distortion=True, **kw)
    pitch_err = [abs(math.degrees(r.camera.pitch_rad - TC_LIKE.pitch_rad)) for r in (plain, lens)]
    assert pitch_err[0] > 0.15 and pitch_err[1] < 0.4 * pitch_err[0]  # barrel distortion tilts the pinhole fit
    assert lens.distortion < 0 and lens.std["distortion"] < abs(lens.distortion) / 3  # barrel, and determined
    assert lens.fit_dict()["distortion"] == lens.distortion and "distortion" in lens.fit_dict()["std"]
    assert math.isnan(plain.distortion) and "distortion" not in plain.std


def test_distortion_free_data_leave_the_lens_out():
    """A coefficient the pairs cannot tell from none (fit.LENS_SIGNIFICANCE) is not applied: the pinhole fit,
    with a note naming what the pairs suggested."""
    data = synthetic_pairs(np.random.default_rng(33), frames=60, people=20, roll_deg=None, outlier_fraction=0.1)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, frame_index=data.frame_index,
                     track_id=data.track_id, distortion=True)
    assert res.camera.distortion == 0.0 and math.isnan(res.distortion) and res.fixed["distortion"] == "not significant"
    assert any(n.startswith("lens not applied") for n in res.notes)
    assert_close_camera(res.camera, data.camera)


def test_jackknife_is_leave_one_cluster_out_on_a_linear_problem():
    rng = np.random.default_rng(34)
    J = rng.normal(size=(60, 3))
    y = J @ [1.0, -2.0, 0.5] + rng.normal(size=60)
    cluster = np.repeat(np.arange(6), 10)
    theta = np.linalg.lstsq(J, y, rcond=None)[0]
    loo = np.array([np.linalg.lstsq(J[cluster != g], y[cluster != g], rcond=None)[0] for g in range(6)])
    expected = (loo - theta).T @ (loo - theta) * 5 / 6  # CV3 about the full-sample estimate
    np.testing.assert_allclose(jackknife_cov(J, J @ theta - y, cluster, 6), expected, rtol=1e-9, atol=1e-12)


def test_track_correlated_noise_with_few_people_is_in_the_std():
    # 6 people whose pixel noise drifts slowly (AR(1) 0.95 over frames): the cluster jackknife over
    # the people, not Gauss-Newton over the pairs, sets the std
    errs, sds = [], []
    for seed in range(4):
        data = synthetic_pairs(np.random.default_rng(40 + seed), camera=TC_LIKE, frames=150, people=6,
                               noise_corr=0.95)
        res = fit_camera(data.feet_px, data.heads_px, TC_LIKE.image_size, frame_index=data.frame_index,
                         track_id=data.track_id, focal_px=TC_LIKE.focal_px, residual="vertical")
        errs.append(math.degrees(res.camera.roll_rad - TC_LIKE.roll_rad))
        sds.append(res.std_statistical["roll_deg"])
    assert np.mean(np.abs(errs) < 2.5 * np.array(sds)) >= 0.75


def test_head_columns_that_disagree_with_the_rows_inflate_the_focal_std():
    data = synthetic_pairs(np.random.default_rng(35), camera=TC_LIKE, frames=100, people=20, points="boxes")
    res = fit_camera(data.feet_px, data.heads_px, TC_LIKE.image_size, frame_index=data.frame_index,
                     track_id=data.track_id)  # box-derived points read as mid-sole/crown, full residual
    assert any("head columns disagree" in w for w in res.warnings)
    assert res.std["focal_px"] > 1.1 * res.std_statistical["focal_px"]  # the disagreement is in the std (up to
    # the lens prior's sd) and the camera, 5x the true focal, is never used silently: it is flagged
    assert abs(res.camera.focal_px - TC_LIKE.focal_px) < 2 * res.std["focal_px"] or any(
        finding.startswith("focal length") for finding in res.implausible)
    clean = synthetic_pairs(np.random.default_rng(35), camera=TC_LIKE, frames=100, people=20)
    ok = fit_camera(clean.feet_px, clean.heads_px, TC_LIKE.image_size, frame_index=clean.frame_index,
                    track_id=clean.track_id)
    assert not any("head columns disagree" in w for w in ok.warnings)


# ---- diagnostics and wrappers ---------------------------------------------------------------------------
def test_fit_dict_is_plain_yaml():
    data = synthetic_pairs(np.random.default_rng(10), frames=5, people=10)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, focal_px=data.camera.focal_px,
                     frame_index=data.frame_index)
    d = res.fit_dict()
    assert yaml.safe_load(yaml.safe_dump(d)) == d
    assert d["std"]["focal_px"] is None and d["corr_focal_pitch"] is None
    assert set(d) >= {"method", "person_height_m", "pairs", "inliers", "frames", "rmse_px", "std", "warnings"}
    assert d["frames"] == 5 and d["pairs"] == 50 and isinstance(d["warnings"], list)
    assert isinstance(res, CalibrationResult) and res.inlier_mask.shape == (50,)


def test_calibrate_returns_the_camera():
    data = synthetic_pairs(np.random.default_rng(12), frames=3, people=10)
    cam = calibrate(data.feet_px, data.heads_px, data.camera.image_size, focal_px=data.camera.focal_px)
    assert isinstance(cam, Camera) and cam.focal_px == data.camera.focal_px


def test_fit_per_frame_reports_the_spread():
    data = synthetic_pairs(np.random.default_rng(13), frames=6, people=8, roll_deg=0.0)
    frame = data.frame_index.copy()
    keep = ~((frame == 5) & (np.arange(len(frame)) % 8 > 1))  # frame 5 keeps 2 pairs only
    summary = fit_per_frame(data.feet_px[keep], data.heads_px[keep], data.camera.image_size, frame[keep],
                            focal_px=data.camera.focal_px, estimate_roll=False)
    assert summary.frame_ids == (0, 1, 2, 3, 4, 5) and not summary.skipped  # 2 pairs: the priors cover the rest
    two = summary.results[5]  # ... and the answer is within its std
    assert abs(math.degrees(two.camera.pitch_rad - data.camera.pitch_rad)) < 3 * two.std["pitch_deg"]
    assert summary.iqr["pitch_deg"] >= 0 and abs(summary.median["pitch_deg"]
                                                  - math.degrees(data.camera.pitch_rad)) < 3


# ---- errors ------------------------------------------------------------------------------------------
def test_too_few_pairs():
    feet = np.array([[100.0, 400.0], [300.0, 420.0], [500.0, 440.0]])
    heads = feet - (0.0, 80.0)
    heads[2, 1] = 460.0  # head below the foot: not usable
    with pytest.raises(DegenerateSceneError, match=r"only 2 usable foot-head pairs \(need >= 3 without the lens"):
        fit_camera(feet, heads, (640, 480), focal_prior="none")
    with pytest.raises(DegenerateSceneError, match="no usable foot-head pair"):
        fit_camera(np.zeros((0, 2)), np.zeros((0, 2)), (640, 480))


def test_two_pairs_answer_from_the_priors_and_say_so():
    """Two people in one photo: the priors answer what two pairs cannot, and the result says which."""
    cam = Camera((640, 480), 480.0, None, math.radians(8.0), 0.0, 1.6)
    feet = np.array([[200.0, 400.0], [420.0, 410.0]])
    heads = cam.project(cam.backproject_px_to_ground(feet) + 1.7 * cam.up_cam)
    res = fit_camera(feet, heads, (640, 480), focal_px=480.0)
    assert "focal_px" not in res.determined_by and res.fixed["focal_px"] == "given"
    assert abs(math.degrees(res.camera.pitch_rad) - 8.0) < 2 * res.std["pitch_deg"]
    assert abs(res.camera.height_m - 1.6) < 2 * res.std["height_m"]
    free = fit_camera(feet, heads, (640, 480))
    assert "prior" in free.determined_by["focal_px"].split("+") and free.focal_prior == "lens"


def test_nan_and_swapped_inputs():
    feet = np.array([[100.0, 400.0], [300.0, 420.0], [500.0, 440.0], [200.0, 380.0]])
    heads = feet - (0.0, 80.0)
    bad = feet.copy()
    bad[2, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        fit_camera(bad, heads, (640, 480))
    with pytest.raises(ValueError, match="head is not above the foot.*swapped"):
        fit_camera(heads, feet, (640, 480))


@pytest.mark.parametrize("kwargs,match", [
    (dict(image_size=(0, 480)), "image_size"),
    (dict(image_size=(640,)), "image_size"),
    (dict(method="magic"), "method"),
    (dict(residual="sideways"), "residual"),
    (dict(focal_px=-5.0), "focal_px"),
    (dict(person_height_m=0.0), "person_height_m"),
    (dict(frame_index=np.zeros(3, int)), "frame_index"),
    (dict(points="keypoints"), "points"),
    (dict(method="grid", distortion=True), "need method 'refine'"),
    (dict(method="grid", points="boxes"), "need method 'refine'"),
    (dict(points="boxes", box_depth_sd_m=-0.1), "box_depth"),
])
def test_bad_arguments(kwargs, match):
    feet = np.array([[100.0, 400.0], [300.0, 420.0], [500.0, 440.0], [200.0, 380.0]])
    args = dict(image_size=(640, 480))
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        fit_camera(feet, feet - (0.0, 80.0), **args)


# ---- options: one dataclass, defaults from the packaged YAML ------------------------------------------
def test_options_defaults_are_the_packaged_config():
    section = default_config()["calibrate"]
    assert CalibrateOptions() == CalibrateOptions.from_config(section)  # the dataclass cannot drift from the YAML
    assert set(CalibrateOptions.config_keys()) == set(section)  # every option of the section, no other


def test_options_from_config_refuse_unknown_missing_and_bad_values():
    section = default_config()["calibrate"]
    with pytest.raises(InputError, match="unknown key.*noise_px"):
        CalibrateOptions.from_config({**section, "noise_px": 1.0})  # Python-only: not a config key
    with pytest.raises(InputError, match="missing key.*focal_px"):
        CalibrateOptions.from_config({k: v for k, v in section.items() if k != "focal_px"})
    with pytest.raises(InputError, match=r"calibrate: distortion and points='boxes' need method 'refine'"):
        CalibrateOptions.from_config({**section, "method": "grid", "distortion": True})
    with pytest.raises(InputError, match=r"calibrate\.grid: .*steps"):
        CalibrateOptions.from_config({**section, "grid": {**section["grid"], "steps": [3, 0, 3]}})
    opts = CalibrateOptions.from_config({**section, "principal_point": [600, 350], "focal_px": 900})
    assert opts.principal_point == (600.0, 350.0) and opts.focal_px == 900.0


def test_options_as_keywords_are_the_same_fit():
    data = synthetic_pairs(np.random.default_rng(14), frames=4, people=10)
    size = data.camera.image_size
    a = fit_camera(data.feet_px, data.heads_px, size, CalibrateOptions(focal_px=data.camera.focal_px,
                                                                      estimate_roll=False))
    b = fit_camera(data.feet_px, data.heads_px, size, CalibrateOptions(estimate_roll=False),
                   focal_px=data.camera.focal_px)
    assert a.camera == b.camera and a.std == b.std
    with pytest.raises(TypeError, match="unknown calibration option.*focal "):
        fit_camera(data.feet_px, data.heads_px, size, focal=900.0)
    with pytest.raises(TypeError, match="CalibrateOptions"):
        fit_camera(data.feet_px, data.heads_px, size, {"focal_px": 900.0})


def test_parameter_slots_are_named():
    p = param_vector(focal=900.0, pitch=0.4, roll=-0.01, height=6.0)
    assert (p[FOCAL], p[PITCH], p[ROLL], p[HEIGHT]) == (900.0, 0.4, -0.01, 6.0) and p.shape == (6,)


# ---- residual kinds: a registry ----------------------------------------------------------------------------
def test_the_registry_holds_the_residual_kinds():
    assert RESIDUALS == ("full", "vertical") == tuple(RESIDUAL_KINDS)
    assert residual_kind("full").dof == 2 and residual_kind("vertical").dof == 1
    with pytest.raises(ValueError, match=r"residual must be one of \('full', 'vertical'\), got 'sideways'"):
        residual_kind("sideways")
    from rotavat_cli.cli.calibrate import _RESIDUAL_HELP
    from rotavat_cli.calibration.options import CalibrateOptions

    assert CalibrateOptions.RULES["residual"].names == RESIDUALS  # the option's choices are the registry's
    assert all(f"{name} (" in _RESIDUAL_HELP for name in RESIDUALS)  # and so is --residual's help


@pytest.mark.parametrize("name", RESIDUALS)
def test_every_residual_kind_keeps_the_contract(name):
    """What the fit relies on, for any registered kind: whitened components whose first is along the
    person, the grid's fast kernel equal to the model's cost, an exact fit on noise-free pairs."""
    kind = residual_kind(name)
    data = synthetic_pairs(np.random.default_rng(15), frames=3, people=12, noise_px=0.0, stature_sd_m=0.0,
                           roll_deg=0.0)
    cam = data.camera
    W, H = cam.image_size
    prob = make_problem(data.feet_px, data.heads_px, np.array([W / 2, H / 2]), 1.7, 0.07, 2.0, kind, (W, H), None,
                        None)
    params = param_vector(focal=cam.focal_px * 1.1, pitch=cam.pitch_rad, roll=0.0, height=cam.height_m)[None]
    r, _, valid = whitened(prob, params)
    assert r.shape == (1, len(data.feet_px), kind.dof) and valid.all()
    e, _, _, cov = profiled(prob, params)
    np.testing.assert_allclose(r[..., 0] * np.sqrt(kind.along_variance(cov, prob.axis)), kind.along(e, prob.axis),
                               rtol=1e-12)
    spec = GridSpec(steps=(6, 7, 5))
    focal, pitch, height = spec.focal_values_px(H), spec.pitch_values_rad(), spec.height_values_m()
    fast = grid_costs(data.feet_px, data.heads_px, (W / 2, H / 2), focal, pitch, height, 1.7, name)
    ff, pp_, cc = (a.ravel() for a in np.meshgrid(focal, pitch, height, indexing="ij"))
    ref = reference_cell_costs(data.feet_px, data.heads_px, ff, pp_, cc, (W / 2, H / 2), 1.7, name)
    assert np.array_equal(np.isinf(fast.ravel()), np.isinf(ref))
    np.testing.assert_allclose(fast.ravel()[np.isfinite(ref)], ref[np.isfinite(ref)], rtol=1e-4)
    res = fit_camera(data.feet_px, data.heads_px, (W, H), residual=name, focal_px=cam.focal_px, estimate_roll=False)
    assert res.residual == name
    assert_close_camera(res.camera, cam, focal=1e-9, pitch=1e-3, roll=1e-9, height=1e-4)


def test_the_chi_square_table_is_scipys_to_four_decimals():
    """calibration/chi_square.py's quantiles (a table: no scipy import on calibrate's path) are the distribution's."""
    from scipy.stats import chi2

    from rotavat_cli.calibration.chi_square import CHI2_99, CHI2_MEDIAN
    from rotavat_cli.calibration.params import N_PARAMS

    assert sorted(CHI2_99) == sorted(CHI2_MEDIAN) == list(range(1, N_PARAMS + 1))  # every rank a fit can have
    for dof in CHI2_99:
        assert CHI2_99[dof] == pytest.approx(chi2.ppf(0.99, dof), abs=5e-5)
        assert CHI2_MEDIAN[dof] == pytest.approx(chi2.ppf(0.5, dof), abs=5e-5)
