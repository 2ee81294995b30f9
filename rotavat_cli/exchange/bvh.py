"""BVH (Biovision Hierarchy) motion files: written from a body model's skeleton, read back.

A BVH file is a ``HIERARCHY`` of joints, each with an ``OFFSET`` from its parent (in its parent's rest
axes) and its ``CHANNELS``, then ``MOTION``: ``Frames:``, ``Frame Time:`` (seconds) and one line of channel
values per frame. The root has 6 channels (``Xposition Yposition Zposition`` and 3 rotations), every
other joint 3 rotations, in degrees; a leaf ends in an ``End Site`` (only its offset: a bone's tip).

Rotation channels listed ``Zrotation Xrotation Yrotation`` mean ``R = R_Z(z) R_X(x) R_Y(y)`` (intrinsic: the
first listed is the outermost), as Blender's and MotionBuilder's readers compose them; scipy's
``as_euler("ZXY")`` (upper case: intrinsic) gives the angles in that order. A joint's world transform is
``G = G_parent T(offset) R`` (the root: ``T(position) R``).

rotavat writes the world of docs/conventions.md (Y up, metres: Blender imports it at scale 1); SMPL's
rest pose has every joint's axes along the model's, so a joint's rotation is its body-pose rotation and
the root's is the world root orientation.

>>> data = read_bvh(bvh_text(("root", "tip"), np.array([-1, 0]), np.array([[0, 0, 0], [0, 1.0, 0]]),
...                          np.zeros((1, 3)), np.tile(np.eye(3), (1, 2, 1, 1)), 0.1))
>>> data.names, data.frame_time, bvh_joint_positions(data)[0].tolist()
(('root', 'tip'), 0.1, [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["BvhData", "bvh_text", "read_bvh", "bvh_joint_positions", "depth_first", "END_SITE_FRACTION"]

END_SITE_FRACTION = 0.5  # a leaf's End Site: this fraction of its own bone, continued (a visible tip, not zero length)
_AXIS = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}


def depth_first(parents: np.ndarray) -> list[int]:
    """Joint indices in depth-first order from the root (children by increasing index): BVH's file order."""
    children: dict[int, list[int]] = {}
    for joint, parent in enumerate(np.asarray(parents).tolist()):
        children.setdefault(int(parent), []).append(joint)
    order, stack = [], list(reversed(children.get(-1, [])))
    while stack:
        joint = stack.pop()
        order.append(joint)
        stack.extend(reversed(children.get(joint, [])))
    return order


def _euler_deg(rot: np.ndarray, order: str) -> np.ndarray:
    """(N, J, 3, 3) rotations -> (N, J, 3) intrinsic Euler angles in ``order``, degrees, unwrapped over frames
    (no 360 degree jumps from one frame to the next)."""
    n, j = rot.shape[:2]
    angles = Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_euler(order, degrees=False).reshape(n, j, 3)
    return np.rad2deg(np.unwrap(angles, axis=0)) if n > 1 else np.rad2deg(angles)


