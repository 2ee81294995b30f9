"""Pictures of people in a static camera: front (camera), side and top (orthographic) views, in a grid.

Views (the seed paper's figures; docs/render.md):

- ``front``: the meshes through the intrinsics they were made with (the sequence's focal), fitted
  into the panel, optionally over the video frame. Everything looks right here by construction.
- ``side``: orthographic, looking along the ground and perpendicular to the camera's horizontal
  viewing direction; panel ``x`` = distance along that direction (camera to the left), ``y`` =
  height. The ground is edge-on, so it is drawn as a line; a metric scale bar reads heights and lean.
- ``top``: orthographic bird's-eye view, panel up = the camera's horizontal viewing direction,
  with the camera, its ground field of view and a metric grid.

Every view is one ``clip_from_cam`` 4x4 matrix (OpenGL clip space) applied to camera-frame
vertices, so both rasterisers (:mod:`rotavat_cli.render_gl`, :mod:`rotavat_cli.render_fallback`)
draw the same thing. Side and top extents are shared by all rows (and frames) of a figure, so
"before" and "after" compare at one scale. Person colours come from ``person_id`` modulo the
palette, so a person keeps its colour across frames, rows and views.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .camera import Camera

__all__ = [
    "VIEWS",
    "RenderStyle",
    "RowFrame",
    "OrthoExtent",
    "PanelView",
    "parse_color",
    "person_colors",
    "vertex_normals",
    "shade_vertices",
    "horizontal_forward_world",
    "ortho_basis_world",
    "clip_from_cam_perspective",
    "clip_from_world_ortho",
    "fit_ortho_extent",
    "ortho_bounds",
    "scene_extents",
    "front_view",
    "ortho_view",
    "project_view_px",
    "render_panel",
    "render_grid",
    "nice_length_m",
]

VIEWS = ("front", "side", "top")
VIEW_TITLES = {"front": "front (camera view)", "side": "side (orthographic)", "top": "top (orthographic)"}
UP_WORLD = np.array([0.0, 1.0, 0.0])  # docs/conventions.md: world Y is up
_AMBIENT = 0.35  # shading: light that reaches every surface
_LIGHT_RAISE = 0.4  # the light sits this much above the eye (fraction of the viewing direction)
_NEAR_M, _MIN_FAR_M = 0.05, 10.0  # front view clip planes (far grows with the scene)
_MIN_EXTENT_M = 2.0  # an orthographic panel shows at least this many metres each way
_PALETTE_HEX = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22",
                "#393b79", "#637939", "#ad494a")
_SIDE_FLOOR_ROOM = 0.18  # side view: room under the lowest point (fraction of the panel), for the scale bar
_LABEL_PX = 26  # header row / label column thickness in grids


def parse_color(text: str) -> tuple[float, float, float]:
    """'#rrggbb' -> (r, g, b) in [0, 1]; raises ValueError otherwise."""
    s = str(text).strip().lstrip("#")
    if len(s) != 6 or any(ch not in "0123456789abcdefABCDEF" for ch in s):
        raise ValueError(f"colour {text!r} must be '#rrggbb'")
    return tuple(int(s[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


@dataclass(frozen=True)
class RenderStyle:
    """Colours (RGB in [0, 1]) and the margin around people in orthographic views."""

    background: tuple[float, float, float] = parse_color("#f2f2f0")  # defaults as configs/default.yaml render:
    ground: tuple[float, float, float] = parse_color("#8c8273")
    grid: tuple[float, float, float] = parse_color("#d9d6cf")
    camera: tuple[float, float, float] = parse_color("#bf382b")
    text: tuple[float, float, float] = parse_color("#222222")
    palette: tuple[tuple[float, float, float], ...] = tuple(parse_color(c) for c in _PALETTE_HEX)
    margin: float = 0.08  # fraction of the people's extent added on each side (side/top views)

    @classmethod
    def from_config(cls, opts: dict) -> "RenderStyle":
        """Style from a ``render:`` config section (hex colours, palette as comma-separated hex)."""
        palette = tuple(parse_color(c) for c in str(opts["palette"]).split(",") if c.strip())
        if not palette:
            raise ValueError("palette must list at least one colour")
        if not 0.0 <= float(opts["margin"]) <= 10.0:
            raise ValueError(f"render.margin must be in [0, 10], got {opts['margin']}")
        return cls(parse_color(opts["background"]), parse_color(opts["ground"]), parse_color(opts["grid"]),
                   parse_color(opts["camera_color"]), parse_color(opts["text"]), palette, float(opts["margin"]))


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
    camera: Camera | None = None  # needed by side/top views
    image: np.ndarray | None = None  # (H, W, 3) uint8 video frame under the front view


@dataclass(frozen=True)
class OrthoExtent:
    """Orthographic window: metres per panel (centre in the view plane, px per metre, depth range)."""

    center_m: tuple[float, float]  # (u, v) in the view plane
    px_per_m: float
    depth_m: tuple[float, float]  # (near, far) along the viewing direction


@dataclass(frozen=True)
class PanelView:
    """One panel's projection: ``clip_from_cam`` for meshes, plus what the overlays need."""

    kind: str  # front | side | top
    size: tuple[int, int]  # (W, H) px
    clip_from_cam: np.ndarray  # (4, 4)
    light_cam: np.ndarray  # (3,) unit, toward the light, camera frame
    clip_from_world: np.ndarray | None = None  # (4, 4), orthographic views
    px_per_m: float | None = None
    image_rect: tuple[float, float, float, float] | None = None  # front: x0, y0, x1, y1 of the image


