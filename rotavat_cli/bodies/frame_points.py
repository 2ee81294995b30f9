"""Where each person of a frame stands and how tall it is drawn: the foot points (the ground contact:
:func:`rotavat_cli.bodies.landmarks.ground_contact`) and crown points (P, 3)
in the method's camera frame, and the intrinsics the frame's meshes were made with.

Calibration (its evidence of who stands), alignment (what it re-seats) and rendering (the tracks
plot) take the same points from here: the mesh landmarks (:mod:`rotavat_cli.bodies.landmarks`), or for a
joints-only frame its 2D foot point and crown back-projected to the joints' depth.

Who is in view is decided here too, once for every command: a foot or crown pixel outside the image or
within :func:`edge_margin_px` of its border (:func:`in_view`) is not seen whole, and a person whose foot
or crown is not seen is neither a calibration pair nor re-seated by align.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera, pixel_rays_cam, project_cam_to_px
from ..errors import InputError
from .landmarks import foot_head_points
from ..sequence import Frame, Intrinsics, can_align

__all__ = ["EDGE_MARGIN_FRACTION", "EDGE_MARGIN_MIN_PX", "MeshIntrinsics", "beyond_border_px", "edge_margin_px", "in_view",
           "joints_foot_head_cam", "frame_foot_head_cam"]

# A point this close to the image's border is not seen whole: a foot at the last row may be a cut leg, a detector's
# keypoint clamped to the border, or a sole half outside. Half a percent of the shorter side (5 px at 1080), at least 2.
EDGE_MARGIN_FRACTION = 0.005
EDGE_MARGIN_MIN_PX = 2.0


def edge_margin_px(image_size: tuple[int, int]) -> float:
    """The border band (px) of an image of ``image_size (W, H)`` where a foot or crown is not seen whole."""
    return max(EDGE_MARGIN_MIN_PX, EDGE_MARGIN_FRACTION * min(image_size))


def in_view(points_px: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(...) bool: pixels (..., 2) inside the image by more than :func:`edge_margin_px` (NaN: not in view).

    >>> in_view(np.array([[100.0, 100.0], [100.0, 1078.0], [-3.0, 50.0], [np.nan, 5.0]]), (1920, 1080)).tolist()
    [True, False, False, False]
    """
    m = edge_margin_px(image_size)
    p = np.asarray(points_px, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return (p[..., 0] >= m) & (p[..., 0] <= image_size[0] - m) & (p[..., 1] >= m) & (p[..., 1] <= image_size[1] - m)


def beyond_border_px(points_px: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(...) px: how far pixels (..., 2) lie beyond the image's nearest border (negative: inside, by that much);
    inf for non-finite pixels."""
    p = np.asarray(points_px, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        beyond = np.max(np.stack([-p[..., 0], p[..., 0] - image_size[0], -p[..., 1], p[..., 1] - image_size[1]]),
                        axis=0)
    return np.where(np.isfinite(beyond), beyond, np.inf)


@dataclass(frozen=True)
class MeshIntrinsics:
    """The intrinsics a frame's meshes were made with: focal per person (P,) px and principal point px."""

    focal_px: np.ndarray  # (P,)
    principal_point: tuple[float, float]

    @classmethod
    def of_frame(cls, frame: Frame, intrinsics: Intrinsics | None, camera: Camera) -> "MeshIntrinsics":
        """From a frame's stated intrinsics; what is not stated is the camera's (meshes assumed made in it)."""
        focals = None if intrinsics is None else intrinsics.focals_px(frame.n_people)
        pp = None if intrinsics is None else intrinsics.principal_point
        return cls(np.full(frame.n_people, camera.focal_px) if focals is None else focals,
                   camera.principal_point if pp is None else pp)

    def same_as(self, camera: Camera) -> bool:
        """True when every person's mesh was made in the camera's own intrinsics: its focal, its principal point
        and no lens (a method's camera is a pinhole: through a camera with ``distortion`` the pixels it drew see
        other rays, :meth:`Camera.pixel_rays_cam`)."""
        return (camera.distortion == 0.0 and bool(np.all(self.focal_px == camera.focal_px))
                and tuple(self.principal_point) == tuple(camera.principal_point))


_FOOT_JOINTS_RADIUS = 0.15  # joints drawn within this fraction of the foot-crown pixel distance are the foot's


def joints_foot_head_cam(joints_cam: np.ndarray, feet_px: np.ndarray, heads_px: np.ndarray,
                         mesh: MeshIntrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Foot and crown points (P, 3) of joints-only people: their pixels (P, 2), drawn in the
    method's intrinsics, back-projected to the depth of the joints drawn there.

    A person with joints but no mesh has no landmark vertices; the tool's own 2D keypoints give
    the pixels of the foot point and crown (``feet_2d``/``heads_2d``, rotavat_cli.formats.keypoints)
    and the joints their depth: the mean depth of the joints drawn within 15% of the foot-crown
    pixel distance of the foot (ankles and toes, whatever the layout), and the depth of the joint
    drawn nearest the crown (the head). Against the mesh landmarks of synthetic walkers 5-8 m
    away this puts the foot point within 2.1 cm and the crown within 5.2 cm of their depth
    (tests/test_align.py). NaN for people without finite inputs.
    """
    focal = mesh.focal_px.astype(np.float64)
    joints = np.asarray(joints_cam, dtype=np.float64)
    feet_px, heads_px = (np.asarray(p, dtype=np.float64) for p in (feet_px, heads_px))
    drawn = project_cam_to_px(joints, focal[:, None], mesh.principal_point)  # (P, J, 2)
    with np.errstate(invalid="ignore"):
        to_foot = np.linalg.norm(drawn - feet_px[:, None], axis=-1)  # (P, J)
        to_head = np.linalg.norm(drawn - heads_px[:, None], axis=-1)
        radius = _FOOT_JOINTS_RADIUS * np.linalg.norm(heads_px - feet_px, axis=-1)
    to_foot[~np.isfinite(to_foot)] = np.inf
    to_head[~np.isfinite(to_head)] = np.inf
    near_foot = (to_foot <= radius[:, None]) | (to_foot == to_foot.min(axis=1, keepdims=True))
    depth = np.where(near_foot, joints[..., 2], 0.0).sum(axis=1) / near_foot.sum(axis=1)
    foot_depth = np.where(np.isfinite(to_foot.min(axis=1)), depth, np.nan)
    head_depth = np.take_along_axis(joints[..., 2], to_head.argmin(axis=1)[:, None], axis=1)[:, 0]
    head_depth[~np.isfinite(to_head.min(axis=1))] = np.nan
    return (pixel_rays_cam(feet_px, focal, mesh.principal_point) * foot_depth[:, None],
            pixel_rays_cam(heads_px, focal, mesh.principal_point) * head_depth[:, None])


def frame_foot_head_cam(frame: Frame, mesh: MeshIntrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Foot and crown points (P, 3) in the method's camera frame: the mesh landmarks, or for a
    frame without meshes its joints with ``feet_2d``/``heads_2d`` (:func:`joints_foot_head_cam`)."""
    if not can_align(frame):
        raise InputError(f"{frame.source}: align needs 'vertices' (meshes), or 'joints' with 'feet_2d' and "
                         "'heads_2d' (joint-level alignment), in every frame with people")
    if frame.get("vertices") is not None:
        return foot_head_points(frame.data["vertices"])
    return joints_foot_head_cam(frame.data["joints"], frame.data["feet_2d"], frame.data["heads_2d"], mesh)
