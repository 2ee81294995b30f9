"""``rotavat view``: sequences as one Rerun recording (.rrd), streamed frame by frame.

Every row (each sequence, and the ground truth) is placed in one world, the scene camera's (Y up, the
ground at ``Y = 0``: docs/conventions.md), from its camera-frame coordinates: rows differ in the viewer
exactly as ``rotavat eval`` compares them. The scene camera is ``--camera``, else the first sequence's
own camera.yaml, else the ground truth's; it passes the camera gate first
(:func:`rotavat_cli.alignment.camera_gate.check_fit`). The entity tree (docs/render.md, "rotavat view"):

- ``world``: the view coordinates (right-handed, Y up); ``world/ground``: the grid and its metre ticks;
  ``world/ground/uncertainty/<height|pitch>_<minus|plus>_1sd``: the ground as it would be one standard deviation
  away (camera.yaml's ``fit.std``); ``world/camera``: the camera's pose and label, ``world/camera/image`` its
  pinhole (intrinsics), ``world/camera/image/video`` the video frames (``--image``; :func:`.detail.video_frame`);
- ``world/<row>/people/<id>/{mesh,points,skeleton,joints,label}``: one person, by what the row has (a mesh,
  reduced to about ``view.mesh_vertices`` vertices by :func:`.detail.reduce_mesh`; vertices without faces; joints
  only), in its colour tinted by the row's role (:mod:`.roles`), its label its id (and its flag, from align's
  people.csv);
  ``world/<row>/tracks/<id>``: its path on the ground; ``world/<row>/ground``: the row's own ground when its
  camera.yaml is not the scene camera (the ground truth's true ground);
  ``world/<row>/their_world/{paths,up,ground}/<id>``: a row with a tool's own world (WHAM's, GVHMR's
  ``tool_world_*`` keys): the track's pelvis path in that world put in ours by the heading fit of
  :mod:`rotavat_cli.metrics.tool_world`, its up as an arrow and its ground as a faint square, tilted by the angle;
- ``plots/<series>/<row>/<id>``: foot height (m), lean (deg), stature (m) of each track over time and, with a
  ground truth, the W-MPJPE (mm) of each ground-truth person (``rotavat eval``'s matching and values, scored from the
  frames the recording reads: :func:`rotavat_cli.metrics.evaluate.frame_w_mpjpe`).

Timelines: ``frame`` (the index in the sorted frame names of all rows) and ``time`` (seconds, when the first
row's meta.yaml gives an ``fps``). The viewer's 3D view starts framed on the aligned rows, the truth and the camera
(:func:`.roles.framed_rows`; every row with ``view.frame_all``). Memory stays flat in the number of frames: one frame of every row is held
at a time, and only the tracks' small per-frame numbers are kept for the end. Each frame of every row is read once.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..alignment.camera_gate import check_fit, render_remedies
from ..files.atomic import atomic_path
from ..geometry.camera import Camera
from ..settings.config import default_config, packaged_default
from ..errors import InputError, RotavatError, input_errors
from ..bodies.measure import scale_source
from ..metrics.evaluate import EvalOptions, frame_w_mpjpe, pairing_options
from ..metrics.tool_world import angles_deg, heading_fit, pelvis_cam, their_up_cam
from ..settings.option_rules import Rule, check_fields
from ..files.outputs import RRD_APPLICATION_ID
from ..render.rows import (frame_image_path, label_stem, no_camera, people_flags, read_row, row_labels,
                           select_frames)
from ..render.style import RenderStyle, person_colors, vertex_normals
from ..render.tracks import frame_track_values
from ..render.views import RowFrame
from ..sequence import Frame, Sequence, read_camera_yaml
from ..unpickle.streams import read_bytes
from ..version import __version__
from .detail import MeshReduction, reduce_mesh, thin_points, video_frame
from .roles import RowTone, framed_rows, row_role, row_tint, row_tones
from .scene import (GRID_MARGIN_M, camera_label, eye_world, ground_extent_m, label_anchors_world, plane_quad_world,
                    tilted_square_world, track_strips, uncertainty_cameras, world_points_f32)
from .writer import SERIES, W_MPJPE_SERIES, WORLD, RecordingWriter, blueprint, require_rerun

__all__ = ["ViewOptions", "ViewSummary", "record_sequences", "view_steps"]

UNCERTAINTY_ALPHA = 6  # of 255: the grounds at ±1 std of the camera's height and pitch
OWN_GROUND_ALPHA = 70  # of 255: a row's own (true) ground
THEIR_GROUND_ALPHA = 40  # of 255: a tool's own ground (its up), under each of its tracks
THEIR_GROUND_HALF_M = 1.0  # that square's half side
THEIR_UP_M = 1.0  # the length of a tool's up arrow
_AHEAD = 2  # frames prepared ahead, one thread each (the machine's two cores, or more, are kept busy)


@functools.lru_cache(maxsize=1)
def _packaged_options() -> "ViewOptions":
    """ViewOptions of the packaged ``view:`` and ``render:`` sections (read once)."""
    config = default_config()
    return ViewOptions.from_config(config["view"], config["render"])


@dataclass(frozen=True)
class ViewOptions:
    """Everything ``rotavat view`` can vary; defaults from configs/default.yaml, section ``view`` (the
    palette and colours: section ``render``, one palette for every picture)."""

    frames: str | None = packaged_default(_packaged_options, "frames")  # "0,10,-1"; None = every frame (or every)
    every: int | None = packaged_default(_packaged_options, "every")
    image_plane_m: float = packaged_default(_packaged_options, "image_plane_m")
    normals: bool = packaged_default(_packaged_options, "normals")
    frame_all: bool = packaged_default(_packaged_options, "frame_all")  # the 3D view framed on every row (--frame-all)
    mesh_vertices: int = packaged_default(_packaged_options, "mesh_vertices")  # meshes reduced to about this many; 0 = all
    image_max_px: int = packaged_default(_packaged_options, "image_max_px")  # video frames scaled down to it; 0 = the files
    style: RenderStyle = packaged_default(_packaged_options, "style")
    camera_path: Path | None = None  # not a config key: --camera
    image_dir: Path | None = None  # not a config key: --image
    accept_camera: bool = False  # not a config key: --accept-camera
    reader_flags: tuple[str, ...] = ()  # not a config key: how rows read with --from were read (the gate's advice)

    RULES: ClassVar[dict[str, Rule]] = {"every": Rule(low=1), "image_plane_m": Rule(low=0.01, high=1000, unit="m"),
                                        "mesh_vertices": Rule(low=0), "image_max_px": Rule(low=0)}

    def __post_init__(self) -> None:
        check_fields(self, self.RULES)
        for name in ("mesh_vertices", "image_max_px"):  # counts: 1000.0 is 1000, 2.5 is refused
            value = getattr(self, name)
            if isinstance(value, bool) or not float(value).is_integer():
                raise ValueError(f"{name} must be a whole number, got {value!r}")
            object.__setattr__(self, name, int(value))

    @classmethod
    def from_config(cls, view: dict, render: dict, camera_path: Path | None = None,
                    image_dir: Path | None = None) -> "ViewOptions":
        """Options from merged ``view`` and ``render`` config sections; ValueError naming a bad option."""
        return cls(frames=None if view["frames"] is None else str(view["frames"]), every=view["every"],
                   image_plane_m=float(view["image_plane_m"]), normals=bool(view["normals"]), frame_all=bool(view["frame_all"]),
                   mesh_vertices=view["mesh_vertices"], image_max_px=view["image_max_px"],
                   style=RenderStyle.from_config(render), camera_path=camera_path, image_dir=image_dir)


@dataclass
class ViewSummary:
    """What was recorded and where it went."""

    out: str
    rows: list[str]
    gt: str | None
    frames: int
    people: int  # person-frames drawn, over every row
    camera: str  # the scene camera's label
    bytes: int
    seconds: float
    entities: list[str] = field(default_factory=list)  # the entity tree's top (world/<row>, plots/<series>)
    framed: list[str] = field(default_factory=list)  # the rows the 3D view starts framed on (roles.py)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def view_steps(seqs: list[Sequence], gt: Sequence | None, opts: ViewOptions) -> int:
    """How many ``progress()`` calls :func:`record_sequences` makes: one per recorded frame."""
    return len(_chosen_frames(_timeline([*seqs, *([gt] if gt is not None else [])]), opts))


def _timeline(rows: list[Sequence]) -> list[str]:
    """The ``frame`` timeline: the sorted union of every row's frame names (a frame's index is its place here)."""
    return sorted(set().union(*(s.frame_names for s in rows)))


def _chosen_frames(timeline: list[str], opts: ViewOptions) -> list[int]:
    """The indices into ``timeline`` of the frames recorded: ``frames``/``every``, all by default; InputError for
    indices out of range."""
    if opts.frames is None and opts.every is None:
        return list(range(len(timeline)))
    with input_errors():  # the messages name --frames/--every
        return select_frames(len(timeline), opts.frames, opts.every)


def _scene_camera(seqs: list[Sequence], gt: Sequence | None, opts: ViewOptions) -> tuple[Camera, dict, str, str | None]:
    """The scene camera, its fit, where it came from, and the gate's warning (None: plausible). ``--camera``,
    else the first sequence with a camera.yaml of its own, else the ground truth's; else an InputError
    naming the commands that make one."""
    if opts.camera_path is not None:
        camera, fit = read_camera_yaml(opts.camera_path, seqs[0].image_size)
        seq, what, own = seqs[0], str(opts.camera_path), False
    else:
        owners = [s for s in seqs if s.camera is not None] or ([gt] if gt is not None and gt.camera is not None else [])
        if not owners:
            raise no_camera(seqs[0], "3D scene", opts.reader_flags if seqs[0].origin is not None else (),
                            tuple(s.label for s in seqs), command="view")
        seq = owners[0]
        camera, fit, what, own = seq.camera, dict(seq.camera_fit or {}), seq.camera_label, True
    remedies = render_remedies(seq.label, own=own, aligned="aligned_from" in (seq.meta or {}),
                               reader_flags=opts.reader_flags if seq.origin is not None else (), command="view")
    warning = check_fit(what, fit, opts.accept_camera, remedies)
    return camera, fit, what, warning


def _w_mpjpe_options(seq: Sequence, gt: Sequence, warnings: list[str]) -> EvalOptions | None:
    """How ``seq``'s people are matched to ``gt``'s to score their W-MPJPE (``rotavat eval``'s options, numpy
    engine); None and a warning when the two cannot be compared (:func:`pairing_options`)."""
    try:
        return pairing_options(seq, gt, dataclasses.replace(EvalOptions(), engine="numpy"))
    except RotavatError as exc:
        warnings.append(_no_w_mpjpe(seq, gt, exc))
        return None


def _no_w_mpjpe(seq: Sequence, gt: Sequence, exc: RotavatError) -> str:
    """The warning for a row whose W-MPJPE against the ground truth cannot be scored."""
    return f"{seq.label}: no W-MPJPE against {gt.label} ({exc})"


def _frame_w_mpjpe(seq: Sequence, gt: Sequence, frame: Frame, gt_frame: Frame,
                   opts: EvalOptions) -> dict[int, float] | RotavatError:
    """``{ground-truth person id: W-MPJPE mm}`` of one frame's matched people (finite values only), or the error
    that keeps ``seq`` from being compared with ``gt`` (:func:`frame_w_mpjpe`). Pure: runs on a worker thread."""
    try:
        ids, values = frame_w_mpjpe(frame, gt_frame, seq.frame_intrinsics(frame), gt.frame_intrinsics(gt_frame), opts)
    except RotavatError as exc:
        return exc
    return {int(pid): float(v) for pid, v in zip(ids.tolist(), values.tolist()) if math.isfinite(v)}


@dataclass
class _RowState:
    """What the frame loop keeps of one row between frames: tiny per-frame numbers, never meshes."""

    seq: Sequence
    label: str
    path: str  # its entity name
    flags: dict | None
    own_ground: Camera | None  # the row's own camera when it is not the scene camera (its ground is drawn)
    role: str  # aligned | truth | raw (roles.py)
    framed: bool  # the 3D view starts framed on it
    tone: RowTone  # how its people's colours are tinted
    box: np.ndarray | None = None  # (2, 3) world box (lo, hi) of everything of it drawn so far, None before anything
    shown: set[int] = field(default_factory=set)  # person ids drawn in the previous frame
    static_done: set[int] = field(default_factory=set)  # person ids whose static parts (faces, colour) are logged
    series: dict[str, dict[int, list[tuple[int, float]]]] = field(default_factory=dict)  # key -> id -> (frame, value)
    footprints: dict[int, list[tuple[int, float, float]]] = field(default_factory=dict)  # id -> (frame, x, z) on the ground
    their: dict[int, list[tuple[int, np.ndarray]]] = field(default_factory=dict)  # id -> (frame, (3, 3): ours, theirs, up)
    people: int = 0
    w_mpjpe: EvalOptions | None = None  # how its people are matched to the ground truth's (None: not scored)

    def colors(self, person_ids: np.ndarray, style: RenderStyle) -> np.ndarray:
        """(P,) ids -> (P, 3) RGB in [0, 1]: the palette's colours in the row's tone."""
        ids = np.asarray(person_ids, dtype=np.int64)
        return row_tint(person_colors(ids, style.palette).reshape(len(ids), 3), self.tone)

    def grow(self, box: np.ndarray | None) -> None:
        """Widen the row's box by a frame's (2, 3) box (None: nothing drawn)."""
        if box is not None:
            self.box = box if self.box is None else np.stack([np.minimum(self.box[0], box[0]), np.maximum(self.box[1], box[1])])

    def add(self, key: str, pid: int, index: int, value: float) -> None:
        """One value of a track's series (non-finite values are left out)."""
        if math.isfinite(value):
            self.series.setdefault(key, {}).setdefault(pid, []).append((index, value))


