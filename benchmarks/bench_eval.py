"""Throughput of rotavat's batched evaluation metrics vs a per-person Python loop.

Usage: python benchmarks/bench_eval.py [--pairs 100000] [--chunk 128] [--loop-pairs 2000]
                                        [--seed 0] [--engines numpy,numba]

Person-pairs (prediction + ground truth, SMPL-sized: 24 joints, 6,890 vertices, float32 as HPS
tools dump them) go through the eight per-person metrics of ``rotavat_cli.metrics``: W-MPJPE,
MPJPE, PA-MPJPE, SPEC's W-MPJPE and the same four on vertices. The batched path is what
``evaluate`` calls: one :func:`~rotavat_cli.metrics.person_errors_mm` per ``--chunk`` people
(default: evaluate's own batch, ``SCORE_BATCH_PEOPLE`` matched people of consecutive frames), on
the float32 arrays as loaded (it converts the joints once and the vertices block by block
itself, so its time includes every conversion). It is timed three ways: joints only, vertices
only, and all eight at once, once per vertex engine: ``numba`` (the compiled kernels of
``rotavat[fast]``, what ``evaluate`` runs when numba is installed; its one-off JIT compile or
cache load is done before timing and reported) and ``numpy``. The baseline is the straightforward per-person loop (per-person
float64 conversion, per-person ``np.linalg.svd`` Procrustes in the style of SPIN's
``compute_similarity_transform``, ``np.linalg.norm(axis=1)`` errors), run in the same process
on ``--loop-pairs`` pairs and extrapolated. For reference, the single-metric public functions
(``mpjpe``, ``pve``, ``w_spec_pve``, ..., float64 throughout) are timed on the same subset.
All paths see the same data and their results are compared with the loop's.

The fused vertex pass uses float32 per-vertex arithmetic on per-person centred coordinates
(see the ``rotavat_cli.metrics`` docstring), so a second check runs it on far bodies (25-30 m
from the camera, predictions placed up to a few metres off) against the float64 loop.

The random data are drawn once into a float32 pool of max(--loop-pairs, --chunk) pairs (~0.35 GB
at the defaults) and cycled, so the timings measure the metrics, not the random number generator.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _reference_metrics import reference_pa_errors_mm  # noqa: E402

from rotavat_cli.metrics import compiled_kernels, mpjpe, person_errors_mm, pve, w_spec_mpjpe, w_spec_pve  # noqa: E402
from rotavat_cli.metrics.evaluate import SCORE_BATCH_PEOPLE  # noqa: E402

N_JOINTS = 24
N_VERTS = 6890
METRICS = (
    "w_mpjpe", "mpjpe", "pa_mpjpe", "w_spec_mpjpe",
    "w_pve", "pve", "pa_pve", "w_spec_pve",
)
# person_errors_mm's names for the same metrics (evaluate's column names).
FUSED_KEY = dict(zip(METRICS, (
    "w_mpjpe", "mpjpe", "pa_mpjpe", "w_mpjpe_spec", "w_pve", "pve", "pa_pve", "w_pve_spec",
)))
PARTS = {"joints (4)": METRICS[:4], "vertices (4)": METRICS[4:], "all 8": METRICS}


def rot_x(angle_deg: float) -> np.ndarray:
    """Rotation about the camera x axis (a pitch), (3, 3)."""
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


R_WORLD_FROM_CAM_PRED = rot_x(-22.0)  # estimated camera: pitch 22 deg
R_WORLD_FROM_CAM_GT = rot_x(-25.0)    # true camera: pitch 25 deg


def make_pool(
    rng: np.random.Generator,
    n_people: int,
    block: int = 250,
    near_far_m: tuple[float, float] = (4.0, 20.0),
    placement_sd_m: float = 0.2,
) -> tuple[np.ndarray, ...]:
    """Random body-sized pred/gt joints (P, 24, 3) and vertices (P, 6890, 3), float32 metres.

    Bodies stand ``near_far_m`` in front of the camera; predictions are placed off by a normal
    ``placement_sd_m`` per axis (depth / placement error) plus 3 cm noise per point.
    """
    pool = tuple(
        np.empty((n_people, n, 3), np.float32) for n in (N_JOINTS, N_JOINTS, N_VERTS, N_VERTS)
    )
    low, high = [-3.0, 0.5, near_far_m[0]], [3.0, 2.0, near_far_m[1]]
    for k in range(0, n_people, block):  # in blocks, so float64 scratch stays small
        size = min(block, n_people - k)
        place = rng.uniform(low, high, size=(size, 1, 3))
        shift = rng.normal(0.0, placement_sd_m, size=(size, 1, 3))
        for pred, gt in ((pool[0], pool[1]), (pool[2], pool[3])):
            body = place + rng.normal(0.0, 0.3, size=(size, gt.shape[1], 3))
            gt[k : k + size] = body
            pred[k : k + size] = body + shift + rng.normal(0.0, 0.03, size=body.shape)
    return pool


# --------------------------------------------------------------------------- batched


def batched_metrics(
    pred_pts: np.ndarray, gt_pts: np.ndarray, pred_root: np.ndarray, gt_root: np.ndarray
) -> dict[str, Callable[[], np.ndarray]]:
    """The four metrics of one point kind (float64 arrays), as zero-argument calls -> (P,) mm."""
    rp, rg = R_WORLD_FROM_CAM_PRED, R_WORLD_FROM_CAM_GT
    if pred_pts.shape[1] == N_JOINTS:
        return {
            "w_mpjpe": lambda: mpjpe(pred_pts, gt_pts, "none"),
            "mpjpe": lambda: mpjpe(pred_pts, gt_pts, "root"),
            "pa_mpjpe": lambda: mpjpe(pred_pts, gt_pts, "procrustes"),
            "w_spec_mpjpe": lambda: w_spec_mpjpe(pred_pts, gt_pts, rp, rg),
        }
    return {
        "w_pve": lambda: pve(pred_pts, gt_pts, "none"),
        "pve": lambda: pve(pred_pts, gt_pts, "root", pred_root, gt_root),
        "pa_pve": lambda: pve(pred_pts, gt_pts, "procrustes"),
        "w_spec_pve": lambda: w_spec_pve(pred_pts, gt_pts, rp, rg, pred_root, gt_root),
    }


def fused_call(part: str, engine: str, pj, gj, pv, gv) -> dict[str, np.ndarray]:
    """``person_errors_mm`` on one chunk as evaluate calls it, for "joints", "vertices" or both."""
    joints = (pj, gj) if part != "vertices (4)" else (None, None)
    verts = (pv, gv) if part != "joints (4)" else (None, None)
    roots = (pj[:, 0], gj[:, 0]) if part == "vertices (4)" else (None, None)
    return person_errors_mm(
        *joints, *verts, R_WORLD_FROM_CAM_PRED, R_WORLD_FROM_CAM_GT, 0, *roots, engine=engine
    )


def time_fused(
    pool: tuple[np.ndarray, ...], n_pairs: int, chunk: int, part: str, engine: str
) -> float:
    """Seconds for ``n_pairs`` pairs through :func:`fused_call`, ``chunk`` people per call."""
    n_pool, seconds, done, k = len(pool[0]), 0.0, 0, 0
    while done < n_pairs:
        size = min(chunk, n_pool - k, n_pairs - done)
        arrays = (x[k : k + size] for x in pool)
        t0 = time.perf_counter()
        fused_call(part, engine, *arrays)
        seconds += time.perf_counter() - t0
        done += size
        k = (k + size) % n_pool
    return seconds


def per_metric_values(subset: tuple[np.ndarray, ...], chunk_verts: int = 32) -> tuple[dict, dict]:
    """Seconds per metric and values of the single-metric public functions on ``subset``.

    Joints go in one call, vertices in ``chunk_verts`` people (a float64 (P, 6890, 3) array
    is 165 kB per person); each chunk's float64 conversion is shared out over its metrics.
    """
    seconds = dict.fromkeys(METRICS, 0.0)
    values: dict[str, list[np.ndarray]] = {n: [] for n in METRICS}
    n_people = len(subset[0])
    for on_verts, chunk in ((False, n_people), (True, chunk_verts)):
        for k in range(0, n_people, chunk):
            t0 = time.perf_counter()
            pj, gj, pv, gv = (x[k : k + chunk] for x in subset)
            pj, gj = np.asarray(pj, np.float64), np.asarray(gj, np.float64)
            pred, gt = (np.asarray(x, np.float64) for x in (pv, gv)) if on_verts else (pj, gj)
            convert_s = (time.perf_counter() - t0) / 4
            for name, call in batched_metrics(pred, gt, pj[:, 0], gj[:, 0]).items():
                t0 = time.perf_counter()
                values[name].append(call())
                seconds[name] += time.perf_counter() - t0 + convert_s
    return seconds, {n: np.concatenate(v) for n, v in values.items()}


# --------------------------------------------------------------------------- loop baseline


def loop_pa_error_mm(pred: np.ndarray, gt: np.ndarray) -> float:
    """One person's PA error, textbook per-person Umeyama (as SPIN/mmhuman3d loop it)."""
    return float(reference_pa_errors_mm(pred, gt).mean())


