"""Statures from a camera calibrated from one reference person with tens of clicks (issue 35, point 3).

    python benchmarks/bench_reference.py            # 9 cameras x 11 references
    python benchmarks/bench_reference.py --quick    # 5 cameras x 4 references (under a minute)

A synthetic stand-in for the CCVS protocol of Li et al. 2015 (9 real cameras, 11 subjects with
tape-measured statures, hand-clicked crown and mid-sole points, each camera calibrated from one
subject and the others measured; that data is not available here). Seeded, CCVS-like:

- 9 surveillance-like cameras: 1280x720 or 704x576, focal 0.8-1.6 x width, pitch 10-35 deg, height
  2.5-6 m, roll +-2 deg, principal point a few px off-centre; 5 with barrel distortion of the division
  model rotavat fits (``calibration.model.undistort``), the corner moved by +20% to +30%;
- 11 subjects of statures 1.55-1.95 m, each walking two straight legs (away from the camera and toward it), 10-40 clicks
  each; on 3 cameras subject 0 walks only in the far half of the image and everyone else in the near
  half; clicks at mid-sole and crown with 1.75 px noise, the crown a few cm off the vertical (a
  persistent lean per subject, sd 1.5 cm per axis, plus per-click sway, sd 2 cm), and gross click
  errors (4% of the clicks, 10-40 px).

For each camera and each subject as the reference: the camera calibrated from that subject alone
with its tape stature known (sd 0.01 m), every other subject measured with ``result.camera``
(median of ``statures_from_camera_m`` over its clicks) and the mean |error| in cm. Policies, on the
same clicks: ``defaults (old)`` (the refinement without the few-pairs policy), ``roll 0`` (``--residual
vertical --no-roll``), ``default`` (the few-pairs policy, ``few_pairs=True``: ``calibration.fit._few_pairs_policy``; opt-in until
issue 35 decides, since it changes the sample's 20-pair calibration),
and on the distorted cameras ``default + lens`` (``distortion=True``). The lens is measured with
the fitted camera as returned: until the camera carries its distortion, the statures are measured
as by a pinhole. Exits 1 when the default is worse than roll 0 for some reference (the issue's
"done when"). Prints markdown tables.
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

from rotavat_cli.bodies.measure import statures_from_camera_m  # noqa: E402
from rotavat_cli.calibration import CalibrateOptions, fit_camera  # noqa: E402
from rotavat_cli.errors import RotavatError  # noqa: E402
from rotavat_cli.geometry.camera import Camera  # noqa: E402

SEED = 35
N_CAMERAS, N_SUBJECTS = 9, 11
DISTORTED = (0, 2, 4, 6, 8)  # cameras with barrel distortion (5 of 9, as in CCVS)
FAR_NEAR = (1, 4, 7)  # cameras where subject 0 walks in the far half and everyone else in the near half
CLICK_NOISE_PX = 1.75
LEAN_SD_M, SWAY_SD_M = 0.015, 0.02  # crown off the vertical: per subject (persistent), per click
GROSS_FRACTION, GROSS_PX = 0.04, (10.0, 40.0)
KNOWN_STATURE_SD_M = 0.01  # a tape-measured reference
PUBLISHED_MAE_CM = 1.52  # Li et al. 2015, calibration subject left out
# policy -> (option changes, only on distorted cameras)
POLICIES = {
    "defaults (old)": ({"few_pairs": False}, False),
    "roll 0": ({"residual": "vertical", "estimate_roll": False}, False),
    "default": ({"few_pairs": True}, False),
    "default + lens": ({"few_pairs": True, "distortion": True}, True),
}


@dataclass(frozen=True)
class Scene:
    """One camera and every subject's clicks: feet and heads (N, 2) distorted px, subject (N,) int."""

    camera: Camera
    distortion: float  # division-model lam (0: none)
    statures_m: np.ndarray  # (S,)
    feet_px: np.ndarray
    heads_px: np.ndarray
    subject: np.ndarray


