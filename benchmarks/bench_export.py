"""Wall time of ``rotavat export SEQ`` (an animated .glb) against writing the same vertices as npz, and its memory
against length.

Usage: python benchmarks/bench_export.py [--frames 300] [--people 20] [--repeats 2] [--quick] [--workdir DIR] [--keep]

Writes one ``rotavat synth`` scene (``--frames`` frames x ``--people`` bodies of 6,591 vertices / 13,178
triangles; ``gt/`` with camera.yaml, about 85 kB per person-frame) in a temporary folder, reads it once so
every run starts from the page cache, then times in the same run (interleaved, best of ``--repeats``):

- read: ``open_sequence(gt).read_frame(name)`` for every frame (the input floor);
- npz, the baseline: the same reading, the world transform the export applies
  (:func:`rotavat_cli.geometry.camera.world_points_f32`, float32) and the same vertex bytes written with
  ``np.savez`` (uncompressed), one file per frame;
- ``export_animated`` (what ``rotavat export SEQ --out X.glb`` runs): both passes, per-frame meshes;
- the whole command ``rotavat export GT --out X.glb --quiet`` in a fresh process, once.

Memory: peak RSS of a fresh process exporting a sequence of the first tenth of the frames (links to them)
against one exporting all of them (the child's own ``VmHWM`` from /proc/self/status, else ``ru_maxrss`` of
``resource.getrusage``: on Linux ``ru_maxrss`` keeps the forking parent's RSS across exec).

Targets (issue 32): export / npz < 3x, and the whole sequence's peak RSS <= 1.25x the tenth's + 50 MB (flat:
frames are streamed, two passes). Exit status 1 when one is missed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rotavat_cli.exchange.animated import export_animated  # noqa: E402
from rotavat_cli.geometry.camera import world_points_f32  # noqa: E402
from rotavat_cli.sequence import open_sequence  # noqa: E402
from rotavat_cli.synth import SynthOptions, write_synth_scene  # noqa: E402
from _measure import (PEAK_KB_SOURCE, check_disk, read_all, rotavat_argv, row, run_or_exit,  # noqa: E402
                      scene_args, size_bytes, timed)

TARGET_RATIO = 3.0  # export / npz
TARGET_RSS_RATIO, RSS_SLACK_MB = 1.25, 50.0  # whole sequence vs its first tenth
KB_PER_PERSON_FRAME = 500  # disk: synth pred + gt (~170) + the largest output at once (~80) + npz (~80), doubled


def write_npz(seq_dir: Path, out: Path) -> None:
    """Read every frame, move its people's vertices to the world (float32) and np.savez them, one file per frame."""
    seq = open_sequence(seq_dir)
    out.mkdir(parents=True)
    for name in seq.frame_names:
        np.savez(out / f"{name}.npz", vertices=world_points_f32(seq.camera, seq.read_frame(name).data["vertices"]))


def run_cli(seq_dir: Path, out: Path) -> None:
    """The whole ``rotavat export`` command in a fresh process; SystemExit when it fails."""
    argv = [*rotavat_argv(), "export", str(seq_dir), "--out", str(out), "--quiet"]
    run_or_exit(argv, ROOT)


_CHILD = """
import sys
sys.path.insert(0, {root!r})
from pathlib import Path
from rotavat_cli.exchange.animated import export_animated
from rotavat_cli.sequence import open_sequence
{peak_kb}

start = peak_kb()
summary = export_animated(open_sequence({seq!r}), Path({out!r}))
print(summary["frames"], summary["bytes"], start, peak_kb())
"""


def first_frames(seq_dir: Path, n_frames: int, out: Path) -> Path:
    """A sequence of the first ``n_frames`` frames of ``seq_dir``: links to its frames, copies of its YAML files."""
    out.mkdir(parents=True, exist_ok=True)
    for name in ("meta.yaml", "camera.yaml"):
        shutil.copy(seq_dir / name, out / name)
    for frame in sorted(seq_dir.glob("*.npz"))[:n_frames]:
        (out / frame.name).symlink_to(frame)
    return out


def peak_rss_mb(seq_dir: Path, out: Path) -> tuple[int, int, float, float]:
    """(frames exported, bytes written, peak RSS after the imports, peak RSS at the end) in MB of a fresh process."""
    code = _CHILD.format(peak_kb=PEAK_KB_SOURCE, root=str(ROOT), seq=str(seq_dir), out=str(out))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"peak RSS child failed ({proc.returncode}): {proc.stderr.strip()[-500:]}")
    out.unlink(missing_ok=True)
    n, written, start_kb, peak_kb = proc.stdout.split()[-4:]
    return int(n), int(written), int(start_kb) / 1024.0, int(peak_kb) / 1024.0


