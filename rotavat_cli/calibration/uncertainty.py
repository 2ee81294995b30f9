"""Uncertainty of a calibration: covariances (statistical, cluster jackknife, assumed systematics,
the head-column test), standard deviations and correlations, and warnings in plain words.

Covariances are over the internal parameters (:mod:`.params`: log focal, pitch, roll, log height,
distortion, box depth), ``(6, 6)`` with zeros for the fixed slots; :func:`std_and_corr` turns
them into report units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..geometry.camera import Camera
from .chi_square import chi2_99
from .grid import order_invariant_subset
from .model import undistort
from .objective import Problem, model_residual, pair_chi2, residual_and_jacobian, robust_scale
from .params import BOX_DEPTH, DISTORTION, FOCAL, HEIGHT, MODEL_NAMES, PARAM_NAMES, PITCH, ROLL, from_internal, to_internal
from .refine import robust_least_squares
from .residuals import RESIDUAL_KINDS

__all__ = ["MOVED_PRIOR_SD", "moved_by_data", "WARN_FOCAL_REL_SD", "WARN_FOCAL_PITCH_CORR", "WARN_PITCH_SD_DEG", "WARN_HEIGHT_REL_SD",
           "WARN_INLIER_FRACTION", "Systematics", "covariances", "jackknife_cov", "std_and_corr", "fit_warnings"]

_COLUMN_TEST_PAIRS = 5000  # the head-column test runs on at most this many inliers (order-independent)
# ... and only with this many people (tracks, else frames) or independent pairs: with fewer, the head rows alone
# barely determine a camera, their refit wanders, and the linearised test rejects clean data (one synthetic
# walker: chi-square 25 on 2 dof, and a std 30x too wide once the "disagreement" was added).
_COLUMN_TEST_MIN_CLUSTERS = 5
_COLUMN_TEST_MIN_PAIRS = 20
# The linearised statistic is over-dispersed on clean but realistic data (bodies whose crown is not
# straight above the mid-sole as they turn): on 10 synthetic scenes (8 walkers x 20 frames) it reached
# 30 on 3 dof, where its 99% quantile is 11; true disagreement gives hundreds (Town Centre's head points
# from a separate head box: 269; synthetic box points: 456). So it speaks from 5x its 99% quantile.
_COLUMN_TEST_FACTOR = 5.0
_MIN_CLUSTERS = 2  # cluster-robust (jackknife) covariance from this many clusters (tracks, else frames)
_NULL_EIG = 1e-9  # information eigenvalues below this fraction of the largest: direction undetermined

# Warning thresholds: a parameter is "poorly determined" past these standard deviations.
WARN_FOCAL_REL_SD = 0.10
WARN_FOCAL_PITCH_CORR = 0.95
WARN_PITCH_SD_DEG = 2.0
WARN_HEIGHT_REL_SD = 0.10
WARN_INLIER_FRACTION = 0.6


# ---- uncertainty ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Systematics:
    """Prior sds of what the model assumes but does not fit (propagated into the reported std)."""

    principal_point_px: float  # per axis
    distortion: float  # radial displacement at the image corner / half-diagonal
    stature_mean_m: float  # population mean stature
    box_depth_m: float  # box depth (box-derived points)
    held: tuple[tuple[int, float], ...] = ()  # (slot, prior sd, internal units) held at its prior's median


def _statistical_cov(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float,
                     clusters: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariance (n_free, n_free) of the free internal parameters, with the residuals and Jacobian.

    Gauss-Newton ``(J^T J)^-1`` of the whitened residuals; with >= 2 clusters (tracks, else frames)
    each variance is the larger of it and the cluster jackknife's (:func:`jackknife_cov`: correlated
    errors of a person, honest with few people).
    """
    r, J = residual_and_jacobian(prob, to_internal(params)[free], params, free, scale)
    A_inv = np.linalg.pinv(J.T @ J, rcond=_NULL_EIG)
    if clusters is None or len(np.unique(clusters)) < _MIN_CLUSTERS:
        return A_inv, r, J
    row_cluster, n_groups = _row_clusters(prob, clusters, len(r))
    sandwich = jackknife_cov(J, r, row_cluster, n_groups)
    ratio = np.diag(sandwich) / np.maximum(np.diag(A_inv), 1e-300)
    base = sandwich if np.mean(ratio) > 1.0 else A_inv  # correlations from the larger of the two
    sd_base = np.sqrt(np.maximum(np.diag(base), 1e-300))
    sd = np.sqrt(np.maximum(np.diag(A_inv), np.diag(sandwich)))
    return base / np.outer(sd_base, sd_base) * np.outer(sd, sd), r, J


