"""``rotavat view``: sequences as one Rerun recording (.rrd), streamed frame by frame.

Every row (each sequence, and the ground truth) is placed in one world, the scene camera's (Y up, the
ground at ``Y = 0``: docs/conventions.md), from its camera-frame coordinates: rows differ in the viewer
exactly as ``rotavat eval`` compares them. The scene camera is ``--camera``, else the first sequence's
own camera.yaml, else the ground truth's; it passes the camera gate first
(:func:`rotavat_cli.alignment.camera_gate.check_fit`). The entity tree (docs/render.md, "rotavat view"):

- ``world``: the view coordinates (right-handed, Y up); ``world/ground``: the grid and its metre ticks;
  ``world/ground/uncertainty/<height|pitch>_<minus|plus>_1sd``: the ground as it would be one standard deviation
  away (camera.yaml's ``fit.std``); ``world/camera``: the camera's pose and label, ``world/camera/image`` its
  pinhole (intrinsics) and the video frames (``--image``);
- ``world/<row>/people/<id>/{mesh,points,skeleton,joints,label}``: one person, by what the row has (a mesh,
  vertices without faces, joints only), its label its id (and its flag, from align's people.csv);
  ``world/<row>/tracks/<id>``: its path on the ground; ``world/<row>/ground``: the row's own ground when its
  camera.yaml is not the scene camera (the ground truth's true ground);
- ``plots/<series>/<row>/<id>``: foot height (m), lean (deg), stature (m) of each track over time and, with a
  ground truth, the W-MPJPE (mm) of each ground-truth person.

Timelines: ``frame`` (the index in the sorted frame names of all rows) and ``time`` (seconds, when the first
row's meta.yaml gives an ``fps``). Memory stays flat in the number of frames: one frame of every row is held
at a time, and only the tracks' small per-frame numbers are kept for the end.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..alignment.camera_gate import check_fit, render_remedies
from ..atomic import atomic_path
from ..camera import Camera
from ..config import default_config, packaged_default
from ..errors import InputError, RotavatError
from ..metrics.evaluate import EvalOptions, evaluate
from ..option_rules import Rule, check_fields
from ..outputs import RRD_APPLICATION_ID
from ..render.rows import frame_image_path, label_stem, no_camera, people_flags, read_row, row_labels, select_frames
from ..render.skeleton import BONE_RADIUS_M, JOINT_RADIUS_M, POINT_RADIUS_M, layout_bones
from ..render.style import RGB, RenderStyle, person_colors, rgb8, vertex_normals
from ..render.tracks import TRACK_SERIES, frame_track_values
from ..render.views import RowFrame
from ..sequence import Frame, Sequence, read_camera_yaml
from ..version import __version__
from .scene import (camera_label, grid_lines_world, grid_step_m, grid_ticks_world, ground_extent_m, label_anchors_world,
                    plane_quad_world, track_strips, uncertainty_cameras, world_points_f32, eye_world)

__all__ = ["RERUN_INSTALL", "ViewOptions", "ViewSummary", "require_rerun", "record_sequences",
           "view_steps"]

RERUN_INSTALL = "pip install 'rotavat[view]'"  # the extra that brings the Rerun SDK (and its viewer)
WORLD = "world"
W_MPJPE_SERIES = ("w_mpjpe_mm", "W-MPJPE", "mm")  # with a ground truth: per ground-truth person
_SERIES = tuple((key, title, unit) for key, title, unit, *_ in TRACK_SERIES) + (W_MPJPE_SERIES,)
_FLAG_RGB = (0.85, 0.1, 0.1)  # a flagged person's label
_LABEL_RADIUS_M = 0.03
_UNCERTAINTY_ALPHA = 6  # of 255: the ±1 std grounds
_OWN_GROUND_ALPHA = 70  # a row's own (true) ground
_TRACK_RADIUS_M = 0.015


def require_rerun() -> Any:
    """The ``rerun`` module; InputError (exit 2) saying how to install it when it is missing."""
    try:
        import rerun  # lazy: optional extra rotavat[view]
    except ImportError:
        raise InputError(f"rotavat view needs the Rerun SDK, which is not installed: {RERUN_INSTALL}") from None
    return rerun


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
    style: RenderStyle = packaged_default(_packaged_options, "style")
    camera_path: Path | None = None  # not a config key: --camera
    image_dir: Path | None = None  # not a config key: --image
    accept_camera: bool = False  # not a config key: --accept-camera
    reader_flags: tuple[str, ...] = ()  # not a config key: how rows read with --from were read (the gate's advice)

    RULES: ClassVar[dict[str, Rule]] = {"every": Rule(low=1), "image_plane_m": Rule(low=0.01, high=1000, unit="m")}

    def __post_init__(self) -> None:
        check_fields(self, self.RULES)

    @classmethod
    def from_config(cls, view: dict, render: dict, camera_path: Path | None = None,
                    image_dir: Path | None = None) -> "ViewOptions":
        """Options from merged ``view`` and ``render`` config sections; ValueError naming a bad option."""
        return cls(None if view["frames"] is None else str(view["frames"]), view["every"], float(view["image_plane_m"]),
                   bool(view["normals"]), RenderStyle.from_config(render), camera_path, image_dir)


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
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def view_steps(seqs: list[Sequence], gt: Sequence | None, opts: ViewOptions) -> int:
    """How many ``progress()`` calls :func:`record_sequences` makes: one per recorded frame."""
    return len(_chosen_names([*seqs, *([gt] if gt is not None else [])], opts))


def _chosen_names(rows: list[Sequence], opts: ViewOptions) -> list[str]:
    """The frames recorded: the sorted union of every row's frame names, then ``frames``/``every`` (all by default)."""
    names = sorted(set().union(*(s.frame_names for s in rows))) if rows else []
    if opts.frames is None and opts.every is None:
        return names
    return [names[i] for i in select_frames(len(names), opts.frames, opts.every)]


