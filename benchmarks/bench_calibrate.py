"""Benchmark of rotavat's camera calibration: synthetic accuracy, real sequences, speed.

    python benchmarks/bench_calibrate.py            # full run (a few minutes)
    python benchmarks/bench_calibrate.py --quick    # short version
    python benchmarks/bench_calibrate.py --only synthetic|causes|real|speed

Synthetic scenes come from tests/_synthetic_pairs.py. Real sequences are read from
../shared/realdata/ (relative to the repository) when present; their camera_gt.yaml is the
answer key, used here for scoring only. Prints markdown tables.
"""

from __future__ import annotations

import argparse
import glob
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from _synthetic_pairs import random_surveillance_camera, synthetic_pairs  # noqa: E402

from rotavat_cli.calibration import (  # noqa: E402
    CalibrateOptions,
    CalibrationResult,
    GridSpec,
    calibrate_sequence,
    fit_camera,
    fit_per_frame,
    paper_grid_search,
)
from rotavat_cli.geometry.camera import Camera, backproject_px_to_plane, camera_from_yaml_dict, project_cam_to_px, up_vector_cam  # noqa: E402
from rotavat_cli.errors import RotavatError  # noqa: E402
from rotavat_cli.bodies.frame_points import in_view  # noqa: E402

REALDATA = ROOT.parent / "shared" / "realdata"
METRICS = ("focal %", "pitch °", "roll °", "height %", "horizon px")


def errors(est: Camera, true: Camera) -> dict[str, float]:
    """Absolute errors of an estimated camera against the truth (report units)."""
    w = true.image_size[0] / 2.0
    return {
        "focal %": abs(100.0 * (est.focal_px / true.focal_px - 1.0)),
        "pitch °": abs(math.degrees(est.pitch_rad - true.pitch_rad)),
        "roll °": abs(math.degrees(est.roll_rad - true.roll_rad)),
        "height %": abs(100.0 * (est.height_m / true.height_m - 1.0)),
        "horizon px": abs(float(est.horizon_v_px(w) - true.horizon_v_px(w))),
    }


def z_score(res: CalibrationResult, true: Camera, key: str) -> float:
    """|error| / reported std for focal_px or height_m (NaN if fixed)."""
    sd = res.std[key]
    value, truth = (res.camera.focal_px, true.focal_px) if key == "focal_px" else (res.camera.height_m, true.height_m)
    if math.isnan(sd):
        return math.nan  # fixed
    return 0.0 if sd == math.inf else abs(value - truth) / sd  # inf: reported as undetermined


# ---- synthetic ---------------------------------------------------------------------------------------
def synthetic_table(seeds: int) -> None:
    """Median and 90th-percentile errors over seeds, per scene and method."""
    print(f"\n## Synthetic scenes ({seeds} seeds each; 2 px noise, stature sd 0.07 m, 1920x1080)\n")
    print("focal free for both methods; `grid` = the paper (roll 0); `refine` = default. Cells: median / p90 of the "
          "absolute error. `z<2` = share of runs whose focal and height errors are within 2 reported std.\n")
    head = "| scene | outliers | roll | method | " + " | ".join(METRICS) + " | z<2 f/h | fails | s/run |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for frames, people in ((1, 10), (100, 20)):
        for roll in (False, True):
            for outliers in (0.0, 0.1, 0.3):
                runs = {"grid": [], "refine": []}
                for seed in range(seeds):
                    rng = np.random.default_rng(1000 + seed)
                    data = synthetic_pairs(rng, frames=frames, people=people, outlier_fraction=outliers,
                                           roll_deg=None if roll else 0.0)
                    for method in runs:
                        t0 = time.perf_counter()
                        try:
                            res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, method=method,
                                             frame_index=data.frame_index, track_id=data.track_id)
                        except RotavatError:
                            runs[method].append(None)
                            continue
                        runs[method].append((res, data.camera, time.perf_counter() - t0))
                for method, items in runs.items():
                    ok = [r for r in items if r is not None]
                    errs = {m: np.array([errors(r.camera, cam)[m] for r, cam, _ in ok]) for m in METRICS}
                    cells = [f"{np.median(v):.2f} / {np.percentile(v, 90):.2f}" if len(v) else "-"
                             for v in errs.values()]
                    zf = np.array([z_score(r, cam, "focal_px") for r, cam, _ in ok])
                    zh = np.array([z_score(r, cam, "height_m") for r, cam, _ in ok])
                    cover = f"{np.mean(zf < 2):.0%}/{np.mean(zh < 2):.0%}" if len(ok) else "-"
                    secs = np.mean([t for _, _, t in ok]) if ok else math.nan
                    print(f"| {frames}x{people} | {outliers:.0%} | {'±5°' if roll else '0'} | {method} | "
                          + " | ".join(cells) + f" | {cover} | {len(items) - len(ok)} | {secs:.2f} |")


