"""Synthetic foot/head pixel pairs from a known camera, for calibration tests and benchmarks.

People stand upright on the ground of a random surveillance camera and walk across it over the
frames (a person keeps its stature and track id; one who leaves the view re-enters elsewhere), or
(``layout="still"``) stand about where they are at every depth, swaying a few centimetres from frame
to frame, or (``"mix"``) half of each.
The head is straight above the mid-sole along world up, both are projected, Gaussian pixel noise
is added, and a fraction of the pairs is replaced by gross outliers: sitting people (head at
1.0-1.35 m), cropped people (foot pixel moved up the body) and random heads.
Deterministic for a given generator state. Imported by tests/ and benchmarks/ (one copy).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.synth import random_camera
from rotavat_cli.synth.layouts import STILL_SWAY_M  # a standing person's offset from their place per frame, sd

__all__ = ["LAYOUTS", "SyntheticPairs", "box_points_px", "distort_px", "random_surveillance_camera", "synthetic_pairs"]

FRAME_DT_S = 0.2  # 5 frames per second
MAX_DISTANCE_M = 45.0  # people farther than this are too small to be detected
MIN_PERSON_PX = 12.0  # smaller people are not detected
OUTLIER_KINDS = ("sitting", "cropped", "random_head")
LAYOUTS = ("walk", "still", "mix")


@dataclass(frozen=True)
class SyntheticPairs:
    """Foot/head pixels (N, 2) with their frame, track, outlier flag and true camera."""

    camera: Camera
    feet_px: np.ndarray  # (N, 2)
    heads_px: np.ndarray  # (N, 2)
    frame_index: np.ndarray  # (N,) int
    track_id: np.ndarray  # (N,) int
    is_outlier: np.ndarray  # (N,) bool
    stature_m: np.ndarray  # (N,) true stature of the person


def random_surveillance_camera(rng: np.random.Generator, image_size: tuple[int, int] = (1920, 1080),
                               roll_deg: float | None = 0.0, roll_max_deg: float = 5.0) -> Camera:
    """Focal 0.6-2.5 H, pitch 10-60 deg, height 2.5-15 m; roll fixed, or uniform +-roll_max if None."""
    return random_camera(rng, image_size, roll_deg, roll_max_deg)


def _project_world(camera: Camera, points_world: np.ndarray) -> np.ndarray:
    """World points (..., 3) -> pixels (..., 2), NaN behind the camera."""
    return camera.project(camera.cam_from_world(points_world))


def _visible(camera: Camera, ground_world: np.ndarray, stature_m: np.ndarray) -> np.ndarray:
    """(M,) bool: the person at ``ground_world`` (M, 3) is detectable (in view, near, big enough)."""
    W, H = camera.image_size
    up = np.array([0.0, 1.0, 0.0])
    feet = _project_world(camera, ground_world)
    heads = _project_world(camera, ground_world + stature_m[:, None] * up)
    dist = np.linalg.norm(ground_world[:, [0, 2]], axis=1)
    with np.errstate(invalid="ignore"):
        inside = (feet[:, 0] >= 0) & (feet[:, 0] < W) & (feet[:, 1] >= 0) & (feet[:, 1] < H)
        inside &= (heads[:, 1] >= 0) & (heads[:, 0] >= 0) & (heads[:, 0] < W)
        big = np.linalg.norm(feet - heads, axis=1) >= MIN_PERSON_PX
    return inside & big & (dist <= MAX_DISTANCE_M)


def _spawn(rng: np.random.Generator, camera: Camera, stature_m: np.ndarray) -> np.ndarray:
    """Random visible ground positions (M, 3) in the world frame for people of these statures."""
    W, H = camera.image_size
    out = np.full((len(stature_m), 3), np.nan)
    todo = np.arange(len(stature_m))
    for _ in range(200):
        if todo.size == 0:
            return out
        uv = np.stack([rng.uniform(0, W, todo.size), rng.uniform(0, H, todo.size)], axis=1)
        ground = camera.world_from_cam(camera.backproject_px_to_ground(uv))
        ok = np.all(np.isfinite(ground), axis=1)
        ok[ok] = _visible(camera, ground[ok], stature_m[todo[ok]])
        out[todo[ok]] = ground[ok]
        todo = todo[~ok]
    raise ValueError("camera sees too little ground to place people")


def _make_outliers(rng: np.random.Generator, camera: Camera, ground_world: np.ndarray, feet_px: np.ndarray,
                   heads_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Replace every pair by a gross outlier of a random kind; returns new (feet_px, heads_px)."""
    feet, heads = feet_px.copy(), heads_px.copy()
    kind = rng.integers(0, len(OUTLIER_KINDS), len(feet))
    length = np.linalg.norm(feet - heads, axis=1)
    sit = kind == 0
    sit_height = rng.uniform(1.0, 1.35, sit.sum())
    heads[sit] = _project_world(camera, ground_world[sit] + sit_height[:, None] * np.array([0.0, 1.0, 0.0]))
    crop = kind == 1
    frac = rng.uniform(0.25, 0.6, crop.sum())[:, None]
    feet[crop] = feet[crop] + frac * (heads[crop] - feet[crop])
    rnd = kind == 2
    offset = np.stack([rng.normal(0.0, 0.3, rnd.sum()), -rng.uniform(0.3, 2.0, rnd.sum())], axis=1)
    heads[rnd] = feet[rnd] + offset * length[rnd, None]
    return feet, heads


