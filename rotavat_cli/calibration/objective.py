"""The refinement's objective: pairs and weights, track statures profiled out, whitened residuals.

A :class:`Problem` holds the usable pairs and everything that weighs them (never the camera).
For parameter sets ``params (Q, 6)`` (:mod:`.params` slots) the person model (:mod:`.model`) gives
each head's error; the residual kind (:mod:`.residuals`) turns it into whitened components; each
tracked person's stature is profiled out against the prior ``N(S, sd_S)``; the camera's priors
(:mod:`.priors`) add one row per free parameter they cover, and standing bodies' own vertical axes
may add two rows (:class:`BodyAxes`). Pairs that are not independent (consecutive frames of one
track share their errors) count for what they carry: each pair's whitened residual is divided by
the square root of its *design effect* ``deff`` (:func:`design_effect`; 1 for independent pairs).
:func:`model_residual` is the vector ``least_squares`` minimises, :func:`pair_chi2` and
:func:`robust_scale` drive the outlier rejection (per pair, without the design effect).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..camera import up_vector_cam
from .model import head_errors
from .params import PITCH, ROLL, from_internal, to_internal
from .priors import Priors
from .residuals import ResidualKind

__all__ = ["MIN_NOISE_PX", "BodyAxes", "Problem", "make_problem", "profiled", "whitened", "prior_rows", "body_rows",
           "model_residual", "residual_and_jacobian", "pair_chi2", "robust_scale", "design_effect"]

_FD_STEP = 1e-6  # finite-difference step in the internal parameters (log f, rad, rad, log h, ...)
MIN_NOISE_PX = 0.5  # floor of the residual scale in pixels: annotation is never better than this
_DEFF_MIN_RHO = 0.05  # autocorrelations below this end the design effect's sum (they are noise)


@dataclass(frozen=True)
class BodyAxes:
    """Standing bodies' own vertical: one observed up direction in the camera frame and its sd.

    ``up_cam (3,)``: the robust mean of the standing people's sole->crown unit vectors as the HPS
    method drew them; ``sd_rad``: how far a body's axis may be from the true vertical (the lean
    HPS methods give bodies; docs/calibration.md); ``people``: how many it came from.
    """

    up_cam: np.ndarray
    sd_rad: float
    people: int

    def tangent_basis(self) -> np.ndarray:
        """(2, 3) orthonormal vectors perpendicular to ``up_cam`` (the residual's two components)."""
        a = self.up_cam
        seed = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        t1 = seed - (seed @ a) * a
        t1 /= np.linalg.norm(t1)
        return np.stack([t1, np.cross(a, t1)])


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
    priors: Priors | None  # the camera's priors (None: none, the paper's pure least squares)
    radius_px: float  # half-diagonal: the distortion's unit radius
    deff: np.ndarray | None = None  # (N,) design effect of each pair (None: 1, independent pairs)
    body: BodyAxes | None = None  # standing bodies' vertical, when used

    def subset(self, idx: np.ndarray) -> "Problem":
        """The same problem on pairs ``idx`` (tracks renumbered)."""
        track = np.full(len(idx), -1)
        tracked = self.track[idx] >= 0
        labels, track[tracked] = np.unique(self.track[idx][tracked], return_inverse=True)
        return replace(self, rel_feet=self.rel_feet[idx], diff=self.diff[idx], axis=self.axis[idx],
                       sd_along=self.sd_along[idx], track=track, n_tracks=len(labels),
                       deff=None if self.deff is None else self.deff[idx])

    @property
    def dof(self) -> int:
        """Residual components per pair."""
        return self.residual.dof

    def effective_sds(self, effective: bool) -> tuple[np.ndarray, np.ndarray | float]:
        """(sd_along (N,), sd_across) px, inflated by the square root of each pair's design effect when
        ``effective`` (the objective and its covariance; never the per-pair outlier test)."""
        if not effective or self.deff is None:
            return self.sd_along, self.sd_across
        root = np.sqrt(self.deff)
        return self.sd_along * root, self.sd_across * root


def make_problem(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, person_height_m: float,
                 person_height_sd_m: float, noise_px: float, residual: ResidualKind, image_size: tuple[int, int],
                 priors: Priors | None, track_id: np.ndarray | None) -> Problem:
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
                   n_tracks, residual, float(image_size[1]), priors, 0.5 * math.hypot(*image_size))