def synth_scene_table(seeds: int) -> None:
    """`refine` on full `rotavat synth` scenes: realistic bodies, their own mid-sole/crown landmarks."""
    from rotavat_cli.settings.config import default_config
    from rotavat_cli.sequence import open_sequence
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    print(f"\n## `rotavat synth` scenes ({seeds} seeds; 100 frames x 20 people, 2 px noise, 10% outliers, "
          "random roll; the prediction's focal is CLIFF's guess, so `rotavat calibrate` estimates the focal)\n")
    print("| method | " + " | ".join(METRICS) + " |")
    print("|---" * (len(METRICS) + 1) + "|")
    errs: dict[str, list[float]] = {m: [] for m in METRICS}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            out = Path(tmp) / f"s{seed}"
            write_synth_scene(out, SynthOptions(seed=100 + seed, frames=100, people=20, noise_px=2.0, outliers=0.1))
            true = open_sequence(out / "gt").camera
            options = CalibrateOptions.from_config(default_config()["calibrate"])
            est = calibrate_sequence(open_sequence(out / "pred"), options).result.camera
            for m, v in errors(est, true).items():
                errs[m].append(v)
    print("| refine | " + " | ".join(f"{np.median(errs[m]):.2f} / {np.percentile(errs[m], 90):.2f}"
                                     for m in METRICS) + " |")


# ---- synthetic scenes with the real sequences' suspected causes -----------------------------------------
CAUSES = {  # generator options (tests/_synthetic_pairs.py); "pp" moves the principal point 4% of W left
    "none": {},
    "box-derived points": dict(points="boxes"),
    "barrel distortion 3% at the corner": dict(distortion=-0.03),
    "principal point 4% W off": dict(pp=True),
    "sway 3 cm + AR(0.95) noise": dict(sway_sd_m=0.03, noise_corr=0.95),
    "all of the above": dict(points="boxes", distortion=-0.03, pp=True, sway_sd_m=0.03, noise_corr=0.95),
}
CAUSE_FITS = {  # fit_camera options
    "landmarks, full": dict(points="landmarks"),
    "landmarks, vertical": dict(points="landmarks", residual="vertical"),
    "boxes": dict(points="boxes"),
    "boxes + distortion": dict(points="boxes", distortion=True),
}


def cause_scene(seed: int, options: dict):
    """Few people (8, 150 frames, 5% outliers) under a random camera, with the given realism options."""
    rng = np.random.default_rng(3000 + seed)
    options = dict(options)
    cam = random_surveillance_camera(rng, roll_deg=None)
    if options.pop("pp", False):
        W, H = cam.image_size
        cam = cam.replace(principal_point=(W / 2 - 0.04 * W, H / 2))
    return synthetic_pairs(rng, camera=cam, frames=150, people=8, outlier_fraction=0.05, **options)


