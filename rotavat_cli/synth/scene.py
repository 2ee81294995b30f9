"""Synthetic static-camera scenes: ground truth plus an "HPS prediction" with the paper's failures.

Ground truth: upright people of varied stature (mean 1.70 m, sd 0.07 m) walking on the ground
of a random surveillance camera (horizontal field of view 45-100 deg). Prediction: the same
people as an HPS method returns them, right from the camera's view but wrong in the world: each
body leans toward the image plane (keeping its foot and crown pixels), has a near-average size,
a per-person depth error, and lives in the method's own assumed camera: a real method's focal
rule (``hps_focal``: ``cliff``, ``bev``, ``romp``, ``4dhumans``, ``true`` or a number of pixels)
puts the rigid, undistorted body with its root on the root pixel's ray at the depth scaled by
``F / f`` (:func:`rotavat_cli.geometry.camera.reexpress_cam`), turned so its foot and crown fall on their
pixels, as a method fitted to the image draws them. Plus small 3D noise and noisy 2D detections
with gross outliers. Deterministic for a given seed.

Where the people stand is the ``layout`` (:mod:`.layouts`): a crowd walking all over the ground
(the default), one or more people walking across the view at one depth, or a group photo (a row
at one depth, still). The random camera's height and pitch ranges are options too (a handheld
camera: 1.2-2 m, -5..15 deg).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from typing import ClassVar
from pathlib import Path

import numpy as np

from ..alignment.transform import closest_scale_on_line
from ..files.atomic import staged_directory
from ..geometry.camera import MAX_HEIGHT_M, MAX_IMAGE_SIDE_PX, Camera, camera_parameters, pixel_rays_cam, reexpress_cam
from ..geometry.focal import ASSUMED, CAMERA, FOCAL_RULES, focal_from_rule
from ..bodies.landmarks import foot_head_points
from ..settings.option_rules import Rule, check_fields
from ..files.outputs import check_output_dir
from ..geometry.rotations import axis_angle_to_matrix, rotation_between
from ..sequence import Frame, write_camera_yaml, write_frame, write_meta
from ..files.yaml_io import write_yaml
from .bodies import BodyLibrary, load_bodies
from .layouts import FPS, LAYOUTS, place_people, sample_walks

__all__ = ["SynthOptions", "HPS_FOCAL_CHOICES", "LAYOUTS", "random_camera", "hps_focal_px", "sample_walks",
           "synth_frames", "write_synth_scene"]

HFOV_RANGE_DEG = (45.0, 100.0)  # horizontal fields of view of real surveillance lenses
CAMERA_HEIGHT_RANGE_M = (2.5, 15.0)  # the random camera's default heights (surveillance)
PITCH_RANGE_DEG = (10.0, 60.0)  # and downward tilts
CAMERA_DRAWS = 20  # cameras drawn for a one-depth layout before giving up
MAX_PITCH_DEG = 89.0  # |pitch| a range may reach (90: looking straight down, no horizon)
HPS_FOCAL_CHOICES = (*FOCAL_RULES, "true")  # or a number of pixels
# Options added after scenes were committed (sample_data/scene): synth.yaml lists them only when they
# differ from these defaults, so an older scene is reproduced byte for byte.
_LATER_OPTIONS = {"layout": "crowd", "camera_height_range_m": CAMERA_HEIGHT_RANGE_M, "pitch_range_deg": PITCH_RANGE_DEG}


@dataclass(frozen=True)
class SynthOptions:
    """Everything ``rotavat synth`` can vary (defaults live in configs/default.yaml)."""

    seed: int = 0
    frames: int = 20
    people: int = 8
    layout: str = "crowd"  # where people stand: LAYOUTS (crowd | walk | row)
    image_size: tuple[int, int] = (1280, 720)
    roll_deg: float | None = None  # None: random in [-3, 3]
    camera_height_range_m: tuple[float, float] = CAMERA_HEIGHT_RANGE_M  # the random camera's height, uniform
    pitch_range_deg: tuple[float, float] = PITCH_RANGE_DEG  # its downward tilt, uniform
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
        for key in ("camera_height_range_m", "pitch_range_deg"):
            if key in values:
                values[key] = tuple(values[key])
        return cls(**values)

    RULES: ClassVar[dict[str, Rule]] = {  # the ``synth`` keys' bounds and names (rotavat_cli/settings/option_rules.py)
        "frames": Rule(low=1), "people": Rule(low=0), "layout": Rule(names=LAYOUTS),
        "image_size": Rule(low=32, high=MAX_IMAGE_SIDE_PX, unit="px"),
        "camera_height_range_m": Rule(low=1e-3, high=MAX_HEIGHT_M, ordered="<=", unit="m"),
        "pitch_range_deg": Rule(low=-MAX_PITCH_DEG, high=MAX_PITCH_DEG, ordered="<=", unit="deg"),
        "noise_px": Rule(low=0, unit="px"), "outliers": Rule(low=0, high=1), "depth_sd": Rule(low=0),
        "lean": Rule(low=0, high=1), "hps_focal": Rule(names=HPS_FOCAL_CHOICES, or_number=True, low=0, open_low=True),
    }

    def __post_init__(self) -> None:
        for name in ("image_size", "camera_height_range_m", "pitch_range_deg"):
            value = getattr(self, name)
            if isinstance(value, (str, bytes)) or len(np.shape(value)) != 1 or len(value) != 2:
                raise ValueError(f"{name} must be two numbers, got {value!r}")
        check_fields(self, self.RULES)
        for name in ("camera_height_range_m", "pitch_range_deg"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))


def random_camera(rng: np.random.Generator, image_size: tuple[int, int], roll_deg: float | None = None,
                  roll_max_deg: float = 3.0, height_range_m: tuple[float, float] = CAMERA_HEIGHT_RANGE_M,
                  pitch_range_deg: tuple[float, float] = PITCH_RANGE_DEG) -> Camera:
    """Realistic camera: horizontal field of view 45-100 deg, pitch and height uniform in their ranges
    (default a surveillance camera: 10-60 deg, 2.5-15 m; handheld: -5..15 deg, 1.2-2 m); roll given
    or +-max."""
    W = image_size[0]
    roll = rng.uniform(-roll_max_deg, roll_max_deg) if roll_deg is None else roll_deg
    hfov = np.deg2rad(rng.uniform(*HFOV_RANGE_DEG))
    return Camera(image_size, W / (2.0 * np.tan(hfov / 2.0)), None, np.deg2rad(rng.uniform(*pitch_range_deg)),
                  np.deg2rad(roll), rng.uniform(*height_range_m))


def hps_focal_px(spec: str | float, camera: Camera) -> tuple[float, str]:
    """The focal (px) an HPS method assumes for this camera's images, and the rule's name.

    spec: a rule of :data:`rotavat_cli.geometry.focal.FOCAL_RULES`, ``"true"`` (the camera's own focal),
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


def _camera_and_places(rng: np.random.Generator, opts: SynthOptions) -> tuple[Camera, tuple[np.ndarray, np.ndarray]]:
    """The random camera, and its people's ground positions (T, P, 3) and headings (T, P).

    A camera with no room for a one-depth layout (walk, row: e.g. 2.6 m up, looking 40 deg down, it
    cuts off the heads of all but the nearest people) is drawn again, up to ``CAMERA_DRAWS`` times; the
    crowd keeps its first camera, as it always has (its scenes stay byte for byte what they were).
    """
    def draw() -> Camera:
        return random_camera(rng, opts.image_size, opts.roll_deg, height_range_m=opts.camera_height_range_m,
                             pitch_range_deg=opts.pitch_range_deg)

    if opts.layout == "crowd":
        camera = draw()
        return camera, place_people(opts.layout, rng, camera, opts.people, opts.frames)
    for _ in range(CAMERA_DRAWS):
        camera = draw()
        try:
            return camera, place_people(opts.layout, rng, camera, opts.people, opts.frames)
        except ValueError as exc:
            why = str(exc)
    low_h, high_h = opts.camera_height_range_m
    low_p, high_p = opts.pitch_range_deg
    raise ValueError(f"{why} for any of {CAMERA_DRAWS} random cameras ({low_h:g}-{high_h:g} m up, pitch {low_p:g} to "
                     f"{high_p:g} deg): try other --camera-height-range / --pitch-range, or fewer --people")


def synth_frames(opts: SynthOptions, library: BodyLibrary | None = None) -> tuple[Camera, float, Iterator[tuple[Frame, Frame]]]:
    """True camera, the HPS focal, and an iterator of (gt frame, pred frame)."""
    library = library or load_bodies()
    rng = np.random.default_rng(opts.seed)
    camera, (pos, heading) = _camera_and_places(rng, opts)
    hps_focal, _ = hps_focal_px(opts.hps_focal, camera)
    P = opts.people
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
    params = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(opts).items()
              if k not in _LATER_OPTIONS or v != _LATER_OPTIONS[k]}
    write_yaml(out / "synth.yaml", params)
    return {"out": str(out), "gt": str(out / "gt"), "pred": str(out / "pred"), "frames": opts.frames,
            "people": opts.people, "layout": opts.layout, "camera": camera_parameters(camera),
            "hps_focal_px": hps_focal, "hps_focal_rule": rule}
