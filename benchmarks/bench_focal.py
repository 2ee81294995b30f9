"""World error of HPS predictions made with a method's focal rule, before and after ``rotavat align``.

Usage:

    python benchmarks/bench_focal.py            # full: 8 seeds x 20 frames x 8 people, 1920x1080 and 1280x720
    python benchmarks/bench_focal.py --quick    # short: 3 seeds x 10 frames x 6 people, 1920x1080
    python benchmarks/bench_focal.py --seeds 4 --frames 10 --people 6 --rules cliff bev --sizes 1920x1080

HPS methods guess the camera's focal F by a fixed rule (CLIFF/WHAM/GVHMR: the image diagonal;
BEV/ROMP: a 60 deg field of view; 4D-Humans: 5000/256 * max(W, H)); their meshes project onto the
image only with that F, while the real camera has focal f. For every rule and seed, ``rotavat
synth`` writes a scene under one of its random realistic cameras (horizontal field of view
45-100 deg; default noise, lean and depth error) whose prediction is made with the rule's F, and
this measures W-MPJPE (mm, no alignment at all) of:

- ``pred``: the prediction as it is;
- ``self-cal``: ``align`` into the camera calibrated from the people (focal estimated);
- ``true f``: ``align`` into the camera calibrated with the true focal given;
- ``ref``: the same scene (same seed: same camera, people and noise) made with F = f, calibrated
  with the true focal given and aligned: what the rule costs once the focal is known.

plus the median aligned stature of both aligned variants (people.csv, aligned rows) against the
median true stature (crown height above the ground of the ground-truth meshes), the
self-calibrated focal's error and the people flagged ``implausible_stature``.

Targets, checked per image size and rule on the medians over seeds (exit 1 when one is missed):
``true f`` / ``ref`` <= 1.15; ``self-cal`` at least 80% below ``pred``; both aligned median
statures within 5% of the truth.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rotavat_cli.alignment import AlignOptions, align_sequence, summarize_people_csv  # noqa: E402
from rotavat_cli.calibration import CalibrateOptions, calibrate_sequence  # noqa: E402
from rotavat_cli.geometry.camera import Camera  # noqa: E402
from rotavat_cli.settings.config import default_config  # noqa: E402
from rotavat_cli.errors import RotavatError  # noqa: E402
from rotavat_cli.geometry.focal import FOCAL_RULES, focal_from_rule  # noqa: E402
from rotavat_cli.bodies.landmarks import foot_head_points  # noqa: E402
from rotavat_cli.metrics.evaluate import evaluate  # noqa: E402
from rotavat_cli.sequence import open_sequence  # noqa: E402
from rotavat_cli.synth import SynthOptions, write_synth_scene  # noqa: E402

REFERENCE_RULE = "true"  # the prediction made with the camera's own focal (F = f)
SEED_BASE = 0
TARGET_RATIO = 1.15  # true f / ref
TARGET_DROP_PCT = 80.0  # self-cal below pred
TARGET_STATURE_PCT = 5.0  # |median aligned stature / median true stature - 1|


@dataclass(frozen=True)
class Aligned:
    """One aligned variant of a prediction: its camera, world error and statures."""

    focal_px: float  # the focal of the camera it was aligned into
    w_mpjpe_mm: float
    median_stature_m: float  # over aligned people (flag "" or implausible_stature), from people.csv
    implausible: int  # people flagged implausible_stature


FAILED = Aligned(math.nan, math.nan, math.nan, 0)  # calibration refused the scene


@dataclass(frozen=True)
class SeedResult:
    """Everything measured for one (image size, rule, seed)."""

    size: tuple[int, int]
    rule: str
    seed: int
    true_focal_px: float
    true_stature_m: float
    pred_mm: float
    self_cal: Aligned
    true_f: Aligned
    ref: Aligned

    @property
    def ratio(self) -> float:
        """W-MPJPE aligned with the true focal given / the same scene made with F = f."""
        return self.true_f.w_mpjpe_mm / self.ref.w_mpjpe_mm

    @property
    def drop_pct(self) -> float:
        """How far (%) the self-calibrated W-MPJPE is below the prediction's."""
        return 100.0 * (1.0 - self.self_cal.w_mpjpe_mm / self.pred_mm)

    @property
    def focal_err_pct(self) -> float:
        """Signed error (%) of the self-calibrated focal."""
        return 100.0 * (self.self_cal.focal_px / self.true_focal_px - 1.0)

    def stature_err_pct(self, variant: Aligned) -> float:
        """Signed error (%) of a variant's median aligned stature against the median true stature."""
        return 100.0 * (variant.median_stature_m / self.true_stature_m - 1.0)


