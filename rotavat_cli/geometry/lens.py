"""A camera's lens distortion: the one-parameter division model about the principal point.

With ``p`` a pixel measured from the principal point (px) and ``R`` the image half-diagonal
(:func:`lens_radius_px`, px), a distorted pixel ``p_d`` (the one in the image) and its undistorted
(pinhole) pixel ``p_u`` are

    p_u = p_d / (1 + lam |p_d|^2 / R^2)                                     (undistort)
    p_d = 2 p_u / (1 + sqrt(1 - 4 lam |p_u|^2 / R^2))                        (distort: its exact inverse)

``lam`` (the ``distortion`` coefficient, dimensionless) is about the relative displacement at the
image corner: negative for barrel distortion, 0 for a pinhole. The inverse takes the root that is
continuous at ``lam = 0`` (the branch on which the radius grows with the radius); where it has
none (``lam > 0`` and ``|p_u| > R / (2 sqrt(lam))``) the distorted pixel is NaN, and so is an
undistorted pixel whose denominator ``1 + lam |p_d|^2 / R^2`` is not positive (``lam < 0`` and
``|p_d| >= R / sqrt(-lam)``: beyond the image corners for ``|lam| <= 0.5``). Conventions:
docs/conventions.md (camera.yaml's ``distortion``) and docs/calibration.md.

Every function broadcasts the coefficient (scalar or ``(...)``) over the points' leading dimensions.

>>> pp, R = (320.0, 240.0), lens_radius_px((640, 480))
>>> R
400.0
>>> corner = np.array([640.0, 480.0])  # 400 px from the principal point: |p_d| = R
>>> undistort_px(corner, -0.25, pp, R).tolist()   # barrel: the pinhole pixel lies farther out
[746.6666666666667, 560.0]
>>> bool(np.allclose(distort_px(undistort_px(corner, -0.25, pp, R), -0.25, pp, R), corner, rtol=0, atol=1e-12))
True
>>> distort_px(np.array([2000.0, 240.0]), 0.2, pp, R).tolist()   # beyond R / (2 sqrt(0.2)) = 447 px: no inverse
[nan, nan]
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MAX_DISTORTION", "lens_radius_px", "undistort_rel_px", "undistort_px", "distort_scale", "distort_rel_px", "distort_px",
           "check_distortion"]

# The largest |lam| a camera may carry: the calibration's search bound (calibration/params.py), a corner moved by half
# the half-diagonal; real lenses move it by a few percent.
MAX_DISTORTION = 0.5


def lens_radius_px(image_size: tuple[int, int]) -> float:
    """The division model's unit radius ``R`` (px): half the diagonal of an image ``(W, H)`` px.

    >>> lens_radius_px((1920, 1080))
    1101.4535850411492
    """
    width, height = (float(v) for v in image_size)
    return 0.5 * math.hypot(width, height)


def check_distortion(distortion: float, key: str = "distortion") -> float:
    """``distortion`` as a float, or ValueError naming ``key`` when it is not finite or beyond +-:data:`MAX_DISTORTION`.

    >>> check_distortion(-0.1)
    -0.1
    >>> check_distortion(0.9)
    Traceback (most recent call last):
    ValueError: key 'distortion' 0.9 is beyond +-0.5 (division-model coefficient)
    """
    try:
        value = float(distortion)
    except (TypeError, ValueError):
        raise ValueError(f"key '{key}' must be a number, got {distortion!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"key '{key}' must be finite, got {value}")
    if abs(value) > MAX_DISTORTION:
        raise ValueError(f"key '{key}' {value:g} is beyond +-{MAX_DISTORTION:g} (division-model coefficient)")
    return value


def undistort_rel_px(points_rel_px: np.ndarray, distortion: np.ndarray | float, radius_px: float) -> np.ndarray:
    """The division model's formula on pixels about the principal point: ``p / (1 + lam |p|^2 / R^2)`` -> (..., 2).

    points_rel_px: (..., 2) px from the principal point; distortion: lam, scalar or broadcasting against the
    points' leading dimensions (``(Q, 1)`` parameter sets against ``(N, 2)`` points give ``(Q, N, 2)``);
    radius_px: R. No domain check (the calibration's model evaluates it anywhere); :func:`undistort_px` has one.

    >>> undistort_rel_px(np.array([[400.0, 0.0], [0.0, 200.0]]), np.array([[0.0], [-0.2]]), 400.0).tolist()
    [[[400.0, 0.0], [0.0, 200.0]], [[500.0, 0.0], [0.0, 210.5263157894737]]]
    """
    p = np.asarray(points_rel_px, dtype=np.float64)
    lam = np.asarray(distortion, dtype=np.float64)[..., None]
    return p / (1.0 + lam * (np.sum(p * p, axis=-1, keepdims=True) / radius_px**2))


def undistort_px(points_px: np.ndarray, distortion: np.ndarray | float, principal_point: np.ndarray | tuple,
                 radius_px: float) -> np.ndarray:
    """Distorted (image) pixels (..., 2) -> undistorted (pinhole) pixels (..., 2), px.

    distortion: lam (module docstring), scalar or (...); principal_point: (cx, cy) px; radius_px: R
    (:func:`lens_radius_px`). NaN where ``1 + lam |p_d|^2 / R^2 <= 0`` (no pinhole pixel) or a pixel is not finite.
    """
    p = np.asarray(points_px, dtype=np.float64)
    pp = np.asarray(principal_point, dtype=np.float64)
    rel = p - pp
    lam = np.asarray(distortion, dtype=np.float64)
    denom = 1.0 + lam * (np.sum(rel * rel, axis=-1) / radius_px**2)
    return np.where((denom > 0.0)[..., None], pp + undistort_rel_px(rel, lam, radius_px), np.nan)


def distort_scale(points_rel_px: np.ndarray, distortion: np.ndarray | float, radius_px: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The distortion's scale ``s = 2 / (1 + sqrt(1 - 4 lam rho))`` of pixels about the principal point (``p_d = s
    p_u``, ``rho = |p_u|^2 / R^2``) and its derivative ``ds/drho = s^2 lam / sqrt(1 - 4 lam rho)``, each (...):
    NaN where no real inverse exists. Broadcasting as :func:`undistort_rel_px`."""
    p = np.asarray(points_rel_px, dtype=np.float64)
    lam = np.asarray(distortion, dtype=np.float64)
    disc = 1.0 - 4.0 * lam * (np.sum(p * p, axis=-1) / radius_px**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        root = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
        scale = 2.0 / (1.0 + root)
        return scale, scale * scale * lam / root


def distort_rel_px(points_rel_px: np.ndarray, distortion: np.ndarray | float, radius_px: float) -> np.ndarray:
    """:func:`undistort_rel_px`'s exact inverse on pixels about the principal point -> (..., 2): ``p_d = s(p_u) p_u``
    (:func:`distort_scale`), NaN where it has none. Broadcasting as :func:`undistort_rel_px`.

    >>> distort_rel_px(undistort_rel_px(np.array([[400.0, 0.0]]), np.array([[-0.2]]), 400.0), np.array([[-0.2]]),
    ...                400.0).round(9).tolist()
    [[[400.0, 0.0]]]
    """
    p = np.asarray(points_rel_px, dtype=np.float64)
    return p * distort_scale(p, distortion, radius_px)[0][..., None]


def distort_px(points_px: np.ndarray, distortion: np.ndarray | float, principal_point: np.ndarray | tuple,
               radius_px: float) -> np.ndarray:
    """Undistorted (pinhole) pixels (..., 2) -> distorted (image) pixels (..., 2), px: :func:`undistort_px`'s
    exact inverse in closed form, ``p_d = 2 p_u / (1 + sqrt(1 - 4 lam |p_u|^2 / R^2))`` about the principal point.

    distortion: lam, scalar or (...); principal_point: (cx, cy) px; radius_px: R. NaN where no real inverse
    exists (``4 lam |p_u|^2 / R^2 > 1``, only for lam > 0) or a pixel is not finite.

    >>> distort_px(np.array([[720.0, 240.0]]), -0.25, (320.0, 240.0), 400.0).tolist()   # |p_u| = R: pulled in
    [[651.3708498984761, 240.0]]
    """
    pp = np.asarray(principal_point, dtype=np.float64)
    return pp + distort_rel_px(np.asarray(points_px, dtype=np.float64) - pp, distortion, radius_px)
