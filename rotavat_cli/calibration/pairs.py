"""Foot (mid-sole) and head (crown) points of the people of a frame or a whole sequence.

2D points: explicit ``feet_2d``/``heads_2d`` in a frame take precedence; otherwise they are the
projections of the mesh landmarks (:mod:`rotavat_cli.bodies.landmarks`) through the intrinsics the HPS
method used (the frame's ``focal_length``/``K``, one per person or one per frame, or meta.yaml's):
the pixels the method drew, whatever the camera's real focal.

Where the frame has 3D people, each pair also carries the person's own sole->crown axis in the
method's camera frame (the mesh landmarks, or align's rule for joints:
:func:`rotavat_cli.bodies.frame_points.frame_foot_head_cam`), which calibration may use as evidence of
the vertical.

**Who is in view.** A pair whose foot or crown pixel lies outside the image or within
:func:`rotavat_cli.bodies.frame_points.edge_margin_px` of its border (for a mesh, its projected mid-sole or crown: the tool drew
legs the photo cuts off, as BEV on upper-body photos puts the feet 600-1300 px below a 2500-px
image) is not a foot/head pair: :func:`rotavat_cli.bodies.frame_points.in_view` marks it, ``FootHeadPairs.cut`` carries
the mark, and calibration leaves it out with a note (:func:`rotavat_cli.calibration.sequence.calibrate_sequence`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ..geometry.camera import project_cam_to_px
from ..bodies.frame_points import MeshIntrinsics, beyond_border_px, edge_margin_px, frame_foot_head_cam
from ..errors import InputError
from ..bodies.landmarks import foot_head_points
from ..bodies.posture import postures
from ..parallel import cap_workers, ordered_map
from ..sequence import DirectorySource, Frame, Intrinsics, Sequence, can_align, people_not_placed

__all__ = ["FootHeadPairs", "frame_foot_head_px", "gather_pairs"]

@dataclass(frozen=True)
class FootHeadPairs:
    """Foot/head pixel pairs pooled over a sequence."""

    feet_px: np.ndarray  # (N, 2)
    heads_px: np.ndarray  # (N, 2)
    frame_index: np.ndarray  # (N,) int
    person_ids: np.ndarray  # (N,) int track ids (frame-local indices when ``tracked`` is False)
    tracked: bool  # every frame with people carries person_ids
    n_frames: int
    source: str  # "2d" (explicit points), "mesh" (projected landmarks) or "mixed"
    not_in_front: int = 0  # meshes dropped: root-centred or behind the camera (sequence.people_not_placed)
    axes_cam: np.ndarray | None = None  # (N, 3) unit sole->crown axis in the method's camera frame; NaN: no 3D person
    postures: np.ndarray | None = None  # (N,) posture of the person (rotavat_cli.bodies.posture.POSTURES); "unknown": no joints
    cut: np.ndarray | None = None  # (N,) bool: the person is cut by the image border (:func:`in_view`); None: unknown
    cut_depth_px: np.ndarray | None = None  # (N,) px: how far the cut pair's farthest point lies beyond the border

    def subset(self, keep: np.ndarray) -> "FootHeadPairs":
        """The pairs selected by ``keep`` ((N,) bool or indices)."""
        return replace(self, feet_px=self.feet_px[keep], heads_px=self.heads_px[keep],
                       frame_index=self.frame_index[keep], person_ids=self.person_ids[keep],
                       **{name: None if getattr(self, name) is None else getattr(self, name)[keep]
                          for name in ("axes_cam", "postures", "cut", "cut_depth_px")})


def frame_foot_head_px(frame: Frame, intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray, str]:
    """(P, 2) foot and head pixels of a frame and where they came from ('2d' or 'mesh')."""
    feet, heads = frame.get("feet_2d"), frame.get("heads_2d")
    if feet is not None and heads is not None:
        return feet[:, :2].astype(np.float64), heads[:, :2].astype(np.float64), "2d"
    verts = frame.get("vertices")
    if verts is None:
        if frame.n_people == 0:
            return np.zeros((0, 2)), np.zeros((0, 2)), "2d"
        raise InputError(f"{frame.source}: needs 'feet_2d' and 'heads_2d', or 'vertices' to find them")
    focals = intrinsics.focals_px(frame.n_people)
    if focals is None or intrinsics.principal_point is None:
        raise InputError(f"{frame.source}: projecting the meshes needs the focal length they were made with "
                         "(meta.yaml 'focal_length' or 'K', or a frame key)")
    feet_cam, heads_cam = foot_head_points(verts)
    return (project_cam_to_px(feet_cam, focals, intrinsics.principal_point),
            project_cam_to_px(heads_cam, focals, intrinsics.principal_point), "mesh")


class _FramePairs(NamedTuple):
    """One frame's pairs before pooling (:func:`_frame_pairs`): (P, ...) arrays each."""

    feet_px: np.ndarray
    heads_px: np.ndarray
    person_ids: np.ndarray  # frame-local 0..P-1 when the frame has no track ids
    tracked: bool  # no people, or track ids
    axes_cam: np.ndarray
    postures: np.ndarray
    source: str
    not_in_front: int


