"""The view registry: each figure column (front, side, top) is one :class:`View` entry in :data:`REGISTRY`.

An entry says everything about its view: its name (a ``render.views`` / ``--views`` value), its
column title, how it projects a row (the camera's own perspective, or an orthographic
:class:`Ortho` basis with what its window must hold), and what it draws under and over the
people. Adding a view = one entry here, its test and its row in docs/render.md's table.

- ``front``: the people through the intrinsics they were made with (the sequence's focal),
  optionally over the video frame, cropped to the people (``fit="people"``) or the whole image
  (``fit="camera"``). Everything looks right here by construction.
- ``side``: orthographic, looking along the ground and perpendicular to the camera's horizontal
  viewing direction; panel ``x`` = distance ahead of the camera, ``y`` = height, both ticked in
  metres. The ground is edge-on, so it is drawn as a line; the camera is drawn at its height with
  its viewing direction and the edges of its field of view (or, off the panel, a marker on the edge
  pointing to it), and its numbers.
- ``top``: orthographic bird's-eye view, panel up = the camera's horizontal viewing direction,
  with the camera, its ground field of view and a metric grid ticked in metres.

Windows (:meth:`View.window`) are fitted on the people of the rows given (every frame of a
figure, so a GIF does not jump), or also on the camera with ``fit="camera"``. The side and top
windows leave out the people align flagged (:attr:`RowFrame.flags`, from people.csv) unless nobody
framed with them is unflagged: they are drawn and marked, with an :func:`edge_marker` when off the panel.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from ..geometry.camera import Camera, camera_parameters
from .geometry import (UP_WORLD, FrontCrop, OrthoExtent, PanelView, clip_from_cam_perspective, clip_from_world_ortho,
                       fit_front_crop, fit_ortho_extent, horizontal_forward_world, nice_length_m, paste_boxes_px,
                       project_view_px, unit, world_from_cam_h)
from .style import RenderStyle, font, mix, rgb8

__all__ = ["RowFrame", "Ortho", "View", "REGISTRY", "VIEWS", "FITS", "view_specs", "parse_views", "ortho_basis_world",
           "ortho_bounds", "WindowBounds", "window_bounds", "extents_from_bounds", "scene_extents", "front_view", "ortho_view", "camera_numbers", "tick_marks", "side_fov_px",
           "edge_marker", "overlaps"]

FITS = ("people", "camera")  # what windows are fitted on: the people, or also the camera (whole image, camera in view)
_LIGHT_RAISE = 0.4  # the light sits this much above the eye (fraction of the viewing direction)
_NEAR_M, _MIN_FAR_M = 0.05, 10.0  # front view clip planes (far grows with the scene)
_SIDE_FLOOR_ROOM = 0.18  # side view: room under the lowest point (fraction of the panel), for the tick labels
_TICKS_PER_PANEL = 5  # about this many metric ticks across a panel's width


@dataclass(frozen=True)
class RowFrame:
    """What one grid row shows for one frame: people in the camera frame and how to view them.

    People are meshes (``verts_cam`` with ``faces``), point clouds (``verts_cam`` without faces) or
    skeletons (``joints_cam`` only, bones from ``joints_layout``): :attr:`kind`. ``ghost``: another
    row's people (the ground truth) drawn faintly over these, placed by *this* row's camera.
    """

    label: str
    verts_cam: np.ndarray  # (P, V, 3) float, camera frame, metres; V = 0 without vertices
    faces: np.ndarray  # (F, 3) int; F = 0: no triangles
    person_ids: np.ndarray  # (P,) int
    image_size: tuple[int, int]  # (W, H) px of the front view's image
    focal_px: float  # the focal the people were made with
    principal_point: tuple[float, float]
    camera: Camera | None = None  # needed by orthographic views
    image: np.ndarray | None = None  # (H, W, 3) uint8 video frame under the front view
    joints_cam: np.ndarray | None = None  # (P, J, 3) float, camera frame, metres
    joints_layout: str | None = None  # a joint_layouts layout name (bones), None: joints drawn as points
    ghost: "RowFrame | None" = None
    caption: str = ""  # numbers shown after the label (camera, metrics)
    flags: tuple[str, ...] | None = None  # (P,) people.csv's flag per person ("" = none: plausible); None: no flags
    lens: Camera | None = None  # the lens the people are seen through in the image (Sequence.image_lens): front view

    @property
    def plausible(self) -> np.ndarray:
        """(P,) bool: the people the side/top windows are fitted on: those whose flag is empty (every
        person of a row without flags). Flagged people are drawn, marked, but may fall outside the window."""
        if self.flags is None:
            return np.ones(len(self.person_ids), dtype=bool)
        return np.array([not flag for flag in self.flags], dtype=bool).reshape(len(self.person_ids))

    @property
    def flagged(self) -> dict[int, str]:
        """{person index: flag} of the flagged people (empty for a row without flags)."""
        return {} if self.flags is None else {i: flag for i, flag in enumerate(self.flags) if flag}

    @property
    def kind(self) -> str:
        """``mesh``, ``points`` (vertices without faces), ``skeleton`` (joints only) or ``none``."""
        verts = np.asarray(self.verts_cam)
        if verts.ndim == 3 and verts.shape[1] > 0:
            return "mesh" if np.asarray(self.faces).reshape(-1, 3).shape[0] else "points"
        if self.joints_cam is not None and np.asarray(self.joints_cam).ndim == 3 and np.asarray(self.joints_cam).shape[1]:
            return "skeleton"
        return "none"

    @property
    def points_cam(self) -> np.ndarray:
        """(P, N, 3) what each person is drawn from: vertices, else joints (camera frame)."""
        if self.kind in ("mesh", "points"):
            return np.asarray(self.verts_cam, dtype=np.float64)
        if self.kind == "skeleton":
            return np.asarray(self.joints_cam, dtype=np.float64)
        return np.zeros((len(self.person_ids), 0, 3))


def front_points_cam(points_cam: np.ndarray, row: RowFrame) -> np.ndarray:
    """Points (..., 3) camera frame -> the points the front view draws: where the row's pinhole (its focal and
    principal point) puts them at the pixel the row's lens shows them, the depth kept (so the z-buffer is the
    same). The points themselves without a lens.

    A pinhole drawing of a camera with a lens puts people toward the corners where the image does not; moving
    each vertex to its lens pixel draws the (dense) meshes through the lens, and the side and top views keep
    the true points.
    """
    if row.lens is None:
        return points_cam
    pts = np.asarray(points_cam, dtype=np.float64)
    pp = np.asarray(row.principal_point, dtype=np.float64)
    z = pts[..., 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        pinhole_px = pp + row.focal_px * pts[..., :2] / z
        image_px = row.lens.distort_px(pinhole_px)
        xy = (image_px - pp) * z / row.focal_px
    return np.concatenate([np.where(np.isfinite(xy), xy, pts[..., :2]), z], axis=-1)


Box = tuple[float, float, float, float]  # x0, y0, x1, y1 panel px
# (PIL image, panel, row, style): draws in place; an ``over`` returns the boxes of the labels it wrote, which
# the flagged people's edge markers keep clear of
Draw = Callable[[Any, PanelView, RowFrame, RenderStyle], "list[Box] | None"]


@dataclass(frozen=True)
class Ortho:
    """What makes a view orthographic: its axes in the world and what its window must hold."""

    basis: Callable[[Camera], np.ndarray]  # camera -> (3, 3) rows: panel right, panel up, into the panel (world)
    # (people (N, 3) in the view's axes, basis, camera, fit) -> (2, 3) min/max the window must hold
    bounds: Callable[[np.ndarray, np.ndarray, Camera, str], np.ndarray]
    floor_room: float | None = None  # fit_ortho_extent: keep the content this low in the panel, else centre it


@dataclass(frozen=True)
class View:
    """One figure column: its name, title, projection and drawings."""

    name: str  # the render.views / --views value
    title: str  # column header
    under: Draw  # background, before the people
    over: Draw  # annotations, after the people
    ortho: Ortho | None = None  # None: the camera's own view (perspective; needs no camera.yaml)
    shows_ghost: bool = True  # draw a row's ghost (the camera's view does not: there every body fits its pixels)

    @property
    def needs_camera(self) -> bool:
        """Whether a row needs a camera placing it in the world (orthographic views)."""
        return self.ortho is not None

    def window(self, rows: list[RowFrame], size: tuple[int, int], margin: float, fit: str = "people") -> Any:
        """This view's window holding every row given (and its ghost): an :class:`OrthoExtent`, or for
        the camera's view a :class:`FrontCrop` (None: the whole image)."""
        return self.window_of([window_bounds(r, (self.name,), fit) for r in rows], size, margin, fit)

    def window_of(self, bounds: list["WindowBounds"], size: tuple[int, int], margin: float, fit: str = "people") -> Any:
        """:meth:`window` from the rows' :func:`window_bounds` (which hold this view's)."""
        if self.ortho is None:
            return _front_window(bounds, size, margin, fit)
        placed = [b for b in bounds if b.placed]
        if not placed:
            raise ValueError(f"the {self.name} view needs a camera")
        plausible_only = any(b.plausible for b in placed)  # else nobody is plausible: frame everyone
        stacked = np.stack([b.ortho[self.name][0 if plausible_only else 1] for b in placed])
        union = np.stack([stacked[:, 0].min(axis=0), stacked[:, 1].max(axis=0)])
        return fit_ortho_extent(union, size, margin, self.ortho.floor_room)

    def panel(self, row: RowFrame, size: tuple[int, int], extents: Mapping[str, Any]) -> PanelView:
        """This view's panel for a row, in the window ``extents[name]``."""
        if self.ortho is None:
            return front_view(row, size, extents.get(self.name))
        if row.camera is None:
            raise ValueError(f"row {row.label!r}: the {self.name} view needs a camera")
        return ortho_view(self.name, row.camera, extents[self.name], size)