def bvh_text(names: tuple[str, ...], parents: np.ndarray, offsets: np.ndarray, root_position: np.ndarray,
             local_rot: np.ndarray, frame_time_s: float, order: str = "ZXY", precision: int = 6) -> str:
    """A BVH file's text.

    names: (J,) joint names; parents: (J,) parent indices (-1: the root, joint 0); offsets: (J, 3) each
    joint's rest offset from its parent (the root's is written, usually 0); root_position: (N, 3) the root's
    position per frame; local_rot: (N, J, 3, 3) each joint's rotation relative to its parent (the root's:
    world from model); frame_time_s: seconds per frame; order: the rotation channels, outermost first.
    """
    parents = np.asarray(parents)
    offsets = np.asarray(offsets, dtype=np.float64)
    channels = " ".join(f"{axis}rotation" for axis in order)
    children: dict[int, list[int]] = {}
    for joint, parent in enumerate(parents.tolist()):
        children.setdefault(int(parent), []).append(joint)
    lines = ["HIERARCHY"]
    fmt = f"{{:.{precision}f}}"

    def vec(v: np.ndarray) -> str:
        return " ".join(fmt.format(float(x)) for x in v)

    def emit(joint: int, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parents[joint] < 0 else 'JOINT'} {names[joint]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {vec(offsets[joint])}")
        lines.append(f"{pad}  CHANNELS {'6 Xposition Yposition Zposition ' if parents[joint] < 0 else '3 '}{channels}")
        kids = children.get(joint, [])
        for child in kids:
            emit(child, depth + 1)
        if not kids:
            lines.append(f"{pad}  End Site")
            lines.append(f"{pad}  {{")
            lines.append(f"{pad}    OFFSET {vec(END_SITE_FRACTION * offsets[joint])}")
            lines.append(f"{pad}  }}")
        lines.append(f"{pad}}}")

    emit(int(np.flatnonzero(parents < 0)[0]), 0)
    order_joints = depth_first(parents)
    angles = _euler_deg(np.asarray(local_rot, dtype=np.float64), order)[:, order_joints]  # (N, J, 3)
    motion = np.concatenate([np.asarray(root_position, dtype=np.float64), angles.reshape(len(angles), -1)], axis=1)
    body = io.StringIO()
    np.savetxt(body, motion, fmt=f"%.{precision}f", delimiter=" ")
    lines += ["MOTION", f"Frames: {len(motion)}", f"Frame Time: {frame_time_s:.8g}"]
    return "\n".join(lines) + "\n" + body.getvalue()


@dataclass(frozen=True)
class BvhData:
    """A BVH file read back: joints in file order (End Sites left out), their parents (-1: root), offsets
    (J, 3), channel names per joint, seconds per frame and the motion (N, C) in file order."""

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    frame_time: float
    motion: np.ndarray


def read_bvh(text: str) -> BvhData:
    """Parse a BVH file's text (one root). Raises ValueError on a malformed file."""
    tokens = text.split()
    names, parents, offsets, channels = [], [], [], []
    stack: list[int] = []
    i, in_end_site, pending = 0, False, -1
    try:
        if tokens[0] != "HIERARCHY":
            raise ValueError("a BVH file starts with HIERARCHY")
        i = 1
        while tokens[i] != "MOTION":
            token = tokens[i]
            if token in ("ROOT", "JOINT"):
                names.append(tokens[i + 1])
                parents.append(stack[-1] if stack else -1)
                pending = len(names) - 1
                i += 2
            elif token == "End":
                in_end_site = True
                i += 2
            elif token == "{":
                stack.append(pending if not in_end_site else -2)
                i += 1
            elif token == "}":
                if stack.pop() == -2:
                    in_end_site = False
                i += 1
            elif token == "OFFSET":
                if not in_end_site:
                    offsets.append([float(v) for v in tokens[i + 1:i + 4]])
                i += 4
            elif token == "CHANNELS":
                n = int(tokens[i + 1])
                channels.append(tuple(tokens[i + 2:i + 2 + n]))
                i += 2 + n
            else:
                raise ValueError(f"unexpected {token!r} in HIERARCHY")
        if tokens[i + 1] != "Frames:" or tokens[i + 3:i + 5] != ["Frame", "Time:"]:
            raise ValueError("MOTION must give 'Frames:' and 'Frame Time:'")
        n_frames, frame_time = int(tokens[i + 2]), float(tokens[i + 5])
        values = np.array(tokens[i + 6:], dtype=np.float64)
    except IndexError:
        raise ValueError("truncated BVH file") from None
    n_channels = sum(len(c) for c in channels)
    if len(channels) != len(names) or values.size != n_frames * n_channels:
        raise ValueError(f"{values.size} motion values for {n_frames} frames of {n_channels} channels")
    return BvhData(tuple(names), tuple(parents), np.array(offsets, dtype=np.float64).reshape(-1, 3),
                   tuple(channels), frame_time, values.reshape(n_frames, n_channels))


def bvh_joint_positions(data: BvhData) -> np.ndarray:
    """(N, J, 3) every joint's position per frame (forward kinematics of the channels as written)."""
    n_frames = len(data.motion)
    world_rot = np.zeros((n_frames, len(data.names), 3, 3))
    world_pos = np.zeros((n_frames, len(data.names), 3))
    column = 0
    for joint, (parent, chans) in enumerate(zip(data.parents, data.channels)):
        values = data.motion[:, column:column + len(chans)]
        column += len(chans)
        position = np.tile(data.offsets[joint], (n_frames, 1))
        for axis, name in enumerate(("Xposition", "Yposition", "Zposition")):
            if name in chans:
                position[:, axis] += values[:, chans.index(name)]
        rot_names = [c for c in chans if c in _AXIS]
        local = (Rotation.from_euler("".join(_AXIS[c] for c in rot_names),
                                     values[:, [chans.index(c) for c in rot_names]], degrees=True).as_matrix()
                 if rot_names else np.tile(np.eye(3), (n_frames, 1, 1)))
        if parent < 0:
            world_rot[:, joint], world_pos[:, joint] = local, position
        else:
            world_rot[:, joint] = world_rot[:, parent] @ local
            world_pos[:, joint] = world_pos[:, parent] + np.einsum("nab,nb->na", world_rot[:, parent], position)
    return world_pos
