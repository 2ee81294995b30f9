"""What a calibration saw and how sure it is, in the units camera.yaml reports: the footprint of its
feet and the covariance of its camera parameters (``fit.footprint_px``, ``fit.covariance``).

``rotavat measure`` reads both back (:mod:`rotavat_cli.bodies.stature_error`): the covariance gives
each measured stature the camera's part of its standard deviation, and a person whose feet stand
outside the footprint is measured by extrapolation.

>>> footprint_polygon_px(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 5.0], [0.0, 5.0], [4.0, 2.0]])).tolist()
[[0.0, 0.0], [10.0, 0.0], [10.0, 5.0], [0.0, 5.0]]
>>> footprint_polygon_px(np.array([[0.0, 0.0], [8.0, 0.0], [4.0, 0.0]])).tolist()  # collinear: a thin box
[[-2.0, -2.0], [10.0, -2.0], [10.0, 2.0], [-2.0, 2.0]]
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.camera_covariance import CameraCovariance
from .params import DISTORTION, FOCAL, HEIGHT, PITCH, ROLL

__all__ = ["FOOTPRINT_MAX_VERTICES", "FOOTPRINT_PAD_PX", "COVARIANCE_SLOTS", "footprint_polygon_px",
           "report_covariance"]

FOOTPRINT_MAX_VERTICES = 32  # a hull with more is thinned (the vertices that add the least area go first)
FOOTPRINT_PAD_PX = 2.0  # a degenerate footprint (one point, a segment) is thickened by this much each way (click noise)
_COLLINEAR_REL = 1e-9  # a hull whose area is below this fraction of its bounding box squared is a segment
# Camera slots of the covariance, with their report names (the camera's parameters; the box depth is the point
# model's, not the camera's, and measure does not use it).
COVARIANCE_SLOTS = {FOCAL: "focal_px", PITCH: "pitch_deg", ROLL: "roll_deg", HEIGHT: "height_m",
                    DISTORTION: "distortion"}


def footprint_polygon_px(feet_px: np.ndarray) -> np.ndarray:
    """The image region a calibration's feet covered: their convex hull, counter-clockwise in the image's
    (u right, v down) axes as drawn, at most :data:`FOOTPRINT_MAX_VERTICES` vertices.

    feet_px: (N, 2) px, the inliers' foot pixels (non-finite rows ignored). Returns (V, 2) float64 px;
    (0, 2) for no foot. Fewer than 3 distinct points, or all on one line: the box of the points
    padded by :data:`FOOTPRINT_PAD_PX` (a square around one point, a thin rectangle along a segment,
    its sides along the image axes when the segment is, else the segment's own axes).
    """
    pts = np.asarray(feet_px, dtype=np.float64).reshape(-1, 2)
    pts = np.unique(pts[np.all(np.isfinite(pts), axis=1)], axis=0)
    if len(pts) == 0:
        return np.zeros((0, 2))
    centre = pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(pts - centre, full_matrices=False)
    extent = float(np.ptp(pts, axis=0).max())
    if len(pts) < 3 or len(sv) < 2 or sv[1] <= _COLLINEAR_REL * max(extent, 1.0) * math.sqrt(len(pts)):
        return _padded_box(pts, centre, vt)
    from scipy.spatial import ConvexHull  # lazy: scipy's import costs ~0.1 s, only calibrate needs it here

    try:
        hull = pts[ConvexHull(pts).vertices]  # counter-clockwise in (u, v)
    except RuntimeError:  # scipy's QhullError: nearly collinear after all
        return _padded_box(pts, centre, vt)
    return _thinned(hull, FOOTPRINT_MAX_VERTICES)


def _padded_box(pts: np.ndarray, centre: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(4, 2) box around collinear points ``pts`` (M, 2), along their principal ``axes`` (2, 2) (the image
    axes when the points are one point or lie along one), padded by FOOTPRINT_PAD_PX."""
    along = axes[0] if len(pts) > 1 else np.array([1.0, 0.0])
    if np.isclose(abs(along[0]), 1.0) or np.isclose(abs(along[1]), 1.0):
        along = np.array([1.0, 0.0])
    across = np.array([-along[1], along[0]])
    t = (pts - centre) @ along
    lo, hi = float(t.min()) - FOOTPRINT_PAD_PX, float(t.max()) + FOOTPRINT_PAD_PX
    p = FOOTPRINT_PAD_PX
    return np.array([centre + a * along + b * across for a, b in ((lo, -p), (hi, -p), (hi, p), (lo, p))])


def _thinned(polygon: np.ndarray, max_vertices: int) -> np.ndarray:
    """A convex polygon (V, 2) with its vertices dropped, smallest triangle first (Visvalingam), down to
    ``max_vertices``: the dropped vertices are the ones that add the least area (a nearly straight edge)."""
    poly = polygon
    while len(poly) > max_vertices:
        prev, nxt = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
        a, b = poly - prev, nxt - prev
        area = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / 2.0
        poly = np.delete(poly, int(np.argmin(area)), axis=0)
    return poly


# Assumed quantities a stature measured with the camera depends on directly (the camera holds them), with their
# report names and the sign of their error's covariance with the fit's shift (uncertainty.covariances' ``shifts``):
# the principal point is moved up by its sd there (+), the lens's undistortion coefficient down (-).
ASSUMED_CAMERA_PARTS = {"cx": ("cx_px", 1.0), "cy": ("cy_px", 1.0), "distortion": ("distortion", -1.0)}


def report_covariance(params: np.ndarray, cov: np.ndarray, free: np.ndarray, held: dict[int, float] | None = None,
                      height_given: bool = False, shifts: dict | None = None) -> CameraCovariance:
    """The camera parameters' covariance in report units (px, deg, deg, m, 1), over the estimated ones only.

    params: (6,) the fit (:mod:`.params`; focal px, height m at the fit's own scale); cov: (6, 6) over the
    internal parameters (log focal, pitch rad, roll rad, log height, distortion, box depth; zero rows for
    fixed slots: :func:`.uncertainty.covariances`); free: (6,) bool; held: slots held at their prior's
    median with the prior's sd (internal units): their variance is the prior's, their covariance with
    the others the shift the fit makes when the held value moves by that sd (``shifts``; 0 without it: a
    focal held at the lens prior moves the pitch and height with it, and a stature measured with the
    camera depends on all three, largely cancelling); height_given: the
    camera height was given, so it is not estimated (the angles' covariance is their marginal: the
    given height fixes the scale, the fit's own log height only carried the stature's).
    shifts: the assumed quantities' parameter shifts and sds (:func:`.uncertainty.covariances`): the principal
    point (``cx_px``, ``cy_px``) and an unfitted lens (``distortion``) join the names, with their sd as variance
    and their covariance with the parameters they moved. A stature measured with the camera depends on them
    directly too, and the two effects largely cancel (an off-centre principal point tilts the fitted camera the
    way that keeps the people's pixels): without them its std came out about 2.5x its error.
    Returns the :class:`CameraCovariance` of those (k may be 0: nothing estimated).
    """
    held = held or {}
    slots = [s for s in COVARIANCE_SLOTS if (free[s] or s in held) and not (s == HEIGHT and height_given)]
    unit = {FOCAL: float(params[FOCAL]), PITCH: math.degrees(1.0), ROLL: math.degrees(1.0),
            HEIGHT: float(params[HEIGHT]), DISTORTION: 1.0}  # d(report) / d(internal)
    scale = np.array([unit[s] for s in slots])
    matrix = np.array(cov, dtype=np.float64)[np.ix_(slots, slots)] * np.outer(scale, scale)
    for k, s in enumerate(slots):
        if s in held:  # the prior's variance; with the others, what moving it by its sd does to them (``shifts``)
            moved = shifts.get(s) if shifts else None
            cross = 0.0 if moved is None else np.asarray(moved[0], dtype=np.float64)[slots] * scale * scale[k] * held[s]
            matrix[k, :] = matrix[:, k] = cross
            matrix[k, k] = (scale[k] * held[s]) ** 2
    names = [COVARIANCE_SLOTS[s] for s in slots]
    for key, (name, sign) in ASSUMED_CAMERA_PARTS.items():
        if not shifts or key not in shifts or name in names:
            continue
        shift, sd = shifts[key]
        cross = np.zeros(len(names))  # two assumed quantities are independent of each other
        cross[:len(slots)] = sign * sd * np.asarray(shift, dtype=np.float64)[slots] * scale
        grown = np.zeros((len(names) + 1, len(names) + 1))
        grown[:-1, :-1] = matrix
        grown[-1, :-1] = grown[:-1, -1] = cross
        grown[-1, -1] = sd * sd
        matrix, names = grown, names + [name]
    return CameraCovariance(tuple(names), matrix)
