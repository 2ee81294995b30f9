"""The person model of calibration and its robust fit (used by :mod:`.calibrate`).

A pair's head pixel is predicted in closed form from its foot pixel and the camera (focal, pitch,
roll, height; optionally a division-model lens distortion and box-derived points), broadcast over
parameter sets; tracked people have their stature profiled out against the prior; the camera is
refined by robust least squares with rounds of outlier rejection, from starts along the
focal/pitch valley.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .calibrate_grid import GridSpec, order_invariant_subset, robust_grid_costs, seed_cells
from .camera import up_vector_cam
from .errors import DegenerateSceneError

__all__ = ["PARAM_NAMES", "MODEL_NAMES", "MIN_NOISE_PX", "Problem", "make_problem", "profiled", "whitened", "prior_rows",
           "undistort", "to_internal", "model_residual", "residual_and_jacobian", "robust_least_squares", "param_bounds",
           "pair_chi2", "robust_scale", "refine_fit"]

PARAM_NAMES = ("focal_px", "pitch_deg", "roll_deg", "height_m")
MODEL_NAMES = PARAM_NAMES + ("distortion",)  # the camera's, then the lens model's
_RAY_EPS = 1e-12  # foot ray "parallel to the ground" (as camera.backproject_px_to_plane)
_Z_MIN = 0.05  # head depth / foot depth below this: head (nearly) behind the camera -> invalid pair
_INIT_PAIRS = 600  # robust grid and multi-start run on at most this many pairs
_INIT_STEPS = (40, 30)  # robust grid: log-spaced focal and height values over the GridSpec ranges
_INIT_TRUNCATE = 0.25  # robust grid: head errors beyond 25% of the person's pixel length are outliers
_CHI2_99 = {2: 9.2103, 1: 6.6349}  # chi-square 99% quantiles (pair residual: 2 or 1 components)
_CHI2_MEDIAN = {2: 1.3863, 1: 0.4549}  # chi-square medians, for the robust residual scale
_FD_STEP = 1e-6  # finite-difference step in the internal parameters (log f, rad, rad, log h)
MIN_NOISE_PX = 0.5  # floor of the residual scale in pixels: annotation is never better than this


# ---- the model (closed form, broadcast over Q parameter sets) ----------------------------------------
def undistort(rel_feet: np.ndarray, diff: np.ndarray, lam: np.ndarray, radius_px: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Division-model undistortion ``p / (1 + lam |p|^2 / R^2)`` of feet and heads -> (Q, N, 2) each.

    rel_feet, diff: (N, 2) px about the principal point; lam: (Q, 1); radius_px: R, the half-diagonal.
    """
    def one(p: np.ndarray) -> np.ndarray:
        return p / (1.0 + lam[..., None] * (np.sum(p * p, axis=-1) / radius_px**2)[None, :, None])

    feet = one(rel_feet)
    return feet, feet - one(rel_feet - diff)


def _head_errors(rel_feet: np.ndarray, diff: np.ndarray, params: np.ndarray, stature_m: float | np.ndarray,
                 radius_px: float = 1.0
                 ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray]:
    """Head errors (u, v), their derivatives by the stature (u, v), each (Q, N), and validity (Q, N).

    params (Q, 6) rows: (focal_px, pitch_rad, roll_rad, height_m, distortion, box_depth_m);
    rel_feet = feet - pp and diff = feet - heads, (N, 2) px; stature_m: scalar, (N,) or (Q, N);
    radius_px: the distortion's radius (half-diagonal). Errors are predicted minus observed heads,
    px; derivatives px/m. The model of :func:`.calibrate_grid.predict_heads_px`: the head is
    ``F + k M / z`` with ``k = S / h`` (module docstring of calibrate_grid), on points undistorted
    by the division model. A box depth ``b`` moves the head ``b`` metres farther from the camera
    along the ground than the foot (box-derived points, :func:`_box_k`).
    """
    f, pitch, roll, h, lam, box = (params[:, i : i + 1] for i in range(6))
    if np.any(lam):
        rel_feet, diff = undistort(rel_feet, diff, lam, radius_px)
    n = up_vector_cam(pitch[:, 0], roll[:, 0])
    nx, ny, nz = n[:, 0:1], n[:, 1:2], n[:, 2:3]
    u, v = rel_feet[..., 0], rel_feet[..., 1]
    d = -(nx * u + ny * v) / f - nz
    k, dk, ok = _box_k(u, v, f, h, d, box, stature_m) if np.any(box) else (stature_m / h, 1.0 / h, True)
    z = 1.0 + k * nz * d
    valid = (d > _RAY_EPS) & (z > _Z_MIN) & ok
    z = np.maximum(z, _Z_MIN)
    m_u, m_v = d * (f * nx - nz * u), d * (f * ny - nz * v)
    coef, dcoef = k / z, dk / (z * z)
    return (diff[..., 0] + coef * m_u, diff[..., 1] + coef * m_v), (dcoef * m_u, dcoef * m_v), valid


