"""Stature measurement on real surveillance cameras, calibrated from one person (single-view metrology).

    python benchmarks/bench_stature.py            # 10 reference tracks per camera
    python benchmarks/bench_stature.py --quick    # 3 reference tracks per camera
    python benchmarks/bench_stature.py --extras   # also the other point model (about twice the time)
    python benchmarks/bench_stature.py --refs 5 --min-pairs 20

The protocol of surveillance stature measurement (Li et al. 2015: 9 cameras, 11 subjects, the
camera calibrated from one subject of known stature with hand-clicked points; mean absolute error
1.39 cm). For each real sequence in ``../shared/realdata/`` (beside the repository; README there):

- the answer: every track's stature measured with the true camera (``camera_gt.yaml``, read for
  scoring only, never given to a calibration), ``statures_by_track(statures_from_camera_m(...))``;
- for each of the K longest tracks as the reference: the camera calibrated from that track alone
  (``fit_camera`` on its pairs, its true-camera stature given as known: ``person_height_m`` with a
  0.01 m sd; points ``auto``), then every other track with at least ``--min-pairs`` pairs measured
  with that camera and compared with its true-camera stature: mean absolute error (cm) per
  reference; the same with the true focal given (``focal_px``), and the estimated camera against
  the true one;
- a baseline per reference: the error of saying every other person has the reference's stature
  (what measuring must beat).

The true-camera statures treat the box-derived points as mid-sole and crown (the measurement's
model), so this scores the camera calibrated from one person, not the annotation. Nothing here is
tuned to these sequences. Exits 0 with "skipped: ../shared/realdata absent" when they are absent.
Prints markdown tables.
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

from rotavat_cli.calibration import CalibrateOptions, fit_camera  # noqa: E402
from rotavat_cli.calibration.pairs import FootHeadPairs, gather_pairs  # noqa: E402
from rotavat_cli.geometry.camera import Camera  # noqa: E402
from rotavat_cli.errors import RotavatError  # noqa: E402
from rotavat_cli.bodies.measure import TrackStatures, statures_from_camera_m, statures_by_track  # noqa: E402
from rotavat_cli.sequence import open_sequence, read_camera_yaml  # noqa: E402

REALDATA = ROOT.parent / "shared" / "realdata"
SEQUENCES = ("pets2009_s2l1", "towncentre")
PUBLISHED_MAE_CM = 1.39  # Li et al. 2015, 9 cameras, 11 subjects, calibration from one subject
KNOWN_STATURE_SD_M = 0.01  # the reference's stature is known (the protocol)
# variant -> (true focal given, point model). The protocol's is points "auto" (PETS's one-box points are
# taken for boxes, Town Centre's two-box points for landmarks); the extras fit the other point model
# ("other": landmarks where auto chose boxes, boxes where it chose landmarks), for comparison.
MODES = {"f estimated": (False, "auto"), "true f": (True, "auto")}
EXTRA_MODES = {"(extra) f estimated, other points": (False, "other"), "(extra) true f, other points": (True, "other")}


@dataclass(frozen=True)
class Reference:
    """One reference track's calibration (per mode) and the other tracks measured with it."""

    track: int
    pairs: int
    stature_m: float  # its true-camera stature, given to the calibration
    mae_cm: dict[str, float]  # mode -> mean |error| over the other tracks (NaN: the calibration failed)
    measured: dict[str, int]  # mode -> other tracks measured
    camera_err: dict[str, dict[str, float]]  # mode -> focal %, pitch deg, height % (signed)
    points: dict[str, str]  # mode -> the point model the fit chose
    failures: dict[str, str]  # mode -> why the calibration failed
    implausible: dict[str, list]  # mode -> the calibration's own plausibility findings (fit.implausible)
    baseline_cm: float  # mean |S_other - S_ref|: every other person given the reference's stature


def camera_errors(est: Camera, true: Camera) -> dict[str, float]:
    """Signed errors of an estimated camera: focal %, pitch deg, height %."""
    return {"focal %": 100.0 * (est.focal_px / true.focal_px - 1.0),
            "pitch °": math.degrees(est.pitch_rad - true.pitch_rad),
            "height %": 100.0 * (est.height_m / true.height_m - 1.0)}


