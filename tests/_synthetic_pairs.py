"""Synthetic foot/head pixel pairs from a known camera, for calibration tests and benchmarks.

People stand upright on the ground of a random surveillance camera and walk across it over the
frames (a person keeps its stature and track id; one who leaves the view re-enters elsewhere).
The head is straight above the mid-sole along world up, both are projected, Gaussian pixel noise
is added, and a fraction of the pairs is replaced by gross outliers: sitting people (head at
1.0-1.35 m), cropped people (foot pixel moved up the body) and random heads.
Deterministic for a given generator state. Imported by tests/ and benchmarks/ (one copy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rotavat_cli.camera import Camera
from rotavat_cli.synth import random_camera

__all__ = ["SyntheticPairs", "random_surveillance_camera", "synthetic_pairs"]

FRAME_DT_S = 0.2  # 5 frames per second
MAX_DISTANCE_M = 45.0  # people farther than this are too small to be detected
MIN_PERSON_PX = 12.0  # smaller people are not detected
OUTLIER_KINDS = ("sitting", "cropped", "random_head")


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
                    walk_speed_mps: float = 1.3) -> SyntheticPairs:
    """``people`` walkers seen over ``frames`` frames; roll_deg None = random roll (+-5 deg)."""
    cam = random_surveillance_camera(rng, image_size, roll_deg) if camera is None else camera
    stature = rng.normal(stature_mean_m, stature_sd_m, people)
    pos = _spawn(rng, cam, stature)
    heading = rng.uniform(0, 2 * np.pi, people)
    up = np.array([0.0, 1.0, 0.0])
    chunks = []
    for t in range(frames):
        if t > 0:
            step = walk_speed_mps * FRAME_DT_S * np.stack([np.cos(heading), np.zeros(people), np.sin(heading)], 1)
            pos = pos + step
            gone = ~_visible(cam, pos, stature)
            if gone.any():
                pos[gone] = _spawn(rng, cam, stature[gone])
                heading[gone] = rng.uniform(0, 2 * np.pi, gone.sum())
        feet = _project_world(cam, pos)
        heads = _project_world(cam, pos + stature[:, None] * up)
        chunks.append((feet, heads, np.full(people, t), np.arange(people), pos.copy(), stature.copy()))
    feet, heads, frame, track, ground, stat = (np.concatenate(c) for c in zip(*chunks))
    n = len(feet)
    outlier = np.zeros(n, bool)
    n_out = int(round(outlier_fraction * n))
    if n_out:
        outlier[rng.choice(n, n_out, replace=False)] = True
        feet[outlier], heads[outlier] = _make_outliers(rng, cam, ground[outlier], feet[outlier], heads[outlier])
    feet = feet + rng.normal(0.0, noise_px, feet.shape)
    heads = heads + rng.normal(0.0, noise_px, heads.shape)
    return SyntheticPairs(cam, feet, heads, frame.astype(np.int64), track.astype(np.int64), outlier, stat)
