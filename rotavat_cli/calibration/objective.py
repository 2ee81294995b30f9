"""The refinement's objective: pairs and weights, track statures profiled out, whitened residuals.

A :class:`Problem` holds the usable pairs and everything that weighs them (never the camera).
For parameter sets ``params (Q, 6)`` (:mod:`.params` slots) the person model (:mod:`.model`) gives
each head's error; the residual kind (:mod:`.residuals`) turns it into whitened components under
the pair's error covariance (:func:`pair_covariance`: the head's pixel noise, the foot's pixel noise
carried through the model, and for an untracked pair the stature spread along the person); each
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
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from ..design_effect import MAX_LAG, autocorrelation_time
from ..geometry.camera import up_vector_cam
from ..geometry.lens import lens_radius_px
from ..parallel import cpu_count
from .model import CameraTerms, camera_terms, head_errors, head_gain
from .params import PITCH, ROLL, from_internal, to_internal
from .priors import Priors
from .residuals import PairCovariance, ResidualKind, component_sum

__all__ = ["MIN_NOISE_PX", "BodyAxes", "Problem", "make_problem", "foot_gain", "pair_covariance", "profiled", "whitened",
           "prior_rows", "body_rows", "ROBUST_LOSSES", "robust_rows", "model_residual", "residual_and_jacobian", "residual_at", "jacobian_at", "pair_chi2", "robust_scale",
           "design_effect"]

_FD_STEP = 1e-6  # finite-difference step in the internal parameters (log f, rad, rad, log h, ...)
_FOOT_STEP_PX = 0.5  # finite-difference step of the foot pixel (the model is smooth over a pixel)
MIN_NOISE_PX = 0.5  # floor of the residual scale in pixels: annotation is never better than this
_THREAD_ROWS = 40_000  # pairs x parameter sets from which a Jacobian's sets are split over two threads


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
    spread_px: np.ndarray  # (N,) px: the stature spread along an untracked person (0 for tracked pairs)
    noise_px: float  # pixel noise of a head (and of a foot), per axis
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
    foot_noise: bool = True  # the foot's noise carried into the head error (errors in variables); False: the paper's

    def subset(self, idx: np.ndarray) -> "Problem":
        """The same problem on pairs ``idx`` (tracks renumbered)."""
        track = np.full(len(idx), -1)
        tracked = self.track[idx] >= 0
        labels, track[tracked] = np.unique(self.track[idx][tracked], return_inverse=True)
        return replace(self, rel_feet=self.rel_feet[idx], diff=self.diff[idx], axis=self.axis[idx],
                       spread_px=self.spread_px[idx], track=track, n_tracks=len(labels),
                       deff=None if self.deff is None else self.deff[idx])

    @property
    def dof(self) -> int:
        """Residual components per pair."""
        return self.residual.dof

    def inflation(self, effective: bool) -> np.ndarray | float:
        """Each pair's variance factor (N,): its design effect when ``effective`` (the objective and its
        covariance; never the per-pair outlier test), else 1."""
        return self.deff if effective and self.deff is not None else 1.0


def make_problem(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, person_height_m: float,
                 person_height_sd_m: float, noise_px: float, residual: ResidualKind, image_size: tuple[int, int],
                 priors: Priors | None, track_id: np.ndarray | None, foot_noise: bool = True) -> Problem:
    """The pairs, their stature spread from the observed pixel lengths, tracks of id >= 0.

    feet, heads: (N, 2) px; pp: (2,) px; track_id: (N,) int or None; foot_noise: the foot's noise carried
    into the head error (:func:`pair_covariance`).
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
    return Problem(feet - pp, diff, axis, spread, float(noise_px), person_height_m, person_height_sd_m, track,
                   n_tracks, residual, float(image_size[1]), priors, lens_radius_px(image_size),
                   foot_noise=bool(foot_noise))


def foot_gain(prob: Problem, params: np.ndarray, e: tuple[np.ndarray, np.ndarray],
              stature_m: float | np.ndarray, terms: CameraTerms | None = None) -> np.ndarray:
    """How each predicted head moves with its foot pixel: ``G[q, n] = d e / d foot`` (Q, N, 2, 2), rows
    (u, v) of the head error, columns (u, v) of the foot: in closed form (:func:`.model.head_gain`), or with a
    lens distortion or a box depth by forward differences of half a pixel.

    e: the head errors (u, v) (Q, N) at params (Q, 6) and stature_m (as :func:`.model.head_errors`); terms: their
    :func:`.model.camera_terms`, when already computed.
    """
    closed = head_gain(prob.rel_feet, params, stature_m, terms)
    if closed is not None:
        return closed
    columns = []
    for step in ((_FOOT_STEP_PX, 0.0), (0.0, _FOOT_STEP_PX)):
        moved, _, _ = head_errors(prob.rel_feet + step, prob.diff + step, params, stature_m, prob.radius_px)
        columns.append(np.stack([(moved[0] - e[0]) / _FOOT_STEP_PX, (moved[1] - e[1]) / _FOOT_STEP_PX], axis=-1))
    return np.stack(columns, axis=-1)


