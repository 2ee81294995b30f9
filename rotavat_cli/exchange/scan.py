"""The first pass over a sequence: who is in which frame, and what each person is drawn from.

An animated export lays its whole file out before writing any vertex (:mod:`.glb`), so it reads the
sequence twice: this pass keeps a few numbers per person-frame (the track, how many points, which
triangle list), never the points themselves; the second pass computes and writes them.

A person's **track** is its ``person_ids`` entry, stable across frames. A frame without ``person_ids``
numbers its people 0..P-1 (frame-local, docs/conventions.md): its ``person_3`` is the fourth person of
each frame, not one body followed in time (:attr:`SequenceScan.frame_local_ids` says so).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..formats.smpl import BodyModel
from ..render.skeleton import layout_bones, layout_name
from ..sequence import Frame, Sequence
from .body import has_body_params

__all__ = ["PersonFrame", "SequenceScan", "scan_sequence", "frame_kind", "topology_key"]


@dataclass(frozen=True)
class PersonFrame:
    """One person in one frame: frame index, index in the frame, track id, what is drawn (``mesh``: vertices
    and triangles; ``points``: vertices without faces; ``skeleton``: joints only), how many points and the
    key of its index list in :attr:`SequenceScan.topologies` (None for points)."""

    frame: int
    slot: int
    track: int
    kind: str
    n_points: int
    topology: str | None


@dataclass
class SequenceScan:
    """What the first pass found: frame names, every person-frame in frame order, the index lists
    (triangles, or bones as line pairs) by key, the tracks, and the body-model facts the skinned export needs."""

    names: list[str]
    person_frames: list[PersonFrame] = field(default_factory=list)
    topologies: dict[str, np.ndarray] = field(default_factory=dict)  # key -> (F, 3) triangles or (B, 2) bones
    frame_local_ids: bool = False  # some frame had no person_ids
    params_everywhere: bool = True  # every frame with people carries the body-model parameters
    betas_sum: dict[int, np.ndarray] = field(default_factory=dict)  # track -> sum of its betas over its frames
    betas_count: dict[int, int] = field(default_factory=dict)  # track -> frames summed
    betas_first: dict[int, np.ndarray] = field(default_factory=dict)  # track -> its first frame's betas
    betas_spread: dict[int, float] = field(default_factory=dict)  # track -> largest |betas - first betas|

    @property
    def tracks(self) -> list[int]:
        """Track ids, sorted."""
        return sorted({pf.track for pf in self.person_frames})

    def track_frames(self) -> dict[int, list[int]]:
        """Track -> the indices of the frames it is in, increasing."""
        out: dict[int, list[int]] = {}
        for pf in self.person_frames:
            out.setdefault(pf.track, []).append(pf.frame)
        return out

    def mean_betas(self, track: int) -> np.ndarray:
        """(B,) the mean of a track's betas over its frames."""
        return self.betas_sum[track] / self.betas_count[track]


def topology_key(kind: str, index_list: np.ndarray) -> str:
    """A short key naming one index list (same triangles, same key)."""
    digest = hashlib.blake2b(np.ascontiguousarray(index_list, dtype=np.int64).tobytes(), digest_size=12).hexdigest()
    return f"{kind}:{len(index_list)}:{digest}"


def frame_kind(frame: Frame) -> str:
    """What a frame's people are drawn from: ``mesh``, ``points``, ``skeleton`` or ``none`` (as the pictures)."""
    verts, faces, joints = frame.get("vertices"), frame.get("faces"), frame.get("joints")
    if verts is not None and verts.shape[1]:
        return "mesh" if faces is not None and len(faces) else "points"
    if joints is not None and joints.shape[1]:
        return "skeleton"
    return "none"


def _frame_topology(seq: Sequence, frame: Frame, kind: str, known: dict[str, np.ndarray]) -> tuple[str, str | None, int]:
    """(kind, index list key or None, points per person) of a frame's people; new index lists go into ``known``.
    A skeleton whose layout has no bones is drawn as its joints' points."""
    if kind == "mesh":
        faces = np.asarray(frame.data["faces"], dtype=np.int64)
        key = topology_key("mesh", faces)
        known.setdefault(key, faces)
        return kind, key, int(frame.data["vertices"].shape[1])
    if kind == "points":
        return kind, None, int(frame.data["vertices"].shape[1])
    n_joints = int(frame.data["joints"].shape[1])
    bones = layout_bones(layout_name(seq.joints_layout, n_joints))
    if not bones:
        return "points", None, n_joints
    pairs = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    key = topology_key("skeleton", pairs)
    known.setdefault(key, pairs)
    return kind, key, n_joints


def scan_sequence(seq: Sequence, model: BodyModel | None = None, progress: Callable[[], None] | None = None,
                  check: Callable[[Frame], None] | None = None, frames: Iterable[Frame] | None = None) -> SequenceScan:
    """Read every frame once and note its people (see :class:`SequenceScan`).

    model: a body model whose betas are summed per track (for a skinned export), or None. check: called on
    each frame (e.g. that its parameters fit the model). Raises InputError naming a frame whose people have
    nothing to draw.
    """
    scan = SequenceScan(list(seq.frame_names))
    for index, frame in enumerate(seq.frames() if frames is None else frames):
        if check is not None:
            check(frame)
        n_people = frame.n_people
        if frame.get("person_ids") is None and n_people:
            scan.frame_local_ids = True
        if n_people:
            kind = frame_kind(frame)
            if kind == "none":
                raise InputError(f"{frame.source}: neither 'vertices' nor 'joints': nothing to draw")
            kind, key, n_points = _frame_topology(seq, frame, kind, scan.topologies)
            tracks = frame.person_ids.tolist()
            scan.person_frames.extend(PersonFrame(index, slot, int(track), kind, n_points, key)
                                      for slot, track in enumerate(tracks))
            if not has_body_params(frame):
                scan.params_everywhere = False
            elif model is not None:
                _add_betas(scan, tracks, np.asarray(frame.data["smpl_betas"], dtype=np.float64).reshape(n_people, -1))
        if progress is not None:
            progress()
    return scan


def _add_betas(scan: SequenceScan, tracks: list[int], betas: np.ndarray) -> None:
    """Add a frame's betas (P, B) to its tracks' sums; note how far each strays from the track's first."""
    for track, row in zip(tracks, betas):
        if track not in scan.betas_sum:
            scan.betas_sum[track], scan.betas_first[track], scan.betas_spread[track] = row.copy(), row.copy(), 0.0
            scan.betas_count[track] = 1
            continue
        scan.betas_count[track] += 1
        width = min(len(row), len(scan.betas_sum[track]))  # a track's betas count should not change; if it does
        scan.betas_sum[track] = scan.betas_sum[track][:width] + row[:width]
        spread = float(np.max(np.abs(row[:width] - scan.betas_first[track][:width]))) if width else 0.0
        scan.betas_spread[track] = max(scan.betas_spread[track], spread)
