"""Synthetic static-camera scenes: ground truth plus an "HPS prediction" with the paper's failures.

Ground truth: upright people of varied stature (mean 1.70 m, sd 0.07 m) walking on the ground
of a random surveillance camera (horizontal field of view 45-100 deg). Prediction: the same
people as an HPS method returns them, right from the camera's view but wrong in the world: each
body leans toward the image plane (keeping its foot and crown pixels), has a near-average size,
a per-person depth error, and lives in the method's own assumed camera: a real method's focal
rule (``hps_focal``: ``cliff``, ``bev``, ``romp``, ``4dhumans``, ``true`` or a number of pixels)
puts the rigid, undistorted body with its root on the root pixel's ray at the depth scaled by
``F / f`` (:func:`rotavat_cli.camera.reexpress_cam`), turned so its foot and crown fall on their
pixels, as a method fitted to the image draws them. Plus small 3D noise and noisy 2D detections
with gross outliers. Deterministic for a given seed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..alignment.transform import closest_scale_on_line
from ..atomic import staged_directory
from ..camera import MAX_IMAGE_SIDE_PX, Camera, camera_parameters, pixel_rays_cam, reexpress_cam
from ..focal import ASSUMED, CAMERA, FOCAL_RULES, focal_from_rule
from ..landmarks import foot_head_points
from ..outputs import check_output_dir
from ..rotations import axis_angle_to_matrix, rotation_between
from ..sequence import Frame, write_camera_yaml, write_frame, write_meta, write_yaml
from .bodies import BodyLibrary, load_bodies

__all__ = ["SynthOptions", "HPS_FOCAL_CHOICES", "random_camera", "hps_focal_px", "sample_walks", "synth_frames",
           "write_synth_scene"]

FPS = 5.0  # frames per second of the synthetic video
WALK_SPEED_MPS = (0.8, 1.6)  # walking speeds
MAX_GROUND_DISTANCE_M = 45.0  # people farther than this are too small to matter
HFOV_RANGE_DEG = (45.0, 100.0)  # horizontal fields of view of real surveillance lenses
HPS_FOCAL_CHOICES = (*FOCAL_RULES, "true")  # or a number of pixels


@dataclass(frozen=True)
class SynthOptions:
    """Everything ``rotavat synth`` can vary (defaults live in configs/default.yaml)."""

    seed: int = 0
    frames: int = 20
    people: int = 8
    image_size: tuple[int, int] = (1280, 720)
    roll_deg: float | None = None  # None: random in [-3, 3]
    noise_px: float = 2.0
    outliers: float = 0.0
    hps_focal: str | float = "cliff"  # a focal rule (HPS_FOCAL_CHOICES), "true", or a number of pixels
    depth_sd: float = 0.1
    lean: float = 0.7
    stature_sd_m: float = 0.07
    pred_stature_sd_m: float = 0.03
    noise_3d_m: float = 0.005

    @classmethod
    def from_config(cls, section: dict) -> "SynthOptions":
        """Options from the ``synth`` config section (its keys are the fields; the rest keep their defaults)."""
        values = {**section, "image_size": tuple(section["image_size"])}
        return cls(**values)

    def __post_init__(self) -> None:
        width, height = self.image_size
        if not (32 <= int(width) <= MAX_IMAGE_SIDE_PX and 32 <= int(height) <= MAX_IMAGE_SIDE_PX):
            raise ValueError(f"--image-size (image_size) must be two sizes of 32 to {MAX_IMAGE_SIDE_PX} px, got "
                             f"{list(self.image_size)}")
        if self.frames < 1 or self.people < 0:
            raise ValueError(f"frames must be >= 1 and people >= 0, got {self.frames} and {self.people}")


def random_camera(rng: np.random.Generator, image_size: tuple[int, int], roll_deg: float | None = None,
                  roll_max_deg: float = 3.0) -> Camera:
    """Realistic surveillance camera: horizontal field of view 45-100 deg, pitch 10-60 deg, height
    2.5-15 m; roll given or +-max."""
    W = image_size[0]
    roll = rng.uniform(-roll_max_deg, roll_max_deg) if roll_deg is None else roll_deg
    hfov = np.deg2rad(rng.uniform(*HFOV_RANGE_DEG))
    return Camera(image_size, W / (2.0 * np.tan(hfov / 2.0)), None, np.deg2rad(rng.uniform(10.0, 60.0)),
                  np.deg2rad(roll), rng.uniform(2.5, 15.0))


def hps_focal_px(spec: str | float, camera: Camera) -> tuple[float, str]:
    """The focal (px) an HPS method assumes for this camera's images, and the rule's name.

    spec: a rule of :data:`rotavat_cli.focal.FOCAL_RULES`, ``"true"`` (the camera's own focal),
    or a number of pixels (given as a number or a numeric string). Raises ValueError otherwise.
    """
    if isinstance(spec, str) and spec in FOCAL_RULES:
        return focal_from_rule(spec, camera.image_size), spec
    if spec == "true":
        return float(camera.focal_px), "true"
    try:
        value = float(spec)
    except (TypeError, ValueError):
        raise ValueError(f"hps_focal must be one of {', '.join(HPS_FOCAL_CHOICES)} or a number of pixels, "
                         f"got {spec!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"hps_focal must be a positive number of pixels, got {spec!r}")
    return value, "number"


def _in_view(camera: Camera, ground_world: np.ndarray, stature_m: float = 1.9) -> np.ndarray:
    """Ground points (..., 3) whose foot and head (at ``stature_m``) project well inside the image."""
    W, H = camera.image_size
    foot_px = camera.project(camera.cam_from_world(ground_world))
    head_px = camera.project(camera.cam_from_world(ground_world + np.array([0.0, stature_m, 0.0])))
    with np.errstate(invalid="ignore"):
        ok = (foot_px[..., 0] > 0.04 * W) & (foot_px[..., 0] < 0.96 * W) & (foot_px[..., 1] < 0.97 * H)
        ok &= (head_px[..., 1] > 0.03 * H) & (head_px[..., 0] > 0.02 * W) & (head_px[..., 0] < 0.98 * W)
    return ok & (np.linalg.norm(ground_world[..., [0, 2]], axis=-1) < MAX_GROUND_DISTANCE_M)


def _sample_ground_points(rng: np.random.Generator, camera: Camera, n: int) -> np.ndarray:
    """n ground points (n, 3) world frame, uniform over the visible image region."""
    W, H = camera.image_size
    found = np.zeros((0, 3))
    for _ in range(200):
        px = np.stack([rng.uniform(0, W, 64 * n), rng.uniform(0, H, 64 * n)], axis=-1)
        ground = camera.world_from_cam(camera.backproject_px_to_ground(px))
        keep = np.all(np.isfinite(ground), axis=-1)
        keep[keep] = _in_view(camera, ground[keep])
        found = np.concatenate([found, ground[keep]])
        if len(found) >= n:
            return found[:n]
    raise ValueError("this camera sees almost no ground where people fit in the image")


def sample_walks(rng: np.random.Generator, camera: Camera, n_people: int, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Back-and-forth walks: ground positions (T, P, 3) world frame and headings (T, P) rad."""
    start = _sample_ground_points(rng, camera, n_people)
    end = _sample_ground_points(rng, camera, n_people)
    seg = end - start
    length = np.maximum(np.linalg.norm(seg, axis=-1), 1e-6)
    speed = rng.uniform(*WALK_SPEED_MPS, n_people)
    phase0 = rng.uniform(0.0, 2.0, n_people)
    t = np.arange(n_frames)[:, None] / FPS
    phase = (phase0 + t * speed / length) % 2.0  # (T, P): 0..1 forward, 1..2 back
    frac = np.where(phase < 1.0, phase, 2.0 - phase)
    pos = start + frac[..., None] * seg
    forward = np.where(phase < 1.0, 1.0, -1.0)[..., None] * seg / length[:, None]
    heading = np.arctan2(forward[..., 0], forward[..., 2])  # yaw about +Y taking +Z to the walk direction
    return pos, heading


def _pose_bodies(library: BodyLibrary, body_index: np.ndarray, scale: np.ndarray, heading: np.ndarray,
                 pos_world: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Scaled, turned, placed bodies in the camera frame: vertices (P, V, 3), joints (P, 24, 3)."""
    R_world_from_body = axis_angle_to_matrix(np.array([0.0, 1.0, 0.0]), heading)  # (P, 3, 3)
    R = np.einsum("ij,pjk->pik", camera.R_cam_from_world, R_world_from_body)
    t = camera.cam_from_world(pos_world)  # (P, 3)
    verts = np.einsum("pij,pvj->pvi", R, library.vertices[body_index] * scale[:, None, None]) + t[:, None]
    joints = np.einsum("pij,pvj->pvi", R, library.joints[body_index] * scale[:, None, None]) + t[:, None]
    return verts, joints


def _lean_toward_image_plane(points: list[np.ndarray], feet: np.ndarray, heads: np.ndarray, fraction: np.ndarray) -> list[np.ndarray]:
    """Lean bodies toward the image plane while keeping their foot and crown pixels.

    Each body's axis turns, in the plane of the camera centre and the axis, by ``fraction`` of the
    angle between the axis and the image plane (the failure the paper shows); the rigidly turned
    body is then slid inside that plane so its foot and crown stay on their camera rays, as an
    HPS fit to the image would place it.
    """
    centre = 0.5 * (feet + heads)
    axis = heads - feet
    length = np.linalg.norm(axis, axis=-1)
    sight = centre / np.linalg.norm(centre, axis=-1, keepdims=True)
    normal = np.cross(sight, axis)  # rotating about it keeps the axis in the camera-axis plane
    tilt = np.arcsin(np.clip(np.sum(axis * sight, axis=-1) / length, -1.0, 1.0))
    R = axis_angle_to_matrix(normal, fraction * tilt)  # brings the axis toward perpendicular-to-sight
    new_axis = np.einsum("pij,pj->pi", R, axis)
    foot_ray = feet / np.linalg.norm(feet, axis=-1, keepdims=True)
    # new foot a * foot_ray such that new foot + new_axis lies on the crown ray
    new_feet = closest_scale_on_line(new_axis, foot_ray, heads)[:, None] * foot_ray
    return [new_feet[:, None] + np.einsum("pij,pnj->pni", R, p - feet[:, None]) for p in points]


def _into_hps_camera(points: list[np.ndarray], roots: np.ndarray, feet_px: np.ndarray, heads_px: np.ndarray,
                     size_ratio: np.ndarray, depth_scale: np.ndarray, camera: Camera,
                     hps_focal: float) -> list[np.ndarray]:
    """Bodies as the HPS method places them in its own camera (focal ``hps_focal``).

    Scaled about the camera centre by size x depth error (pixels kept), rigidly re-expressed in
    the method's camera (root pixel kept, depth x F / f), then turned and slid, rigidly, so the
    foot and crown fall on the pixels ``feet_px``/``heads_px`` (P, 2) again, as a method fitted to
    the image puts them: at F / f of 20 or more a body re-expressed alone is seen nearly
    orthographically, and its foot and crown would move by 10 % of its height in the picture.
    """
    scale = (size_ratio * depth_scale)[:, None, None]
    scaled_roots = roots * scale[:, 0]
    moved = [reexpress_cam(p * scale, scaled_roots, camera.focal_px, camera.principal_point, hps_focal,
                           camera.principal_point) for p in points]
    feet, heads = foot_head_points(moved[0])
    rays = [pixel_rays_cam(px, hps_focal, camera.principal_point) for px in (feet_px, heads_px)]
    return _onto_rays(moved, feet, heads, *rays)


def _onto_rays(points: list[np.ndarray], feet: np.ndarray, heads: np.ndarray, foot_rays: np.ndarray,
               head_rays: np.ndarray) -> list[np.ndarray]:
    """Rigid bodies (P, N, 3) turned and slid so foot and crown (P, 3) lie on their rays (P, 3), z = 1.

    The new foot ``a rF`` and crown ``b rH`` keep the body's length and its foot-crown midpoint
    depth (``a + b = 2 z_mid``: a quadratic in ``a``, the root nearer the old foot depth); the
    body turns by the shortest rotation taking its old axis to the new one. A person for whom no
    such placement exists keeps its place.
    """
    length = np.linalg.norm(heads - feet, axis=-1)
    z_mid = 0.5 * (feet[:, 2] + heads[:, 2])
    d, e = 2.0 * z_mid[:, None] * head_rays, -(head_rays + foot_rays)  # crown - foot = d + a e
    qa, qb, qc = np.sum(e * e, -1), np.sum(d * e, -1), np.sum(d * d, -1) - length**2
    disc = qb * qb - qa * qc
    ok = disc >= 0
    roots = (-qb[:, None] + np.array([-1.0, 1.0]) * np.sqrt(np.maximum(disc, 0.0))[:, None]) / qa[:, None]
    a = roots[np.arange(len(roots)), np.argmin(np.abs(roots - feet[:, 2:3]), axis=1)]
    new_feet = np.where(ok[:, None], a[:, None] * foot_rays, feet)
    new_heads = np.where(ok[:, None], (2.0 * z_mid - a)[:, None] * head_rays, heads)
    axis, angle = rotation_between(heads - feet, new_heads - new_feet)
    R = axis_angle_to_matrix(axis, angle)
    return [new_feet[:, None] + np.einsum("pij,pnj->pni", R, p - feet[:, None]) for p in points]


def _detections(rng: np.random.Generator, feet_px: np.ndarray, heads_px: np.ndarray, opts: SynthOptions) -> tuple[np.ndarray, np.ndarray]:
    """Noisy 2D foot/head detections with a fraction of gross outliers (sitting, cropped, children)."""
    P = len(feet_px)
    feet = feet_px + rng.normal(0.0, opts.noise_px, (P, 2))
    heads = heads_px + rng.normal(0.0, opts.noise_px, (P, 2))
    bad = rng.random(P) < opts.outliers
    kind = rng.integers(0, 3, P)
    body = heads_px - feet_px
    heads = np.where((bad & (kind == 0))[:, None], feet_px + body * rng.uniform(0.55, 0.75, (P, 1)), heads)  # sitting
    feet = np.where((bad & (kind == 1))[:, None], feet_px + body * rng.uniform(0.25, 0.5, (P, 1)), feet)  # cropped
    heads = np.where((bad & (kind == 2))[:, None], feet_px + body * rng.uniform(1.2, 1.5, (P, 1))
                     + rng.normal(0.0, 0.1, (P, 2)) * np.abs(body[:, 1:2]), heads)  # mis-detected
    return feet, heads


def synth_frames(opts: SynthOptions, library: BodyLibrary | None = None) -> tuple[Camera, float, Iterator[tuple[Frame, Frame]]]:
    """True camera, the HPS focal, and an iterator of (gt frame, pred frame)."""
    library = library or load_bodies()
    rng = np.random.default_rng(opts.seed)
    camera = random_camera(rng, opts.image_size, opts.roll_deg)
    hps_focal, _ = hps_focal_px(opts.hps_focal, camera)
    P = opts.people
    pos, heading = sample_walks(rng, camera, P, opts.frames)
    body_index = rng.integers(0, len(library), P)
    stature = np.clip(rng.normal(1.70, opts.stature_sd_m, P), 1.45, 2.05)
    scale = stature / library.stature_m[body_index]
    pred_size = np.clip(rng.normal(1.70, opts.pred_stature_sd_m, P), 1.55, 1.85) / stature
    lean = np.clip(rng.normal(opts.lean, 0.15, P), 0.0, 1.0) if opts.lean > 0 else np.zeros(P)
    ids = np.arange(P, dtype=np.int64)
    faces = library.faces.astype(np.int32)

    def frames() -> Iterator[tuple[Frame, Frame]]:
        for t in range(opts.frames):
            verts, joints = _pose_bodies(library, body_index, scale, heading[t], pos[t], camera)
            feet, heads = foot_head_points(verts)
            feet_px, heads_px = camera.project(feet), camera.project(heads)
            kp_px = camera.project(joints)
            common = {"faces": faces, "person_ids": ids, "image_size": np.array(camera.image_size, dtype=np.int64)}
            gt = Frame(f"{t:06d}", {
                "vertices": verts.astype(np.float32), "joints": joints.astype(np.float32),
                "feet_2d": feet_px, "heads_2d": heads_px,
                "keypoints_2d": np.concatenate([kp_px, np.ones(kp_px.shape[:2] + (1,))], axis=-1),
                "focal_length": np.float64(camera.focal_px), **common})
            v_pred, j_pred = _lean_toward_image_plane([verts, joints], feet, heads, lean)
            depth = np.exp(rng.normal(0.0, opts.depth_sd, P))
            v_pred, j_pred = _into_hps_camera([v_pred, j_pred], j_pred[:, 0], feet_px, heads_px, pred_size, depth,
                                              camera, hps_focal)
            v_pred = v_pred + rng.normal(0.0, opts.noise_3d_m, v_pred.shape)
            j_pred = j_pred + rng.normal(0.0, opts.noise_3d_m, j_pred.shape)
            det_feet, det_heads = _detections(rng, feet_px, heads_px, opts)
            kp_noisy = kp_px + rng.normal(0.0, opts.noise_px, kp_px.shape)
            pred = Frame(f"{t:06d}", {
                "vertices": v_pred.astype(np.float32), "joints": j_pred.astype(np.float32),
                "feet_2d": det_feet, "heads_2d": det_heads,
                "keypoints_2d": np.concatenate([kp_noisy, np.ones(kp_px.shape[:2] + (1,))], axis=-1),
                "focal_length": np.float64(hps_focal), **common})
            yield gt, pred

    return camera, hps_focal, frames()


def write_synth_scene(out: str | Path, opts: SynthOptions, progress: Callable[[], None] | None = None,
                      force: bool = False) -> dict:
    """Write ``out/gt`` (truth + camera.yaml) and ``out/pred`` (the HPS prediction); returns a summary.

    ``out`` is built aside and swapped in whole: an existing ``out`` is replaced only when it is
    empty or rotavat's own output, or with ``force`` (never a mix of old and new frames).
    """
    out = Path(out)
    check_output_dir(out, [], force)
    camera, hps_focal, frames = synth_frames(opts)
    with staged_directory(out, "synth") as stage:
        summary = _write_scene(stage, camera, hps_focal, frames, opts, progress)
    return {**summary, "out": str(out), "gt": str(out / "gt"), "pred": str(out / "pred")}


def _write_scene(out: Path, camera: Camera, hps_focal: float, frames: Iterator[tuple[Frame, Frame]],
                 opts: SynthOptions, progress: Callable[[], None] | None) -> dict:
    """The files of a synthetic scene in ``out``; returns the summary."""
    for gt, pred in frames:
        write_frame(out / "gt", gt, "npz")
        write_frame(out / "pred", pred, "npz")
        if progress:
            progress()
    size = [int(v) for v in camera.image_size]
    _, rule = hps_focal_px(opts.hps_focal, camera)
    write_meta(out / "gt", {"image_size": size, "focal_length": float(camera.focal_px), "focal_kind": CAMERA,
                            "source": "rotavat-synth", "fps": FPS})
    pred_meta = {"image_size": size, "focal_length": hps_focal, "focal_kind": CAMERA if rule == "true" else ASSUMED}
    if rule in FOCAL_RULES:
        pred_meta["focal_rule"] = rule
    write_meta(out / "pred", {**pred_meta, "source": "rotavat-synth", "fps": FPS})
    write_camera_yaml(out / "gt" / "camera.yaml", camera)
    params = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(opts).items()}
    write_yaml(out / "synth.yaml", params)
    return {"out": str(out), "gt": str(out / "gt"), "pred": str(out / "pred"), "frames": opts.frames,
            "people": opts.people, "camera": camera_parameters(camera),
            "hps_focal_px": hps_focal, "hps_focal_rule": rule}
