"""Static camera over a ground plane: a pinhole and an optional lens distortion (conventions: docs/conventions.md).

Frames
------
- pixels ``px``: origin top-left, ``u`` right, ``v`` down;
- camera ``cam`` (OpenCV): ``x`` right, ``y`` down, ``z`` forward, metres;
- world ``world``: origin on the ground below the camera centre, ``Y`` up, ``X`` the camera's
  ``x`` axis projected on the ground, ``Z = X x Y`` (back toward the camera).

The camera pose is three scene parameters: ``pitch`` (downward tilt, + = looking down), ``roll``
(about the optical axis) and ``height`` (camera centre above the ground). World up in the camera
frame is ``n = (-sin(roll) cos(pitch), -cos(roll) cos(pitch), -sin(pitch))`` and the ground is
``n . X + h = 0``.

The lens (``Camera.distortion``, 0 = a pinhole) is the one-parameter division model of
:mod:`.lens` about the principal point: the camera's pixels ``px`` are distorted pixels (those of
the image), the pinhole's are undistorted. :meth:`Camera.project` applies the distortion after the
pinhole, :meth:`Camera.pixel_rays_cam` and :meth:`Camera.backproject_px_to_ground` remove it first;
the module-level functions (``project_cam_to_px``, ``pixel_rays_cam``, ...) are the bare pinhole
(also what an HPS method's own camera is). With ``distortion == 0`` every method returns what the
pinhole functions return, bit for bit.

Every array function broadcasts over leading dimensions, so the calibration grid can pass
parameter arrays of shape ``(G, 1)`` against points of shape ``(1, N, 2)``.

Examples
--------
>>> cam = Camera(image_size=(640, 480), focal_px=500.0, principal_point=(320.0, 240.0),
...              pitch_rad=np.deg2rad(30.0), roll_rad=0.0, height_m=5.0)
>>> ground_cam = cam.backproject_px_to_ground(np.array([320.0, 240.0]))
>>> round(float(ground_cam[2]), 6)  # 5 m / sin(30 deg) along the optical axis
10.0
>>> round(float(cam.height_above_ground(ground_cam)), 9)
0.0
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import Any

import numpy as np

from .lens import check_distortion, distort_px, lens_radius_px, undistort_px

__all__ = [
    "Camera",
    "world_points_f32",
    "up_vector_cam",
    "pitch_roll_from_up",
    "intrinsics_matrix",
    "project_cam_to_px",
    "pixel_rays_cam",
    "backproject_px_to_plane",
    "height_above_ground",
    "R_cam_from_world_from_up",
    "horizon_v_px",
    "reexpress_cam",
    "camera_parameters",
    "people_not_in_front",
    "world_to_cam",
    "ROOT_CENTRED_M",
    "check_camera_bounds",
    "MAX_IMAGE_SIDE_PX",
    "MAX_FOCAL_PX",
    "MAX_HEIGHT_M",
]

_EPS = 1e-12  # denominators below this are treated as "ray parallel to the plane"
# Sanity bounds of a camera read from a file (why: the largest sensors are ~20,000 px wide; a 1e7 px
# focal is a 0.01 deg field of view; 100 km is no camera over a walking person).
MAX_IMAGE_SIDE_PX = 100_000
MAX_FOCAL_PX = 1e7
MAX_HEIGHT_M = 1e5
SAME_CAMERA_TOL = 1e-9  # Camera.matches: float noise (YAML round trips, matrices re-derived: ~1e-16) is far below it


def up_vector_cam(pitch_rad: np.ndarray | float, roll_rad: np.ndarray | float = 0.0) -> np.ndarray:
    """World up ``n`` in the camera frame: (..., 3) from pitch and roll (radians, broadcast)."""
    pitch = np.asarray(pitch_rad, dtype=np.float64)
    roll = np.asarray(roll_rad, dtype=np.float64)
    cp = np.cos(pitch)
    return np.stack(np.broadcast_arrays(-np.sin(roll) * cp, -np.cos(roll) * cp, -np.sin(pitch)), axis=-1)


def pitch_roll_from_up(up_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`up_vector_cam`: up_cam (..., 3), any norm -> (pitch_rad, roll_rad)."""
    n = np.asarray(up_cam, dtype=np.float64)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    pitch = np.arcsin(np.clip(-n[..., 2], -1.0, 1.0))
    roll = np.arctan2(-n[..., 0], -n[..., 1])
    return pitch, roll