def _frame_pairs(seq: Sequence, frame: Frame) -> _FramePairs:
    """A frame's foot/head pixels, track ids, body axes and postures; meshes not placed in the camera frame NaN."""
    seq.require_static_frame(frame)
    intrinsics = seq.frame_intrinsics(frame)
    f, h, src = frame_foot_head_px(frame, intrinsics)
    not_in_front = 0
    if src == "mesh":  # a mesh that is not where the camera saw it projects to meaningless pixels
        off = np.logical_or(*people_not_placed(frame))
        f[off], h[off] = np.nan, np.nan
        not_in_front = int(off.sum())
    return _FramePairs(f, h, frame.person_ids, frame.n_people == 0 or frame.get("person_ids") is not None,
                       _body_axes_cam(frame, intrinsics, f, h), _postures(frame, seq.joints_layout), src, not_in_front)


def _chunk_pairs(task: tuple[Sequence, tuple[str, ...]]) -> list[_FramePairs]:
    """:func:`_frame_pairs` of the frames ``names`` of ``seq`` (a worker's share)."""
    seq, names = task
    return [_frame_pairs(seq, seq.read_frame(name)) for name in names]


_PARALLEL_MIN_FRAMES = 400  # fewer frames are read in this process: starting workers costs more than it saves


def _all_frame_pairs(seq: Sequence, meanwhile: Callable[[], None] | None) -> list[_FramePairs]:
    """:func:`_frame_pairs` of every frame, in order: a long sequence directory's frames read by worker processes
    (one per core; the pairs are small to send back), ``meanwhile`` run here while they read."""
    names = seq.frame_names
    workers = cap_workers(0, len(names) // _PARALLEL_MIN_FRAMES)
    if workers <= 1 or not isinstance(seq.frame_source, DirectorySource):  # an importer's source may hold a whole file
        if meanwhile is not None:
            meanwhile()
        return [_frame_pairs(seq, frame) for frame in seq.frames()]
    size = -(-len(names) // (2 * workers))  # two chunks per worker: every chunk in flight at once
    chunks = [(seq, names[i:i + size]) for i in range(0, len(names), size)]
    return [pairs for part in ordered_map(_chunk_pairs, chunks, workers, window=len(chunks), processes=True,
                                          meanwhile=meanwhile) for pairs in part]


def gather_pairs(seq: Sequence, meanwhile: Callable[[], None] | None = None) -> FootHeadPairs:
    """Pool every frame's foot/head pixel pairs (non-finite pairs dropped).

    Meshes that are root-centred or behind the camera (never placed in the camera frame) give no
    pair; ``not_in_front`` counts them, so a refusal can say why. A long sequence directory is read by
    worker processes; ``meanwhile`` is run in this process while they read (the refinement's imports).
    """
    parts = _all_frame_pairs(seq, meanwhile)
    size = seq.image_size
    tracked = all(part.tracked for part in parts)
    sources = {part.source for part in parts if len(part.feet_px)}
    feet_px = np.concatenate([part.feet_px for part in parts]) if parts else np.zeros((0, 2))
    heads_px = np.concatenate([part.heads_px for part in parts]) if parts else np.zeros((0, 2))
    keep = np.all(np.isfinite(feet_px), axis=1) & np.all(np.isfinite(heads_px), axis=1)
    source = sources.pop() if len(sources) == 1 else ("mixed" if sources else "none")
    beyond = _cut_beyond_px(feet_px, heads_px, size)[keep]  # over every pair at once, not frame by frame
    index = [np.full(len(part.feet_px), i, dtype=np.int64) for i, part in enumerate(parts)]
    ids = [part.person_ids for part in parts]
    return FootHeadPairs(feet_px[keep], heads_px[keep], np.concatenate(index)[keep] if index else np.zeros(0, np.int64),
                         np.concatenate(ids)[keep] if ids else np.zeros(0, np.int64), tracked, len(seq), source,
                         sum(part.not_in_front for part in parts),
                         np.concatenate([part.axes_cam for part in parts])[keep] if parts else np.zeros((0, 3)),
                         np.concatenate([part.postures for part in parts])[keep] if parts else np.zeros(0, "<U8"),
                         None if size is None else beyond > -edge_margin_px(size), None if size is None else beyond)


def _cut_beyond_px(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int] | None) -> np.ndarray:
    """(P,) px: how far each pair's foot or crown lies beyond the image border (negative: how far inside); NaN
    without an image size. The pair's own pixels decide (a mesh whose projection leaves its tool's 2D keypoints
    is a mismatched model: :mod:`rotavat_cli.formats.model_fit`)."""
    if image_size is None:
        return np.full(len(feet_px), np.nan)
    return np.maximum(beyond_border_px(feet_px, image_size), beyond_border_px(heads_px, image_size))


def _postures(frame: Frame, layout: str | None) -> np.ndarray:
    """(P,) posture of each person from the frame's 3D joints (:func:`rotavat_cli.bodies.posture.postures`);
    "unknown" without joints or for a layout without the legs' and shoulders' joints."""
    joints = frame.get("joints")
    names = None if joints is None or frame.n_people == 0 else postures(joints, layout)
    return np.full(frame.n_people, "unknown", "<U8") if names is None else np.asarray(names, "<U8")


def _body_axes_cam(frame: Frame, intrinsics: Intrinsics, feet_px: np.ndarray, heads_px: np.ndarray) -> np.ndarray:
    """(P, 3) unit sole->crown axis of each person in the method's camera frame (NaN without 3D people):
    the mesh landmarks, or for joints-only frames align's rule from the joints and the pixels."""
    out = np.full((frame.n_people, 3), np.nan)
    if frame.n_people == 0 or not can_align(frame) or intrinsics.principal_point is None:
        return out
    focals = intrinsics.focals_px(frame.n_people)
    if focals is None:
        return out
    if frame.get("vertices") is None and not (np.isfinite(feet_px).all() and np.isfinite(heads_px).all()):
        frame = frame.replace(feet_2d=np.where(np.isfinite(feet_px), feet_px, 0.0),
                              heads_2d=np.where(np.isfinite(heads_px), heads_px, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        sole, crown = frame_foot_head_cam(frame, MeshIntrinsics(np.asarray(focals, np.float64),
                                                                tuple(intrinsics.principal_point)))
        axis = crown - sole
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    return np.where(np.isfinite(axis).all(axis=-1, keepdims=True), axis, np.nan)
