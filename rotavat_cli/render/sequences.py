"""Figures of sequences on disk: what ``rotavat render`` runs (PNG per frame, optional GIF and GLB).

One grid row per sequence (:mod:`.rows` reads them), one column per view (:mod:`.views`), drawn
by :func:`.grid.render_grid` with the rasteriser :func:`.raster.open_rasterizer` picks. Defaults:
the packaged configs/default.yaml, section ``render``, is their one source (``FigureOptions()`` is
``FigureOptions.from_config(default_config()["render"])``).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_open
from ..camera import Camera
from ..config import packaged_default
from ..errors import InputError
from ..sequence import Sequence
from .export import build_scene, write_glb
from .grid import render_grid
from .raster import RENDERERS, open_rasterizer
from .rows import frame_names, no_camera, read_row, row_labels, sequence_camera
from .style import RenderStyle
from .views import RowFrame, parse_views, scene_extents, view_specs

__all__ = ["FigureOptions", "FigureSummary", "render_sequences"]


@functools.lru_cache(maxsize=1)
def _packaged_options() -> "FigureOptions":
    """FigureOptions of the packaged ``render:`` section (read once)."""
    from ..config import default_config

    return FigureOptions.from_config(default_config()["render"])


@dataclass(frozen=True)
class FigureOptions:
    """Everything ``rotavat render`` can vary; defaults from configs/default.yaml, section ``render``."""

    views: tuple[str, ...] = packaged_default(_packaged_options, "views")
    size: tuple[int, int] = packaged_default(_packaged_options, "size")
    frames: str | None = packaged_default(_packaged_options, "frames")  # "0,10,-1"; None = the first (or every)
    every: int | None = packaged_default(_packaged_options, "every")
    renderer: str = packaged_default(_packaged_options, "renderer")
    camera_path: Path | None = None  # not a config key: --camera
    image_dir: Path | None = None  # not a config key: --image
    gif: bool = packaged_default(_packaged_options, "gif")
    fps: float = packaged_default(_packaged_options, "fps")
    glb: bool = packaged_default(_packaged_options, "glb")
    style: RenderStyle = packaged_default(_packaged_options, "style")

    @classmethod
    def from_config(cls, render: dict, camera_path: Path | None = None, image_dir: Path | None = None) -> "FigureOptions":
        """Options from a merged ``render`` config section; ValueError naming a bad option."""
        if render["renderer"] not in RENDERERS:
            raise ValueError(f"--renderer (render.renderer) must be one of {', '.join(RENDERERS)}, got {render['renderer']!r}")
        if min(render["size"]) < 16 or max(render["size"]) > 8192:
            raise ValueError(f"--size (render.size) must be between 16 and 8192 px, got {render['size']}")
        if render["fps"] <= 0:
            raise ValueError(f"render.fps must be > 0, got {render['fps']}")
        return cls(parse_views(render["views"]), tuple(render["size"]),
                   None if render["frames"] is None else str(render["frames"]), render["every"], render["renderer"],
                   camera_path, image_dir, render["gif"], float(render["fps"]), render["glb"], RenderStyle.from_config(render))


@dataclass
class FigureSummary:
    """What was rendered, by which renderer, and where it went."""

    out: str
    renderer: str
    renderer_detail: str
    renderer_note: str
    rows: list[str]
    views: list[str]
    frames: list[str]
    files: list[str]
    seconds: float
    seconds_per_frame: float

    def moved_to(self, out: str | Path) -> "FigureSummary":
        """The same summary once its folder was moved to ``out`` (a staging folder swapped in)."""
        files = [str(Path(out) / Path(f).name) for f in self.files]
        return dataclasses.replace(self, out=str(out), files=files)


def _cameras(seqs: list[Sequence], opts: FigureOptions, needs: str) -> list[Camera | None]:
    """Each sequence's camera (``opts.camera_path``, else its own); an error naming what ``needs`` one if it is missing."""
    cameras = [sequence_camera(s, opts.camera_path) for s in seqs]
    if needs:
        for seq, cam in zip(seqs, cameras):
            if cam is None:
                raise no_camera(seq, needs)
    return cameras


def _save_png(path: Path, image: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 image as PNG atomically."""
    from PIL import Image

    with atomic_open(path, "wb") as handle:
        Image.fromarray(image).save(handle, format="PNG", optimize=False)


def _save_gif(path: Path, images: list[np.ndarray], fps: float) -> None:
    """Write frames as a looping GIF atomically."""
    from PIL import Image

    frames = [Image.fromarray(im).convert("P", palette=Image.ADAPTIVE, colors=255) for im in images]
    with atomic_open(path, "wb") as handle:
        frames[0].save(handle, format="GIF", save_all=True, append_images=frames[1:], duration=int(round(1000 / fps)), loop=0)


def render_sequences(seqs: list[Sequence], out: Path, opts: FigureOptions | None = None,
                     progress: Callable[[], None] | None = None) -> FigureSummary:
    """Render the chosen frames of one or more sequences as labelled grids in ``out`` (PNG per frame,
    optional GIF/GLB): one grid row per sequence, frames named by the first sequence."""
    opts = FigureOptions() if opts is None else opts
    if not seqs:
        raise InputError("give at least one sequence directory")
    placed = [view.name for view in view_specs(opts.views) if view.needs_camera]  # views placing rows in the world
    needs = [f"{'/'.join(placed)} views"] if placed else []
    if opts.glb:
        needs.append("the GLB")
    cameras = _cameras(seqs, opts, " and ".join(needs))
    labels = row_labels([Path(s.label) for s in seqs])
    names = frame_names(seqs[0], opts.frames, opts.every)

    def rows_of(name: str, image_dir: Path | None = None) -> list[RowFrame]:
        return [read_row(s, name, lab, cam, image_dir) for s, lab, cam in zip(seqs, labels, cameras)]

    start = time.perf_counter()
    # pass 1: one shared metric extent for every row and frame, so all pictures compare at one scale
    extents = {}
    if placed:
        extents = scene_extents([r for n in names for r in rows_of(n)], tuple(placed), opts.size, opts.style.margin)
    files, images = [], []
    with open_rasterizer(opts.renderer) as rasterizer:
        for name in names:
            rows = rows_of(name, opts.image_dir)
            image = render_grid(rows, opts.views, opts.size, rasterizer.rasterize, opts.style, extents, title=f"frame {name}")
            _save_png(out / f"{name}.png", image)
            files.append(str(out / f"{name}.png"))
            if opts.gif:
                images.append(image)
            if opts.glb:
                scene = build_scene(rows, rows[0].camera, opts.style.palette)
                files.append(str(write_glb(out / f"{name}.glb", scene, rows[0].camera)))
            if progress:
                progress()
        if opts.gif:
            _save_gif(out / "render.gif", images, opts.fps)
            files.append(str(out / "render.gif"))
    seconds = time.perf_counter() - start
    return FigureSummary(str(out), rasterizer.name, rasterizer.detail, rasterizer.note, labels, list(opts.views), names,
                         files, seconds, seconds / max(len(names), 1))