def record_sequences(seqs: list[Sequence], out: Path, gt: Sequence | None = None, opts: ViewOptions | None = None,
                     progress: Callable[[], None] | None = None, labels: list[str] | None = None) -> ViewSummary:
    """Write one Rerun recording of ``seqs`` (and the ground truth ``gt``) to ``out``, atomically: the whole
    file or nothing. ``progress()`` is called :func:`view_steps` times. Each row is named by ``labels`` (one
    per sequence, then the ground truth's), else by its folder (:func:`rotavat_cli.render.rows.row_labels`);
    its entity tree by that name as a path part (:func:`rotavat_cli.render.rows.label_stem`)."""
    opts = ViewOptions() if opts is None else opts
    if not seqs:
        raise InputError("give at least one sequence")
    rr = require_rerun()
    rows = [*seqs, *([gt] if gt is not None else [])]
    labels = list(labels) if labels is not None else row_labels([Path(s.label) for s in rows])
    if len(labels) != len(rows) or len({label_stem(lab) for lab in labels}) < len(rows):
        raise InputError(f"give one distinct label per row ({len(rows)}), got {labels}")
    warnings: list[str] = []
    camera, fit, camera_source, gate_warning = _scene_camera(seqs, gt, opts)
    if gate_warning:
        warnings.append(gate_warning)
    timeline = _timeline(rows)
    chosen = _chosen_frames(timeline, opts)
    fps = next((float(s.meta["fps"]) for s in rows if (s.meta or {}).get("fps")), None)
    roles = [row_role(s.meta, truth=gt is not None and i == len(rows) - 1) for i, s in enumerate(rows)]
    states = [_RowState(s, lab, label_stem(lab), people_flags(s, warnings),
                        s.camera if s.camera is not None and not s.camera.matches(camera) else None, role, framed, tone)
              for s, lab, role, framed, tone in zip(rows, labels, roles, framed_rows(roles, opts.frame_all), row_tones(roles))]
    for state in states[:len(seqs)] if gt is not None else ():
        state.w_mpjpe = _w_mpjpe_options(state.seq, gt, warnings)
    notes = [f"{state.label}: placed in the scene camera ({camera_source}), as eval compares it; its own camera "
             f"({state.seq.camera_label}) gives its ground, drawn at {WORLD}/{state.path}/ground"
             for state in states if state.own_ground is not None]
    start = time.perf_counter()
    label = camera_label(camera, fit, camera_source)
    with atomic_path(out) as tmp:
        rec = rr.RecordingStream(RRD_APPLICATION_ID, recording_id=uuid.uuid5(uuid.NAMESPACE_URL, str(Path(out).resolve())),
                                 send_properties=False)
        try:
            rec.set_log_time_enabled(False)  # no wall-clock column: the same inputs give the same data
            rec.save(tmp)
            rec.send_recording_name(f"rotavat {__version__}: {', '.join(labels)}")
            writer = RecordingWriter(rr, rec, opts.style)
            writer.scene(camera, label, opts.image_plane_m)
            names = [timeline[k] for k in chosen]
            meshes = _Meshes(opts)
            for index, name, (image, ready) in zip(chosen, names, _prepared_frames(names, states, camera, opts)):
                writer.set_frame(index, fps)
                if image is not None:
                    writer.image(*image, camera.image_size)
                for state, row in zip(states, ready):
                    _record_row_frame(writer, state, row, index, meshes)
                    _keep_w_mpjpe(state, row, index, gt, warnings)
                if progress:
                    progress()
            rec.reset_time()
            box = _framed_box(states, camera)
            grid = ground_extent_m(box)  # (lo, hi): (x, z) of the grid under it
            _record_statics(writer, states, camera, fit.get("std"), grid, fps, opts.style)
            rec.send_blueprint(blueprint(rr, gt is not None, eye_world(_framed_points(states, camera, grid))))
            notes += _outside_notes(states, box)
            rec.flush()
        finally:
            rec.disconnect()
    seconds = time.perf_counter() - start
    entities = [f"{WORLD}/{s.path}" for s in states] + [f"plots/{k}" for k, *_ in SERIES if gt is not None or
                                                         k != W_MPJPE_SERIES[0]]
    return ViewSummary(str(out), labels, labels[-1] if gt is not None else None, len(chosen),
                       sum(s.people for s in states), label, os.path.getsize(out), seconds, entities,
                       [s.label for s in states if s.framed], warnings, notes)