# ---- measuring -----------------------------------------------------------------------------------------
def make_scene(root: Path, size: tuple[int, int], rule: str, seed: int, frames: int, people: int) -> Path:
    """Write a ``rotavat synth`` scene (``gt/`` and ``pred/``) under ``root``; returns its directory."""
    out = root / f"{rule}_{size[0]}x{size[1]}_s{seed}"
    write_synth_scene(out, SynthOptions(seed=seed, hps_focal=rule, image_size=size, frames=frames, people=people))
    return out


def calibrate(pred_dir: Path, focal_px: float | None) -> Camera:
    """Camera calibrated from the prediction's people with the defaults; the focal fixed when given."""
    options = default_config()["calibrate"]
    options["focal_px"] = focal_px
    return calibrate_sequence(open_sequence(pred_dir), CalibrateOptions.from_config(options)).result.camera


def align_and_eval(pred_dir: Path, gt_dir: Path, camera: Camera, out: Path) -> Aligned:
    """Align the prediction into ``camera`` (written to ``out``) and score it against the ground truth."""
    align_sequence(open_sequence(pred_dir), camera, out, AlignOptions(jobs=1))
    people = summarize_people_csv(out / "people.csv")
    return Aligned(float(camera.focal_px), float(evaluate(open_sequence(out), open_sequence(gt_dir)).metrics["w_mpjpe"]),
                   people.median_stature_m, people.implausible)


def calibrate_align_eval(scene: Path, focal_px: float | None, name: str) -> Aligned:
    """One aligned variant of a scene's prediction: calibrate (focal given or not), align, evaluate."""
    try:
        camera = calibrate(scene / "pred", focal_px)
    except RotavatError as exc:
        print(f"  {scene.name} {name}: calibration failed: {exc}", file=sys.stderr)
        return FAILED
    return align_and_eval(scene / "pred", scene / "gt", camera, scene / f"aligned_{name}")


def true_stature_m(gt_dir: Path) -> float:
    """Median true stature (m): crown height above the ground of every ground-truth mesh."""
    seq = open_sequence(gt_dir)
    heights = []
    for frame in seq.frames():
        if frame.n_people:
            _, crowns = foot_head_points(frame.data["vertices"])
            heights.append(seq.camera.height_above_ground(crowns))
    return float(np.nanmedian(np.concatenate(heights)))


def run_seed(root: Path, size: tuple[int, int], rules: list[str], seed: int, frames: int,
             people: int) -> list[SeedResult]:
    """Every rule's measurements for one seed (the F = f reference scene is shared by the rules)."""
    ref_scene = make_scene(root, size, REFERENCE_RULE, seed, frames, people)
    truth = open_sequence(ref_scene / "gt").camera
    stature = true_stature_m(ref_scene / "gt")
    ref = calibrate_align_eval(ref_scene, truth.focal_px, "true_f")
    results = []
    for rule in rules:
        scene = make_scene(root, size, rule, seed, frames, people)
        gt_focal = open_sequence(scene / "gt").camera.focal_px
        assert gt_focal == truth.focal_px, "the rule changed the synthetic camera"
        results.append(SeedResult(
            size, rule, seed, float(gt_focal), stature,
            pred_mm=float(evaluate(open_sequence(scene / "pred"), open_sequence(scene / "gt")).metrics["w_mpjpe"]),
            self_cal=calibrate_align_eval(scene, None, "self_cal"),
            true_f=calibrate_align_eval(scene, gt_focal, "true_f"),
            ref=ref))
    return results


