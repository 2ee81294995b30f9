"""People as one mesh per person-frame, each shown on its own frame only (no body model needed).

Why this layout (docs/export.md, "Per-frame meshes"): glTF animates node transforms, skins and morph
weights, not vertex positions. Morph targets would need one weight per target per keyframe (frames^2
numbers per person) and every frame's vertices all the same; a mesh per person-frame costs its
vertices once and a few hundred bytes of JSON. Each person-frame node is made visible on its frame
only by a ``STEP`` keyframed ``scale`` (0 -> 1 -> 0), the standard trick that Blender's and three.js's
importers play back. All nodes of a frame share one time accessor (three keyframes: the frames before,
at and after it) and every node shares the same three value accessors; all meshes of one topology share
one index accessor. No normals are stored (viewers compute them: glTF's rule for a mesh without normals
is flat shading), which halves the file.

Node tree: ``person_<id>`` (static) -> ``person_<id>/<frame name>`` (its mesh, points or bone lines).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera, world_points_f32
from ..errors import InputError
from ..render.rows import read_row
from ..render.style import RGB
from ..sequence import Frame, Sequence
from .glb import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, GlbWriter, index_component
from .scan import SequenceScan, frame_kind
from .scene import LINES, PLACEHOLDER_BOUNDS3, POINTS, TRIANGLES, GltfBuilder, Stage, add_stage, frame_times_s

__all__ = ["FramesPlan", "plan_frames", "world_points_f32"]

_MODES = {"mesh": TRIANGLES, "skeleton": LINES, "points": POINTS}
# STEP keyframe values of the visibility trick: hidden, shown, hidden (scale x, y, z)
_VISIBILITY = np.array([[0.0] * 3, [1.0] * 3, [0.0] * 3], dtype=np.float32)


@dataclass
class FramesPlan:
    """The laid-out scene of per-frame meshes: the document, its stage, and where each frame's points go."""

    builder: GltfBuilder
    stage: Stage
    scan: SequenceScan
    position_accessors: list[int]  # per person-frame, in scan order
    frame_offsets: np.ndarray  # (T,) BIN offset of each frame's first person's points
    frame_starts: np.ndarray  # (T + 1,) index of each frame's first person-frame in scan order

    def write(self, writer: GlbWriter, seq: Sequence, camera: Camera, frames: Iterable[Frame],
              progress: Callable[[], None] | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Second pass: every frame's people to the world (float32), written at their offsets, their
        accessors' bounds set. ``frames``: the sequence's frames again, in order. Returns the people's
        (lo, hi) box (world, (3,) each; None without people)."""
        lo = hi = None
        for index, frame in enumerate(frames):
            first, last = int(self.frame_starts[index]), int(self.frame_starts[index + 1])
            if first < last:
                world = self._frame_points(seq, frame, camera, first, last)
                writer.write_at(int(self.frame_offsets[index]), world)
                by_axis = np.ascontiguousarray(world.transpose(0, 2, 1))  # (P, 3, N): reduces 15x faster than axis 1
                frame_lo, frame_hi = by_axis.min(axis=2), by_axis.max(axis=2)  # (P, 3)
                for accessor, p_lo, p_hi in zip(self.position_accessors[first:last], frame_lo, frame_hi):
                    entry = self.builder.layout.accessors[accessor]
                    entry["min"], entry["max"] = p_lo.astype(np.float64).tolist(), p_hi.astype(np.float64).tolist()
                lo = frame_lo.min(axis=0) if lo is None else np.minimum(lo, frame_lo.min(axis=0))
                hi = frame_hi.max(axis=0) if hi is None else np.maximum(hi, frame_hi.max(axis=0))
            if progress is not None:
                progress()
        return lo, hi

    def _frame_points(self, seq: Sequence, frame: Frame, camera: Camera, first: int, last: int) -> np.ndarray:
        """(P, N, 3) float32 world points of a frame's people, as the one-frame export places them; InputError
        when the frame no longer holds the people the first pass found there (it changed meanwhile)."""
        tracks = [pf.track for pf in self.scan.person_frames[first:last]]
        if frame.person_ids.tolist() != tracks:
            raise InputError(f"{frame.source}: changed while it was being exported (people {frame.person_ids.tolist()}, "
                             f"{tracks} before); export again")
        row = read_row(seq, frame.name, "", camera, frame=frame)
        points_cam = row.verts_cam if frame_kind(frame) in ("mesh", "points") else row.joints_cam
        if points_cam.shape[1] != self.scan.person_frames[first].n_points:
            raise InputError(f"{frame.source}: changed while it was being exported (its points per person); export again")
        return world_points_f32(camera, points_cam)


def _index_accessors(builder: GltfBuilder, scan: SequenceScan) -> dict[str, int]:
    """One index accessor per triangle list or bone list of the scan (16-bit indices when they fit)."""
    out = {}
    for key, indices in scan.topologies.items():
        component, dtype = index_component(int(indices.max()) + 1 if indices.size else 0)
        out[key] = builder.static_accessor(np.asarray(indices, dtype=dtype).reshape(-1), component, "SCALAR",
                                           ELEMENT_ARRAY_BUFFER, key.split(":")[0] + "_indices")
    return out


def _visibility_accessors(builder: GltfBuilder, n_frames: int, fps: float) -> tuple[list[int], list[int]]:
    """Per frame: the time accessor and the value accessor of its nodes' STEP scale keyframes.

    Frame i's nodes are keyed at the frames before, at and after it (0 -> 1 -> 0): shown from frame i's
    time until the next frame's. The first frame's have two keys (1 -> 0), the last frame's two (0 -> 1).
    """
    layout = builder.layout
    times = frame_times_s(n_frames, fps)
    times_view = layout.static_array(times, times.nbytes, None, "frame_times")
    values_view = layout.static_array(_VISIBILITY, _VISIBILITY.nbytes, None, "visibility")
    shown_hidden = layout.accessor(values_view, 12, FLOAT, 2, "VEC3", name="shown_hidden")
    hidden_shown_hidden = layout.accessor(values_view, 0, FLOAT, 3, "VEC3", name="hidden_shown_hidden")
    hidden_shown = layout.accessor(values_view, 0, FLOAT, 2, "VEC3", name="hidden_shown")
    time_accessors, value_accessors = [], []
    for i in range(n_frames):
        start, stop = max(i - 1, 0), min(i + 1, n_frames - 1)
        bounds = ([float(times[start])], [float(times[stop])])
        time_accessors.append(layout.accessor(times_view, 4 * start, FLOAT, stop - start + 1, "SCALAR", bounds))
        value_accessors.append(shown_hidden if i == 0 else hidden_shown if i == n_frames - 1 else hidden_shown_hidden)
    return time_accessors, value_accessors


def plan_frames(scan: SequenceScan, camera: Camera, palette: tuple[RGB, ...], fps: float) -> FramesPlan:
    """Lay out the scene of per-frame meshes (:mod:`.frames`) from the first pass's findings."""
    builder = GltfBuilder()
    layout = builder.layout
    n_frames = len(scan.names)
    tracks = scan.tracks
    materials = builder.person_materials(tracks, palette)
    person_nodes = {track: builder.node({"name": f"person_{track}", "children": []}, root=True) for track in tracks}
    indices = _index_accessors(builder, scan)
    animated = n_frames > 1 and bool(scan.person_frames)
    time_accessors, value_accessors = _visibility_accessors(builder, n_frames, fps) if animated else ([], [])
    total_points = sum(pf.n_points for pf in scan.person_frames)
    positions = layout.view(total_points * 12, ARRAY_BUFFER, "positions", stride=12) if total_points else None
    frame_offsets = np.zeros(n_frames, dtype=np.int64)
    frame_starts = np.zeros(n_frames + 1, dtype=np.int64)
    accessors, offset, previous = [], 0, -1
    base = layout.view_offset(positions) if positions is not None else 0
    for i, pf in enumerate(scan.person_frames):
        if pf.frame != previous:
            frame_offsets[pf.frame] = base + offset
            frame_starts[previous + 1:pf.frame + 1] = i
            previous = pf.frame
        name = f"person_{pf.track}/{scan.names[pf.frame]}"
        accessor = layout.accessor(positions, offset, FLOAT, pf.n_points, "VEC3", PLACEHOLDER_BOUNDS3)
        mesh = builder.mesh(name, {"POSITION": accessor}, materials[pf.track], _MODES[pf.kind], indices.get(pf.topology or ""))
        node: dict = {"name": name, "mesh": mesh}
        if animated and pf.frame != 0:
            node["scale"] = [0.0, 0.0, 0.0]  # shown by its keyframes only (a still viewer shows the first frame)
        index = builder.node(node)
        builder.nodes[person_nodes[pf.track]]["children"].append(index)
        if animated:
            builder.animate(index, "scale", time_accessors[pf.frame], value_accessors[pf.frame], "STEP")
        accessors.append(accessor)
        offset += pf.n_points * 12
    frame_starts[previous + 1:] = len(scan.person_frames)
    stage = add_stage(builder, camera)
    return FramesPlan(builder, stage, scan, accessors, frame_offsets, frame_starts)