@dataclass
class _Ready:
    """One row's frame made ready to log (on the worker thread): its people in world metres, float32."""

    row: RowFrame
    points_world: np.ndarray  # (P, N, 3): what each person is drawn from (vertices, a point cloud thinned, else joints)
    normals: np.ndarray | None  # (P, V, 3) unit vertex normals of meshes drawn with every vertex, or None
    colors: np.ndarray  # (P, 3) RGB in [0, 1]
    anchors: np.ndarray  # (P, 3) where each label goes (NaN: nowhere)
    texts: list[str]  # (P,) each label: the id, and a flagged person's flag
    flagged: np.ndarray  # (P,) bool: align flagged the person (people.csv)
    track: tuple[dict[str, np.ndarray], np.ndarray] | None  # the frame's track values {key: (P,)}, mid-soles (P, 3) world
    box: np.ndarray | None  # (2, 3) world box (lo, hi) of the finite points drawn, None when there are none
    their: np.ndarray | None = None  # (P, 3, 3) a tool's world: our pelvis (world), their pelvis (theirs), their up (world)
    w_mpjpe: dict[int, float] | RotavatError | None = None  # against the ground truth's frame: {gt id: mm}, or why not


def _prepared_frames(names: list[str], states: list[_RowState], camera: Camera, opts: ViewOptions
                     ) -> Iterator[tuple[tuple[bytes, str, tuple[int, int]] | None, list[_Ready | None]]]:
    """Per frame name, in order: its video frame (``--image``: the file, within ``limits.max_file_mb``, as
    :func:`.detail.video_frame` stores it: bytes, media type, (W, H) px) and each row's :class:`_Ready` (None
    where the row has no such frame).

    The next :data:`_AHEAD` frames are prepared on as many threads while the caller logs the current one
    (reading, placing and the normals are numpy work that releases the GIL, and overlaps Rerun's encoding): at
    most ``_AHEAD + 1`` frames are held at a time, whatever the sequence's length. A row read with ``--from``
    keeps its reader's state as it builds frames, so with one such row the frames are prepared one at a
    time (still ahead of the logging, on one thread). Each row's frame is read once: with a ground truth (the
    last row), the other rows' W-MPJPE against it is scored from the same frames (:func:`_frame_w_mpjpe`)."""
    def prepare(name: str) -> tuple[tuple[bytes, str, tuple[int, int]] | None, list[_Ready | None]]:
        image = None
        if opts.image_dir is not None:
            path = frame_image_path(opts.image_dir, name)
            image = video_frame(read_bytes(path), path, opts.image_max_px)
        frames = [state.seq.read_frame(name) if name in state.seq.frame_names else None for state in states]
        ready = [None if frame is None else _prepare(state, name, frame, camera, opts) for state, frame in zip(states, frames)]
        truth, truth_frame = states[-1], frames[-1]
        for state, frame, row in zip(states[:-1], frames[:-1], ready[:-1]):
            if state.w_mpjpe is not None and row is not None and truth_frame is not None:
                row.w_mpjpe = _frame_w_mpjpe(state.seq, truth.seq, frame, truth_frame, state.w_mpjpe)
        return image, ready

    ahead = _AHEAD if all(state.seq.origin is None for state in states) else 1
    with ThreadPoolExecutor(max_workers=ahead, thread_name_prefix="rotavat-view") as pool:
        queued = deque(pool.submit(prepare, name) for name in names[:ahead])
        for k in range(len(names)):
            ready = queued.popleft().result()
            if k + ahead < len(names):
                queued.append(pool.submit(prepare, names[k + ahead]))
            yield ready


