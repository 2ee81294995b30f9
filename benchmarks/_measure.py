"""What several benchmarks measure the same way: CPU and wall time of a step, the bytes it wrote, the input floor,
how to start rotavat and time whole processes, free disk, and a table row against a baseline. Imported by the bench_*.py scripts (run as
scripts, this folder is on their path)."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from rotavat_cli.sequence import open_sequence


def cpu_seconds() -> float:
    """User + system CPU time of this process (every thread) and its finished children."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def size_bytes(path: Path) -> int:
    """Bytes of a file, or of every file under a folder."""
    return path.stat().st_size if path.is_file() else sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def timed(step: Callable[[Path], None], out: Path) -> dict:
    """Wall and CPU seconds of ``step(out)``, and the bytes it wrote there (then deleted: the disk is not filled)."""
    start, cpu = time.perf_counter(), cpu_seconds()
    step(out)
    result = {"s": time.perf_counter() - start, "cpu": cpu_seconds() - cpu, "bytes": size_bytes(out) if out.exists() else 0}
    if out.is_dir():
        shutil.rmtree(out)
    elif out.exists():
        out.unlink()
    return result


def read_all(seq_dir: Path) -> None:
    """Read every frame of the sequence (the input floor)."""
    seq = open_sequence(seq_dir)
    for name in seq.frame_names:
        seq.read_frame(name)


def wall_seconds(argv: list[str]) -> float:
    """Wall seconds of one whole process; RuntimeError when it fails."""
    start = time.perf_counter()
    proc = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} exited {proc.returncode}: {proc.stderr.strip()[-300:]}")
    return seconds


def interleaved(commands: dict[str, list[str]], runs: int) -> dict[str, list[float]]:
    """Each command ``runs`` times, in turn (after one warm-up each), so a machine's drift touches them alike;
    name -> wall seconds."""
    for argv in commands.values():
        wall_seconds(argv)
    times: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(runs):
        for name, argv in commands.items():
            times[name].append(wall_seconds(argv))
    return times


def rotavat_argv() -> list[str]:
    """How to start rotavat: the console script beside this interpreter, else the same entry point."""
    script = Path(sys.executable).with_name("rotavat")
    return [str(script)] if script.exists() else [sys.executable, "-c", "from rotavat_cli.cli import main; main()"]


def check_disk(work: Path, frames: int, people: int, kb_per_person_frame: float) -> None:
    """Say how much disk is free against what the run needs; SystemExit when it is short."""
    need = frames * people * kb_per_person_frame * 1e3 + 200e6
    free = shutil.disk_usage(work).free
    print(f"free disk at {work}: {free / 1e9:.1f} GB (the run needs about {need / 1e9:.1f} GB)")
    if free < need:
        raise SystemExit(f"not enough free disk at {work}: {free / 1e9:.1f} GB free, about {need / 1e9:.1f} GB needed "
                         "(use --workdir elsewhere or fewer --frames)")


def row(name: str, r: dict, floor: dict | None) -> str:
    """One table row: wall s, MB, MB/s, CPU s and the ratio to the npz baseline."""
    mb = r["bytes"] / 1e6
    rate = f"{mb / r['s']:.0f}" if mb else "-"
    ratio = f"{r['s'] / floor['s']:.2f}x" if floor else "-"
    seconds = f"{r['s']:.2f}" + (f" ({', '.join(f'{s:.2f}' for s in r['all'])})" if len(r.get("all", [])) > 1 else "")
    return f"| {name} | {seconds} | {mb:.0f} | {rate} | {r['cpu']:.2f} | {ratio} |"


def run_or_exit(argv: list[str], cwd: Path) -> None:
    """Run a whole command in a fresh process; SystemExit naming it when it fails."""
    proc = subprocess.run(argv, cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}): {proc.stderr.strip()[-500:]}")


# A child process's own high-water mark (``peak_kb()``), for the peak-RSS children's code (``{peak_kb}`` in it).
PEAK_KB_SOURCE = '''
import resource

def peak_kb():
    # this process's own high-water mark: ru_maxrss also keeps the forking parent's RSS across exec
    try:
        with open("/proc/self/status") as f:
            return int(next(line.split()[1] for line in f if line.startswith("VmHWM:")))
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
'''


def scene_args(description: str) -> argparse.Namespace:
    """The options of a benchmark over a synthetic scene; ``--quick`` only changes the defaults of the others."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="60 frames x 20 people, 1 repeat")
    parser.add_argument("--frames", type=int, default=None, help="frames of the scene (default 300, quick 60)")
    parser.add_argument("--people", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=None, help="best of this many runs of each step (default 2, quick 1)")
    parser.add_argument("--workdir", type=Path, default=None, help="default: a new temporary folder, deleted at the end")
    parser.add_argument("--keep", action="store_true", help="keep the work folder")
    args = parser.parse_args()
    args.frames = args.frames or (60 if args.quick else 300)
    args.repeats = max(1, args.repeats or (1 if args.quick else 2))
    return args
