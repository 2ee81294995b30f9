"""Calibrate a static camera from the people it sees: foot (mid-sole) and head (crown) pixels only.

Two methods (conventions: CONVENTIONS.md; the model and the fast grid: :mod:`.calibrate_grid`):

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
  known principal point, fixed focal, no roll, head-row-only residuals (box-derived points), and
  a weak prior on the vertical field of view.

From upright people on a plane the horizon (~ f tan(pitch)) and the camera height are well
determined, but focal and pitch slide along a valley. :class:`CalibrationResult` reports standard
deviations: the fit's own (Gauss-Newton at the optimum, or per parameter the larger of it and a
cluster-robust sandwich over tracks, else frames) plus, linearised, what the model assumes
without knowing it (principal point, mild radial distortion, the people's mean stature); the
focal/pitch correlation; and warnings in plain words.

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

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from .calibrate_grid import GridSpec, order_invariant_subset, paper_grid_search, robust_grid_costs, seed_cells
from .camera import Camera, horizon_v_px, up_vector_cam
from .errors import DegenerateSceneError

__all__ = ["CalibrationResult", "PerFrameSummary", "GridSpec", "fit_camera", "calibrate", "fit_per_frame"]

METHODS = ("grid", "refine")
RESIDUALS = ("full", "vertical")
PARAM_NAMES = ("focal_px", "pitch_deg", "roll_deg", "height_m")

_RAY_EPS = 1e-12  # foot ray "parallel to the ground" (as camera.backproject_px_to_plane)
_Z_MIN = 0.05  # head depth / foot depth below this: head (nearly) behind the camera -> invalid pair
_INIT_PAIRS = 600  # robust grid and multi-start run on at most this many pairs
_INIT_STEPS = (40, 30)  # robust grid: log-spaced focal and height values over the GridSpec ranges
_INIT_TRUNCATE = 0.25  # robust grid: head errors beyond 25% of the person's pixel length are outliers
_CHI2_99 = {2: 9.2103, 1: 6.6349}  # chi-square 99% quantiles (pair residual: 2 or 1 components)
_CHI2_MEDIAN = {2: 1.3863, 1: 0.4549}  # chi-square medians, for the robust residual scale
_FD_STEP = 1e-6  # finite-difference step in the internal parameters (log f, rad, rad, log h)
_MIN_NOISE_PX = 0.5  # floor of the residual scale in pixels: annotation is never better than this
_NULL_EIG = 1e-9  # information eigenvalues below this fraction of the largest: direction undetermined

# Warning thresholds: a parameter is "poorly determined" past these standard deviations.
WARN_FOCAL_REL_SD = 0.10
WARN_FOCAL_PITCH_CORR = 0.95
WARN_PITCH_SD_DEG = 2.0
WARN_HEIGHT_REL_SD = 0.10
WARN_INLIER_FRACTION = 0.6


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

    @property
    def horizon_v_px(self) -> float:
        """Image row of the horizon at the image's centre column."""
        cam = self.camera
        return float(horizon_v_px(cam.image_size[0] / 2.0, cam.focal_px, cam.principal_point, cam.up_cam))

    def fit_dict(self) -> dict:
        """Plain-typed ``fit:`` block of camera.yaml (CONVENTIONS.md); NaN becomes None."""
        return {
            "method": self.method,
            "residual": self.residual,
            "person_height_m": float(self.person_height_m),
            "pairs": int(self.pairs),
            "inliers": int(self.inliers),
            "frames": int(self.frames),
            "rmse_px": _plain(self.rmse_px),
            "std": {k: _plain(self.std.get(k, math.nan)) for k in PARAM_NAMES},
            "corr_focal_pitch": _plain(self.corr_focal_pitch),
            "horizon_v_px": _plain(self.horizon_v_px),
            "warnings": list(self.warnings),
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


# ---- the model (closed form, broadcast over Q parameter sets) ----------------------------------------
def _head_errors(rel_feet: np.ndarray, diff: np.ndarray, params: np.ndarray, stature_m: float | np.ndarray
                 ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Head errors (u, v), their derivatives by the stature (u, v), each (Q, N), and validity (Q, N).

    params (Q, 4) rows: (focal_px, pitch_rad, roll_rad, height_m); rel_feet = feet - pp and
    diff = feet - heads, (N, 2) px; stature_m: scalar, (N,) or (Q, N). Errors are predicted minus
    observed heads, px; derivatives px/m. The model of :func:`.calibrate_grid.predict_heads_px`:
    the head is ``F + k M / z`` with ``k = S / h`` (module docstring of calibrate_grid).
    """
    f, pitch, roll, h = (params[:, i : i + 1] for i in range(4))
    n = up_vector_cam(pitch[:, 0], roll[:, 0])
    nx, ny, nz = n[:, 0:1], n[:, 1:2], n[:, 2:3]
    u, v = rel_feet[:, 0], rel_feet[:, 1]
    k = stature_m / h
    d = -(nx * u + ny * v) / f - nz
    z = 1.0 + k * nz * d
    valid = (d > _RAY_EPS) & (z > _Z_MIN)
    z = np.maximum(z, _Z_MIN)
    m_u, m_v = d * (f * nx - nz * u), d * (f * ny - nz * v)
    coef, dcoef = k / z, 1.0 / (h * z * z)
    return (diff[:, 0] + coef * m_u, diff[:, 1] + coef * m_v), (dcoef * m_u, dcoef * m_v), valid


@dataclass(frozen=True)
class _Problem:
    """Pairs and weights of one refinement (all arrays over the usable pairs, (N, ...))."""

    rel_feet: np.ndarray  # (N, 2) feet minus principal point
    diff: np.ndarray  # (N, 2) feet minus heads
    axis: np.ndarray  # (N, 2) unit vector foot -> head (observed)
    sd_along: np.ndarray  # (N,) px: noise, plus the stature spread for untracked pairs
    sd_across: float  # px
    person_height_m: float
    stature_sd_m: float
    track: np.ndarray  # (N,) int in [0, n_tracks), -1 = untracked
    n_tracks: int
    vertical: bool
    image_height_px: float
    fov_prior: tuple[float, float] | None  # (mean, sd) of the vertical field of view, degrees

    def subset(self, idx: np.ndarray) -> "_Problem":
        """The same problem on pairs ``idx`` (tracks renumbered)."""
        track = np.full(len(idx), -1)
        tracked = self.track[idx] >= 0
        labels, track[tracked] = np.unique(self.track[idx][tracked], return_inverse=True)
        return replace(self, rel_feet=self.rel_feet[idx], diff=self.diff[idx], axis=self.axis[idx],
                       sd_along=self.sd_along[idx], track=track, n_tracks=len(labels))

    @property
    def dof(self) -> int:
        """Residual components per pair."""
        return 1 if self.vertical else 2


def _make_problem(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, person_height_m: float,
                  person_height_sd_m: float, noise_px: float, vertical: bool, image_height_px: float,
                  fov_prior: tuple[float, float] | None, track_id: np.ndarray | None) -> _Problem:
    """Weights from the observed pixel lengths (they never depend on the camera); tracks of id >= 0."""
    diff = feet - heads
    length = np.linalg.norm(diff, axis=1)
    axis = -diff / np.maximum(length, 1e-9)[:, None]
    axis[length < 1e-9] = (0.0, -1.0)
    track = np.full(len(feet), -1)
    n_tracks = 0
    if track_id is not None and person_height_sd_m > 0:
        tracked = track_id >= 0
        labels, track[tracked] = np.unique(track_id[tracked], return_inverse=True)
        n_tracks = len(labels)
    spread = np.where(track >= 0, 0.0, length * person_height_sd_m / person_height_m)
    sd_along = np.sqrt(noise_px**2 + spread**2)
    return _Problem(feet - pp, diff, axis, sd_along, float(noise_px), person_height_m, person_height_sd_m, track,
                    n_tracks, vertical, image_height_px, fov_prior)


def _along(prob: _Problem, e: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Component (Q, N) of a pixel vector field along the person (the head row if vertical), unwhitened."""
    return e[1] if prob.vertical else e[0] * prob.axis[:, 0] + e[1] * prob.axis[:, 1]


def _profiled(prob: _Problem, params: np.ndarray, scale: float = 1.0
              ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray, np.ndarray]:
    """Head errors (u, v) (Q, N) px with each track's stature profiled out, validity (Q, N), deltas (Q, T) m.

    A tracked person's stature is ``S + delta_t`` with ``delta_t ~ N(0, sd_S)``, solved by two robust
    Gauss-Newton steps (Cauchy weights inside the track) against the whitened residuals / scale.
    """
    Q, T = len(params), prob.n_tracks
    e, de, valid = _head_errors(prob.rel_feet, prob.diff, params, prob.person_height_m)
    delta = np.zeros((Q, T))
    if T:
        tracked = prob.track >= 0
        flat = (np.arange(Q)[:, None] * T + np.maximum(prob.track, 0)[None, :]).ravel()
        prec = 1.0 / prob.stature_sd_m**2
        for _ in range(2):
            r = _along(prob, e) / (prob.sd_along * scale)
            j = _along(prob, de) / (prob.sd_along * scale)
            w = (valid & tracked) / (1.0 + (r / 3.0) ** 2)
            num = np.bincount(flat, (w * j * r).ravel(), Q * T).reshape(Q, T) + delta * prec
            den = np.bincount(flat, (w * j * j).ravel(), Q * T).reshape(Q, T) + prec
            delta = delta - num / den
            stature = prob.person_height_m + np.where(tracked, delta[:, np.maximum(prob.track, 0)], 0.0)
            e, de, valid = _head_errors(prob.rel_feet, prob.diff, params, stature)
    return e, valid, delta


def _whitened(prob: _Problem, params: np.ndarray, scale: float = 1.0
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whitened residuals (Q, N, dof) / scale, track-stature prior rows (Q, T), validity (Q, N).

    Untracked pairs carry the stature spread in their along-the-person weight instead.
    """
    e, valid, delta = _profiled(prob, params, scale)
    along = _along(prob, e) / prob.sd_along
    if prob.vertical:
        r = along[..., None]
    else:
        across = (e[1] * prob.axis[:, 0] - e[0] * prob.axis[:, 1]) / prob.sd_across
        r = np.stack([along, across], axis=-1)
    return r / scale, delta / prob.stature_sd_m if prob.n_tracks else delta, valid


def _prior_rows(prob: _Problem, params: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Prior residuals (Q, R): the field-of-view prior when the focal is free."""
    if prob.fov_prior is None or not free[0]:
        return np.zeros((len(params), 0))
    mean, sd = prob.fov_prior
    fov = np.rad2deg(2.0 * np.arctan(prob.image_height_px / (2.0 * params[:, 0])))
    return ((fov - mean) / sd)[:, None]


# ---- refinement ---------------------------------------------------------------------------------------
def _to_params(x: np.ndarray, full0: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Internal vectors x (Q, n_free) -> params (Q, 4) = (f, pitch, roll, h); log f and log h inside."""
    internal = np.repeat(_to_internal(full0)[None], len(x), axis=0)
    internal[:, free] = x
    return np.stack([np.exp(internal[:, 0]), internal[:, 1], internal[:, 2], np.exp(internal[:, 3])], axis=1)


def _to_internal(params: np.ndarray) -> np.ndarray:
    """(4,) params -> (log f, pitch, roll, log h)."""
    return np.array([math.log(params[0]), params[1], params[2], math.log(params[3])])


def _residual(prob: _Problem, params: np.ndarray, free: np.ndarray, scale: float) -> np.ndarray:
    """Residual vectors (Q, M) for params (Q, 4): pairs (whitened / scale), track statures, fov prior."""
    r, rows, _ = _whitened(prob, params, scale)
    return np.concatenate([r.reshape(len(params), -1), rows, _prior_rows(prob, params, free)], axis=1)


def _residual_and_jacobian(prob: _Problem, x: np.ndarray, full0: np.ndarray, free: np.ndarray,
                           scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Residual vector (M,) and its Jacobian (M, n_free) by one vectorised forward difference."""
    xs = np.vstack([x, x + _FD_STEP * np.eye(len(x))])
    r = _residual(prob, _to_params(xs, full0, free), free, scale)
    return r[0], ((r[1:] - r[0]) / _FD_STEP).T


def _least_squares(prob: _Problem, params0: np.ndarray, free: np.ndarray, scale: float, loss: str,
                   f_scale: float) -> np.ndarray:
    """Robust least squares from params0 (4,); returns the params (4,)."""
    cache: dict = {}

    def both(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = _residual_and_jacobian(prob, x, params0, free, scale)
        return cache[key]

    lo, hi = _bounds(prob.image_height_px)
    x0 = np.clip(_to_internal(params0), lo + 1e-6, hi - 1e-6)[free]
    sol = least_squares(lambda x: both(x)[0], x0, jac=lambda x: both(x)[1], bounds=(lo[free], hi[free]),
                        loss=loss, f_scale=f_scale, method="trf", x_scale="jac", xtol=1e-10, ftol=1e-10,
                        gtol=1e-10, max_nfev=200)
    return _to_params(sol.x[None], params0, free)[0]


def _bounds(image_height_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Internal-parameter bounds: focal 0.02-50 H, pitch -80..89.9 deg, roll +-45 deg, height 0.05-1000 m."""
    lo = np.array([math.log(0.02 * image_height_px), np.deg2rad(-80.0), np.deg2rad(-45.0), math.log(0.05)])
    hi = np.array([math.log(50.0 * image_height_px), np.deg2rad(89.9), np.deg2rad(45.0), math.log(1000.0)])
    return lo, hi


def _pair_chi2(prob: _Problem, params: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(N,) squared whitened residual norm per pair at params (4,) (not divided by scale); inf if invalid."""
    r, _, valid = _whitened(prob, params[None], scale)
    chi2 = np.sum((r[0] * scale) ** 2, axis=-1)
    return np.where(valid[0], chi2, np.inf)


def _robust_scale(chi2: np.ndarray, prob: _Problem) -> float:
    """Residual scale from the median of chi2 values (1 for correctly whitened residuals), floored."""
    finite = chi2[np.isfinite(chi2)]
    floor = _MIN_NOISE_PX / prob.sd_across
    if finite.size == 0:
        return max(1.0, floor)
    return max(math.sqrt(float(np.median(finite)) / _CHI2_MEDIAN[prob.dof]), floor)


def _fit_with_rejection(prob: _Problem, params0: np.ndarray, free: np.ndarray, mask0: np.ndarray,
                        max_rounds: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Alternate robust fits and chi-square rejection; returns (params, inlier mask, scale)."""
    n_free = int(free.sum())
    need = max(3, math.ceil(n_free / prob.dof))
    params, mask = params0, mask0.copy()
    scale = _robust_scale(_pair_chi2(prob, params)[mask], prob)
    scale = _robust_scale(_pair_chi2(prob, params, scale)[mask], prob)
    thr = _CHI2_99[prob.dof]
    for round_ in range(max_rounds):
        sub = prob.subset(np.flatnonzero(mask))
        loss, f_scale = ("cauchy", 2.0) if round_ == 0 else ("soft_l1", 3.0)
        params = _least_squares(sub, params, free, scale, loss, f_scale)
        chi2 = _pair_chi2(prob, params, scale)
        scale = _robust_scale(chi2[mask], prob)
        new_mask = chi2 <= thr * scale**2
        if new_mask.sum() < need:
            break
        if np.array_equal(new_mask, mask) and round_ > 0:
            break
        mask = new_mask
    scale = _robust_scale(_pair_chi2(prob, params, scale)[mask], prob)
    return params, mask, scale


def _refine(prob: _Problem, feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, image_size: tuple[int, int],
            focal_px: float | None, estimate_roll: bool, grid: GridSpec, max_rounds: int
            ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Grid seeds, multi-start on a subsample, then the full fit; returns (params, mask, scale, free)."""
    free = np.array([focal_px is None, True, estimate_roll, True])
    sub_idx = order_invariant_subset(feet, heads, _INIT_PAIRS)
    lo, hi = (v * image_size[1] for v in grid.focal_range_h)
    focal = np.geomspace(lo, hi, _INIT_STEPS[0]) if focal_px is None else np.array([float(focal_px)])
    pitch, height = grid.pitch_values_rad(), np.geomspace(*grid.height_range_m, _INIT_STEPS[1])
    costs = robust_grid_costs(feet[sub_idx], heads[sub_idx], pp, focal, pitch, height, prob.person_height_m,
                              "vertical" if prob.vertical else "full", _INIT_TRUNCATE)
    seeds = [np.array([focal[i], pitch[j], 0.0, height[c]]) for i, j, c in seed_cells(costs, focal)]
    sub = prob.subset(sub_idx)
    best = None
    for seed in seeds:
        seed = seed.copy()
        seed[1] = min(seed[1], np.deg2rad(89.0))
        chi2 = _pair_chi2(sub, seed)
        mask0 = np.isfinite(chi2)
        if mask0.sum() < 3:
            continue
        params, mask, scale = _fit_with_rejection(sub, seed, free, mask0, max_rounds=3)
        best = _better(sub, best, (params, mask, scale))
    if best is None:
        raise DegenerateSceneError("no camera explains the pairs: every start put the feet above the horizon "
                                   "or the heads behind the camera (are these pixels of this image?)")
    start = best[0]
    chi2 = _pair_chi2(prob, start, best[2])
    mask0 = chi2 <= _CHI2_99[prob.dof] * best[2] ** 2 * 4.0
    if mask0.sum() < 3:
        mask0 = np.isfinite(chi2)
    params, mask, scale = _fit_with_rejection(prob, start, free, mask0, max_rounds)
    return params, mask, scale, free


def _better(prob: _Problem, a, b):
    """The better of two (params, mask, scale) fits by a common truncated chi-square cost."""
    if a is None:
        return b
    ref = min(a[2], b[2])
    thr = _CHI2_99[prob.dof]
    cost = [np.minimum(_pair_chi2(prob, fit[0], ref) / ref**2, thr).sum() for fit in (a, b)]
    return b if cost[1] < cost[0] else a


# ---- uncertainty ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Systematics:
    """Prior sds of what the model assumes but does not fit (propagated into the reported std)."""

    principal_point_px: float  # per axis
    distortion: float  # radial displacement at the image corner / half-diagonal
    stature_mean_m: float  # population mean stature
    half_diagonal_px: float


def _statistical_cov(prob: _Problem, params: np.ndarray, free: np.ndarray, scale: float,
                     clusters: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariance (n_free, n_free) of the free internal parameters, with the residuals and Jacobian.

    Gauss-Newton ``(J^T J)^-1`` of the whitened residuals; with >= 10 clusters (tracks, else frames)
    each variance is the larger of it and a cluster-robust sandwich's (correlated errors of a person).
    """
    r, J = _residual_and_jacobian(prob, _to_internal(params)[free], params, free, scale)
    A_inv = np.linalg.pinv(J.T @ J, rcond=_NULL_EIG)
    if clusters is None or len(np.unique(clusters)) < 10:
        return A_inv, r, J
    n_data = len(prob.rel_feet) * prob.dof
    groups, inv = np.unique(clusters, return_inverse=True)
    row_cluster = np.full(len(r), -1)
    row_cluster[:n_data] = np.repeat(inv, prob.dof)
    if prob.n_tracks:  # a track's stature-prior row belongs to the cluster of its pairs
        tracked = np.flatnonzero(prob.track >= 0)
        member = np.zeros(prob.n_tracks, int)
        member[prob.track[tracked]] = tracked  # any pair of the track (tracks sit inside one cluster)
        row_cluster[n_data : n_data + prob.n_tracks] = inv[member]
    scored = row_cluster >= 0
    scores = np.zeros((len(groups), J.shape[1]))
    np.add.at(scores, row_cluster[scored], J[scored] * r[scored, None])
    Jp = J[~scored]
    sandwich = A_inv @ (scores.T @ scores * len(groups) / (len(groups) - 1) + Jp.T @ Jp) @ A_inv
    ratio = np.diag(sandwich) / np.maximum(np.diag(A_inv), 1e-300)
    base = sandwich if np.mean(ratio) > 1.0 else A_inv  # correlations from the larger of the two
    sd_base = np.sqrt(np.maximum(np.diag(base), 1e-300))
    sd = np.sqrt(np.maximum(np.diag(A_inv), np.diag(sandwich)))
    return base / np.outer(sd_base, sd_base) * np.outer(sd, sd), r, J


def _perturbed(prob: _Problem, which: str, amount: float, half_diagonal_px: float) -> _Problem:
    """The problem with its principal point, lens distortion or stature moved by ``amount``."""
    rel_feet, diff, height = prob.rel_feet, prob.diff, prob.person_height_m
    if which == "cx":
        rel_feet = rel_feet - (amount, 0.0)
    elif which == "cy":
        rel_feet = rel_feet - (0.0, amount)
    elif which == "distortion":
        rel_heads = rel_feet - diff
        def undistort(p: np.ndarray) -> np.ndarray:
            return p * (1.0 + amount * np.sum(p * p, axis=1, keepdims=True) / half_diagonal_px**2)
        rel_feet = undistort(rel_feet)
        diff = rel_feet - undistort(rel_heads)
    else:
        height = height + amount
    return replace(prob, rel_feet=rel_feet, diff=diff, person_height_m=height)


def _systematic_cov(prob: _Problem, params: np.ndarray, free: np.ndarray, scale: float, r: np.ndarray,
                    J: np.ndarray, assumed: _Systematics) -> np.ndarray:
    """Covariance (n_free, n_free) induced by the assumed-but-unknown quantities (linearised)."""
    sds = {"cx": assumed.principal_point_px, "cy": assumed.principal_point_px, "distortion": assumed.distortion,
           "stature": assumed.stature_mean_m}
    gain = -np.linalg.pinv(J.T @ J, rcond=_NULL_EIG) @ J.T
    cov = np.zeros((J.shape[1], J.shape[1]))
    for name, sd in sds.items():
        if sd <= 0:
            continue
        step = 0.1 * sd
        r_moved = _residual(_perturbed(prob, name, step, assumed.half_diagonal_px), params[None], free, scale)[0]
        shift = gain @ ((r_moved - r) / step) * sd  # parameter shift for a one-sd change
        cov += np.outer(shift, shift)
    return cov


def _covariances(prob: _Problem, params: np.ndarray, free: np.ndarray, scale: float, clusters: np.ndarray | None,
                 assumed: _Systematics) -> tuple[np.ndarray, np.ndarray]:
    """(total, statistical) covariances (4, 4) of (log f, pitch, roll, log h); zero for fixed ones."""
    stat, r, J = _statistical_cov(prob, params, free, scale, clusters)
    total = stat + _systematic_cov(prob, params, free, scale, r, J, assumed)
    lost = _undetermined(J)
    out = []
    for cov in (total, stat):
        cov = cov.copy()
        cov[lost, :] = cov[:, lost] = np.nan
        cov[lost, lost] = np.inf
        full = np.zeros((4, 4))
        full[np.ix_(free, free)] = cov
        out.append(full)
    return out[0], out[1]


def _undetermined(J: np.ndarray) -> np.ndarray:
    """(n_free,) bool: parameters with a component in the null space of the information J^T J."""
    w, V = np.linalg.eigh(J.T @ J)
    null = w <= _NULL_EIG * max(float(w.max()), 1e-300)
    return (V[:, null] ** 2).sum(axis=1) > 1e-6


def _std_and_corr(params: np.ndarray, cov: np.ndarray, free: np.ndarray) -> tuple[dict[str, float], float]:
    """Per-parameter standard deviations (px, deg, deg, m; NaN if fixed) and corr(focal, pitch)."""
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    values = [params[0] * sd[0], math.degrees(sd[1]), math.degrees(sd[2]), params[3] * sd[3]]
    std = {k: (float(v) if free[i] else math.nan) for i, (k, v) in enumerate(zip(PARAM_NAMES, values))}
    ok = free[0] and free[1] and 0 < sd[0] < math.inf and 0 < sd[1] < math.inf
    corr = float(np.clip(cov[0, 1] / (sd[0] * sd[1]), -1.0, 1.0)) if ok else math.nan
    return std, corr


def _warnings(camera: Camera, std: dict[str, float], corr: float, inliers: int, usable: int,
              pairs: int) -> list[str]:
    """Plain-words warnings about what the data could not determine."""
    out = []
    lost = [k for k, v in std.items() if v == math.inf]
    horizon = float(horizon_v_px(camera.image_size[0] / 2.0, camera.focal_px, camera.principal_point,
                                 camera.up_cam))
    if lost:
        out.append(f"the pairs cannot determine {', '.join(lost)}: their values are arbitrary (the horizon, "
                   f"row {horizon:.0f} at the centre, may still be right); give the focal length or a "
                   "field-of-view prior")
    f_sd = std["focal_px"]
    if math.isfinite(f_sd) and f_sd > WARN_FOCAL_REL_SD * camera.focal_px:
        valley = (f"; focal and pitch trade off (correlation {corr:+.2f}): the horizon is better determined than "
                  "either") if abs(corr) > WARN_FOCAL_PITCH_CORR else ""
        out.append(f"focal length poorly determined: {camera.focal_px:.0f} +- {f_sd:.0f} px "
                   f"({100 * f_sd / camera.focal_px:.0f}%){valley}; give the focal length if it is known, "
                   "or a field-of-view prior")
    if math.isfinite(std["pitch_deg"]) and std["pitch_deg"] > WARN_PITCH_SD_DEG:
        out.append(f"pitch poorly determined: +- {std['pitch_deg']:.1f} deg")
    if math.isfinite(std["height_m"]) and std["height_m"] > WARN_HEIGHT_REL_SD * camera.height_m:
        out.append(f"camera height poorly determined: {camera.height_m:.2f} +- {std['height_m']:.2f} m")
    if inliers < WARN_INLIER_FRACTION * usable:
        out.append(f"only {inliers} of {usable} usable pairs fit upright people of the given stature "
                   "(sitting, cropped or mis-detected people, or a wrong stature?)")
    if usable < pairs:
        out.append(f"{pairs - usable} pairs with the head below the foot were ignored")
    return out


# ---- public API -----------------------------------------------------------------------------------
def fit_camera(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int], *, method: str = "refine",
               frame_index: np.ndarray | None = None, track_id: np.ndarray | None = None,
               focal_px: float | None = None, estimate_roll: bool = True,
               principal_point: tuple[float, float] | None = None, person_height_m: float = 1.70,
               person_height_sd_m: float = 0.07, residual: str = "full", fov_prior_deg: float | None = None,
               fov_prior_sd_deg: float = 10.0, noise_px: float = 2.0, grid: GridSpec = GridSpec(),
               principal_point_sd_px: float | None = None, distortion_sd: float = 0.01,
               person_height_mean_sd_m: float = 0.04, max_rounds: int = 6,
               workers: int | None = None) -> CalibrationResult:
    """Estimate the static camera from foot/head pixel pairs pooled over all frames.

    feet_px, heads_px: (N, 2) px, mid-sole and crown; image_size: (W, H) px.
    frame_index, track_id: (N,) int, optional (frame count; clusters for the uncertainty).
    focal_px: fix the focal length (else estimated). principal_point: (cx, cy), default the centre.
    method: "grid" (the paper: roll 0, no robustness) or "refine". residual: "full" (head u and v)
    or "vertical" (head row only: box-derived points). fov_prior_deg: mean of a weak prior on the
    vertical field of view (sd fov_prior_sd_deg), used when the focal is estimated (refine only).
    noise_px: pixel noise of the points (refine weights). workers: grid threads (None = auto).
    The reported std adds, to the fit's own uncertainty, what the model assumes but cannot know:
    the principal point (sd principal_point_sd_px per axis; None = 2% of the larger image side,
    or 0 when principal_point is given), radial lens distortion (sd of the corner displacement
    over the half-diagonal, distortion_sd) and the people's mean stature (person_height_mean_sd_m).
    Raises ValueError for malformed input and DegenerateSceneError when the pairs cannot
    determine a camera (fewer than 3 usable pairs, or no candidate camera is valid).
    """
    size, feet, heads, usable, frames, tracks, pp, fov = _check_inputs(
        feet_px, heads_px, image_size, method, residual, frame_index, track_id, focal_px, estimate_roll,
        principal_point, person_height_m, person_height_sd_m, noise_px, fov_prior_deg, fov_prior_sd_deg)
    n_usable = int(usable.sum())
    n_frames = 1 if frames is None else len(np.unique(frames[usable]))
    idx = np.flatnonzero(usable)
    prob = _make_problem(feet[idx], heads[idx], pp, float(person_height_m), float(person_height_sd_m),
                         float(noise_px), residual == "vertical", float(size[1]), fov,
                         None if tracks is None or method == "grid" else tracks[idx])
    extra: list[str] = []
    if method == "grid":
        params, mask_u, free, scale, extra, prob = _grid_fit(feet[idx], heads[idx], pp, size, focal_px,
                                                             person_height_m, residual, grid, workers, prob)
    else:
        params, mask_u, scale, free = _refine(prob, feet[idx], heads[idx], pp, size, focal_px, estimate_roll, grid,
                                              max_rounds)
        extra = _bound_warnings(params, free, size[1])
    if focal_px is not None:
        params[0] = float(focal_px)  # exactly as given (no log/exp round trip)
    camera = Camera(size, params[0], tuple(pp), params[1], params[2], params[3])
    inlier_mask = np.zeros(len(feet), bool)
    inlier_mask[idx[mask_u]] = True
    clusters = tracks if tracks is not None else frames
    inl = prob.subset(np.flatnonzero(mask_u))
    pp_sd = (0.02 * max(size) if principal_point is None else 0.0) if principal_point_sd_px is None \
        else float(principal_point_sd_px)
    assumed = _Systematics(pp_sd, float(distortion_sd), float(person_height_mean_sd_m), 0.5 * math.hypot(*size))
    cov, cov_stat = _covariances(inl, params, free, scale, None if clusters is None else clusters[idx[mask_u]],
                                 assumed)
    std, corr = _std_and_corr(params, cov, free)
    std_stat, _ = _std_and_corr(params, cov_stat, free)
    (eu, ev), _, _ = _profiled(inl, params[None], scale)
    sq = ev[0] ** 2 if residual == "vertical" else eu[0] ** 2 + ev[0] ** 2
    rmse = float(np.sqrt(np.mean(sq))) if len(sq) else math.nan
    warns = extra + _warnings(camera, std, corr, int(mask_u.sum()), n_usable, len(feet))
    if method == "refine" and tracks is None and n_frames > 1:
        warns.append("no track ids: a person seen in several frames counts as a new person each time, so the std "
                     "is too small when people persist (give the person ids)")
    return CalibrationResult(camera, method, float(person_height_m), len(feet), int(mask_u.sum()), n_frames, rmse,
                             std, corr, inlier_mask, tuple(warns), residual, std_stat)


def _check_inputs(feet_px, heads_px, image_size, method: str, residual: str, frame_index, track_id,
                  focal_px: float | None, estimate_roll: bool, principal_point, person_height_m: float,
                  person_height_sd_m: float, noise_px: float, fov_prior_deg: float | None, fov_prior_sd_deg: float):
    """Validated (size, feet, heads, usable, frames, tracks, pp, fov prior) or ValueError/DegenerateSceneError."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if residual not in RESIDUALS:
        raise ValueError(f"residual must be one of {RESIDUALS}, got {residual!r}")
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
    fov = None
    if fov_prior_deg is not None:
        if not (0 < fov_prior_deg < 180 and fov_prior_sd_deg > 0):
            raise ValueError(f"fov_prior_deg must be in (0, 180) with a positive sd, got {fov_prior_deg}")
        fov = (float(fov_prior_deg), float(fov_prior_sd_deg))
    n_usable = int(usable.sum())
    n_free = (focal_px is None) + 2 + (estimate_roll and method == "refine")
    if n_usable < 3:
        raise DegenerateSceneError(f"only {n_usable} usable foot-head pairs (need >= 3)")
    n_places = len(np.unique(np.round(feet[usable] * 2.0), axis=0))
    if n_places < 3:
        raise DegenerateSceneError(f"the {n_usable} usable pairs stand at only {n_places} distinct foot positions "
                                   "(need >= 3)")
    if n_usable * (1 if residual == "vertical" else 2) < n_free:
        raise DegenerateSceneError(f"{n_usable} usable pairs with {residual} residuals cannot determine "
                                   f"{n_free} parameters; fix the focal length or add pairs")
    return size, feet, heads, usable, frames, tracks, pp, fov


def _bound_warnings(params: np.ndarray, free: np.ndarray, image_height_px: float) -> list[str]:
    """Warnings for refined parameters stopped at their search bounds."""
    lo, hi = _bounds(image_height_px)
    x = _to_internal(params)
    names = ("focal length", "pitch", "roll", "camera height")
    return [f"the {names[i]} stopped at its search bound; the data do not determine it"
            for i in range(4) if free[i] and min(x[i] - lo[i], hi[i] - x[i]) < 1e-3]


def _grid_fit(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, size: tuple[int, int], focal_px: float | None,
              person_height_m: float, residual: str, grid: GridSpec, workers: int | None, prob: _Problem):
    """The paper's grid: (params, all-inlier mask, free, scale, warnings, unweighted problem)."""
    focal = grid.focal_values_px(size[1]) if focal_px is None else np.array([float(focal_px)])
    fit = paper_grid_search(feet, heads, pp, focal, grid.pitch_values_rad(), grid.height_values_m(),
                            person_height_m, residual, 0.0, workers)
    if fit is None:
        raise DegenerateSceneError("no grid cell explains the pairs: every candidate camera puts a foot above the "
                                   "horizon or a head behind the camera (are these pixels of this image?)")
    params = np.array([fit.focal_px, fit.pitch_rad, 0.0, fit.height_m])
    free = np.array([focal_px is None, True, False, True])
    extra = []
    names = ("focal", "pitch", "height")
    for axis, (i, n) in enumerate(zip(fit.index, fit.costs.shape)):
        if n > 1 and i in (0, n - 1):
            extra.append(f"the best {names[axis]} is on the edge of the search grid; the camera may lie outside it")
    # Unweighted residuals for the paper's uncertainty: equal weights, scale from the residual sum.
    flat = replace(prob, sd_along=np.ones(len(feet)), sd_across=1.0, track=np.full(len(feet), -1), n_tracks=0,
                   fov_prior=None)
    dof_total = max(1, len(feet) * flat.dof - int(free.sum()))
    scale = max(math.sqrt(fit.cost / dof_total), _MIN_NOISE_PX)
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