def _with_ghost(row: RowFrame, plausible_only: bool = False) -> np.ndarray:
    """(N, 3) finite camera-frame points of a row's people (``plausible_only``: of its :attr:`RowFrame.plausible`
    people) and its ghost's."""
    people = row.points_cam[row.plausible] if plausible_only else row.points_cam
    parts = [people.reshape(-1, 3)] + ([row.ghost.points_cam.reshape(-1, 3)] if row.ghost is not None else [])
    pts = np.concatenate(parts)
    return pts[np.isfinite(pts).all(axis=1)]


def camera_numbers(camera: Camera) -> str:
    """'f 593 px · pitch 48.8° · roll 0.8° · height 5.32 m'."""
    p = camera_parameters(camera)
    return f"f {p['focal_px']:.0f} px · pitch {p['pitch_deg']:.1f}° · roll {p['roll_deg']:.1f}° · height {p['height_m']:.2f} m"


@dataclass(frozen=True)
class WindowBounds:
    """What one row (of one frame) adds to the views' windows (:func:`window_bounds`): a few numbers per view,
    whatever the size of its people, so the windows of a long clip are fitted without keeping its frames."""

    image_size: tuple[int, int]  # (W, H) px of the row's front image
    placed: bool  # it has a camera (the orthographic views place it)
    plausible: bool  # it has a plausible person (:attr:`RowFrame.plausible`)
    front: np.ndarray | None  # (4,) x0, y0, x1, y1 px of its people's pixels; None: nobody in front of the camera
    ortho: Mapping[str, tuple[np.ndarray, np.ndarray]]  # view -> (2, 3) :func:`ortho_bounds` of (its plausible
    # people, every person), each with its ghost; {} when not placed