# ---- reporting -----------------------------------------------------------------------------------------
def _table(head: list[str], rows: list[list[str]]) -> None:
    """Print a markdown table."""
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for row in rows:
        print("| " + " | ".join(row) + " |")


def _median(values: list[float]) -> float:
    """Median ignoring NaN (failed calibrations); NaN when nothing is left."""
    arr = np.asarray(values, dtype=float)
    return float(np.nanmedian(arr)) if np.isfinite(arr).any() else math.nan


def _size_name(size: tuple[int, int]) -> str:
    """(1920, 1080) -> '1920x1080'."""
    return f"{size[0]}x{size[1]}"


# (column, value of one seed result, format); the table shows the median over a group's seeds
COLUMNS = [
    ("F/f", lambda x: focal_from_rule(x.rule, x.size) / x.true_focal_px, "{:.2f}"),
    ("focal err % (self-cal)", lambda x: x.focal_err_pct, "{:+.1f}"),
    ("pred mm", lambda x: x.pred_mm, "{:,.0f}"),
    ("self-cal mm", lambda x: x.self_cal.w_mpjpe_mm, "{:.0f}"),
    ("true f mm", lambda x: x.true_f.w_mpjpe_mm, "{:.0f}"),
    ("ref mm", lambda x: x.ref.w_mpjpe_mm, "{:.0f}"),
    ("true f / ref", lambda x: x.ratio, "{:.3f}"),
    ("self-cal drop %", lambda x: x.drop_pct, "{:.1f}"),
    ("stature self-cal %", lambda x: x.stature_err_pct(x.self_cal), "{:+.1f}"),
    ("stature true f %", lambda x: x.stature_err_pct(x.true_f), "{:+.1f}"),
]
ROW_HEAD = ["size", "rule", *(name for name, _, _ in COLUMNS), "implausible sc / tf"]


def _cells(r: list[SeedResult]) -> list[str]:
    """Table cells of a group of seed results (one seed, or the medians over seeds; implausible: summed)."""
    cells = [fmt.format(_median([value(x) for x in r])) for _, value, fmt in COLUMNS]
    return cells + [f"{sum(x.self_cal.implausible for x in r)} / {sum(x.true_f.implausible for x in r)}"]


def print_per_seed(results: list[SeedResult]) -> None:
    """One row per (size, rule, seed)."""
    print("\n### Per seed\n")
    rows = [[_size_name(r.size), r.rule, str(r.seed), f"{r.true_focal_px:.0f}", *_cells([r])] for r in results]
    _table(ROW_HEAD[:2] + ["seed", "f px"] + ROW_HEAD[2:], rows)


def groups(results: list[SeedResult]) -> dict[tuple[tuple[int, int], str], list[SeedResult]]:
    """Seed results grouped by (image size, rule), in run order."""
    out: dict[tuple[tuple[int, int], str], list[SeedResult]] = {}
    for r in results:
        out.setdefault((r.size, r.rule), []).append(r)
    return out


def print_summary(results: list[SeedResult]) -> None:
    """One row per (size, rule): medians over seeds (implausible person-frames: summed)."""
    print("\n### Summary (medians over seeds; implausible_stature: person-frames summed over seeds)\n")
    _table(ROW_HEAD, [[_size_name(size), rule, *_cells(r)] for (size, rule), r in groups(results).items()])


