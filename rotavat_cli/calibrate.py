"""Calibrate a static camera from the people it sees: foot (mid-sole) and head (crown) pixels only.

Two methods (conventions: docs/conventions.md; the model and the fast grid: :mod:`.calibrate_grid`):

- ``"grid"``: the seed paper exactly. Focal, pitch and camera height on a 50^3 grid, roll 0,
  principal point at the image centre, stature 1.70 m, least squares on the head pixels; the
  result is the grid's best cell.
- ``"refine"`` (default): a robust (truncated) grid on an order-independent subsample seeds a few
  starts along the focal/pitch valley; each is refined continuously (``scipy.optimize.least_squares``,
  Cauchy then soft-L1 loss) over log-focal, pitch, roll and log-height, with rounds of outlier
  rejection (chi-square test on each pair's whitened residual, robust scale from the median);
  the best start is refined on all pairs. Residuals are split along and across the person's
  image axis. The stature prior ``N(S, sd_S)`` enters in two ways: a tracked person (track id
  >= 0) has its own stature, profiled out with that prior, so a person walking through the scene
  constrains the perspective whatever their height; an untracked pair carries the spread in its
  along-the-person weight ``sqrt(noise^2 + (L sd_S / S)^2)`` (``L`` its pixel length). Optional:
  known principal point, fixed focal, no roll, head-row-only residuals, a weak prior on the
  vertical field of view, radial lens distortion (one-parameter division model, fitted), and
  box-derived points (``points="boxes"``: a box's bottom is the nearest foot point and its top
  the head's silhouette, so the top stands a box depth, 0.25 m, farther from the camera than the
  bottom; the head row only, since a box's two centres share one column).

From upright people on a plane the horizon (~ f tan(pitch)) and the camera height are well
determined, but focal and pitch slide along a valley. :class:`CalibrationResult` reports standard
deviations: the fit's own (Gauss-Newton at the optimum, or per parameter the larger of it and a
cluster jackknife over tracks, else frames) plus, linearised, what the model assumes without
knowing it (principal point, mild radial distortion unless fitted, the people's mean stature, the
box depth); with the full residual, the disagreement between the head rows alone and the joint
fit when a Hausman test rejects it (head columns that do not follow the model); the focal/pitch
correlation; and warnings in plain words.

Examples
--------
>>> cam = Camera((640, 480), 500.0, None, np.deg2rad(30.0), 0.0, 5.0)
>>> feet_px = np.array([[100.0, 300.0], [320.0, 400.0], [500.0, 350.0], [250.0, 460.0], [600.0, 420.0]])
>>> heads_px = cam.project(cam.backproject_px_to_ground(feet_px) + 1.7 * cam.up_cam)
>>> res = fit_camera(feet_px, heads_px, (640, 480), focal_px=500.0)
>>> round(float(np.rad2deg(res.camera.pitch_rad)), 4), round(res.camera.height_m, 4), res.inliers
(30.0, 5.0, 5)
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from .calibrate_grid import GridSpec, paper_grid_search
from .camera import Camera, horizon_v_px
from .errors import DegenerateSceneError
from .calibrate_model import (MIN_NOISE_PX, MODEL_NAMES, PARAM_NAMES, Problem, make_problem, param_bounds, profiled,
                              refine_fit, to_internal)
from .calibrate_uncertainty import Systematics, covariances, fit_warnings, std_and_corr

__all__ = ["CalibrationResult", "PerFrameSummary", "GridSpec", "fit_camera", "calibrate", "fit_per_frame"]

METHODS = ("grid", "refine")
RESIDUALS = ("full", "vertical")
POINTS = ("auto", "landmarks", "boxes")  # auto: boxes when every pair's head is in its foot's column
# Box-derived points: a box's top- and bottom-centre share one column exactly; landmark points
# (mid-sole, crown) of real people never do all at once (verticals converge, people sway).
BOX_COLUMN_TOL_PX = 0.5
# People at one depth (feet along one image row, up to a tilt of the roll's size) cannot tell the
# camera: no depth spread, no perspective. Why these numbers: a receding ground line images steeper
# than 10 deg; the feet of people at one depth scatter by their detection noise only (a few px),
# well under 10% of a person's pixel height.
_ONE_DEPTH_MAX_SLOPE = math.tan(math.radians(10.0))
_ONE_DEPTH_SPREAD = 0.10
# A refined parameter closer than this to its start (internal units: log f, rad, rad, log h, ...)
# did not move: the pairs did not constrain the refinement.
_UNMOVED_TOL = 1e-4
# Box depth, m, and its sd (why: a box's bottom is the walker's lowest image point, the nearest
# foot's toe or heel: half a foot length, 0.13 m, plus on average ~0.1 m of stride toward the
# camera; its top is the head's silhouette, ~0.03 m beyond the crown for a camera looking down;
# the sd spans standing people, 0.15 m, to long strides, 0.35 m).
BOX_DEPTH_M = 0.25
BOX_DEPTH_SD_M = 0.10


@dataclass(frozen=True)
class CalibrationResult:
    """An estimated camera with the diagnostics of its fit (never a silent default camera)."""

    camera: Camera
    method: str  # "grid" | "refine"
    person_height_m: float
    pairs: int  # foot-head pairs offered
    inliers: int  # pairs kept by the fit
    frames: int  # distinct frames among the pairs
    rmse_px: float  # head reprojection residual over the inliers (2D, or rows only if vertical)
    std: dict[str, float]  # focal_px, pitch_deg, roll_deg, height_m; NaN when fixed
    corr_focal_pitch: float  # NaN when either is fixed
    inlier_mask: np.ndarray  # (N,) bool
    warnings: tuple[str, ...] = ()
    residual: str = "full"  # "full" | "vertical"
    std_statistical: dict[str, float] = field(default_factory=dict)  # the fit's own part of ``std``
    points: str = "landmarks"  # "landmarks" (mid-sole, crown) | "boxes" (box bottom- and top-centre)
    distortion: float = math.nan  # fitted division-model coefficient (NaN: not fitted)
    box_depth_m: float = 0.0  # assumed box depth, m (boxes only; 0 for landmarks)
    fixed: dict[str, str] = field(default_factory=dict)  # parameter -> why it was not estimated
    notes: tuple[str, ...] = ()  # what rotavat decided on its own (e.g. box-derived points detected)
    person_height_estimated: bool = False  # the mean stature was estimated (camera height given), not assumed
    person_height_std_m: float = math.nan  # its std when estimated

    @property
    def horizon_v_px(self) -> float:
        """Image row of the horizon at the image's centre column."""
        cam = self.camera
        return float(horizon_v_px(cam.image_size[0] / 2.0, cam.focal_px, cam.principal_point, cam.up_cam))

    def fit_dict(self) -> dict:
        """Plain-typed ``fit:`` block of camera.yaml (docs/conventions.md); NaN becomes None."""
        return {
            "method": self.method,
            "residual": self.residual,
            "person_height_m": float(self.person_height_m),
            "pairs": int(self.pairs),
            "inliers": int(self.inliers),
            "frames": int(self.frames),
            "rmse_px": _plain(self.rmse_px),
            "std": {**{k: _plain(self.std.get(k, math.nan)) for k in MODEL_NAMES if k in PARAM_NAMES or k in self.std},
                    **({"person_height_m": _plain(self.person_height_std_m)} if self.person_height_estimated else {})},
            "fixed": dict(self.fixed),
            "person_height": "estimated" if self.person_height_estimated else "assumed",
            "corr_focal_pitch": _plain(self.corr_focal_pitch),
            "horizon_v_px": _plain(self.horizon_v_px),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "points": self.points,
            **({"distortion": float(self.distortion)} if math.isfinite(self.distortion) else {}),
            **({"box_depth_m": float(self.box_depth_m)} if self.points == "boxes" else {}),
        }


