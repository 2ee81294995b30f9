"""The robust refinement: least squares with rounds of outlier rejection, from several starts.

Seeds come from the robust grid (:func:`.grid.seed_params`) on an order-independent subsample;
each start is refined there (``scipy.optimize.least_squares`` over the internal parameters of
:mod:`.params`, Cauchy then soft-L1 loss) with rounds of rejection (each pair's whitened residual
against the 99% chi-square quantile of its residual kind, scale from the median); the best start
by a common truncated cost is then refined on all pairs.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import DegenerateSceneError
from .grid import GridSpec, seed_params
from .objective import Problem, body_rows, jacobian_at, pair_chi2, prior_rows, residual_at, robust_scale
from .params import FOCAL, from_internal, param_bounds, to_internal

__all__ = ["MANY_PAIRS", "import_least_squares", "robust_least_squares", "min_pairs", "fit_with_rejection",
           "refine_fit"]

_SEED_ROUNDS = 3  # rejection rounds of each start on the subsample
# A least-squares fit stops when a step changes the parameters or the cost by less than this (relative). With more
# than MANY_PAIRS pairs, 1e-6: the parameters' std is then under 1% and the robust losses converge linearly, so the
# last digits of 1e-10 cost tens of passes over every pair (20,000 walkers' pairs, 10% outliers: 292 evaluations ->
# 143, the fit 1.9 s -> 0.8 s, every parameter within 1% of its std of the tighter fit's; docs/performance.md).
_TOL, _TOL_MANY, MANY_PAIRS = 1e-10, 1e-6, 4000
_FULL_START_WIDEN = 4.0  # the full fit starts from the pairs within 4x the 99% chi-square of the best start


def import_least_squares() -> None:
    """Import what the refinement needs (scipy.optimize: ~0.25 s), e.g. while worker processes read the frames."""
    import scipy.optimize  # lazy: ~0.25 s to import, what this function is for  # noqa: F401


def robust_least_squares(prob: Problem, params0: np.ndarray, free: np.ndarray, scale: float, loss: str,
                         f_scale: float, many: bool | None = None) -> np.ndarray:
    """Robust least squares over the free slots from params0 (6,); returns the params (6,). ``many``: stop at the
    tolerance of a fit of many pairs (default: when ``prob`` has more than ``MANY_PAIRS``)."""
    from scipy.optimize import least_squares  # lazy: ~0.5 s to import; calibrate --method grid never refines

    cache: dict = {}

    def residual(x: np.ndarray) -> np.ndarray:  # the last point's residual: the Jacobian at it reuses it
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = residual_at(prob, x, params0, free, scale, loss, f_scale)
        return cache[key]

    def jacobian(x: np.ndarray) -> np.ndarray:
        return jacobian_at(prob, x, residual(x), params0, free, scale, loss, f_scale)

    lo, hi = param_bounds(prob.image_height_px)
    x0 = np.clip(to_internal(params0), lo + 1e-6, hi - 1e-6)[free]
    tol = _TOL_MANY if (len(prob.rel_feet) > MANY_PAIRS if many is None else many) else _TOL
    sol = least_squares(residual, x0, jac=jacobian, bounds=(lo[free], hi[free]),
                        method="trf", x_scale="jac", xtol=tol, ftol=tol, gtol=tol, max_nfev=200)
    return from_internal(sol.x[None], params0, free)[0]


def min_pairs(prob: Problem, free: np.ndarray) -> int:
    """Fewest pairs a fit keeps: 1 when the priors cover every free camera parameter, else 3 (and enough
    residual components for the free parameters)."""
    if prob.priors is not None and prob.priors.cover(free):
        return 1
    return max(3, math.ceil(int(free.sum()) / prob.dof))


def fit_with_rejection(prob: Problem, params0: np.ndarray, free: np.ndarray, mask0: np.ndarray,
                       max_rounds: int, many: bool | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Alternate robust fits and chi-square rejection from params0 (6,) on pairs mask0 (N,);
    returns (params (6,), inlier mask (N,), scale). ``many``: as :func:`robust_least_squares`."""
    need = min_pairs(prob, free)
    params, mask = params0, mask0.copy()
    scale = robust_scale(pair_chi2(prob, params)[mask], prob)
    scale = robust_scale(pair_chi2(prob, params, scale)[mask], prob)
    thr = prob.residual.chi2_99
    for round_ in range(max_rounds):
        sub = prob.subset(np.flatnonzero(mask))
        loss, f_scale = ("cauchy", 2.0) if round_ == 0 else ("soft_l1", 3.0)
        params = robust_least_squares(sub, params, free, scale, loss, f_scale, many)
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
    """Grid seeds, multi-start on a subsample, then the full fit.

    feet, heads: (N, 2) px, the pairs of ``prob``; free: (6,) bool slots to refine. Returns
    (params (6,), inlier mask (N,), scale, the seed (6,) the best start came from).
    """
    priors = prob.priors
    prior_focal = () if priors is None or not free[FOCAL] or not np.isfinite(priors.sd[FOCAL]) \
        else (float(np.exp(priors.mean[FOCAL])),)
    sub_idx, seeds = seed_params(feet, heads, pp, image_size[1], focal_px, grid, prob.person_height_m,
                                 prob.residual.name, box_depth_m, prior_focal)
    sub = prob.subset(sub_idx)
    need = min_pairs(prob, free)
    best = None
    for seed in seeds:
        chi2 = pair_chi2(sub, seed)
        mask0 = np.isfinite(chi2)
        if mask0.sum() < need:
            continue
        # a start of a fit of many pairs only has to be near: its fits stop at that fit's tolerance
        params, mask, scale = fit_with_rejection(sub, seed, free, mask0, _SEED_ROUNDS, len(prob.rel_feet) > MANY_PAIRS)
        best = _better(sub, free, best, (params, mask, scale, seed))
    if best is None:
        raise DegenerateSceneError("no camera explains the pairs: every start put the feet above the horizon "
                                   "or the heads behind the camera (are these pixels of this image?)")
    start = best[0]
    chi2 = pair_chi2(prob, start, best[2])
    mask0 = chi2 <= prob.residual.chi2_99 * best[2] ** 2 * _FULL_START_WIDEN
    if mask0.sum() < max(need, 3):
        mask0 = np.isfinite(chi2)
    params, mask, scale = fit_with_rejection(prob, start, free, mask0, max_rounds)
    return params, mask, scale, best[3]


def _better(prob: Problem, free: np.ndarray, a, b):
    """The better of two (params, mask, scale, seed) fits by a common cost: the truncated chi-square of
    the pairs plus the priors' and the bodies' rows (which decide between starts the pairs cannot tell apart)."""
    if a is None:
        return b
    ref = max(a[2], b[2])
    thr = prob.residual.chi2_99

    def cost(fit) -> float:
        params = fit[0][None]
        extra = np.concatenate([prior_rows(prob, params, free), body_rows(prob, params, free)], axis=1)
        return float(np.minimum(pair_chi2(prob, fit[0], ref) / ref**2, thr).sum() + np.sum(extra**2))

    return b if cost(b) < cost(a) else a
