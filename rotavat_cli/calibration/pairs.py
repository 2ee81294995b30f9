"""Foot (mid-sole) and head (crown) points of the people of a frame or a whole sequence.

2D points: explicit ``feet_2d``/``heads_2d`` in a frame take precedence; otherwise they are the
projections of the mesh landmarks (:mod:`rotavat_cli.landmarks`) through the intrinsics the HPS
method used (the frame's ``focal_length``/``K``, one per person or one per frame, or meta.yaml's):
the pixels the method drew, whatever the camera's real focal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import project_cam_to_px
from ..errors import InputError
from ..landmarks import foot_head_points
from ..sequence import Frame, Intrinsics, Sequence, people_not_placed

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


def gather_pairs(seq: Sequence) -> FootHeadPairs:
    """Pool every frame's foot/head pixel pairs (non-finite pairs dropped), one frame at a time.

    Meshes that are root-centred or behind the camera (never placed in the camera frame) give no
    pair; ``not_in_front`` counts them, so a refusal can say why.
    """
    feet, heads, index, ids, sources = [], [], [], [], set()
    tracked = True
    not_in_front = 0
    for i, frame in enumerate(seq.frames()):
        seq.require_static_frame(frame)
        tracked &= frame.n_people == 0 or frame.get("person_ids") is not None
        f, h, src = frame_foot_head_px(frame, seq.frame_intrinsics(frame))
        if src == "mesh":  # a mesh that is not where the camera saw it projects to meaningless pixels
            off = np.logical_or(*people_not_placed(frame))
            f[off], h[off] = np.nan, np.nan
            not_in_front += int(off.sum())
        if len(f):
            sources.add(src)
        feet.append(f)
        heads.append(h)
        index.append(np.full(len(f), i, dtype=np.int64))
        ids.append(frame.person_ids)
    feet_px = np.concatenate(feet) if feet else np.zeros((0, 2))
    heads_px = np.concatenate(heads) if heads else np.zeros((0, 2))
    keep = np.all(np.isfinite(feet_px), axis=1) & np.all(np.isfinite(heads_px), axis=1)
    source = sources.pop() if len(sources) == 1 else ("mixed" if sources else "none")
    return FootHeadPairs(feet_px[keep], heads_px[keep], np.concatenate(index)[keep] if index else np.zeros(0, np.int64),
                         np.concatenate(ids)[keep] if ids else np.zeros(0, np.int64), tracked, len(seq), source,
                         not_in_front)