def loop_metric(name: str, pj, gj, pv, gv) -> float:
    """One metric for one person, the straightforward way: (J, 3) / (V, 3) -> mm."""
    rp, rg = R_WORLD_FROM_CAM_PRED, R_WORLD_FROM_CAM_GT
    on_verts = name.endswith("pve")
    pred = np.asarray(pv if on_verts else pj, dtype=np.float64)
    gt = np.asarray(gv if on_verts else gj, dtype=np.float64)
    pr, gr = np.asarray(pj[0], np.float64), np.asarray(gj[0], np.float64)
    if name.startswith("w_spec"):
        diff = (pred - pr) @ rp.T - (gt - gr) @ rg.T
    elif name.startswith("pa_"):
        return loop_pa_error_mm(pred, gt)
    elif name.startswith("w_"):
        diff = pred - gt
    else:
        diff = (pred - pr) - (gt - gr)
    return float(np.linalg.norm(diff, axis=1).mean() * 1000.0)


# --------------------------------------------------------------------------- driver


def loop_values(subset: tuple[np.ndarray, ...]) -> tuple[dict, dict]:
    """Seconds per metric and values of the per-person loop baseline on ``subset``."""
    seconds, values = {}, {}
    for name in METRICS:
        t0 = time.perf_counter()
        values[name] = np.array(
            [loop_metric(name, *(x[i] for x in subset)) for i in range(len(subset[0]))]
        )
        seconds[name] = time.perf_counter() - t0
    return seconds, values


