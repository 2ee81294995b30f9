"""The view registry: each figure column (front, side, top) is one :class:`View` entry in :data:`REGISTRY`.

An entry says everything about its view: its name (a ``render.views`` / ``--views`` value), its
column title, how it projects a row (the camera's own perspective, or an orthographic
:class:`Ortho` basis with what its shared window must hold), and what it draws under and over the
people. Adding a view = one entry here, its test and its row in docs/render.md's table.

- ``front``: the meshes through the intrinsics they were made with (the sequence's focal), fitted
  into the panel, optionally over the video frame. Everything looks right here by construction.
- ``side``: orthographic, looking along the ground and perpendicular to the camera's horizontal
  viewing direction; panel ``x`` = distance along that direction (camera to the left), ``y`` =
  height. The ground is edge-on, so it is drawn as a line; a metric scale bar reads heights and lean.
- ``top``: orthographic bird's-eye view, panel up = the camera's horizontal viewing direction,
  with the camera, its ground field of view and a metric grid.

Orthographic windows are shared by all rows (and frames) of a figure (:func:`scene_extents`), so
"before" and "after" compare at one scale.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..camera import Camera
from .geometry import (UP_WORLD, OrthoExtent, PanelView, clip_from_cam_perspective, clip_from_world_ortho,
                       fit_ortho_extent, horizontal_forward_world, nice_length_m, project_view_px, unit,
                       world_from_cam_h)
from .style import RenderStyle, font, mix, rgb8

__all__ = ["RowFrame", "Ortho", "View", "REGISTRY", "VIEWS", "view_specs", "parse_views", "ortho_basis_world",
           "ortho_bounds", "scene_extents", "front_view", "ortho_view"]

_LIGHT_RAISE = 0.4  # the light sits this much above the eye (fraction of the viewing direction)
_NEAR_M, _MIN_FAR_M = 0.05, 10.0  # front view clip planes (far grows with the scene)
_SIDE_FLOOR_ROOM = 0.18  # side view: room under the lowest point (fraction of the panel), for the scale bar


@dataclass(frozen=True)
class RowFrame:
    """What one grid row shows for one frame: meshes in the camera frame and how to view them."""

    label: str
    verts_cam: np.ndarray  # (P, V, 3) float, camera frame, metres
    faces: np.ndarray  # (F, 3) int
    person_ids: np.ndarray  # (P,) int
    image_size: tuple[int, int]  # (W, H) px of the front view's image
    focal_px: float  # the focal the meshes were made with
    principal_point: tuple[float, float]
    camera: Camera | None = None  # needed by orthographic views
    image: np.ndarray | None = None  # (H, W, 3) uint8 video frame under the front view


Draw = Callable[[Any, PanelView, RowFrame, RenderStyle], None]  # (PIL image, panel, row, style): draws in place


@dataclass(frozen=True)
class Ortho:
    """What makes a view orthographic: its axes in the world and what its shared window must hold."""

    basis: Callable[[Camera], np.ndarray]  # camera -> (3, 3) rows: panel right, panel up, into the panel (world)
    # (people (N, 3) in the view's axes, basis, camera) -> (2, 3) min/max the shared window must hold
    bounds: Callable[[np.ndarray, np.ndarray, Camera], np.ndarray]
    floor_room: float | None = None  # fit_ortho_extent: keep the content this low in the panel, else centre it


@dataclass(frozen=True)
class View:
    """One figure column: its name, title, projection and drawings."""

    name: str  # the render.views / --views value
    title: str  # column header
    under: Draw  # background, before the people
    over: Draw  # annotations, after the people
    ortho: Ortho | None = None  # None: the camera's own view (perspective; needs no camera.yaml)

    @property
    def needs_camera(self) -> bool:
        """Whether a row needs a camera placing it in the world (orthographic views)."""
        return self.ortho is not None

    def panel(self, row: RowFrame, size: tuple[int, int], extents: Mapping[str, OrthoExtent]) -> PanelView:
        """This view's panel for a row: the camera's view, or orthographic in the shared window ``extents[name]``."""
        if self.ortho is None:
            return front_view(row, size)
        if row.camera is None:
            raise ValueError(f"row {row.label!r}: the {self.name} view needs a camera")
        return ortho_view(self.name, row.camera, extents[self.name], size)


# ---- projections -----------------------------------------------------------------------------------
def front_view(row: RowFrame, size: tuple[int, int]) -> PanelView:
    """The camera view: the row's image (W_i x H_i) letterboxed into the panel, its intrinsics scaled."""
    W, H = size
    Wi, Hi = row.image_size
    s = min(W / Wi, H / Hi)
    ox, oy = 0.5 * (W - s * Wi), 0.5 * (H - s * Hi)
    pp = (s * row.principal_point[0] + ox, s * row.principal_point[1] + oy)
    z = np.asarray(row.verts_cam, dtype=np.float64)[..., 2]
    z = z[np.isfinite(z)]
    far = max(_MIN_FAR_M, 1.5 * float(z.max()) + 1.0) if z.size else _MIN_FAR_M
    clip = clip_from_cam_perspective(s * row.focal_px, pp, size, _NEAR_M, far)
    light = unit(np.array([0.0, -_LIGHT_RAISE, -1.0]))  # from the eye, a little above (image up = -y)
    return PanelView("front", size, clip, light, image_rect=(ox, oy, ox + s * Wi, oy + s * Hi))


