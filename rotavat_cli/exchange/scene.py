"""The glTF document of an animated scene: what both kinds of people (per-frame meshes, skinned bodies) share.

:class:`GltfBuilder` collects nodes, meshes, materials, the one animation and the BIN layout
(:class:`.glb.BinLayout`); :func:`add_stage` adds the scene's fixed parts: the calibrated camera as a
glTF camera node (``world_from_gl_camera``, ``gltf_camera`` of :mod:`rotavat_cli.render.export`: the
same camera as the one-frame export), the ground quad on ``Y = 0`` and the camera frustum as lines.
The ground and frustum are sized from where the people went, so their points are written last
(:func:`write_stage`).

Keyframe times are ``frame index / fps`` seconds (:func:`frame_times_s`).

>>> frame_times_s(3, 5.0).tolist()
[0.0, 0.20000000298023224, 0.4000000059604645]
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..geometry.camera import Camera
from ..render.export import frustum_segments_world, gltf_camera, ground_quad_world, world_from_gl_camera
from ..render.style import RGB, person_colors
from ..version import WRITTEN_BY
from .glb import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, PLACEHOLDER_BOUND, UNSIGNED_SHORT, BinLayout, GlbWriter, bounds_json

__all__ = ["GltfBuilder", "Stage", "add_stage", "write_stage", "frame_times_s", "PLACEHOLDER_BOUNDS3",
           "TRIANGLES", "POINTS", "LINES"]

TRIANGLES, POINTS, LINES = 4, 0, 1  # mesh.primitive.mode
PLACEHOLDER_BOUNDS3 = ([PLACEHOLDER_BOUND] * 3, [PLACEHOLDER_BOUND] * 3)  # widest min/max: the JSON's length is fixed
GROUND_RGBA = (150, 150, 140, 255)  # as the one-frame export (render/export.py)
FRUSTUM_RGBA = (190, 56, 43, 255)
_FRUSTUM_POINTS = 16  # 8 segments


def frame_times_s(n_frames: int, fps: float) -> np.ndarray:
    """(T,) float32 keyframe times in seconds: frame ``i`` at ``i / fps``."""
    return (np.arange(n_frames, dtype=np.float64) / fps).astype(np.float32)


def _material(rgba: tuple[int, int, int, int], name: str) -> dict:
    """A double-sided PBR material of one colour (0-255 values, as the one-frame export's)."""
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": [c / 255.0 for c in rgba], "metallicFactor": 0.0,
                                     "roughnessFactor": 0.8}}


def _column_major(matrix: np.ndarray) -> list[float]:
    """A (4, 4) matrix as glTF's node.matrix: 16 numbers, column by column."""
    return np.asarray(matrix, dtype=np.float64).T.reshape(-1).tolist()


@dataclass
class GltfBuilder:
    """A glTF document being laid out: lists of its objects (indices are positions in them) and its BIN."""

    layout: BinLayout = field(default_factory=BinLayout)
    nodes: list[dict] = field(default_factory=list)
    roots: list[int] = field(default_factory=list)  # the scene's root nodes
    meshes: list[dict] = field(default_factory=list)
    materials: list[dict] = field(default_factory=list)
    skins: list[dict] = field(default_factory=list)
    cameras: list[dict] = field(default_factory=list)
    samplers: list[dict] = field(default_factory=list)
    channels: list[dict] = field(default_factory=list)
    extras: dict[str, Any] = field(default_factory=dict)

    def node(self, entry: dict, root: bool = False) -> int:
        """Add a node (a root of the scene when ``root``); its index."""
        self.nodes.append(entry)
        if root:
            self.roots.append(len(self.nodes) - 1)
        return len(self.nodes) - 1

    def mesh(self, name: str, attributes: dict[str, int], material: int, mode: int, indices: int | None = None) -> int:
        """Add a one-primitive mesh; its index."""
        primitive: dict[str, Any] = {"attributes": attributes, "material": material, "mode": mode}
        if indices is not None:
            primitive["indices"] = indices
        self.meshes.append({"name": name, "primitives": [primitive]})
        return len(self.meshes) - 1

    def material(self, rgba: tuple[int, int, int, int], name: str) -> int:
        """Add a material; its index."""
        self.materials.append(_material(rgba, name))
        return len(self.materials) - 1

    def person_materials(self, tracks: list[int], palette: tuple[RGB, ...]) -> dict[int, int]:
        """One material per track, coloured by ``palette[id mod len]`` (render's rule); track -> material."""
        colors = np.round(255 * person_colors(np.asarray(tracks, dtype=np.int64), palette)).astype(int)
        return {track: self.material((*map(int, rgb), 255), f"person_{track}") for track, rgb in zip(tracks, colors)}

    def animate(self, node: int, path: str, times: int, values: int, interpolation: str) -> None:
        """Animate ``node``'s ``path`` (translation, rotation, scale) by the keyframes of two accessors."""
        self.samplers.append({"input": times, "output": values, "interpolation": interpolation})
        self.channels.append({"sampler": len(self.samplers) - 1, "target": {"node": node, "path": path}})

    def static_accessor(self, data: np.ndarray, component: int, kind: str, target: int | None = None,
                        name: str | None = None, bounds: bool = False) -> int:
        """An accessor over a new buffer view holding ``data`` (written with the BIN's static data); its index.
        ``bounds``: give it ``min``/``max`` (POSITION, animation inputs)."""
        data = np.ascontiguousarray(data)
        view = self.layout.static_array(data, data.nbytes, target, name)
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[kind]
        flat = data.reshape(-1, width)
        return self.layout.accessor(view, 0, component, len(flat), kind, bounds_json(flat) if bounds else None, name)

    def gltf(self) -> dict:
        """The glTF document as it stands (accessor bounds as last set)."""
        doc: dict[str, Any] = {"asset": {"version": "2.0", "generator": WRITTEN_BY}, "scene": 0,
                               "scenes": [{"name": "rotavat", "nodes": self.roots}], "nodes": self.nodes}
        for key, value in (("meshes", self.meshes), ("materials", self.materials), ("skins", self.skins),
                           ("cameras", self.cameras), ("accessors", self.layout.accessors),
                           ("bufferViews", self.layout.views)):
            if value:
                doc[key] = value
        if self.channels:
            doc["animations"] = [{"name": "sequence", "channels": self.channels, "samplers": self.samplers}]
        doc["buffers"] = [{"byteLength": self.layout.size}]
        if self.extras:
            doc["extras"] = self.extras
        return doc