def _prepare(state: _RowState, name: str, frame: Frame, camera: Camera, opts: ViewOptions) -> _Ready:
    """Row ``state``'s frame ``name`` (``frame``, read) in ``camera``'s world. Pure computation: nothing of ``state``
    changes (it runs on the worker thread)."""
    seq = state.seq
    row = read_row(seq, name, state.label, camera, None, state.flags, frame)
    P = len(row.person_ids)
    drawn = row.verts_cam if row.kind in ("mesh", "points") else row.joints_cam if row.kind == "skeleton" else None
    points_world = world_points_f32(camera, drawn) if P and drawn is not None else np.zeros((P, 0, 3), np.float32)
    anchors = label_anchors_world(points_world)
    every_vertex = not _reduced(row.kind, points_world.shape[1], opts)  # else the logging thread reduces it (_Meshes)
    normals = vertex_normals(points_world, row.faces) if opts.normals and row.kind == "mesh" and P and every_vertex else None
    if row.kind == "points":
        points_world = thin_points(points_world, opts.mesh_vertices)
    flags = row.flags or ("",) * P
    texts = [f"{pid} {flag}" if flag else str(pid) for pid, flag in zip(row.person_ids, flags)]
    got = frame_track_values(seq, frame, camera)
    track = None if got is None else (got[0], camera.world_from_cam(got[1]))
    return _Ready(row, points_world, normals, state.colors(row.person_ids, opts.style), anchors, texts,
                  np.array([bool(f) for f in flags], dtype=bool).reshape(P), track, _finite_box(points_world),
                  _their_world(seq, frame.data, camera) if P else None)


