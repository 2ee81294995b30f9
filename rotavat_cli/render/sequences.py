"""Figures of sequences on disk: what ``rotavat render`` runs (PNG per frame; optional GIF, MP4, GLB, track plots).

One grid row per sequence (:mod:`.rows` reads them), one column per view (:mod:`.views`), drawn
by :func:`.grid.render_grid` with the rasteriser :func:`.raster.open_rasterizer` picks. Each row
is placed in the world by its own camera (:func:`.rows.sequence_camera`), which passes the camera
gate first (:func:`rotavat_cli.alignment.check_fit`: an implausible calibration is refused unless
``accept_camera``; the warnings go to :attr:`FigureSummary.warnings`). One row may be the
ground truth (``gt``): the other rows' captions then give their errors against it on the frame
shown (W-MPJPE, lean, foot height: :func:`rotavat_cli.metrics.evaluate.evaluate_frame`, from the frames drawn),
and with ``ghost="gt"`` it is drawn faintly over them (docs/render.md, "Ground truth"). An aligned
row's people carry the flags of its ``people.csv`` (:func:`.rows.people_flags`): the side/top windows
are fitted on the unflagged people and the flagged ones are marked (:func:`.grid.person_label`).

Defaults: the packaged configs/default.yaml, section ``render``, is their one source
(``FigureOptions()`` is ``FigureOptions.from_config(default_config()["render"])``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar
from pathlib import Path

import numpy as np
from PIL import Image

from ..alignment.camera_gate import check_fit, render_remedies
from ..files.atomic import atomic_open
from ..geometry.camera import Camera
from ..settings.config import default_config, packaged_default
from ..errors import InputError, RotavatError
from ..metrics.evaluate import EvalOptions, evaluate_frame
from ..settings.option_rules import Rule, check_fields
from ..sequence import Frame, Sequence
from .export import build_scene, write_glb
from .grid import render_grid
from .raster import RENDERERS, open_rasterizer
from .rows import OWN, frame_names, label_stem, no_camera, people_flags, read_row, row_labels, sequence_camera_fit
from .style import RenderStyle
from .tracks import plot_tracks, sequence_tracks
from .video import gif_writer, mp4_writer, require_mp4
from .views import FITS, RowFrame, WindowBounds, camera_numbers, extents_from_bounds, parse_views, view_specs, window_bounds

__all__ = ["FigureOptions", "FigureSummary", "SCALES", "GHOSTS", "render_sequences", "figure_steps", "ground_truth_row",
           "metrics_caption", "flagged_caption"]

SCALES = ("row", "shared")  # side/top windows: each row its own, or one for every row
GHOSTS = ("none", "gt")  # what is drawn faintly over the rows


@functools.lru_cache(maxsize=1)
def _packaged_options() -> "FigureOptions":
    """FigureOptions of the packaged ``render:`` section (read once)."""
    return FigureOptions.from_config(default_config()["render"])


@dataclass(frozen=True)
class FigureOptions:
    """Everything ``rotavat render`` can vary; defaults from configs/default.yaml, section ``render``."""

    views: tuple[str, ...] = packaged_default(_packaged_options, "views")
    size: tuple[int, int] = packaged_default(_packaged_options, "size")
    frames: str | None = packaged_default(_packaged_options, "frames")  # "0,10,-1"; None = the first (or every)
    every: int | None = packaged_default(_packaged_options, "every")
    renderer: str = packaged_default(_packaged_options, "renderer")
    camera_path: Path | None = None  # not a config key: --camera (rows without a camera.yaml of their own)
    image_dir: Path | None = None  # not a config key: --image
    fit: str = packaged_default(_packaged_options, "fit")  # people | camera
    scale: str = packaged_default(_packaged_options, "scale")  # row | shared
    gt: str = packaged_default(_packaged_options, "gt")  # auto | none | a row's label or 1-based number
    ghost: str = packaged_default(_packaged_options, "ghost")  # none | gt
    labels: bool = packaged_default(_packaged_options, "labels")
    gif: bool = packaged_default(_packaged_options, "gif")
    mp4: bool = packaged_default(_packaged_options, "mp4")
    fps: float = packaged_default(_packaged_options, "fps")
    glb: bool = packaged_default(_packaged_options, "glb")
    plots: bool = packaged_default(_packaged_options, "plots")
    style: RenderStyle = packaged_default(_packaged_options, "style")
    accept_camera: bool = False  # not a config key: --accept-camera (use cameras whose calibration is implausible)
    reader_flags: tuple[str, ...] = ()  # not a config key: how rows read with --from were read (the gate's advice)

    RULES: ClassVar[dict[str, Rule]] = {  # the ``render`` keys' bounds and names (rotavat_cli/settings/option_rules.py)
        "size": Rule(low=16, high=8192, unit="px"), "every": Rule(low=1), "renderer": Rule(names=RENDERERS),
        "fit": Rule(names=FITS), "scale": Rule(names=SCALES), "ghost": Rule(names=GHOSTS),
        "fps": Rule(low=0.01, high=1000), "margin": RenderStyle.RULES["margin"],
    }

    def __post_init__(self) -> None:
        check_fields(self, self.RULES)

    @classmethod
    def from_config(cls, render: dict, camera_path: Path | None = None, image_dir: Path | None = None) -> "FigureOptions":
        """Options from a merged ``render`` config section; ValueError naming a bad option."""
        return cls(parse_views(render["views"]), tuple(render["size"]),
                   None if render["frames"] is None else str(render["frames"]), render["every"], render["renderer"],
                   camera_path, image_dir, render["fit"], render["scale"], str(render["gt"]), render["ghost"], bool(render["labels"]), render["gif"],
                   bool(render["mp4"]), float(render["fps"]), render["glb"], bool(render["plots"]),
                   RenderStyle.from_config(render))


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
    gt: str | None = None  # the ground-truth row's label
    captions: dict[str, str] = dataclasses.field(default_factory=dict)  # row label -> its numbers (last frame)
    warnings: list[str] = dataclasses.field(default_factory=list)  # e.g. an implausible camera used (--accept-camera)
    notes: list[str] = dataclasses.field(default_factory=list)  # e.g. a row drawn in its own camera, not --camera's

    def moved_to(self, out: str | Path) -> "FigureSummary":
        """The same summary once its folder was moved to ``out`` (a staging folder swapped in)."""
        files = [str(Path(out) / Path(f).name) for f in self.files]
        return dataclasses.replace(self, out=str(out), files=files)


def ground_truth_row(spec: str, labels: list[str]) -> int | None:
    """Index of the ground-truth row: ``none``; ``auto`` = the one row whose folder is named ``gt``
    (else none); a row's label; or its 1-based number. InputError for a name that is no row.

    >>> ground_truth_row("auto", ["pred", "pred_aligned", "gt"])
    2
    >>> ground_truth_row("1", ["a", "b"]), ground_truth_row("none", ["gt"])
    (0, None)
    """
    if spec == "none":
        return None
    if spec == "auto":
        named = [i for i, label in enumerate(labels) if label == "gt" or label.endswith("/gt")]
        return named[0] if len(named) == 1 else None
    if spec in labels:
        return labels.index(spec)
    if spec.isdigit() and 1 <= int(spec) <= len(labels):
        return int(spec) - 1
    raise InputError(f"--gt {spec!r} names no row: give one of {', '.join(labels)}, a number 1..{len(labels)}, "
                     "auto or none")


def _fmt(value: float, text: str) -> str | None:
    """``text`` formatted with ``value``, or None when the value is not finite."""
    return text.format(value) if value is not None and math.isfinite(value) else None


def metrics_caption(pred: Sequence, gt: Sequence, name: str, pred_frame: Frame | None = None,
                    gt_frame: Frame | None = None) -> str:
    """Errors of ``pred`` against the ground truth on frame ``name``: W-MPJPE (else W-PVE), lean, foot
    height (means over the matched people, as ``rotavat eval`` computes them on that frame alone), from
    ``pred_frame`` and ``gt_frame`` when the caller has read them (None: read)."""
    if name not in pred.frame_names and name not in gt.frame_names:
        return ""
    try:
        # numpy engine: a frame's few people are scored at once; numba's start-up (~2 s) would dominate
        result = evaluate_frame(pred, gt, name, pred_frame, gt_frame, dataclasses.replace(EvalOptions(), engine="numpy"))
    except RotavatError as exc:
        return f"vs gt: not comparable ({exc})"
    m = result.metrics
    parts = [_fmt(m.get("w_mpjpe"), "W-MPJPE {:.0f} mm") or _fmt(m.get("w_pve"), "W-PVE {:.0f} mm"),
             _fmt(m.get("lean_deg"), "lean {:.1f}°"), _fmt(m.get("foot_height"), "foot height {:.0f} mm")]
    shown = [p for p in parts if p]
    return f"vs gt: {' · '.join(shown) or 'no metric'} ({result.matched}/{result.people_gt} matched)"


def _cameras(seqs: list[Sequence], opts: FigureOptions, needs: str) -> tuple[list[Camera | None], list[str], list[str]]:
    """Each sequence's camera (its own, else ``opts.camera_path``), each past the camera gate, the gate's
    warnings and notes (a row whose own camera is used although ``--camera`` was given); an error naming
    what ``needs`` one if it is missing, or refusing an implausible camera."""
    cameras, warnings, notes = [], [], []
    for seq in seqs:
        cam, fit, whence = sequence_camera_fit(seq, opts.camera_path, own_first=True)
        if cam is None and needs:
            raise no_camera(seq, needs, opts.reader_flags if seq.origin is not None else (),
                            tuple(s.label for s in seqs))
        if whence == OWN and opts.camera_path is not None and not _same_file(seq.camera_label, opts.camera_path):
            notes.append(f"{seq.label}: drawn in its own camera ({seq.camera_label}), not --camera {opts.camera_path} "
                         "(--camera is for the rows without one)")
        if cam is not None:
            what = seq.camera_label if whence == OWN else f"{opts.camera_path} (--camera, for {seq.label})"
            remedies = render_remedies(seq.label, own=whence == OWN, aligned="aligned_from" in (seq.meta or {}),
                                       reader_flags=opts.reader_flags if seq.origin is not None else ())
            warning = check_fit(what, fit, opts.accept_camera, remedies)
            if warning is not None and warning not in warnings:
                warnings.append(warning)
        cameras.append(cam)
    return cameras, warnings, notes


def _same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two paths name one existing file."""
    try:
        return Path(a).samefile(b)
    except OSError:
        return False