def pair_covariance(prob: Problem, gain: np.ndarray | None, effective: bool = False) -> PairCovariance:
    """Each pair's head-error covariance (px^2, image basis): ``noise^2 (I + G G^T) + spread^2 a a^T``,
    times its design effect when ``effective``.

    The observed foot is as noisy as the head, and the model predicts the head *from* it: a foot
    pixel off by ``eps`` moves the predicted head by ``G eps`` (:func:`foot_gain`). Ignoring it is
    the errors-in-variables mistake: within a person who barely moves, the foot's noise is as large
    as their real motion, the head seems to follow the foot less than perspective says (regression
    dilution), and the fit bends the camera to explain it (synthetic scenes of people standing still
    at many depths, 200 frames: focal 8% low, height 10% low; with this term within 1-2%, as a fit
    that ignores those people's own statures). ``gain``: (Q, N, 2, 2) or None (no foot noise: the
    paper's model, the grid's unweighted residuals).
    """
    var = prob.noise_px**2
    a, s2 = prob.axis, prob.spread_px**2
    uu, uv, vv = var + s2 * a[:, 0] ** 2, s2 * a[:, 0] * a[:, 1], var + s2 * a[:, 1] ** 2
    if gain is not None:
        g = gain
        uu = uu + var * (g[..., 0, 0] ** 2 + g[..., 0, 1] ** 2)
        uv = uv + var * (g[..., 0, 0] * g[..., 1, 0] + g[..., 0, 1] * g[..., 1, 1])
        vv = vv + var * (g[..., 1, 0] ** 2 + g[..., 1, 1] ** 2)
    k = prob.inflation(effective)
    return PairCovariance(uu * k, uv * k, vv * k)


def profiled(prob: Problem, params: np.ndarray, scale: float = 1.0, effective: bool = False
             ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray, np.ndarray, PairCovariance]:
    """Head errors (u, v) (Q, N) px with each track's stature profiled out, validity (Q, N), deltas (Q, T) m,
    and the pairs' error covariance (:func:`pair_covariance`).

    params: (Q, 6). A tracked person's stature is ``S + delta_t`` with ``delta_t ~ N(0, sd_S)``,
    solved by two robust Gauss-Newton steps (Cauchy weights inside the track) against the whitened
    residuals / scale (``effective``: with the pairs' design effects, as the objective weighs them).
    """
    Q, T = len(params), prob.n_tracks
    terms = camera_terms(prob.rel_feet, prob.diff, params, prob.radius_px)  # the same at every stature
    e, de, valid = head_errors(prob.rel_feet, prob.diff, params, prob.person_height_m, prob.radius_px, terms=terms)
    delta = np.zeros((Q, T))
    stature = prob.person_height_m
    if T:
        tracked = prob.track >= 0
        flat = (np.arange(Q)[:, None] * T + np.maximum(prob.track, 0)[None, :]).ravel()
        prec = 1.0 / prob.stature_sd_m**2
        # The statures' steps weigh as the objective does (the foot's gain at the prior stature): weighed by the
        # pixel noise alone, the profiled statures are not the objective's own and people standing still drift
        # again (2,000 frames: focal 2.3% off, against 0.7%).
        whiten = prob.residual.whitener(prob.axis, _covariance_at(prob, params, e, stature, effective, terms))
        for _ in range(2):
            r = whiten(e) / scale
            j = whiten(de) / scale
            w = (valid & tracked) / (1.0 + (r[..., 0] / 3.0) ** 2)
            num = np.bincount(flat, (w * component_sum(j * r)).ravel(), Q * T).reshape(Q, T) + delta * prec
            den = np.bincount(flat, (w * component_sum(j * j)).ravel(), Q * T).reshape(Q, T) + prec
            delta = delta - num / den
            stature = prob.person_height_m + np.where(tracked, delta[:, np.maximum(prob.track, 0)], 0.0)
            e, de, valid = head_errors(prob.rel_feet, prob.diff, params, stature, prob.radius_px, terms=terms)
    # The foot's gain at each person's own stature: the pairs then cannot see the scene's scale.
    return e, valid, delta, _covariance_at(prob, params, e, stature, effective, terms)


def _covariance_at(prob: Problem, params: np.ndarray, e: tuple[np.ndarray, np.ndarray], stature_m: float | np.ndarray,
                   effective: bool, terms: CameraTerms | None = None) -> PairCovariance:
    """:func:`pair_covariance` with the foot's gain at ``params`` (Q, 6) and ``stature_m`` where the problem carries
    the foot's noise (``e``: the head errors there, (Q, N) each; terms: their :func:`.model.camera_terms`)."""
    return pair_covariance(prob, foot_gain(prob, params, e, stature_m, terms) if prob.foot_noise else None, effective)