def _plain(x: float) -> float | None:
    """Float for YAML, None for NaN (a fixed parameter); an undetermined std stays inf (YAML .inf)."""
    x = float(x)
    return None if math.isnan(x) else x


@dataclass(frozen=True)
class PerFrameSummary:
    """Every frame calibrated alone: per-frame results and the spread of each parameter."""

    frame_ids: tuple[int, ...]  # frames that were fitted
    results: tuple[CalibrationResult, ...]
    skipped: dict[int, str]  # frame id -> why it could not be fitted
    median: dict[str, float]  # per parameter (PARAM_NAMES), over the fitted frames
    iqr: dict[str, float]  # 75th minus 25th percentile


# ---- input checks ----------------------------------------------------------------------------------
def _check_image_size(image_size) -> tuple[int, int]:
    """(W, H) as positive ints, or ValueError."""
    try:
        w, h = (float(v) for v in image_size)
    except (TypeError, ValueError):
        raise ValueError(f"image_size must be [W, H] in pixels, got {image_size!r}") from None
    if not (math.isfinite(w) and math.isfinite(h) and w >= 1 and h >= 1):
        raise ValueError(f"image_size must be two positive numbers [W, H], got {image_size!r}")
    return int(round(w)), int(round(h))


def _check_points(feet_px, heads_px) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Float64 (N, 2) feet and heads and the (N,) mask of usable pairs (head above the foot)."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    if feet.ndim != 2 or feet.shape[1:] != (2,) or heads.shape != feet.shape:
        raise ValueError(f"feet_px and heads_px must both have shape (N, 2), got {feet.shape} and {heads.shape}")
    bad = ~(np.isfinite(feet).all(axis=1) & np.isfinite(heads).all(axis=1))
    if bad.any():
        raise ValueError(f"{int(bad.sum())} foot-head pairs have NaN or infinite pixels (first: pair "
                         f"{int(np.flatnonzero(bad)[0])}); drop them before calibrating")
    below = heads[:, 1] >= feet[:, 1]
    if len(feet) and below.sum() * 2 > len(feet):
        raise ValueError(f"the head is not above the foot (head v >= foot v) in {int(below.sum())} of {len(feet)} "
                         "pairs; image v points down, so heads need smaller v: are feet and heads swapped?")
    return feet, heads, ~below