def _scene_camera(seqs: list[Sequence], gt: Sequence | None, labels: list[str],
                  opts: ViewOptions) -> tuple[Camera, dict, str, str | None]:
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


def _w_mpjpe_series(seq: Sequence, gt: Sequence, warnings: list[str]) -> dict[str, dict[int, float]]:
    """``{frame name: {ground-truth person id: W-MPJPE mm}}`` of ``seq`` against ``gt`` (``rotavat eval``'s
    matching, per matched pair); {} and a warning when the two cannot be compared."""
    try:
        result = evaluate(seq, gt, dataclasses.replace(EvalOptions(), engine="numpy"))
    except RotavatError as exc:
        warnings.append(f"{seq.label}: no W-MPJPE against {gt.label} ({exc})")
        return {}
    out: dict[str, dict[int, float]] = {}
    columns = result.per_person
    for name, pid, value in zip(columns["frame"], columns["person_id"], columns["w_mpjpe"]):
        if value is not None and math.isfinite(value):
            out.setdefault(name, {})[int(pid)] = float(value)
    return out


@dataclass
class _RowState:
    """What the frame loop keeps of one row between frames: tiny per-frame numbers, never meshes."""

    seq: Sequence
    label: str
    path: str  # its entity name
    flags: dict | None
    shown: set[int] = field(default_factory=set)  # person ids drawn in the previous frame
    static_done: set[int] = field(default_factory=set)  # person ids whose static parts (faces, colour) are logged
    series: dict[str, dict[int, list[tuple[int, float]]]] = field(default_factory=dict)  # key -> id -> (frame, value)
    footprints: dict[int, list[tuple[int, float, float]]] = field(default_factory=dict)  # id -> (frame, x, z) on the ground
    people: int = 0

    def add(self, key: str, pid: int, index: int, value: float) -> None:
        """One value of a track's series (non-finite values are left out)."""
        if math.isfinite(value):
            self.series.setdefault(key, {}).setdefault(pid, []).append((index, value))


