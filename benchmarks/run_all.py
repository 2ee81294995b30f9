"""Run every benchmark in turn (``make bench``); ``--quick`` passes each one its short settings.

Each benchmark measures its own baseline in the same run and prints the ratio, so the numbers
compare on whatever machine runs them. Benchmarks are never part of ``make test``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# name -> (full arguments, quick arguments)
BENCHMARKS = {
    "bench_startup.py": ([], ["--quick"]),
    "bench_calibrate.py": ([], ["--quick"]),
    "bench_floors.py": ([], ["--quick"]),
    "bench_consistency.py": ([], ["--quick"]),
    "bench_align.py": ([], ["--frames", "200"]),
    "bench_eval.py": ([], ["--pairs", "10000", "--loop-pairs", "500"]),
    "bench_render.py": ([], ["--repeats", "1"]),
    "bench_batch.py": ([], ["--quick"]),
    "bench_focal.py": ([], ["--quick"]),
    "bench_onedepth.py": ([], ["--quick"]),
    "bench_stature.py": ([], ["--quick"]),
    "bench_reference.py": ([], ["--quick"]),
    "bench_view.py": ([], ["--quick"]),
    "bench_export.py": ([], ["--quick"]),
    "bench_import.py": ([], ["--quick"]),
}


def main() -> int:
    """Run the benchmarks; returns the number that failed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short settings for every benchmark")
    parser.add_argument("names", nargs="*", help="only these benchmarks (e.g. bench_align.py)")
    args = parser.parse_args()
    failed = 0
    for name, (full, quick) in BENCHMARKS.items():
        if args.names and name not in args.names or not (HERE / name).exists():
            continue
        print(f"\n## {name} {' '.join(quick if args.quick else full)}\n", flush=True)
        start = time.perf_counter()
        rc = subprocess.call([sys.executable, str(HERE / name), *(quick if args.quick else full)])
        print(f"\n({name}: {time.perf_counter() - start:.0f} s, exit {rc})", flush=True)
        failed += rc != 0
    return failed


if __name__ == "__main__":
    sys.exit(main())
