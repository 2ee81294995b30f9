"""The Rerun calls of ``rotavat view``: one method per kind of thing a recording holds, the viewer's layout,
and the one import of Rerun (the optional extra ``rotavat[view]``: :func:`require_rerun`).

Positions come in world metres (float32) from :mod:`.recording`; what is drawn where is the entity tree
of docs/render.md ("rotavat view"). Colours are RGB in [0, 1] (:mod:`rotavat_cli.render.style`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..geometry.camera import Camera
from ..errors import InputError
from ..render.skeleton import BONE_RADIUS_M, JOINT_RADIUS_M, POINT_RADIUS_M, layout_bones
from ..render.style import RGB, RenderStyle, rgb8
from ..render.tracks import TRACK_SERIES
from ..render.views import RowFrame
from .scene import grid_lines_world, grid_step_m, grid_ticks_world

__all__ = ["RERUN_INSTALL", "WORLD", "SERIES", "W_MPJPE_SERIES", "FLAG_RGB", "require_rerun", "RecordingWriter",
           "blueprint"]

RERUN_INSTALL = "pip install 'rotavat[view]'"  # the extra that brings the Rerun SDK (and its viewer)
WORLD = "world"
W_MPJPE_SERIES = ("w_mpjpe_mm", "W-MPJPE", "mm")  # with a ground truth: per ground-truth person
SERIES = tuple((key, title, unit) for key, title, unit, *_ in TRACK_SERIES) + (W_MPJPE_SERIES,)
FLAG_RGB = (0.85, 0.1, 0.1)  # a flagged person's label
_LABEL_RADIUS_M = 0.03
_TRACK_RADIUS_M = 0.015
_ARROW_RADIUS_M = 0.02


def require_rerun() -> Any:
    """The ``rerun`` module; InputError (exit 2) saying how to install it when it is missing."""
    try:
        import rerun  # lazy: optional extra rotavat[view]
    except ImportError:
        raise InputError(f"rotavat view needs the Rerun SDK, which is not installed: {RERUN_INSTALL}") from None
    return rerun


class RecordingWriter:
    """The Rerun calls: one method per kind of thing logged. Holds the recording stream and the style."""

    def __init__(self, rr: Any, rec: Any, style: RenderStyle) -> None:
        self.rr, self.rec, self.style = rr, rec, style

    def set_frame(self, index: int, fps: float | None) -> None:
        """Every log call until the next one belongs to frame ``index`` (and second ``index / fps``)."""
        self.rec.set_time("frame", sequence=index)
        if fps:
            self.rec.set_time("time", duration=index / fps)

    def scene(self, camera: Camera, label: str, image_plane_m: float) -> None:
        """The world's axes and the camera: its pose (world from camera), its label, its pinhole. A camera's lens
        (``camera.distortion``) is not drawn: rerun's Pinhole has no lens model, so with one the video frame on the
        image plane is the distorted image (off the pinhole's rays by the lens's displacement, a few percent at
        the corners) while the people and the ground are where the camera, lens included, put them."""
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

    def image(self, contents: bytes, media_type: str, size_px: tuple[int, int], image_size: tuple[int, int]) -> None:
        """This frame's video frame on the camera's image plane: an encoded image (``image/png``, ``image/jpeg`` ...)
        of ``size_px`` (W, H), stretched to the camera's ``image_size`` (a frame scaled down, or stored at
        another size, fills the pinhole all the same)."""
        scale = [image_size[0] / size_px[0], image_size[1] / size_px[1], 1.0]
        self.rec.log(f"{WORLD}/camera/image/video", self.rr.Transform3D(scale=scale),
                     self.rr.EncodedImage(contents=contents, media_type=media_type))

    def person(self, base: str, row: RowFrame, points_world: np.ndarray, normals: np.ndarray | None, color: RGB,
               first: bool, faces: np.ndarray | None = None) -> None:
        """One person of a row: mesh (with its (V, 3) ``normals``, or None; on ``faces``, by default the row's own),
        point cloud or skeleton by the row's kind."""
        rr, rec, rgb = self.rr, self.rec, rgb8(color)
        kind = row.kind
        if kind == "mesh":
            if first:  # the faces and colour of a track do not change: logged once, for every frame
                triangles = np.asarray(row.faces if faces is None else faces, dtype=np.uint32)
                rec.log(f"{base}/mesh", rr.Mesh3D.from_fields(triangle_indices=triangles,
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

    def labels(self, path: str, anchors: np.ndarray, texts: list[str], colors: np.ndarray, flagged: np.ndarray) -> None:
        """A row's labels, one above each person: (P, 3) places, (P,) texts, (P, 3) RGB in [0, 1], (P,) flagged
        (drawn in red, twice the size)."""
        rgb = np.where(np.asarray(flagged, dtype=bool)[:, None], FLAG_RGB, np.asarray(colors, dtype=np.float64).reshape(-1, 3))
        self.rec.log(path, self.rr.Points3D(np.asarray(anchors, dtype=np.float32), labels=texts,
                                            colors=np.round(255 * rgb).astype(np.uint8),
                                            radii=np.where(flagged, 2 * _LABEL_RADIUS_M, _LABEL_RADIUS_M), show_labels=True))

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

    def arrow(self, path: str, origin: np.ndarray, vector: np.ndarray, color: RGB, label: str) -> None:
        """One labelled arrow (static): ``vector`` (3,) from ``origin`` (3,), world metres."""
        self.rec.log(path, self.rr.Arrows3D(origins=[np.asarray(origin, dtype=np.float32)],
                                            vectors=[np.asarray(vector, dtype=np.float32)], colors=[rgb8(color)],
                                            radii=_ARROW_RADIUS_M, labels=[label], show_labels=True), static=True)

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


def blueprint(rr: Any, with_gt: bool, eye: tuple[np.ndarray, np.ndarray]) -> Any:
    """The viewer's layout: the 3D scene seen from ``eye`` (position, target), one time-series panel per series,
    the timeline open and the other panels folded away."""
    rrb = rr.blueprint
    keys = [k for k, *_ in SERIES if with_gt or k != W_MPJPE_SERIES[0]]
    titles = {k: f"{title} ({unit})" for k, title, unit in SERIES}
    plots = [rrb.TimeSeriesView(origin=f"plots/{k}", name=titles[k], plot_legend=rrb.PlotLegend(visible=False))
             for k in keys]  # a crowd's legend would cover its plot; hovering a line names it
    scene = rrb.Spatial3DView(origin=WORLD, name="scene (world metres, Y up)", line_grid=False,
                              eye_controls=rrb.EyeControls3D(position=eye[0], look_target=eye[1]))
    return rrb.Blueprint(rrb.Horizontal(scene, rrb.Vertical(*plots), column_shares=[3, 1]),
                         rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
                         rrb.TimePanel(state="expanded"))