# ---- colours and shading ---------------------------------------------------------------------------
def person_colors(person_ids: np.ndarray, palette: tuple[tuple[float, float, float], ...]) -> np.ndarray:
    """(P,) ids -> (P, 3) colours: ``palette[id mod len(palette)]``, stable across frames and rows."""
    pal = np.asarray(palette, dtype=np.float64).reshape(-1, 3)
    return pal[np.mod(np.asarray(person_ids, dtype=np.int64), len(pal))]


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P, V, 3) vertices, (F, 3) faces -> (P, V, 3) unit area-weighted normals (0 where undefined)."""
    from scipy.sparse import csr_matrix

    v = np.asarray(verts, dtype=np.float64)
    P, V = v.shape[:2]
    f = np.asarray(faces, dtype=np.int64)
    a, b = v[:, f[:, 1]] - v[:, f[:, 0]], v[:, f[:, 2]] - v[:, f[:, 0]]
    face_n = np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                       a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)  # (P, F, 3), |n| = 2 area
    incidence = csr_matrix((np.ones(f.size), (f.reshape(-1), np.repeat(np.arange(f.shape[0]), 3))), shape=(V, f.shape[0]))
    n = (incidence @ face_n.transpose(1, 0, 2).reshape(f.shape[0], P * 3)).reshape(V, P, 3).transpose(1, 0, 2)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


def shade_vertices(colors: np.ndarray, normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Two-sided Lambert: colours and unit normals (..., 3) (broadcast), light (3,) -> lit colours (..., 3)."""
    lambert = np.abs(np.asarray(normals, dtype=np.float64) @ np.asarray(light, dtype=np.float64))
    return np.asarray(colors, dtype=np.float64) * (_AMBIENT + (1.0 - _AMBIENT) * lambert)[..., None]


# ---- view geometry ---------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    """Vector (..., 3) divided by its norm."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _h44(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(3, 3) rotation/linear part and (3,) translation -> (4, 4) homogeneous matrix."""
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, t
    return M


def world_from_cam_h(camera: Camera) -> np.ndarray:
    """(4, 4) homogeneous ``world_from_cam`` of a camera."""
    R = camera.R_cam_from_world
    return _h44(R.T, -R.T @ camera.t_cam_from_world)


