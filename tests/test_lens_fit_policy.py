"""calibrate --distortion from few clicks: a lens prior (priors.DISTORTION_PRIOR_SD) and a lens the pairs cannot
tell from none left out (fit.LENS_SIGNIFICANCE), so that fitting the lens does not make a pinhole camera worse."""

from __future__ import annotations

import numpy as np
import pytest

from rotavat_cli.bodies.measure import statures_from_camera_m
from rotavat_cli.calibration import fit_camera
from rotavat_cli.calibration.fit import LENS_SIGNIFICANCE
from rotavat_cli.geometry.camera import Camera

SIZE = (1280, 720)


def _walker(lam: float, n: int, seed: int, rows: tuple[float, float] = (330.0, 700.0)):
    """One walker's clicks (feet, heads (n, 2) px, 1.5 px noise) crossing the view in depth, through lens ``lam``."""
    rng = np.random.default_rng(seed)
    cam = Camera(SIZE, 1100.0, None, np.deg2rad(22.0), np.deg2rad(0.5), 4.5, distortion=lam)
    uv = np.column_stack([np.linspace(200, 1080, n), np.linspace(*rows, n)]) + rng.normal(0, 20, (n, 2))
    feet_cam = cam.backproject_px_to_ground(uv)
    feet, heads = cam.project(feet_cam), cam.project(feet_cam + 1.75 * cam.up_cam)
    return cam, feet + rng.normal(0, 1.5, feet.shape), heads + rng.normal(0, 1.5, heads.shape)


def test_a_lens_the_few_pairs_cannot_tell_from_none_is_left_out():
    _, feet, heads = _walker(0.0, 20, seed=2)
    plain = fit_camera(feet, heads, SIZE, person_height_m=1.75, person_height_sd_m=0.01)
    lensed = fit_camera(feet, heads, SIZE, person_height_m=1.75, person_height_sd_m=0.01, distortion=True)
    assert lensed.camera.distortion == 0.0 and lensed.fixed["distortion"] == "not significant"
    assert any(n.startswith("lens not applied: the pairs suggest a division coefficient") for n in lensed.notes)
    assert lensed.camera.matches(plain.camera)  # the fit without the lens, exactly


def test_a_lens_the_pairs_determine_is_kept():
    truth, feet, heads = _walker(-0.2, 300, seed=3)
    lensed = fit_camera(feet, heads, SIZE, person_height_m=1.75, person_height_sd_m=0.01, distortion=True)
    assert lensed.camera.distortion == pytest.approx(-0.2, abs=0.03)
    assert abs(lensed.distortion) > LENS_SIGNIFICANCE * lensed.std["distortion"]
    plain = fit_camera(feet, heads, SIZE, person_height_m=1.75, person_height_sd_m=0.01)
    errors = [np.nanmean(np.abs(statures_from_camera_m(feet, heads, r.camera) - 1.75)) for r in (plain, lensed)]
    assert errors[1] < 0.5 * errors[0], errors