def distort_division_px(points_px: np.ndarray, pp: np.ndarray, lam: float, radius_px: float) -> np.ndarray:
    """Distorted pixels (N, 2) whose division-model undistortion ``p_d / (1 + lam |p_d|^2 / R^2)`` is
    ``points_px`` (N, 2): the root of ``lam r_u r_d^2 / R^2 - r_d + r_u = 0`` nearest ``r_u`` (closed form)."""
    p = points_px - pp
    r_u = np.linalg.norm(p, axis=1, keepdims=True)
    if lam == 0.0:
        return points_px.copy()
    a = lam * r_u / radius_px**2
    with np.errstate(divide="ignore", invalid="ignore"):
        r_d = np.where(a == 0.0, r_u, (1.0 - np.sqrt(1.0 - 4.0 * a * r_u)) / (2.0 * a))
        scale = np.where(r_u > 0, r_d / r_u, 1.0)
    return pp + p * scale


def lam_for_corner(displacement: float) -> float:
    """Division-model lam that moves the image corner (r_d = R) outward by ``displacement`` (0.25: +25%)."""
    return 1.0 / (1.0 + displacement) - 1.0


def make_camera(rng: np.random.Generator, index: int) -> tuple[Camera, float]:
    """A surveillance-like camera (module docstring) and its division-model lam (0 when undistorted)."""
    size = (1280, 720) if index % 2 == 0 else (704, 576)
    while True:  # drawn again until whole people fill at least the lower 45% of the image (a camera that watches people)
        pp = (size[0] / 2 + rng.uniform(-4, 4), size[1] / 2 + rng.uniform(-4, 4))
        cam = Camera(size, rng.uniform(0.8, 1.6) * size[0], pp, math.radians(rng.uniform(10, 35)),
                     math.radians(rng.uniform(-2, 2)), rng.uniform(2.5, 6.0))
        if _highest_foot_row(cam, 1.95) < 0.55 * size[1]:
            break
    lam = lam_for_corner(rng.uniform(0.20, 0.30)) if index in DISTORTED else 0.0
    return cam, lam


def _ground_point(rng: np.random.Generator, cam: Camera, rows: tuple[float, float], tallest_m: float) -> np.ndarray:
    """A world ground point (3,) whose foot pixel lies in image rows ``rows`` (fractions of the foot rows a
    person of ``tallest_m`` fits in whole) and in the central 90% of the columns."""
    W, H = cam.image_size
    top = _highest_foot_row(cam, tallest_m)
    v = top + (H - 8 - top) * rng.uniform(*rows)
    u = rng.uniform(0.05 * W, 0.95 * W)
    return cam.world_from_cam(cam.backproject_px_to_ground(np.array([u, v])))


def _highest_foot_row(cam: Camera, tallest_m: float) -> float:
    """The highest foot row (px) whose person of ``tallest_m`` has the crown inside the image (and at most 30 m)."""
    W, H = cam.image_size
    for v in np.linspace(0, H - 10, 400):
        ground = cam.backproject_px_to_ground(np.array([W / 2, v]))
        if not np.all(np.isfinite(ground)) or ground[2] > 30.0:
            continue
        if cam.project(ground + tallest_m * cam.up_cam)[1] > 6.0:
            return float(v)
    return math.inf  # no row shows a whole person