def window_bounds(row: RowFrame, views: tuple[str, ...], fit: str = "people") -> WindowBounds:
    """A row's :class:`WindowBounds` for the orthographic ``views`` (the camera's view's is always made)."""
    pts = front_points_cam(row.points_cam, row).reshape(-1, 3)  # not the ghost: drawn in another row's focal, it may
    # land anywhere in the image
    pts = pts[np.isfinite(pts).all(axis=1) & (pts[:, 2] > _NEAR_M)]
    front = None
    if len(pts):
        uv = pts[:, :2] / pts[:, 2:] * row.focal_px + np.asarray(row.principal_point)
        front = np.concatenate([uv.min(axis=0), uv.max(axis=0)])
    ortho = {}
    if row.camera is not None:
        for view in view_specs(views) if views else ():
            if view.ortho is not None:
                ortho[view.name] = tuple(ortho_bounds(view.name, row.camera, _with_ghost(row, only), fit)
                                         for only in (True, False))
    return WindowBounds(row.image_size, row.camera is not None, bool(row.plausible.any()), front, ortho)


# ---- projections -----------------------------------------------------------------------------------
def _front_window(bounds: list[WindowBounds], size: tuple[int, int], margin: float, fit: str) -> FrontCrop | None:
    """The image part around every row's people (their pixels through each row's intrinsics); None =
    the whole image (``fit="camera"``, no people, or people all over it)."""
    if fit == "camera" or not bounds:
        return None
    boxes = [b.front for b in bounds if b.front is not None]
    if not boxes:
        return None
    b = np.stack(boxes)
    return fit_front_crop(np.concatenate([b[:, :2].min(axis=0), b[:, 2:].max(axis=0)]), bounds[0].image_size, size, margin)