def scored_tracks(truth: TrackStatures, min_pairs: int) -> np.ndarray:
    """(T,) bool: tracks with at least ``min_pairs`` measured pairs under the true camera."""
    return (truth.pairs >= min_pairs) & np.isfinite(truth.median_m)


def mae_cm(est: TrackStatures, truth: TrackStatures, others: np.ndarray) -> tuple[float, int]:
    """Mean |estimated - true| track stature (cm) over the tracks ``others`` (T,) bool of ``truth``
    that the estimated camera could measure, and how many those are."""
    est_median = np.full(len(truth), np.nan)
    est_median[np.searchsorted(truth.ids, est.ids)] = est.median_m  # same ids: the same pairs
    err = np.abs(est_median - truth.median_m)[others]
    err = err[np.isfinite(err)]
    return (100.0 * float(np.mean(err)) if len(err) else math.nan), len(err)


def evaluate_reference(pairs: FootHeadPairs, size: tuple[int, int], true: Camera, truth: TrackStatures,
                       row: int, scored: np.ndarray, modes: dict[str, tuple[bool, str]]) -> Reference:
    """Calibrate from track ``truth.ids[row]`` alone (each of ``modes``) and measure every other scored track."""
    track = int(truth.ids[row])
    sel = pairs.person_ids == track
    stature = float(truth.median_m[row])
    others = scored.copy()
    others[row] = False
    mae, measured, cam_err, points, failures, implausible = {}, {}, {}, {}, {}, {}
    chosen: dict[bool, str] = {}  # true focal given -> the point model "auto" chose
    for mode, (focal_given, point_model) in modes.items():
        if point_model == "other":
            if focal_given not in chosen:
                mae[mode], measured[mode], failures[mode] = math.nan, 0, "not run: the points-auto fit was refused"
                continue
            point_model = "landmarks" if chosen[focal_given] == "boxes" else "boxes"
        options = CalibrateOptions(person_height_m=stature, person_height_sd_m=KNOWN_STATURE_SD_M, points=point_model,
                                   focal_px=true.focal_px if focal_given else None)
        try:
            res = fit_camera(pairs.feet_px[sel], pairs.heads_px[sel], size, options,
                             frame_index=pairs.frame_index[sel], track_id=pairs.person_ids[sel])
        except (RotavatError, ValueError) as exc:  # refused: one person cannot give this camera
            mae[mode], measured[mode], failures[mode] = math.nan, 0, " ".join(str(exc).split())
            continue
        est = statures_by_track(statures_from_camera_m(pairs.feet_px, pairs.heads_px, res.camera), pairs.person_ids)
        mae[mode], measured[mode] = mae_cm(est, truth, others)
        cam_err[mode], points[mode] = camera_errors(res.camera, true), res.points
        chosen.setdefault(focal_given, res.points)
        implausible[mode] = list(res.fit_dict().get("implausible") or [])
    baseline = 100.0 * float(np.mean(np.abs(truth.median_m[others] - stature))) if others.any() else math.nan
    return Reference(track, int(truth.pairs[row]), stature, mae, measured, cam_err, points, failures, implausible,
                     baseline)


