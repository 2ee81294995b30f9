"""The calibration of Li et al. 2015 ("A simplified nonlinear regression method for human height estimation in video
surveillance", EURASIP JIVP), as a baseline for ``bench_reference.py``: the paper on the same protocol and clicks.

Their model keeps three parameters of a surveillance camera, the focal length, the tilt and the camera's height
(no roll, no pan, the principal point at the image centre, no lens), and estimates them by nonlinear regression from
the head and foot points of a walking person of known stature: each foot pixel is put on the ground, the crown
``stature`` above it is projected, and the predicted head pixels are fitted to the observed ones. Here that
regression is ``scipy.optimize.least_squares`` over (log f, tilt, log height) from the best cell of a coarse grid,
with a soft-L1 loss of scale ``LOSS_SCALE_PX`` (the paper's real clicks carry no gross errors; this stand-in's do, and
a plain least squares would lose to them for a reason the paper does not share). A person's stature is then the
model's own: the crown's height above the foot's ground point along the vertical through it, as
``statures_from_camera_m`` computes it with the fitted camera (the same geometry with roll 0, principal point at the
centre and no lens).

Written from the paper's description (its abstract and model), not from its code.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from rotavat_cli.calibration.model import predict_heads_px
from rotavat_cli.geometry.camera import Camera

LOSS_SCALE_PX = 3.0  # the soft-L1 loss's scale: a few pixels, the clicks' noise
MISS_PX = 1e4  # the residual of a foot the model cannot put on the ground (at or above the horizon)
_GRID = np.meshgrid(np.log(np.linspace(0.4, 3.0, 9)), np.radians(np.linspace(0.0, 60.0, 13)),
                    np.log(np.geomspace(1.0, 20.0, 13)), indexing="ij")  # log focal/W, tilt rad, log height m


def li2015_camera(image_size: tuple[int, int], params: np.ndarray) -> Camera:
    """The paper's camera of ``params`` (log focal/W, tilt rad, log height m): roll 0, principal point at the centre."""
    W, H = image_size
    return Camera(image_size, float(math.exp(params[0]) * W), (W / 2.0, H / 2.0), float(params[1]), 0.0,
                  float(math.exp(params[2])))


def head_residuals_px(params: np.ndarray, feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
                      stature_m: float) -> np.ndarray:
    """(..., N, 2) predicted minus observed head pixels of the feet ``feet_px`` (N, 2) for a person of
    ``stature_m``, for parameter sets ``params`` (..., 3) (log focal/W, tilt rad, log height m; roll 0, principal
    point at the centre): rotavat's closed-form person model (``calibration.model.predict_heads_px``, the same
    geometry as the paper's); :data:`MISS_PX` for a foot at or above the horizon."""
    W, H = image_size
    p = np.asarray(params, dtype=np.float64)
    heads = predict_heads_px(feet_px, np.exp(p[..., 0]) * W, p[..., 1], 0.0, np.exp(p[..., 2]), (W / 2.0, H / 2.0),
                             stature_m)
    res = heads - heads_px
    return np.where(np.isfinite(res).all(axis=-1, keepdims=True), res, MISS_PX)


def _soft_l1_cost(res_px: np.ndarray) -> np.ndarray:
    """scipy's soft-L1 cost of residuals (..., N, 2) px at :data:`LOSS_SCALE_PX`, summed over the pairs -> (...)."""
    d2 = np.sum(res_px * res_px, axis=-1) / LOSS_SCALE_PX**2
    return np.sum(2.0 * (np.sqrt(1.0 + d2) - 1.0), axis=-1)


def fit_li2015(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int], stature_m: float) -> Camera:
    """The paper's camera from one person's foot and head clicks (N, 2) px of known ``stature_m``: the best cell of
    a coarse grid over the focal (0.4-3 x W), tilt (0-60 deg) and height (1-20 m), all cells at once, refined by the
    regression."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    cells = np.stack([g.ravel() for g in _GRID], axis=-1)
    start = cells[int(np.argmin(_soft_l1_cost(head_residuals_px(cells, feet, heads, image_size, stature_m))))]
    fit = least_squares(lambda p: head_residuals_px(p, feet, heads, image_size, stature_m).ravel(), start,
                        loss="soft_l1", f_scale=LOSS_SCALE_PX, method="trf")
    return li2015_camera(image_size, fit.x)