def intrinsics_matrix(focal_px: float, principal_point: tuple[float, float]) -> np.ndarray:
    """3x3 pinhole matrix K with square pixels and no skew."""
    cx, cy = principal_point
    return np.array([[focal_px, 0.0, cx], [0.0, focal_px, cy], [0.0, 0.0, 1.0]])


def project_cam_to_px(points_cam: np.ndarray, focal_px: np.ndarray | float, principal_point: np.ndarray | tuple) -> np.ndarray:
    """Project camera-frame points (..., 3) to pixels (..., 2); points with z <= 0 give NaN."""
    p = np.asarray(points_cam, dtype=np.float64)
    pp = np.asarray(principal_point, dtype=np.float64)
    f = np.asarray(focal_px, dtype=np.float64)[..., None]
    z = p[..., 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = pp + f * p[..., :2] / z
    return np.where(z > 0, uv, np.nan)


def pixel_rays_cam(points_px: np.ndarray, focal_px: np.ndarray | float, principal_point: np.ndarray | tuple) -> np.ndarray:
    """Viewing rays (..., 3) with z = 1 through pixels (..., 2)."""
    px = np.asarray(points_px, dtype=np.float64)
    pp = np.asarray(principal_point, dtype=np.float64)
    f = np.asarray(focal_px, dtype=np.float64)[..., None]
    xy = (px - pp) / f
    return np.concatenate([xy, np.ones_like(xy[..., :1])], axis=-1)


def backproject_px_to_plane(
    points_px: np.ndarray,
    focal_px: np.ndarray | float,
    principal_point: np.ndarray | tuple,
    up_cam: np.ndarray,
    ground_offset_m: np.ndarray | float,
    plane_height_m: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Intersect pixel rays (..., 2) with the plane ``plane_height_m`` above the ground -> (..., 3).

    Rays that meet the plane behind the camera, or never (parallel), give NaN.
    """
    rays = pixel_rays_cam(points_px, focal_px, principal_point)
    n = np.asarray(up_cam, dtype=np.float64)
    denom = np.sum(rays * n, axis=-1)
    num = np.asarray(plane_height_m, dtype=np.float64) - np.asarray(ground_offset_m, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = num / denom
    s = np.where((np.abs(denom) > _EPS) & (s > 0), s, np.nan)
    return rays * s[..., None]


def height_above_ground(points_cam: np.ndarray, up_cam: np.ndarray, ground_offset_m: np.ndarray | float) -> np.ndarray:
    """Signed height (...,) of camera-frame points (..., 3) above the ground ``n.X + h = 0``."""
    return np.sum(np.asarray(points_cam, dtype=np.float64) * np.asarray(up_cam, dtype=np.float64), axis=-1) + ground_offset_m


def R_cam_from_world_from_up(up_cam: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) whose columns are the world X, Y (= up), Z axes written in the camera frame."""
    y_axis = np.asarray(up_cam, dtype=np.float64)
    y_axis = y_axis / np.linalg.norm(y_axis)
    x_cam = np.array([1.0, 0.0, 0.0])
    x_axis = x_cam - np.dot(x_cam, y_axis) * y_axis
    norm = np.linalg.norm(x_axis)
    if norm < 1e-9:  # camera x axis vertical (roll of +-90 deg): fall back to the optical axis
        z_cam = np.array([0.0, 0.0, 1.0])
        x_axis = np.cross(y_axis, z_cam)
        norm = np.linalg.norm(x_axis)
    x_axis = x_axis / norm
    z_axis = np.cross(x_axis, y_axis)
    return np.stack([x_axis, y_axis, z_axis], axis=1)


def horizon_v_px(u_px: np.ndarray | float, focal_px: float, principal_point: tuple[float, float], up_cam: np.ndarray,
                 distortion: float = 0.0, radius_px: float = 1.0) -> np.ndarray:
    """Image row (px) of the horizon (vanishing line of the ground) at columns ``u_px`` (...,) px.

    A pinhole's horizon is the line ``n . ((p - pp) / f, 1) = 0``. With a division-model lens
    (``distortion`` lam, ``radius_px`` R: :mod:`.lens`) a distorted pixel ``x = p - pp`` is on it when
    ``n_x x_u + n_y y_u + n_z f (1 + lam |x|^2 / R^2) = 0``: a circle, solved exactly for the row (its root
    continuous at lam = 0; NaN where the column does not meet it).

    >>> n = up_vector_cam(0.3, 0.05)
    >>> u = np.array([0.0, 320.0, 640.0])
    >>> v = horizon_v_px(u, 500.0, (320.0, 240.0), n, -0.2, 400.0)   # barrel: the horizon bends
    >>> from .lens import undistort_px
    >>> rays = pixel_rays_cam(undistort_px(np.stack([u, v], -1), -0.2, (320.0, 240.0), 400.0), 500.0, (320.0, 240.0))
    >>> bool(np.allclose(rays @ n, 0.0, atol=1e-12))   # each pixel's ray is level
    True
    """
    n = np.asarray(up_cam, dtype=np.float64)
    cx, cy = principal_point
    u = np.asarray(u_px, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        if distortion == 0.0:
            return cy - (n[0] * (u - cx) + n[2] * focal_px) / n[1]
        # a y^2 + b y + c = 0 in y = v - cy, with x = u - cx
        x = u - cx
        a = n[2] * focal_px * distortion / radius_px**2
        c = a * x * x + n[0] * x + n[2] * focal_px
        b = n[1]
        root = np.sqrt(b * b - 4.0 * a * c)
        return cy + 2.0 * c / (-b - np.copysign(root, b))


def reexpress_cam(points_cam: np.ndarray, roots_cam: np.ndarray, focal_from_px: np.ndarray | float,
                  pp_from: np.ndarray | tuple, focal_to_px: np.ndarray | float, pp_to: np.ndarray | tuple) -> np.ndarray:
    """Bodies made in one camera (``focal_from_px``, ``pp_from``) re-expressed in another, rigidly.

    points_cam: (P, N, 3) per person; roots_cam: (P, 3) each body's root; focals scalar or (P,).
    Each body is translated (never deformed) so its root keeps its pixel and its depth scales by
    ``focal_to / focal_from``, so the body keeps its size in pixels. Returns (P, N, 3) float64.

    >>> body = np.array([[[0.5, 0.2, 10.0], [0.5, -1.5, 10.0]]])
    >>> moved = reexpress_cam(body, body[:, 0], 1000.0, (640.0, 360.0), 2000.0, (640.0, 360.0))
    >>> moved[0].tolist()   # the root's pixel is kept at twice the depth; the body is only moved
    [[0.5, 0.2, 20.0], [0.5, -1.5, 20.0]]
    """
    roots = np.asarray(roots_cam, dtype=np.float64)
    f_from = np.broadcast_to(np.asarray(focal_from_px, dtype=np.float64), roots.shape[:-1])
    f_to = np.broadcast_to(np.asarray(focal_to_px, dtype=np.float64), roots.shape[:-1])
    rays = pixel_rays_cam(project_cam_to_px(roots, f_from, pp_from), f_to, pp_to)
    new_roots = rays * (roots[..., 2] * f_to / f_from)[..., None]
    return np.asarray(points_cam, dtype=np.float64) + (new_roots - roots)[..., None, :]


ROOT_CENTRED_M = 0.5  # a root this near the camera centre is a root-centred body, not a person in view


def people_not_in_front(points_cam: np.ndarray, roots_cam: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Which people (P,) cannot be what the camera saw, from their points (P, N, 3) in the camera frame.

    Returns ``(root_centred, behind)``: the root (``roots_cam`` (P, 3), e.g. the pelvis joint;
    default the mean of the points) lies within 0.5 m of the camera centre (a root-centred output,
    its translation zero or never applied, e.g. AGORA's sample predictions); some of the points are
    at or behind the camera plane (z <= 0). Non-finite points are ignored. Such people cannot be
    calibrated from or aligned; root-aligned metrics (MPJPE, PVE, PA-*) still apply to them.

    >>> pts = np.array([[[0.0, -0.8, 0.1], [0.0, 0.9, -0.1]], [[0.2, -0.8, 5.0], [0.2, 0.9, 5.1]]])
    >>> [v.tolist() for v in people_not_in_front(pts)]
    [[True, False], [True, False]]
    """
    points = np.asarray(points_cam, dtype=np.float64)
    if points.shape[0] == 0 or points.shape[1] == 0:
        return np.zeros(points.shape[0], bool), np.zeros(points.shape[0], bool)
    finite = np.isfinite(points).all(axis=-1)  # (P, N)
    with np.errstate(invalid="ignore"):
        behind = (finite & (points[..., 2] <= 0.0)).any(axis=1)
        if roots_cam is None:
            roots_cam = np.where(finite[..., None], points, 0.0).sum(axis=1) / np.maximum(finite.sum(axis=1), 1)[:, None]
        distance = np.linalg.norm(np.asarray(roots_cam, dtype=np.float64), axis=-1)
    centred = finite.any(axis=1) & (distance < ROOT_CENTRED_M)
    return centred, behind


def world_to_cam(points_world: np.ndarray, R_cam_from_world: np.ndarray, t_cam_from_world: np.ndarray) -> np.ndarray:
    """World points (..., 3) into a camera: ``R_cam_from_world (3, 3) X + t_cam_from_world (3,)`` (metres)
    (a moving camera's pose of one frame; :meth:`Camera.cam_from_world` is a static camera's)."""
    return np.asarray(points_world, dtype=np.float64) @ np.asarray(R_cam_from_world).T + t_cam_from_world


def _read_only(array: np.ndarray) -> np.ndarray:
    """``array`` marked read-only (a cached value shared by every caller)."""
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class Camera:
    """Static camera over a ground plane: a pinhole and a division-model lens (``distortion``, 0 = none;
    :mod:`.lens`); angles in radians, lengths in metres, pixels of the (distorted) image."""

    image_size: tuple[int, int]  # (W, H) px
    focal_px: float
    principal_point: tuple[float, float] = field(default=None)  # (cx, cy) px; None -> image centre
    pitch_rad: float = 0.0  # + = looking down
    roll_rad: float = 0.0
    height_m: float = 1.0  # camera centre above the ground
    distortion: float = 0.0  # division-model coefficient lam (0 = pinhole; |lam| <= 0.5; geometry/lens.py)

    def __post_init__(self) -> None:
        w, h = (int(v) for v in self.image_size)
        object.__setattr__(self, "image_size", (w, h))
        pp = (w / 2.0, h / 2.0) if self.principal_point is None else tuple(float(v) for v in self.principal_point)
        object.__setattr__(self, "principal_point", pp)
        for name in ("focal_px", "pitch_rad", "roll_rad", "height_m"):
            object.__setattr__(self, name, float(getattr(self, name)))
        if not all(math.isfinite(v) for v in (self.focal_px, self.pitch_rad, self.roll_rad, self.height_m, *pp)):
            raise ValueError("camera parameters must be finite")
        if self.focal_px <= 0:
            raise ValueError(f"focal_px must be > 0, got {self.focal_px}")
        object.__setattr__(self, "distortion", check_distortion(self.distortion))
        if w <= 0 or h <= 0:
            raise ValueError(f"image_size must be positive, got {self.image_size}")

    def __getstate__(self) -> dict[str, Any]:
        """Pickle the parameters only: a worker derives its own read-only arrays (unpickled ones are writable)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    # ---- derived quantities ---------------------------------------------------------------
    # The arrays are derived once per camera (a frame-by-frame loop asks for them per frame) and
    # returned read-only, so no caller can change a cached value under another.
    @cached_property
    def K(self) -> np.ndarray:
        """Intrinsics (3, 3)."""
        return _read_only(intrinsics_matrix(self.focal_px, self.principal_point))

    @cached_property
    def up_cam(self) -> np.ndarray:
        """World up ``n`` (3,) in the camera frame."""
        return _read_only(up_vector_cam(self.pitch_rad, self.roll_rad))

    @property
    def ground_offset_m(self) -> float:
        """``h`` in the ground plane ``n.X + h = 0`` (equals the camera height)."""
        return self.height_m

    @cached_property
    def R_cam_from_world(self) -> np.ndarray:
        """Rotation (3, 3): ``X_cam = R_cam_from_world @ X_world + t_cam_from_world``."""
        return _read_only(R_cam_from_world_from_up(self.up_cam))

    @cached_property
    def t_cam_from_world(self) -> np.ndarray:
        """Translation (3,): the world origin (ground below the camera) in the camera frame."""
        return _read_only(-self.height_m * self.up_cam)

    @property
    def center_world(self) -> np.ndarray:
        """Camera centre (3,) in the world frame: (0, h, 0)."""
        return np.array([0.0, self.height_m, 0.0])

    @property
    def lens_radius_px(self) -> float:
        """The lens distortion's unit radius R (px): the image half-diagonal (:func:`.lens.lens_radius_px`)."""
        return lens_radius_px(self.image_size)

    @property
    def pinhole(self) -> "Camera":
        """This camera without its lens (itself when ``distortion`` is 0): the camera whose pixels are this
        one's undistorted pixels (:meth:`undistort_px`)."""
        return self if self.distortion == 0.0 else self.replace(distortion=0.0)

    @property
    def horizontal_fov_rad(self) -> float:
        """Full horizontal field of view of the pinhole (the undistorted image's: ``2 atan(W / 2f)``, lens ignored)."""
        return 2.0 * math.atan(self.image_size[0] / (2.0 * self.focal_px))

    @property
    def vertical_fov_rad(self) -> float:
        """Full vertical field of view of the pinhole (the undistorted image's: ``2 atan(H / 2f)``, lens ignored)."""
        return 2.0 * math.atan(self.image_size[1] / (2.0 * self.focal_px))

    def matches(self, other: object, tol: float = SAME_CAMERA_TOL) -> bool:
        """True when ``other`` is this camera up to float noise: the same image size, and focal, principal point
        and height within ``tol`` relative, pitch, roll within ``tol`` rad and the lens distortion within ``tol``. Two cameras equal but for the
        last bits (one read back from YAML, one re-derived through its matrices) are one camera; ``==`` says
        they differ.

        >>> a = Camera((640, 480), 500.0, None, 0.3, 0.01, 3.0)
        >>> a.matches(Camera((640, 480), 500.0 * (1 + 1e-16), None, 0.3 + 1e-16, 0.01, 3.0)), a.matches(a.replace(height_m=3.001))
        (True, False)
        """
        if not isinstance(other, Camera) or tuple(self.image_size) != tuple(other.image_size):
            return False
        relative = [(self.focal_px, other.focal_px), (self.height_m, other.height_m),
                    *zip(self.principal_point, other.principal_point)]
        return all(math.isclose(a, b, rel_tol=tol, abs_tol=tol) for a, b in relative) and all(
            abs(a - b) <= tol for a, b in ((self.pitch_rad, other.pitch_rad), (self.roll_rad, other.roll_rad),
                                           (self.distortion, other.distortion)))

    # ---- geometry -------------------------------------------------------------------------
    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Camera-frame points (..., 3) -> image pixels (..., 2): the pinhole, then the lens distortion.
        NaN behind the camera, and where the lens has no image of the pinhole pixel (:func:`.lens.distort_px`)."""
        return self.distort_px(project_cam_to_px(points_cam, self.focal_px, self.principal_point))

    def undistort_px(self, points_px: np.ndarray) -> np.ndarray:
        """Image pixels (..., 2) -> the pinhole's (undistorted) pixels (..., 2) float64; unchanged without a lens."""
        if self.distortion == 0.0:
            return np.asarray(points_px, dtype=np.float64)
        return undistort_px(points_px, self.distortion, self.principal_point, self.lens_radius_px)

    def distort_px(self, points_px: np.ndarray) -> np.ndarray:
        """The pinhole's (undistorted) pixels (..., 2) -> image pixels (..., 2) float64; unchanged without a lens."""
        if self.distortion == 0.0:
            return np.asarray(points_px, dtype=np.float64)
        return distort_px(points_px, self.distortion, self.principal_point, self.lens_radius_px)

    def pixel_rays_cam(self, points_px: np.ndarray) -> np.ndarray:
        """Viewing rays (..., 3), camera frame with z = 1, through image pixels (..., 2) (the lens removed first)."""
        return pixel_rays_cam(self.undistort_px(points_px), self.focal_px, self.principal_point)

    def backproject_px_to_ground(self, points_px: np.ndarray, plane_height_m: float | np.ndarray = 0.0) -> np.ndarray:
        """Image pixels (..., 2) -> camera-frame points (..., 3) on the plane at that height (the lens removed
        first); NaN if missed."""
        return backproject_px_to_plane(self.undistort_px(points_px), self.focal_px, self.principal_point, self.up_cam,
                                       self.height_m, plane_height_m)

    def height_above_ground(self, points_cam: np.ndarray) -> np.ndarray:
        """Signed height (...,) of camera-frame points above the ground."""
        return height_above_ground(points_cam, self.up_cam, self.height_m)

    def cam_from_world(self, points_world: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> camera frame."""
        return world_to_cam(points_world, self.R_cam_from_world, self.t_cam_from_world)

    def world_from_cam(self, points_cam: np.ndarray) -> np.ndarray:
        """Camera-frame points (..., 3) -> world frame (float64; :func:`world_points_f32` for meshes stored as float32)."""
        return (np.asarray(points_cam, dtype=np.float64) - self.t_cam_from_world) @ self.R_cam_from_world

    def horizon_v_px(self, u_px: np.ndarray | float) -> np.ndarray:
        """Image row (px) of the horizon at image columns ``u_px``, exact with the lens (:func:`horizon_v_px`)."""
        return horizon_v_px(u_px, self.focal_px, self.principal_point, self.up_cam, self.distortion, self.lens_radius_px)

    # ---- construction ---------------------------------------------------------------------
    @classmethod
    def from_up(cls, image_size: tuple[int, int], focal_px: float, up_cam: np.ndarray, ground_offset_m: float,
                principal_point: tuple[float, float] | None = None) -> "Camera":
        """Camera from an up vector (any norm) and the ground offset ``h``."""
        n = np.asarray(up_cam, dtype=np.float64)
        norm = float(np.linalg.norm(n))
        pitch, roll = pitch_roll_from_up(n)
        return cls(image_size, focal_px, principal_point, float(pitch), float(roll), ground_offset_m / norm)

    @classmethod
    def from_extrinsics(cls, image_size: tuple[int, int], focal_px: float, R_cam_from_world: np.ndarray,
                        t_cam_from_world: np.ndarray, principal_point: tuple[float, float] | None = None) -> "Camera":
        """Camera from world-to-camera extrinsics (world Y = up, ground at Y = 0)."""
        R = np.asarray(R_cam_from_world, dtype=np.float64)
        n = R[:, 1]
        h = -float(np.dot(n, np.asarray(t_cam_from_world, dtype=np.float64)))
        return cls.from_up(image_size, focal_px, n, h, principal_point)

    def replace(self, **changes: Any) -> "Camera":
        """Copy with some fields changed."""
        return dataclasses.replace(self, **changes)


# ---- camera.yaml (the only place the contract's key names meet the code's) ---------------------
_ANGLE_KEYS = ("pitch_deg", "roll_deg")


def camera_parameters(camera: Camera) -> dict[str, float]:
    """The four scene parameters in report units: focal_px, pitch_deg, roll_deg, height_m (plain floats).

    >>> camera_parameters(Camera((640, 480), 500.0, None, np.deg2rad(20.0), 0.0, 5.0))
    {'focal_px': 500.0, 'pitch_deg': 20.0, 'roll_deg': 0.0, 'height_m': 5.0}
    """
    return {"focal_px": float(camera.focal_px), "pitch_deg": float(np.rad2deg(camera.pitch_rad)),
            "roll_deg": float(np.rad2deg(camera.roll_rad)), "height_m": float(camera.height_m)}


def camera_to_yaml_dict(camera: Camera, fit: dict | None = None) -> dict:
    """Plain-typed dict in the ``camera.yaml`` schema of docs/conventions.md (degrees, metres, lists); the lens's
    ``distortion`` only when it is not 0 (a pinhole's file is what it always was).

    >>> list(camera_to_yaml_dict(Camera((640, 480), 500.0, None, 0.3, 0.0, 3.0, distortion=-0.1)))[-2:]
    ['t_world_to_cam', 'distortion']
    """
    params = camera_parameters(camera)
    d: dict[str, Any] = {
        "image_size": [int(v) for v in camera.image_size],
        "focal_px": params["focal_px"],
        "principal_point": [float(v) for v in camera.principal_point],
        "pitch_deg": params["pitch_deg"],
        "roll_deg": params["roll_deg"],
        "height_m": params["height_m"],
        "up_cam": [float(v) for v in camera.up_cam],
        "ground_offset_m": float(camera.ground_offset_m),
        "R_world_to_cam": [[float(v) for v in row] for row in camera.R_cam_from_world],
        "t_world_to_cam": [float(v) for v in camera.t_cam_from_world],
    }
    if camera.distortion != 0.0:
        d["distortion"] = float(camera.distortion)
    if fit:
        d["fit"] = fit
    return d


def _floats(value: Any, shape: tuple[int, ...], key: str) -> np.ndarray:
    """Validate a YAML value as a finite float array of the given shape."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"key '{key}' must be numeric, got {value!r}") from None
    if arr.shape != shape:
        raise ValueError(f"key '{key}' must have shape {list(shape) or 'scalar'}, got {list(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"key '{key}' has non-finite values")
    return arr


def camera_from_yaml_dict(d: dict, image_size: tuple[int, int] | None = None) -> Camera:
    """Camera from a ``camera.yaml`` dict: pitch/roll/height, else up_cam/ground_offset_m, else R/t; the lens from
    ``distortion``, else (a file of an earlier version) the fitted ``fit.distortion``, else none.

    Raises ValueError naming the key when something is missing, misshaped, inconsistent or out of range.

    >>> camera_from_yaml_dict({"image_size": [640, 480], "focal_px": 500.0, "pitch_deg": 10.0, "height_m": 3.0,
    ...                        "fit": {"distortion": -0.05}}).distortion
    -0.05
    """
    if not isinstance(d, dict):
        raise ValueError("camera file must hold a mapping")
    if "image_size" in d:
        size = _floats(d["image_size"], (2,), "image_size")
        image_size = (int(size[0]), int(size[1]))
    if image_size is None:
        raise ValueError("key 'image_size' is missing")
    if "focal_px" not in d:
        raise ValueError("key 'focal_px' is missing")
    focal = float(_floats(d["focal_px"], (), "focal_px"))
    pp = tuple(_floats(d["principal_point"], (2,), "principal_point")) if d.get("principal_point") is not None else None
    if all(k in d for k in ("pitch_deg", "height_m")):
        pitch = np.deg2rad(float(_floats(d["pitch_deg"], (), "pitch_deg")))
        roll = np.deg2rad(float(_floats(d.get("roll_deg", 0.0), (), "roll_deg")))
        cam = Camera(image_size, focal, pp, pitch, roll, float(_floats(d["height_m"], (), "height_m")))
    elif "up_cam" in d and "ground_offset_m" in d:
        cam = Camera.from_up(image_size, focal, _floats(d["up_cam"], (3,), "up_cam"),
                             float(_floats(d["ground_offset_m"], (), "ground_offset_m")), pp)
    elif "R_world_to_cam" in d and "t_world_to_cam" in d:
        cam = Camera.from_extrinsics(image_size, focal, _floats(d["R_world_to_cam"], (3, 3), "R_world_to_cam"),
                                     _floats(d["t_world_to_cam"], (3,), "t_world_to_cam"), pp)
    else:
        raise ValueError("needs pitch_deg and height_m (or up_cam and ground_offset_m, or R_world_to_cam and t_world_to_cam)")
    if "up_cam" in d:
        up = _floats(d["up_cam"], (3,), "up_cam")
        if np.linalg.norm(up / np.linalg.norm(up) - cam.up_cam) > 1e-4:
            raise ValueError("key 'up_cam' disagrees with pitch_deg/roll_deg")
    if cam.height_m <= 0:
        raise ValueError(f"camera height must be > 0 (camera above the ground), got {cam.height_m}")
    check_camera_bounds(cam)
    distortion = _yaml_distortion(d)
    return cam if distortion == 0.0 else cam.replace(distortion=distortion)


def _yaml_distortion(d: dict) -> float:
    """The lens coefficient of a camera.yaml dict: ``distortion``, else the legacy ``fit.distortion`` (calibrate
    wrote only that before the camera carried its lens; null there: not fitted), else 0. ValueError naming the key
    when it is not a finite number within +-0.5. A mapping under ``distortion`` describes another lens model (the
    real-data answer keys carry an OpenCV ``{model: opencv_k1_k2_p1_p2, params: ...}``): not read, a pinhole."""
    if isinstance(d.get("distortion"), dict):
        return 0.0
    if d.get("distortion") is not None:
        return check_distortion(d["distortion"], "distortion")
    fit = d.get("fit")
    if isinstance(fit, dict) and fit.get("distortion") is not None:
        return check_distortion(fit["distortion"], "fit.distortion")
    return 0.0


def check_camera_bounds(cam: Camera) -> None:
    """ValueError naming the key when a camera is out of every real camera's range (image size, focal,
    principal point within the image's reach, height)."""
    W, H = cam.image_size
    if max(W, H) > MAX_IMAGE_SIDE_PX:
        raise ValueError(f"key 'image_size' {[W, H]} is beyond {MAX_IMAGE_SIDE_PX} px")
    if cam.focal_px > MAX_FOCAL_PX:
        raise ValueError(f"key 'focal_px' {cam.focal_px:g} is beyond {MAX_FOCAL_PX:g} px")
    cx, cy = cam.principal_point
    if not (-W <= cx <= 2 * W and -H <= cy <= 2 * H):
        raise ValueError(f"key 'principal_point' [{cx:g}, {cy:g}] is far outside the {W}x{H} image")
    if cam.height_m > MAX_HEIGHT_M:
        raise ValueError(f"key 'height_m' {cam.height_m:g} is beyond {MAX_HEIGHT_M:g} m")


def world_points_f32(camera: Camera, points_cam: np.ndarray) -> np.ndarray:
    """Camera-frame points (..., 3) -> world frame in float32, what a recording or a glTF stores (0.1 mm at 1 km):
    about twice as fast as :meth:`Camera.world_from_cam` on a crowd's meshes."""
    R = np.asarray(camera.R_cam_from_world, dtype=np.float32)
    t = np.asarray(camera.t_cam_from_world, dtype=np.float32)
    return (np.asarray(points_cam, dtype=np.float32) - t) @ R