class _Writer:
    """The Rerun calls: one method per kind of thing logged. Holds the recording stream and the style."""

    def __init__(self, rr: Any, rec: Any, style: RenderStyle, normals: bool) -> None:
        self.rr, self.rec, self.style, self.normals = rr, rec, style, normals

    def set_frame(self, index: int, fps: float | None) -> None:
        """Every log call until the next one belongs to frame ``index`` (and second ``index / fps``)."""
        self.rec.set_time("frame", sequence=index)
        if fps:
            self.rec.set_time("time", duration=index / fps)

    def scene(self, camera: Camera, label: str, image_plane_m: float) -> None:
        """The world's axes and the camera: its pose (world from camera), its label, its pinhole."""
        rr = self.rr
        self.rec.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Y_UP, static=True)
        self.rec.log(f"{WORLD}/camera", rr.Transform3D(translation=camera.center_world, mat3x3=camera.R_cam_from_world.T),
                     static=True)
        self.rec.log(f"{WORLD}/camera", rr.Points3D([[0.0, 0.0, 0.0]], labels=[label], colors=[rgb8(self.style.camera)],
                                                   radii=0.05, show_labels=True), static=True)
        self.rec.log(f"{WORLD}/camera/image", rr.Pinhole(image_from_camera=camera.K, resolution=list(camera.image_size),
                                                         camera_xyz=rr.ViewCoordinates.RDF,
                                                         image_plane_distance=image_plane_m,
                                                         color=rgb8(self.style.camera)), static=True)

    def image(self, path: Path) -> None:
        """This frame's video frame under the camera (the file's bytes: JPEG or PNG, never decoded here)."""
        self.rec.log(f"{WORLD}/camera/image", self.rr.EncodedImage(path=path))

    def person(self, base: str, row: RowFrame, points_world: np.ndarray, normals: np.ndarray | None, color: RGB,
               first: bool) -> None:
        """One person of a row: mesh (with its (V, 3) ``normals``, or None), point cloud or skeleton by the row's kind."""
        rr, rec, rgb = self.rr, self.rec, rgb8(color)
        kind = row.kind
        if kind == "mesh":
            if first:  # the faces and colour of a track do not change: logged once, for every frame
                rec.log(f"{base}/mesh", rr.Mesh3D.from_fields(triangle_indices=np.asarray(row.faces, dtype=np.uint32),
                                                              albedo_factor=rgb), static=True)
            rec.log(f"{base}/mesh", rr.Mesh3D.from_fields(vertex_positions=np.asarray(points_world, dtype=np.float32),
                                                          vertex_normals=normals))
        elif kind == "points":
            rec.log(f"{base}/points", rr.Points3D(np.asarray(points_world, dtype=np.float32), colors=[rgb], radii=POINT_RADIUS_M))
        elif kind == "skeleton":
            bones = layout_bones(row.joints_layout)
            if bones:
                pairs = points_world[np.asarray(bones, dtype=np.int64)].astype(np.float32)  # (B, 2, 3)
                rec.log(f"{base}/skeleton", rr.LineStrips3D(pairs, colors=[rgb], radii=BONE_RADIUS_M))
            rec.log(f"{base}/joints", rr.Points3D(np.asarray(points_world, dtype=np.float32), colors=[rgb], radii=JOINT_RADIUS_M))

    def labels(self, path: str, anchors: np.ndarray, texts: list[str], colors: np.ndarray) -> None:
        """A row's labels, one above each person (P, 3): its id, a flagged person's with its flag (and in red)."""
        radii = np.where([" " in t for t in texts], 2 * _LABEL_RADIUS_M, _LABEL_RADIUS_M)
        self.rec.log(path, self.rr.Points3D(anchors.astype(np.float32), labels=texts, colors=colors, radii=radii,
                                            show_labels=True))

    def clear(self, base: str) -> None:
        """A person no longer in the frame: nothing of it is drawn from now on (until it is logged again)."""
        self.rec.log(base, self.rr.Clear(recursive=True))

    def ground(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """The ground grid (static) and its metre ticks."""
        rr = self.rr
        step = grid_step_m(lo, hi)
        self.rec.log(f"{WORLD}/ground", rr.LineStrips3D(grid_lines_world(lo, hi, step).astype(np.float32),
                                                        colors=[rgb8(self.style.grid)], radii=0.005), static=True)
        points, labels = grid_ticks_world(lo, hi, step)
        self.rec.log(f"{WORLD}/ground/ticks", rr.Points3D(points.astype(np.float32), labels=labels, radii=0.02,
                                                          colors=[rgb8(self.style.grid)], show_labels=True), static=True)

    def plane(self, path: str, corners: np.ndarray, color: RGB, alpha: int) -> None:
        """A faint quad (static): another ground over the grid's rectangle."""
        quad = corners.astype(np.float32)
        self.rec.log(path, self.rr.Mesh3D(vertex_positions=quad, triangle_indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                                          albedo_factor=[*rgb8(color), alpha]), static=True)
        outline = np.concatenate([quad, quad[:1]])
        self.rec.log(f"{path}/outline", self.rr.LineStrips3D([outline], colors=[[*rgb8(color), 160]], radii=0.006),
                     static=True)

    def track(self, path: str, strips: list[np.ndarray], color: RGB) -> None:
        """A track's path on the ground (static)."""
        if strips:
            self.rec.log(path, self.rr.LineStrips3D([s.astype(np.float32) for s in strips], colors=[rgb8(color)],
                                                    radii=_TRACK_RADIUS_M), static=True)

    def series(self, path: str, name: str, color: RGB, points: list[tuple[int, float]], fps: float | None) -> None:
        """One time series at once (its style static, its values as columns on the frame timeline)."""
        rr = self.rr
        index = np.array([i for i, _ in points], dtype=np.int64)
        values = np.array([v for _, v in points], dtype=np.float64)
        self.rec.log(path, rr.SeriesLines(colors=[rgb8(color)], names=[name], widths=[1.5]), static=True)
        indexes = [rr.TimeColumn("frame", sequence=index)]
        if fps:
            indexes.append(rr.TimeColumn("time", duration=index / fps))
        self.rec.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=values))