def _row_clusters(prob: Problem, clusters: np.ndarray | None, n_rows: int) -> tuple[np.ndarray, int]:
    """Cluster (M,) of each residual row (-1: none, e.g. a prior) and the number of clusters.

    Pair rows take their pair's cluster (each pair its own when ``clusters`` is None); a track's
    stature-prior row belongs to the cluster of its pairs.
    """
    n_pairs = len(prob.rel_feet)
    groups, inv = np.unique(np.arange(n_pairs) if clusters is None else clusters, return_inverse=True)
    row_cluster = np.full(n_rows, -1)
    row_cluster[: n_pairs * prob.dof] = np.repeat(inv, prob.dof)
    if prob.n_tracks:
        tracked = np.flatnonzero(prob.track >= 0)
        member = np.zeros(prob.n_tracks, int)
        member[prob.track[tracked]] = tracked  # any pair of the track (tracks sit inside one cluster)
        row_cluster[n_pairs * prob.dof : n_pairs * prob.dof + prob.n_tracks] = inv[member]
    return row_cluster, len(groups)


def _cluster_sums(values: np.ndarray, row_cluster: np.ndarray, n_groups: int) -> np.ndarray:
    """(G, ...) sums of the rows of ``values`` (M, ...) per cluster; rows of cluster -1 are left out."""
    rows = np.flatnonzero(row_cluster >= 0)
    sums = np.zeros((n_groups,) + values.shape[1:])
    np.add.at(sums, row_cluster[rows], values[rows])  # in row order, as a sparse membership product would
    return sums


def jackknife_cov(J: np.ndarray, r: np.ndarray, row_cluster: np.ndarray, n_groups: int) -> np.ndarray:
    """Cluster jackknife covariance (k, k): ``(G-1)/G sum_g d_g d_g^T`` over the G clusters.

    ``d_g = (A - A_g)^-1 J_g^T r_g`` is the linearised shift of the estimate when cluster g is left
    out (``A = J^T J``; rows of cluster -1, such as priors, are never left out). Unlike the plain
    sandwich, it does not shrink with few clusters (MacKinnon, Nielsen & Webb 2023, "CV3").
    """
    scores = _cluster_sums(J * r[:, None], row_cluster, n_groups)
    A_g = _cluster_sums(J[:, :, None] * J[:, None, :], row_cluster, n_groups)
    shifts = np.einsum("gij,gj->gi", np.linalg.pinv((J.T @ J)[None] - A_g, rcond=_NULL_EIG), scores)
    return shifts.T @ shifts * (n_groups - 1) / n_groups


def _column_shift(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float, clusters: np.ndarray | None,
                  cov_full: np.ndarray) -> tuple[np.ndarray, float, int, np.ndarray]:
    """How far the head rows alone move the full fit, and a Hausman test of that move.

    Refits the inliers with the residual kind's ``test_against`` kind (the head rows only) from the
    full fit and returns the shift ``d`` (n_free,) of the internal parameters, the statistic
    ``d^T V^+ d`` with ``V = cov_rows - cov_full`` (the rows-only fit is the less efficient of two
    consistent estimates), V's rank, and V (n_free, n_free). Under a right model the two agree to within V; head
    columns that do not follow the person's vertical (drawn straight above the foot, as boxes
    are) make them disagree.
    """
    rows = replace(prob, residual=RESIDUAL_KINDS[prob.residual.test_against])
    scale_rows = robust_scale(pair_chi2(rows, params), rows)
    refit = robust_least_squares(rows, params, free, scale_rows, "soft_l1", 3.0)
    cov_rows = _statistical_cov(rows, refit, free, scale_rows, clusters)[0]
    shift = to_internal(refit)[free] - to_internal(params)[free]
    w, U = np.linalg.eigh(cov_rows - cov_full)
    keep = w > _NULL_EIG * max(float(w.max()), 1e-300)
    proj = U[:, keep].T @ shift
    return shift, float(np.sum(proj**2 / w[keep])), int(keep.sum()), cov_rows - cov_full


