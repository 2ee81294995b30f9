"""Projection maths shared by every view: clip-space matrices, orthographic windows, panel pixels.

Every view is one ``clip_from_cam`` 4x4 matrix (OpenGL clip space: NDC ``x`` right, ``y`` up,
``z`` in [-1, 1], nearer = smaller) applied to camera-frame vertices, so both rasterisers
(:mod:`rotavat_cli.render.gl`, :mod:`rotavat_cli.render.fallback`) draw the same thing. World
frame as in docs/conventions.md (``Y`` up, metres).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera

__all__ = [
    "UP_WORLD",
    "OrthoExtent",
    "FrontCrop",
    "PanelView",
    "world_from_cam_h",
    "horizontal_forward_world",
    "clip_from_cam_perspective",
    "clip_from_world_ortho",
    "fit_ortho_extent",
    "fit_front_crop",
    "paste_boxes_px",
    "panel_px_per_m",
    "ndc_to_px",
    "project_view_px",
    "nice_length_m",
]

UP_WORLD = np.array([0.0, 1.0, 0.0])  # docs/conventions.md: world Y is up
_MIN_EXTENT_M = 2.0  # an orthographic panel shows at least this many metres each way


@dataclass(frozen=True)
class OrthoExtent:
    """Orthographic window: metres per panel (centre in the view plane, px per metre, depth range)."""

    center_m: tuple[float, float]  # (u, v) in the view plane
    px_per_m: float
    depth_m: tuple[float, float]  # (near, far) along the viewing direction


@dataclass(frozen=True)
class FrontCrop:
    """The part of the image a front panel shows: ``x0, y0, x1, y1`` image pixels, at the panel's aspect."""

    box_px: tuple[float, float, float, float]


@dataclass(frozen=True)
class PanelView:
    """One panel's projection: ``clip_from_cam`` for meshes, plus what the overlays need."""

    kind: str  # a view's name (rotavat_cli.render.views.VIEWS)
    size: tuple[int, int]  # (W, H) px
    clip_from_cam: np.ndarray  # (4, 4)
    light_cam: np.ndarray  # (3,) unit, toward the light, camera frame
    clip_from_world: np.ndarray | None = None  # (4, 4), orthographic views
    px_per_m: float | None = None  # orthographic views: panel px per metre
    image_rect: tuple[float, float, float, float] | None = None  # front: x0, y0, x1, y1 of the whole image in the panel
    focal_px: float | None = None  # front: the panel's focal (px per metre at 1 m depth)
    extent: OrthoExtent | None = None  # orthographic views: the window


def panel_px_per_m(view: PanelView, depth_m: np.ndarray) -> np.ndarray:
    """Panel pixels per metre of objects at camera depths ``depth_m`` (...,): constant in orthographic
    views, ``focal / depth`` in the camera's view."""
    depth = np.asarray(depth_m, dtype=np.float64)
    if view.px_per_m is not None:
        return np.full(depth.shape, float(view.px_per_m))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(depth > 0, float(view.focal_px or 1.0) / depth, np.nan)


def unit(v: np.ndarray) -> np.ndarray:
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
            return unit(d)
    return np.array([0.0, 0.0, -1.0])  # unreachable for a valid rotation


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


def fit_front_crop(box_px: np.ndarray, image_size: tuple[int, int], size: tuple[int, int], margin: float,
                   min_fraction: float = 0.1) -> FrontCrop | None:
    """The image part to show around ``box_px`` (x0, y0, x1, y1; the people's pixels) in a W x H panel:
    the box plus ``margin`` of its size (and 2 % of the image) each way, grown to the panel's aspect and
    to at least ``min_fraction`` of the image width, slid inside the image. None when that is the whole
    image anyway (then the panel shows all of it, letterboxed).

    >>> [round(v) for v in fit_front_crop(np.array([1000.0, 500.0, 1100.0, 700.0]), (3840, 2160), (640, 360), 0.1).box_px]
    [680, 392, 1420, 808]
    """
    Wi, Hi = image_size
    W, H = size
    x0, y0, x1, y1 = (float(v) for v in box_px)
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or x1 <= x0 or y1 <= y0:
        return None
    pad = 0.02 * math.hypot(Wi, Hi)
    x0, x1 = x0 - margin * (x1 - x0) - pad, x1 + margin * (x1 - x0) + pad
    y0, y1 = y0 - margin * (y1 - y0) - pad, y1 + margin * (y1 - y0) + pad
    w = max(x1 - x0, (y1 - y0) * W / H, min_fraction * Wi)
    h = w * H / W
    if w >= 0.95 * Wi and h >= 0.95 * Hi:
        return None
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    cx = min(max(cx, w / 2), Wi - w / 2) if w <= Wi else Wi / 2  # slide inside the image where it fits
    cy = min(max(cy, h / 2), Hi - h / 2) if h <= Hi else Hi / 2
    return FrontCrop((cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2))