def front_view(row: RowFrame, size: tuple[int, int], crop: FrontCrop | None = None) -> PanelView:
    """The camera view: the row's image (W_i x H_i), or the ``crop`` of it, fitted into the panel, its intrinsics scaled."""
    W, H = size
    Wi, Hi = row.image_size
    if crop is None:
        s = min(W / Wi, H / Hi)
        ox, oy = 0.5 * (W - s * Wi), 0.5 * (H - s * Hi)
    else:
        x0, y0, x1, y1 = crop.box_px
        s = min(W / (x1 - x0), H / (y1 - y0))
        ox, oy = 0.5 * (W - s * (x1 - x0)) - s * x0, 0.5 * (H - s * (y1 - y0)) - s * y0
    pp = (s * row.principal_point[0] + ox, s * row.principal_point[1] + oy)
    z = _with_ghost(row)[:, 2]
    far = max(_MIN_FAR_M, 1.5 * float(z.max()) + 1.0) if z.size else _MIN_FAR_M
    clip = clip_from_cam_perspective(s * row.focal_px, pp, size, _NEAR_M, far)
    light = unit(np.array([0.0, -_LIGHT_RAISE, -1.0]))  # from the eye, a little above (image up = -y)
    return PanelView("front", size, clip, light, image_rect=(ox, oy, ox + s * Wi, oy + s * Hi), focal_px=s * row.focal_px)


def ortho_view(kind: str, camera: Camera, extent: OrthoExtent, size: tuple[int, int]) -> PanelView:
    """An orthographic view (side, top) of a camera's world in a window."""
    basis = ortho_basis_world(kind, camera)
    clip_from_world = clip_from_world_ortho(basis, extent, size)
    light_world = unit(-basis[2] + _LIGHT_RAISE * basis[1])
    return PanelView(kind, size, clip_from_world @ world_from_cam_h(camera), camera.R_cam_from_world @ light_world,
                     clip_from_world, extent.px_per_m, extent=extent)


def _side_basis(camera: Camera) -> np.ndarray:
    """right = horizontal forward, up = world up, depth = up x forward (camera on the left)."""
    fwd = horizontal_forward_world(camera)
    return np.stack([fwd, UP_WORLD, np.cross(UP_WORLD, fwd)])


def _top_basis(camera: Camera) -> np.ndarray:
    """right = forward x up (the camera's right), up = horizontal forward, depth = -up (looking down)."""
    fwd = horizontal_forward_world(camera)
    return np.stack([np.cross(fwd, UP_WORLD), fwd, -UP_WORLD])


def _min_max(pts_view: np.ndarray) -> np.ndarray:
    """(2, 3) min/max of view-axis points; a 2 m box when there are none."""
    if not len(pts_view):
        return np.array([[-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]])
    return np.stack([pts_view.min(axis=0), pts_view.max(axis=0)])


def _camera_view(basis: np.ndarray, camera: Camera) -> np.ndarray:
    """(1, 3) the camera centre in a view's axes."""
    return (basis @ camera.center_world)[None]


def _side_bounds(pts_view: np.ndarray, basis: np.ndarray, camera: Camera, fit: str) -> np.ndarray:
    """The people (and with ``fit="camera"`` the camera), with the ground line (height 0) always in view."""
    bounds = _min_max(np.concatenate([pts_view, _camera_view(basis, camera)]) if fit == "camera" or not len(pts_view)
                      else pts_view)
    bounds[0, 1], bounds[1, 1] = min(bounds[0, 1], 0.0), max(bounds[1, 1], 0.0)
    return bounds


def _top_bounds(pts_view: np.ndarray, basis: np.ndarray, camera: Camera, fit: str) -> np.ndarray:
    """The people (and with ``fit="camera"`` the camera)."""
    return _min_max(np.concatenate([pts_view, _camera_view(basis, camera)]) if fit == "camera" or not len(pts_view)
                    else pts_view)


# ---- drawings (Pillow) -----------------------------------------------------------------------------
def _draw(img: Any) -> Any:
    """An alpha-blending ImageDraw on ``img``."""
    return ImageDraw.Draw(img, "RGBA")


