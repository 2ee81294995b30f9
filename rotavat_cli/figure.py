"""Figures of sequences on disk: pick frames, read one row per sequence, render grids, write PNG/GIF/GLB.

This is what ``rotavat render`` and ``rotavat export`` run; the pictures themselves are drawn by
:mod:`rotavat_cli.render` and the scenes built by :mod:`rotavat_cli.export`.

Which camera places a row in the world (side/top views, GLB): ``camera_path`` if given (shared
by every row), else the sequence's own ``camera.yaml``, else an :class:`InputError` saying to
run ``rotavat calibrate`` or pass ``--camera``. The front view uses the intrinsics the meshes
were made with (the frame's ``focal_length``/``K``, else ``meta.yaml``), falling back to the camera's.
Frames are chosen by index in the first sequence and matched by name in the others.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import atomic_open
from .camera import Camera, reexpress_cam
from .errors import InputError
from .render import VIEWS, RenderStyle, RowFrame, render_grid, scene_extents
from .sequence import Sequence, open_sequence, read_camera_yaml

__all__ = ["FigureOptions", "FigureSummary", "parse_views", "select_frames", "row_labels", "sequence_camera",
           "read_row", "render_sequences", "export_frame", "IMAGE_SUFFIXES"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp")


@dataclass(frozen=True)
class FigureOptions:
    """Everything ``rotavat render`` can vary (defaults live in configs/default.yaml, section ``render``)."""

    views: tuple[str, ...] = VIEWS
    size: tuple[int, int] = (640, 360)
    frames: str | None = None  # comma-separated indices; None = the first frame (or every)
    every: int | None = None
    renderer: str = "auto"
    camera_path: Path | None = None
    image_dir: Path | None = None
    gif: bool = False
    fps: float = 5.0
    glb: bool = False
    style: RenderStyle = field(default_factory=RenderStyle)

    @classmethod
    def from_config(cls, render: dict, camera_path: Path | None = None, image_dir: Path | None = None) -> "FigureOptions":
        """Options from a merged ``render`` config section; ValueError naming a bad option."""
        from .render_gl import RENDERERS

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


def parse_views(text: str) -> tuple[str, ...]:
    """'front,side' -> ('front', 'side'); raises ValueError naming an unknown view."""
    views = tuple(v.strip().lower() for v in str(text).split(",") if v.strip())
    bad = [v for v in views if v not in VIEWS]
    if bad or not views:
        raise ValueError(f"unknown view(s) {', '.join(bad) or '(none)'}; choose from {', '.join(VIEWS)}")
    return views


def select_frames(n_frames: int, frames: str | None, every: int | None) -> list[int]:
    """Frame indices from '0,10,-1' (negative = from the end) or every N-th; default the first frame."""
    if frames is not None and every is not None:
        raise ValueError("give --frames or --every, not both")
    if every is not None:
        if every < 1:
            raise ValueError(f"--every must be >= 1, got {every}")
        return list(range(0, n_frames, every))
    if frames is None:
        return [0]
    picked = []
    for part in str(frames).split(","):
        try:
            index = int(part.strip())
        except ValueError:
            raise ValueError(f"--frames must be comma-separated integers, got {frames!r}") from None
        if not -n_frames <= index < n_frames:
            raise ValueError(f"frame index {index} out of range: the sequence has {n_frames} frames")
        picked.append(index % n_frames)
    return picked


def row_labels(paths: list[Path]) -> list[str]:
    """Directory names, made unique by their parents when two sequences share a name."""
    labels = [p.resolve().name or str(p) for p in paths]
    if len(set(labels)) < len(labels):
        labels = [f"{p.resolve().parent.name}/{p.resolve().name}" for p in paths]
    if len(set(labels)) < len(labels):
        labels = [str(p) for p in paths]
    return labels


def sequence_camera(seq: Sequence, camera_path: Path | None) -> Camera | None:
    """``camera_path`` if given, else the sequence's camera.yaml, else None."""
    if camera_path is not None:
        return read_camera_yaml(camera_path, seq.image_size)[0]
    return seq.camera


def _no_camera(seq: Sequence, what: str) -> InputError:
    """The error for a view that needs a camera the sequence does not have."""
    return InputError(f"{seq.path}: no camera.yaml for the {what}: run `rotavat calibrate {seq.path}` "
                      "or pass --camera camera.yaml")


def _frame_image(image_dir: Path, name: str) -> np.ndarray:
    """The video frame ``image_dir/<name>.<png|jpg|...>`` as (H, W, 3) uint8."""
    from PIL import Image, UnidentifiedImageError

    for path in sorted(image_dir.glob(f"{name}.*")):
        if path.suffix.lower() in IMAGE_SUFFIXES:
            try:
                with Image.open(path) as img:
                    return np.asarray(img.convert("RGB"))
            except (OSError, UnidentifiedImageError) as exc:
                raise InputError(f"{path}: not a readable image ({exc})") from None
    raise InputError(f"{image_dir}: no image named {name}.png/.jpg (images are matched to frames by name)")


