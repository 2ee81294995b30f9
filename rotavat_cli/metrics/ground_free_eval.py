"""A sequence measured without ground truth: its people against the scene camera's ground, one pass over its frames.

``rotavat eval SEQ...`` without ``--gt`` gives one :class:`GroundFreeResult` per sequence (the input
and its aligned output side by side: before and after) from :func:`measure_sequence`; the
measures are the pure functions of :mod:`.ground_free`, their definitions in docs/metrics.md
("Without ground truth").

**The scene camera** (:func:`scene_cameras`, the one rule): each sequence is measured in the world
of its own camera.yaml; a sequence without one in ``--camera FILE``, else in the camera of the first
sequence given alongside that has one (the aligned output's camera.yaml is the camera it was aligned
with), as ``eval --gt`` measures every prediction against the one camera given alongside them (the
ground truth's). ``None`` for a sequence none of these gives: the caller says how to make one.

**Per person and frame** it keeps the foot point (ground contact: :func:`rotavat_cli.bodies.landmarks.ground_contact`
of the soles and the crown, the point align seats; meshes only), the crown, the two soles and the
joints (else the foot point and crown) for the temporal measures: a few hundred bytes, never meshes.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry.camera import Camera, camera_parameters
from ..errors import InputError
from ..bodies.landmarks import ground_contact, sole_crown_points
from ..bodies.measure import scale_source
from ..sequence import Frame, Sequence, read_camera_yaml
from .ground_free import (CONTACT_M, UP_WORLD, acceleration_m, contact_sliding_m, feet_height_summary, lean_summary,
                          stature_summary)
from .protocols import GVHMR_FPS
from .scene import lean_deg, stature_m

__all__ = ["GROUND_FREE", "GROUND_FREE_METRICS", "GROUND_FREE_UNITS", "CAMERA_STD_METRICS", "OWN", "GIVEN",
           "ALONGSIDE", "SceneCamera", "scene_cameras", "GroundFreeResult", "measure_sequence"]

GROUND_FREE = "ground_free"  # what a result's ``protocol`` says: the definitions of docs/metrics.md, "Without ground truth"
# Report names and units, headline first (the order of the tables).
GROUND_FREE_UNITS: dict[str, str] = {
    "feet_height": "mm", "penetration_pct": "%", "floating_pct": "%", "lean": "deg", "sliding": "m/s",
    "accel": "m/s²", "stature": "m", "stature_spread": "mm", "stature_sd": "mm", "feet_height_median": "mm",
    "penetration_depth": "mm", "lean_p90": "deg",
}
GROUND_FREE_METRICS = tuple(GROUND_FREE_UNITS)
_STD_UNITS = {"focal_px": "px", "pitch_deg": "deg", "roll_deg": "deg", "height_m": "m"}  # camera.yaml fit.std keys
CAMERA_STD_METRICS = tuple(f"cam_std_{key}" for key in _STD_UNITS)  # the camera's own uncertainty, as recorded
OWN, GIVEN, ALONGSIDE = "own", "given", "alongside"  # where a sequence's scene camera came from


@dataclass(frozen=True)
class SceneCamera:
    """The camera a sequence is measured in: the camera, its ``fit:`` block ({} for a given camera), where it
    came from (:data:`OWN`, :data:`GIVEN` by ``--camera``, :data:`ALONGSIDE`: another sequence's) and its file."""

    camera: Camera
    fit: dict
    whence: str
    file: str


def scene_cameras(seqs: Seq[Sequence], camera_path: str | Path | None = None) -> list[SceneCamera | None]:
    """Each sequence's scene camera by the module's rule: its own camera.yaml, else ``camera_path``, else the
    first other sequence's own camera.yaml; None when there is none."""
    out: list[SceneCamera | None] = []
    for seq in seqs:
        if seq.camera is not None:
            out.append(SceneCamera(seq.camera, dict(seq.camera_fit or {}), OWN, seq.camera_label))
        elif camera_path is not None:
            camera, fit = read_camera_yaml(camera_path, seq.image_size)
            out.append(SceneCamera(camera, dict(fit or {}), GIVEN, str(camera_path)))
        else:
            other = next((s for s in seqs if s is not seq and s.camera is not None), None)
            out.append(None if other is None else
                       SceneCamera(other.camera, dict(other.camera_fit or {}), ALONGSIDE, other.camera_label))
    return out


@dataclass
class GroundFreeResult:
    """One sequence's ground-free measures; the keys it shares with :class:`~.evaluate.EvalResult` mean the same."""

    pred: str
    gt: None = None
    frames: int = 0
    people_pred: int = 0  # people-frames
    tracks: int = 0  # track ids (0 without person_ids)
    protocol: str = GROUND_FREE
    metrics: dict[str, float] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    camera: dict[str, float] = field(default_factory=dict)  # the scene camera's recorded std (CAMERA_STD_METRICS)
    scene_camera: dict = field(default_factory=dict)  # file, from (own | given | alongside) and its parameters
    statures: list[dict] = field(default_factory=list)  # per track: id, pairs, median_m, spread_m
    flags: dict[str, int] | None = None  # people.csv's flag counts (an aligned output), None without one
    fps: float = GVHMR_FPS
    fps_assumed: bool = False  # meta.yaml gives no fps: GVHMR_FPS
    stature_from: str | None = None  # an aligned output: where its camera's scale came from (measure.SCALE_SOURCES)
    tool_world: dict | None = None  # the tool's own world against rotavat's (metrics.tool_world), None without one

    def as_dict(self) -> dict:
        """Plain dict for JSON."""
        return dict(vars(self))


@dataclass
class _Rows:
    """Per person-frame values of a sequence, gathered frame by frame (lists of per-frame arrays)."""

    frame_index: list = field(default_factory=list)  # (P,) int
    track_ids: list = field(default_factory=list)  # (P,) int
    foot_world: list = field(default_factory=list)  # (P, 3)
    crown_world: list = field(default_factory=list)  # (P, 3)
    soles_world: list = field(default_factory=list)  # (P, 2, 3)
    points_cam: list = field(default_factory=list)  # (P, J, 3) joints as read (else foot and crown), camera frame
    meshless: int = 0  # people-frames without a mesh (no foot point)
    without_ids: int = 0  # frames with people but no person_ids

    def add(self, index: int, frame: Frame, camera: Camera) -> None:
        """One frame's people."""
        n = frame.n_people
        if n == 0:
            return
        verts = frame.get("vertices")
        if verts is not None and verts.shape[1] > 0:
            left, right, crown = sole_crown_points(verts)
            foot = ground_contact(left, right, crown)
        else:
            left = right = crown = foot = np.full((n, 3), np.nan)
            self.meshless += n
        self.without_ids += frame.get("person_ids") is None
        self.frame_index.append(np.full(n, index, dtype=np.int64))
        self.track_ids.append(frame.person_ids)
        self.foot_world.append(camera.world_from_cam(foot))
        self.crown_world.append(camera.world_from_cam(crown))
        self.soles_world.append(camera.world_from_cam(np.stack([left, right], axis=1)))
        joints = frame.get("joints")
        self.points_cam.append(joints if joints is not None and joints.shape[1] else np.stack([foot, crown], axis=1))

    def stacked(self, key: str) -> np.ndarray:
        """All frames' values of ``key``, concatenated along the rows."""
        return np.concatenate(getattr(self, key)) if getattr(self, key) else np.zeros(0)


def measure_sequence(seq: Sequence, scene: SceneCamera, progress: Callable[[], None] | None = None) -> GroundFreeResult:
    """Every ground-free measure of one sequence (opened: :func:`~rotavat_cli.sequence.open_sequence`) in the
    world of ``scene`` (:func:`scene_cameras`), reading its frames once."""
    fps, fps_assumed = _fps(seq)
    result = GroundFreeResult(seq.label, frames=len(seq), fps=fps, fps_assumed=fps_assumed,
                              units=dict(GROUND_FREE_UNITS))
    rows = _Rows()
    for index, frame in enumerate(seq.frames()):
        rows.add(index, frame, scene.camera)
        if progress:
            progress()
    result.people_pred = sum(len(ids) for ids in rows.track_ids)
    has_ids = result.people_pred > 0 and rows.without_ids == 0
    foot, crown = rows.stacked("foot_world").reshape(-1, 3), rows.stacked("crown_world").reshape(-1, 3)
    ids, frame_index = rows.stacked("track_ids").astype(np.int64), rows.stacked("frame_index").astype(np.int64)
    metrics = feet_height_summary(foot[:, 1])
    metrics.update(lean_summary(lean_deg(foot, crown, UP_WORLD)))
    statures, tracks = stature_summary(stature_m(foot, crown), ids if has_ids else None)
    metrics.update(statures)
    result.tracks = len(tracks) if tracks is not None else 0
    result.statures = tracks.rows() if tracks is not None else []
    metrics.update(_temporal(rows, ids, frame_index, has_ids, fps, result.notes))
    result.metrics = {name: metrics[name] for name in GROUND_FREE_METRICS}
    result.camera = {f"cam_std_{key}": float(value) for key, value in (scene.fit.get("std") or {}).items()
                     if key in _STD_UNITS and value is not None}
    result.units.update({f"cam_std_{key}": unit for key, unit in _STD_UNITS.items()})
    result.scene_camera = {"file": scene.file, "from": scene.whence, **camera_parameters(scene.camera)}
    if "aligned_from" in (seq.meta or {}) and seq.camera is not None:  # statures scaled by the camera it was aligned with
        result.stature_from = scale_source(seq.camera_fit)
    result.flags = _people_csv_flags(seq, result.notes)
    result.notes[:0] = _notes(seq, scene, rows, result)
    return result


def _temporal(rows: _Rows, ids: np.ndarray, frame_index: np.ndarray, has_ids: bool, fps: float,
              notes: list[str]) -> dict[str, float]:
    """Sliding (m/s) and acceleration (m/s^2) of the tracks; NaN with a note when there is none."""
    if not has_ids:
        if rows.track_ids:
            notes.append("sliding, accel, stature_spread: no person_ids (track ids) in "
                         f"{rows.without_ids} frame(s) with people: no tracks to follow")
        return {"sliding": math.nan, "accel": math.nan}
    sliding = contact_sliding_m(rows.stacked("soles_world").reshape(-1, 2, 3), ids, frame_index)
    if sliding.size == 0:
        notes.append(f"sliding: no sole within {CONTACT_M * 100:g} cm of the ground in two consecutive frames "
                     "of a track (no contact to slide on)")
    shapes = {p.shape[1:] for p in rows.points_cam}
    if len(shapes) > 1:
        notes.append(f"accel: the frames' joint counts differ ({', '.join(str(s[0]) for s in sorted(shapes))}): "
                     "not measured")
        return {"sliding": float(sliding.mean() * fps) if sliding.size else math.nan, "accel": math.nan}
    accel = acceleration_m(np.concatenate(rows.points_cam), ids, frame_index)
    accel = accel[np.isfinite(accel)]
    if accel.size == 0:
        notes.append("accel: no track has 3 consecutive frames")
    return {"sliding": float(sliding.mean() * fps) if sliding.size else math.nan,
            "accel": float(accel.mean() * fps * fps) if accel.size else math.nan}


def _notes(seq: Sequence, scene: SceneCamera, rows: _Rows, result: GroundFreeResult) -> list[str]:
    """What a reader of the numbers should know: whose camera, the fps assumed, what was left out."""
    notes = []
    if result.people_pred == 0:
        notes.append("no people in any frame: nothing to measure")
    if scene.whence != OWN:
        why = "--camera" if scene.whence == GIVEN else "the camera of the sequence given alongside"
        notes.append(f"measured in {scene.file} ({why}: it has no camera.yaml of its own)")
    if not scene.fit:
        notes.append(f"{scene.file}: a given camera (no fit: block): no uncertainty recorded")
    if scene.fit.get("implausible"):
        notes.append(f"{scene.file}: its calibration found it implausible ({'; '.join(map(str, scene.fit['implausible']))})")
    if result.fps_assumed and result.tracks:
        notes.append(f"fps: meta.yaml gives none; {GVHMR_FPS:g} assumed (sliding in m/s and accel in m/s² scale with it)")
    if rows.meshless:
        notes.append(f"{rows.meshless} of {result.people_pred} people-frames have no mesh (no foot point): left out of "
                     "feet height, lean, stature and sliding")
    return notes


def _fps(seq: Sequence) -> tuple[float, bool]:
    """The sequence's frame rate (meta.yaml ``fps``) and whether it was assumed (GVHMR's 30 when absent)."""
    fps = (seq.meta or {}).get("fps")
    if fps is None:
        return GVHMR_FPS, True
    if not (math.isfinite(fps) and fps > 0):
        where = Path(seq.path) / "meta.yaml" if seq.origin is None else seq.label
        raise InputError(f"{where}: key 'fps' must be a positive number of frames per second, got {fps!r}")
    return float(fps), False


def _people_csv_flags(seq: Sequence, notes: list[str]) -> dict[str, int] | None:
    """How many people-frames of an aligned output's people.csv carry each flag; None without a people.csv."""
    path = Path(seq.path) / "people.csv"
    if seq.origin is not None or not path.is_file():
        return None
    counts: dict[str, int] = {}
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            reader = csv.DictReader(handle)
            if "flag" not in (reader.fieldnames or ()):
                notes.append(f"{path}: no flag column: flags not counted")
                return None
            for record in reader:
                flag = (record["flag"] or "").strip()
                if flag:
                    counts[flag] = counts.get(flag, 0) + 1
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        notes.append(f"{path}: unreadable ({exc}): flags not counted")
        return None
    return counts