def horizontal_forward_world(camera: Camera) -> np.ndarray:
    """(3,) unit: the optical axis projected on the ground (image-up direction if looking straight down)."""
    R_world_from_cam = camera.R_cam_from_world.T
    for axis_cam in (np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0])):
        d = R_world_from_cam @ axis_cam
        d = d - np.dot(d, UP_WORLD) * UP_WORLD
        if np.linalg.norm(d) > 1e-6:
            return _unit(d)
    return np.array([0.0, 0.0, -1.0])  # unreachable for a valid rotation


def ortho_basis_world(kind: str, camera: Camera) -> np.ndarray:
    """(3, 3) rows = panel right, panel up, into the panel (depth), in world coordinates.

    side: right = horizontal forward, up = world up, depth = up x forward (camera on the left).
    top: right = forward x up (the camera's right), up = horizontal forward, depth = -up (looking down).
    """
    fwd = horizontal_forward_world(camera)
    if kind == "side":
        return np.stack([fwd, UP_WORLD, np.cross(UP_WORLD, fwd)])
    if kind == "top":
        return np.stack([np.cross(fwd, UP_WORLD), fwd, -UP_WORLD])
    raise ValueError(f"no orthographic basis for view {kind!r}")


def clip_from_cam_perspective(focal_px: float, principal_point: tuple[float, float], size: tuple[int, int],
                              near_m: float, far_m: float) -> np.ndarray:
    """(4, 4) OpenGL clip-from-OpenCV-camera matrix: pixel ``(u, v)`` of a W x H image <-> NDC, z in [near, far]."""
    W, H = size
    cx, cy = principal_point
    a, b = (far_m + near_m) / (far_m - near_m), -2.0 * far_m * near_m / (far_m - near_m)
    return np.array([[2.0 * focal_px / W, 0.0, 2.0 * cx / W - 1.0, 0.0],
                     [0.0, -2.0 * focal_px / H, 1.0 - 2.0 * cy / H, 0.0],
                     [0.0, 0.0, a, b],
                     [0.0, 0.0, 1.0, 0.0]])


def clip_from_world_ortho(basis_world: np.ndarray, extent: OrthoExtent, size: tuple[int, int]) -> np.ndarray:
    """(4, 4) orthographic clip-from-world matrix for a (3, 3) view basis and its extent."""
    W, H = size
    (uc, vc), s, (d0, d1) = extent.center_m, extent.px_per_m, extent.depth_m
    scale = np.diag([2.0 * s / W, 2.0 * s / H, 2.0 / (d1 - d0)])
    shift = np.array([-2.0 * s * uc / W, -2.0 * s * vc / H, -(d1 + d0) / (d1 - d0)])
    return _h44(scale @ basis_world, shift)


def ortho_bounds(kind: str, camera: Camera, verts_cam: np.ndarray) -> np.ndarray:
    """(2, 3) min/max (right, up, depth) view-plane coordinates of people, metres; the side view includes
    the ground's height, the top view the camera."""
    basis = ortho_basis_world(kind, camera)
    pts_view = camera.world_from_cam(np.asarray(verts_cam, dtype=np.float64).reshape(-1, 3)) @ basis.T
    pts_view = pts_view[np.isfinite(pts_view).all(axis=1)]
    if kind == "top":
        pts_view = np.concatenate([pts_view, (basis @ camera.center_world)[None]])  # the map always shows the camera
    if not len(pts_view):
        return np.array([[-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]])
    lo, hi = pts_view.min(axis=0), pts_view.max(axis=0)
    if kind == "side":  # the ground line (height 0) is always in view
        lo[1], hi[1] = min(lo[1], 0.0), max(hi[1], 0.0)
    return np.stack([lo, hi])