def _check_index(values, n: int, name: str) -> np.ndarray | None:
    """(N,) int64 array or None, or ValueError."""
    if values is None:
        return None
    arr = np.asarray(values)
    if arr.shape != (n,) or not (np.issubdtype(arr.dtype, np.integer) or n == 0):
        raise ValueError(f"{name} must be an (N,) integer array matching the {n} pairs, got {arr.dtype} {arr.shape}")
    return arr.astype(np.int64)


# ---- public API -----------------------------------------------------------------------------------
def fit_camera(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int], *, method: str = "refine",
               frame_index: np.ndarray | None = None, track_id: np.ndarray | None = None,
               focal_px: float | None = None, estimate_roll: bool = True,
               principal_point: tuple[float, float] | None = None, person_height_m: float = 1.70,
               person_height_sd_m: float = 0.07, camera_height_m: float | None = None, residual: str = "full",
               points: str = "auto", distortion: bool = False, box_depth_m: float = BOX_DEPTH_M,
               box_depth_sd_m: float = BOX_DEPTH_SD_M, fov_prior_deg: float | None = None,
               fov_prior_sd_deg: float = 10.0, noise_px: float = 2.0, grid: GridSpec = GridSpec(),
               principal_point_sd_px: float | None = None, distortion_sd: float = 0.01,
               person_height_mean_sd_m: float = 0.04, max_rounds: int = 6,
               workers: int | None = None) -> CalibrationResult:
    """Estimate the static camera from foot/head pixel pairs pooled over all frames.

    feet_px, heads_px: (N, 2) px, mid-sole and crown; image_size: (W, H) px.
    frame_index, track_id: (N,) int, optional (frame count; clusters for the uncertainty).
    focal_px: fix the focal length (else estimated). principal_point: (cx, cy), default the centre.
    camera_height_m: the camera's known height above the ground (m): it fixes the metric scale,
    and the people's mean stature is estimated instead of assumed (``person_height_m`` of the
    result, with ``person_height_std_m``). The model sees stature and height only through their
    ratio, so the fit is the same and only the scale moves to the stature.
    method: "grid" (the paper: roll 0, no robustness) or "refine". points: "landmarks" (mid-sole
    and crown), "boxes" (bottom- and top-centre of person boxes, refine only: the box top lies
    box_depth_m farther from the camera along the ground than the box bottom; a box's two
    centres share a column by construction, so boxes always use the head row) or "auto" (boxes
    when every pair's head is within BOX_COLUMN_TOL_PX of its foot's column, said in ``notes``).
    residual: "full" (head u and v) or "vertical" (head row only). distortion: also fit a
    one-parameter division model of radial lens distortion (refine only;
    ``CalibrationResult.distortion`` is about the relative displacement at the image corner,
    negative for barrel). fov_prior_deg: mean of a weak prior on the vertical field of view (sd
    fov_prior_sd_deg), used when the focal is estimated (refine only). noise_px: pixel noise of
    the points (refine weights). workers: grid threads (None = auto).
    The reported std adds, to the fit's own uncertainty, what the model assumes but cannot know:
    the principal point (sd principal_point_sd_px per axis; None = 2% of the larger image side,
    or 0 when principal_point is given), radial lens distortion unless fitted (sd of the corner
    displacement over the half-diagonal, distortion_sd), the people's mean stature
    (person_height_mean_sd_m; not when camera_height_m is given) and, for boxes, the box depth
    (box_depth_sd_m); with the full residual, the disagreement of the head rows with the joint
    fit when a test rejects it. A refinement that ends where it started (the pairs did not move
    it) falls back to the paper grid's best cell, with a warning.
    Raises ValueError for malformed input and DegenerateSceneError when the pairs cannot
    determine a camera (fewer than 3 usable pairs, or no candidate camera is valid).
    """
    notes: list[str] = []
    if points == "auto":
        points, notes = _resolve_points(feet_px, heads_px, method)
    with _naming_the_chosen_model(notes, points):
        if camera_height_m is not None and not (math.isfinite(camera_height_m) and camera_height_m > 0):
            raise ValueError(f"camera_height_m must be a positive number of metres, got {camera_height_m}")
        size, feet, heads, usable, frames, tracks, pp, fov, residual = _check_inputs(
            feet_px, heads_px, image_size, method, residual, points, distortion, box_depth_m, box_depth_sd_m, frame_index,
            track_id, focal_px, estimate_roll, principal_point, person_height_m, person_height_sd_m, noise_px,
            fov_prior_deg, fov_prior_sd_deg)
        n_usable = int(usable.sum())
        n_frames = 1 if frames is None else len(np.unique(frames[usable]))
        idx = np.flatnonzero(usable)
        prob = make_problem(feet[idx], heads[idx], pp, float(person_height_m), float(person_height_sd_m),
                             float(noise_px), residual == "vertical", size, fov,
                             None if tracks is None or method == "grid" else tracks[idx])
        extra: list[str] = []
        if method == "refine":
            free = np.array([focal_px is None, True, estimate_roll, True, distortion, False])
            box = float(box_depth_m) if points == "boxes" else 0.0
            params, mask_u, scale, start = refine_fit(prob, feet[idx], heads[idx], pp, size, focal_px, free, box, grid,
                                                      max_rounds)
            if _unmoved(params, start, free):
                method = "grid"
                extra = [f"the refinement ended where it started (pitch {math.degrees(params[1]):.5f} deg, height "
                         f"{params[3]:.5f} m): the pairs do not constrain it; falling back to the paper grid's best cell"]
            else:
                _refuse_bounds(params, free, size[1])
        if method == "grid":
            params, mask_u, free, scale, grid_warns, prob = _grid_fit(feet[idx], heads[idx], pp, size, focal_px,
                                                                      person_height_m, residual, grid, workers, prob)
            extra += grid_warns
        if focal_px is not None:
            params[0] = float(focal_px)  # exactly as given (no log/exp round trip)
        camera = Camera(size, params[0], tuple(pp), params[1], params[2], params[3])  # params[4:]: the point model
        inlier_mask = np.zeros(len(feet), bool)
        inlier_mask[idx[mask_u]] = True
        clusters = tracks if tracks is not None else frames
        inl = prob.subset(np.flatnonzero(mask_u))
        pp_sd = (0.02 * max(size) if principal_point is None else 0.0) if principal_point_sd_px is None \
            else float(principal_point_sd_px)
        stature_mean_sd = 0.0 if camera_height_m is not None else float(person_height_mean_sd_m)
        assumed = Systematics(pp_sd, 0.0 if distortion else float(distortion_sd), stature_mean_sd,
                               float(box_depth_sd_m) if points == "boxes" else 0.0)
        cov, cov_stat, cov_warns = covariances(inl, params, free, scale,
                                                None if clusters is None else clusters[idx[mask_u]], assumed,
                                                method == "refine")
        std, corr = std_and_corr(params, cov, free)
        std_stat, _ = std_and_corr(params, cov_stat, free)
        (eu, ev), _, _ = profiled(inl, params[None], scale)
        sq = ev[0] ** 2 if residual == "vertical" else eu[0] ** 2 + ev[0] ** 2
        rmse = float(np.sqrt(np.mean(sq))) if len(sq) else math.nan
        warns = extra + cov_warns + fit_warnings(camera, std, corr, int(mask_u.sum()), n_usable, len(feet))
        if method == "refine" and tracks is None and n_frames > 1:
            warns.append("no track ids: a person seen in several frames counts as a new person each time, so the std "
                         "is too small when people persist (give the person ids)")
        fixed = {name: reason for name, reason, free_ in (
            ("focal_px", "given", free[0]), ("roll_deg", "0 (not estimated)", free[2]),
            ("distortion", "none", free[4] or not distortion)) if not free_}
        stature, stature_sd = float(person_height_m), math.nan
        if camera_height_m is not None:  # the same fit at the known scale: the stature carries it
            ratio = float(camera_height_m) / camera.height_m
            stature, stature_sd = stature * ratio, stature * ratio * std["height_m"] / camera.height_m
            camera = camera.replace(height_m=float(camera_height_m))
            std = {**std, "height_m": math.nan}
            std_stat = {**std_stat, "height_m": math.nan}
            fixed["height_m"] = "given"
        return CalibrationResult(camera, method, stature, len(feet), int(mask_u.sum()), n_frames, rmse,
                                 std, corr, inlier_mask, tuple(warns), residual, std_stat, points,
                                 float(params[4]) if distortion else math.nan,
                                 float(params[5]), fixed, tuple(notes), camera_height_m is not None, stature_sd)


