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

from rotavat_cli.geometry.camera import Camera

LOSS_SCALE_PX = 3.0  # the soft-L1 loss's scale: a few pixels, the clicks' noise
MISS_PX = 1e4  # the residual of a foot the model cannot put on the ground (at or above the horizon)
_GRID = (np.linspace(0.4, 3.0, 9), np.radians(np.linspace(0.0, 60.0, 13)), np.geomspace(1.0, 20.0, 13))


def li2015_camera(image_size: tuple[int, int], params: np.ndarray) -> Camera:
    """The paper's camera of ``params`` (log focal/W, tilt rad, log height m): roll 0, principal point at the centre."""
    W, H = image_size
    return Camera(image_size, float(math.exp(params[0]) * W), (W / 2.0, H / 2.0), float(params[1]), 0.0,
                  float(math.exp(params[2])))


def head_residuals_px(params: np.ndarray, feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
                      stature_m: float) -> np.ndarray:
    """(2N,) predicted minus observed head pixels of the feet ``feet_px`` (N, 2) for a person of ``stature_m``;
    :data:`MISS_PX` for a foot at or above the model's horizon."""
    cam = li2015_camera(image_size, params)
    ground = cam.backproject_px_to_ground(feet_px)
    ok = np.all(np.isfinite(ground), axis=1) & (ground[:, 2] > 0)
    head = np.full_like(heads_px, MISS_PX)
    if ok.any():
        head[ok] = cam.project(ground[ok] + stature_m * cam.up_cam)
    res = head - heads_px
    res[~ok | ~np.all(np.isfinite(res), axis=1)] = MISS_PX
    return res.ravel()


def fit_li2015(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int], stature_m: float) -> Camera:
    """The paper's camera from one person's foot and head clicks (N, 2) px of known ``stature_m``: the best cell of
    a coarse grid over the focal (0.4-3 x W), tilt (0-60 deg) and height (1-20 m), refined by the regression."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)

    def cost(p: np.ndarray) -> float:
        r = head_residuals_px(p, feet, heads, image_size, stature_m).reshape(-1, 2)
        d2 = np.sum(r * r, axis=1) / LOSS_SCALE_PX ** 2
        return float(np.sum(2.0 * (np.sqrt(1.0 + d2) - 1.0)))  # scipy's soft_l1

    cells = [np.array([math.log(f), t, math.log(h)]) for f in _GRID[0] for t in _GRID[1] for h in _GRID[2]]
    start = min(cells, key=cost)
    fit = least_squares(head_residuals_px, start, args=(feet, heads, image_size, stature_m), loss="soft_l1",
                        f_scale=LOSS_SCALE_PX, method="trf")
    return li2015_camera(image_size, fit.x)
