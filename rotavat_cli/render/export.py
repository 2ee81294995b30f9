"""A frame as a glTF 2.0 binary scene (``.glb``): people, a ground quad, the camera frustum and a glTF camera.

What ``rotavat export`` runs (:func:`export_frame`) and ``rotavat render --glb`` writes per frame.

World frame = the contract's world (docs/conventions.md) (origin on the ground below the camera, ``Y`` up, right-handed),
which is glTF's own convention (``+Y`` up, metres), so vertices go in untouched. The glTF camera
looks along its local ``-Z`` with ``+Y`` up, while the OpenCV camera looks along ``+z`` with
``y`` down: the camera node's transform is ``world_from_cv @ R_CV_FROM_GL``.

trimesh (checked on 4.x/5.x: ``exchange/gltf.py::_convert_camera``) writes ``aspectRatio`` as
``fov_x / fov_y``, a ratio of angles, not ``W / H``; the exporter's tree post-processor here
rewrites the camera with ``aspectRatio = W / H`` and ``yfov`` = the vertical field of view.

Examples
--------
>>> (R_CV_FROM_GL @ np.array([0.0, 0.0, -1.0])).tolist()  # glTF forward is OpenCV forward
[0.0, 0.0, 1.0]
"""

from __future__ import annotations

import json
import struct
from collections.abc import Sequence as SequenceABC
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from trimesh.exchange.gltf import export_glb
from trimesh.visual.material import PBRMaterial

from ..version import WRITTEN_BY
from ..files.atomic import atomic_open
from ..geometry.camera import Camera
from ..sequence import Sequence
from .rows import frame_names, no_camera, read_row, row_labels, sequence_camera
from .grid import row_shapes
from .style import RGB, RenderStyle, person_colors
from .views import RowFrame

__all__ = [
    "export_frame",
    "R_CV_FROM_GL",
    "world_from_gl_camera",
    "frustum_segments_world",
    "ground_quad_world",
    "build_scene",
    "glb_bytes",
    "write_glb",
    "read_glb_json",
    "gltf_camera",
]

# glTF/OpenGL camera axes (x right, y up, looking along -z) -> OpenCV camera axes (x right, y down, z forward).
R_CV_FROM_GL = np.diag([1.0, -1.0, -1.0])
_GROUND_RGBA = (150, 150, 140, 255)
_FRUSTUM_RGBA = (190, 56, 43, 255)
_GROUND_MARGIN_M = 2.0  # ground quad reaches this far beyond the people and the camera
_Z_NEAR_M = 0.05


def world_from_gl_camera(camera: Camera) -> np.ndarray:
    """(4, 4) pose of the glTF camera node in the world (columns: its x, y, z axes and the centre)."""
    M = np.eye(4)
    M[:3, :3] = camera.R_cam_from_world.T @ R_CV_FROM_GL
    M[:3, 3] = camera.center_world
    return M


def frustum_segments_world(camera: Camera, depth_m: float) -> np.ndarray:
    """(8, 2, 3) line segments of the image pyramid to ``depth_m``: 4 edges from the centre, 4 around the far rectangle."""
    W, H = camera.image_size
    corners_px = np.array([[0.0, 0.0], [W, 0.0], [W, H], [0.0, H]])
    rays = np.concatenate([(corners_px - camera.principal_point) / camera.focal_px, np.ones((4, 1))], axis=1)
    far_world = camera.world_from_cam(rays * depth_m)
    center = np.broadcast_to(camera.center_world, (4, 3))
    return np.concatenate([np.stack([center, far_world], axis=1), np.stack([far_world, np.roll(far_world, -1, axis=0)], axis=1)])


