"""A calibration through a known lens: the pairs undistorted first, the fitted camera given the lens.

Where the lens is known (a lens profile, or the scene's straight lines: :mod:`.plumb_lines`) it is
not fitted from the people: a few tens of clicks of one reference person cannot tell a barrel lens
from a longer focal and a steeper pitch (docs/calibration.md). The foot and crown pixels are mapped
to the pinhole image (:func:`rotavat_cli.geometry.lens.undistort_px`, about the principal point the
fit uses), the pinhole camera is fitted there exactly as without a lens, and the result's camera
carries the lens (``Camera.distortion``), so that ``measure``, ``align``, ``eval`` and ``view``
apply it. The lens's own sd enters the reported std as an assumed-but-unknown quantity (the
calibration's ``distortion_sd``), and camera.yaml's ``fit.lens`` says where it came from.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..geometry.lens import distort_px, lens_radius_px, undistort_px
from .options import CalibrateOptions

__all__ = ["fit_through_lens", "lens_principal_point"]


def lens_principal_point(options: CalibrateOptions, image_size: tuple[int, int]) -> tuple[float, float]:
    """The lens's centre (px): the fit's principal point, the given one or the image centre."""
    if options.principal_point is not None:
        return tuple(options.principal_point)
    return image_size[0] / 2.0, image_size[1] / 2.0


def fit_through_lens(fit: Callable, feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
                     options: CalibrateOptions, **kwargs):
    """``fit`` (:func:`.fit.fit_camera`) of pairs (N, 2) px seen through ``options.lens_distortion``: undistorted
    first, fitted as a pinhole, and the result's camera given the lens; its footprint is mapped back to image
    pixels, and its fit block gains ``lens`` (from, distortion, sd) and a note."""
    lam = float(options.lens_distortion)
    pp = lens_principal_point(options, image_size)
    radius = lens_radius_px(image_size)
    feet_u = undistort_px(np.asarray(feet_px, dtype=np.float64), lam, pp, radius)
    heads_u = undistort_px(np.asarray(heads_px, dtype=np.float64), lam, pp, radius)
    sd = options.distortion_sd if options.lens_distortion_sd is None else options.lens_distortion_sd
    pinhole = options.replace(lens_distortion=None, lens_distortion_sd=None, lens_source=None, distortion_sd=sd,
                              distortion=False)  # the pairs are undistorted: no lens is fitted to them again
    result = fit(feet_u, heads_u, image_size, pinhole, **kwargs)
    source = options.lens_source or "given"
    footprint = result.footprint_px
    if len(footprint):
        footprint = distort_px(footprint, lam, pp, radius)
    note = (f"lens {source}: division coefficient {lam:+.4f} (sd {sd:.4f}); the pairs were undistorted before the "
            "fit and the camera carries the lens")
    return replace(result, camera=result.camera.replace(distortion=lam), footprint_px=footprint,
                   lens={"from": source, "distortion": lam, "sd": float(sd)},
                   fixed={**result.fixed, "distortion": source}, notes=result.notes + (note,))
