"""Consistency and coverage of ``rotavat calibrate`` against the paper's plain fit of the same pairs.

    python benchmarks/bench_consistency.py            # 20, 200, 2,000 frames; 8 scenes per cell (a few minutes)
    python benchmarks/bench_consistency.py --quick    # 20 and 200 frames; 4 scenes per cell

Scenes (tests/_synthetic_pairs.py): a random surveillance camera (1920x1080, roll +-3 deg), 24 people
of statures N(1.70 m, 0.07 m) with their track ids, exact mid-sole/crown pixels plus 2 px of noise on
each point, in three layouts: ``still`` (everyone stands about their place at every depth, swaying
5 cm per frame), ``walk`` (everyone walks across the ground) and ``mix`` (half each).

Two fits of the same pairs, in the same run:

- **rotavat**: the sequence calibration's own path (:func:`rotavat_cli.calibration.sequence.fit_pooled_pairs`:
  still people merged, per-person statures, the priors, outlier rounds, the design effect), defaults;
- **plain**: the paper's model fitted by plain least squares: every stature 1.70 m, no priors, no
  merging, no rejection, roll free (the paper fixes it at 0; these cameras have some), the head's
  pixel error in u and v, started from the paper's 50^3 grid on 2,000 of the pairs.

A third row, **rotavat, no errors in variables** (``errors_in_variables=False``: the foot's pixel
noise not carried into the head's error), shows the bias this round removed.

Per cell (layout x frames): the median absolute error of focal (%), pitch (deg) and camera height (%)
over the scenes, and rotavat's coverage: the share of (scene, parameter) whose truth lies within
+-2 reported std, and the largest |error| / std. Targets (exit 1 when one is missed):

- coverage: within +-2 std in at least 90% of (scene, parameter) over every cell, within +-3.5 std always;
- accuracy: in every cell and for each parameter, rotavat's median error is at most 1.25x the plain
  fit's, or at most 3 points above it (focal and height in %; pitch: 0.5 deg).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from _synthetic_pairs import synthetic_pairs  # noqa: E402

from rotavat_cli.calibration import CalibrateOptions, paper_grid_search  # noqa: E402
from rotavat_cli.calibration.model import head_errors  # noqa: E402
from rotavat_cli.calibration.pairs import FootHeadPairs  # noqa: E402
from rotavat_cli.calibration.params import FOCAL, HEIGHT, N_PARAMS, PITCH, ROLL  # noqa: E402
from rotavat_cli.calibration.sequence import fit_pooled_pairs  # noqa: E402
from rotavat_cli.geometry.camera import Camera  # noqa: E402

LAYOUTS = ("still", "walk", "mix")
PARAMS = ("focal %", "pitch °", "height %")
PEOPLE = 24
NOISE_PX = 2.0
GRID_PAIRS = 2000  # the plain fit's grid seed runs on this many pairs (evenly spaced)
COVERAGE_2SD_MIN = 0.90
Z_MAX = 3.5
RATIO_MAX = 1.25
SLACK = {"focal %": 3.0, "pitch °": 0.5, "height %": 3.0}


@dataclass(frozen=True)
class Fit:
    """One fit's signed errors (focal %, pitch deg, height %) and, for rotavat, |error| / std."""

    errors: dict[str, float]
    z: dict[str, float]
    seconds: float


def signed_errors(focal_px: float, pitch_rad: float, height_m: float, true: Camera) -> dict[str, float]:
    """Estimate minus truth: focal and height in % of the truth, pitch in degrees."""
    return {"focal %": 100.0 * (focal_px / true.focal_px - 1.0), "pitch °": math.degrees(pitch_rad - true.pitch_rad),
            "height %": 100.0 * (height_m / true.height_m - 1.0)}


def rotavat_fit(scene, true: Camera, **options) -> Fit:
    """The sequence calibration's path on the scene's pairs (ids given)."""
    pairs = FootHeadPairs(scene.feet_px, scene.heads_px, scene.frame_index, scene.track_id, True,
                          int(scene.frame_index.max()) + 1, "2d")
    start = time.perf_counter()
    res, _ = fit_pooled_pairs(pairs, true.image_size, CalibrateOptions(**options))
    seconds = time.perf_counter() - start
    cam = res.camera
    err = signed_errors(cam.focal_px, cam.pitch_rad, cam.height_m, true)
    sd = {"focal %": 100.0 * res.std["focal_px"] / true.focal_px, "pitch °": res.std["pitch_deg"],
          "height %": 100.0 * res.std["height_m"] / true.height_m}
    return Fit(err, {k: abs(err[k]) / sd[k] if sd[k] > 0 else math.inf for k in PARAMS}, seconds)