def paste_boxes_px(image_rect: tuple[float, float, float, float], size: tuple[int, int],
                   source_size: tuple[int, int]) -> tuple[tuple[int, int, int, int], tuple[float, float, float, float]] | None:
    """Where a picture of ``source_size`` (w, h px) drawn over ``image_rect`` (x0, y0, x1, y1 panel px,
    possibly overhanging) lands in a W x H panel: the whole panel pixels it covers (``x0, y0, x1, y1``
    ints, clipped to the panel) and the part of the picture that fills them (source px, clipped to the
    picture: never a negative offset, never past its far edge). Each axis has its own scale (a picture
    a pixel off the image size still fills the image's rectangle). None when no whole pixel is covered.

    Rounding the rectangle to whole pixels may reach up to half a pixel past it: that sliver shows the
    picture's edge (the source is clipped), where an unclipped source would start at a negative offset.

    >>> paste_boxes_px((137.45, 0.0, 502.55, 360.0), (640, 360), (500, 493))  # 500x493 letterboxed in 640x360
    ((137, 0, 503, 360), (0.0, 0.0, 500.0, 493.0))
    >>> paste_boxes_px((-50.0, 10.4, 590.0, 350.4), (320, 180), (640, 340))  # a crop: the left part of the picture
    ((0, 10, 320, 180), (50.0, 0.0, 370.0, 169.6))
    """
    W, H = size
    sw, sh = (float(v) for v in source_size)
    x0, y0, x1, y1 = (float(v) for v in image_rect)
    box = (min(max(round(x0), 0), W), min(max(round(y0), 0), H), min(max(round(x1), 0), W), min(max(round(y1), 0), H))
    if box[2] <= box[0] or box[3] <= box[1] or x1 <= x0 or y1 <= y0 or sw < 1 or sh < 1:
        return None
    sx, sy = (x1 - x0) / sw, (y1 - y0) / sh  # panel px per picture px
    source = (min(max((box[0] - x0) / sx, 0.0), sw), min(max((box[1] - y0) / sy, 0.0), sh),
              min(max((box[2] - x0) / sx, 0.0), sw), min(max((box[3] - y0) / sy, 0.0), sh))
    if source[2] <= source[0] or source[3] <= source[1]:
        return None
    return box, source


def ndc_to_px(ndc_xy: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """NDC (..., 2) (x right, y up, [-1, 1]) -> pixels (..., 2) (u right, v down, edges at 0 and W/H)."""
    W, H = size
    ndc = np.asarray(ndc_xy, dtype=np.float64)
    return np.stack([(ndc[..., 0] + 1.0) * (0.5 * W), (1.0 - ndc[..., 1]) * (0.5 * H)], axis=-1)


def project_view_px(clip_from_points: np.ndarray, points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Points (..., 3) through a clip matrix -> panel pixels (..., 2) (u right, v down)."""
    p = np.asarray(points, dtype=np.float64)
    clip = p @ clip_from_points[:, :3].T + clip_from_points[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        return ndc_to_px(clip[..., :2] / clip[..., 3:4], size)


def nice_length_m(target_m: float) -> float:
    """Largest 1, 2 or 5 x 10^k metres not above ``target_m`` (scale bars, grid steps).

    >>> nice_length_m(7.3), nice_length_m(0.3)
    (5.0, 0.2)
    """
    exp = math.floor(math.log10(max(target_m, 1e-9)))
    for mult in (5.0, 2.0, 1.0):
        if mult * 10.0 ** exp <= target_m:
            return mult * 10.0 ** exp
    return 10.0 ** exp