def check_targets(results: list[SeedResult]) -> bool:
    """Print PASS/MISS per (size, rule, target) on the medians over seeds; True when all pass."""
    print("\n### Targets (medians over seeds)\n")
    rows, ok_all = [], True
    for (size, rule), r in groups(results).items():
        ratio = _median([x.ratio for x in r])
        drop = _median([x.drop_pct for x in r])
        st_sc = _median([x.stature_err_pct(x.self_cal) for x in r])
        st_tf = _median([x.stature_err_pct(x.true_f) for x in r])
        checks = [(f"true f / ref <= {TARGET_RATIO:.2f}", f"{ratio:.3f}", ratio <= TARGET_RATIO),
                  (f"self-cal >= {TARGET_DROP_PCT:.0f}% below pred", f"{drop:.1f}%", drop >= TARGET_DROP_PCT),
                  (f"median stature within {TARGET_STATURE_PCT:.0f}% (self-cal, true f)",
                   f"{st_sc:+.1f}%, {st_tf:+.1f}%", max(abs(st_sc), abs(st_tf)) <= TARGET_STATURE_PCT)]
        for name, value, ok in checks:  # NaN compares False: a failed calibration is a miss
            rows.append([_size_name(size), rule, name, value, "PASS" if ok else "MISS"])
            ok_all &= ok
    _table(["size", "rule", "target", "measured", "result"], rows)
    return ok_all


# ---- main ----------------------------------------------------------------------------------------------
def parse_size(text: str) -> tuple[int, int]:
    """'1920x1080' -> (1920, 1080)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"image size must be WxH, e.g. 1920x1080, got {text!r}") from None
    return w, h


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line options; ``--quick`` only changes the defaults of the others."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 seeds x 10 frames x 6 people, 1920x1080 only")
    parser.add_argument("--seeds", type=int, default=None, help="seeds per rule (default 8, quick 3)")
    parser.add_argument("--frames", type=int, default=None, help="frames per scene (default 20, quick 10)")
    parser.add_argument("--people", type=int, default=None, help="people per scene (default 8, quick 6)")
    parser.add_argument("--rules", nargs="+", choices=list(FOCAL_RULES), default=list(FOCAL_RULES),
                        help="focal rules of the predictions (default: all)")
    parser.add_argument("--sizes", nargs="+", type=parse_size, default=None,
                        help="image sizes WxH (default 1920x1080 1280x720, quick 1920x1080)")
    args = parser.parse_args(argv)
    args.seeds = args.seeds or (3 if args.quick else 8)
    args.frames = args.frames or (10 if args.quick else 20)
    args.people = args.people or (6 if args.quick else 8)
    args.sizes = args.sizes or ([(1920, 1080)] if args.quick else [(1920, 1080), (1280, 720)])
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print its tables; 0 when every target is met, else 1."""
    args = parse_args(argv)
    command = (f"python benchmarks/bench_focal.py --seeds {args.seeds} --frames {args.frames} --people {args.people} "
               f"--rules {' '.join(args.rules)} --sizes {' '.join(_size_name(s) for s in args.sizes)}")
    print(f"reproduce: {command}\n")
    print(f"{args.seeds} seeds x {args.frames} frames x {args.people} people per rule and image size; synth's random "
          "realistic cameras (horizontal FOV 45-100 deg), default noise, lean and depth error. W-MPJPE in mm; "
          "'ref' = the same scene made with F = f, aligned with the true focal; 'stature' = median aligned stature vs "
          "the median true one; 'F/f' = the rule's focal over the camera's.")
    start = time.perf_counter()
    results: list[SeedResult] = []
    for size in args.sizes:
        for seed in range(SEED_BASE, SEED_BASE + args.seeds):
            with tempfile.TemporaryDirectory(prefix="rotavat-bench-focal-") as tmp:
                results += run_seed(Path(tmp), size, args.rules, seed, args.frames, args.people)
    print_per_seed(results)
    print_summary(results)
    ok = check_targets(results)
    print(f"\n{len(results)} scenes (+ {len(args.sizes) * args.seeds} references) in "
          f"{time.perf_counter() - start:.0f} s; {'all targets met' if ok else 'some targets MISSED'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