@contextlib.contextmanager
def _naming_the_chosen_model(notes: list[str], points: str) -> Iterator[None]:
    """A DegenerateSceneError says so when rotavat chose the box model by itself."""
    try:
        yield
    except DegenerateSceneError as exc:
        if notes and points == "boxes":
            raise DegenerateSceneError(f"{exc} (with the box model: the points were recognised as box-derived; "
                                       "--points landmarks to override)") from None
        raise


def at_one_depth(feet_px: np.ndarray, heads_px: np.ndarray) -> bool:
    """True when the feet (N, 2) px lie along one nearly level image line, within a tenth of a person's height."""
    u, v = feet_px[:, 0], feet_px[:, 1]
    if len(u) < 3 or np.ptp(u) == 0:
        return len(u) >= 3 and np.ptp(v) < _ONE_DEPTH_SPREAD * np.median(np.linalg.norm(feet_px - heads_px, axis=1))
    slope, offset = np.polyfit(u, v, 1)
    residual = v - (slope * u + offset)
    spread = float(np.subtract(*np.percentile(residual, [95, 5])))
    length = float(np.median(np.linalg.norm(feet_px - heads_px, axis=1)))
    return abs(slope) < _ONE_DEPTH_MAX_SLOPE and spread < _ONE_DEPTH_SPREAD * length