def main() -> int:
    """Run the benchmark, print its tables; 0 when every target is met, else 1."""
    args = scene_args(__doc__.splitlines()[0])
    work = Path(args.workdir or tempfile.mkdtemp(prefix="rotavat-bench-export-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        check_disk(work, args.frames, args.people, KB_PER_PERSON_FRAME)
        scene = work / "scene"
        t0 = time.perf_counter()
        write_synth_scene(scene, SynthOptions(seed=0, frames=args.frames, people=args.people, image_size=(1280, 720)))
        gt = scene / "gt"
        shutil.rmtree(scene / "pred")  # not used: the ground truth has the camera
        print(f"wrote {args.frames} frames x {args.people} people ({size_bytes(gt) / 1e6:.0f} MB gt) in "
              f"{time.perf_counter() - t0:.0f} s")
        read_all(gt)  # warm the page cache
        steps = {
            "read": lambda out: read_all(gt),
            "npz": lambda out: write_npz(gt, out),
            "export": lambda out: export_animated(open_sequence(gt), out),
        }
        runs: dict[str, list[dict]] = {key: [] for key in steps}
        for i in range(args.repeats):  # interleaved: a drifting machine touches every step alike
            for key, step in steps.items():
                runs[key].append(timed(step, work / (f"{key}_{i}.glb" if key == "export" else f"{key}_{i}")))
        best = {key: {**min(rs, key=lambda r: r["s"]), "all": [r["s"] for r in rs]} for key, rs in runs.items()}
        cli = timed(lambda out: run_cli(gt, out), work / "cli.glb")
        npz = best["npz"]
        print()
        print(f"{args.frames} frames x {args.people} people (SMPL-sized meshes), best of {args.repeats}"
              f"{' (every run in brackets)' if args.repeats > 1 else ''}; ratios against the npz baseline\n")
        print("| step | wall s | MB written | MB/s | CPU s | vs npz |")
        print("|---|---|---|---|---|---|")
        print(row("read every frame (input floor)", best["read"], npz))
        print(row("**npz baseline**: read + world (float32) + np.savez", npz, npz))
        print(row("**export_animated** (two passes, per-frame meshes)", best["export"], npz))
        print(row("`rotavat export ... --quiet` (fresh process, once)", cli, npz))

        small = first_frames(gt, max(1, args.frames // 10), work / "tenth")
        n_small, bytes_small, base_small, rss_small = peak_rss_mb(small, work / "rss_small.glb")
        n_full, bytes_full, base_full, rss_full = peak_rss_mb(gt, work / "rss_full.glb")
        per_100 = (rss_full - rss_small) / (n_full - n_small) * 100 if n_full > n_small else float("nan")
        print(f"\npeak RSS (fresh process): {rss_small:.0f} MB exporting {n_small} frames ({bytes_small / 1e6:.0f} MB "
              f"written), {rss_full:.0f} MB exporting {n_full} frames ({bytes_full / 1e6:.0f} MB written) "
              f"({per_100:+.1f} MB per 100 frames); after the imports: {base_small:.0f} / {base_full:.0f} MB")

        ratio = best["export"]["s"] / npz["s"]
        limit = TARGET_RSS_RATIO * rss_small + RSS_SLACK_MB
        checks = [(f"export / npz < {TARGET_RATIO:.0f}x", f"{ratio:.2f}x", ratio < TARGET_RATIO),
                  (f"peak RSS {n_full} frames <= {TARGET_RSS_RATIO}x {n_small} frames + {RSS_SLACK_MB:.0f} MB "
                   f"({limit:.0f} MB)", f"{rss_full:.0f} MB ({rss_full / rss_small:.2f}x)", rss_full <= limit)]
        print("\n| target | measured | result |")
        print("|---|---|---|")
        for name, value, ok in checks:
            print(f"| {name} | {value} | {'PASS' if ok else 'MISS'} |")
        ok_all = all(ok for _, _, ok in checks)
        print(f"\n{'all targets met' if ok_all else 'some targets MISSED'}")
        print(json.dumps({"frames": args.frames, "people": args.people, "repeats": args.repeats,
                          **{k: round(v["s"], 3) for k, v in best.items()}, "cli": round(cli["s"], 3),
                          "glb_mb": round(best["export"]["bytes"] / 1e6, 1),
                          "rss_mb": [round(rss_small, 1), round(rss_full, 1)]}))
        return 0 if ok_all else 1
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