def _font_px(view: PanelView) -> int:
    """Annotation font size of a panel."""
    return max(10, min(view.size) // 28)


def _label(draw: Any, xy: tuple[float, float], text: str, ink: tuple, font_px: int, anchor: str = "la",
           outline: tuple | None = None) -> Box:
    """Text on a translucent white box (readable over people, grid and ground), the box outlined in
    ``outline`` if given; returns the box (panel px)."""
    face = font(font_px)
    box = draw.textbbox(xy, text, font=face, anchor=anchor)
    frame = (box[0] - 2, box[1] - 1, box[2] + 2, box[3] + 1)
    draw.rectangle(list(frame), fill=(255, 255, 255, 190), outline=outline, width=1 if outline else 0)
    draw.text(xy, text, fill=ink, font=face, anchor=anchor)
    return frame


def overlaps(a: Box, b: Box) -> bool:
    """Whether two (x0, y0, x1, y1) boxes overlap."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def edge_marker(draw: Any, view: PanelView, target_px: np.ndarray, fill: tuple, ink: tuple, text: str, radius_px: int,
                font_px: int, outline: tuple | None = None, taken: list[Box] | None = None) -> Box:
    """Something off an orthographic panel at ``target_px`` (2,) panel px: a triangle in ``fill`` on the
    nearest edge pointing to it, and ``text`` with its distance beyond the edge (metres) in ``ink``. Its
    label slides along the edge past the boxes in ``taken`` (to which it is added); returns the label's box."""
    W, H = view.size
    c, r = np.asarray(target_px, dtype=np.float64), radius_px
    m = 2 * r + 2
    edge = np.array([min(max(c[0], m), W - m), min(max(c[1], m), H - m)])
    d = c - edge
    dist_m = float(np.linalg.norm(d) / view.px_per_m)
    d = d / max(np.linalg.norm(d), 1e-9)
    anchor = ("l" if d[0] <= 0 else "r") + ("t" if d[1] <= 0 else "b")
    along = np.array([0.0, 1.0]) if abs(d[0]) >= abs(d[1]) else np.array([1.0, 0.0])  # the edge's direction
    along *= 1.0 if edge @ along < 0.5 * (H if along[1] else W) else -1.0  # toward the panel's middle
    face, label = font(font_px), f"{text} {dist_m:.1f} m"
    anchor_pil = {"lt": "la", "rt": "ra", "lb": "ld", "rb": "rd"}[anchor]
    n = np.array([-d[1], d[0]])
    for _ in range(12):  # slide along the edge past the boxes taken (earlier labels and markers)
        text_xy = (edge[0] - (r + 3) * np.sign(d[0] or -1),  # toward the panel's inside; below the axis name at the top
                   edge[1] - (r + 3) * np.sign(d[1] or -1) + (font_px + 4 if edge[1] < 3 * font_px else 0))
        box = draw.textbbox(text_xy, label, font=face, anchor=anchor_pil)
        tri = np.stack([edge + 2 * r * d, edge - r * d + 1.4 * r * n, edge - r * d - 1.4 * r * n])
        tri_box = (*tri.min(axis=0), *tri.max(axis=0))
        label_box = (box[0] - 2, box[1] - 1, box[2] + 2, box[3] + 1)
        if not any(overlaps(b, t) for b in (label_box, tri_box) for t in taken or ()):
            break
        step = box[3] - box[1] + 4 if along[1] else box[2] - box[0] + 6
        edge = np.clip(edge + step * along, m, [W - m, H - m])
    draw.polygon([tuple(p) for p in tri], fill=fill, outline=(255, 255, 255))
    frame = _label(draw, text_xy, label, ink, font_px, anchor_pil, outline)
    if taken is not None:
        taken.extend([frame, tri_box])
    return frame


def _tick_step_m(view: PanelView) -> float:
    """Metric tick spacing of an orthographic panel (also the top view's grid step)."""
    return nice_length_m(view.size[0] / view.px_per_m / _TICKS_PER_PANEL)


def tick_marks(view: PanelView) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """Metric ticks of an orthographic panel: ([(metres, panel x px)], [(metres, panel y px)]) along its
    right and up axes, every :func:`_tick_step_m`. Both views measure from the camera: its centre is at
    0 on their right axis and on the top view's up axis; the side view's up axis is the height above
    the ground."""
    W, H = view.size
    (uc, vc), s = view.extent.center_m, view.px_per_m
    step = _tick_step_m(view)
    xs = [k * step for k in range(math.ceil((uc - W / 2 / s) / step), math.floor((uc + W / 2 / s) / step) + 1)]
    ys = [k * step for k in range(math.ceil((vc - H / 2 / s) / step), math.floor((vc + H / 2 / s) / step) + 1)]
    return [(u, W / 2 + (u - uc) * s) for u in xs], [(v, H / 2 - (v - vc) * s) for v in ys]


def _ticks(draw: Any, view: PanelView, style: RenderStyle, x_name: str, y_name: str) -> list[Box]:
    """Metre tick labels along the bottom (panel right axis) and left (panel up axis) edges (:func:`tick_marks`)."""
    W, H = view.size
    f_px = _font_px(view)
    ink = rgb8(style.text)
    xs, ys = tick_marks(view)
    boxes = []
    for u, x in xs:
        if f_px < x < W - 3 * f_px:
            draw.line([(x, H - 4), (x, H)], fill=ink, width=1)
            boxes.append(_label(draw, (x, H - 5), f"{u:g}", ink, f_px - 2, "md"))
    for v, y in ys:
        if 2 * f_px < y < H - 2 * f_px:
            draw.line([(0, y), (4, y)], fill=ink, width=1)
            boxes.append(_label(draw, (6, y), f"{v:g}", ink, f_px - 2, "lm"))
    boxes.append(_label(draw, (W - 4, H - 5), f"{x_name} (m)", ink, f_px - 2, "rd"))
    boxes.append(_label(draw, (6, 4), f"{y_name} (m)", ink, f_px - 2, "la"))
    return boxes


def _camera_glyph(draw: Any, view: PanelView, camera: Camera, style: RenderStyle, at_world: np.ndarray) -> Box:
    """The camera as a dot with its viewing direction at ``at_world`` (3,), or when that is off the
    panel a triangle on the nearest edge pointing to it, labelled with its distance; returns its label's box."""
    W, H = view.size
    c = project_view_px(view.clip_from_world, at_world, view.size)
    axis_world = camera.R_cam_from_world.T @ np.array([0.0, 0.0, 1.0])
    tip = project_view_px(view.clip_from_world, at_world + axis_world * (28.0 / view.px_per_m), view.size)
    ink = rgb8(style.camera)
    r = max(4, min(view.size) // 60)
    f_px = _font_px(view)
    if 0 <= c[0] < W and 0 <= c[1] < H:
        draw.line([tuple(c), tuple(tip)], fill=ink, width=3)
        draw.ellipse([c[0] - r, c[1] - r, c[0] + r, c[1] + r], fill=ink, outline=(255, 255, 255))
        return _label(draw, (c[0] + r + 3, c[1] + r + 1), "camera", ink, f_px, "la")
    return edge_marker(draw, view, c, ink, ink, "camera", r, f_px)


def _front_under(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """Letterbox, then the video frame (or the background colour) in the image area (cropped to the panel)."""
    W, H = view.size
    draw = _draw(img)
    draw.rectangle([0, 0, W, H], fill=rgb8(mix(style.background, (0.0, 0.0, 0.0), 0.15)))
    frame = None if row.image is None else Image.fromarray(np.asarray(row.image, dtype=np.uint8)).convert("RGB")
    boxes = paste_boxes_px(view.image_rect, view.size, row.image_size if frame is None else frame.size)
    if boxes is None:  # no whole panel pixel of the image
        return
    box, source = boxes  # panel pixels (inside the panel), the picture's part filling them (inside the picture)
    if frame is None:
        draw.rectangle([box[0], box[1], box[2] - 1, box[3] - 1], fill=rgb8(style.background))
        return
    img.paste(frame.resize((box[2] - box[0], box[3] - box[1]), Image.BILINEAR, box=source), box[:2])


def _front_over(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> list[Box]:
    """The image's border, and "crop" when the panel shows part of the image."""
    x0, y0, x1, y1 = view.image_rect
    W, H = view.size
    draw = _draw(img)
    draw.rectangle([x0, y0, x1 - 1, y1 - 1], outline=rgb8(mix(style.background, style.text, 0.4)), width=1)
    if x0 < -0.5 or y0 < -0.5 or x1 > W + 0.5 or y1 > H + 0.5:  # a crop: say which part of the image
        s = (x1 - x0) / row.image_size[0]  # panel px per image px
        u0, u1 = (max(x0, 0.0) - x0) / s, (min(x1, W) - x0) / s
        v0, v1 = (max(y0, 0.0) - y0) / s, (min(y1, H) - y0) / s
        return [_label(draw, (W - 4, 4), f"image x {u0:.0f}-{u1:.0f}, y {v0:.0f}-{v1:.0f} px", rgb8(style.text),
                       _font_px(view) - 2, "ra")]
    return []


def _side_under(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """Metric grid, the camera's field of view (between its edges, down to the ground), the ground
    edge-on as a line, tinted below (sunk body parts show over it)."""
    W, H = view.size
    draw = _draw(img)
    _grid_lines(draw, view, style)
    draw.polygon([tuple(p) for p in side_fov_px(view, row.camera)], fill=(*rgb8(style.camera), 16))
    v_ground = float(project_view_px(view.clip_from_world, np.zeros(3), view.size)[1])
    draw.rectangle([0, v_ground, W, H], fill=rgb8(mix(style.background, style.ground, 0.25)))
    draw.line([(0, v_ground), (W, v_ground)], fill=rgb8(style.ground), width=2)


def _grid_lines(draw: Any, view: PanelView, style: RenderStyle) -> None:
    """Faint grid lines at the ticks (their labels come after the people)."""
    W, H = view.size
    ink = (*rgb8(mix(style.background, style.grid, 0.6)), 255)
    xs, ys = tick_marks(view)
    for _, x in xs:
        draw.line([(x, 0), (x, H)], fill=ink, width=1)
    for _, y in ys:
        draw.line([(0, y), (W, y)], fill=ink, width=1)


def _side_fov_edges_world(camera: Camera) -> np.ndarray:
    """(2, 3) world directions of the field of view's lowest and highest edges seen from the side:
    of the image corners' rays, the two at the extreme elevation angles."""
    W, H = camera.image_size
    corners = np.array([[0.0, 0.0], [W, 0.0], [W, H], [0.0, H], [W / 2, 0.0], [W / 2, H]])
    rays_cam = np.concatenate([(corners - camera.principal_point) / camera.focal_px, np.ones((len(corners), 1))], axis=1)
    rays_world = rays_cam @ camera.R_cam_from_world  # row-wise R_world_from_cam @ ray
    basis = _side_basis(camera)
    elevation = np.arctan2(rays_world @ basis[1], rays_world @ basis[0])
    return rays_world[[int(np.argmin(elevation)), int(np.argmax(elevation))]]


def side_fov_px(view: PanelView, camera: Camera) -> np.ndarray:
    """(K, 2) panel polygon of the camera's field of view from the side, cut at the ground and far off:
    the camera, where the lower edge meets the ground (or its far end), along the ground (when only the
    lower edge meets it), the upper edge's ground hit or far end."""
    far_m = 4.0 * math.hypot(*view.size) / view.px_per_m + float(np.linalg.norm(
        np.asarray(view.extent.center_m) - [0.0, camera.height_m]))
    ends, grounded = [], []
    for d in _side_fov_edges_world(camera):
        t = far_m / max(float(np.linalg.norm(d)), 1e-9)
        hits = d[1] < 0 and camera.height_m / -d[1] < t
        ends.append(camera.center_world + (camera.height_m / -d[1] if hits else t) * d)
        grounded.append(hits)
    pts = [camera.center_world, ends[0]]
    if grounded[0] and not grounded[1]:
        fwd = _side_basis(camera)[0]
        pts.append(camera.center_world * [1.0, 0.0, 1.0] + far_m * fwd)  # the ground, far ahead
    pts.append(ends[1])
    return project_view_px(view.clip_from_world, np.stack(pts), view.size)


def _side_over(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> list[Box]:
    """Ticks, the camera (edges of its field of view, viewing direction, position) and its numbers."""
    camera = row.camera
    draw = _draw(img)
    wedge = side_fov_px(view, camera)
    ink = rgb8(style.camera)
    for end in (wedge[1], wedge[-1]):  # the edges of the field of view
        draw.line([tuple(wedge[0]), tuple(end)], fill=(*ink, 150), width=1)
    boxes = _ticks(draw, view, style, "ahead of the camera", "height")
    boxes.append(_camera_glyph(draw, view, camera, style, camera.center_world))
    boxes.append(_label(draw, (view.size[0] - 4, 4), "camera: " + camera_numbers(camera), ink, _font_px(view) - 2, "ra"))
    return boxes


def _ground_fov_world(camera: Camera, far_m: float, n_per_edge: int = 24) -> np.ndarray:
    """(M, 3) world points: the image border cast on the ground, cut ``far_m`` from the camera (and above the horizon)."""
    W, H = camera.image_size
    t = np.linspace(0.0, 1.0, n_per_edge, endpoint=False)
    border_px = np.concatenate([np.stack([t * W, 0 * t], 1), np.stack([W + 0 * t, t * H], 1),
                                np.stack([W - t * W, H + 0 * t], 1), np.stack([0 * t, H - t * H], 1)])
    hit_world = camera.world_from_cam(camera.backproject_px_to_ground(border_px))
    rays_world = np.concatenate([(border_px - camera.principal_point) / camera.focal_px, np.ones((len(border_px), 1))],
                                axis=1) @ camera.R_cam_from_world  # row-wise R_world_from_cam @ ray
    foot_world = camera.center_world * [1.0, 0.0, 1.0]
    cut_world = foot_world + far_m * unit(rays_world * [1.0, 0.0, 1.0] + [1e-12, 0.0, 0.0])
    near_enough = np.isfinite(hit_world).all(axis=1) & (np.linalg.norm(hit_world - foot_world, axis=1) < far_m)
    return np.where(near_enough[:, None], hit_world, cut_world)


def _top_under(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """The camera's ground field of view (tinted, outlined) and a metric grid."""
    W, H = view.size
    camera = row.camera
    draw = _draw(img)
    origin = project_view_px(view.clip_from_world, camera.center_world * [1.0, 0.0, 1.0], view.size)
    far_m = (np.hypot(*(origin - [W / 2, H / 2])) + np.hypot(W, H)) / view.px_per_m  # well past the panel
    fov_px = project_view_px(view.clip_from_world, _ground_fov_world(camera, far_m), view.size)
    draw.polygon([tuple(p) for p in fov_px], fill=rgb8(mix(style.background, style.camera, 0.08)))
    _grid_lines(draw, view, style)
    outline = np.append(fov_px, fov_px[:1], axis=0)
    draw.line([tuple(p) for p in outline], fill=rgb8(mix(style.background, style.camera, 0.5)), width=1)


def _top_over(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> list[Box]:
    """The camera (dot + viewing direction, or an edge marker) and the ticks."""
    draw = _draw(img)
    boxes = _ticks(draw, view, style, "right of the camera", "ahead")
    boxes.append(_camera_glyph(draw, view, row.camera, style, row.camera.center_world * [1.0, 0.0, 1.0]))
    return boxes


# ---- the registry ------------------------------------------------------------------------------------
REGISTRY: dict[str, View] = {view.name: view for view in (
    View("front", "front (camera view)", _front_under, _front_over, shows_ghost=False),
    View("side", "side (orthographic)", _side_under, _side_over, Ortho(_side_basis, _side_bounds, _SIDE_FLOOR_ROOM)),
    View("top", "top (orthographic)", _top_under, _top_over, Ortho(_top_basis, _top_bounds)),
)}
VIEWS = tuple(REGISTRY)  # the valid render.views values


def view_specs(names: Iterable[str]) -> tuple[View, ...]:
    """The registry entries of view names, in order; ValueError naming unknown ones and the choices."""
    names = tuple(names)
    unknown = [v for v in names if v not in REGISTRY]
    if unknown or not names:
        raise ValueError(f"unknown view(s) {', '.join(unknown) or '(none)'}; choose from {', '.join(VIEWS)}")
    return tuple(REGISTRY[v] for v in names)


def parse_views(text: str) -> tuple[str, ...]:
    """'front,side' -> ('front', 'side'); raises ValueError naming an unknown view.

    >>> parse_views("Front, top")
    ('front', 'top')
    """
    views = tuple(v.strip().lower() for v in str(text).split(",") if v.strip())
    view_specs(views)
    return views


def _ortho(kind: str) -> Ortho:
    """The orthographic part of a view; ValueError for a view that has none."""
    ortho = view_specs([kind])[0].ortho
    if ortho is None:
        raise ValueError(f"no orthographic basis for view {kind!r}")
    return ortho


def ortho_basis_world(kind: str, camera: Camera) -> np.ndarray:
    """(3, 3) rows = panel right, panel up, into the panel (depth), in world coordinates."""
    return _ortho(kind).basis(camera)


def ortho_bounds(kind: str, camera: Camera, points_cam: np.ndarray, fit: str = "people") -> np.ndarray:
    """(2, 3) min/max (right, up, depth) view-plane coordinates of people, metres, plus what the view
    always shows (the side view the ground's height) and with ``fit="camera"`` the camera."""
    ortho = _ortho(kind)
    basis = ortho.basis(camera)
    pts_view = camera.world_from_cam(np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)) @ basis.T
    return ortho.bounds(pts_view[np.isfinite(pts_view).all(axis=1)], basis, camera, fit)


def scene_extents(rows: list[RowFrame], views: tuple[str, ...], size: tuple[int, int], margin: float,
                  fit: str = "people") -> dict[str, Any]:
    """One window per view holding every row given (and frame, when rows of several frames are given)."""
    if fit not in FITS:
        raise ValueError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
    return extents_from_bounds([window_bounds(r, views, fit) for r in rows], views, size, margin, fit)


def extents_from_bounds(bounds: list[WindowBounds], views: tuple[str, ...], size: tuple[int, int], margin: float,
                        fit: str = "people") -> dict[str, Any]:
    """:func:`scene_extents` from the rows' :func:`window_bounds` (made for ``views``, or more)."""
    if fit not in FITS:
        raise ValueError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
    return {view.name: view.window_of(bounds, size, margin, fit) for view in (view_specs(views) if views else ())}
