"""Reading frames and calibrating 20,000 pairs, each against its numpy floor measured in the same run.

    python benchmarks/bench_floors.py            # 2,500 frames x 8 people, 7 interleaved runs of each command
    python benchmarks/bench_floors.py --quick    # the same sequence, 3 runs

Writes a 2D sequence of ``--frames`` npz frames of ``--people`` walkers (feet_2d, heads_2d, person_ids;
``tests/_synthetic_pairs.py`` through ``bench_startup.write_pairs_sequence``, 2 px noise, 10% outliers: 20,000 foot/head pairs by default) and times:

- in this process, reading every frame: ``Sequence.read_frame`` (rotavat's reader: every declared size
  and header checked, the frame validated) against ``np.load`` of the same arrays (the floor), best of 5;
- whole processes, interleaved so a machine's drift touches them alike (median of the runs): the floor,
  a ``python`` process that imports numpy and loads every frame's arrays with ``np.load``; then
  ``rotavat info``, ``rotavat calibrate`` (refine, the default) and ``rotavat calibrate --method grid``,
  start-up and reading included.

Targets (issue 34): reading at numpy's pace (rotavat's reader <= 1.1x ``np.load`` per frame); both
calibrations under 1.5 s (2-core machine) and the grid never slower than the refinement; ``info`` within
2x the numpy process. Exit status 1 when one is missed. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _measure import interleaved, rotavat_argv  # noqa: E402
from bench_startup import write_pairs_sequence  # noqa: E402

from rotavat_cli.sequence import open_sequence  # noqa: E402

READ_TARGET = 1.1  # rotavat's reader / np.load, per frame
CALIBRATE_TARGET_S = 1.5  # whole `rotavat calibrate` of 20,000 pairs, start-up and reading included
INFO_TARGET = 2.0  # whole `rotavat info` / the numpy loading process

NUMPY_FLOOR = """
import sys
from pathlib import Path
import numpy as np
feet, heads, ids = [], [], []
for path in sorted(Path(sys.argv[1]).glob("*.npz")):
    with np.load(path) as npz:
        feet.append(npz["feet_2d"]); heads.append(npz["heads_2d"]); ids.append(npz["person_ids"])
print(len(np.concatenate(feet)), len(np.concatenate(heads)), len(np.concatenate(ids)))
"""


def per_frame_read_us(seq_dir: Path, repeats: int = 5) -> tuple[float, float]:
    """Best-of-``repeats`` microseconds per frame: rotavat's reader, and ``np.load`` of the same arrays."""
    seq = open_sequence(seq_dir)
    paths = [seq.frame_path(name) for name in seq.frame_names]

    def rotavat() -> None:
        for name in seq.frame_names:
            seq.read_frame(name)

    def numpy() -> None:
        for path in paths:
            with np.load(path) as npz:
                for key in npz.files:
                    npz[key]

    best = {}
    for name, step in (("rotavat", rotavat), ("numpy", numpy)):
        step()  # warm: the page cache and the first imports
    for _ in range(repeats):
        for name, step in (("rotavat", rotavat), ("numpy", numpy)):
            start = time.perf_counter()
            step()
            best[name] = min(best.get(name, float("inf")), time.perf_counter() - start)
    return best["rotavat"] / len(paths) * 1e6, best["numpy"] / len(paths) * 1e6


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2500)
    parser.add_argument("--people", type=int, default=8)
    parser.add_argument("--runs", type=int, default=None, help="interleaved runs of each command (default 7; --quick 3)")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    runs = args.runs or (3 if args.quick else 7)
    rotavat = rotavat_argv()
    with tempfile.TemporaryDirectory(prefix="rotavat-bench-floors-") as tmp:
        seq = Path(tmp) / "pairs"
        n_pairs = len(write_pairs_sequence(seq, 34, args.frames, args.people)[1].feet_px)
        ours_us, numpy_us = per_frame_read_us(seq)
        out = str(Path(tmp) / "camera.yaml")
        commands = {
            "numpy floor: np.load every frame": [sys.executable, "-c", NUMPY_FLOOR, str(seq)],
            "rotavat info": [*rotavat, "info", str(seq)],
            "rotavat calibrate (refine)": [*rotavat, "calibrate", str(seq), "--out", out, "--force", "-q"],
            "rotavat calibrate --method grid": [*rotavat, "calibrate", str(seq), "--method", "grid", "--out", out,
                                                "--force", "-q"],
        }
        times = {name: statistics.median(values) for name, values in interleaved(commands, runs).items()}
    floor = times["numpy floor: np.load every frame"]
    refine, grid = times["rotavat calibrate (refine)"], times["rotavat calibrate --method grid"]
    checks = {
        "reading": (ours_us / numpy_us, f"<= {READ_TARGET}x", ours_us / numpy_us <= READ_TARGET),
        "rotavat info": (times["rotavat info"] / floor, f"<= {INFO_TARGET}x", times["rotavat info"] / floor <= INFO_TARGET),
        "rotavat calibrate (refine)": (refine / floor, f"< {CALIBRATE_TARGET_S} s", refine < CALIBRATE_TARGET_S),
        "rotavat calibrate --method grid": (grid / floor, f"< {CALIBRATE_TARGET_S} s and <= refine",
                                            grid < CALIBRATE_TARGET_S and grid <= refine),
    }
    print(f"\n## Reading and calibrating {args.frames:,} frames x {args.people} people ({n_pairs:,} foot/head pairs)\n")
    print(f"Per frame, in one process (best of 5): rotavat's reader {ours_us:.0f} us, np.load {numpy_us:.0f} us: "
          f"**{ours_us / numpy_us:.2f}x** (target {checks['reading'][1]}: {'met' if checks['reading'][2] else 'MISSED'})\n")
    print(f"Whole processes, median of {runs} interleaved runs:\n")
    print("| command | seconds | x the numpy floor | target |")
    print("|---|---|---|---|")
    print(f"| numpy floor: np.load every frame | {floor:.2f} | 1.00x | |")
    for name in ("rotavat info", "rotavat calibrate (refine)", "rotavat calibrate --method grid"):
        ratio, target, ok = checks[name]
        print(f"| {name} | {times[name]:.2f} | {ratio:.2f}x | {target}: {'met' if ok else 'MISSED'} |")
    missed = [name for name, (_, _, ok) in checks.items() if not ok]
    if missed:
        print(f"\nmissed: {', '.join(missed)}")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
