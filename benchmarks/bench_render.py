"""Time ``rotavat render`` on one crowded frame: front + side + top, primary (OpenGL) and fallback (numpy).

Usage: python benchmarks/bench_render.py [--people 20] [--size 1280 720] [--repeats 3] [--renderers gl,fallback]

Builds one synthetic frame in memory (``rotavat synth`` bodies: 6,591 vertices / 13,178 triangles
each, on the ground of a random surveillance camera), then renders the three views of that one row
at ``--size`` per panel with each renderer and prints the best and median wall time of
``render_grid`` (shading, rasterising, overlays, compositing; the GL context is created once,
outside the timing, and its start-up is printed separately). Target: < 2 s with the primary renderer.

Against its floor, measured in the same run with the same renderer: a frame as ``rotavat render`` makes it
(``render_grid`` + the PNG written as ``render_sequences`` writes it) against the unavoidable part of it: the same
rasteriser calls on the same triangles (recorded from a ``render_grid`` run and replayed) and a PNG of the same
size. Target: frame / floor <= 2x with every renderer that runs. Exit status 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import statistics
import sys
import time
from pathlib import Path

# As the command line runs (rotavat_cli/cli/__init__.py): BLAS single-threaded unless the environment says otherwise.
for _blas_threads in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_blas_threads, "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from rotavat_cli.errors import RotavatError  # noqa: E402
from rotavat_cli.render import VIEWS, RenderStyle, RowFrame, open_rasterizer, render_grid, scene_extents  # noqa: E402
from rotavat_cli.synth import SynthOptions, synth_frames  # noqa: E402


def crowded_row(people: int, image_size: tuple[int, int]) -> RowFrame:
    """One ground-truth frame of ``people`` bodies as a figure row."""
    camera, _, frames = synth_frames(SynthOptions(seed=3, frames=1, people=people, image_size=image_size))
    gt, _ = next(frames)
    return RowFrame("gt", gt.data["vertices"], gt.data["faces"], gt.person_ids, camera.image_size,
                    camera.focal_px, camera.principal_point, camera)


TARGET_FLOOR_RATIO = 2.0  # a frame (render_grid + PNG) / its floor (the same rasteriser calls + a PNG)


def png_bytes(image: np.ndarray) -> int:
    """Encode an (H, W, 3) uint8 image as ``render_sequences`` writes it (PNG, not optimised); its size in bytes."""
    out = io.BytesIO()
    Image.fromarray(image).save(out, format="PNG", optimize=False)
    return out.tell()


def time_renderer(kind: str, row: RowFrame, size: tuple[int, int], repeats: int) -> dict:
    """Best/median seconds of one front+side+top render of ``row`` with renderer ``kind``, and of a whole frame
    (render + PNG) against its floor (the same rasteriser calls replayed + a PNG of the same size)."""
    style = RenderStyle()
    start = time.perf_counter()
    try:
        rasterizer = open_rasterizer(kind)
    except RotavatError as exc:
        return {"renderer": kind, "skipped": str(exc)}
    startup = time.perf_counter() - start
    with rasterizer:
        extents = scene_extents([row], VIEWS, size, style.margin)
        calls = []

        def recording(*args):
            calls.append(args)
            return rasterizer.rasterize(*args)

        image = render_grid([row], VIEWS, size, recording, style, extents)  # warm, and the calls of one frame
        times, frame, floor = [], [], []
        for _ in range(repeats):  # interleaved
            t0 = time.perf_counter()
            render_grid([row], VIEWS, size, rasterizer.rasterize, style, extents)
            times.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            png_bytes(render_grid([row], VIEWS, size, rasterizer.rasterize, style, extents))
            frame.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            for args in calls:
                rasterizer.rasterize(*args)
            png_bytes(image)
            floor.append(time.perf_counter() - t0)
    return {"renderer": rasterizer.name, "detail": rasterizer.detail, "startup_s": round(startup, 3),
            "best_s": round(min(times), 3), "median_s": round(statistics.median(times), 3),
            "frame_s": round(min(frame), 4), "floor_s": round(min(floor), 4), "rasterize_calls": len(calls),
            "frame_vs_floor": round(min(frame) / min(floor), 3)}


def main() -> int:
    """Parse arguments, render, print one JSON line per renderer and the targets; 0 when every one is met, else 1."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, default=20)
    parser.add_argument("--size", type=int, nargs=2, default=(1280, 720))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--renderers", default="gl,fallback")
    args = parser.parse_args()
    size = tuple(args.size)
    row = crowded_row(args.people, size)
    triangles = args.people * len(row.faces)
    results = []
    for kind in args.renderers.split(","):
        result = time_renderer(kind.strip(), row, size, args.repeats)
        results.append(result)
        print(json.dumps({"people": args.people, "triangles": triangles, "panel": list(size), "views": list(VIEWS), **result}))
    print("\n| renderer | frame (render + PNG) ms | floor (same rasteriser calls + PNG) ms | frame / floor | target | result |")
    print("|---|---|---|---|---|---|")
    ok_all = True
    for result in results:
        if "skipped" in result:
            print(f"| {result['renderer']} | skipped: {result['skipped']} | | | | |")
            continue
        ok = result["frame_vs_floor"] <= TARGET_FLOOR_RATIO
        ok_all &= ok
        print(f"| {result['renderer']} | {1e3 * result['frame_s']:.0f} | {1e3 * result['floor_s']:.0f} | "
              f"{result['frame_vs_floor']:.2f}x | <= {TARGET_FLOOR_RATIO}x | {'PASS' if ok else 'MISS'} |")
    print(f"\n{'all targets met' if ok_all else 'some targets MISSED'}")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