def profiled(prob: Problem, params: np.ndarray, scale: float = 1.0, effective: bool = False
             ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray, np.ndarray]:
    """Head errors (u, v) (Q, N) px with each track's stature profiled out, validity (Q, N), deltas (Q, T) m.

    params: (Q, 6). A tracked person's stature is ``S + delta_t`` with ``delta_t ~ N(0, sd_S)``,
    solved by two robust Gauss-Newton steps (Cauchy weights inside the track) against the whitened
    residuals / scale (``effective``: with the pairs' design effects, as the objective weighs them).
    """
    Q, T = len(params), prob.n_tracks
    e, de, valid = head_errors(prob.rel_feet, prob.diff, params, prob.person_height_m, prob.radius_px)
    delta = np.zeros((Q, T))
    if T:
        tracked = prob.track >= 0
        flat = (np.arange(Q)[:, None] * T + np.maximum(prob.track, 0)[None, :]).ravel()
        prec = 1.0 / prob.stature_sd_m**2
        sd_along = prob.effective_sds(effective)[0]
        for _ in range(2):
            r = prob.residual.along(e, prob.axis) / (sd_along * scale)
            j = prob.residual.along(de, prob.axis) / (sd_along * scale)
            w = (valid & tracked) / (1.0 + (r / 3.0) ** 2)
            num = np.bincount(flat, (w * j * r).ravel(), Q * T).reshape(Q, T) + delta * prec
            den = np.bincount(flat, (w * j * j).ravel(), Q * T).reshape(Q, T) + prec
            delta = delta - num / den
            stature = prob.person_height_m + np.where(tracked, delta[:, np.maximum(prob.track, 0)], 0.0)
            e, de, valid = head_errors(prob.rel_feet, prob.diff, params, stature, prob.radius_px)
    return e, valid, delta


def whitened(prob: Problem, params: np.ndarray, scale: float = 1.0, effective: bool = False
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whitened residuals (Q, N, dof) / scale, track-stature prior rows (Q, T), validity (Q, N).

    Untracked pairs carry the stature spread in their along-the-person weight instead;
    ``effective``: each pair divided by the square root of its design effect (the objective).
    """
    e, valid, delta = profiled(prob, params, scale, effective)
    sd_along, sd_across = prob.effective_sds(effective)
    r = prob.residual.whitened(e, prob.axis, sd_along, sd_across)
    return r / scale, delta / prob.stature_sd_m if prob.n_tracks else delta, valid


def prior_rows(prob: Problem, params: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Prior residuals (Q, R) of params (Q, 6): one row per free slot the priors cover (:mod:`.priors`)."""
    if prob.priors is None:
        return np.zeros((len(params), 0))
    return prob.priors.rows(to_internal(params), free)


def body_rows(prob: Problem, params: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Body-axis residuals (Q, 2) of params (Q, 6): the camera's up vector against the bodies' own, in
    the two directions perpendicular to the bodies' axis, over ``sin(sd)``; (Q, 0) when not used
    (no bodies, or neither pitch nor roll free)."""
    if prob.body is None or not (free[PITCH] or free[ROLL]):
        return np.zeros((len(params), 0))
    n = up_vector_cam(params[:, PITCH], params[:, ROLL])  # (Q, 3)
    return n @ prob.body.tangent_basis().T / math.sin(prob.body.sd_rad)


def model_residual(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float) -> np.ndarray:
    """Residual vectors (Q, M) for params (Q, 6): pairs (whitened / scale, with their design effects),
    track statures, the camera's priors, the bodies' axis."""
    r, rows, _ = whitened(prob, params, scale, effective=True)
    return np.concatenate([r.reshape(len(params), -1), rows, prior_rows(prob, params, free),
                           body_rows(prob, params, free)], axis=1)



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


def design_effect(prob: Problem, params: np.ndarray, scale: float, frame_index: np.ndarray | None,
                  max_lag: int = 200) -> float:
    """How many pairs one independent pair is worth along a track (>= 1): the integrated
    autocorrelation time ``1 + 2 sum_k rho_k`` of the whitened residuals of consecutive pairs of
    each track (pooled over tracks and components), summed while ``rho_k`` stays above 0.05, at
    most the mean track length. 1 without tracks or frames.

    params: (6,) the fit; frame_index: (N,) frames of the pairs, ordering each track in time.
    A walker seen in 300 frames whose errors drift slowly is worth far fewer than 300 independent
    people; counting them as independent makes the people overrule any prior with a std too
    small to mean anything.
    """
    tracked = prob.track >= 0
    if frame_index is None or not tracked.any():
        return 1.0
    r, _, valid = whitened(prob, params[None], scale)
    r = np.where(valid[0][:, None], r[0], 0.0)  # (N, dof)
    order = np.lexsort((frame_index, prob.track))
    order = order[tracked[order]]
    track, r = prob.track[order], r[order]
    lengths = np.bincount(track)
    lengths = lengths[lengths > 0]
    denom = float(np.sum(r * r))
    if denom <= 0 or len(r) < 3:
        return 1.0
    tau = 1.0
    for k in range(1, min(max_lag, int(lengths.max()))):
        same = track[k:] == track[:-k]
        if not same.any():
            break
        rho = float(np.sum(r[k:][same] * r[:-k][same])) / denom * len(r) / same.sum()
        if rho < _DEFF_MIN_RHO:
            break
        tau += 2.0 * rho
    return float(min(max(tau, 1.0), float(np.mean(lengths))))



def robust_scale(chi2: np.ndarray, prob: Problem) -> float:
    """Residual scale from the median of chi2 values (1 for correctly whitened residuals), floored."""
    finite = chi2[np.isfinite(chi2)]
    floor = MIN_NOISE_PX / prob.sd_across
    if finite.size == 0:
        return max(1.0, floor)
    return max(math.sqrt(float(np.median(finite)) / prob.residual.chi2_median), floor)