def _blueprint(rr: Any, with_gt: bool, eye: tuple[np.ndarray, np.ndarray]) -> Any:
    """The viewer's layout: the 3D scene seen from ``eye`` (position, target), one time-series panel per series,
    the timeline open and the other panels folded away."""
    rrb = rr.blueprint
    keys = [k for k, *_ in _SERIES if with_gt or k != W_MPJPE_SERIES[0]]
    titles = {k: f"{title} ({unit})" for k, title, unit in _SERIES}
    plots = [rrb.TimeSeriesView(origin=f"plots/{k}", name=titles[k], plot_legend=rrb.PlotLegend(visible=False))
             for k in keys]  # a crowd's legend would cover its plot; hovering a line names it
    scene = rrb.Spatial3DView(origin=WORLD, name="scene (world metres, Y up)", line_grid=False,
                              eye_controls=rrb.EyeControls3D(position=eye[0], look_target=eye[1]))
    return rrb.Blueprint(rrb.Horizontal(scene, rrb.Vertical(*plots), column_shares=[3, 1]),
                         rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
                         rrb.TimePanel(state="expanded"))


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
    notes: list[str] = []
    camera, fit, camera_source, gate_warning = _scene_camera(seqs, gt, labels, opts)
    if gate_warning:
        warnings.append(gate_warning)
    names = _chosen_names(rows, opts)
    index_of = {name: k for k, name in enumerate(sorted(set().union(*(s.frame_names for s in rows))))}
    fps = next((float(s.meta["fps"]) for s in rows if (s.meta or {}).get("fps")), None)
    states = [_RowState(s, lab, label_stem(lab), people_flags(s, warnings)) for s, lab in zip(rows, labels)]
    w_mpjpe = {i: _w_mpjpe_series(s, gt, warnings) for i, s in enumerate(seqs)} if gt is not None else {}
    for state in states:
        own = state.seq.camera
        if own is not None and own != camera:
            notes.append(f"{state.label}: placed in the scene camera ({camera_source}), as eval compares it; its own "
                         f"camera ({state.seq.camera_label}) gives its ground, drawn at {WORLD}/{state.path}/ground")
    start = time.perf_counter()
    label = camera_label(camera, fit, camera_source)
    lo_hi = [camera.center_world[[0, 2]].copy(), camera.center_world[[0, 2]].copy()]  # the people's and camera's x, z
    with atomic_path(out) as tmp:
        rec = rr.RecordingStream(RRD_APPLICATION_ID, recording_id=uuid.uuid5(uuid.NAMESPACE_URL, str(Path(out).resolve())),
                                 send_properties=False)
        try:
            rec.set_log_time_enabled(False)  # no wall-clock column: the same inputs give the same data
            rec.save(tmp)
            rec.send_recording_name(f"rotavat {__version__}: {', '.join(labels)}")
            writer = _Writer(rr, rec, opts.style, opts.normals)
            writer.scene(camera, label, opts.image_plane_m)
            for name in names:
                index = index_of[name]
                writer.set_frame(index, fps)
                if opts.image_dir is not None:
                    writer.image(frame_image_path(opts.image_dir, name))
                for i, state in enumerate(states):
                    _record_row_frame(writer, state, name, index, camera, lo_hi, w_mpjpe.get(i, {}))
                if progress:
                    progress()
            rec.reset_time()
            _record_statics(writer, states, camera, fit.get("std") if isinstance(fit.get("std"), dict) else None,
                            lo_hi, fps, opts.style)
            rec.send_blueprint(_blueprint(rr, gt is not None, eye_world(_footprints_xz(states))))
            rec.flush()
        finally:
            rec.disconnect()
    seconds = time.perf_counter() - start
    entities = [f"{WORLD}/{s.path}" for s in states] + [f"plots/{k}" for k, *_ in _SERIES if gt is not None or
                                                         k != W_MPJPE_SERIES[0]]
    return ViewSummary(str(out), labels, labels[-1] if gt is not None else None, len(names),
                       sum(s.people for s in states), label, os.path.getsize(out), seconds, entities, warnings, notes)