def read_row(seq: Sequence, name: str, label: str, camera: Camera | None, image_dir: Path | None = None) -> RowFrame:
    """One row of a figure: frame ``name`` of ``seq`` with its intrinsics, camera and video frame."""
    if name not in seq.frame_names:
        raise InputError(f"{seq.path}: has no frame named {name} (frames are matched by name across sequences)")
    frame = seq.read_frame(name)
    verts = frame.get("vertices")
    faces = frame.get("faces")
    if frame.n_people and verts is None:
        raise InputError(f"{frame.source}: no 'vertices': rendering needs meshes")
    if frame.n_people and faces is None:
        raise InputError(f"{frame.source}: no 'faces': rendering needs the triangle list")
    intr = seq.frame_intrinsics(frame)
    size = intr.image_size or (camera.image_size if camera else None)
    focals = intr.focals_px(frame.n_people)
    focal = float(np.median(focals)) if focals is not None and len(focals) else (intr.focal_px or (camera.focal_px if camera else None))
    if size is None or focal is None:
        raise InputError(f"{frame.source}: unknown {'image size' if size is None else 'focal length'} for the front view: "
                         "add image_size and focal_length to meta.yaml or pass --camera")
    pp = intr.principal_point or (camera.principal_point if camera and camera.image_size == size else (size[0] / 2, size[1] / 2))
    if verts is not None and focals is not None and frame.n_people and np.any(focals != focal):
        # one focal per person (HybrIK): the front view shows each body re-expressed in one camera
        verts = reexpress_cam(verts, verts.mean(axis=1), focals, pp, focal, pp).astype(verts.dtype)
    image = _frame_image(image_dir, name) if image_dir is not None else None
    return RowFrame(label, np.zeros((0, 0, 3)) if verts is None else verts,
                    np.zeros((0, 3), np.int64) if faces is None else faces, frame.person_ids,
                    size, float(focal), pp, camera, image)


def _open_all(paths: list[Path], opts: FigureOptions, need_camera: bool) -> tuple[list[Sequence], list[Camera | None]]:
    """Open the sequences and find each one's camera (an error if a needed one is missing)."""
    seqs = [open_sequence(p) for p in paths]
    cameras = [sequence_camera(s, opts.camera_path) for s in seqs]
    if need_camera:
        for seq, cam in zip(seqs, cameras):
            if cam is None:
                raise _no_camera(seq, "side/top views" if not opts.glb else "side/top views and the GLB")
    return seqs, cameras


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


def render_sequences(paths: list[Path], out: Path, opts: FigureOptions,
                     progress: Callable[[], None] | None = None) -> FigureSummary:
    """Render the chosen frames of one or more sequences as labelled grids in ``out`` (PNG per frame, optional GIF/GLB)."""
    from .export import build_scene, write_glb
    from .render_gl import open_rasterizer

    if not paths:
        raise InputError("give at least one sequence directory")
    need_camera = opts.glb or any(v != "front" for v in opts.views)
    seqs, cameras = _open_all(paths, opts, need_camera)
    labels = row_labels(paths)
    try:
        indices = select_frames(len(seqs[0]), opts.frames, opts.every)
    except ValueError as exc:
        raise InputError(f"{seqs[0].path}: {exc}") from None
    names = [seqs[0].frame_names[i] for i in indices]

    def rows_of(name: str, image_dir: Path | None = None) -> list[RowFrame]:
        return [read_row(s, name, lab, cam, image_dir) for s, lab, cam in zip(seqs, labels, cameras)]

    start = time.perf_counter()
    # pass 1: one shared metric extent for every row and frame, so all pictures compare at one scale
    ortho = tuple(v for v in opts.views if v != "front")
    extents = scene_extents([r for n in names for r in rows_of(n)], ortho, opts.size, opts.style.margin) if ortho else {}
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


def export_frame(path: Path, out: Path, frame: int = 0, camera_path: Path | None = None,
                 palette: tuple[tuple[float, float, float], ...] = RenderStyle().palette) -> dict:
    """Write frame ``frame`` (index; negative from the end) of a sequence as a ``.glb`` scene; returns a summary."""
    from .export import build_scene, write_glb

    seq = open_sequence(path)
    camera = sequence_camera(seq, camera_path)
    if camera is None:
        raise _no_camera(seq, "GLB's world frame")
    try:
        index = select_frames(len(seq), str(frame), None)[0]
    except ValueError as exc:
        raise InputError(f"{seq.path}: {exc}") from None
    name = seq.frame_names[index]
    row = read_row(seq, name, row_labels([path])[0], camera)
    write_glb(out, build_scene([row], camera, palette), camera)
    return {"out": str(out), "sequence": str(path), "frame": name, "people": int(np.asarray(row.verts_cam).shape[0]),
            "image_size": list(camera.image_size), "aspect_ratio": camera.image_size[0] / camera.image_size[1],
            "yfov_deg": float(np.rad2deg(camera.vertical_fov_rad))}