def whitened(prob: Problem, params: np.ndarray, scale: float = 1.0, effective: bool = False
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Whitened residuals (Q, N, dof) / scale, track-stature prior rows (Q, T), validity (Q, N).

    Untracked pairs carry the stature spread in their along-the-person variance instead;
    ``effective``: each pair's variance times its design effect (the objective).
    """
    e, valid, delta, cov = profiled(prob, params, scale, effective)
    r = prob.residual.whitened(e, prob.axis, cov)
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


# The robust losses of the refinement, as residual transforms ``r -> sign(r) sqrt(rho(r^2))`` applied to the pairs'
# rows only (rho as scipy.optimize.least_squares defines it, with its f_scale): the priors, the track statures and
# the bodies' axis stay Gaussian. A loss handed to least_squares itself would cap them too: a stature prior row
# 16 sd out then costs what a 4 sd one should, nothing holds the scale of the scene (which the pairs cannot see),
# and on long sequences the camera height drifts (synthetic walkers, 2,000 frames: +68%).
ROBUST_LOSSES = ("linear", "cauchy", "soft_l1")


def robust_rows(r: np.ndarray, loss: str, f_scale: float) -> np.ndarray:
    """Rows ``r`` (...) under a robust loss: ``sign(r) sqrt(rho(r^2))`` (``linear``: unchanged)."""
    if loss == "linear":
        return r
    z = (r / f_scale) ** 2
    if loss == "cauchy":
        rho = np.log1p(z)
    elif loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    else:
        raise ValueError(f"loss must be one of {ROBUST_LOSSES}, got {loss!r}")
    return np.sign(r) * f_scale * np.sqrt(rho)


def model_residual(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float, loss: str = "linear",
                   f_scale: float = 1.0) -> np.ndarray:
    """Residual vectors (Q, M) for params (Q, 6): pairs (whitened / scale, with their design effects, under the
    robust ``loss``), track statures, the camera's priors, the bodies' axis."""
    r, rows, _ = whitened(prob, params, scale, effective=True)
    return np.concatenate([robust_rows(r.reshape(len(params), -1), loss, f_scale), rows,
                           prior_rows(prob, params, free), body_rows(prob, params, free)], axis=1)


def residual_and_jacobian(prob: Problem, x: np.ndarray, full0: np.ndarray, free: np.ndarray,
                          scale: float, loss: str = "linear", f_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Residual vector (M,) and its Jacobian (M, n_free) at internal ``x (n_free,)`` by one vectorised
    forward difference; the fixed slots come from ``full0 (6,)``; ``loss``: as :func:`model_residual`."""
    xs = np.vstack([x, x + _FD_STEP * np.eye(len(x))])
    r = model_residual(prob, from_internal(xs, full0, free), free, scale, loss, f_scale)
    return r[0], ((r[1:] - r[0]) / _FD_STEP).T


def residual_at(prob: Problem, x: np.ndarray, full0: np.ndarray, free: np.ndarray, scale: float,
                loss: str = "linear", f_scale: float = 1.0) -> np.ndarray:
    """The residual vector (M,) of :func:`residual_and_jacobian` alone (same arguments, the same numbers: each
    parameter set's rows are computed on their own)."""
    return model_residual(prob, from_internal(x[None], full0, free), free, scale, loss, f_scale)[0]


def jacobian_at(prob: Problem, x: np.ndarray, r0: np.ndarray, full0: np.ndarray, free: np.ndarray, scale: float,
                loss: str = "linear", f_scale: float = 1.0) -> np.ndarray:
    """The Jacobian (M, n_free) of :func:`residual_and_jacobian` given its residual ``r0 (M,)`` at ``x``: a
    least-squares step that is rejected then costs one parameter set, not ``1 + n_free``."""
    params = from_internal(x + _FD_STEP * np.eye(len(x)), full0, free)
    if len(prob.rel_feet) * len(params) < _THREAD_ROWS or len(params) < 2 or cpu_count() < 2:
        r = model_residual(prob, params, free, scale, loss, f_scale)
    else:  # many pairs: two halves of the parameter sets on two threads (each set's rows are computed on their own)
        half = len(params) // 2
        with ThreadPoolExecutor(2) as pool:
            parts = pool.map(lambda part: model_residual(prob, part, free, scale, loss, f_scale),
                             (params[:half], params[half:]))
            r = np.concatenate(list(parts))
    return ((r - r0) / _FD_STEP).T


def pair_chi2(prob: Problem, params: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(N,) squared whitened residual norm per pair at params (6,) (not divided by scale); inf if invalid."""
    r, _, valid = whitened(prob, params[None], scale)
    chi2 = component_sum((r[0] * scale) ** 2)
    return np.where(valid[0], chi2, np.inf)


def design_effect(prob: Problem, params: np.ndarray, scale: float, frame_index: np.ndarray | None,
                  max_lag: int = MAX_LAG) -> float:
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
    return autocorrelation_time(r[order], prob.track[order], max_lag)


def robust_scale(chi2: np.ndarray, prob: Problem) -> float:
    """Residual scale from the median of chi2 values (1 for correctly whitened residuals), floored."""
    finite = chi2[np.isfinite(chi2)]
    floor = MIN_NOISE_PX / prob.noise_px
    if finite.size == 0:
        return max(1.0, floor)
    return max(math.sqrt(float(np.median(finite)) / prob.residual.chi2_median), floor)