def run_sequence(path: Path, refs: int, min_pairs: int, modes: dict[str, tuple[bool, str]]) -> list[Reference]:
    """Every reference of one sequence; prints its table."""
    seq = open_sequence(path, read_camera=False)
    pairs = gather_pairs(seq)
    size = seq.require_image_size()
    true, _ = read_camera_yaml(path / "camera_gt.yaml")  # the answer key: scoring only
    if not pairs.tracked:
        print(f"\n### {path.name}: skipped (no person_ids: no tracks to measure)\n")
        return []
    truth = statures_by_track(statures_from_camera_m(pairs.feet_px, pairs.heads_px, true), pairs.person_ids)
    scored = scored_tracks(truth, min_pairs)
    longest = np.argsort(-truth.pairs, kind="stable")[:refs]
    good = truth.median_m[scored]
    print(f"\n### {path.name} ({size[0]}×{size[1]}, {len(pairs.feet_px):,} pairs, {len(truth)} tracks, "
          f"{int(scored.sum())} with ≥ {min_pairs} pairs; true-camera statures of those: median "
          f"{np.median(good):.3f} m, IQR {np.percentile(good, 25):.3f}–{np.percentile(good, 75):.3f} m)\n")
    extras = [m for m in modes if m in EXTRA_MODES]
    head = ("| reference track | pairs | stature m | points (auto) | f estimated: focal % | pitch ° | height % | "
            "MAE cm (tracks) | true f: pitch ° | height % | MAE cm | " + "".join(f"{m}: MAE cm | " for m in extras)
            + "baseline cm | s |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    results = []
    for row in longest:
        t0 = time.perf_counter()
        ref = evaluate_reference(pairs, size, true, truth, int(row), scored, modes)
        results.append(ref)
        print(_row(ref, time.perf_counter() - t0), flush=True)
    notes = [f"- track {ref.track}, {mode}: calibration refused: {why}"
             for ref in results for mode, why in ref.failures.items()]
    notes += [f"- track {ref.track}, {mode}: the calibration found its camera implausible: {'; '.join(found)}"
              for ref in results for mode, found in ref.implausible.items() if found]
    if notes:
        print("\n" + "\n".join(notes))
    return results


def _row(ref: Reference, seconds: float) -> str:
    """One reference's markdown row."""
    free, given = (ref.camera_err.get(m) for m in ("f estimated", "true f"))
    points = "/".join(sorted({ref.points[m] for m in ("f estimated", "true f") if m in ref.points})) or "-"
    cells = [str(ref.track), str(ref.pairs), f"{ref.stature_m:.3f}", points]
    if free is None:
        cells += ["refused", "", "", ""]
    else:
        cells += [f"{free['focal %']:+.1f}", f"{free['pitch °']:+.2f}", f"{free['height %']:+.1f}",
                  f"{ref.mae_cm['f estimated']:.2f} ({ref.measured['f estimated']})"]
    if given is None:
        cells += ["refused", "", ""]
    else:
        cells += [f"{given['pitch °']:+.2f}", f"{given['height %']:+.1f}", f"{ref.mae_cm['true f']:.2f}"]
    cells += [_cm(ref.mae_cm[m]) for m in ref.mae_cm if m in EXTRA_MODES]
    cells += [f"{ref.baseline_cm:.2f}", f"{seconds:.1f}"]
    return "| " + " | ".join(cells) + " |"


def _cm(value: float) -> str:
    """A MAE cell: cm with 2 decimals, 'refused' when the calibration failed."""
    return "refused" if math.isnan(value) else f"{value:.2f}"


def summary_table(all_refs: dict[str, list[Reference]]) -> None:
    """Per camera: median and mean over the references of the per-reference MAE, each mode."""
    print(f"\n## Summary: mean absolute stature error (cm) over the other tracks, per reference; median / mean "
          f"over the references (published: {PUBLISHED_MAE_CM} cm, Li et al. 2015)\n")
    head = "| camera | calibration | references | MAE cm: median | mean | refused |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for name, refs in all_refs.items():
        for mode in refs[0].mae_cm:
            values = np.array([r.mae_cm[mode] for r in refs])
            ok = values[np.isfinite(values)]
            cells = [name, mode, str(len(refs)), f"{np.median(ok):.2f}" if len(ok) else "-",
                     f"{np.mean(ok):.2f}" if len(ok) else "-", str(len(values) - len(ok))]
            print("| " + " | ".join(cells) + " |")
        base = np.array([r.baseline_cm for r in refs])
        print(f"| {name} | baseline: everyone the reference's stature | {len(refs)} | {np.median(base):.2f} | "
              f"{np.mean(base):.2f} | |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="3 reference tracks per camera")
    parser.add_argument("--refs", type=int, default=None, help="reference tracks per camera (default 10, quick 3)")
    parser.add_argument("--min-pairs", type=int, default=10, help="pairs a track needs to be scored (default 10)")
    parser.add_argument("--extras", action="store_true",
                        help="also calibrate with the other point model (twice the time)")
    args = parser.parse_args()
    found = [REALDATA / name for name in SEQUENCES if (REALDATA / name / "camera_gt.yaml").exists()]
    if not found:
        print("skipped: ../shared/realdata absent")
        return 0
    refs = args.refs or (3 if args.quick else 10)
    print(f"# Statures from a camera calibrated from one person ({refs} longest tracks as references)")
    t0 = time.perf_counter()
    modes = {**MODES, **(EXTRA_MODES if args.extras else {})}
    all_refs = {path.name: run_sequence(path, refs, args.min_pairs, modes) for path in found}
    summary_table({k: v for k, v in all_refs.items() if v})
    print(f"\n({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
