"""Wall time of ``rotavat view`` (a Rerun .rrd) against writing the same frames as npz, and its memory against length.

Usage: python benchmarks/bench_view.py [--frames 300] [--people 20] [--repeats 2] [--quick] [--workdir DIR] [--keep]

Writes one ``rotavat synth`` scene (``--frames`` frames x ``--people`` bodies of 6,591 vertices / 13,178
triangles, 1280x720; ``gt/`` with camera.yaml and ``pred/``, about 85 kB per person-frame each) in a
temporary folder, reads it once so every run starts from the page cache, then times in the same run
(interleaved, best of ``--repeats``):

- read: ``open_sequence(pred).read_frame(name)`` for every frame (the input floor);
- npz, the baseline: the same reading, the same world transform the recording applies
  (:func:`rotavat_cli.geometry.camera.world_points_f32`, float32) and the same vertex bytes written with
  ``np.savez`` (uncompressed), one file per frame: a recording minus Rerun (and minus the normals);
- npz with ``Camera.world_from_cam(v).astype(np.float32)`` (float64 temporaries), for reference only: the
  ratios are against the row above. Its extra cost is mostly page faults of fresh 3 MB temporaries, so it
  depends on the allocator's state: 2-4x the float32 transform in a fresh process, about the same here,
  after synth's large arrays have raised glibc's mmap threshold;
- ``record_sequences`` (what ``rotavat view`` runs) with the default options (vertex normals on), and
  with ``normals=False``;
- the whole command ``rotavat view PRED --camera GT/camera.yaml --out X.rrd --quiet`` in a fresh process
  (interpreter start, imports, camera gate; the progress bar's callbacks run, it draws nothing without a
  terminal), once.

Each row gives wall seconds, MB written, MB/s and its CPU seconds (every thread: Rerun encodes and
writes on threads of its own, so on a busy machine its wall time suffers more than its CPU time).

Memory: peak RSS of a fresh process recording the first third of the frames
(``ViewOptions(frames="0,1,...")``) against one recording all of them, same scene, default options
(the child's own ``VmHWM`` from /proc/self/status, else ``ru_maxrss``: on Linux ``ru_maxrss`` keeps
the forking parent's RSS across exec, so a child of this ~230 MB process would read 230 MB whatever it did).

Targets (the issue: "300 frames x 20 people written in seconds"; the order of magnitude is what counts):
recording / npz <= 10x with normals on and off, and the whole sequence's peak RSS <= 1.25x the third's
+ 50 MB (flat: frames are streamed). Exit status 1 when one is missed.
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

from rotavat_cli.sequence import open_sequence, read_camera_yaml  # noqa: E402
from rotavat_cli.synth import SynthOptions, write_synth_scene  # noqa: E402
from rotavat_cli.view import ViewOptions, record_sequences, require_rerun  # noqa: E402
from rotavat_cli.geometry.camera import world_points_f32  # noqa: E402
from _measure import (PEAK_KB_SOURCE, check_disk, read_all, rotavat_argv, row, run_or_exit,  # noqa: E402
                      scene_args, size_bytes, timed)

TARGET_RATIO = 10.0  # recording / npz
TARGET_RSS_RATIO, RSS_SLACK_MB = 1.25, 50.0  # whole sequence vs its first third
KB_PER_PERSON_FRAME = 600  # disk: synth pred + gt (~170) + the largest output at once (~160) + npz (~80), doubled


def write_npz(pred: Path, camera_yaml: Path, out: Path, float64: bool = False) -> None:
    """Read every frame, move its people's vertices to the world (float32) and np.savez them, one file per frame."""
    camera, _ = read_camera_yaml(camera_yaml)
    seq = open_sequence(pred)
    out.mkdir(parents=True)
    for name in seq.frame_names:
        verts = seq.read_frame(name).data["vertices"]
        world = camera.world_from_cam(verts).astype(np.float32) if float64 else world_points_f32(camera, verts)
        np.savez(out / f"{name}.npz", vertices=world)


def record(pred: Path, camera_yaml: Path, out: Path, normals: bool = True) -> None:
    """``record_sequences`` of the pred sequence in the ground truth's camera."""
    record_sequences([open_sequence(pred)], out, None, ViewOptions(camera_path=camera_yaml, normals=normals))


def run_cli(pred: Path, camera_yaml: Path, out: Path) -> None:
    """The whole ``rotavat view`` command in a fresh process; SystemExit when it fails."""
    argv = [*rotavat_argv(), "view", str(pred), "--camera", str(camera_yaml), "--out", str(out), "--quiet"]
    run_or_exit(argv, ROOT)


_CHILD = """
import sys
sys.path.insert(0, {root!r})
from pathlib import Path
from rotavat_cli.sequence import open_sequence
from rotavat_cli.view import ViewOptions, record_sequences, require_rerun
{peak_kb}

require_rerun()
start = peak_kb()
summary = record_sequences([open_sequence({pred!r})], Path({out!r}), None, ViewOptions(camera_path=Path({camera!r}), frames={frames!r}))
print(summary.frames, start, peak_kb())
"""


