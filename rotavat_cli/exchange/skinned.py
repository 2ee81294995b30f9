"""People as skinned body models: one shaped rest mesh and one skeleton per person, animated by keyframes.

For each track (``person_<id>``):

- a **mesh** (node ``person_<id>/mesh``, a root of the scene as glTF recommends for skinned meshes): the
  track's shaped rest mesh ``v_template + shapedirs . betas`` (its betas' mean over its frames), with each
  vertex's 4 largest skinning weights (renormalised: glTF's ``JOINTS_0``/``WEIGHTS_0``, all three.js reads);
- a **skeleton**: node ``person_<id>`` (its visibility), then one node per model joint
  (``person_<id>/<joint name>``) whose rest translation is the joint's offset from its parent for those
  betas, and inverse bind matrices ``translate(-J_j)``;
- **keyframes** on every frame the track is in: each non-root joint's rotation (``smpl_body_pose``), and
  the root joint's translation (the world pelvis), rotation (the world root orientation) and scale
  (``smpl_scale``), ``LINEAR`` (rotations: spherical); and, for a track absent from some frames, ``STEP``
  scale keyframes 0/1 on ``person_<id>`` hiding it there.

Evaluated, joint ``j``'s world transform is ``G_j = T(pelvis) R_root S(scale) ... T(J_j - J_parent) R_j``
and a vertex moves by ``sum_j w_j G_j T(-J_j)``: exactly the model's linear blend skinning scaled about
the pelvis (the posing rule of docs/conventions.md) **without pose-corrective blend shapes**, which glTF
cannot express (they depend on the pose, not on one weight per target).

Keyframes are written track by track and joint by joint (glTF wants each channel contiguous), so the
frames' values are gathered a chunk of frames at a time (:class:`_ChannelChunks`) and written as runs:
memory stays flat in the number of frames.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera
from ..errors import InputError
from ..formats.smpl import BodyModel
from ..render.style import RGB
from ..sequence import Frame, Sequence
from .body import body_frame, continuous_quaternions, joint_names, quaternions_xyzw, rest_shape
from .glb import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT, GlbWriter, index_component
from .scan import SequenceScan
from .scene import POINTS, TRIANGLES, GltfBuilder, Stage, add_stage, frame_times_s

__all__ = ["SkinnedPlan", "plan_skinned", "skin_weights", "inverse_bind_matrices"]

INFLUENCES = 4  # JOINTS_0 / WEIGHTS_0: the one set every glTF viewer reads
_CHUNK_BYTES = 16 << 20  # keyframes gathered before they are written (all tracks together)


def skin_weights(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A model's skinning weights (V, J) -> the 4 largest per vertex: joints (V, 4) int, weights (V, 4)
    float32 summing to 1, and the largest weight left out (0 when no vertex has more than 4 joints).
    Unused slots get joint 0 and weight 0."""
    weights = np.asarray(weights, dtype=np.float64)
    order = np.argsort(-weights, axis=1, kind="stable")[:, :INFLUENCES]
    top = np.take_along_axis(weights, order, axis=1)
    dropped = float(np.sort(weights, axis=1)[:, :-INFLUENCES].max()) if weights.shape[1] > INFLUENCES else 0.0
    top = np.where(top > 0, top, 0.0)
    top = top / np.maximum(top.sum(axis=1, keepdims=True), 1e-12)
    joints = np.where(top > 0, order, 0)
    return joints, top.astype(np.float32), dropped


def inverse_bind_matrices(rest_joints: np.ndarray) -> np.ndarray:
    """(J, 16) float32 glTF inverse bind matrices (column-major) of joints at rest positions (J, 3): ``T(-J_j)``
    (every joint's rest frame has the model's axes)."""
    n_joints = len(rest_joints)
    matrices = np.tile(np.eye(4), (n_joints, 1, 1))
    matrices[:, :3, 3] = -np.asarray(rest_joints, dtype=np.float64)
    return np.ascontiguousarray(matrices.transpose(0, 2, 1)).reshape(n_joints, 16).astype(np.float32)


@dataclass
class _TrackChannels:
    """Where one track's keyframe values go: BIN offsets of its root translation, rotation, scale runs and
    of each joint's rotation run (joint 0's is the root rotation)."""

    translation: int
    scale: int
    rotation: np.ndarray  # (J,) BIN offsets
    count: int  # keyframes: the frames the track is in