def walk(rng: np.random.Generator, cam: Camera, lam: float, stature_m: float, rows: tuple[float, float]
         ) -> tuple[np.ndarray, np.ndarray]:
    """One subject's clicks (feet, heads (N, 2) distorted px) along a walk of two straight legs (far, near, anywhere
    within foot rows ``rows``, so that it spans depth as the CCVS subjects' walks do): click noise, the crown off the vertical (a lean and sway), a few gross click errors."""
    n = int(rng.integers(10, 41))
    lo, hi = rows
    ends = [(lo, lo + 0.4 * (hi - lo)), (hi - 0.4 * (hi - lo), hi), rows]  # away, toward the camera, anywhere
    corners = np.array([_ground_point(rng, cam, r, 1.95) for r in ends])
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(corners, axis=0), axis=1))])
    at = np.sort(rng.uniform(0, length[-1], n))
    ground = np.column_stack([np.interp(at, length, corners[:, k]) for k in range(3)])
    lean = rng.normal(0, LEAN_SD_M, 2)
    offset = lean + rng.normal(0, SWAY_SD_M, (n, 2))
    crown = ground + np.column_stack([offset[:, 0], np.full(n, stature_m), offset[:, 1]])
    pp, radius = np.asarray(cam.principal_point), 0.5 * math.hypot(*cam.image_size)
    feet, heads = (distort_division_px(cam.project(cam.cam_from_world(p)), pp, lam, radius) for p in (ground, crown))
    feet, heads = feet + rng.normal(0, CLICK_NOISE_PX, feet.shape), heads + rng.normal(0, CLICK_NOISE_PX, heads.shape)
    gross = rng.uniform(size=n) < GROSS_FRACTION
    which = rng.uniform(size=n) < 0.5  # the head's click or the foot's
    angle = rng.uniform(0, 2 * np.pi, n)
    jump = rng.uniform(*GROSS_PX, n)[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    heads = heads + np.where((gross & which)[:, None], jump, 0.0)
    feet = feet + np.where((gross & ~which)[:, None], jump, 0.0)
    return feet, heads


def make_scene(rng: np.random.Generator, index: int) -> Scene:
    """Camera ``index`` with its 11 subjects' clicks (subject 0 far, the others near on FAR_NEAR cameras)."""
    cam, lam = make_camera(rng, index)
    statures = rng.uniform(1.55, 1.95, N_SUBJECTS)
    feet, heads, subject = [], [], []
    for s, stature in enumerate(statures):
        rows = ((0.0, 0.5) if s == 0 else (0.5, 1.0)) if index in FAR_NEAR else (0.0, 1.0)
        f, h = walk(rng, cam, lam, stature, rows)
        feet.append(f)
        heads.append(h)
        subject.append(np.full(len(f), s))
    return Scene(cam, lam, statures, np.concatenate(feet), np.concatenate(heads), np.concatenate(subject))


@dataclass(frozen=True)
class Outcome:
    """One calibration from one reference: the others' mean |error| (cm), roll, its notes."""

    mae_cm: float
    roll_err_deg: float
    notes: tuple[str, ...]


def calibrate_and_measure(scene: Scene, ref: int, changes: dict) -> Outcome:
    """Calibrate from subject ``ref`` alone (tape stature known) with option ``changes``; measure the others."""
    sel = scene.subject == ref
    options = CalibrateOptions(person_height_m=float(scene.statures_m[ref]), person_height_sd_m=KNOWN_STATURE_SD_M,
                               **changes)
    try:
        res = fit_camera(scene.feet_px[sel], scene.heads_px[sel], scene.camera.image_size, options,
                         frame_index=np.arange(int(sel.sum())), track_id=scene.subject[sel])
    except (RotavatError, ValueError) as exc:
        return Outcome(math.nan, math.nan, (f"refused: {exc}",))
    statures = statures_from_camera_m(scene.feet_px, scene.heads_px, res.camera)
    errors = [abs(np.nanmedian(statures[scene.subject == s]) - scene.statures_m[s])
              for s in range(N_SUBJECTS) if s != ref]
    roll_err = math.degrees(res.camera.roll_rad - scene.camera.roll_rad)
    return Outcome(100.0 * float(np.mean(errors)), roll_err, res.notes)


def run(cameras: list[int], refs: list[int]) -> dict[str, np.ndarray]:
    """MAE (cm) per policy, (cameras, refs) (NaN: not run or refused); prints the per-camera rows."""
    rng = np.random.default_rng(SEED)
    scenes = [make_scene(rng, i) for i in range(N_CAMERAS)]  # every camera drawn: --quick uses the same ones
    mae = {p: np.full((len(cameras), len(refs)), np.nan) for p in POLICIES}
    roll = {p: np.full((len(cameras), len(refs)), np.nan) for p in POLICIES}
    engaged = np.zeros((len(cameras), len(refs)), int)
    print("| camera | size | f/W | pitch ° | roll ° | h m | corner % | clicks (ref) | "
          + " | ".join(f"{p}: MAE cm" for p in POLICIES) + " | policy notes | s |")
    print("|" + "---|" * (8 + len(POLICIES) + 2))
    for ci, c in enumerate(cameras):
        scene, t0 = scenes[c], time.perf_counter()
        for ri, r in enumerate(refs):
            for p, (changes, distorted_only) in POLICIES.items():
                if distorted_only and scene.distortion == 0.0:
                    continue
                out = calibrate_and_measure(scene, r, changes)
                mae[p][ci, ri], roll[p][ci, ri] = out.mae_cm, out.roll_err_deg
                if p == "default":
                    engaged[ci, ri] = sum("few pairs" in n or "roll held" in n for n in out.notes)
        cam = scene.camera
        corner = 100.0 * (1.0 / (1.0 + scene.distortion) - 1.0)
        clicks = "/".join(str(int((scene.subject == r).sum())) for r in refs)
        cells = [str(c), f"{cam.image_size[0]}×{cam.image_size[1]}", f"{cam.focal_px / cam.image_size[0]:.2f}",
                 f"{math.degrees(cam.pitch_rad):.1f}", f"{math.degrees(cam.roll_rad):+.2f}", f"{cam.height_m:.2f}",
                 f"{corner:+.0f}", clicks]
        cells += [_cm(np.nanmean(mae[p][ci])) if np.isfinite(mae[p][ci]).any() else "-" for p in POLICIES]
        cells += [f"{int(engaged[ci].sum())} notes / {len(refs)} refs", f"{time.perf_counter() - t0:.1f}"]
        print("| " + " | ".join(cells) + " |", flush=True)
    print("\nroll error of the fit (deg), mean |.| over (camera, reference): "
          + ", ".join(f"{p} {np.nanmean(np.abs(roll[p])):.2f}" for p in POLICIES))
    return mae


def _cm(x: float) -> str:
    return "refused" if not math.isfinite(x) else f"{x:.2f}"


def summary(mae: dict[str, np.ndarray], cameras: list[int], refs: list[int]) -> bool:
    """Prints the policy table and the per-reference check; True when the default is no worse than roll 0 for every
    reference (its MAE over the cameras)."""
    undistorted = np.array([c not in DISTORTED for c in cameras])
    print(f"\n## Policies: mean |stature error| (cm) of the other subjects (published, Li et al. 2015: "
          f"{PUBLISHED_MAE_CM} cm)\n")
    print("| policy | MAE all cameras | MAE undistorted cameras | MAE distorted cameras | worst reference: MAE "
          "(ref) | refused |")
    print("|---|---|---|---|---|---|")
    for p, values in mae.items():
        per_ref = np.nanmean(values, axis=0)
        worst = int(np.nanargmax(per_ref))
        dist = values[~undistorted]
        cells = [p, _cm(np.nanmean(values)), "-" if p == "default + lens" else _cm(np.nanmean(values[undistorted])),
                 _cm(np.nanmean(dist)) if np.isfinite(dist).any() else "-",
                 f"{per_ref[worst]:.2f} ({refs[worst]})", str(int(np.isnan(values).sum()) - (len(refs) * int(undistorted.sum()) if p == "default + lens" else 0))]
        if p == "default + lens":
            cells[1:3] = ["-", "-"]
            cells[4] = f"{per_ref[worst]:.2f} ({refs[worst]}), distorted only"
        print("| " + " | ".join(cells) + " |")
    base = mae["default"][~undistorted]
    if "default + lens" in mae and np.isfinite(base).any():
        print(f"\nlens on the distorted cameras: default {np.nanmean(base):.2f} cm, with distortion=True "
              f"{np.nanmean(mae['default + lens'][~undistorted]):.2f} cm (measured with the fitted camera as "
              "returned)")
    print("\n## Per reference: default vs roll 0 (MAE cm over the cameras; done when no worse for every reference)\n")
    print("| reference | defaults (old) | roll 0 | default | default no worse than roll 0 |")
    print("|---|---|---|---|---|")
    ok_all = True
    for ri, r in enumerate(refs):
        old, zero, new = (float(np.nanmean(mae[p][:, ri])) for p in ("defaults (old)", "roll 0", "default"))
        ok = new <= zero + 0.005  # printed to 0.01 cm
        ok_all &= ok
        print(f"| {r} | {old:.2f} | {zero:.2f} | {new:.2f} | {'yes' if ok else 'NO'} |")
    return ok_all


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="5 cameras x 4 references (under a minute)")
    args = parser.parse_args()
    cameras = [0, 1, 3, 4, 5] if args.quick else list(range(N_CAMERAS))
    refs = [0, 3, 6, 9] if args.quick else list(range(N_SUBJECTS))
    print(f"# Statures from one reference person: {len(cameras)} cameras × {len(refs)} references (seed {SEED})\n")
    t0 = time.perf_counter()
    mae = run(cameras, refs)
    ok = summary(mae, cameras, refs)
    print(f"\n({time.perf_counter() - t0:.0f} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