def _perturbed(prob: Problem, which: str, amount: float) -> Problem:
    """The problem with its principal point, lens distortion or stature moved by ``amount``."""
    rel_feet, diff, height = prob.rel_feet, prob.diff, prob.person_height_m
    if which == "cx":
        rel_feet = rel_feet - (amount, 0.0)
    elif which == "cy":
        rel_feet = rel_feet - (0.0, amount)
    elif which == "distortion":  # corner displacement ``amount`` (division model, first order)
        rel_feet, diff = (p[0] for p in undistort(rel_feet, diff, np.array([[-amount]]), prob.radius_px))
    elif which == "stature":
        height = height + amount
    return replace(prob, rel_feet=rel_feet, diff=diff, person_height_m=height)


def _systematic_cov(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float, r: np.ndarray,
                    J: np.ndarray, assumed: Systematics, shifts: dict | None = None) -> np.ndarray:
    """Covariance (n_free, n_free) induced by the assumed-but-unknown quantities (linearised); ``shifts``, when
    given, receives each one's parameter shift (n_free,) for a one-sd change (:func:`covariances`)."""
    sds = {"cx": assumed.principal_point_px, "cy": assumed.principal_point_px, "distortion": assumed.distortion,
           "stature": assumed.stature_mean_m, "box": assumed.box_depth_m, **{slot: sd for slot, sd in assumed.held}}
    gain = -np.linalg.pinv(J.T @ J, rcond=_NULL_EIG) @ J.T
    cov = np.zeros((J.shape[1], J.shape[1]))
    for name, sd in sds.items():
        if sd <= 0:
            continue
        step = 0.1 * sd
        if name == "box":  # a fixed parameter of the model
            r_moved = model_residual(prob, (params + step * np.eye(len(params))[BOX_DEPTH])[None], free, scale)[0]
        elif isinstance(name, int):  # a slot held at the prior's median: its internal value moves by ``step``
            moved = to_internal(params)
            moved[name] += step
            r_moved = model_residual(prob, from_internal(moved[None], moved, np.ones(len(moved), bool)), free,
                                     scale)[0]
        else:
            r_moved = model_residual(_perturbed(prob, name, step), params[None], free, scale)[0]
        shift = gain @ ((r_moved - r) / step) * sd  # parameter shift for a one-sd change
        cov += np.outer(shift, shift)
        if shifts is not None:
            shifts[name] = (shift, sd)
    return cov