def box_derived(feet_px: np.ndarray, heads_px: np.ndarray, tol_px: float = BOX_COLUMN_TOL_PX) -> bool:
    """True when every finite pair (N, 2) px has its head in its foot's column (boxes' centres), N >= 3."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    finite = np.all(np.isfinite(feet), axis=1) & np.all(np.isfinite(heads), axis=1) if feet.ndim == 2 else []
    du = np.abs(feet[finite, 0] - heads[finite, 0]) if len(finite) else np.zeros(0)
    return len(du) >= 3 and bool(np.all(du <= tol_px))


def _resolve_points(feet_px: np.ndarray, heads_px: np.ndarray, method: str) -> tuple[str, list[str]]:
    """The point model for ``points="auto"`` and a note saying what was decided, if anything."""
    if not box_derived(feet_px, heads_px):
        return "landmarks", []
    if method == "grid":
        return "landmarks", ["every pair's head is in its foot's column (box-derived points?), but the paper grid "
                             "knows only mid-sole and crown points: use --method refine for the box model"]
    return "boxes", ["every pair's head is in its foot's column: box-derived points (bottom- and top-centre of "
                     "person boxes); using the box model (--points landmarks to override)"]


def _unmoved(params: np.ndarray, start: np.ndarray, free: np.ndarray) -> bool:
    """True when every refined parameter is still at its start (internal units)."""
    moved = np.abs(to_internal(params) - to_internal(start))[free]
    return bool(moved.size) and bool(np.all(moved < _UNMOVED_TOL))


def _check_inputs(feet_px, heads_px, image_size, method: str, residual: str, points: str, distortion: bool,
                  box_depth_m: float, box_depth_sd_m: float, frame_index, track_id, focal_px: float | None,
                  estimate_roll: bool, principal_point, person_height_m: float, person_height_sd_m: float,
                  noise_px: float, fov_prior_deg: float | None, fov_prior_sd_deg: float):
    """Validated (size, feet, heads, usable, frames, tracks, pp, fov prior, residual) or ValueError/DegenerateSceneError.

    ``residual`` comes back as used: the head row ("vertical") for boxes.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if residual not in RESIDUALS:
        raise ValueError(f"residual must be one of {RESIDUALS}, got {residual!r}")
    if points not in POINTS[1:]:
        raise ValueError(f"points must be one of {POINTS}, got {points!r}")
    if not (math.isfinite(box_depth_m) and math.isfinite(box_depth_sd_m) and box_depth_sd_m >= 0):
        raise ValueError(f"box_depth_m must be finite and box_depth_sd_m >= 0, got {box_depth_m}, {box_depth_sd_m}")
    if method == "grid" and (distortion or points != "landmarks"):
        raise ValueError("distortion and points='boxes' need method 'refine' (the grid is the paper's model)")
    residual = "vertical" if points == "boxes" else residual
    size = _check_image_size(image_size)
    feet, heads, usable = _check_points(feet_px, heads_px)
    frames = _check_index(frame_index, len(feet), "frame_index")
    tracks = _check_index(track_id, len(feet), "track_id")
    for name, value in (("person_height_m", person_height_m), ("noise_px", noise_px)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive number, got {value}")
    if not (math.isfinite(person_height_sd_m) and person_height_sd_m >= 0):
        raise ValueError(f"person_height_sd_m must be >= 0, got {person_height_sd_m}")
    if focal_px is not None and not (math.isfinite(focal_px) and focal_px > 0):
        raise ValueError(f"focal_px must be a positive number of pixels, got {focal_px}")
    pp = np.array([size[0] / 2.0, size[1] / 2.0]) if principal_point is None else np.asarray(principal_point, float)
    if pp.shape != (2,) or not np.all(np.isfinite(pp)):
        raise ValueError(f"principal_point must be (cx, cy) in pixels, got {principal_point!r}")
    if not (0 <= pp[0] <= size[0] and 0 <= pp[1] <= size[1]):
        raise ValueError(f"principal_point ({pp[0]:g}, {pp[1]:g}) must lie inside the {size[0]}x{size[1]} image")
    fov = None
    if fov_prior_deg is not None:
        if not (0 < fov_prior_deg < 180 and fov_prior_sd_deg > 0):
            raise ValueError(f"fov_prior_deg must be in (0, 180) with a positive sd, got {fov_prior_deg}")
        fov = (float(fov_prior_deg), float(fov_prior_sd_deg))
    n_usable = int(usable.sum())
    n_free = (focal_px is None) + 2 + (method == "refine") * (estimate_roll + distortion)
    if n_usable < 3:
        raise DegenerateSceneError(f"only {n_usable} usable foot-head pairs (need >= 3)")
    n_places = len(np.unique(np.round(feet[usable] * 2.0), axis=0))
    if n_places < 3:
        raise DegenerateSceneError(f"the {n_usable} usable pairs stand at only {n_places} distinct foot positions "
                                   "(need >= 3)")
    if at_one_depth(feet[usable], heads[usable]):
        raise DegenerateSceneError(f"all {n_usable} usable pairs stand at about one depth (their feet lie along one "
                                   "image row): the people cannot determine the camera; use frames where people "
                                   "stand nearer and farther")
    if n_usable * (1 if residual == "vertical" else 2) < n_free:
        raise DegenerateSceneError(f"{n_usable} usable pairs with {residual} residuals cannot determine "
                                   f"{n_free} parameters; fix the focal length or add pairs")
    return size, feet, heads, usable, frames, tracks, pp, fov, residual


def _refuse_bounds(params: np.ndarray, free: np.ndarray, image_height_px: float) -> None:
    """DegenerateSceneError when a refined parameter ran to its search bound: the pairs do not
    determine it, and a camera at the bound would be a confident wrong answer."""
    lo, hi = param_bounds(image_height_px)
    x = to_internal(params)
    names = ("focal length", "pitch", "roll", "camera height", "distortion", "box depth")
    values = (f"{params[0]:.0f} px", f"{math.degrees(params[1]):.1f} deg", f"{math.degrees(params[2]):.1f} deg",
              f"{params[3]:.2f} m", f"{params[4]:+.3f}", f"{params[5]:.2f} m")
    hit = [i for i in range(len(names)) if free[i] and min(x[i] - lo[i], hi[i] - x[i]) < 1e-3]
    if hit:
        what = ", ".join(f"the {names[i]} ({values[i]})" for i in hit)
        raise DegenerateSceneError(f"the pairs cannot determine {what}: the fit ran to the end of its search "
                                   "range; give what is known (--focal, --camera-height, --no-roll) or more people "
                                   "at different depths")


def _grid_fit(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, size: tuple[int, int], focal_px: float | None,
              person_height_m: float, residual: str, grid: GridSpec, workers: int | None, prob: Problem):
    """The paper's grid: (params, all-inlier mask, free, scale, warnings, unweighted problem)."""
    focal = grid.focal_values_px(size[1]) if focal_px is None else np.array([float(focal_px)])
    fit = paper_grid_search(feet, heads, pp, focal, grid.pitch_values_rad(), grid.height_values_m(),
                            person_height_m, residual, 0.0, workers)
    if fit is None:
        raise DegenerateSceneError("no grid cell explains the pairs: every candidate camera puts a foot above the "
                                   "horizon or a head behind the camera (are these pixels of this image?)")
    params = np.array([fit.focal_px, fit.pitch_rad, 0.0, fit.height_m, 0.0, 0.0])
    free = np.array([focal_px is None, True, False, True, False, False])
    extra = []
    names = ("focal", "pitch", "height")
    edges = [names[axis] for axis, (i, n) in enumerate(zip(fit.index, fit.costs.shape)) if n > 1 and i in (0, n - 1)]
    if edges:
        raise DegenerateSceneError(f"the paper grid's best {', '.join(edges)} lies on the edge of its search range: "
                                   "the camera is outside it or the pairs do not determine it (calibrate.grid in "
                                   "the config sets the ranges)")
    # Unweighted residuals for the paper's uncertainty: equal weights, scale from the residual sum.
    flat = replace(prob, sd_along=np.ones(len(feet)), sd_across=1.0, track=np.full(len(feet), -1), n_tracks=0,
                   fov_prior=None)
    dof_total = max(1, len(feet) * flat.dof - int(free.sum()))
    scale = max(math.sqrt(fit.cost / dof_total), MIN_NOISE_PX)
    return params, np.ones(len(feet), bool), free, scale, extra, flat


def calibrate(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int], **options) -> Camera:
    """The camera of :func:`fit_camera` (same arguments), without the diagnostics."""
    return fit_camera(feet_px, heads_px, image_size, **options).camera