def _reduced(kind: str, vertices: int, opts: ViewOptions) -> bool:
    """Whether a mesh of ``vertices`` is drawn reduced (``view.mesh_vertices``)."""
    return kind == "mesh" and 0 < opts.mesh_vertices < vertices


def _finite_box(points: np.ndarray) -> np.ndarray | None:
    """(2, 3) lo, hi of the finite rows of (..., 3) points; None when there are none."""
    p = np.asarray(points).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    return np.stack([p.min(axis=0), p.max(axis=0)]).astype(np.float64) if len(p) else None


class _Meshes:
    """The mesh reductions of one recording (:func:`.detail.reduce_mesh`), one per list of faces, each found on the
    largest body of the first row frame drawn with it (a collapsed or empty body would reduce to a point). Used on
    the logging thread only, in frame order: the same inputs give the same reductions."""

    def __init__(self, opts: ViewOptions) -> None:
        self.opts = opts
        self._found: list[tuple[int, np.ndarray, MeshReduction]] = []  # (V, faces, reduction): a few, compared not hashed

    def drawn(self, ready: _Ready) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """A row frame's people as drawn: (P, N, 3) points, (P, N, 3) normals or None, (F, 3) faces or None (the
        row's own)."""
        row, points = ready.row, ready.points_world
        if not len(row.person_ids) or not _reduced(row.kind, points.shape[1], self.opts):
            return points, ready.normals, None
        faces = np.asarray(row.faces)
        reduction = next((r for n, kept, r in self._found if n == points.shape[1] and kept.shape == faces.shape
                          and np.array_equal(kept, faces)), None)  # every frame reads its faces again: a memcmp
        if reduction is None:
            ok = np.isfinite(points).all(axis=2, keepdims=True)  # (P, V, 1)
            spans = np.where(ok, points, -np.inf).max(axis=1) - np.where(ok, points, np.inf).min(axis=1)  # (P, 3)
            size = np.where(ok.any(axis=(1, 2)), spans.max(axis=1), 0.0)  # each body's largest side
            reduction = reduce_mesh(points[int(np.argmax(size))], faces, self.opts.mesh_vertices)
            self._found.append((points.shape[1], faces.copy(), reduction))
        small = reduction.apply(points)
        return small, vertex_normals(small, reduction.faces) if self.opts.normals else None, reduction.faces