def covariances(prob: Problem, params: np.ndarray, free: np.ndarray, scale: float, clusters: np.ndarray | None,
                 assumed: Systematics, test_columns: bool, shifts: dict | None = None
                 ) -> tuple[np.ndarray, np.ndarray, list[str], dict[int, str]]:
    """(total, statistical) covariances (6, 6) of the internal parameters (zero for fixed ones), warnings,
    and what determined each free slot (:func:`determined_by`). ``shifts``, when given, receives for each
    assumed quantity (``"cx"``, ``"cy"``, ``"distortion"``, ``"stature"``, ...) the internal parameters' shift
    (6,) when the fit assumes it one sd higher (the principal point; for ``distortion`` the undistortion's
    coefficient one sd lower: ``_perturbed``), and that sd: what a stature measured with the camera needs to
    carry the assumption's direct effect too (:func:`rotavat_cli.calibration.footprint.report_covariance`).

    The statistical part is the posterior's (Gauss-Newton of the whole objective: the pairs with
    their design effects, the track statures, the priors, the bodies' axis; or the cluster jackknife
    when larger); the total adds the assumed systematics. With ``test_columns`` and a residual kind
    that has a ``test_against`` kind (full: the head rows), when the head rows alone disagree with the
    joint fit beyond their noise (:func:`_column_shift`: 5x the 99% chi-square quantile; from 5 people or
    20 independent pairs), a warning says so and the
    total adds, per parameter, the part of the squared disagreement beyond its noise
    (``max(0, d_i^2 - V_ii)``: an estimate of the squared bias the columns put in the fit; zero on
    average for a right model, whose disagreement is all noise), at most the parameter's prior variance.
    """
    stat, r, J = _statistical_cov(prob, params, free, scale, clusters)
    found: dict = {}
    total = stat + _systematic_cov(prob, params, free, scale, r, J, assumed, found)
    if shifts is not None:
        for name, (shift, sd) in found.items():
            full = np.zeros(len(free))
            full[free] = shift
            shifts[name] = (full, sd)
    warns = []
    by_slot = determined_by(J, _row_groups(prob, free, len(r)), free)
    enough = len(prob.rel_feet) >= _COLUMN_TEST_MIN_PAIRS if clusters is None else \
        len(np.unique(clusters)) >= _COLUMN_TEST_MIN_CLUSTERS
    if test_columns and prob.residual.test_against is not None and enough:
        sub = order_invariant_subset(prob.rel_feet, prob.rel_feet - prob.diff, _COLUMN_TEST_PAIRS)
        sub_clusters = None if clusters is None else clusters[sub]
        sub_prob = prob.subset(sub)
        sub_stat = stat if len(sub) == len(prob.rel_feet) else _statistical_cov(sub_prob, params, free, scale,
                                                                               sub_clusters)[0]
        shift, stat_h, rank, noise = _column_shift(sub_prob, params, free, scale, sub_clusters, sub_stat)
        if rank and stat_h > _COLUMN_TEST_FACTOR * chi2_99(rank):
            excess = np.maximum(shift**2 - np.diag(noise), 0.0)
            if prob.priors is not None:
                excess = np.minimum(excess, prob.priors.sd[free] ** 2)
            total = total + np.diag(excess)
            focal = "" if free[FOCAL] else "a wrong focal length, "
            warns.append(f"the head columns disagree with the head rows (chi-square {stat_h:.0f} on {rank} dof): "
                         f"{focal}box-derived points (then use --points boxes), an off-centre principal point "
                         "(--principal-point CX CY) or lens distortion (--distortion); the std includes the disagreement")
    if assumed.held:  # slots held at their prior's median: where their spread dominates, the prior determines
        spread = np.diag(_systematic_cov(prob, params, free, scale, r, J, Systematics(0.0, 0.0, 0.0, 0.0,
                                                                                       assumed.held)))
        for k, slot in enumerate(np.flatnonzero(free)):
            if spread[k] >= (1.0 - _MATTERS) * total[k, k] and "prior" not in by_slot[int(slot)].split("+"):
                by_slot[int(slot)] += "+prior"
    lost = _undetermined(J)
    out = []
    for cov in (total, stat):
        cov = cov.copy()
        cov[lost, :] = cov[:, lost] = np.nan
        cov[lost, lost] = np.inf
        full = np.zeros((len(free), len(free)))
        full[np.ix_(free, free)] = cov
        out.append(full)
    return out[0], out[1], warns, by_slot


# Sources of information, in the order labels name them (fit.determined_by).
SOURCES = ("people", "bodies", "prior")
_MATTERS = 0.75  # a source matters when leaving it out would raise a parameter's variance by a third or more