def ortho_view(kind: str, camera: Camera, extent: OrthoExtent, size: tuple[int, int]) -> PanelView:
    """An orthographic view (side, top) of a camera's world at a shared extent."""
    basis = ortho_basis_world(kind, camera)
    clip_from_world = clip_from_world_ortho(basis, extent, size)
    light_world = unit(-basis[2] + _LIGHT_RAISE * basis[1])
    return PanelView(kind, size, clip_from_world @ world_from_cam_h(camera), camera.R_cam_from_world @ light_world,
                     clip_from_world, extent.px_per_m)


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


def _side_bounds(pts_view: np.ndarray, basis: np.ndarray, camera: Camera) -> np.ndarray:
    """The people, with the ground line (height 0) always in view."""
    bounds = _min_max(pts_view)
    bounds[0, 1], bounds[1, 1] = min(bounds[0, 1], 0.0), max(bounds[1, 1], 0.0)
    return bounds


def _top_bounds(pts_view: np.ndarray, basis: np.ndarray, camera: Camera) -> np.ndarray:
    """The people and the camera (the map always shows it)."""
    return _min_max(np.concatenate([pts_view, (basis @ camera.center_world)[None]]))


# ---- drawings (Pillow) -----------------------------------------------------------------------------
def _draw(img: Any) -> Any:
    """An alpha-blending ImageDraw on ``img``."""
    from PIL import ImageDraw

    return ImageDraw.Draw(img, "RGBA")


