"""People's statures measured from a calibrated static camera (single-view metrology).

A person is an upright vertical standing on the ground: the foot (mid-sole) pixel, back-projected
onto the ground, gives the vertical's foot ``G`` (camera frame, metres); the stature is the height
``s`` of the point ``G + s n`` (``n`` world up) that best explains the head (crown) pixel. The
image of the vertical is a straight image line through the foot pixel and the vertical vanishing
point; the head pixel is projected orthogonally onto that line (the nearest point of the image of
the vertical) and the 1D projective map ``s -> pixel`` along the line is inverted in closed form.

In homogeneous pixels the vertical is ``a + s b`` with ``a = K G`` and ``b = K n`` (so ``a_z`` is
the foot's depth, ``b_z`` the depth gained per metre of height). Its image line passes through the
foot pixel ``F = a_xy / a_z`` with direction ``d = a_z b_xy - b_z a_xy``. With the head pixel ``H``
and ``t = (H - F).d / |d|^2`` (the orthogonal projection ``F + t d``):

    s = a_z^2 t / (1 - a_z b_z t),     depth of the head = a_z / (1 - a_z b_z t),

so the head is in front of the camera exactly when ``1 - a_z b_z t > 0``.

Per person: :func:`statures_by_track` pools a track's measurements into its median and a robust
spread (half the interquartile range).

**Where a stature comes from.** Every stature rotavat reports (align's people.csv and summary,
measure, eval, view) is only as metric as the camera's scale: the camera height. When it was given,
or the calibration was tied to a reference person of known stature, the statures are measured;
when it was estimated from the people with the default stature prior, their mean is that prior
given back (1.70 m) and only their differences are measured. :func:`scale_source` reads which
from the camera's ``fit:`` block (``fit.scale_from``, written by calibrate) and
:func:`stature_provenance` says it in words.

Examples
--------
>>> cam = Camera((640, 480), 500.0, None, np.deg2rad(30.0), np.deg2rad(2.0), 5.0)
>>> statures_m = np.array([1.62, 1.70, 1.85])
>>> feet_cam = cam.backproject_px_to_ground(np.array([[100.0, 300.0], [320.0, 400.0], [500.0, 350.0]]))
>>> feet_px, heads_px = cam.project(feet_cam), cam.project(feet_cam + statures_m[:, None] * cam.up_cam)
>>> bool(np.allclose(statures_from_camera_m(feet_px, heads_px, cam), statures_m, rtol=0, atol=1e-9))
True
>>> statures_by_track(np.array([1.70, 1.72, 1.80, 1.60]), np.array([7, 7, 7, 3])).median_m.tolist()
[1.6, 1.72]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera

__all__ = ["statures_from_camera_m", "TrackStatures", "statures_by_track", "SCALE_SOURCES", "REFERENCE_SD_MAX_M",
           "scale_source", "source_words", "stature_provenance"]

# Where a camera's scale (hence every stature measured with it) comes from: fit.scale_from, and people.csv's column.
SCALE_SOURCES = ("camera_height", "reference", "given_camera", "prior")
# A calibration from chosen people (--track) whose stature prior is this narrow measures against them (a reference
# person measured with a tape: +-1-2 cm); the default prior's sd is 7 cm, a population's.
REFERENCE_SD_MAX_M = 0.03

_EPS = 1e-12  # a vertical whose image is a point (|d|^2 below this; the camera looks straight up or down it)


def statures_from_camera_m(feet_px: np.ndarray, heads_px: np.ndarray, camera: Camera) -> np.ndarray:
    """Stature (m) of each upright person, from its foot and head pixels and a known camera.

    feet_px, heads_px: (..., 2) px of the image, mid-sole and crown (broadcast together); camera: the
    static camera. Its lens distortion (``camera.distortion``) is removed from both pixels first
    (:meth:`Camera.undistort_px`); the closed form then runs on the pinhole's pixels, where the
    vertical's image is a straight line. Returns (...) float64 metres: the height above the ground of
    the point of the person's vertical whose (undistorted) pixel is nearest to the head's (module
    docstring). NaN where the foot ray misses the ground (foot on or above the horizon), where the
    nearest point is behind the camera or at the vertical vanishing point, or where a pixel is not
    finite or beyond the lens's reach.

    >>> lens = Camera((640, 480), 500.0, None, np.deg2rad(30.0), 0.0, 5.0, distortion=-0.25)
    >>> feet_cam = lens.backproject_px_to_ground(np.array([[20.0, 460.0], [600.0, 300.0]]))
    >>> feet_px, heads_px = lens.project(feet_cam), lens.project(feet_cam + 1.75 * lens.up_cam)
    >>> statures_from_camera_m(feet_px, heads_px, lens).round(9).tolist()
    [1.75, 1.75]
    """
    feet = np.asarray(feet_px, dtype=np.float64)
    heads = np.asarray(heads_px, dtype=np.float64)
    if feet.shape[-1:] != (2,) or heads.shape[-1:] != (2,):
        raise ValueError(f"feet_px and heads_px must be (..., 2) pixels, got {feet.shape} and {heads.shape}")
    feet, heads = np.broadcast_arrays(camera.undistort_px(feet), camera.undistort_px(heads))
    camera = camera.pinhole  # the pixels are the pinhole's now
    a = camera.backproject_px_to_ground(feet) @ camera.K.T  # (..., 3) homogeneous foot pixel; a_z = depth, m
    b = camera.K @ camera.up_cam  # (3,) homogeneous image of world up (the vertical vanishing point)
    a_z = a[..., 2]
    d = a_z[..., None] * b[:2] - b[2] * a[..., :2]  # (..., 2) direction of the vertical's image line
    dd = np.sum(d * d, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.sum((heads - a[..., :2] / a_z[..., None]) * d, axis=-1) / dd
        denom = 1.0 - a_z * b[2] * t  # = foot depth / head depth
        s = a_z * a_z * t / denom
    return np.where((dd > _EPS) & (denom > 0.0), s, np.nan)


@dataclass(frozen=True)
class TrackStatures:
    """Statures pooled per track, one entry per track id (ascending).

    ids: (T,) int track ids; pairs: (T,) int finite measurements; median_m: (T,) m; spread_m: (T,) m,
    half the interquartile range (NaN where a track has no finite measurement).
    """

    ids: np.ndarray
    pairs: np.ndarray
    median_m: np.ndarray
    spread_m: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)

    def rows(self) -> list[dict]:
        """One plain dict per track: id, pairs, median_m, spread_m."""
        return [{"id": int(i), "pairs": int(n), "median_m": float(m), "spread_m": float(q)}
                for i, n, m, q in zip(self.ids, self.pairs, self.median_m, self.spread_m)]


def statures_by_track(statures_m: np.ndarray, track_ids: np.ndarray) -> TrackStatures:
    """Median and spread of each track's statures; NaN statures are left out.

    statures_m: (N,) m; track_ids: (N,) int. The spread is half the interquartile range
    (``(q75 - q25) / 2``, quantiles interpolated linearly as ``np.quantile`` does): robust to the
    frames where a person bends, sits or is cut by the image border; for normal noise it is about
    0.67 standard deviations. A track whose measurements are all NaN keeps its row, with 0 pairs
    and NaN median and spread.

    >>> res = statures_by_track(np.array([1.80, 1.70, np.nan, 1.60, 1.75, 1.65, 1.70]), np.array([2, 2, 2, 5, 5, 5, 5]))
    >>> res.ids.tolist(), res.pairs.tolist(), res.median_m.round(6).tolist(), res.spread_m.round(6).tolist()
    ([2, 5], [2, 4], [1.75, 1.675], [0.025, 0.0375])
    """
    values = np.asarray(statures_m, dtype=np.float64)
    ids = np.asarray(track_ids)
    if values.ndim != 1 or ids.shape != values.shape:
        raise ValueError(f"statures_m and track_ids must be (N,) alike, got {values.shape} and {ids.shape}")
    if ids.size and not np.issubdtype(ids.dtype, np.integer):
        raise ValueError(f"track_ids must be integers, got {ids.dtype}")
    ids = ids.astype(np.int64)
    all_ids = np.unique(ids)
    finite = np.isfinite(values)
    order = np.lexsort((values[finite], ids[finite]))  # by track, then by stature
    sorted_ids, sorted_values = ids[finite][order], values[finite][order]
    kept, start, count = np.unique(sorted_ids, return_index=True, return_counts=True)
    q25, q50, q75 = (_sorted_group_quantile(sorted_values, start, count, q) for q in (0.25, 0.5, 0.75))
    row = np.searchsorted(all_ids, kept)
    pairs = np.zeros(len(all_ids), np.int64)
    median, spread = np.full(len(all_ids), np.nan), np.full(len(all_ids), np.nan)
    pairs[row], median[row], spread[row] = count, q50, (q75 - q25) / 2.0
    return TrackStatures(all_ids, pairs, median, spread)


def _sorted_group_quantile(values: np.ndarray, start: np.ndarray, count: np.ndarray, q: float) -> np.ndarray:
    """Quantile ``q`` (G,) of each group of ``values`` (sorted within groups; group g at
    ``start[g]:start[g] + count[g]``, count >= 1), interpolated linearly as ``np.quantile``."""
    position = q * (count - 1)
    lo = np.floor(position).astype(np.int64)
    hi = np.minimum(lo + 1, count - 1)
    frac = position - lo
    low, high = values[start + lo], values[start + hi]
    return low + frac * (high - low)


def scale_source(fit: Mapping | None) -> str:
    """Where the scale of a camera with this ``fit:`` block comes from (:data:`SCALE_SOURCES`).

    ``fit.scale_from`` when calibrate wrote it; else a given camera height (``fit.fixed.height_m``),
    else the prior; a camera without a fit block (ground truth, written by hand) is a given camera.

    >>> scale_source(None), scale_source({"fixed": {"height_m": "given"}}), scale_source({"method": "refine"})
    ('given_camera', 'camera_height', 'prior')
    """
    if not isinstance(fit, Mapping) or not fit:
        return "given_camera"
    if fit.get("scale_from") in SCALE_SOURCES:
        return str(fit["scale_from"])
    fixed = fit.get("fixed") if isinstance(fit.get("fixed"), Mapping) else {}
    return "camera_height" if fixed.get("height_m") == "given" else "prior"


def source_words(source: str, prior_m: float = 1.70) -> str:
    """A few words saying whether statures measured with a camera whose scale comes from ``source``
    (:data:`SCALE_SOURCES`) are measured or the stature prior ``prior_m`` given back.

    >>> source_words("prior")
    'the 1.70 m stature prior given back: the camera height came from the people, so only their differences are measured'
    """
    if source == "camera_height":
        return "measured: the camera height was given"
    if source == "reference":
        return f"measured: the camera was calibrated against a reference person of {prior_m:.2f} m"
    if source == "given_camera":
        return "measured with a given camera (no fit: block)"
    return (f"the {prior_m:.2f} m stature prior given back: the camera height came from the people, so only their "
            "differences are measured")


def stature_provenance(fit: Mapping | None) -> str:
    """:func:`source_words` for a camera with this ``fit:`` block (its stature prior: ``fit.person_height_m``).

    >>> stature_provenance({"scale_from": "reference", "person_height_m": 1.82})
    'measured: the camera was calibrated against a reference person of 1.82 m'
    """
    prior = float(fit.get("person_height_m", 1.70)) if isinstance(fit, Mapping) else 1.70
    return source_words(scale_source(fit), prior)