def _their_world(seq: Sequence, data: dict, camera: Camera) -> np.ndarray | None:
    """(P, 3, 3) a frame's people in a tool's own world (``tool_*`` keys), or None without one: each person's pelvis
    in the scene's world (NaN without one), in the tool's world (NaN without ``tool_world_pelvis``), and the tool's
    up in the scene's world (its camera-frame up, :func:`their_up_cam`, turned by the scene camera)."""
    if data.get("tool_cam_global_orient") is None or data.get("tool_world_global_orient") is None:
        return None
    up_axis = ((seq.meta or {}).get("tool_world") or {}).get("up_axis", (0.0, 1.0, 0.0))
    up_world = their_up_cam(data["tool_cam_global_orient"], data["tool_world_global_orient"], up_axis) @ camera.R_cam_from_world
    P = len(up_world)
    pelvis = pelvis_cam(data)
    ours = np.full((P, 3), np.nan) if pelvis is None else camera.world_from_cam(pelvis)
    theirs = np.asarray(data.get("tool_world_pelvis", np.full((P, 3), np.nan)), dtype=np.float64)
    return np.stack([ours, theirs, up_world], axis=1)


def _record_row_frame(writer: RecordingWriter, state: _RowState, ready: _Ready | None, index: int,
                      meshes: _Meshes) -> None:
    """One row in frame ``index`` (``ready``: :func:`_prepare`'s, None when the row has no such frame): its people
    drawn (meshes reduced by ``meshes``) and labelled, their track values kept, the people gone since the previous
    frame cleared."""
    people: set[int] = set()
    if ready is not None:
        people = _draw_people(writer, state, ready, meshes)
        state.grow(ready.box)
        if ready.track is not None:
            _keep_track_values(state, ready.row.person_ids, *ready.track, index)
        if ready.their is not None:
            for pid, their in zip(ready.row.person_ids.tolist(), ready.their):
                state.their.setdefault(int(pid), []).append((index, their))
    elif state.shown:
        writer.clear(f"{WORLD}/{state.path}/labels")
    for pid in state.shown - people:
        writer.clear(f"{WORLD}/{state.path}/people/{pid}")
    state.shown = people
    state.people += len(people)


