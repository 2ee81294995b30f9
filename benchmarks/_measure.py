"""What several benchmarks measure the same way: CPU and wall time of a step, the bytes it wrote, the input floor,
how to start rotavat, free disk, and a table row against a baseline. Imported by the bench_*.py scripts (run as
scripts, this folder is on their path)."""

from __future__ import annotations

import os
import shutil
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
