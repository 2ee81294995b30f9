"""Throughput of rotavat's batched evaluation metrics vs a per-person Python loop.

Usage: python benchmarks/bench_eval.py [--pairs 100000] [--chunk-joints 2000]
                                        [--chunk-verts 32] [--loop-pairs 2000] [--seed 0]

Person-pairs (prediction + ground truth, SMPL-sized: 24 joints, 6,890 vertices, float32 as HPS
tools dump them) go through the eight per-person metrics of ``rotavat_cli.metrics``: W-MPJPE,
MPJPE, PA-MPJPE, SPEC's W-MPJPE and the same four on vertices. The batched path converts each
chunk to float64 once (timed, reported on its own line) and calls the public functions. The
baseline is the straightforward per-person loop (per-person ``np.linalg.svd`` Procrustes in
the style of SPIN's ``compute_similarity_transform``, ``np.linalg.norm(axis=1)`` errors), run
in the same process on ``--loop-pairs`` pairs and extrapolated. Both paths see the same data
and their results are compared.

Chunks bound memory. Joints are tiny, so they go 2,000 people per call. Vertex chunks are
small on purpose: a float64 (P, 6890, 3) temporary is 165 kB per person, and above ~32 MB
glibc hands each temporary fresh pages from the kernel (mmap) and returns them on free, so
page faults dominate: 2,000 people per call (330 MB per array, 1.6 GB peak) measured ~5x slower
per pair than 32 (5 MB per array). The random data are drawn once into a float32 pool of
max(--loop-pairs, --chunk-joints) pairs (~0.35 GB at the defaults) and cycled, so the timings
measure the metrics, not the random number generator.
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
from rotavat_cli.metrics import mpjpe, pve, w_spec_mpjpe, w_spec_pve  # noqa: E402

N_JOINTS = 24
N_VERTS = 6890
METRICS = (
    "w_mpjpe", "mpjpe", "pa_mpjpe", "w_spec_mpjpe",
    "w_pve", "pve", "pa_pve", "w_spec_pve",
)


def rot_x(angle_deg: float) -> np.ndarray:
    """Rotation about the camera x axis (a pitch), (3, 3)."""
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


R_WORLD_FROM_CAM_PRED = rot_x(-22.0)  # estimated camera: pitch 22 deg
R_WORLD_FROM_CAM_GT = rot_x(-25.0)    # true camera: pitch 25 deg


def make_pool(rng: np.random.Generator, n_people: int, block: int = 250) -> tuple[np.ndarray, ...]:
    """Random body-sized pred/gt joints (P, 24, 3) and vertices (P, 6890, 3), float32 metres."""
    pool = tuple(
        np.empty((n_people, n, 3), np.float32) for n in (N_JOINTS, N_JOINTS, N_VERTS, N_VERTS)
    )
    for k in range(0, n_people, block):  # in blocks, so float64 scratch stays small
        size = min(block, n_people - k)
        place = rng.uniform([-3.0, 0.5, 4.0], [3.0, 2.0, 20.0], size=(size, 1, 3))
        shift = rng.normal(0.0, 0.2, size=(size, 1, 3))  # depth / placement error
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


def time_batched(pool: tuple[np.ndarray, ...], n_pairs: int, chunk: int, verts: bool) -> dict:
    """Seconds per metric (and for the float64 conversion) over ``n_pairs``, cycling the pool."""
    seconds: dict[str, float] = {}
    n_pool = len(pool[0])
    starts = range(0, n_pool, chunk)
    done, i = 0, 0
    while done < n_pairs:
        k = starts[i % len(starts)]
        size = min(chunk, n_pool - k, n_pairs - done)
        pj, gj, pv, gv = (x[k : k + size] for x in pool)
        t0 = time.perf_counter()
        if verts:
            pred64, gt64 = np.asarray(pv, np.float64), np.asarray(gv, np.float64)
            roots = np.asarray(pj[:, 0], np.float64), np.asarray(gj[:, 0], np.float64)
        else:
            pred64, gt64 = np.asarray(pj, np.float64), np.asarray(gj, np.float64)
            roots = pred64[:, 0], gt64[:, 0]
        key = "to_float64_verts" if verts else "to_float64_joints"
        seconds[key] = seconds.get(key, 0.0) + time.perf_counter() - t0
        for name, call in batched_metrics(pred64, gt64, *roots).items():
            t0 = time.perf_counter()
            call()
            seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - t0
        done += size
        i += 1
    return seconds


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


def run(n_pairs: int, chunk_joints: int, chunk_verts: int, n_loop: int, seed: int) -> dict:
    """Time both paths; returns per-metric seconds per pair and a consistency check."""
    n_loop = min(n_loop, n_pairs)
    pool = make_pool(np.random.default_rng(seed), min(n_pairs, max(n_loop, chunk_joints)))
    batched_s = time_batched(pool, n_pairs, chunk_joints, verts=False)
    batched_s.update(time_batched(pool, n_pairs, chunk_verts, verts=True))

    subset = tuple(x[:n_loop] for x in pool)
    loop_s, loop_vals = {}, {}
    for name in METRICS:
        t0 = time.perf_counter()
        loop_vals[name] = np.array(
            [loop_metric(name, *(x[i] for x in subset)) for i in range(n_loop)]
        )
        loop_s[name] = time.perf_counter() - t0

    batched_vals: dict[str, list[np.ndarray]] = {n: [] for n in METRICS}
    for k in range(0, n_loop, chunk_verts):  # chunked, to keep the peak as in the timed run
        pj, gj, pv, gv = (np.asarray(x[k : k + chunk_verts], np.float64) for x in subset)
        calls = batched_metrics(pj, gj, pj[:, 0], gj[:, 0])
        calls.update(batched_metrics(pv, gv, pj[:, 0], gj[:, 0]))
        for name, call in calls.items():
            batched_vals[name].append(call())
    max_diff_mm = max(
        float(np.abs(np.concatenate(batched_vals[n]) - loop_vals[n]).max()) for n in METRICS
    )
    return {
        "batched": {n: t / n_pairs for n, t in batched_s.items()},
        "loop": {n: loop_s[n] / n_loop for n in METRICS},
        "batched_total_s": sum(batched_s.values()),
        "n_loop": n_loop,
        "max_diff_mm": max_diff_mm,
    }


def print_report(res: dict, n_pairs: int, chunk_joints: int, chunk_verts: int) -> None:
    """Print the per-metric table, subtotals and the overall ratio."""
    b, lp = res["batched"], res["loop"]
    print(
        f"rotavat metrics: {n_pairs:,} person-pairs x ({N_JOINTS} joints + {N_VERTS:,} vertices),"
        f" float32 in; batched chunks: {chunk_joints} people (joints), {chunk_verts} (vertices);"
        f" loop baseline on {res['n_loop']:,} pairs, extrapolated"
    )
    print(f"{'metric':<18}{'batched us/pair':>17}{'loop us/pair':>14}{'speed-up':>10}")
    for name in ("to_float64_joints", "to_float64_verts"):
        print(f"{name:<18}{b[name] * 1e6:>17.2f}{'(in each)':>14}")
    for name in METRICS:
        print(f"{name:<18}{b[name] * 1e6:>17.2f}{lp[name] * 1e6:>14.1f}{lp[name] / b[name]:>9.1f}x")
    joints = [n for n in METRICS if n.endswith("mpjpe")]
    verts = [n for n in METRICS if n.endswith("pve")]
    groups = {
        "joints (4)": joints + ["to_float64_joints"],
        "vertices (4)": verts + ["to_float64_verts"],
        "all 8": list(b),
    }
    print()
    print(f"{'subtotal':<18}{'batched pairs/s':>17}{'loop pairs/s':>14}{'speed-up':>10}")
    for label, names in groups.items():
        tb, tl = sum(b[n] for n in names), sum(lp.get(n, 0.0) for n in names)
        print(f"{label:<18}{1 / tb:>17,.0f}{1 / tl:>14,.0f}{tl / tb:>9.1f}x")
    total_b, total_l = sum(b.values()), sum(lp.values())
    print()
    print(
        f"all 8 metrics on {n_pairs:,} pairs: batched {res['batched_total_s']:.1f} s measured, "
        f"loop {total_l * n_pairs:.1f} s extrapolated -> ratio {total_l / total_b:.1f}x"
    )
    print(f"max |batched - loop| over the subset: {res['max_diff_mm']:.2e} mm")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {peak_mb:,.0f} MB")


def main(argv: list[str] | None = None) -> None:
    """Parse arguments, run the benchmark and print the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=100_000, help="person-pairs to evaluate")
    parser.add_argument("--chunk-joints", type=int, default=2_000, help="people per joint call")
    parser.add_argument("--chunk-verts", type=int, default=32, help="people per vertex call")
    parser.add_argument("--loop-pairs", type=int, default=2_000, help="pairs for the loop")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if min(args.pairs, args.chunk_joints, args.chunk_verts, args.loop_pairs) < 1:
        parser.error("--pairs, --chunk-joints, --chunk-verts and --loop-pairs must be >= 1")
    res = run(args.pairs, args.chunk_joints, args.chunk_verts, args.loop_pairs, args.seed)
    print_report(res, args.pairs, args.chunk_joints, args.chunk_verts)


if __name__ == "__main__":
    main()