def _keep_w_mpjpe(state: _RowState, ready: _Ready | None, index: int, gt: Sequence | None, warnings: list[str]) -> None:
    """A row frame's W-MPJPE per ground-truth person into its series; when the row turns out not comparable with
    the ground truth, a warning and no W-MPJPE series for it at all (as ``rotavat eval`` fails on the sequence)."""
    if state.w_mpjpe is None or ready is None or ready.w_mpjpe is None:
        return
    if isinstance(ready.w_mpjpe, RotavatError):
        warnings.append(_no_w_mpjpe(state.seq, gt, ready.w_mpjpe))
        state.series.pop(W_MPJPE_SERIES[0], None)
        state.w_mpjpe = None
        return
    for pid, value in ready.w_mpjpe.items():
        state.add(W_MPJPE_SERIES[0], pid, index, value)


def _draw_people(writer: RecordingWriter, state: _RowState, ready: _Ready, meshes: _Meshes) -> set[int]:
    """A row frame's people and their labels (a flagged person's in red); returns their ids."""
    row = ready.row
    points, normals, faces = meshes.drawn(ready)
    for p, pid in enumerate(int(v) for v in row.person_ids):
        writer.person(f"{WORLD}/{state.path}/people/{pid}", row, points[p], None if normals is None else normals[p],
                      tuple(ready.colors[p]), pid not in state.static_done, faces)
        state.static_done.add(pid)
    placed = np.isfinite(ready.anchors).all(axis=1)
    writer.labels(f"{WORLD}/{state.path}/labels", ready.anchors[placed], [t for t, ok in zip(ready.texts, placed) if ok],
                  ready.colors[placed], ready.flagged[placed])
    return {int(v) for v in row.person_ids}


def _keep_track_values(state: _RowState, person_ids: np.ndarray, values: dict[str, np.ndarray], feet_world: np.ndarray,
                       index: int) -> None:
    """A frame's foot height, lean and stature per track, and its mid-soles on the ground (the tracks' paths)."""
    for p, pid in enumerate(int(v) for v in person_ids):
        for key, column in values.items():
            state.add(key, pid, index, float(column[p]))
        if np.isfinite(feet_world[p]).all():
            state.footprints.setdefault(pid, []).append((index, float(feet_world[p, 0]), float(feet_world[p, 2])))


def _record_statics(writer: RecordingWriter, states: list[_RowState], camera: Camera, std: dict | None,
                    grid: tuple[np.ndarray, np.ndarray], fps: float | None, style: RenderStyle) -> None:
    """What is known once every frame is seen: the ground grid over ``grid`` ((lo, hi), each (x, z): under what the
    view starts framed on, :func:`_framed_box`), the grounds one std away (``std``: the camera's ``fit.std``) where
    the framed rows' people are, the rows' own grounds, the tracks' paths on the ground, the time series."""
    lo, hi = grid
    writer.ground(lo, hi)
    near_lo, near_hi = ground_extent_m(_bulk(_footprints_xz([s for s in states if s.framed])))  # the ±1 std grounds
    for name, other in uncertainty_cameras(camera, std).items():
        corners = plane_quad_world(other, camera, near_lo, near_hi)
        if corners is not None:
            writer.plane(f"{WORLD}/ground/uncertainty/{name}", corners, style.camera, UNCERTAINTY_ALPHA)
    for state in states:
        if state.own_ground is not None:
            corners = plane_quad_world(state.own_ground, camera, lo, hi)
            if corners is not None:
                writer.plane(f"{WORLD}/{state.path}/ground", corners, style.ground, OWN_GROUND_ALPHA)
        ids = sorted(set(state.footprints) | {pid for series in state.series.values() for pid in series})
        colors = dict(zip(ids, state.colors(np.asarray(ids, dtype=np.int64), style)))
        for pid, steps in state.footprints.items():
            path = np.array([[x, 0.0, z] for _, x, z in steps])
            writer.track(f"{WORLD}/{state.path}/tracks/{pid}", track_strips(np.array([s[0] for s in steps]), path),
                         tuple(colors[pid]))
        _record_their_world(writer, state, style)
        statures = _stature_note(state.seq)
        for key, per_id in state.series.items():
            for pid, points in per_id.items():
                note = f" ({statures})" if key == "stature_m" and statures else ""
                writer.series(f"plots/{key}/{state.path}/{pid}", f"{state.label} {pid}{note}", tuple(colors[pid]),
                              points, fps)