def fit_per_frame(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
                  frame_index: np.ndarray, **options) -> PerFrameSummary:
    """Calibrate every frame alone (same options as :func:`fit_camera`) and summarise the spread."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    frames = _check_index(frame_index, len(feet), "frame_index")
    if frames is None:
        raise ValueError("fit_per_frame needs frame_index")
    track = options.pop("track_id", None)
    ids, results, skipped = [], [], {}
    for t in np.unique(frames):
        sel = frames == t
        try:
            res = fit_camera(feet[sel], heads[sel], image_size, frame_index=frames[sel],
                             track_id=None if track is None else np.asarray(track)[sel], **options)
        except DegenerateSceneError as err:
            skipped[int(t)] = str(err)
            continue
        ids.append(int(t))
        results.append(res)
    values = {k: np.array([_param_value(r.camera, k) for r in results]) for k in PARAM_NAMES}
    median = {k: float(np.median(v)) if len(v) else math.nan for k, v in values.items()}
    iqr = {k: float(np.subtract(*np.percentile(v, [75, 25]))) if len(v) else math.nan for k, v in values.items()}
    return PerFrameSummary(tuple(ids), tuple(results), skipped, median, iqr)


def _param_value(camera: Camera, name: str) -> float:
    """A camera parameter in report units (px, deg, deg, m)."""
    return {"focal_px": camera.focal_px, "pitch_deg": math.degrees(camera.pitch_rad),
            "roll_deg": math.degrees(camera.roll_rad), "height_m": camera.height_m}[name]