def synthetic_pairs(rng: np.random.Generator, *, camera: Camera | None = None,
                    image_size: tuple[int, int] = (1920, 1080), roll_deg: float | None = 0.0,
                    frames: int = 1, people: int = 10, noise_px: float = 2.0, stature_mean_m: float = 1.70,
                    stature_sd_m: float = 0.07, outlier_fraction: float = 0.0,
                    walk_speed_mps: float = 1.3, points: str = "landmarks", distortion: float = 0.0,
                    sway_sd_m: float = 0.0, noise_corr: float = 0.0, layout: str = "walk") -> SyntheticPairs:
    """``people`` walkers seen over ``frames`` frames; roll_deg None = random roll (+-5 deg).

    Realism options (all off by default; the default draws are unchanged): ``points="boxes"``
    replaces mid-sole/crown by box-derived points (:func:`box_points_px`); ``distortion``
    radially distorts every point (:func:`distort_px`); ``sway_sd_m`` moves each crown
    horizontally off the vertical through the mid-sole (walking pose, N(0, sd) per axis and pair);
    ``noise_corr`` makes each track's pixel noise an AR(1) series over the frames (correlation).
    ``layout``: "walk" (everyone walks), "still" (everyone stands about their place, ``STILL_SWAY_M``
    per frame; a person swaying out of view is not seen in that frame) or "mix" (the first half still).
    """
    if points not in ("landmarks", "boxes"):
        raise ValueError(f"points must be 'landmarks' or 'boxes', got {points!r}")
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    cam = random_surveillance_camera(rng, image_size, roll_deg) if camera is None else camera
    stature = rng.normal(stature_mean_m, stature_sd_m, people)
    pos = _spawn(rng, cam, stature)
    heading = rng.uniform(0, 2 * np.pi, people)
    up = np.array([0.0, 1.0, 0.0])
    still = np.zeros(people, bool) if layout == "walk" else np.arange(people) < (people if layout == "still"
                                                                                  else people // 2)
    place = pos.copy()
    chunks = []
    for t in range(frames):
        if t > 0:
            step = walk_speed_mps * FRAME_DT_S * np.stack([np.cos(heading), np.zeros(people), np.sin(heading)], 1)
            pos = np.where(still[:, None], pos, pos + step)
            gone = ~_visible(cam, pos, stature) & ~still
            if gone.any():
                pos[gone] = _spawn(rng, cam, stature[gone])
                heading[gone] = rng.uniform(0, 2 * np.pi, gone.sum())
        if still.any():
            sway = rng.normal(0.0, STILL_SWAY_M, (int(still.sum()), 3)) * np.array([1.0, 0.0, 1.0])
            pos[still] = place[still] + sway
        seen = _visible(cam, pos, stature) | ~still
        feet = _project_world(cam, pos[seen])
        heads = _project_world(cam, pos[seen] + stature[seen, None] * up)
        chunks.append((feet, heads, np.full(int(seen.sum()), t), np.flatnonzero(seen), pos[seen].copy(),
                       stature[seen].copy(), heading[seen].copy()))
    feet, heads, frame, track, ground, stat, head_dir = (np.concatenate(c) for c in zip(*chunks))
    n = len(feet)
    crown = ground + stat[:, None] * up
    if sway_sd_m > 0:
        crown = crown + rng.normal(0.0, sway_sd_m, (n, 3)) * np.array([1.0, 0.0, 1.0])
        heads = _project_world(cam, crown)
    if points == "boxes":
        phase = rng.uniform(0.0, 2.0 * np.pi, people)[track] + 2.0 * np.pi * frame * FRAME_DT_S  # ~1 stride/s
        feet, heads = box_points_px(cam, ground, crown, head_dir, phase)
    outlier = np.zeros(n, bool)
    n_out = int(round(outlier_fraction * n))
    if n_out:
        outlier[rng.choice(n, n_out, replace=False)] = True
        feet[outlier], heads[outlier] = _make_outliers(rng, cam, ground[outlier], feet[outlier], heads[outlier])
    if distortion:
        feet, heads = distort_px(feet, cam, distortion), distort_px(heads, cam, distortion)
    if noise_corr > 0:
        feet = feet + _track_noise(rng, noise_px, noise_corr, frame, track, people)
        heads = heads + _track_noise(rng, noise_px, noise_corr, frame, track, people)
    else:
        feet = feet + rng.normal(0.0, noise_px, feet.shape)
        heads = heads + rng.normal(0.0, noise_px, heads.shape)
    return SyntheticPairs(cam, feet, heads, frame.astype(np.int64), track.astype(np.int64), outlier, stat)


def _track_noise(rng: np.random.Generator, sd_px: float, corr: float, frame: np.ndarray, track: np.ndarray,
                 people: int) -> np.ndarray:
    """(N, 2) pixel noise, an AR(1) series over frames per track (marginal sd ``sd_px``)."""
    frames = int(frame.max()) + 1 if len(frame) else 0
    eps = rng.normal(0.0, sd_px, (frames, people, 2))
    series = np.empty_like(eps)
    if frames:
        series[0] = eps[0]
    for t in range(1, frames):
        series[t] = corr * series[t - 1] + math.sqrt(1.0 - corr * corr) * eps[t]
    return series[frame, track]


def distort_px(points_px: np.ndarray, camera: Camera, corner: float) -> np.ndarray:
    """Radially distorted pixels (N, 2): ``x_d = x (1 + corner |x|^2 / R^2)`` about the principal point.

    R is the image half-diagonal, so ``corner`` is the relative displacement at the image corner
    (negative: barrel; real surveillance lenses: a few percent). A polynomial (Brown) model, not
    the division model the calibration fits.
    """
    pp = np.asarray(camera.principal_point)
    x = points_px - pp
    radius2 = (0.5 * math.hypot(*camera.image_size)) ** 2
    return pp + x * (1.0 + corner * np.sum(x * x, axis=1, keepdims=True) / radius2)


# Body silhouette of a walker (metres; why: adult anthropometry): foot length 0.26, feet 0.2 apart,
# step length 0.65 (feet up to +-0.33 fore and aft of the mid-sole), head a 0.1 m sphere under the
# crown, shoulders 0.44 wide at 0.82 of the stature.
_FOOT_HALF_LENGTH_M, _FOOT_SPACING_M, _STEP_HALF_M = 0.13, 0.10, 0.33
_HEAD_RADIUS_M, _SHOULDER_HALF_M, _SHOULDER_RATIO = 0.10, 0.22, 0.82


def box_points_px(camera: Camera, ground_world: np.ndarray, crown_world: np.ndarray, heading_rad: np.ndarray,
                  phase_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box-derived (foot, head) pixels (N, 2): the bottom- and top-centre of the person's image box.

    The box bounds the projected silhouette: heels and toes of two walking feet (gait phase
    ``phase_rad``), the shoulders and a sphere under the crown. The bottom is the lowest foot
    point (nearest the camera), the top the highest point of the head, both at the box's centre
    column, as annotation boxes give them.
    """
    fwd = np.stack([np.cos(heading_rad), np.zeros_like(heading_rad), np.sin(heading_rad)], axis=1)
    side = np.stack([-fwd[:, 2], np.zeros_like(heading_rad), fwd[:, 0]], axis=1)
    stride = _STEP_HALF_M * np.sin(phase_rad)[:, None]
    feet = []
    for s_side, s_step in ((1.0, 1.0), (-1.0, -1.0)):
        centre = ground_world + s_side * _FOOT_SPACING_M * side + s_step * stride * fwd
        feet += [centre + _FOOT_HALF_LENGTH_M * fwd, centre - _FOOT_HALF_LENGTH_M * fwd]
    u = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    w = np.linspace(0.0, 0.5 * np.pi, 7)
    sphere = np.stack([np.outer(np.cos(w), np.cos(u)), np.outer(np.sin(w), np.ones_like(u)),
                       np.outer(np.cos(w), np.sin(u))], axis=-1).reshape(-1, 3)
    head = crown_world[:, None] + _HEAD_RADIUS_M * (sphere - np.array([0.0, 1.0, 0.0]))
    stature = crown_world[:, 1] - ground_world[:, 1]
    shoulder = ground_world + np.array([0.0, 1.0, 0.0]) * (_SHOULDER_RATIO * stature)[:, None]
    body = [shoulder + _SHOULDER_HALF_M * side, shoulder - _SHOULDER_HALF_M * side]
    feet_px = _project_world(camera, np.stack(feet, axis=1))
    head_px = _project_world(camera, head)
    all_u = np.concatenate([feet_px[..., 0], head_px[..., 0], _project_world(camera, np.stack(body, 1))[..., 0]], 1)
    centre_u = 0.5 * (all_u.min(axis=1) + all_u.max(axis=1))
    return (np.stack([centre_u, feet_px[..., 1].max(axis=1)], axis=1),
            np.stack([centre_u, head_px[..., 1].min(axis=1)], axis=1))
