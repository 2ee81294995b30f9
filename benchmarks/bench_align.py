"""Throughput of ``rotavat align`` against its I/O floor, and its memory against sequence length.

Usage: python benchmarks/bench_align.py [--frames 1000] [--people 10] [--repeats 3] [--workdir DIR] [--keep]

Writes a sequence of ``--frames`` npz frames with ``--people`` SMPL-sized meshes each (6,890
vertices, 24 joints, float32: synthetic bodies from ``rotavat synth`` padded to SMPL's vertex
count, so the SMPL landmark indices apply; the geometry is not meaningful, the work is), then
times, in the same run (interleaved, best of ``--repeats``):

- the I/O floor: read every frame and write it back unchanged (same reader and writer);
- ``align_sequence`` (RotAvat + people.csv + camera.yaml), end to end;

and prints meshes per second and the ratio align / floor (target <= 1.3x), plus the CPU time of
each (all processes: align runs in worker processes, so its wall time depends on free cores while
its CPU time does not). Peak memory (RSS) is measured in child processes aligning the first 20%
and the whole sequence: flat memory means frames are streamed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rotavat_cli.allocator import keep_freed_memory  # noqa: E402
from rotavat_cli.alignment.align import align_sequence  # noqa: E402
from rotavat_cli.sequence import Frame, open_sequence, write_frame, write_meta  # noqa: E402
from rotavat_cli.synth import SynthOptions, synth_frames  # noqa: E402
from _measure import cpu_seconds  # noqa: E402

SMPL_VERTS = 6890
RATIO_TARGET = 1.3  # align's wall time / the I/O floor's
RSS_TARGET = 1.25  # the whole sequence's peak RSS / the first 20%'s: flat memory


def make_sequence(path: Path, n_frames: int, n_people: int) -> object:
    """A pred-like npz sequence of SMPL-sized meshes; returns the true camera."""
    camera, focal, frames = synth_frames(SynthOptions(seed=0, frames=1, people=n_people))
    _, pred = next(frames)
    verts = pred.data["vertices"]
    pad = verts[:, : SMPL_VERTS - verts.shape[1]]
    base = np.concatenate([verts, pad], axis=1)  # (P, 6890, 3) float32
    rng = np.random.default_rng(0)
    for t in range(n_frames):
        jitter = rng.normal(0.0, 0.01, (n_people, 1, 3)).astype(np.float32)
        data = {"vertices": base + jitter, "joints": pred.data["joints"] + jitter,
                "person_ids": pred.data["person_ids"], "focal_length": np.float64(focal)}
        write_frame(path, Frame(f"{t:06d}", data), "npz")
    write_meta(path, {"image_size": list(camera.image_size), "focal_length": focal})
    return camera


def io_floor(seq_path: Path, out: Path) -> tuple[float, float]:
    """Wall and CPU seconds to read every frame and write it back unchanged."""
    start, cpu = time.perf_counter(), cpu_seconds()
    seq = open_sequence(seq_path)
    for frame in seq.frames():
        write_frame(out, frame, seq.form)
    return time.perf_counter() - start, cpu_seconds() - cpu


def time_align(seq_path: Path, out: Path, camera) -> tuple[float, float]:
    """Wall and CPU seconds for align_sequence end to end."""
    start, cpu = time.perf_counter(), cpu_seconds()
    align_sequence(open_sequence(seq_path), camera, out)
    return time.perf_counter() - start, cpu_seconds() - cpu


_CHILD = """
import json, resource, sys
sys.path.insert(0, {root!r})
from rotavat_cli.allocator import keep_freed_memory
keep_freed_memory()
from rotavat_cli.alignment.align import align_sequence
from rotavat_cli.sequence import open_sequence, Sequence
from rotavat_cli.geometry.camera import camera_from_yaml_dict
seq = open_sequence({seq!r})
seq = Sequence(seq.path, seq.form, seq.frame_names[:{n}], seq.meta)
align_sequence(seq, camera_from_yaml_dict(json.loads({cam!r})), {out!r})
print(max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
"""


def peak_rss_mb(seq_path: Path, out: Path, camera, n_frames: int) -> float:
    """Peak RSS (MB) of the largest process (main or worker) aligning the first ``n_frames`` frames."""
    from rotavat_cli.geometry.camera import camera_to_yaml_dict

    code = _CHILD.format(root=str(Path(__file__).resolve().parents[1]), seq=str(seq_path), n=n_frames,
                         cam=json.dumps(camera_to_yaml_dict(camera)), out=str(out))
    kb = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout.split()[-1]
    return int(kb) / 1024.0


def main() -> int:
    """Run the benchmark and print its table; 1 when a target is missed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--people", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved runs of each; the best is kept")
    parser.add_argument("--workdir", type=Path, default=None)
    parser.add_argument("--keep", action="store_true")
    args = parser.parse_args()
    keep_freed_memory()  # as the command line does (rotavat_cli/cli/__init__.py): floor and align alike
    work = Path(args.workdir or tempfile.mkdtemp(prefix="rotavat-bench-align-"))
    try:
        seq = work / "seq"
        t0 = time.perf_counter()
        camera = make_sequence(seq, args.frames, args.people)
        print(f"wrote {args.frames} frames x {args.people} meshes of {SMPL_VERTS} vertices in {time.perf_counter() - t0:.1f} s")
        io_floor(seq, work / "warm")  # warm the page cache for both measurements
        shutil.rmtree(work / "warm")
        floors, aligns = [], []
        for i in range(args.repeats):  # interleaved, so the machine's drift (page cache, writeback) touches both
            os.sync()  # each run starts without the kernel writing back an earlier run's (or the input's) frames
            floors.append(io_floor(seq, work / f"floor{i}"))
            os.sync()
            aligns.append(time_align(seq, work / f"aligned{i}", camera))
            shutil.rmtree(work / f"floor{i}")
            shutil.rmtree(work / f"aligned{i}")
        (floor, floor_cpu), (aligned, aligned_cpu) = min(floors), min(aligns)
        meshes = args.frames * args.people
        print()
        print("| step | seconds | meshes/s | ratio to I/O floor | CPU seconds (ratio) |")
        print("|---|---|---|---|---|")
        print(f"| I/O floor (read + write) | {floor:.2f} | {meshes / floor:,.0f} | 1.00x | {floor_cpu:.2f} (1.00x) |")
        print(f"| align (RotAvat + people.csv) | {aligned:.2f} | {meshes / aligned:,.0f} | {aligned / floor:.2f}x (target <= {RATIO_TARGET}x) "
              f"| {aligned_cpu:.2f} ({aligned_cpu / floor_cpu:.2f}x) |")
        small = max(1, args.frames // 5)
        rss_small = peak_rss_mb(seq, work / "rss_small", camera, small)
        rss_full = peak_rss_mb(seq, work / "rss_full", camera, args.frames)
        print()
        print(f"peak RSS: {rss_small:.0f} MB for {small} frames, {rss_full:.0f} MB for {args.frames} frames "
              f"(ratio {rss_full / rss_small:.2f}: flat means streamed)")
        missed = [what for what, ok in ((f"align {aligned / floor:.2f}x its I/O floor (target <= {RATIO_TARGET}x)",
                                         aligned / floor <= RATIO_TARGET),
                                        (f"peak RSS {rss_full / rss_small:.2f}x the 20% run's (target <= {RSS_TARGET}x)",
                                         rss_full / rss_small <= RSS_TARGET)) if not ok]
        if missed:
            print(f"\nmissed: {'; '.join(missed)}")
        return 1 if missed else 0
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