def peak_rss_mb(pred: Path, camera_yaml: Path, out: Path, n_frames: int, total: int) -> tuple[int, float, float]:
    """(frames recorded, peak RSS after the imports, peak RSS at the end) in MB of a fresh process recording
    the first ``n_frames`` frames."""
    frames = None if n_frames >= total else ",".join(str(i) for i in range(n_frames))
    code = _CHILD.format(peak_kb=PEAK_KB_SOURCE, root=str(ROOT), pred=str(pred), out=str(out), camera=str(camera_yaml), frames=frames)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"peak RSS child failed ({proc.returncode}): {proc.stderr.strip()[-500:]}")
    out.unlink(missing_ok=True)
    n, start_kb, peak_kb = proc.stdout.split()[-3:]
    return int(n), int(start_kb) / 1024.0, int(peak_kb) / 1024.0


def main() -> int:
    """Run the benchmark, print its tables; 0 when every target is met, else 1."""
    args = scene_args(__doc__.splitlines()[0])
    require_rerun()
    work = Path(args.workdir or tempfile.mkdtemp(prefix="rotavat-bench-view-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        check_disk(work, args.frames, args.people, KB_PER_PERSON_FRAME)
        scene = work / "scene"
        t0 = time.perf_counter()
        write_synth_scene(scene, SynthOptions(seed=0, frames=args.frames, people=args.people, image_size=(1280, 720)))
        pred, camera_yaml = scene / "pred", scene / "gt" / "camera.yaml"
        print(f"wrote {args.frames} frames x {args.people} people ({size_bytes(pred) / 1e6:.0f} MB pred, "
              f"{size_bytes(scene / 'gt') / 1e6:.0f} MB gt) in {time.perf_counter() - t0:.0f} s")
        read_all(pred)  # warm the page cache
        steps = {
            "read": lambda out: read_all(pred),
            "npz": lambda out: write_npz(pred, camera_yaml, out),
            "npz64": lambda out: write_npz(pred, camera_yaml, out, float64=True),
            "rec": lambda out: record(pred, camera_yaml, out),
            "rec_nonormals": lambda out: record(pred, camera_yaml, out, normals=False),
        }
        runs: dict[str, list[dict]] = {key: [] for key in steps}
        for i in range(args.repeats):  # interleaved: a drifting machine touches every step alike
            for key, step in steps.items():
                runs[key].append(timed(step, work / (f"{key}_{i}.rrd" if key.startswith("rec") else f"{key}_{i}")))
        best = {key: {**min(rs, key=lambda r: r["s"]), "all": [r["s"] for r in rs]} for key, rs in runs.items()}
        cli = timed(lambda out: run_cli(pred, camera_yaml, out), work / "cli.rrd")
        npz = best["npz"]
        print()
        print(f"{args.frames} frames x {args.people} people (SMPL-sized meshes), best of {args.repeats}"
              f"{' (every run in brackets)' if args.repeats > 1 else ''}; ratios against the npz baseline\n")
        print("| step | wall s | MB written | MB/s | CPU s | vs npz |")
        print("|---|---|---|---|---|---|")
        print(row("read every frame (input floor)", best["read"], npz))
        print(row("**npz baseline**: read + world (float32) + np.savez", npz, npz))
        print(row("npz, Camera.world_from_cam (float64) transform", best["npz64"], npz))
        print(row("**record_sequences**, default (normals on)", best["rec"], npz))
        print(row("record_sequences, normals=False", best["rec_nonormals"], npz))
        print(row("`rotavat view ... --quiet` (fresh process, once)", cli, npz))

        small = max(1, args.frames // 3)
        n_small, base_small, rss_small = peak_rss_mb(pred, camera_yaml, work / "rss_small.rrd", small, args.frames)
        n_full, base_full, rss_full = peak_rss_mb(pred, camera_yaml, work / "rss_full.rrd", args.frames, args.frames)
        per_100 = (rss_full - rss_small) / (n_full - n_small) * 100 if n_full > n_small else float("nan")
        print(f"\npeak RSS (fresh process, default options): {rss_small:.0f} MB recording {n_small} frames, {rss_full:.0f} MB "
              f"recording {n_full} frames ({per_100:+.1f} MB per 100 frames); after the imports: {base_small:.0f} / "
              f"{base_full:.0f} MB")

        checks = [(f"recording (normals on) / npz <= {TARGET_RATIO:.0f}x", best["rec"]["s"] / npz["s"], TARGET_RATIO),
                  (f"recording (normals off) / npz <= {TARGET_RATIO:.0f}x", best["rec_nonormals"]["s"] / npz["s"], TARGET_RATIO)]
        limit = TARGET_RSS_RATIO * rss_small + RSS_SLACK_MB
        print("\n| target | measured | result |")
        print("|---|---|---|")
        ok_all = True
        for name, value, bound in checks:
            ok = value <= bound
            ok_all &= ok
            print(f"| {name} | {value:.2f}x | {'PASS' if ok else 'MISS'} |")
        ok = rss_full <= limit
        ok_all &= ok
        print(f"| peak RSS {n_full} frames <= {TARGET_RSS_RATIO}x {n_small} frames + {RSS_SLACK_MB:.0f} MB ({limit:.0f} MB) "
              f"| {rss_full:.0f} MB ({rss_full / rss_small:.2f}x) | {'PASS' if ok else 'MISS'} |")
        print(f"\n{'all targets met' if ok_all else 'some targets MISSED'}")
        print(json.dumps({"frames": args.frames, "people": args.people, "repeats": args.repeats,
                          **{k: round(v["s"], 3) for k, v in best.items()}, "cli": round(cli["s"], 3),
                          "rss_mb": [round(rss_small, 1), round(rss_full, 1)]}))
        return 0 if ok_all else 1
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