def _row_groups(prob: Problem, free: np.ndarray, n_rows: int) -> np.ndarray:
    """(M,) index into :data:`SOURCES` of each residual row of :func:`.objective.model_residual`:
    the pairs and the track statures (people), the camera's priors (prior), the bodies' axis (bodies)."""
    groups = np.zeros(n_rows, int)
    n_prior = 0 if prob.priors is None else len(prob.priors.slots(free))
    n_body = n_rows - len(prob.rel_feet) * prob.dof - prob.n_tracks - n_prior
    groups[n_rows - n_body - n_prior : n_rows - n_body] = SOURCES.index("prior")
    if n_body:
        groups[n_rows - n_body :] = SOURCES.index("bodies")
    return groups


def _marginal_variances(info: np.ndarray) -> np.ndarray:
    """(k,) diagonal of the inverse of an information matrix (k, k); inf for parameters it leaves undetermined."""
    w, V = np.linalg.eigh(info)
    null = w <= _NULL_EIG * max(float(w.max()), 1e-300)
    var = (V[:, ~null] ** 2 / w[~null]).sum(axis=1)
    var[(V[:, null] ** 2).sum(axis=1) > 1e-6] = np.inf
    return var


def determined_by(J: np.ndarray, row_groups: np.ndarray, free: np.ndarray) -> dict[int, str]:
    """What determined each free slot: the :data:`SOURCES` without which its variance would rise by a
    third or more, joined by "+" ("people", "prior", "people+prior", "bodies+prior", ...).

    J: (M, n_free) Jacobian of the whitened objective; row_groups: (M,) source of each row.
    Returns {slot: label}.
    """
    info = J.T @ J
    v_all = _marginal_variances(info)
    ratios = {}
    for g, name in enumerate(SOURCES):
        rows = row_groups == g
        if rows.any():
            v_without = _marginal_variances(info - J[rows].T @ J[rows])
            ratios[name] = np.where(np.isfinite(v_without), v_all / np.where(np.isfinite(v_without), v_without, 1.0),
                                    0.0)
    out = {}
    for k, slot in enumerate(np.flatnonzero(free)):
        names = [n for n in SOURCES if n in ratios and ratios[n][k] < _MATTERS]
        out[int(slot)] = "+".join(names) if names else min(ratios, key=lambda n: ratios[n][k])
    return out


MOVED_PRIOR_SD = 2.0  # an estimate this many of its prior's sd from the prior's mean was put there by the data


def moved_by_data(labels: dict[int, str], params: np.ndarray, priors, free: np.ndarray) -> dict[int, str]:
    """``labels`` (:func:`determined_by`) with "people" added to every free slot labelled without it whose estimate
    lies more than :data:`MOVED_PRIOR_SD` of its prior's sd from the prior's mean: a prior alone answers its mean,
    so the pairs moved it there (they may still leave its variance to the prior: a stature 2.6 sd from 1.70 m
    is the people's, not the prior's).

    labels: {slot: label}; params: (6,) external; priors: :class:`.priors.Priors` or None; free: (6,) bool.
    """
    if priors is None:
        return dict(labels)
    z = np.abs(to_internal(np.asarray(params, np.float64)[None])[0] - priors.mean) / priors.sd
    out = dict(labels)
    for slot, label in labels.items():
        names = label.split("+")
        if free[slot] and "people" not in names and np.isfinite(priors.sd[slot]) and z[slot] > MOVED_PRIOR_SD:
            out[slot] = "+".join(n for n in SOURCES if n == "people" or n in names)
    return out


def _undetermined(J: np.ndarray) -> np.ndarray:
    """(n_free,) bool: parameters with a component in the null space of the information J^T J."""
    w, V = np.linalg.eigh(J.T @ J)
    null = w <= _NULL_EIG * max(float(w.max()), 1e-300)
    return (V[:, null] ** 2).sum(axis=1) > 1e-6


