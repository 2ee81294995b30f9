"""How sure a measured stature is: its standard deviation, propagated, and whether it is extrapolated.

A stature from :func:`~.measure.statures_from_camera_m` has two sources of error (docs/calibration.md,
"How sure is a stature"):

- **the camera's**: the calibration's parameters are uncertain (camera.yaml ``fit.covariance``, report
  units). The Jacobian ``J`` of the stature with respect to them is taken by central differences through
  ``Camera.replace`` (so whatever the camera applies, principal point, roll, lens distortion, is
  differentiated too) and the variance is ``J Σ Jᵀ``. A track's part uses its pairs' mean Jacobian: it
  does not average down over frames, and it is correlated between tracks (:attr:`StatureErrors.camera_cov_m2`).
  The camera's scale is in ``Σ`` too: a height from the stature prior carries the prior mean's sd, a
  reference person's known stature its own, a given camera height none (calibrate writes it so).
- **the pixels'**: each pair's foot and head clicks. The derivatives ``g`` (4,) of the stature with respect
  to the foot and head pixels, times the click noise ``σ``, give a pair's sd ``σ |g|``. ``σ`` is each track's
  own, from its scatter (``sd = spread / 0.6745``, ``σ = sd / rms|g|``) when it has
  :data:`MIN_SCATTER_PAIRS` pairs or more; else the median of those tracks' ``σ``; else the calibration's
  (``rmse_px / sqrt(2 axes)``: the head residual carries the head's and the foot's click on each of the
  residual's pixel axes); else :data:`CLICK_NOISE_PX`. A track's median then has sd
  ``sqrt(pi/2) · rms(σ|g|) / sqrt(n / deff)`` (the median of ``n`` normal values; 1 instead of
  ``sqrt(pi/2)`` for ``n <= 2``, where the median is the mean), with ``deff`` the design effect of
  consecutive frames (:func:`stature_design_effect`).

A track is **extrapolated** when its median foot pixel lies outside the calibration's footprint
(``fit.footprint_px``, the hull of its inliers' feet) by more than :data:`FOOTPRINT_MARGIN_REL` of the
image's larger side, or when that foot's depth lies beyond the footprint's depth range by more than
:data:`DEPTH_TOLERANCE_REL` (a pixel margin near the horizon is many metres). Without a footprint
nobody is extrapolated, and :attr:`StatureErrors.footprint_known` says it is unknown.

Examples
--------
>>> cam = Camera((640, 480), 500.0, None, np.deg2rad(30.0), 0.0, 5.0)
>>> foot = np.array([[320.0, 400.0]])
>>> head = cam.project(cam.backproject_px_to_ground(foot) + 1.7 * cam.up_cam)
>>> J = camera_jacobian_m(foot, head, cam, ("height_m",))  # a stature scales with the camera height
>>> round(float(J[0, 0]), 6)
0.34
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from ..design_effect import autocorrelation_time
from ..geometry.camera import Camera
from ..geometry.camera_covariance import CameraCovariance
from .measure import statures_by_track, statures_from_camera_m

__all__ = ["CAMERA_PARAMETERS", "CLICK_NOISE_PX", "MIN_SCATTER_PAIRS", "FOOTPRINT_MARGIN_REL", "DEPTH_TOLERANCE_REL",
           "StatureErrors", "camera_jacobian_m", "pixel_gradient_m", "stature_design_effect",
           "within_polygon", "extrapolated_feet", "stature_errors"]

# Report name -> (Camera field, report unit -> field unit, central-difference step in report units, relative?).
CAMERA_PARAMETERS = {
    "focal_px": ("focal_px", 1.0, 1e-4, True),
    "pitch_deg": ("pitch_rad", math.pi / 180.0, 1e-3, False),
    "roll_deg": ("roll_rad", math.pi / 180.0, 1e-3, False),
    "height_m": ("height_m", 1.0, 1e-4, True),
    "distortion": ("distortion", 1.0, 1e-5, False),
    "cx_px": ("principal_point", 0, 1e-2, False),  # the principal point's components (the field is a pair)
    "cy_px": ("principal_point", 1, 1e-2, False),
}
CLICK_NOISE_PX = 2.0  # the click noise when nothing says better (calibrate's default noise_px)
MIN_SCATTER_PAIRS = 8  # a track with this many measured pairs estimates its own click noise from its scatter
_IQR_TO_SD = 0.6745  # half the interquartile range of a normal is 0.6745 sd
_MEDIAN_EFFICIENCY = math.sqrt(math.pi / 2.0)  # sd of a large sample's median over sd / sqrt(n), normal data
_PIXEL_STEP_PX = 0.01  # central-difference step of the pixel derivatives
FOOTPRINT_MARGIN_REL = 0.02  # a foot this far (x the image's larger side, px) outside the footprint is still inside
FOOTPRINT_MAX_READ = 10_000  # vertices a camera.yaml's footprint may hold (calibrate writes at most 32)
DEPTH_TOLERANCE_REL = 0.10  # a foot depth within this fraction beyond the footprint's depth range is still inside


def camera_jacobian_m(feet_px: np.ndarray, heads_px: np.ndarray, camera: Camera, names: tuple[str, ...]) -> np.ndarray:
    """(N, k) m per report unit: derivatives of each pair's stature with respect to the camera parameters
    ``names`` (:data:`CAMERA_PARAMETERS`), by central differences through ``camera.replace``.

    feet_px, heads_px: (N, 2) px. A parameter the camera does not have (a Camera without ``distortion``)
    has derivative 0: it does not apply it. NaN where the stature is NaN.
    """
    have = {f.name for f in fields(camera)}
    out = np.zeros((len(np.asarray(feet_px)), len(names)))
    for k, name in enumerate(names):
        field_name, to_field, step, relative = CAMERA_PARAMETERS[name]
        if field_name not in have:
            continue
        if field_name == "principal_point":  # to_field: which component
            h = step
            moved = [list(camera.principal_point), list(camera.principal_point)]
            moved[0][to_field] += h
            moved[1][to_field] -= h
            plus, minus = (camera.replace(principal_point=tuple(pp)) for pp in moved)
        else:
            value = float(getattr(camera, field_name))
            h = step * (abs(value / to_field) if relative else 1.0)
            plus = camera.replace(**{field_name: value + h * to_field})
            minus = camera.replace(**{field_name: value - h * to_field})
        out[:, k] = (statures_from_camera_m(feet_px, heads_px, plus)
                     - statures_from_camera_m(feet_px, heads_px, minus)) / (2.0 * h)
    return out


def pixel_gradient_m(feet_px: np.ndarray, heads_px: np.ndarray, camera: Camera) -> np.ndarray:
    """(N, 4) m/px: derivatives of each pair's stature with respect to (foot u, foot v, head u, head v).

    feet_px, heads_px: (N, 2) px; central differences of :data:`_PIXEL_STEP_PX`.
    """
    feet = np.asarray(feet_px, dtype=np.float64)
    heads = np.asarray(heads_px, dtype=np.float64)
    out = np.zeros((len(feet), 4))
    for k in range(4):
        shift = np.zeros(2)
        shift[k % 2] = _PIXEL_STEP_PX
        if k < 2:
            plus, minus = (feet + shift, heads), (feet - shift, heads)
        else:
            plus, minus = (feet, heads + shift), (feet, heads - shift)
        out[:, k] = (statures_from_camera_m(*plus, camera) - statures_from_camera_m(*minus, camera)) / (2 * _PIXEL_STEP_PX)
    return out


def stature_design_effect(statures_m: np.ndarray, track_ids: np.ndarray, frame_index: np.ndarray | None) -> float:
    """How many consecutive pairs of a track one independent pair is worth (>= 1), pooled over the tracks.

    statures_m: (N,) m (NaN left out); track_ids: (N,) int (negative: untracked, left out); frame_index:
    (N,) int ordering each track in time (None: the pairs are taken as independent, 1). The integrated
    autocorrelation time ``1 + 2 sum_k rho_k`` of the statures' deviations from their track's median,
    summed while ``rho_k`` stays above 0.05, at most the mean track length: the calibration's rule
    (:func:`rotavat_cli.calibration.objective.design_effect`) on the statures.

    >>> one_track, frames = np.zeros(40, int), np.arange(40)
    >>> stature_design_effect(1.7 + 0.01 * (-1.0) ** frames, one_track, frames)  # no memory from frame to frame
    1.0
    >>> round(stature_design_effect(np.repeat([1.69, 1.71], 20), one_track, frames), 1)  # off one way, then the other
    15.1
    """
    s = np.asarray(statures_m, dtype=np.float64)
    ids = np.asarray(track_ids)
    keep = np.isfinite(s) & (ids >= 0)
    if frame_index is None or keep.sum() < 3:
        return 1.0
    s, ids, frames = s[keep], ids[keep].astype(np.int64), np.asarray(frame_index)[keep]
    order = np.lexsort((frames, ids))
    s, ids = s[order], ids[order]
    tracks = statures_by_track(s, ids)
    return autocorrelation_time(s - tracks.median_m[np.searchsorted(tracks.ids, ids)], ids)


def within_polygon(points_px: np.ndarray, polygon_px: np.ndarray, margin_px: float = 0.0) -> np.ndarray:
    """(P,) bool: each point (P, 2) px inside the convex polygon (V, 2) px (either orientation) or within
    ``margin_px`` of its boundary. A polygon of fewer than 3 vertices has no inside (only its margin).

    >>> square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    >>> within_polygon(np.array([[5.0, 5.0], [12.0, 5.0], [15.0, 5.0]]), square, 3.0).tolist()
    [True, True, False]
    """
    p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(polygon_px, dtype=np.float64).reshape(-1, 2)
    if len(v) == 0:
        return np.zeros(len(p), bool)
    a, b = v, np.roll(v, -1, axis=0)  # (V, 2) edges a -> b
    e = b - a
    rel = p[:, None, :] - a[None]  # (P, V, 2)
    cross = e[None, :, 0] * rel[..., 1] - e[None, :, 1] * rel[..., 0]
    inside = (np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1)) if len(v) >= 3 else np.zeros(len(p), bool)
    ee = np.maximum(np.sum(e * e, axis=-1), 1e-300)
    t = np.clip(np.sum(rel * e[None], axis=-1) / ee, 0.0, 1.0)
    dist = np.linalg.norm(rel - t[..., None] * e[None], axis=-1).min(axis=1)
    return inside | (dist <= margin_px)


def extrapolated_feet(feet_px: np.ndarray, camera: Camera, footprint_px: np.ndarray) -> np.ndarray:
    """(P,) bool: feet (P, 2) px outside the footprint (V, 2) px by more than :data:`FOOTPRINT_MARGIN_REL` of
    the image's larger side, or deeper or nearer than its vertices' depths by more than
    :data:`DEPTH_TOLERANCE_REL` (a vertex on or above the horizon: no far limit); a foot whose ray misses the
    ground (NaN depth) is extrapolated. An empty footprint: nobody (unknown, not inside)."""
    feet = np.asarray(feet_px, dtype=np.float64).reshape(-1, 2)
    poly = np.asarray(footprint_px, dtype=np.float64).reshape(-1, 2)
    if len(poly) == 0:
        return np.zeros(len(feet), bool)
    margin = FOOTPRINT_MARGIN_REL * max(camera.image_size)
    depth = camera.backproject_px_to_ground(feet)[:, 2]
    vertex_depth = camera.backproject_px_to_ground(poly)[:, 2]
    near = float(np.nanmin(vertex_depth)) if np.isfinite(vertex_depth).any() else 0.0
    far = float(np.nanmax(vertex_depth)) if np.isfinite(vertex_depth).all() else math.inf
    with np.errstate(invalid="ignore"):
        in_depth = (depth >= near / (1.0 + DEPTH_TOLERANCE_REL)) & (depth <= far * (1.0 + DEPTH_TOLERANCE_REL))
    return ~(within_polygon(feet, poly, margin) & in_depth)


@dataclass(frozen=True)
class StatureErrors:
    """Standard deviations of measured statures, per pair and per track (tracks in
    :func:`~.measure.statures_by_track`'s order), in metres.

    ids: (T,) track ids; std_m, std_camera_m, std_pixels_m: (T,) the track median's total sd and its camera
    and pixel parts (``std² = camera² + pixels²``; NaN for a track with no measured pair); extrapolated: (T,)
    bool; click_noise_px: (T,) the click noise each track's pixel part used; camera_cov_m2: (T, T) the camera
    part's covariance between tracks; pair_camera_m, pair_pixels_m: (N,) each pair's two parts;
    design_effect: consecutive pairs per independent one; camera_known: the camera had a covariance
    (else the camera part is 0 and unknown); footprint_known: the camera had a footprint (else nobody is
    extrapolated and that is unknown).
    """

    ids: np.ndarray
    std_m: np.ndarray
    std_camera_m: np.ndarray
    std_pixels_m: np.ndarray
    extrapolated: np.ndarray
    click_noise_px: np.ndarray
    camera_cov_m2: np.ndarray
    pair_camera_m: np.ndarray
    pair_pixels_m: np.ndarray
    design_effect: float
    camera_known: bool
    footprint_known: bool


def _fit_click_noise_px(fit: Mapping | None) -> float:
    """Click noise (px) implied by the calibration's ``rmse_px``: the head residual carries the head's and the
    foot's click on each of the residual's pixel axes (2 for ``full``, 1 for ``vertical``); NaN when absent."""
    rmse = fit.get("rmse_px") if isinstance(fit, Mapping) else None
    if not isinstance(rmse, (int, float)) or not math.isfinite(rmse) or rmse <= 0:
        return math.nan
    axes = 1 if fit.get("residual") == "vertical" else 2
    return float(rmse) / math.sqrt(2.0 * axes)


def _group_mean(values: np.ndarray, row: np.ndarray, n_rows: int) -> np.ndarray:
    """(T, ...) mean of the finite ``values`` (N, ...) in each of ``n_rows`` groups (``row`` (N,)); NaN when none."""
    values = values.reshape(len(values), -1)
    ok = np.all(np.isfinite(values), axis=1)
    sums = np.zeros((n_rows, values.shape[1]))
    np.add.at(sums, row[ok], values[ok])
    counts = np.bincount(row[ok], minlength=n_rows)
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / counts[:, None]


def stature_errors(feet_px: np.ndarray, heads_px: np.ndarray, statures_m: np.ndarray, track_ids: np.ndarray,
                   camera: Camera, fit: Mapping | None, frame_index: np.ndarray | None = None) -> StatureErrors:
    """Per-pair and per-track standard deviations of the statures (module docstring), and who is extrapolated.

    feet_px, heads_px: (N, 2) px; statures_m: (N,) m as measured with ``camera`` (NaN: not measured, e.g. a
    person cut by the border); track_ids: (N,) int (negative: untracked, pooled into one row, which gives
    no click noise to the others); fit: the camera's ``fit:`` block (``covariance``, ``footprint_px``,
    ``rmse_px``, ``residual``) or None; frame_index: (N,) int for the design effect.
    ValueError for a malformed ``fit.covariance``.
    """
    feet = np.asarray(feet_px, dtype=np.float64).reshape(-1, 2)
    heads = np.asarray(heads_px, dtype=np.float64).reshape(-1, 2)
    s = np.asarray(statures_m, dtype=np.float64)
    ids = np.asarray(track_ids).astype(np.int64)
    tracks = statures_by_track(s, ids)
    row = np.searchsorted(tracks.ids, ids)
    n_tracks = len(tracks)
    measured = np.isfinite(s)

    cov = CameraCovariance.from_fit(fit)
    if cov is not None and cov.names:
        J = np.where(measured[:, None], camera_jacobian_m(feet, heads, camera, cov.names), np.nan)  # (N, k)
        J_track = _group_mean(J, row, n_tracks)  # (T, k)
        with np.errstate(invalid="ignore"):
            pair_camera = np.sqrt(np.einsum("nk,kl,nl->n", J, cov.matrix, J))
            camera_cov = J_track @ cov.matrix @ J_track.T
    else:
        pair_camera, camera_cov = np.where(measured, 0.0, np.nan), np.zeros((n_tracks, n_tracks))
        camera_cov[~(tracks.pairs > 0)] = np.nan
    std_camera = np.sqrt(np.abs(np.diag(camera_cov)))  # |.|: a float-rounding -0 of a zero variance

    grad = np.linalg.norm(pixel_gradient_m(feet, heads, camera), axis=1)  # (N,) m per px of click noise
    grad = np.where(measured, grad, np.nan)
    rms_grad = np.sqrt(_group_mean(grad**2, row, n_tracks)[:, 0])  # (T,)
    with np.errstate(invalid="ignore", divide="ignore"):
        own = tracks.spread_m / _IQR_TO_SD / rms_grad
    scatter = (tracks.pairs >= MIN_SCATTER_PAIRS) & (tracks.ids >= 0) & np.isfinite(own)
    fallback = next((v for v in (float(np.median(own[scatter])) if scatter.any() else math.nan,
                                 _fit_click_noise_px(fit)) if math.isfinite(v)), CLICK_NOISE_PX)
    noise = np.where(scatter, own, fallback)
    deff = stature_design_effect(s, ids, frame_index)
    n_eff = np.maximum(tracks.pairs / deff, 1.0)
    efficiency = np.where(tracks.pairs <= 2, 1.0, _MEDIAN_EFFICIENCY)
    with np.errstate(invalid="ignore"):
        std_pixels = np.where(tracks.pairs > 0, efficiency * noise * rms_grad / np.sqrt(n_eff), np.nan)
    pair_pixels = noise[row] * grad

    footprint = _footprint_px(fit)
    median_feet = np.stack([_group_median(feet[measured, axis], row[measured], n_tracks) for axis in (0, 1)], axis=-1)
    extrapolated = extrapolated_feet(median_feet, camera, footprint) & (tracks.pairs > 0)
    return StatureErrors(tracks.ids, np.hypot(std_camera, std_pixels), std_camera, std_pixels, extrapolated, noise,
                         camera_cov, pair_camera, pair_pixels, deff, cov is not None and bool(cov.names),
                         len(footprint) > 0)


def _footprint_px(fit: Mapping | None) -> np.ndarray:
    """(V, 2) px: the ``fit.footprint_px`` polygon written by calibrate, (0, 2) when absent; ValueError when malformed."""
    block = fit.get("footprint_px") if isinstance(fit, Mapping) else None
    if block is None:
        return np.zeros((0, 2))
    polygon = None
    if isinstance(block, list) and len(block) <= FOOTPRINT_MAX_READ and all(
            isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v) for v in block):
        polygon = np.array(block, dtype=np.float64)  # checked first: numpy never expands a nest of YAML aliases
    if polygon is None or polygon.ndim != 2 or polygon.shape[1:] != (2,) or not np.isfinite(polygon).all():
        raise ValueError("fit.footprint_px must be a list of [u, v] pixel vertices")
    return polygon


def _group_median(values: np.ndarray, row: np.ndarray, n_rows: int) -> np.ndarray:
    """(T,) median of ``values`` (M,) in each of ``n_rows`` groups (``row`` (M,)); NaN for an empty group."""
    out = np.full(n_rows, np.nan)
    if len(values):
        kept = statures_by_track(values, row)
        out[kept.ids] = kept.median_m
    return out