class _ChannelChunks:
    """A few frames of keyframe values per track, written as contiguous runs when a track's chunk fills."""

    def __init__(self, writer: GlbWriter, channels: list[_TrackChannels], n_joints: int) -> None:
        n_tracks = len(channels)
        self.size = int(np.clip(_CHUNK_BYTES // max(n_tracks * (n_joints * 16 + 24), 1), 4, 512))
        self.writer, self.channels = writer, channels
        self.rotation = np.zeros((n_tracks, self.size, n_joints, 4), np.float32)
        self.translation = np.zeros((n_tracks, self.size, 3), np.float32)
        self.scale = np.zeros((n_tracks, self.size, 3), np.float32)
        self.fill = np.zeros(n_tracks, np.int64)
        self.written = np.zeros(n_tracks, np.int64)

    def add(self, slots: np.ndarray, quat: np.ndarray, pelvis_world: np.ndarray, scale: np.ndarray) -> None:
        """One frame's people: track slots (P,), quaternions (P, J, 4), pelvis (P, 3), scale (P,). InputError
        when a track has more frames than the first pass found (the sequence changed meanwhile)."""
        if any(self.written[slot] + self.fill[slot] >= self.channels[slot].count for slot in slots):
            raise InputError("the sequence changed while it was being exported (its people per frame); export again")
        at = self.fill[slots]
        self.rotation[slots, at] = quat
        self.translation[slots, at] = pelvis_world
        self.scale[slots, at] = scale[:, None]
        self.fill[slots] += 1
        for slot in slots[self.fill[slots] == self.size]:
            self.flush(int(slot))

    def flush(self, slot: int) -> None:
        """Write a track's gathered frames after those already written."""
        k, start = int(self.fill[slot]), int(self.written[slot])
        if not k:
            return
        where = self.channels[slot]
        self.writer.write_at(where.translation + 12 * start, self.translation[slot, :k])
        self.writer.write_at(where.scale + 12 * start, self.scale[slot, :k])
        for joint, offset in enumerate(where.rotation):
            self.writer.write_at(int(offset) + 16 * start, self.rotation[slot, :k, joint])
        self.written[slot] += k
        self.fill[slot] = 0

    def flush_all(self) -> None:
        for slot in range(len(self.channels)):
            self.flush(slot)


@dataclass
class SkinnedPlan:
    """The laid-out scene of skinned bodies: the document, its stage, each track's keyframe offsets."""

    builder: GltfBuilder
    stage: Stage
    scan: SequenceScan
    model: BodyModel
    slots: dict[int, int]  # track -> slot (its index in ``channels``)
    channels: list[_TrackChannels]
    stored_world: bool  # the frames' world parameters are in this camera's world
    weight_dropped: float  # the largest skinning weight left out (more than 4 joints on a vertex)

    def write(self, writer: GlbWriter, seq: Sequence, camera: Camera, frames: Iterable[Frame],
              progress: Callable[[], None] | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Second pass: each frame's parameters (``frames``: ``seq``'s, in order) to keyframes. Returns the
        pelvises' (lo, hi) box (world, (3,) each; None without people)."""
        chunks = _ChannelChunks(writer, self.channels, self.model.n_joints)
        last = np.zeros((len(self.channels), self.model.n_joints, 4))  # each track's previous quaternions
        lo = hi = None
        for frame in frames:
            if frame.n_people:
                slots = self._slots(frame)
                body = body_frame(frame, camera, self.model.n_joints, self.stored_world)
                quat = continuous_quaternions(quaternions_xyzw(body.local_rot), last[slots])
                last[slots] = quat
                chunks.add(slots, quat, body.pelvis_world, body.scale)
                lo = body.pelvis_world.min(axis=0) if lo is None else np.minimum(lo, body.pelvis_world.min(axis=0))
                hi = body.pelvis_world.max(axis=0) if hi is None else np.maximum(hi, body.pelvis_world.max(axis=0))
            if progress is not None:
                progress()
        chunks.flush_all()
        if any(int(chunks.written[slot]) != where.count for slot, where in enumerate(self.channels)):
            raise InputError("the sequence changed while it was being exported (its people per frame); export again")
        return lo, hi

    def _slots(self, frame: Frame) -> np.ndarray:
        """(P,) track slots of a frame's people; InputError for a person the first pass did not see."""
        try:
            return np.array([self.slots[int(track)] for track in frame.person_ids], dtype=np.int64)
        except KeyError:
            raise InputError(f"{frame.source}: changed while it was being exported (new people); export again") from None


def _visibility_keys(frames: list[int], n_frames: int, times: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """STEP scale keyframes hiding a track outside its frames: (times (K,), values (K, 3)), or None when it
    is in every frame. A key wherever it appears (1) or leaves (0), and one at 0 s when it starts hidden."""
    present = np.zeros(n_frames, dtype=bool)
    present[frames] = True
    if present.all():
        return None
    keys = np.concatenate([[0], np.flatnonzero(present[1:] != present[:-1]) + 1])
    return times[keys], np.repeat(present[keys].astype(np.float32)[:, None], 3, axis=1)


def plan_skinned(scan: SequenceScan, model: BodyModel, camera: Camera, palette: tuple[RGB, ...], fps: float,
                 stored_world: bool) -> SkinnedPlan:
    """Lay out the scene of skinned bodies (:mod:`.skinned`) from the first pass's findings (betas by track)."""
    builder = GltfBuilder()
    layout = builder.layout
    n_frames, n_joints = len(scan.names), model.n_joints
    names = joint_names(model)
    tracks = scan.tracks
    materials = builder.person_materials(tracks, palette)
    times = frame_times_s(n_frames, fps)
    all_times = builder.static_accessor(times, FLOAT, "SCALAR", name="frame_times", bounds=True)
    joints, weights, dropped = skin_weights(model.weights)
    joints_acc = builder.static_accessor(joints.astype(np.uint8 if n_joints <= 256 else np.uint16),
                                         UNSIGNED_BYTE if n_joints <= 256 else UNSIGNED_SHORT, "VEC4", ARRAY_BUFFER, "joints")
    weights_acc = builder.static_accessor(weights, FLOAT, "VEC4", ARRAY_BUFFER, "weights")
    faces = model.faces
    if faces is not None and len(faces):
        component, dtype = index_component(model.n_verts)
        indices = builder.static_accessor(faces.astype(dtype).reshape(-1), component, "SCALAR", ELEMENT_ARRAY_BUFFER,
                                          "faces")
    else:
        indices = None
    track_frames = scan.track_frames()
    slots, channels = {}, []
    for track in tracks:
        frames = track_frames[track]
        n_keys = len(frames)
        rest_verts, rest_joints = rest_shape(model, scan.mean_betas(track))
        person = builder.node({"name": f"person_{track}", "children": []}, root=True)
        joint_nodes = []
        for j in range(n_joints):
            parent = int(model.parents[j])
            offset = rest_joints[j] - (rest_joints[parent] if parent >= 0 else 0.0)
            joint_nodes.append(builder.node({"name": f"person_{track}/{names[j]}", "translation": offset.tolist()}))
            host = builder.nodes[person] if parent < 0 else builder.nodes[joint_nodes[parent]]
            host.setdefault("children", []).append(joint_nodes[-1])
        positions = builder.static_accessor(rest_verts.astype(np.float32), FLOAT, "VEC3", ARRAY_BUFFER,
                                            f"person_{track}/rest", bounds=True)
        ibm = builder.static_accessor(inverse_bind_matrices(rest_joints), FLOAT, "MAT4", name=f"person_{track}/ibm")
        builder.skins.append({"name": f"person_{track}", "joints": joint_nodes, "inverseBindMatrices": ibm,
                              "skeleton": joint_nodes[0]})
        mesh = builder.mesh(f"person_{track}", {"POSITION": positions, "JOINTS_0": joints_acc, "WEIGHTS_0": weights_acc},
                            materials[track], TRIANGLES if indices is not None else POINTS, indices)
        builder.node({"name": f"person_{track}/mesh", "mesh": mesh, "skin": len(builder.skins) - 1}, root=True)
        # keyframes: root translation, scale, then every joint's rotation (joint 0 = the root's), each contiguous
        view = layout.view(n_keys * (12 + 12 + 16 * n_joints), None, f"person_{track}/keyframes")
        base = layout.view_offset(view)
        if n_keys == n_frames:
            key_times = all_times
        else:
            track_times = times[frames]
            key_times = builder.static_accessor(track_times, FLOAT, "SCALAR", name=f"person_{track}/times", bounds=True)
        translation = layout.accessor(view, 0, FLOAT, n_keys, "VEC3")
        scale = layout.accessor(view, 12 * n_keys, FLOAT, n_keys, "VEC3")
        builder.animate(joint_nodes[0], "translation", key_times, translation, "LINEAR")
        builder.animate(joint_nodes[0], "scale", key_times, scale, "LINEAR")
        rotation_offsets = 24 * n_keys + 16 * n_keys * np.arange(n_joints)
        for j in range(n_joints):
            rotation = layout.accessor(view, int(rotation_offsets[j]), FLOAT, n_keys, "VEC4")
            builder.animate(joint_nodes[j], "rotation", key_times, rotation, "LINEAR")
        channels.append(_TrackChannels(base, base + 12 * n_keys, base + rotation_offsets, n_keys))
        slots[track] = len(channels) - 1
        visibility = _visibility_keys(frames, n_frames, times)
        if visibility is not None:
            key_t, key_v = visibility
            builder.nodes[person]["scale"] = key_v[0].tolist()  # a still viewer shows the first frame
            vis_times = builder.static_accessor(key_t, FLOAT, "SCALAR", name=f"person_{track}/shown_times", bounds=True)
            vis_values = builder.static_accessor(key_v, FLOAT, "VEC3", name=f"person_{track}/shown")
            builder.animate(person, "scale", vis_times, vis_values, "STEP")
    stage = add_stage(builder, camera)
    return SkinnedPlan(builder, stage, scan, model, slots, channels, stored_world, dropped)