def ground_quad_world(points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rectangle on Y = 0 around (N, 3) points plus a margin -> vertices (4, 3), faces (2, 3) facing up."""
    p = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    lo = p[:, [0, 2]].min(axis=0) - _GROUND_MARGIN_M if len(p) else np.array([-5.0, -10.0])
    hi = p[:, [0, 2]].max(axis=0) + _GROUND_MARGIN_M if len(p) else np.array([5.0, 0.0])
    verts = np.array([[lo[0], 0.0, lo[1]], [hi[0], 0.0, lo[1]], [hi[0], 0.0, hi[1]], [lo[0], 0.0, hi[1]]])
    return verts, np.array([[0, 2, 1], [0, 3, 2]])  # counter-clockwise seen from +Y: normal = +Y


def gltf_camera(camera: Camera, name: str = "camera") -> dict:
    """glTF perspective camera dict: aspectRatio = W / H, yfov = vertical field of view (rad)."""
    W, H = camera.image_size
    return {"name": name, "type": "perspective",
            "perspective": {"aspectRatio": W / H, "yfov": camera.vertical_fov_rad, "znear": _Z_NEAR_M}}


def _material(rgba: tuple[int, int, int, int]) -> Any:
    """A double-sided PBR material of one colour."""
    return PBRMaterial(baseColorFactor=list(rgba), metallicFactor=0.0, roughnessFactor=0.8, doubleSided=True)


def _people_world(row: RowFrame, cam: Camera, colors: np.ndarray) -> Any:
    """Per finite person of a row: (node name, world points (N, 3), faces (F, 3) or None for a point
    cloud, colour (3,) uint8). Meshes as they are; skeletons as tubes and balls (:mod:`.skeleton`)."""
    shapes = row_shapes(row) if row.kind == "skeleton" else None
    for p, (pid, rgb) in enumerate(zip(row.person_ids, colors)):
        node = f"{row.label}/person_{int(pid)}"
        if row.kind in ("mesh", "points"):
            verts_cam = np.asarray(row.verts_cam[p], dtype=np.float64)
            if not np.isfinite(verts_cam).all():
                continue
            faces = np.asarray(row.faces, dtype=np.int64) if row.kind == "mesh" else None
            yield node, cam.world_from_cam(verts_cam), faces, rgb
        elif shapes is not None:
            mine = np.flatnonzero(shapes.person == p)
            if not len(mine):
                continue
            remap = np.full(len(shapes.points), -1, np.int64)
            remap[mine] = np.arange(len(mine))
            faces = remap[shapes.faces[np.isin(shapes.faces[:, 0], mine)]]
            yield node, cam.world_from_cam(shapes.points[mine]), faces, rgb


def build_scene(rows: SequenceABC[RowFrame], camera: Camera, palette: tuple[RGB, ...],
                frustum_depth_m: float | None = None) -> Any:
    """trimesh.Scene of rows' people (world frame, coloured by id), ground quad, frustum and camera node.

    Each row's people go to the world through the row's own camera (``camera`` if it has none):
    meshes, point clouds (glTF points) or skeletons (tubes along the bones, balls at the joints);
    node names are ``<row label>/person_<id>``. ``camera`` gives the frustum and the glTF camera.
    """
    scene = trimesh.Scene()
    everything = [camera.center_world[None] * [1.0, 0.0, 1.0]]
    for row in rows:
        cam = row.camera or camera
        colors = np.round(255 * person_colors(row.person_ids, palette)).astype(np.uint8)
        for node, verts_world, faces, rgb in _people_world(row, cam, colors):
            everything.append(verts_world)
            if faces is None:  # a point cloud: glTF POINTS
                geometry = trimesh.PointCloud(verts_world, colors=np.tile(np.append(rgb, 255), (len(verts_world), 1)))
            else:
                geometry = trimesh.Trimesh(verts_world, faces, process=False)
                geometry.visual = trimesh.visual.TextureVisuals(material=_material((*map(int, rgb), 255)))
            scene.add_geometry(geometry, geom_name=node, node_name=node)
    pts = np.concatenate(everything)
    quad_v, quad_f = ground_quad_world(pts)
    ground = trimesh.Trimesh(quad_v, quad_f, process=False)
    ground.visual = trimesh.visual.TextureVisuals(material=_material(_GROUND_RGBA))
    scene.add_geometry(ground, geom_name="ground", node_name="ground")
    if frustum_depth_m is None:
        dist = np.linalg.norm(pts - camera.center_world, axis=1)
        frustum_depth_m = float(np.clip(0.25 * dist.max(), 1.0, 10.0)) if len(pts) > 1 else 2.0
    segments = frustum_segments_world(camera, frustum_depth_m)
    frustum = trimesh.load_path(segments)
    frustum.colors = np.tile(np.array(_FRUSTUM_RGBA, dtype=np.uint8), (len(frustum.entities), 1))
    scene.add_geometry(frustum, geom_name="camera_frustum", node_name="camera_frustum")
    W, H = camera.image_size
    scene.camera = trimesh.scene.Camera(name="camera", resolution=(W, H), focal=(camera.focal_px, camera.focal_px), z_near=_Z_NEAR_M)
    scene.camera_transform = world_from_gl_camera(camera)
    return scene


def glb_bytes(scene: Any, camera: Camera) -> bytes:
    """Export a scene to GLB with the camera rewritten by :func:`gltf_camera` (aspect ratio W / H)."""
    def fix_camera(tree: dict) -> None:
        if tree.get("cameras"):
            tree["cameras"][0] = gltf_camera(camera, tree["cameras"][0].get("name", "camera"))
        tree.setdefault("asset", {})["generator"] = f"{WRITTEN_BY} (trimesh)"  # says rotavat wrote it

    return export_glb(scene, tree_postprocessor=fix_camera)


def write_glb(path: str | Path, scene: Any, camera: Camera) -> Path:
    """Write a scene as ``.glb`` atomically."""
    path = Path(path)
    data = glb_bytes(scene, camera)
    with atomic_open(path, "wb") as handle:
        handle.write(data)
    return path


def read_glb_json(path: str | Path) -> dict:
    """The JSON chunk of a ``.glb`` file (header, then the first chunk, which must be JSON)."""
    data = Path(path).read_bytes()
    magic, version, _length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        raise ValueError(f"{path}: not a glTF 2.0 binary file")
    chunk_len, chunk_type = struct.unpack_from("<I4s", data, 12)
    if chunk_type != b"JSON":
        raise ValueError(f"{path}: first chunk is {chunk_type!r}, not JSON")
    return json.loads(data[20:20 + chunk_len].decode("utf-8"))


def export_frame(seq: Sequence, out: Path, frame: int = 0, camera_path: Path | None = None,
                 palette: tuple[RGB, ...] | None = None) -> dict:
    """Write frame ``frame`` (index; negative from the end) of a sequence as a ``.glb`` scene; returns a summary.

    camera_path: a camera.yaml (default the sequence's own camera); palette: person colours
    (default the packaged ``render.palette``).
    """
    camera = sequence_camera(seq, camera_path)
    if camera is None:
        raise no_camera(seq, "GLB's world frame")
    name = frame_names(seq, str(frame), None)[0]
    row = read_row(seq, name, row_labels([Path(seq.label)])[0], camera)
    write_glb(out, build_scene([row], camera, RenderStyle().palette if palette is None else palette), camera)
    return {"out": str(out), "sequence": seq.label, "frame": name, "people": int(len(row.person_ids)), "drawn_as": row.kind,
            "image_size": list(camera.image_size), "aspect_ratio": camera.image_size[0] / camera.image_size[1],
            "yfov_deg": float(np.rad2deg(camera.vertical_fov_rad))}