def fit_ortho_extent(bounds: np.ndarray, size: tuple[int, int], margin: float, floor_room: float | None = None) -> OrthoExtent:
    """Fit (2, 3) view-plane bounds plus a relative margin into a W x H panel at one scale (metres isotropic).

    floor_room: if set, sit the content's bottom this fraction of the panel height above the
    bottom edge when there is vertical room to spare (side view: ground low, sky above), else centre.
    """
    W, H = size
    lo, hi = np.asarray(bounds, dtype=np.float64)
    span = np.maximum(hi - lo, 1e-6)
    pad = margin * span[:2] + 0.05 * _MIN_EXTENT_M
    width_m = max(span[0] + 2 * pad[0], _MIN_EXTENT_M)
    height_m = max(span[1] + 2 * pad[1], _MIN_EXTENT_M)
    px_per_m = min(W / width_m, H / height_m)
    center = 0.5 * (lo[:2] + hi[:2])
    if floor_room is not None:
        panel_h_m = H / px_per_m
        bottom, top = lo[1] - pad[1], hi[1] + pad[1]
        edge = max(top - panel_h_m, min(bottom - floor_room * panel_h_m, bottom))
        center[1] = edge + 0.5 * panel_h_m
    depth_pad = 0.1 * span[2] + 1.0
    return OrthoExtent((float(center[0]), float(center[1])), float(px_per_m), (float(lo[2] - depth_pad), float(hi[2] + depth_pad)))


def scene_extents(rows: list[RowFrame], views: tuple[str, ...], size: tuple[int, int], margin: float) -> dict[str, OrthoExtent]:
    """One shared extent per orthographic view over every row (and frame) given."""
    extents = {}
    for kind in views:
        if kind == "front":
            continue
        bounds = [ortho_bounds(kind, r.camera, r.verts_cam) for r in rows if r.camera is not None]
        if not bounds:
            raise ValueError(f"the {kind} view needs a camera")
        stacked = np.stack(bounds)
        union = np.stack([stacked[:, 0].min(axis=0), stacked[:, 1].max(axis=0)])
        extents[kind] = fit_ortho_extent(union, size, margin, _SIDE_FLOOR_ROOM if kind == "side" else None)
    return extents


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
    light = _unit(np.array([0.0, -_LIGHT_RAISE, -1.0]))  # from the eye, a little above (image up = -y)
    return PanelView("front", size, clip, light, image_rect=(ox, oy, ox + s * Wi, oy + s * Hi))


def ortho_view(kind: str, camera: Camera, extent: OrthoExtent, size: tuple[int, int]) -> PanelView:
    """Side or top orthographic view of a camera's world at a shared extent."""
    basis = ortho_basis_world(kind, camera)
    clip_from_world = clip_from_world_ortho(basis, extent, size)
    light_world = _unit(-basis[2] + _LIGHT_RAISE * basis[1])
    return PanelView(kind, size, clip_from_world @ world_from_cam_h(camera), camera.R_cam_from_world @ light_world,
                     clip_from_world, extent.px_per_m)


def project_view_px(clip_from_points: np.ndarray, points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Points (..., 3) through a clip matrix -> panel pixels (..., 2) (u right, v down)."""
    from .render_fallback import ndc_to_px

    p = np.asarray(points, dtype=np.float64)
    clip = p @ clip_from_points[:, :3].T + clip_from_points[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        return ndc_to_px(clip[..., :2] / clip[..., 3:4], size)


def nice_length_m(target_m: float) -> float:
    """Largest 1, 2 or 5 x 10^k metres not above ``target_m`` (scale bars, grid steps)."""
    exp = math.floor(math.log10(max(target_m, 1e-9)))
    for mult in (5.0, 2.0, 1.0):
        if mult * 10.0 ** exp <= target_m:
            return mult * 10.0 ** exp
    return 10.0 ** exp


# ---- drawing (Pillow) ----------------------------------------------------------------------------
def _rgb8(color: tuple[float, float, float]) -> tuple[int, int, int]:
    """Colour in [0, 1] -> 8-bit tuple."""
    return tuple(int(round(255 * min(max(c, 0.0), 1.0))) for c in color)  # type: ignore[return-value]


def _mix(a: tuple[float, float, float], b: tuple[float, float, float], t: float) -> tuple[float, float, float]:
    """(1 - t) a + t b."""
    return tuple((1 - t) * x + t * y for x, y in zip(a, b))  # type: ignore[return-value]


def _font(size_px: int) -> Any:
    """Pillow's default font at a size (bitmap default on Pillow builds without FreeType)."""
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size_px)
    except (TypeError, OSError, ImportError):
        return ImageFont.load_default()