def std_and_corr(params: np.ndarray, cov: np.ndarray, free: np.ndarray) -> tuple[dict[str, float], float]:
    """Standard deviations (px, deg, deg, m; NaN if fixed; then the fitted point-model ones) and corr(focal, pitch).

    params: (6,); cov: (6, 6) internal; free: (6,) bool.
    """
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    values = {FOCAL: params[FOCAL] * sd[FOCAL], PITCH: math.degrees(sd[PITCH]), ROLL: math.degrees(sd[ROLL]),
              HEIGHT: params[HEIGHT] * sd[HEIGHT], DISTORTION: sd[DISTORTION]}  # slot -> std in MODEL_NAMES' units
    std = {k: (float(values[i]) if free[i] else math.nan) for k, i in zip(MODEL_NAMES, values)
           if k in PARAM_NAMES or free[i]}
    ok = free[FOCAL] and free[PITCH] and 0 < sd[FOCAL] < math.inf and 0 < sd[PITCH] < math.inf
    corr = float(np.clip(cov[FOCAL, PITCH] / (sd[FOCAL] * sd[PITCH]), -1.0, 1.0)) if ok else math.nan
    return std, corr


_GIVE = {"focal_px": "--focal PX or --focal-mm MM", "pitch_deg": "--pitch DEG", "roll_deg": "--no-roll", "height_m": "--camera-height M",
         "person_height_m": "--person-height M"}
_WORDS = {"focal_px": "focal length", "pitch_deg": "pitch", "roll_deg": "roll", "height_m": "camera height",
          "person_height_m": "people's mean stature"}


def fit_warnings(camera: Camera, std: dict[str, float], corr: float, inliers: int, usable: int, pairs: int,
                 determined: dict[str, str] | None = None, one_depth: bool = False) -> list[str]:
    """Plain-words warnings about what the data could not determine (``determined``: fit.determined_by)."""
    out = []
    determined = determined or {}
    lost = [k for k, v in std.items() if v == math.inf]
    horizon = float(camera.horizon_v_px(camera.image_size[0] / 2.0))  # the image's row (with the lens)
    if lost:
        out.append(f"the pairs cannot determine {', '.join(lost)}: their values are arbitrary (the horizon, "
                   f"row {horizon:.0f} at the centre, may still be right); give the focal length (--focal PX or --focal-mm MM) or "
                   "a field-of-view prior (--fov-prior DEG)")
    from_prior = [k for k, v in determined.items() if "people" not in v.split("+") and "prior" in v.split("+")]
    if from_prior:
        why = "the people stand at about one depth" if one_depth else "the people do not determine it"
        out.append(f"{', '.join(_WORDS.get(k, k) for k in from_prior)} from the prior{'s' * (len(from_prior) > 1)} "
                   f"({why}): give what you know ({', '.join(_GIVE.get(k, k) for k in from_prior)})")
    f_sd = std["focal_px"]
    if math.isfinite(f_sd) and f_sd > WARN_FOCAL_REL_SD * camera.focal_px and "focal_px" not in from_prior:
        valley = (f"; focal and pitch trade off (correlation {corr:+.2f}): the horizon is better determined than "
                  "either") if abs(corr) > WARN_FOCAL_PITCH_CORR else ""
        out.append(f"focal length poorly determined: {camera.focal_px:.0f} +- {f_sd:.0f} px "
                   f"({100 * f_sd / camera.focal_px:.0f}%){valley}; give --focal PX (or --focal-mm MM, 35 mm equivalent) if it is known")
    if math.isfinite(std["pitch_deg"]) and std["pitch_deg"] > WARN_PITCH_SD_DEG and "pitch_deg" not in from_prior:
        out.append(f"pitch poorly determined: +- {std['pitch_deg']:.1f} deg")
    if (math.isfinite(std["height_m"]) and std["height_m"] > WARN_HEIGHT_REL_SD * camera.height_m
            and "height_m" not in from_prior):
        out.append(f"camera height poorly determined: {camera.height_m:.2f} +- {std['height_m']:.2f} m")
    if inliers < WARN_INLIER_FRACTION * usable:
        out.append(f"only {inliers} of {usable} usable pairs fit upright people of the given stature "
                   "(sitting, cropped or mis-detected people, or a wrong stature?)")
    if usable < pairs:
        out.append(f"{pairs - usable} pair{'s' * (pairs - usable != 1)} with the head below the foot "
                   f"{'were' if pairs - usable != 1 else 'was'} ignored")
    return out