def plain_fit(scene, true: Camera) -> Fit:
    """Plain least squares of the paper's model (module docstring) from the paper grid's best cell."""
    from scipy.optimize import least_squares

    start = time.perf_counter()
    feet, heads = scene.feet_px, scene.heads_px
    pp = np.asarray(true.principal_point)
    step = max(1, len(feet) // GRID_PAIRS)
    H = true.image_size[1]
    grid = paper_grid_search(feet[::step], heads[::step], pp, np.linspace(0.1 * H, 6.0 * H, 50),
                             np.deg2rad(np.linspace(-45.0, 90.0, 50)), np.linspace(0.5, 40.0, 50), 1.70, "full", 0.0)
    rel_feet, diff = feet - pp, feet - heads

    def residual(x: np.ndarray) -> np.ndarray:
        params = np.zeros((1, N_PARAMS))
        params[0, [FOCAL, PITCH, ROLL, HEIGHT]] = math.exp(x[0]), x[1], x[2], math.exp(x[3])
        (eu, ev), _, _ = head_errors(rel_feet, diff, params, 1.70, z_min=0.0)
        return np.concatenate([eu[0], ev[0]])

    sol = least_squares(residual, [math.log(grid.focal_px), grid.pitch_rad, 0.0, math.log(grid.height_m)],
                        method="lm", xtol=1e-12, ftol=1e-12)
    err = signed_errors(math.exp(sol.x[0]), sol.x[1], math.exp(sol.x[3]), true)
    return Fit(err, {}, time.perf_counter() - start)


def run_cell(layout: str, frames: int, seeds: int) -> dict[str, list[Fit]]:
    """Every fit of ``seeds`` scenes of one layout and length."""
    fits: dict[str, list[Fit]] = {"rotavat": [], "plain": [], "no-eiv": []}
    for seed in range(seeds):
        rng = np.random.default_rng(7000 + 97 * seed + LAYOUTS.index(layout))
        scene = synthetic_pairs(rng, frames=frames, people=PEOPLE, noise_px=NOISE_PX, roll_deg=None, layout=layout)
        fits["rotavat"].append(rotavat_fit(scene, scene.camera))
        fits["no-eiv"].append(rotavat_fit(scene, scene.camera, errors_in_variables=False))
        fits["plain"].append(plain_fit(scene, scene.camera))
    return fits


def median_abs(fits: list[Fit], key: str) -> float:
    """Median over scenes of |error|."""
    return float(np.median([abs(f.errors[key]) for f in fits]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20 and 200 frames, 4 scenes per cell")
    parser.add_argument("--seeds", type=int, default=None, help="scenes per cell (default 8, quick 4)")
    args = parser.parse_args(argv)
    frames_list = (20, 200) if args.quick else (20, 200, 2000)
    seeds = args.seeds or (4 if args.quick else 8)
    print(f"# Calibration consistency and coverage: {PEOPLE} people, {NOISE_PX:g} px noise, {seeds} scenes per "
          f"cell, frames {', '.join(map(str, frames_list))}\n")
    print("Median |error| over the scenes (focal %, pitch °, height %); rotavat's coverage: truth within "
          "+-2 std (of the cell's scenes x 3 parameters) and the largest |error| / std.\n")
    print("| layout | frames | rotavat | plain LS | rotavat / plain | rotavat, no errors in variables | "
          "within 2 sd | max z | rotavat s | plain s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    z_all, failures = [], []
    start = time.perf_counter()
    for layout in LAYOUTS:
        for frames in frames_list:
            fits = run_cell(layout, frames, seeds)
            rot, plain, no_eiv = (fits[k] for k in ("rotavat", "plain", "no-eiv"))
            z = [f.z[k] for f in rot for k in PARAMS]
            z_all += z
            cells = {k: (median_abs(rot, k), median_abs(plain, k), median_abs(no_eiv, k)) for k in PARAMS}
            for k, (r, p, _) in cells.items():
                if not (r <= RATIO_MAX * p or r <= p + SLACK[k]):
                    failures.append(f"{layout} x {frames}: {k} median {r:.2f} vs the plain fit's {p:.2f}")
            fmt = lambda i: " / ".join(f"{cells[k][i]:.2f}" for k in PARAMS)  # noqa: E731
            ratio = " / ".join(f"{cells[k][0] / cells[k][1]:.2f}" if cells[k][1] > 0 else "-" for k in PARAMS)
            print(f"| {layout} | {frames} | {fmt(0)} | {fmt(1)} | {ratio} | {fmt(2)} | "
                  f"{np.mean(np.asarray(z) <= 2.0):.0%} | {max(z):.1f} | "
                  f"{np.median([f.seconds for f in rot]):.2f} | {np.median([f.seconds for f in plain]):.2f} |",
                  flush=True)
    z_all = np.asarray(z_all)
    within = float(np.mean(z_all <= 2.0))
    print(f"\nOver every cell: truth within +-2 std in {within:.1%} of {len(z_all)} (scene, parameter) (target >= "
          f"{COVERAGE_2SD_MIN:.0%}); largest |error| / std {z_all.max():.2f} (target <= {Z_MAX:g}); "
          f"{time.perf_counter() - start:.0f} s in all.")
    if within < COVERAGE_2SD_MIN:
        failures.append(f"coverage {within:.1%} < {COVERAGE_2SD_MIN:.0%}")
    if z_all.max() > Z_MAX:
        failures.append(f"largest |error| / std {z_all.max():.2f} > {Z_MAX:g}")
    for line in failures:
        print(f"TARGET MISSED: {line}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