def _record_row_frame(writer: _Writer, state: _RowState, name: str, index: int, camera: Camera,
                      lo_hi: list[np.ndarray], w_mpjpe: dict[str, dict[int, float]]) -> None:
    """One row in frame ``name``: its people drawn and labelled, their track values kept, the people gone
    since the previous frame cleared (all of them when the row has no such frame)."""
    seq = state.seq
    people: set[int] = set()
    if name in seq.frame_names:
        frame = seq.read_frame(name)
        people = _draw_people(writer, state, read_row(seq, name, state.label, camera, None, state.flags, frame), camera)
        _keep_track_values(state, seq, frame, index, camera, lo_hi)
        for pid, value in w_mpjpe.get(name, {}).items():
            state.add(W_MPJPE_SERIES[0], pid, index, value)
    elif state.shown:
        writer.clear(f"{WORLD}/{state.path}/labels")
    for pid in state.shown - people:
        writer.clear(f"{WORLD}/{state.path}/people/{pid}")
    state.shown = people
    state.people += len(people)


def _draw_people(writer: _Writer, state: _RowState, row: RowFrame, camera: Camera) -> set[int]:
    """A row frame's people, in ``camera``'s world, and their labels; returns their ids."""
    P = len(row.person_ids)
    drawn = row.verts_cam if row.kind in ("mesh", "points") else row.joints_cam if row.kind == "skeleton" else None
    points_world = world_points_f32(camera, drawn) if P and drawn is not None else np.zeros((P, 0, 3), np.float32)
    normals = vertex_normals(points_world, row.faces) if writer.normals and row.kind == "mesh" and P else None
    colors = person_colors(row.person_ids, writer.style.palette)
    for p, pid in enumerate(int(v) for v in row.person_ids):
        writer.person(f"{WORLD}/{state.path}/people/{pid}", row, points_world[p], None if normals is None else normals[p],
                      tuple(colors[p]), pid not in state.static_done)
        state.static_done.add(pid)
    flags = row.flags or ("",) * P
    anchors = label_anchors_world(points_world)
    placed = np.isfinite(anchors).all(axis=1)
    flagged = np.array([bool(f) for f in flags], dtype=bool).reshape(P)
    label_rgb = np.where(flagged[:, None], _FLAG_RGB, colors.reshape(P, 3))
    texts = [f"{pid} {flag}" if flag else str(pid) for pid, flag in zip(row.person_ids, flags)]
    writer.labels(f"{WORLD}/{state.path}/labels", anchors[placed], [t for t, ok in zip(texts, placed) if ok],
                  np.round(255 * label_rgb[placed]).astype(np.uint8))
    return {int(v) for v in row.person_ids}