def _box_k(u: np.ndarray, v: np.ndarray, f: np.ndarray, h: np.ndarray, d: np.ndarray, box: np.ndarray,
           stature_m: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``k``, ``dk/dS`` and validity (Q, N) when the head stands ``box`` m beyond the foot, away from the camera.

    With ``rho`` the foot's ground distance over the camera height, the head point
    ``G + b e + S n`` (``e`` the horizontal direction away from the camera) projects like an
    upright person with ``k = (S rho + b) / (h rho + b)`` (``k = S / h`` when ``b = 0``).
    """
    rho = np.sqrt(np.maximum(((u * u + v * v) / (f * f) + 1.0) / np.maximum(d, _RAY_EPS) ** 2 - 1.0, 0.0))
    denom = h * rho + box
    safe = np.where(denom > 0, denom, 1.0)
    return (stature_m * rho + box) / safe, rho / safe, denom > 0


@dataclass(frozen=True)
class Problem:
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
    radius_px: float  # half-diagonal: the distortion's unit radius

    def subset(self, idx: np.ndarray) -> "Problem":
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


def make_problem(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, person_height_m: float,
                  person_height_sd_m: float, noise_px: float, vertical: bool, image_size: tuple[int, int],
                  fov_prior: tuple[float, float] | None, track_id: np.ndarray | None) -> Problem:
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
    return Problem(feet - pp, diff, axis, sd_along, float(noise_px), person_height_m, person_height_sd_m, track,
                    n_tracks, vertical, float(image_size[1]), fov_prior, 0.5 * math.hypot(*image_size))


def _along(prob: Problem, e: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Component (Q, N) of a pixel vector field along the person (the head row if vertical), unwhitened."""
    return e[1] if prob.vertical else e[0] * prob.axis[:, 0] + e[1] * prob.axis[:, 1]


def profiled(prob: Problem, params: np.ndarray, scale: float = 1.0
              ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray, np.ndarray]:
    """Head errors (u, v) (Q, N) px with each track's stature profiled out, validity (Q, N), deltas (Q, T) m.

    A tracked person's stature is ``S + delta_t`` with ``delta_t ~ N(0, sd_S)``, solved by two robust
    Gauss-Newton steps (Cauchy weights inside the track) against the whitened residuals / scale.
    """
    Q, T = len(params), prob.n_tracks
    e, de, valid = _head_errors(prob.rel_feet, prob.diff, params, prob.person_height_m, prob.radius_px)
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
            e, de, valid = _head_errors(prob.rel_feet, prob.diff, params, stature, prob.radius_px)
    return e, valid, delta


def whitened(prob: Problem, params: np.ndarray, scale: float = 1.0
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whitened residuals (Q, N, dof) / scale, track-stature prior rows (Q, T), validity (Q, N).

    Untracked pairs carry the stature spread in their along-the-person weight instead.
    """
    e, valid, delta = profiled(prob, params, scale)
    along = _along(prob, e) / prob.sd_along
    if prob.vertical:
        r = along[..., None]
    else:
        across = (e[1] * prob.axis[:, 0] - e[0] * prob.axis[:, 1]) / prob.sd_across
        r = np.stack([along, across], axis=-1)
    return r / scale, delta / prob.stature_sd_m if prob.n_tracks else delta, valid


def prior_rows(prob: Problem, params: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Prior residuals (Q, R): the field-of-view prior when the focal is free."""
    if prob.fov_prior is None or not free[0]:
        return np.zeros((len(params), 0))
    mean, sd = prob.fov_prior
    fov = np.rad2deg(2.0 * np.arctan(prob.image_height_px / (2.0 * params[:, 0])))
    return ((fov - mean) / sd)[:, None]


# ---- refinement ---------------------------------------------------------------------------------------
def _to_params(x: np.ndarray, full0: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Internal vectors x (Q, n_free) -> params (Q, 6) = (f, pitch, roll, h, distortion, box); log f, log h inside."""
    internal = np.repeat(to_internal(full0)[None], len(x), axis=0)
    internal[:, free] = x
    internal[:, [0, 3]] = np.exp(internal[:, [0, 3]])
    return internal


def to_internal(params: np.ndarray) -> np.ndarray:
    """(6,) params -> (log f, pitch, roll, log h, distortion, box depth)."""
    internal = np.array(params, dtype=np.float64)
    internal[[0, 3]] = np.log(internal[[0, 3]])
    return internal


def model_residual(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float) -> np.ndarray:
    """Residual vectors (Q, M) for params (Q, 4): pairs (whitened / scale), track statures, fov prior."""
    r, rows, _ = whitened(prob, params, scale)
    return np.concatenate([r.reshape(len(params), -1), rows, prior_rows(prob, params, free)], axis=1)


def residual_and_jacobian(prob: Problem, x: np.ndarray, full0: np.ndarray, free: np.ndarray,
                           scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Residual vector (M,) and its Jacobian (M, n_free) by one vectorised forward difference."""
    xs = np.vstack([x, x + _FD_STEP * np.eye(len(x))])
    r = model_residual(prob, _to_params(xs, full0, free), free, scale)
    return r[0], ((r[1:] - r[0]) / _FD_STEP).T


def robust_least_squares(prob: Problem, params0: np.ndarray, free: np.ndarray, scale: float, loss: str,
                   f_scale: float) -> np.ndarray:
    """Robust least squares from params0 (4,); returns the params (4,)."""
    from scipy.optimize import least_squares  # imported when used: keeps `rotavat --help` fast

    cache: dict = {}

    def both(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residual_and_jacobian(prob, x, params0, free, scale)
        return cache[key]

    lo, hi = param_bounds(prob.image_height_px)
    x0 = np.clip(to_internal(params0), lo + 1e-6, hi - 1e-6)[free]
    sol = least_squares(lambda x: both(x)[0], x0, jac=lambda x: both(x)[1], bounds=(lo[free], hi[free]),
                        loss=loss, f_scale=f_scale, method="trf", x_scale="jac", xtol=1e-10, ftol=1e-10,
                        gtol=1e-10, max_nfev=200)
    return _to_params(sol.x[None], params0, free)[0]


def param_bounds(image_height_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Internal-parameter bounds: focal 0.02-50 H, pitch -80..89.9 deg, roll +-45 deg, height 0.05-1000 m,
    distortion +-0.5 (corner displacement over the half-diagonal), box depth -1..2 m."""
    lo = np.array([math.log(0.02 * image_height_px), np.deg2rad(-80.0), np.deg2rad(-45.0), math.log(0.05), -0.5, -1.0])
    hi = np.array([math.log(50.0 * image_height_px), np.deg2rad(89.9), np.deg2rad(45.0), math.log(1000.0), 0.5, 2.0])
    return lo, hi


def pair_chi2(prob: Problem, params: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(N,) squared whitened residual norm per pair at params (4,) (not divided by scale); inf if invalid."""
    r, _, valid = whitened(prob, params[None], scale)
    chi2 = np.sum((r[0] * scale) ** 2, axis=-1)
    return np.where(valid[0], chi2, np.inf)


def robust_scale(chi2: np.ndarray, prob: Problem) -> float:
    """Residual scale from the median of chi2 values (1 for correctly whitened residuals), floored."""
    finite = chi2[np.isfinite(chi2)]
    floor = MIN_NOISE_PX / prob.sd_across
    if finite.size == 0:
        return max(1.0, floor)
    return max(math.sqrt(float(np.median(finite)) / _CHI2_MEDIAN[prob.dof]), floor)


def _fit_with_rejection(prob: Problem, params0: np.ndarray, free: np.ndarray, mask0: np.ndarray,
                        max_rounds: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Alternate robust fits and chi-square rejection; returns (params, inlier mask, scale)."""
    n_free = int(free.sum())
    need = max(3, math.ceil(n_free / prob.dof))
    params, mask = params0, mask0.copy()
    scale = robust_scale(pair_chi2(prob, params)[mask], prob)
    scale = robust_scale(pair_chi2(prob, params, scale)[mask], prob)
    thr = _CHI2_99[prob.dof]
    for round_ in range(max_rounds):
        sub = prob.subset(np.flatnonzero(mask))
        loss, f_scale = ("cauchy", 2.0) if round_ == 0 else ("soft_l1", 3.0)
        params = robust_least_squares(sub, params, free, scale, loss, f_scale)
        chi2 = pair_chi2(prob, params, scale)
        scale = robust_scale(chi2[mask], prob)
        new_mask = chi2 <= thr * scale**2
        if new_mask.sum() < need:
            break
        if np.array_equal(new_mask, mask) and round_ > 0:
            break
        mask = new_mask
    scale = robust_scale(pair_chi2(prob, params, scale)[mask], prob)
    return params, mask, scale


def refine_fit(prob: Problem, feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, image_size: tuple[int, int],
            focal_px: float | None, free: np.ndarray, box_depth_m: float, grid: GridSpec, max_rounds: int
            ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Grid seeds, multi-start on a subsample, then the full fit; returns (params (6,), mask, scale, the
    seed (6,) the best start came from)."""
    sub_idx = order_invariant_subset(feet, heads, _INIT_PAIRS)
    lo, hi = (v * image_size[1] for v in grid.focal_range_h)
    focal = np.geomspace(lo, hi, _INIT_STEPS[0]) if focal_px is None else np.array([float(focal_px)])
    pitch, height = grid.pitch_values_rad(), np.geomspace(*grid.height_range_m, _INIT_STEPS[1])
    costs = robust_grid_costs(feet[sub_idx], heads[sub_idx], pp, focal, pitch, height, prob.person_height_m,
                              "vertical" if prob.vertical else "full", _INIT_TRUNCATE)
    seeds = [np.array([focal[i], pitch[j], 0.0, height[c], 0.0, box_depth_m]) for i, j, c in seed_cells(costs, focal)]
    sub = prob.subset(sub_idx)
    best = None
    for seed in seeds:
        seed = seed.copy()
        seed[1] = min(seed[1], np.deg2rad(89.0))
        chi2 = pair_chi2(sub, seed)
        mask0 = np.isfinite(chi2)
        if mask0.sum() < 3:
            continue
        params, mask, scale = _fit_with_rejection(sub, seed, free, mask0, max_rounds=3)
        best = _better(sub, best, (params, mask, scale, seed))
    if best is None:
        raise DegenerateSceneError("no camera explains the pairs: every start put the feet above the horizon "
                                   "or the heads behind the camera (are these pixels of this image?)")
    start = best[0]
    chi2 = pair_chi2(prob, start, best[2])
    mask0 = chi2 <= _CHI2_99[prob.dof] * best[2] ** 2 * 4.0
    if mask0.sum() < 3:
        mask0 = np.isfinite(chi2)
    params, mask, scale = _fit_with_rejection(prob, start, free, mask0, max_rounds)
    return params, mask, scale, best[3]


def _better(prob: Problem, a, b):
    """The better of two (params, mask, scale, seed) fits by a common truncated chi-square cost."""
    if a is None:
        return b
    ref = min(a[2], b[2])
    thr = _CHI2_99[prob.dof]
    cost = [np.minimum(pair_chi2(prob, fit[0], ref) / ref**2, thr).sum() for fit in (a, b)]
    return b if cost[1] < cost[0] else a