def max_diff_mm(values: dict[str, np.ndarray], reference: dict[str, np.ndarray]) -> float:
    """Largest absolute difference over every metric and pair, mm."""
    return max(float(np.abs(values[n] - reference[n]).max()) for n in METRICS)


def fused_values(subset: tuple[np.ndarray, ...], chunk: int, engine: str) -> dict[str, np.ndarray]:
    """The eight metrics of ``subset`` through the fused path, under the loop's names."""
    parts = [fused_call("all 8", engine, *(x[k : k + chunk] for x in subset))
             for k in range(0, len(subset[0]), chunk)]
    return {n: np.concatenate([p[FUSED_KEY[n]] for p in parts]) for n in METRICS}


def far_check_mm(seed: int, engines: list[str], n_pairs: int = 200) -> dict[str, float]:
    """Max |fused - loop| per engine on far bodies: 25-30 m away, predictions ~1 m (up to ~3 m) off."""
    far = make_pool(np.random.default_rng(seed + 1), n_pairs, near_far_m=(25.0, 30.0),
                    placement_sd_m=1.0)
    reference = loop_values(far)[1]
    return {e: max_diff_mm(fused_values(far, n_pairs, e), reference) for e in engines}


def warm_up_s(engine: str, pool: tuple[np.ndarray, ...]) -> float:
    """Seconds of the engine's one-off start (numba: import + JIT compile or cache load)."""
    t0 = time.perf_counter()
    fused_call("all 8", engine, *(x[:2] for x in pool))
    return time.perf_counter() - t0


def run(n_pairs: int, chunk: int, n_loop: int, seed: int, engines: list[str]) -> dict:
    """Time every path; returns seconds per pair and the consistency checks."""
    n_loop = min(n_loop, n_pairs)
    pool = make_pool(np.random.default_rng(seed), min(n_pairs, max(n_loop, chunk)))
    warm = {e: warm_up_s(e, pool) for e in engines}
    fused_s = {e: {part: time_fused(pool, n_pairs, chunk, part, e) for part in PARTS}
               for e in engines}
    subset = tuple(x[:n_loop] for x in pool)
    loop_s, loop_vals = loop_values(subset)
    per_metric_s, per_metric_vals = per_metric_values(subset)
    return {
        "engines": engines,
        "warm_up_s": warm,
        "fused": {e: {part: t / n_pairs for part, t in fused_s[e].items()} for e in engines},
        "fused_all_s": {e: fused_s[e]["all 8"] for e in engines},
        "loop": {n: loop_s[n] / n_loop for n in METRICS},
        "per_metric": {n: per_metric_s[n] / n_loop for n in METRICS},
        "n_loop": n_loop,
        "max_diff_mm": {e: max_diff_mm(fused_values(subset, chunk, e), loop_vals) for e in engines},
        "per_metric_diff_mm": max_diff_mm(per_metric_vals, loop_vals),
        "far_diff_mm": far_check_mm(seed, engines),
    }


