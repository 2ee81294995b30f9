"""Wall time of ``rotavat batch`` on a synthetic dataset: one worker, two workers, and a Dask cluster.

Usage: python benchmarks/bench_batch.py [--sequences 20] [--frames 200] [--people 10] [--quick]
                                        [--repeats 3] [--no-dask] [--workdir DIR] [--keep]

Writes ``--sequences`` synthetic scenes (``rotavat synth``, one seed each) as a dataset
``pred/seq_XX`` with ground truth ``gt/seq_XX``, warms the page cache, then times the whole command
(``rotavat batch pred --gt-root gt``, steps calibrate, align, eval and render, in a fresh process
each time, start-up included) with:

- ``--jobs 1`` (everything in one process): the baseline;
- ``--jobs 2`` (a process pool): target speed-up >= 1.7x on 2 cores;
- ``--executor dask --jobs 2``: the ``dask.distributed.LocalCluster`` rotavat starts itself on loopback
  (2 worker processes, 1 thread each; its start-up is timed): target overhead <= 15% over ``--jobs 2``.

The ``--jobs 2`` and Dask runs are repeated ``--repeats`` times (default 3), interleaved, so both see
the same machine: a shared virtual machine's speed drifts by +-10% from minute to minute. The table
gives the median wall time of each, the Dask overhead as the median of the pairwise ratios, and every
run's figure beside it.

It checks that the Dask run's aligned meshes and people.csv equal the local run's byte for byte,
prints each run's peak RSS per worker (from batch_report.json), and, for memory against sequence
length, the peak RSS per worker of one sequence of ``--frames`` frames against one four times as long.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rotavat_cli.synth import SynthOptions, write_synth_scene  # noqa: E402


def make_scene(work: Path, name: str, seed: int, frames: int, people: int) -> None:
    """One synthetic scene moved into the dataset layout pred/<name>, gt/<name>."""
    tmp = work / f".tmp-{name}"
    write_synth_scene(tmp, SynthOptions(seed=seed, frames=frames, people=people))
    for side in ("pred", "gt"):
        (work / side).mkdir(parents=True, exist_ok=True)
        os.replace(tmp / side, work / side / name)
    shutil.rmtree(tmp)


def make_dataset(work: Path, names: list[str], frames: int, people: int) -> None:
    """Write the scenes two at a time."""
    with ProcessPoolExecutor(max_workers=2) as pool:
        list(pool.map(make_scene, [work] * len(names), names, range(len(names)), [frames] * len(names), [people] * len(names)))


def warm(path: Path) -> None:
    """Read every file once so every run starts from the page cache."""
    for p in path.rglob("*"):
        if p.is_file():
            p.read_bytes()


def run(args: list[str]) -> float:
    """Seconds for one ``rotavat batch`` in a fresh process; raises if it fails."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", "from rotavat_cli.cli import main; main()", "batch", *args, "--quiet"],
                          cwd=ROOT, capture_output=True, text=True, env={**os.environ, "CI": "1"})
    if proc.returncode != 0:
        raise SystemExit(f"rotavat batch {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()}")
    return time.perf_counter() - start


def worker_rss(out: Path) -> str:
    """Peak RSS per worker of a run, from its batch_report.json."""
    report = json.loads((out / "batch_report.json").read_text())
    return ", ".join(f"{w['peak_rss_mb']:.0f}" for w in report["worker_stats"]) + " MB"


def same_meshes(a: Path, b: Path) -> int:
    """Compare every aligned file of two batch outputs (npz members byte for byte); returns the count."""
    n = 0
    for f in sorted(a.rglob("aligned/*")):
        g = b / f.relative_to(a)
        if f.suffix == ".npz":
            with zipfile.ZipFile(f) as za, zipfile.ZipFile(g) as zb:
                assert za.namelist() == zb.namelist(), f
                assert all(za.read(m) == zb.read(m) for m in za.namelist()), f
        else:
            assert f.read_bytes() == g.read_bytes(), f
        n += 1
    return n