def _scale_bar(draw: Any, view: PanelView, style: RenderStyle) -> None:
    """Metric scale bar, one line ("|----| 5 m"), at the panel's bottom-left corner (below the side view's ground)."""
    W, H = view.size
    length_m = nice_length_m(0.2 * W / view.px_per_m)
    L = length_m * view.px_per_m
    label = f"{length_m:g} m" if length_m >= 1 else f"{length_m * 100:g} cm"
    font_px = max(10, H // 30)
    font = _font(font_px)
    x0, y0 = 10, H - 6 - font_px // 2
    text_w = draw.textlength(label, font=font)
    draw.rectangle([x0 - 5, y0 - font_px // 2 - 3, x0 + L + 10 + text_w, y0 + font_px // 2 + 3], fill=(255, 255, 255, 170))
    ink = _rgb8(style.text)
    draw.line([(x0, y0), (x0 + L, y0)], fill=ink, width=2)
    for x in (x0, x0 + L):
        draw.line([(x, y0 - font_px // 3), (x, y0 + font_px // 3)], fill=ink, width=2)
    draw.text((x0 + L + 6, y0), label, fill=ink, font=font, anchor="lm")


def _side_under(draw: Any, view: PanelView, style: RenderStyle) -> None:
    """Side view background: ground edge-on as a line, tinted below (sunk body parts show over it)."""
    W, H = view.size
    v_ground = float(project_view_px(view.clip_from_world, np.zeros(3), view.size)[1])
    draw.rectangle([0, v_ground, W, H], fill=_rgb8(_mix(style.background, style.ground, 0.25)))
    draw.line([(0, v_ground), (W, v_ground)], fill=_rgb8(style.ground), width=2)


def _side_over(draw: Any, view: PanelView, style: RenderStyle) -> None:
    """Side view annotations: scale bar and where the camera is."""
    _scale_bar(draw, view, style)
    draw.text((8, 6), "<- camera", fill=_rgb8(style.text), font=_font(max(10, view.size[1] // 30)))


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
    cut_world = foot_world + far_m * _unit(rays_world * [1.0, 0.0, 1.0] + [1e-12, 0.0, 0.0])
    near_enough = np.isfinite(hit_world).all(axis=1) & (np.linalg.norm(hit_world - foot_world, axis=1) < far_m)
    return np.where(near_enough[:, None], hit_world, cut_world)


def _top_under(draw: Any, view: PanelView, camera: Camera, style: RenderStyle) -> None:
    """Top view background: the camera's ground field of view (tinted, outlined) and a metric grid."""
    W, H = view.size
    origin = project_view_px(view.clip_from_world, camera.center_world * [1.0, 0.0, 1.0], view.size)
    far_m = (np.hypot(*(origin - [W / 2, H / 2])) + np.hypot(W, H)) / view.px_per_m  # well past the panel
    fov_px = project_view_px(view.clip_from_world, _ground_fov_world(camera, far_m), view.size)
    draw.polygon([tuple(p) for p in fov_px], fill=_rgb8(_mix(style.background, style.camera, 0.08)))
    step_px = view.px_per_m * nice_length_m(0.2 * W / view.px_per_m)  # grid step = the scale bar's length
    ink = _rgb8(style.grid)
    for k in range(math.ceil(-origin[0] / step_px), math.floor((W - origin[0]) / step_px) + 1):
        draw.line([(origin[0] + k * step_px, 0), (origin[0] + k * step_px, H)], fill=ink, width=1)
    for k in range(math.ceil(-origin[1] / step_px), math.floor((H - origin[1]) / step_px) + 1):
        draw.line([(0, origin[1] + k * step_px), (W, origin[1] + k * step_px)], fill=ink, width=1)
    outline = np.append(fov_px, fov_px[:1], axis=0)
    draw.line([tuple(p) for p in outline], fill=_rgb8(_mix(style.background, style.camera, 0.5)), width=1)


def _top_over(draw: Any, view: PanelView, camera: Camera, style: RenderStyle) -> None:
    """Top view annotations: the camera (dot + viewing direction) and the scale bar."""
    c = project_view_px(view.clip_from_world, camera.center_world * [1, 0, 1], view.size)
    tip = project_view_px(view.clip_from_world, camera.center_world * [1, 0, 1] + horizontal_forward_world(camera)
                          * (24.0 / view.px_per_m), view.size)
    r = max(4, view.size[1] // 70)
    ink = _rgb8(style.camera)
    draw.line([tuple(c), tuple(tip)], fill=ink, width=3)
    draw.ellipse([c[0] - r, c[1] - r, c[0] + r, c[1] + r], fill=ink, outline=(255, 255, 255))
    draw.text((c[0] + r + 3, c[1] + r), "camera", fill=ink, font=_font(max(10, view.size[1] // 30)), anchor="lt")
    _scale_bar(draw, view, style)


def _front_under(img: Any, view: PanelView, style: RenderStyle, image: np.ndarray | None) -> Any:
    """Front view background: letterbox, then the video frame (or the background colour) in the image area."""
    from PIL import Image, ImageDraw

    x0, y0, x1, y1 = view.image_rect
    draw = ImageDraw.Draw(img, "RGBA")
    draw.rectangle([0, 0, *view.size], fill=_rgb8(_mix(style.background, (0.0, 0.0, 0.0), 0.15)))
    box = (int(round(x0)), int(round(y0)), int(round(x1)), int(round(y1)))
    if image is not None:
        frame = Image.fromarray(np.asarray(image, dtype=np.uint8)).convert("RGB").resize((box[2] - box[0], box[3] - box[1]), Image.BILINEAR)
        img.paste(frame, box[:2])
    else:
        draw.rectangle([box[0], box[1], box[2] - 1, box[3] - 1], fill=_rgb8(style.background))
    return img


# ---- panels and grids --------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Mesh:
    """A row's people flattened for the rasterisers: computed once, shaded per view."""

    points_cam: np.ndarray  # (N, 3) float64, N = P * V
    faces: np.ndarray  # (P * F, 3) int64, offset per person
    colors: np.ndarray  # (N, 3) unlit colours
    normals_cam: np.ndarray  # (N, 3) unit


def _row_mesh(row: RowFrame, style: RenderStyle) -> _Mesh:
    """Flatten a row's finite people into one mesh with per-vertex colours and normals."""
    verts = np.asarray(row.verts_cam, dtype=np.float64)
    faces = np.asarray(row.faces, dtype=np.int64).reshape(-1, 3)
    if verts.ndim != 3 or verts.shape[0] == 0 or verts.shape[1] == 0 or faces.shape[0] == 0:
        return _Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
    finite = np.isfinite(verts).all(axis=(1, 2))
    verts, ids = verts[finite], np.asarray(row.person_ids)[finite]
    P, V = verts.shape[:2]
    colors = np.broadcast_to(person_colors(ids, style.palette)[:, None, :], (P, V, 3))
    flat_faces = (faces[None] + V * np.arange(P)[:, None, None]).reshape(-1, 3)
    return _Mesh(verts.reshape(-1, 3), flat_faces, colors.reshape(-1, 3), vertex_normals(verts, faces).reshape(-1, 3))


def _mesh_layer(mesh: _Mesh, view: PanelView, rasterize: Any) -> np.ndarray:
    """Rasterise a row's shaded people in one view -> (H, W, 4) float RGBA."""
    if mesh.faces.shape[0] == 0:
        return np.zeros((view.size[1], view.size[0], 4), dtype=np.float32)
    lit = shade_vertices(mesh.colors, mesh.normals_cam, view.light_cam)
    return rasterize(mesh.points_cam, mesh.faces, lit, view.clip_from_cam, view.size)


def render_panel(row: RowFrame, view: PanelView, rasterize: Any, style: RenderStyle, mesh: _Mesh | None = None) -> np.ndarray:
    """One panel: background and under-overlays, the shaded meshes, then annotations -> (H, W, 3) uint8."""
    from PIL import Image, ImageDraw

    W, H = view.size
    img = Image.new("RGB", (W, H), _rgb8(style.background))
    draw = ImageDraw.Draw(img, "RGBA")
    if view.kind == "front":
        img = _front_under(img, view, style, row.image)
    elif view.kind == "side":
        _side_under(draw, view, style)
    else:
        _top_under(draw, view, row.camera, style)
    layer = _mesh_layer(mesh if mesh is not None else _row_mesh(row, style), view, rasterize)
    base = np.asarray(img, dtype=np.float32) / 255.0
    alpha = layer[..., 3:4]
    img = Image.fromarray(np.round(255.0 * (base * (1.0 - alpha) + layer[..., :3] * alpha)).astype(np.uint8))
    draw = ImageDraw.Draw(img, "RGBA")
    if view.kind == "side":
        _side_over(draw, view, style)
    elif view.kind == "top":
        _top_over(draw, view, row.camera, style)
    else:
        x0, y0, x1, y1 = view.image_rect
        draw.rectangle([x0, y0, x1 - 1, y1 - 1], outline=_rgb8(_mix(style.background, style.text, 0.4)), width=1)
    return np.asarray(img)


def render_grid(rows: list[RowFrame], views: tuple[str, ...], size: tuple[int, int], rasterize: Any,
                style: RenderStyle, extents: dict[str, OrthoExtent] | None = None, title: str = "") -> np.ndarray:
    """Figure: one row per RowFrame, one column per view, labelled -> (H_total, W_total, 3) uint8.

    extents: shared orthographic extents (default: fitted to these rows).
    """
    from PIL import Image, ImageDraw

    unknown = [v for v in views if v not in VIEWS]
    if unknown or not views:
        raise ValueError(f"unknown view(s) {', '.join(unknown) or '(none)'}; choose from {', '.join(VIEWS)}")
    extents = extents if extents is not None else scene_extents(rows, views, size, style.margin)
    W, H = size
    fig = Image.new("RGB", (_LABEL_PX + W * len(views), _LABEL_PX + H * len(rows)), (255, 255, 255))
    draw = ImageDraw.Draw(fig)
    font = _font(_LABEL_PX * 6 // 10)
    ink = _rgb8(style.text)
    for j, kind in enumerate(views):
        draw.text((_LABEL_PX + W * j + W / 2, _LABEL_PX / 2), VIEW_TITLES[kind], fill=ink, font=font, anchor="mm")
    if title:
        draw.text((4, _LABEL_PX / 2), title, fill=ink, font=_font(_LABEL_PX * 4 // 10), anchor="lm")
    for i, row in enumerate(rows):
        label = Image.new("RGB", (H, _LABEL_PX), (255, 255, 255))
        ImageDraw.Draw(label).text((H / 2, _LABEL_PX / 2), row.label, fill=ink, font=font, anchor="mm")
        fig.paste(label.rotate(90, expand=True), (0, _LABEL_PX + H * i))
        mesh = _row_mesh(row, style)
        for j, kind in enumerate(views):
            if kind == "front":
                view = front_view(row, size)
            else:
                if row.camera is None:
                    raise ValueError(f"row {row.label!r}: the {kind} view needs a camera")
                view = ortho_view(kind, row.camera, extents[kind], size)
            panel = render_panel(row, view, rasterize, style, mesh)
            fig.paste(Image.fromarray(panel), (_LABEL_PX + W * j, _LABEL_PX + H * i))
    return np.asarray(fig)
