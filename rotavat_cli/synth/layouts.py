"""Where the people of a synthetic scene stand and walk (``rotavat synth --layout``).

- ``crowd``: people walking back and forth between random visible ground points, at every depth
  the camera sees (the calibration's easy case);
- ``walk``: people walking back and forth across the view along one line on the ground
  perpendicular to the camera's viewing direction: everyone at one depth, the feet on one image
  line (parallel to the horizon: an image row when the roll is 0), as in a video of one passer-by;
- ``row``: a group photo: people side by side (``ROW_SPACING_M`` apart) at one depth, facing the
  camera, standing still;
- ``still``: people standing at random visible ground points, at every depth the camera sees, each
  swaying about its place (``STILL_SWAY_M`` per frame) and turning on the spot: people waiting,
  talking, queueing. A person who barely moves gives no perspective of their own, and their
  pixel noise is as large as their motion: the calibration's hard case for per-person statures.

The one-depth layouts choose their line so every foot and crown stays inside the image and a
person is a reasonable size (``PERSON_SIZE_RANGE_H`` of the image height, when the camera allows
it: a camera 15 m up looking steeply down sees people smaller than that wherever they stand).
Every layout returns ground positions (T, P, 3) in the world frame and headings (T, P), radians
about +Y, taking a body's +Z (its front) to the direction it faces.
"""

from __future__ import annotations

import numpy as np

from ..geometry.camera import Camera

__all__ = ["LAYOUTS", "FPS", "WALK_SPEED_MPS", "MAX_GROUND_DISTANCE_M", "STILL_SWAY_M", "place_people", "sample_walks",
           "standing_still"]

LAYOUTS = ("crowd", "walk", "row", "still")
FPS = 5.0  # frames per second of the synthetic video
WALK_SPEED_MPS = (0.8, 1.6)  # walking speeds
MAX_GROUND_DISTANCE_M = 45.0  # people farther than this are too small to matter
# ---- one-depth layouts (walk, row) ----
PERSON_SIZE_RANGE_H = (0.25, 0.70)  # a 1.70 m person's image height / the image height, aimed at
ROW_FILL_RANGE = (0.5, 0.85)  # a row's width / the visible width at its depth, aimed at
ROW_SPACING_M = 0.6  # shoulder to shoulder
DEPTH_JITTER_M = 0.03  # sd of each person's offset from the line, along the viewing direction (and across, row)
DEPTH_JITTER_MAX_M = 0.08  # the offsets are clipped to this
FACING_SD_DEG = 10.0  # a row faces the camera roughly
STILL_SWAY_M = 0.05  # still: sd of a standing person's offset from their place in each frame (per ground axis)
STILL_TURN_SD_DEG = 20.0  # still: sd of their heading about its mean, frame to frame
BODY_MARGIN_M = 0.35  # half a body's width (arms) beyond its foot point: kept inside the view
MIN_TRACK_M = 2.0  # a walk's shortest track
IN_VIEW_STATURE_M = 2.1  # the tallest synthetic person (2.05 m) and some: whose crown must be in view
_REFERENCE_STATURE_M = 1.70  # the person whose image height is aimed at
_DEPTHS_M = np.geomspace(0.5, MAX_GROUND_DISTANCE_M, 200)  # candidate lines (2.3% apart)
_ACROSS_M = np.linspace(-MAX_GROUND_DISTANCE_M, MAX_GROUND_DISTANCE_M, 901)  # 10 cm steps along a line


def in_view(camera: Camera, ground_world: np.ndarray, stature_m: float = 1.9) -> np.ndarray:
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
        keep[keep] = in_view(camera, ground[keep])
        found = np.concatenate([found, ground[keep]])
        if len(found) >= n:
            return found[:n]
    raise ValueError("this camera sees almost no ground where people fit in the image")