def _save_png(path: Path, image: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 image as PNG atomically."""
    with atomic_open(path, "wb") as handle:
        Image.fromarray(image).save(handle, format="PNG", optimize=False)


_WINDOW_POINTS = 512  # windows are fitted on about this many points per person (they need extents, not meshes)
_KEEP_FRAMES_BYTES = 64 << 20  # pass 1 keeps the frames it read, up to this many bytes, for pass 2 (a short clip: read once)


def _read_frames(seqs: list[Sequence], name: str) -> list[Frame | None]:
    """Frame ``name`` of each sequence (None where it has none: :func:`.rows.read_row` says so)."""
    return [s.read_frame(name) if name in s.frame_names else None for s in seqs]


def _frames_bytes(frames: list[Frame | None]) -> int:
    """The bytes of the arrays of ``frames``."""
    return sum(int(np.asarray(a).nbytes) for f in frames if f is not None for a in f.data.values())


def _window_row(row: RowFrame) -> RowFrame:
    """A light copy of a row for fitting windows: every k-th point of each person (and of its ghost)."""
    points = row.points_cam
    k = max(1, points.shape[1] // _WINDOW_POINTS)
    ghost = None if row.ghost is None else _window_row(row.ghost)
    if row.kind in ("mesh", "points"):
        return dataclasses.replace(row, verts_cam=points[:, ::k], faces=np.zeros((0, 3), np.int64), joints_cam=None,
                                   image=None, ghost=ghost)
    return dataclasses.replace(row, image=None, ghost=ghost)


def figure_steps(seqs: list[Sequence], opts: FigureOptions) -> int:
    """How many ``progress()`` calls :func:`render_sequences` makes: one per rendered frame, plus one
    per frame of every row with ``plots``."""
    n = len(frame_names(seqs[0], opts.frames, opts.every)) if seqs else 0
    return n + (sum(len(s) for s in seqs) if opts.plots else 0)


def flagged_caption(row: RowFrame, framed: bool = True) -> str:
    """What a row's caption says of its flagged people (:attr:`RowFrame.flagged`): how many, what marks them
    and, when the side/top windows are ``framed`` on the others, that they are left out of them; "" for none.

    >>> row = RowFrame("a", np.zeros((3, 0, 3)), np.zeros((0, 3)), np.arange(3), (64, 48), 50.0, (32.0, 24.0),
    ...                flags=("", "sitting", "implausible_stature"))
    >>> flagged_caption(row)
    '2 flagged in people.csv (outlined label: id and flag; not framed in side/top)'
    """
    n = len(row.flagged)
    if not n:
        return ""
    return f"{n} flagged in people.csv (outlined label: id and flag{'; not framed in side/top' if framed else ''})"


def _captions(rows: list[RowFrame], seqs: list[Sequence], gt: int | None, name: str, framed: bool,
              frames: list[Frame | None]) -> list[str]:
    """Per row: its camera's numbers, against the ground-truth row its errors on frame ``name`` (``frames``: each
    row's, as read), and its flagged people (``framed``: the side/top windows are fitted on the others)."""
    out = []
    for i, (row, seq) in enumerate(zip(rows, seqs)):
        parts = ["ground truth"] if i == gt else []
        if row.camera is not None:
            parts.append("camera " + camera_numbers(row.camera))
        if gt is not None and i != gt:
            parts.append(metrics_caption(seq, seqs[gt], name, frames[i], frames[gt]))
        parts.append(flagged_caption(row, framed and bool(row.plausible.any())))  # nobody plausible: everyone framed
        out.append("   ".join(p for p in parts if p))
    return out


def render_sequences(seqs: list[Sequence], out: Path, opts: FigureOptions | None = None,
                     progress: Callable[[], None] | None = None) -> FigureSummary:
    """Render the chosen frames of one or more sequences as labelled grids in ``out`` (PNG per frame,
    optional GIF/MP4/GLB/track plots): one grid row per sequence, frames named by the first sequence.
    ``progress()`` is called :func:`figure_steps` times."""
    opts = FigureOptions() if opts is None else opts
    if not seqs:
        raise InputError("give at least one sequence directory")
    if opts.mp4:
        require_mp4()  # before any work: say how to install it
    placed = [view.name for view in view_specs(opts.views) if view.needs_camera]  # views placing rows in the world
    needs = [f"{'/'.join(placed)} views"] if placed else []
    needs += (["the GLB"] if opts.glb else []) + (["the track plots"] if opts.plots else [])
    cameras, warnings, notes = _cameras(seqs, opts, " and ".join(needs))
    flags = [people_flags(s, warnings) for s in seqs]  # aligned rows: people.csv's flags
    labels = row_labels([Path(s.label) for s in seqs])
    names = frame_names(seqs[0], opts.frames, opts.every)
    gt = ground_truth_row(opts.gt, labels)
    if opts.ghost == "gt" and gt is None:
        raise InputError("--ghost gt needs a ground-truth row: name it with --gt ROW (its label or number), "
                         "or give a sequence folder named gt")

    def rows_of(name: str, frames: list[Frame | None], image_dir: Path | None = None) -> list[RowFrame]:
        rows = [read_row(s, name, lab, cam, image_dir, f, frame)
                for s, lab, cam, f, frame in zip(seqs, labels, cameras, flags, frames)]
        if opts.ghost == "gt":
            rows = [r if i == gt else dataclasses.replace(r, ghost=rows[gt]) for i, r in enumerate(rows)]
        return rows

    start = time.perf_counter()
    # pass 1: windows shared by every frame (per row, or by every row), so pictures compare at one scale; of each
    # frame only its rows' window bounds are kept (and its frames while they fit _KEEP_FRAMES_BYTES: not read again)
    every_frame: list[list[WindowBounds]] = []
    kept: dict[str, list[Frame | None]] = {}
    kept_bytes = 0
    for name in names:
        frames = _read_frames(seqs, name)
        every_frame.append([window_bounds(_window_row(r), opts.views, opts.fit) for r in rows_of(name, frames)])
        kept_bytes += _frames_bytes(frames)
        if kept_bytes <= _KEEP_FRAMES_BYTES and name not in kept:
            kept[name] = frames
    if opts.scale == "shared":
        extents = extents_from_bounds([b for rows in every_frame for b in rows], opts.views, opts.size, opts.style.margin,
                                      opts.fit)
    else:  # each row its own side/top windows; the camera's view shows the same part of the image in every row
        shared = extents_from_bounds([b for rows in every_frame for b in rows], tuple(v for v in opts.views if v not in placed),
                                     opts.size, opts.style.margin, opts.fit)
        extents = [{**extents_from_bounds([rows[i] for rows in every_frame], tuple(placed), opts.size, opts.style.margin,
                                          opts.fit), **shared} for i in range(len(seqs))]
    del every_frame
    files, captions = [], {}
    with contextlib.ExitStack() as stack:
        animations = [stack.enter_context(writer(out / f"render.{ext}", opts.fps))
                      for ext, writer, wanted in (("gif", gif_writer, opts.gif), ("mp4", mp4_writer, opts.mp4)) if wanted]
        rasterizer = stack.enter_context(open_rasterizer(opts.renderer))
        for name in names:
            frames = kept.pop(name, None)  # a name given twice (--frames 0,0) is read again
            frames = _read_frames(seqs, name) if frames is None else frames
            rows = rows_of(name, frames, opts.image_dir)
            rows = [dataclasses.replace(r, caption=c)
                    for r, c in zip(rows, _captions(rows, seqs, gt, name, bool(placed), frames))]
            del frames
            captions = {r.label: r.caption for r in rows}
            image = render_grid(rows, opts.views, opts.size, rasterizer.rasterize, opts.style, extents,
                                title=f"frame {name}", labels=opts.labels)
            _save_png(out / f"{name}.png", image)
            files.append(str(out / f"{name}.png"))
            for animation in animations:
                animation.add(image)
            if opts.glb:
                scene = build_scene(rows, rows[0].camera, opts.style.palette)
                files.append(str(write_glb(out / f"{name}.glb", scene, rows[0].camera)))
            if progress:
                progress()
    files += [str(animation.path) for animation in animations]
    if opts.plots:
        for seq, label, cam in zip(seqs, labels, cameras):
            tracks = sequence_tracks(seq, cam, label, progress)
            files.append(str(plot_tracks(out / f"tracks_{label_stem(label)}.png", tracks, opts.style.palette)))
    seconds = time.perf_counter() - start
    return FigureSummary(str(out), rasterizer.name, rasterizer.detail, rasterizer.note, labels, list(opts.views), names,
                         files, seconds, seconds / max(len(names), 1), None if gt is None else labels[gt], captions,
                         warnings, notes)