def _record_their_world(writer: RecordingWriter, state: _RowState, style: RenderStyle) -> None:
    """A row's tool world, per track (docs/render.md): its pelvis path moved into ours by the heading fit (a rotation
    about the vertical and a translation, no scale: :func:`rotavat_cli.metrics.tool_world.heading_fit`) against the
    row's own pelvis path, in the track's colour paled; its ground as a faint square on ours below the track's
    median pelvis, tilted by its up (the mean over the track); that up as an arrow from the square's +X edge,
    labelled with its angle to ours."""
    up_axis = ((state.seq.meta or {}).get("tool_world") or {}).get("up_axis", (0.0, 1.0, 0.0))
    for pid, steps in state.their.items():
        index = np.array([i for i, _ in steps])
        ours, theirs, up = np.stack([v for _, v in steps]).transpose(1, 0, 2)  # (3, N, 3)
        color = tuple(0.5 + 0.5 * state.colors(np.array([pid]), style)[0])
        base = f"{WORLD}/{state.path}/their_world"
        paired = np.isfinite(ours).all(axis=1) & np.isfinite(theirs).all(axis=1)
        if paired.any():
            R, t = heading_fit(theirs[paired], ours[paired], None, up_axis)
            writer.track(f"{base}/paths/{pid}", track_strips(index[paired], theirs[paired] @ R[0].T + t[0]), color)
        placed = np.isfinite(ours).all(axis=1)
        mean_up = up.mean(axis=0)
        if not placed.any() or not np.isfinite(mean_up).all() or not np.linalg.norm(mean_up):
            continue
        mean_up /= np.linalg.norm(mean_up)
        square = tilted_square_world(np.median(ours[placed], axis=0) * [1.0, 0.0, 1.0], mean_up, THEIR_GROUND_HALF_M)
        angle = float(angles_deg(mean_up, np.array([0.0, 1.0, 0.0])))
        writer.plane(f"{base}/ground/{pid}", square, color, THEIR_GROUND_ALPHA)
        writer.arrow(f"{base}/up/{pid}", square[1:3].mean(axis=0), THEIR_UP_M * mean_up, color,  # beside the body
                     f"{pid}: their up, {angle:.1f}° from ours")


def _stature_note(seq: Sequence) -> str:
    """How an aligned row's statures are to be read (rotavat_cli.bodies.measure): "prior given back" when its camera's
    scale came from the people's stature prior, else "measured"; "" for other rows (a raw prediction's statures
    are its tool's bodies, the truth's the truth)."""
    if "aligned_from" not in seq.meta:
        return ""
    return "prior given back" if scale_source(seq.camera_fit) == "prior" else "measured"


def _footprints_xz(states: list[_RowState]) -> np.ndarray:
    """(N, 2) every track's ground positions (x, z) in every row of ``states``."""
    return np.array([(x, z) for s in states for steps in s.footprints.values() for _, x, z in steps]).reshape(-1, 2)


_EMPTY_BOX = np.array([[-5.0, 0.0, -10.0], [5.0, 2.0, 0.0]])  # framed when no framed row draws anything: ahead of the camera


def _framed_box(states: list[_RowState], camera: Camera) -> np.ndarray:
    """(2, 3) world box (lo, hi) the 3D view starts framed on (:func:`.roles.framed_rows`): everything the framed
    rows drew, and the camera centre."""
    boxes = [s.box for s in states if s.framed and s.box is not None] or [_EMPTY_BOX]
    points = np.vstack([*boxes, camera.center_world[None]])
    return np.stack([points.min(axis=0), points.max(axis=0)])


def _framed_points(states: list[_RowState], camera: Camera, grid: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(N, 3) what the eye frames (:func:`.scene.eye_world`): the corners of each framed row's box, the camera centre,
    the grid's corners (its tick labels are along its edges)."""
    (x0, z0), (x1, z1) = grid
    corners = [np.array([[x, y, z] for x in b[:, 0] for y in b[:, 1] for z in b[:, 2]])
               for b in (s.box for s in states if s.framed and s.box is not None)]
    return np.vstack([*corners, camera.center_world[None], [[x0, 0.0, z0], [x0, 0.0, z1], [x1, 0.0, z0], [x1, 0.0, z1]]])


def _outside_notes(states: list[_RowState], box: np.ndarray) -> list[str]:
    """A note for each row the 3D view does not start framed on whose people reach beyond ``box`` (+ the grid's
    margin): how far, and the flag that frames it."""
    notes = []
    framed = ", ".join(s.label for s in states if s.framed)
    for s in states:
        if s.framed or s.box is None:
            continue
        beyond = np.maximum(np.maximum(box[0] - s.box[0], s.box[1] - box[1]), 0.0)  # (3,) how far past each side
        if beyond.max() > GRID_MARGIN_M:
            notes.append(f"{s.label} ({s.role}): drawn up to {np.linalg.norm(beyond):.0f} m beyond the 3D view's first "
                         f"framing ({framed} and the camera); --frame-all frames every row")
    return notes


def _bulk(xz: np.ndarray) -> np.ndarray:
    """(2, 3) world corners of the 10th to 90th percentile of (N, 2) ground positions (a far outlier, a raw
    prediction metres off, is left out), or NaN when there are none."""
    if not len(xz):
        return np.full((2, 3), np.nan)
    lo, hi = np.percentile(xz, 10, axis=0), np.percentile(xz, 90, axis=0)
    return np.array([[lo[0], 0.0, lo[1]], [hi[0], 0.0, hi[1]]])