def sample_walks(rng: np.random.Generator, camera: Camera, n_people: int, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Back-and-forth walks (the crowd): ground positions (T, P, 3) world frame and headings (T, P) rad."""
    start = _sample_ground_points(rng, camera, n_people)
    end = _sample_ground_points(rng, camera, n_people)
    return _back_and_forth(rng, start, end, n_frames)


def _back_and_forth(rng: np.random.Generator, start: np.ndarray, end: np.ndarray,
                    n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Walks from ``start`` to ``end`` (P, 3) and back at a random speed and phase: positions (T, P, 3), headings (T, P)."""
    n_people = len(start)
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


def standing_still(rng: np.random.Generator, camera: Camera, n_people: int,
                   n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """People standing at random visible places, swaying about them and turning on the spot: positions
    (T, P, 3) world frame and headings (T, P) rad."""
    place = _sample_ground_points(rng, camera, n_people)
    sway = rng.normal(0.0, STILL_SWAY_M, (n_frames, n_people, 3)) * np.array([1.0, 0.0, 1.0])
    heading = rng.uniform(0.0, 2.0 * np.pi, n_people) + np.deg2rad(rng.normal(0.0, STILL_TURN_SD_DEG,
                                                                              (n_frames, n_people)))
    return place + sway, heading


def view_axes_world(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Unit ground directions (3,) world frame: along the viewing direction, and across it (to the right).

    A line along ``across`` is at one depth (camera z) all along: the optical axis is perpendicular
    to it whatever the roll.
    """
    axis_world = camera.R_cam_from_world[2]  # the optical axis (camera z) in the world frame
    along = np.array([axis_world[0], 0.0, axis_world[2]])
    norm = np.linalg.norm(along)
    along = along / norm if norm > 1e-9 else np.array([0.0, 0.0, -1.0])  # looking straight down
    return along, np.cross(along, np.array([0.0, 1.0, 0.0]))


def _one_depth_line(rng: np.random.Generator, camera: Camera, width_m: float, aim: str,
                    what: str) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """A line across the view, at one ground distance, holding ``width_m`` of people in view.

    Among the lines where that width fits (feet and crowns inside the image, ``BODY_MARGIN_M`` to
    spare at both ends), those where a 1.70 m person is ``PERSON_SIZE_RANGE_H`` of the image height
    tall when there are any, the one nearest a random aim: the person's image height (``aim`` =
    "size") or the width's share of the visible line (``aim`` = "fill"). Returns the directions
    along and across the view (3,), the line's ground distance and its visible interval [lo, hi]
    (m along ``across``, less the margins). ValueError when no line fits.
    """
    H = camera.image_size[1]
    target = rng.uniform(*(PERSON_SIZE_RANGE_H if aim == "size" else ROW_FILL_RANGE))
    along, across = view_axes_world(camera)
    ground = _DEPTHS_M[:, None, None] * along + _ACROSS_M[None, :, None] * across  # (D, S, 3)
    ok = in_view(camera, ground, IN_VIEW_STATURE_M)
    seen = ok.any(axis=1)
    lo = np.where(seen, np.where(ok, _ACROSS_M, np.inf).min(axis=1), 0.0) + BODY_MARGIN_M
    hi = np.where(seen, np.where(ok, _ACROSS_M, -np.inf).max(axis=1), 0.0) - BODY_MARGIN_M
    fits = seen & (hi - lo >= width_m)
    if not fits.any():
        raise ValueError(f"no line across the view holds {what} in the image at one depth")
    mid = 0.5 * (lo + hi)
    feet = _DEPTHS_M[:, None] * along + mid[:, None] * across
    size_h = np.linalg.norm(camera.project(camera.cam_from_world(feet + np.array([0.0, _REFERENCE_STATURE_M, 0.0])))
                            - camera.project(camera.cam_from_world(feet)), axis=-1) / H
    sized = fits & (size_h >= PERSON_SIZE_RANGE_H[0]) & (size_h <= PERSON_SIZE_RANGE_H[1])
    pool = sized if sized.any() else fits
    value = size_h if aim == "size" else width_m / np.maximum(hi - lo + 2 * BODY_MARGIN_M, 1e-9)
    best = int(np.argmin(np.where(pool, np.abs(value - target), np.inf)))
    return along, across, float(_DEPTHS_M[best]), float(lo[best]), float(hi[best])


def _offsets(rng: np.random.Generator, n: int) -> np.ndarray:
    """n small offsets (m) from a line: ``DEPTH_JITTER_M`` sd, clipped to ``DEPTH_JITTER_MAX_M``."""
    return np.clip(rng.normal(0.0, DEPTH_JITTER_M, n), -DEPTH_JITTER_MAX_M, DEPTH_JITTER_MAX_M)


def one_depth_walks(rng: np.random.Generator, camera: Camera, n_people: int,
                    n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """People walking back and forth across the view from one side of it to the other, at one depth:
    positions (T, P, 3) world frame and headings (T, P) rad."""
    along, across, depth, lo, hi = _one_depth_line(rng, camera, MIN_TRACK_M + 2 * DEPTH_JITTER_MAX_M, "size",
                                                   "walkers")
    lo, hi = lo + DEPTH_JITTER_MAX_M, hi - DEPTH_JITTER_MAX_M  # the line's visible ends move a little with depth
    on_line = (depth + _offsets(rng, n_people))[:, None] * along
    return _back_and_forth(rng, on_line + lo * across, on_line + hi * across, n_frames)


def standing_row(rng: np.random.Generator, camera: Camera, n_people: int,
                 n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """A group photo: people side by side at one depth, facing the camera, still: positions (T, P, 3)
    world frame and headings (T, P) rad (the same in every frame)."""
    width = (n_people - 1) * ROW_SPACING_M + 2 * DEPTH_JITTER_MAX_M
    along, across, depth, lo, hi = _one_depth_line(rng, camera, width, "fill", f"{n_people} people side by side")
    centre = 0.5 * (lo + hi) + rng.uniform(-0.5, 0.5) * (hi - lo - width)
    side = centre + (np.arange(n_people) - 0.5 * (n_people - 1)) * ROW_SPACING_M + _offsets(rng, n_people)
    pos = (depth + _offsets(rng, n_people))[:, None] * along + side[:, None] * across
    to_camera = -pos  # the camera stands above the world origin
    heading = np.arctan2(to_camera[:, 0], to_camera[:, 2]) + np.deg2rad(rng.normal(0.0, FACING_SD_DEG, n_people))
    return np.broadcast_to(pos, (n_frames, n_people, 3)).copy(), np.broadcast_to(heading, (n_frames, n_people)).copy()


def place_people(layout: str, rng: np.random.Generator, camera: Camera, n_people: int,
                 n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Ground positions (T, P, 3) world frame and headings (T, P) rad of a layout's people (LAYOUTS)."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    if layout == "crowd":
        return sample_walks(rng, camera, n_people, n_frames)
    if layout == "still":
        return standing_still(rng, camera, n_people, n_frames)
    if n_people == 0:
        return np.zeros((n_frames, 0, 3)), np.zeros((n_frames, 0))
    return (one_depth_walks if layout == "walk" else standing_row)(rng, camera, n_people, n_frames)