def print_report(res: dict, n_pairs: int, chunk: int) -> None:
    """Print the per-metric table, the fused subtotals per engine and the overall ratios."""
    lp, pm = res["loop"], res["per_metric"]
    print(
        f"rotavat metrics: {n_pairs:,} person-pairs x ({N_JOINTS} joints + {N_VERTS:,} vertices),"
        f" float32 in; person_errors_mm on {chunk:,} people per call; loop baseline on"
        f" {res['n_loop']:,} pairs, extrapolated"
    )
    print(f"{'metric':<14}{'loop us/pair':>14}{'single-metric fn us/pair':>26}{'speed-up':>10}")
    for name in METRICS:
        print(f"{name:<14}{lp[name] * 1e6:>14.1f}{pm[name] * 1e6:>26.1f}{lp[name] / pm[name]:>9.1f}x")
    total_l = sum(lp.values())
    for engine in res["engines"]:
        fused = res["fused"][engine]
        print()
        print(f"engine {engine} (one-off start {res['warm_up_s'][engine]:.2f} s, not in the timings)")
        print(f"{'fused':<14}{'loop us/pair':>14}{'batched us/pair':>17}{'speed-up':>10}"
              f"{'batched pairs/s':>17}{'loop pairs/s':>14}")
        for part, names in PARTS.items():
            tb, tl = fused[part], sum(lp[n] for n in names)
            print(f"{part:<14}{tl * 1e6:>14.1f}{tb * 1e6:>17.1f}{tl / tb:>9.1f}x{1 / tb:>17,.0f}"
                  f"{1 / tl:>14,.0f}")
    print()
    for engine in res["engines"]:
        print(
            f"all 8 metrics on {n_pairs:,} pairs, engine {engine}: batched "
            f"{res['fused_all_s'][engine]:.1f} s measured, loop {total_l * n_pairs:.1f} s "
            f"extrapolated -> ratio {total_l / res['fused'][engine]['all 8']:.1f}x"
        )
    for engine in res["engines"]:
        print(f"max |batched - loop|, engine {engine}: {res['max_diff_mm'][engine]:.2e} mm on the subset, "
              f"{res['far_diff_mm'][engine]:.2e} mm on 200 far pairs (25-30 m away, ~1 m off)")
    print(f"max |single-metric functions - loop|: {res['per_metric_diff_mm']:.2e} mm")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak_mb:,.0f} MB")


def main(argv: list[str] | None = None) -> None:
    """Parse arguments, run the benchmark and print the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=100_000, help="person-pairs to evaluate")
    parser.add_argument("--chunk", type=int, default=SCORE_BATCH_PEOPLE,
                        help="people per batched call (default: what evaluate uses)")
    parser.add_argument("--loop-pairs", type=int, default=2_000, help="pairs for the loop")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--engines", default="numba,numpy",
                        help="vertex engines to time, comma-separated (numba needs rotavat[fast])")
    args = parser.parse_args(argv)
    if min(args.pairs, args.chunk, args.loop_pairs) < 1:
        parser.error("--pairs, --chunk and --loop-pairs must be >= 1")
    engines = [e.strip() for e in args.engines.split(",") if e.strip()]
    if not engines or any(e not in ("numpy", "numba") for e in engines):
        parser.error("--engines takes numpy and/or numba")
    if "numba" in engines and compiled_kernels() is None:
        print("numba is not installed (pip install 'rotavat[fast]'): timing the numpy engine only")
        engines = [e for e in engines if e != "numba"] or ["numpy"]
    res = run(args.pairs, args.chunk, args.loop_pairs, args.seed, engines)
    print_report(res, args.pairs, args.chunk)


if __name__ == "__main__":
    main()