def _scale_bar(draw: Any, view: PanelView, style: RenderStyle) -> None:
    """Metric scale bar, one line ("|----| 5 m"), at the panel's bottom-left corner (below the side view's ground)."""
    W, H = view.size
    length_m = nice_length_m(0.2 * W / view.px_per_m)
    L = length_m * view.px_per_m
    label = f"{length_m:g} m" if length_m >= 1 else f"{length_m * 100:g} cm"
    font_px = max(10, H // 30)
    face = font(font_px)
    x0, y0 = 10, H - 6 - font_px // 2
    text_w = draw.textlength(label, font=face)
    draw.rectangle([x0 - 5, y0 - font_px // 2 - 3, x0 + L + 10 + text_w, y0 + font_px // 2 + 3], fill=(255, 255, 255, 170))
    ink = rgb8(style.text)
    draw.line([(x0, y0), (x0 + L, y0)], fill=ink, width=2)
    for x in (x0, x0 + L):
        draw.line([(x, y0 - font_px // 3), (x, y0 + font_px // 3)], fill=ink, width=2)
    draw.text((x0 + L + 6, y0), label, fill=ink, font=face, anchor="lm")


def _front_under(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """Letterbox, then the video frame (or the background colour) in the image area."""
    from PIL import Image

    x0, y0, x1, y1 = view.image_rect
    draw = _draw(img)
    draw.rectangle([0, 0, *view.size], fill=rgb8(mix(style.background, (0.0, 0.0, 0.0), 0.15)))
    box = (int(round(x0)), int(round(y0)), int(round(x1)), int(round(y1)))
    if row.image is not None:
        frame = Image.fromarray(np.asarray(row.image, dtype=np.uint8)).convert("RGB").resize((box[2] - box[0], box[3] - box[1]), Image.BILINEAR)
        img.paste(frame, box[:2])
    else:
        draw.rectangle([box[0], box[1], box[2] - 1, box[3] - 1], fill=rgb8(style.background))


def _front_over(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """The image's border."""
    x0, y0, x1, y1 = view.image_rect
    _draw(img).rectangle([x0, y0, x1 - 1, y1 - 1], outline=rgb8(mix(style.background, style.text, 0.4)), width=1)


def _side_under(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """The ground edge-on as a line, tinted below (sunk body parts show over it)."""
    W, H = view.size
    draw = _draw(img)
    v_ground = float(project_view_px(view.clip_from_world, np.zeros(3), view.size)[1])
    draw.rectangle([0, v_ground, W, H], fill=rgb8(mix(style.background, style.ground, 0.25)))
    draw.line([(0, v_ground), (W, v_ground)], fill=rgb8(style.ground), width=2)


def _side_over(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """Scale bar and where the camera is."""
    draw = _draw(img)
    _scale_bar(draw, view, style)
    draw.text((8, 6), "<- camera", fill=rgb8(style.text), font=font(max(10, view.size[1] // 30)))


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
    step_px = view.px_per_m * nice_length_m(0.2 * W / view.px_per_m)  # grid step = the scale bar's length
    ink = rgb8(style.grid)
    for k in range(math.ceil(-origin[0] / step_px), math.floor((W - origin[0]) / step_px) + 1):
        draw.line([(origin[0] + k * step_px, 0), (origin[0] + k * step_px, H)], fill=ink, width=1)
    for k in range(math.ceil(-origin[1] / step_px), math.floor((H - origin[1]) / step_px) + 1):
        draw.line([(0, origin[1] + k * step_px), (W, origin[1] + k * step_px)], fill=ink, width=1)
    outline = np.append(fov_px, fov_px[:1], axis=0)
    draw.line([tuple(p) for p in outline], fill=rgb8(mix(style.background, style.camera, 0.5)), width=1)


def _top_over(img: Any, view: PanelView, row: RowFrame, style: RenderStyle) -> None:
    """The camera (dot + viewing direction) and the scale bar."""
    camera = row.camera
    draw = _draw(img)
    c = project_view_px(view.clip_from_world, camera.center_world * [1, 0, 1], view.size)
    tip = project_view_px(view.clip_from_world, camera.center_world * [1, 0, 1] + horizontal_forward_world(camera)
                          * (24.0 / view.px_per_m), view.size)
    r = max(4, view.size[1] // 70)
    ink = rgb8(style.camera)
    draw.line([tuple(c), tuple(tip)], fill=ink, width=3)
    draw.ellipse([c[0] - r, c[1] - r, c[0] + r, c[1] + r], fill=ink, outline=(255, 255, 255))
    draw.text((c[0] + r + 3, c[1] + r), "camera", fill=ink, font=font(max(10, view.size[1] // 30)), anchor="lt")
    _scale_bar(draw, view, style)


# ---- the registry ------------------------------------------------------------------------------------
REGISTRY: dict[str, View] = {view.name: view for view in (
    View("front", "front (camera view)", _front_under, _front_over),
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


def ortho_bounds(kind: str, camera: Camera, verts_cam: np.ndarray) -> np.ndarray:
    """(2, 3) min/max (right, up, depth) view-plane coordinates of people, metres, plus what the view
    always shows (the side view the ground's height, the top view the camera)."""
    ortho = _ortho(kind)
    basis = ortho.basis(camera)
    pts_view = camera.world_from_cam(np.asarray(verts_cam, dtype=np.float64).reshape(-1, 3)) @ basis.T
    return ortho.bounds(pts_view[np.isfinite(pts_view).all(axis=1)], basis, camera)


def scene_extents(rows: list[RowFrame], views: tuple[str, ...], size: tuple[int, int], margin: float) -> dict[str, OrthoExtent]:
    """One shared extent per orthographic view over every row (and frame) given."""
    extents = {}
    for view in view_specs(views) if views else ():
        if view.ortho is None:
            continue
        bounds = [ortho_bounds(view.name, r.camera, r.verts_cam) for r in rows if r.camera is not None]
        if not bounds:
            raise ValueError(f"the {view.name} view needs a camera")
        stacked = np.stack(bounds)
        union = np.stack([stacked[:, 0].min(axis=0), stacked[:, 1].max(axis=0)])
        extents[view.name] = fit_ortho_extent(union, size, margin, view.ortho.floor_room)
    return extents