def main() -> None:
    """Run the benchmark and print its table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sequences", type=int, default=20)
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--people", type=int, default=10)
    parser.add_argument("--quick", action="store_true", help="6 sequences x 40 frames x 10 people")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved --jobs 2 / Dask runs (median)")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask run")
    parser.add_argument("--workdir", type=Path, default=None)
    parser.add_argument("--keep", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.sequences, args.frames = 6, 40
    work = Path(args.workdir or tempfile.mkdtemp(prefix="rotavat-bench-batch-"))
    try:
        t0 = time.perf_counter()
        names = [f"seq_{i:02d}" for i in range(args.sequences)]
        make_dataset(work, names, args.frames, args.people)
        print(f"wrote {args.sequences} sequences x {args.frames} frames x {args.people} people (+ ground truth) "
              f"in {time.perf_counter() - t0:.0f} s")
        warm(work)
        common = [str(work / "pred"), "--gt-root", str(work / "gt")]
        t1 = run([*common, "--out", str(work / "out_j1"), "--jobs", "1"])
        local, dask = [], []
        for _ in range(max(1, args.repeats)):
            local.append(run([*common, "--out", str(work / "out_j2"), "--force", "--jobs", "2"]))
            if not args.no_dask:
                dask.append(run([*common, "--out", str(work / "out_dask"), "--force", "--executor", "dask", "--jobs", "2"]))
        t2 = statistics.median(local)
        rows = [("`--jobs 1` (one process)", f"{t1:.1f}", "1.00x", worker_rss(work / "out_j1")),
                ("`--jobs 2` (process pool)", runs(local), (f"{t1 / t2:.2f}x speed-up (target >= 1.7x); "
                 f"runs {', '.join(f'{t1 / t:.2f}x' for t in local)}"), worker_rss(work / "out_j2"))]
        if dask:
            rows.append(dask_row(work, local, dask))
        print()
        print("| run | wall s | vs baseline | peak RSS per worker |")
        print("|---|---|---|---|")
        for name, seconds, ratio, rss in rows:
            print(f"| {name} | {seconds} | {ratio} | {rss} |")
        memory(work, args)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


def runs(seconds: list[float]) -> str:
    """Median wall time, and every run's when there are several."""
    median = f"{statistics.median(seconds):.1f}"
    return median if len(seconds) == 1 else f"{median} ({', '.join(f'{s:.1f}' for s in seconds)})"


def dask_row(work: Path, local: list[float], dask: list[float]) -> tuple:
    """The Dask runs (rotavat's LocalCluster, start-up timed): overhead as the median of the pairwise ratios."""
    n = same_meshes(work / "out_j2", work / "out_dask")
    print(f"Dask outputs equal the local ones byte for byte ({n} aligned files)")
    overheads = [100.0 * (d / t - 1.0) for t, d in zip(local, dask)]
    return ("`--executor dask --jobs 2` (rotavat's LocalCluster, 2 workers)", runs(dask),
            (f"{statistics.median(overheads):+.1f}% vs `--jobs 2` (target <= 15%); "
             f"runs {', '.join(f'{o:+.1f}%' for o in overheads)}"), worker_rss(work / "out_dask"))


def memory(work: Path, args: argparse.Namespace) -> None:
    """Peak RSS per worker: one sequence of F frames against one of 4F (flat = frames are streamed)."""
    sizes = {}
    for label, frames in (("short", args.frames), ("long", 4 * args.frames)):
        mem = work / f"mem_{label}"
        make_scene(mem, "seq", 99, frames, args.people)
        run([str(mem / "pred"), "--gt-root", str(mem / "gt"), "--out", str(mem / "out"), "--jobs", "2"])
        report = json.loads((mem / "out" / "batch_report.json").read_text())
        sizes[frames] = max(w["peak_rss_mb"] for w in report["worker_stats"])
        shutil.rmtree(mem)
    (f1, r1), (f4, r4) = sizes.items()
    print(f"\npeak RSS per worker (max over workers, --jobs 2, default chunks): {r1:.0f} MB for one {f1}-frame "
          f"sequence, {r4:.0f} MB for one {f4}-frame sequence (ratio {r4 / r1:.2f}: flat means streamed)")


if __name__ == "__main__":
    main()
