"""The few-pairs policy of the calibration (issue 35, point 3; fit._few_pairs_policy): with fewer than
FEW_PAIRS usable pairs a soft robust loss instead of hard rejection, and the roll held near 0 by the
mounting prior when the pairs cannot determine it; every decision in the fit's notes.
benchmarks/bench_reference.py measures what it buys on one-reference calibrations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rotavat_cli.bodies.measure import statures_from_camera_m
from rotavat_cli.calibration import CalibrateOptions, fit_camera
from rotavat_cli.calibration.priors import MOUNTED_ROLL_SD_DEG
from rotavat_cli.calibration.refine import FEW_PAIRS
from rotavat_cli.geometry.camera import Camera

CAMERA = Camera((1280, 720), 1400.0, (643.0, 357.0), math.radians(22.0), math.radians(1.2), 4.0)


def walker_px(rng: np.random.Generator, camera: Camera, stature_m: float, n: int, gross: int = 0
              ) -> tuple[np.ndarray, np.ndarray]:
    """(feet, heads) (n, 2) px of one person walking away and back across the ground (world x -3..3 m, depth
    7..16 m): 1.75 px click noise, the crown off the vertical by a lean (1.5 cm) and sway (2 cm), and
    ``gross`` head clicks moved 25 px."""
    depth = np.concatenate([np.linspace(7.0, 16.0, n // 2), np.linspace(16.0, 8.0, n - n // 2)])
    x = np.linspace(-3.0, 3.0, n) + rng.normal(0, 0.3, n)
    ground = np.column_stack([x, np.zeros(n), -depth])
    offset = rng.normal(0, 0.015, 2) + rng.normal(0, 0.02, (n, 2))
    crown = ground + np.column_stack([offset[:, 0], np.full(n, stature_m), offset[:, 1]])
    feet, heads = (camera.project(camera.cam_from_world(p)) + rng.normal(0, 1.75, (n, 2)) for p in (ground, crown))
    heads[rng.choice(n, gross, replace=False)] += (18.0, -18.0)
    return feet, heads


def fit_reference(feet, heads, stature_m: float, **changes):
    """The camera calibrated from one reference person of known stature (sd 1 cm), as bench_reference does."""
    options = CalibrateOptions(person_height_m=stature_m, person_height_sd_m=0.01, **{"few_pairs": True, **changes})
    return fit_camera(feet, heads, CAMERA.image_size, options, frame_index=np.arange(len(feet)),
                      track_id=np.zeros(len(feet), int))


def test_one_walker_engages_the_policy_and_holds_roll_within_its_prior():
    rng = np.random.default_rng(1)
    feet, heads = walker_px(rng, CAMERA, 1.78, 24)
    res = fit_reference(feet, heads, 1.78)
    assert any(n.startswith("few pairs (24 usable < 50)") for n in res.notes), res.notes
    assert any(n.startswith(f"roll held near 0 (prior sd {MOUNTED_ROLL_SD_DEG:g}°)") for n in res.notes), res.notes
    assert abs(math.degrees(res.camera.roll_rad)) < 2.0 * MOUNTED_ROLL_SD_DEG
    assert fit_reference(feet, heads, 1.78, few_pairs=False).notes == ()
    assert CalibrateOptions().few_pairs is False  # opt-in: it changes the sample's 20-pair calibration


def test_many_pairs_do_not_engage_it():
    rng = np.random.default_rng(2)
    parts = [walker_px(rng, CAMERA, s, 20) for s in (1.60, 1.68, 1.75, 1.82, 1.90)]
    feet, heads = (np.concatenate([p[k] for p in parts]) for k in (0, 1))
    tracks = np.repeat(np.arange(5), 20)
    assert len(feet) >= FEW_PAIRS
    results = [fit_camera(feet, heads, CAMERA.image_size, CalibrateOptions(few_pairs=flag),
                          frame_index=np.tile(np.arange(20), 5), track_id=tracks) for flag in (True, False)]
    assert results[0].notes == ()
    assert results[0].camera == results[1].camera  # byte-identical: the policy is not there


@pytest.mark.xfail(strict=True, reason="measured: the soft (Cauchy) loss as implemented loses to hard rejection here, "
                   "1.67 cm vs 0.98 cm (soft_l1: 2.13 vs 0.91 on 8 scenes; without gross errors 0.49 vs 0.48): the "
                   "issue's 0.2-0.3 cm gain is not reproduced; open")
def test_soft_loss_beats_hard_rejection_on_few_pairs_with_two_gross_errors():
    """Roll held at 0 in both (the roll rule off): only the loss differs. Over 12 seeded scenes, each a reference of
    16 clicks with 2 gross ones, the other people's mean |stature error| should be smaller with the soft loss."""
    errors = {True: [], False: []}
    others = np.array([1.58, 1.66, 1.71, 1.80, 1.92])
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        feet, heads = walker_px(rng, CAMERA, 1.74, 16, gross=2)
        truth = [walker_px(rng, CAMERA, s, 20) for s in others]
        for soft in (True, False):
            res = fit_reference(feet, heads, 1.74, few_pairs=soft, estimate_roll=False)
            assert any("soft robust loss" in n for n in res.notes) == soft
            measured = [np.median(statures_from_camera_m(f, h, res.camera)) for f, h in truth]
            errors[soft].append(100.0 * float(np.mean(np.abs(np.array(measured) - others))))
    soft_cm, hard_cm = np.mean(errors[True]), np.mean(errors[False])
    print(f"soft {soft_cm:.3f} cm, hard {hard_cm:.3f} cm")
    assert soft_cm < hard_cm