@dataclass(frozen=True)
class Stage:
    """Where :func:`add_stage` put the ground's and frustum's points (written last, by :func:`write_stage`)."""

    ground_accessor: int
    ground_offset: int  # BIN byte offset of the ground's 4 points
    frustum_accessor: int
    frustum_offset: int


def add_stage(builder: GltfBuilder, camera: Camera) -> Stage:
    """Add the camera node, the ground quad and the frustum (their points reserved, written by :func:`write_stage`)."""
    layout = builder.layout
    builder.cameras.append(gltf_camera(camera))
    builder.node({"name": "camera", "camera": len(builder.cameras) - 1,
                  "matrix": _column_major(world_from_gl_camera(camera))}, root=True)
    ground_view = layout.view(4 * 12, ARRAY_BUFFER, "ground")
    ground = layout.accessor(ground_view, 0, FLOAT, 4, "VEC3", PLACEHOLDER_BOUNDS3, "ground")
    quad = builder.static_accessor(np.array([0, 2, 1, 0, 3, 2], np.uint16), UNSIGNED_SHORT, "SCALAR",
                                   ELEMENT_ARRAY_BUFFER, "ground_indices")
    mesh = builder.mesh("ground", {"POSITION": ground}, builder.material(GROUND_RGBA, "ground"), TRIANGLES, quad)
    builder.node({"name": "ground", "mesh": mesh}, root=True)
    frustum_view = layout.view(_FRUSTUM_POINTS * 12, ARRAY_BUFFER, "camera_frustum")
    frustum = layout.accessor(frustum_view, 0, FLOAT, _FRUSTUM_POINTS, "VEC3", PLACEHOLDER_BOUNDS3, "camera_frustum")
    mesh = builder.mesh("camera_frustum", {"POSITION": frustum}, builder.material(FRUSTUM_RGBA, "camera_frustum"), LINES)
    builder.node({"name": "camera_frustum", "mesh": mesh}, root=True)
    return Stage(ground, layout.view_offset(ground_view), frustum, layout.view_offset(frustum_view))


def write_stage(writer: GlbWriter, builder: GltfBuilder, stage: Stage, camera: Camera,
                people_lo_world: np.ndarray | None, people_hi_world: np.ndarray | None) -> None:
    """Write the ground quad around the people's box (lo, hi: (3,) world, None without people) and the
    camera, and the frustum (a quarter of the farthest person's distance, 1-10 m, as the one-frame export)."""
    center = camera.center_world
    if people_lo_world is None or people_hi_world is None:
        corners = np.zeros((0, 3))
    else:
        lo, hi = np.asarray(people_lo_world, np.float64), np.asarray(people_hi_world, np.float64)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    quad, _ = ground_quad_world(np.concatenate([center[None] * [1.0, 0.0, 1.0], corners]))
    depth_m = float(np.clip(0.25 * np.linalg.norm(corners - center, axis=1).max(), 1.0, 10.0)) if len(corners) else 2.0
    segments = frustum_segments_world(camera, depth_m).reshape(-1, 3)
    for accessor, offset, points in ((stage.ground_accessor, stage.ground_offset, quad),
                                     (stage.frustum_accessor, stage.frustum_offset, segments)):
        points32 = np.asarray(points, dtype=np.float32)
        writer.write_at(offset, points32)
        entry = builder.layout.accessors[accessor]
        entry["min"], entry["max"] = bounds_json(points32)
