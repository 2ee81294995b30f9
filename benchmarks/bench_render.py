"""Time ``rotavat render`` on one crowded frame: front + side + top, primary (OpenGL) and fallback (numpy).

Usage: python benchmarks/bench_render.py [--people 20] [--size 1280 720] [--repeats 3] [--renderers gl,fallback]

Builds one synthetic frame in memory (``rotavat synth`` bodies: 6,591 vertices / 13,178 triangles
each, on the ground of a random surveillance camera), then renders the three views of that one row
at ``--size`` per panel with each renderer and prints the best and median wall time of
``render_grid`` (shading, rasterising, overlays, compositing; the GL context is created once,
outside the timing, and its start-up is printed separately). Target: < 2 s with the primary renderer.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rotavat_cli.errors import RotavatError  # noqa: E402
from rotavat_cli.render import VIEWS, RenderStyle, RowFrame, open_rasterizer, render_grid, scene_extents  # noqa: E402
from rotavat_cli.synth import SynthOptions, synth_frames  # noqa: E402


def crowded_row(people: int, image_size: tuple[int, int]) -> RowFrame:
    """One ground-truth frame of ``people`` bodies as a figure row."""
    camera, _, frames = synth_frames(SynthOptions(seed=3, frames=1, people=people, image_size=image_size))
    gt, _ = next(frames)
    return RowFrame("gt", gt.data["vertices"], gt.data["faces"], gt.person_ids, camera.image_size,
                    camera.focal_px, camera.principal_point, camera)


def time_renderer(kind: str, row: RowFrame, size: tuple[int, int], repeats: int) -> dict:
    """Best/median seconds of one front+side+top render of ``row`` with renderer ``kind``."""
    style = RenderStyle()
    start = time.perf_counter()
    try:
        rasterizer = open_rasterizer(kind)
    except RotavatError as exc:
        return {"renderer": kind, "skipped": str(exc)}
    startup = time.perf_counter() - start
    with rasterizer:
        extents = scene_extents([row], VIEWS, size, style.margin)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            render_grid([row], VIEWS, size, rasterizer.rasterize, style, extents)
            times.append(time.perf_counter() - t0)
    return {"renderer": rasterizer.name, "detail": rasterizer.detail, "startup_s": round(startup, 3),
            "best_s": round(min(times), 3), "median_s": round(statistics.median(times), 3)}


def main() -> None:
    """Parse arguments, render, print one JSON line per renderer."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, default=20)
    parser.add_argument("--size", type=int, nargs=2, default=(1280, 720))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--renderers", default="gl,fallback")
    args = parser.parse_args()
    size = tuple(args.size)
    row = crowded_row(args.people, size)
    triangles = args.people * len(row.faces)
    for kind in args.renderers.split(","):
        result = time_renderer(kind.strip(), row, size, args.repeats)
        print(json.dumps({"people": args.people, "triangles": triangles, "panel": list(size), "views": list(VIEWS), **result}))


if __name__ == "__main__":
    main()