def causes_table(seeds: int) -> None:
    """Signed error (mean ± sd over seeds) and std coverage per cause and fit option, focal given and free."""
    print(f"\n## Synthetic scenes with the real sequences' suspected causes ({seeds} seeds; 8 people x 150 "
          "frames, 2 px noise, 5% outliers, random camera and roll)\n")
    print("Signed errors (estimate - truth), mean ± sd over seeds; `z<2` = share of runs within 2 reported std "
          "(pitch / roll / height, or focal / height).\n")
    head = ("| cause | fit | focal given: pitch ° | roll ° | height % | z<2 p/r/h | focal free: focal % | horizon % H | "
            "height % | z<2 f/h |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for cause, gen in CAUSES.items():
        scenes = [cause_scene(seed, gen) for seed in range(seeds)]
        for fit_name, kw in CAUSE_FITS.items():
            given, free = [], []
            refused = 0
            for data in scenes:
                cam = data.camera
                args = (data.feet_px, data.heads_px, cam.image_size)
                common = dict(frame_index=data.frame_index, track_id=data.track_id, **kw)
                for out, extra in ((given, dict(focal_px=cam.focal_px)), (free, {})):
                    try:
                        out.append(_signed(fit_camera(*args, **extra, **common), cam))
                    except RotavatError:
                        refused += 1
            if not given or not free:
                print(f"| {cause} | {fit_name} | refused on every scene |" + " |" * 7)
                continue
            g, f = np.array(given), np.array(free)
            cells = [f"{np.mean(g[:, i]):+.2f} ± {np.std(g[:, i]):.2f}" for i in (1, 2, 3)]
            cells.append("/".join(f"{np.mean(g[:, i] < 2):.0%}" for i in (6, 7, 8)))
            cells += [f"{np.mean(f[:, i]):+.1f} ± {np.std(f[:, i]):.1f}" for i in (0, 4, 3)]
            cells.append("/".join(f"{np.mean(f[:, i] < 2):.0%}" for i in (5, 8)))
            print(f"| {cause} | {fit_name} | " + " | ".join(cells) + " |" + (f" ({refused} refused)" if refused else ""))


def _signed(res: CalibrationResult, true: Camera) -> list[float]:
    """Signed errors (focal %, pitch °, roll °, height %, horizon % H) and |error|/std (focal, pitch, roll, height)."""
    c = res.camera
    W, H = true.image_size
    err = [100.0 * (c.focal_px / true.focal_px - 1.0), math.degrees(c.pitch_rad - true.pitch_rad),
           math.degrees(c.roll_rad - true.roll_rad), 100.0 * (c.height_m / true.height_m - 1.0),
           100.0 * float(c.horizon_v_px(W / 2.0) - true.horizon_v_px(W / 2.0)) / H]
    raw = [c.focal_px - true.focal_px, err[1], err[2], c.height_m - true.height_m]
    z = [abs(e) / sd if sd > 0 and not math.isnan(sd) else math.nan
         for e, sd in zip(raw, (res.std[k] for k in ("focal_px", "pitch_deg", "roll_deg", "height_m")))]
    return err + z


# ---- real sequences ---------------------------------------------------------------------------------
def load_real(seq_dir: Path, every: int = 1) -> dict:
    """Pairs, frame indices, person ids, image size and the true camera of one real sequence; the pairs of
    people cut by the image border are left out, as ``rotavat calibrate`` leaves them out (:func:`in_view`)."""
    meta = yaml.safe_load((seq_dir / "meta.yaml").read_text())
    truth = camera_from_yaml_dict(yaml.safe_load((seq_dir / "camera_gt.yaml").read_text()))
    feet, heads, frame, ids = [], [], [], []
    for t, path in enumerate(sorted(glob.glob(str(seq_dir / "*.npz")))[::every]):
        with np.load(path, allow_pickle=False) as z:
            feet.append(z["feet_2d"])
            heads.append(z["heads_2d"])
            frame.append(np.full(len(z["feet_2d"]), t))
            ids.append(z["person_ids"] if "person_ids" in z else np.full(len(z["feet_2d"]), -1))
    feet, heads = np.concatenate(feet).astype(float), np.concatenate(heads).astype(float)
    size = tuple(meta["image_size"])
    whole = in_view(feet, size) & in_view(heads, size)
    return {"feet": feet[whole], "heads": heads[whole], "frame": np.concatenate(frame)[whole],
            "ids": np.concatenate(ids)[whole], "size": size, "truth": truth}


def real_table(quick: bool) -> None:
    """Each method against camera_gt.yaml (scored, never used by the fit)."""
    seqs = sorted(p for p in REALDATA.glob("*") if (p / "camera_gt.yaml").exists()) if REALDATA.exists() else []
    if not seqs:
        print(f"\n## Real sequences: none found under {REALDATA}\n")
        return
    print("\n## Real sequences (answer key: camera_gt.yaml; report only, nothing is tuned to them)\n")
    print("Signed errors (estimate - truth). Points are box-derived (README), so `boxes` is the point model that "
          "says so (box depth 0.25 m, head row); `full` and `vertical` treat them as mid-sole/crown. "
          "`f z` = |focal error| / reported focal std.\n")
    head = ("| sequence | method | focal px (err) | pitch ° (err) | roll ° (err) | height m (err) | horizon err px "
            "(% H) | std f / pitch / h | f z | inliers | rmse px | s |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for seq in seqs:
        d = load_real(seq)
        true = d["truth"]
        W, H = d["size"]
        rows = [("grid (paper)", dict(method="grid")),
                ("refine, f estimated, default (points auto)", dict()),
                ("refine, f estimated, full", dict(points="landmarks")),
                ("refine, f estimated, vertical", dict(points="landmarks", residual="vertical")),
                ("refine, f estimated, boxes", dict(points="boxes")),
                ("refine, f estimated, boxes + distortion", dict(points="boxes", distortion=True)),
                ("refine, true f, default (points auto)", dict(focal_px=true.focal_px)),
                ("refine, true f, full", dict(focal_px=true.focal_px, points="landmarks")),
                ("refine, true f, vertical", dict(focal_px=true.focal_px, points="landmarks", residual="vertical")),
                ("refine, true f, boxes", dict(focal_px=true.focal_px, points="boxes")),
                ("refine, true f, boxes + distortion", dict(focal_px=true.focal_px, points="boxes", distortion=True)),
                ("(extra) refine, true f + pp, vertical",
                 dict(focal_px=true.focal_px, principal_point=true.principal_point, points="landmarks",
                      residual="vertical")),
                ("(extra) refine, true f + pp, boxes + distortion",
                 dict(focal_px=true.focal_px, principal_point=true.principal_point, points="boxes", distortion=True))]
        for name, kw in rows:
            t0 = time.perf_counter()
            try:
                res = fit_camera(d["feet"], d["heads"], d["size"], frame_index=d["frame"], track_id=d["ids"], **kw)
            except RotavatError as exc:  # refused: the people cannot give this camera
                print(f"| {seq.name} | {name} | refused: {str(exc)[:90]} |" + " |" * 9)
                continue
            dt = time.perf_counter() - t0
            c = res.camera
            hor = float(c.horizon_v_px(W / 2.0) - true.horizon_v_px(W / 2.0))
            sd = res.std
            print(f"| {seq.name} | {name} | {c.focal_px:.0f} ({100 * (c.focal_px / true.focal_px - 1):+.1f}%) | "
                  f"{math.degrees(c.pitch_rad):.2f} ({math.degrees(c.pitch_rad - true.pitch_rad):+.2f}) | "
                  f"{math.degrees(c.roll_rad):.2f} ({math.degrees(c.roll_rad - true.roll_rad):+.2f}) | "
                  f"{c.height_m:.2f} ({100 * (c.height_m / true.height_m - 1):+.1f}%) | "
                  f"{hor:+.1f} ({100 * hor / H:+.1f}%) | {sd['focal_px']:.0f} / {sd['pitch_deg']:.2f} / "
                  f"{sd['height_m']:.2f} | {z_score(res, true, 'focal_px'):.1f} | {res.inliers}/{res.pairs} | "
                  f"{res.rmse_px:.1f} | {dt:.2f} |")
        print(f"| {seq.name} | truth | {true.focal_px:.0f} | {math.degrees(true.pitch_rad):.2f} | "
              f"{math.degrees(true.roll_rad):.2f} | {true.height_m:.2f} | | | | | | |")
    print("\nPer-frame mode (refine, true f, boxes; each frame alone) against pooling all frames:\n")
    head = ("| sequence | frames fitted (skipped) | focal | pitch ° median (IQR) | roll ° median (IQR) | "
            "height m median (IQR) | pooled pitch / roll / height |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for seq in seqs:
        d = load_real(seq, every=10 if quick else 2)
        true = d["truth"]
        kw = dict(focal_px=true.focal_px, points="boxes")
        summary = fit_per_frame(d["feet"], d["heads"], d["size"], d["frame"], **kw)
        pooled = fit_camera(d["feet"], d["heads"], d["size"], frame_index=d["frame"], track_id=d["ids"], **kw).camera
        m, q = summary.median, summary.iqr
        print(f"| {seq.name} | {len(summary.results)} ({len(summary.skipped)}) | given | "
              f"{m['pitch_deg']:.2f} ({q['pitch_deg']:.2f}) | {m['roll_deg']:.2f} ({q['roll_deg']:.2f}) | "
              f"{m['height_m']:.2f} ({q['height_m']:.2f}) | {math.degrees(pooled.pitch_rad):.2f} / "
              f"{math.degrees(pooled.roll_rad):.2f} / {pooled.height_m:.2f} |")


# ---- speed ---------------------------------------------------------------------------------------------
def loop_baseline(feet: np.ndarray, heads: np.ndarray, pp, focal, pitch, height, max_cells: int) -> float:
    """Seconds per cell of a straightforward loop over grid cells (camera.py functions per cell)."""
    cells = [(f, p, c) for f in focal for p in pitch for c in height]
    step = max(1, len(cells) // max_cells)
    chosen = cells[::step][:max_cells]
    best = math.inf
    t0 = time.perf_counter()
    for f, p, c in chosen:  # the person model written plainly with camera.py (what the grid's kernel replaces)
        up = up_vector_cam(p, 0.0)
        pred = project_cam_to_px(backproject_px_to_plane(feet, f, pp, up, c) + 1.70 * up, f, pp)
        cost = float(np.sum((pred - heads) ** 2))
        if math.isfinite(cost) and cost < best:
            best = cost
    return (time.perf_counter() - t0) / len(chosen)


def speed_table(quick: bool) -> None:
    """Paper grid on 200 and 20,000 pairs and refine on 20,000, against the loop baseline."""
    print("\n## Speed (this machine, this run)\n")
    spec = GridSpec()
    head = "| task | pairs | seconds | loop baseline s (extrapolated from cells) | speed-up |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for n_pairs, frames in ((200, 10), (20_000, 1000)):
        data = synthetic_pairs(np.random.default_rng(7), frames=frames, people=20, outlier_fraction=0.1)
        W, H = data.camera.image_size
        pp = (W / 2.0, H / 2.0)
        focal, pitch, height = spec.focal_values_px(H), spec.pitch_values_rad(), spec.height_values_m()
        times = []
        for _ in range(1 if quick else 3):
            t0 = time.perf_counter()
            paper_grid_search(data.feet_px, data.heads_px, pp, focal, pitch, height, 1.70)
            times.append(time.perf_counter() - t0)
        t_grid = min(times)
        per_cell = loop_baseline(data.feet_px, data.heads_px, pp, focal, pitch, height,
                                 (200 if quick else 1000) if n_pairs > 1000 else (2000 if quick else 10000))
        t_base = per_cell * focal.size * pitch.size * height.size
        print(f"| paper grid 50^3 | {n_pairs:,} | {t_grid:.3f} | {t_base:.1f} | {t_base / t_grid:.0f}x |")
        if n_pairs == 20_000:
            data_r = synthetic_pairs(np.random.default_rng(8), frames=1000, people=20, outlier_fraction=0.1,
                                     roll_deg=None)
            times = []
            for _ in range(1 if quick else 3):
                t0 = time.perf_counter()
                fit_camera(data_r.feet_px, data_r.heads_px, data_r.camera.image_size,
                           frame_index=data_r.frame_index, track_id=data_r.track_id)
                times.append(time.perf_counter() - t0)
            print(f"| refine (f free, roll, 10% outliers) | {n_pairs:,} | {min(times):.3f} | | |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer seeds and repetitions")
    parser.add_argument("--seeds", type=int, default=None, help="synthetic seeds per scene (default 20, quick 4)")
    parser.add_argument("--only", choices=("synthetic", "causes", "real", "speed"), default=None)
    args = parser.parse_args()
    seeds = args.seeds or (4 if args.quick else 20)
    if args.only in (None, "speed"):
        speed_table(args.quick)
    if args.only in (None, "synthetic"):
        synthetic_table(seeds)
        synth_scene_table(max(2, seeds // 4))
    if args.only in (None, "synthetic", "causes"):
        causes_table(max(3, seeds // 4))
    if args.only in (None, "real"):
        real_table(args.quick)


if __name__ == "__main__":
    main()
