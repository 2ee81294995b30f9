"""Benchmark of rotavat's start-up: what a user waits for before a command does anything.

    python benchmarks/bench_startup.py            # 9 runs of each command
    python benchmarks/bench_startup.py --quick    # 5 runs

Each command runs as a whole process (interpreter start, imports, the work, exit), in turn with the
others so a machine's drift touches them alike; the table gives the median wall seconds (min..max)
and the ratio to the bare interpreter measured in the same run. The last rows calibrate a 2D
sequence of 2,000 foot/head pairs with the paper's grid (``--method grid``) and compare it with the
same 50^3 grid written as a plain loop over cells (camera.py per cell, extrapolated from a
sample of cells, as bench_calibrate does): the speed-up a user sees, start-up included.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _synthetic_pairs import synthetic_pairs  # noqa: E402
from bench_calibrate import loop_baseline  # noqa: E402

from rotavat_cli.calibration.grid import GridSpec  # noqa: E402
from _measure import interleaved, rotavat_argv  # noqa: E402

PAIRS_FRAMES, PAIRS_PEOPLE = 100, 20  # 2,000 pairs


def write_pairs_sequence(folder: Path, seed: int = 7, frames: int = PAIRS_FRAMES,
                         people: int = PAIRS_PEOPLE) -> tuple[Path, object]:
    """A 2D-only sequence of ``frames`` npz frames of ``people`` walkers' foot/head pixels, 10% outliers (default
    2,000 pairs: 100 frames x 20 people); its data."""
    data = synthetic_pairs(np.random.default_rng(seed), frames=frames, people=people, outlier_fraction=0.1)
    folder.mkdir(parents=True, exist_ok=True)
    for t in range(frames):
        sel = data.frame_index == t
        np.savez(folder / f"{t:06d}.npz", feet_2d=data.feet_px[sel], heads_2d=data.heads_px[sel],
                 person_ids=data.track_id[sel])
    width, height = data.camera.image_size
    (folder / "meta.yaml").write_text(f"image_size: [{width}, {height}]\n")
    return folder, data


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="5 runs of each command instead of 9")
    args = parser.parse_args()
    runs = 5 if args.quick else 9
    rotavat = rotavat_argv()
    with tempfile.TemporaryDirectory() as tmp:
        seq, data = write_pairs_sequence(Path(tmp) / "pairs")
        commands = {
            "python -c pass (the interpreter)": [sys.executable, "-c", "pass"],
            "python -c 'import numpy'": [sys.executable, "-c", "import numpy"],
            "rotavat --version": [*rotavat, "--version"],
            "rotavat --help": [*rotavat, "--help"],
            "rotavat calibrate --help": [*rotavat, "calibrate", "--help"],
            "rotavat calibrate --method grid (2,000 pairs)": [*rotavat, "calibrate", str(seq), "--method", "grid",
                                                              "--out", str(Path(tmp) / "camera.yaml"), "--force", "-q"],
        }
        times = interleaved(commands, runs)
    base = statistics.median(times["python -c pass (the interpreter)"])
    print(f"\n## Start-up (whole processes, {runs} interleaved runs each, this machine)\n")
    print("| command | median s | min..max s | x the interpreter |")
    print("|---|---|---|---|")
    for name, values in times.items():
        median = statistics.median(values)
        print(f"| {name} | {median:.3f} | {min(values):.3f}..{max(values):.3f} | {median / base:.1f} |")
    spec = GridSpec()
    width, height = data.camera.image_size
    per_cell = loop_baseline(data.feet_px, data.heads_px, (width / 2.0, height / 2.0), spec.focal_values_px(height),
                             spec.pitch_values_rad(), spec.height_values_m(), 200 if args.quick else 1000)
    cells = math.prod(spec.steps)
    loop_s = per_cell * cells
    calibrate_s = statistics.median(times["rotavat calibrate --method grid (2,000 pairs)"])
    print(f"\nThe paper grid as a plain loop over its {cells:,} cells: {loop_s:.1f} s (extrapolated); "
          f"`rotavat calibrate --method grid`, start-up included: {calibrate_s:.2f} s, "
          f"{loop_s / calibrate_s:.1f}x faster.")


if __name__ == "__main__":
    main()
