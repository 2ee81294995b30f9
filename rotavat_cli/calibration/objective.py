"""The refinement's objective: pairs and weights, track statures profiled out, whitened residuals.

A :class:`Problem` holds the usable pairs and everything that weighs them (never the camera).
For parameter sets ``params (Q, 6)`` (:mod:`.params` slots) the person model (:mod:`.model`) gives
each head's error; the residual kind (:mod:`.residuals`) turns it into whitened components; each
tracked person's stature is profiled out against the prior ``N(S, sd_S)``; a weak prior on the
vertical field of view may be added. :func:`model_residual` is the vector ``least_squares``
minimises, :func:`pair_chi2` and :func:`robust_scale` drive the outlier rejection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .model import head_errors
from .params import FOCAL, from_internal
from .residuals import ResidualKind

__all__ = ["MIN_NOISE_PX", "Problem", "make_problem", "profiled", "whitened", "prior_rows", "model_residual",
           "residual_and_jacobian", "pair_chi2", "robust_scale"]

_FD_STEP = 1e-6  # finite-difference step in the internal parameters (log f, rad, rad, log h, ...)
MIN_NOISE_PX = 0.5  # floor of the residual scale in pixels: annotation is never better than this


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
    residual: ResidualKind
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
        return self.residual.dof


def make_problem(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, person_height_m: float,
                 person_height_sd_m: float, noise_px: float, residual: ResidualKind, image_size: tuple[int, int],
                 fov_prior: tuple[float, float] | None, track_id: np.ndarray | None) -> Problem:
    """Weights from the observed pixel lengths (they never depend on the camera); tracks of id >= 0.

    feet, heads: (N, 2) px; pp: (2,) px; track_id: (N,) int or None.
    """
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
                   n_tracks, residual, float(image_size[1]), fov_prior, 0.5 * math.hypot(*image_size))


def profiled(prob: Problem, params: np.ndarray, scale: float = 1.0
             ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray, np.ndarray]:
    """Head errors (u, v) (Q, N) px with each track's stature profiled out, validity (Q, N), deltas (Q, T) m.

    params: (Q, 6). A tracked person's stature is ``S + delta_t`` with ``delta_t ~ N(0, sd_S)``,
    solved by two robust Gauss-Newton steps (Cauchy weights inside the track) against the whitened
    residuals / scale.
    """
    Q, T = len(params), prob.n_tracks
    e, de, valid = head_errors(prob.rel_feet, prob.diff, params, prob.person_height_m, prob.radius_px)
    delta = np.zeros((Q, T))
    if T:
        tracked = prob.track >= 0
        flat = (np.arange(Q)[:, None] * T + np.maximum(prob.track, 0)[None, :]).ravel()
        prec = 1.0 / prob.stature_sd_m**2
        for _ in range(2):
            r = prob.residual.along(e, prob.axis) / (prob.sd_along * scale)
            j = prob.residual.along(de, prob.axis) / (prob.sd_along * scale)
            w = (valid & tracked) / (1.0 + (r / 3.0) ** 2)
            num = np.bincount(flat, (w * j * r).ravel(), Q * T).reshape(Q, T) + delta * prec
            den = np.bincount(flat, (w * j * j).ravel(), Q * T).reshape(Q, T) + prec
            delta = delta - num / den
            stature = prob.person_height_m + np.where(tracked, delta[:, np.maximum(prob.track, 0)], 0.0)
            e, de, valid = head_errors(prob.rel_feet, prob.diff, params, stature, prob.radius_px)
    return e, valid, delta


def whitened(prob: Problem, params: np.ndarray, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whitened residuals (Q, N, dof) / scale, track-stature prior rows (Q, T), validity (Q, N).

    Untracked pairs carry the stature spread in their along-the-person weight instead.
    """
    e, valid, delta = profiled(prob, params, scale)
    r = prob.residual.whitened(e, prob.axis, prob.sd_along, prob.sd_across)
    return r / scale, delta / prob.stature_sd_m if prob.n_tracks else delta, valid


def prior_rows(prob: Problem, params: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Prior residuals (Q, R): the field-of-view prior when the focal is free."""
    if prob.fov_prior is None or not free[FOCAL]:
        return np.zeros((len(params), 0))
    mean, sd = prob.fov_prior
    fov = np.rad2deg(2.0 * np.arctan(prob.image_height_px / (2.0 * params[:, FOCAL])))
    return ((fov - mean) / sd)[:, None]


def model_residual(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float) -> np.ndarray:
    """Residual vectors (Q, M) for params (Q, 6): pairs (whitened / scale), track statures, fov prior."""
    r, rows, _ = whitened(prob, params, scale)
    return np.concatenate([r.reshape(len(params), -1), rows, prior_rows(prob, params, free)], axis=1)


def residual_and_jacobian(prob: Problem, x: np.ndarray, full0: np.ndarray, free: np.ndarray,
                          scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Residual vector (M,) and its Jacobian (M, n_free) at internal ``x (n_free,)`` by one vectorised
    forward difference; the fixed slots come from ``full0 (6,)``."""
    xs = np.vstack([x, x + _FD_STEP * np.eye(len(x))])
    r = model_residual(prob, from_internal(xs, full0, free), free, scale)
    return r[0], ((r[1:] - r[0]) / _FD_STEP).T


def pair_chi2(prob: Problem, params: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(N,) squared whitened residual norm per pair at params (6,) (not divided by scale); inf if invalid."""
    r, _, valid = whitened(prob, params[None], scale)
    chi2 = np.sum((r[0] * scale) ** 2, axis=-1)
    return np.where(valid[0], chi2, np.inf)


def robust_scale(chi2: np.ndarray, prob: Problem) -> float:
    """Residual scale from the median of chi2 values (1 for correctly whitened residuals), floored."""
    finite = chi2[np.isfinite(chi2)]
    floor = MIN_NOISE_PX / prob.sd_across
    if finite.size == 0:
        return max(1.0, floor)
    return max(math.sqrt(float(np.median(finite)) / prob.residual.chi2_median), floor)