def _keep_track_values(state: _RowState, seq: Sequence, frame: Frame, index: int, camera: Camera,
                       lo_hi: list[np.ndarray]) -> None:
    """A frame's foot height, lean and stature per track, and its mid-soles on the ground (the tracks' paths;
    ``lo_hi``: the x, z range they span so far, grown in place)."""
    got = frame_track_values(seq, frame, camera)
    if got is None:
        return
    values, feet_cam, _ = got
    feet_world = camera.world_from_cam(feet_cam)
    for p, pid in enumerate(int(v) for v in frame.person_ids):
        for key, column in values.items():
            state.add(key, pid, index, float(column[p]))
        if np.isfinite(feet_world[p]).all():
            state.footprints.setdefault(pid, []).append((index, float(feet_world[p, 0]), float(feet_world[p, 2])))
    placed = feet_world[np.isfinite(feet_world).all(axis=1)][:, [0, 2]]
    if len(placed):
        lo_hi[0] = np.minimum(lo_hi[0], placed.min(axis=0))
        lo_hi[1] = np.maximum(lo_hi[1], placed.max(axis=0))


def _record_statics(writer: _Writer, states: list[_RowState], camera: Camera, std: dict | None,
                    lo_hi: list[np.ndarray], fps: float | None, style: RenderStyle) -> None:
    """What is known once every frame is seen: the ground grid over everyone, the grounds one std away
    (``std``: the camera's ``fit.std``), the rows' own grounds, the tracks' paths on the ground, the time series."""
    lo, hi = ground_extent_m(np.array([[lo_hi[0][0], 0.0, lo_hi[0][1]], [lo_hi[1][0], 0.0, lo_hi[1][1]]]))
    writer.ground(lo, hi)
    near_lo, near_hi = ground_extent_m(_bulk(states))  # the ±1 std grounds: where the people are
    for name, other in uncertainty_cameras(camera, std).items():
        corners = plane_quad_world(other, camera, near_lo, near_hi)
        if corners is not None:
            writer.plane(f"{WORLD}/ground/uncertainty/{name}", corners, style.camera, _UNCERTAINTY_ALPHA)
    for state in states:
        own = state.seq.camera
        if own is not None and own != camera:
            corners = plane_quad_world(own, camera, lo, hi)
            if corners is not None:
                writer.plane(f"{WORLD}/{state.path}/ground", corners, style.ground, _OWN_GROUND_ALPHA)
        ids = sorted(set(state.footprints) | {pid for series in state.series.values() for pid in series})
        colors = dict(zip(ids, person_colors(np.asarray(ids, dtype=np.int64), style.palette))) if ids else {}
        for pid, steps in state.footprints.items():
            path = np.array([[x, 0.0, z] for _, x, z in steps])
            writer.track(f"{WORLD}/{state.path}/tracks/{pid}", track_strips(np.array([s[0] for s in steps]), path),
                         tuple(colors[pid]))
        for key, per_id in state.series.items():
            for pid, points in per_id.items():
                writer.series(f"plots/{key}/{state.path}/{pid}", f"{state.label} {pid}", tuple(colors[pid]), points, fps)


def _footprints_xz(states: list[_RowState]) -> np.ndarray:
    """(N, 2) every track's ground positions (x, z) in every row."""
    return np.array([(x, z) for s in states for steps in s.footprints.values() for _, x, z in steps]).reshape(-1, 2)


def _bulk(states: list[_RowState]) -> np.ndarray:
    """(2, 3) world corners of the 10th to 90th percentile of the people's ground positions (a far outlier,
    a raw prediction metres off, is left out), or NaN when there are none."""
    xz = _footprints_xz(states)
    if not len(xz):
        return np.full((2, 3), np.nan)
    lo, hi = np.percentile(xz, 10, axis=0), np.percentile(xz, 90, axis=0)
    return np.array([[lo[0], 0.0, lo[1]], [hi[0], 0.0, hi[1]]])
