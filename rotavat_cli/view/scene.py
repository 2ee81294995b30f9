"""What a recording shows besides the people, in world metres: the ground grid and its ticks, other
grounds as planes (a row's own camera, the calibration's ±1 std), the camera's label, the tracks'
ground trajectories. Pure numpy; nothing here knows Rerun (:mod:`.recording` logs what these return).

The world is the scene camera's (docs/conventions.md, "World frame"): Y up, the ground at ``Y = 0``,
the origin on the ground below the camera centre, the camera looking along −Z.

>>> lo, hi = ground_extent_m(np.array([[0.4, 0.0, -6.2], [-1.5, 1.7, -3.0]]), margin_m=1.0)
>>> lo.tolist(), hi.tolist()
([-3.0, -8.0], [2.0, -2.0])
>>> grid_lines_world(lo, hi, 1.0).shape     # 6 lines along Z (x = -3..2), 7 along X (z = -8..-2)
(13, 2, 3)
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..geometry.camera import Camera, world_points_f32

__all__ = ["GRID_MARGIN_M", "MAX_GRID_LINES", "ground_extent_m", "grid_step_m", "grid_lines_world", "grid_ticks_world",
           "plane_quad_world", "uncertainty_cameras", "camera_label", "track_strips", "EYE_FOV_Y_DEG", "eye_world",
           "world_points_f32", "label_anchors_world", "tilted_square_world"]

GRID_MARGIN_M = 2.0  # the grid reaches this far beyond the people and the camera
MAX_GRID_LINES = 60  # per axis: a wider scene gets 2, 5, 10 ... m between lines
_MAX_TICK_LABELS = 8  # per axis
_LABEL_RAISE_M = 0.15  # a person's label floats this far above its top
_STEEP_PLANE = 0.2  # a plane whose normal's world-up part is below this is not drawn (nearly vertical)


def ground_extent_m(points_world: np.ndarray, margin_m: float = GRID_MARGIN_M) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi), each (2,) = (x, z) metres: the ground rectangle holding the (N, 3) world points (NaN rows
    ignored) and ``margin_m`` around them, snapped outward to whole metres; 10 m x 10 m ahead of the
    camera when there is no point."""
    p = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)][:, [0, 2]]
    if not len(p):
        return np.array([-5.0, -10.0]), np.array([5.0, 0.0])
    return np.floor(p.min(axis=0) - margin_m), np.ceil(p.max(axis=0) + margin_m)


def _next_nice(step: float) -> float:
    """The next of 1, 2, 5, 10, 20, 50 ... after ``step`` (itself one of them).

    >>> _next_nice(1.0), _next_nice(2.0), _next_nice(5.0), _next_nice(50.0)
    (2.0, 5.0, 10.0, 100.0)
    """
    decade = 10.0 ** math.floor(math.log10(step) + 1e-9)
    return {1: 2.0, 2: 5.0, 5: 10.0}[round(step / decade)] * decade


def _spaced(lo: np.ndarray, hi: np.ndarray, start: float, most: int) -> float:
    """The first of ``start``, then 2, 5, 10 ... times it, that spaces the widest side of lo..hi into at most ``most`` steps."""
    span = float(np.max(np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64)))
    step = start
    while span / step > most:
        step = _next_nice(step)
    return step


def grid_step_m(lo: np.ndarray, hi: np.ndarray) -> float:
    """Metres between grid lines: 1, or 2, 5, 10 ... when a side would need more than :data:`MAX_GRID_LINES`.

    >>> grid_step_m(np.array([0.0, 0.0]), np.array([40.0, 10.0])), grid_step_m(np.array([0.0, 0.0]), np.array([150.0, 10.0]))
    (1.0, 5.0)
    """
    return _spaced(lo, hi, 1.0, MAX_GRID_LINES)


def _grid_values(lo: float, hi: float, step: float) -> np.ndarray:
    """Multiples of ``step`` in [lo, hi]."""
    return np.arange(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1) * step


def grid_lines_world(lo: np.ndarray, hi: np.ndarray, step: float) -> np.ndarray:
    """(L, 2, 3) segments on the ground (Y = 0): one along Z at every multiple of ``step`` in x, one along X
    at every multiple in z."""
    xs, zs = _grid_values(lo[0], hi[0], step), _grid_values(lo[1], hi[1], step)
    along_z = np.stack([np.stack([xs, np.zeros_like(xs), np.full_like(xs, lo[1])], axis=1),
                        np.stack([xs, np.zeros_like(xs), np.full_like(xs, hi[1])], axis=1)], axis=1)
    along_x = np.stack([np.stack([np.full_like(zs, lo[0]), np.zeros_like(zs), zs], axis=1),
                        np.stack([np.full_like(zs, hi[0]), np.zeros_like(zs), zs], axis=1)], axis=1)
    return np.concatenate([along_z, along_x])


def grid_ticks_world(lo: np.ndarray, hi: np.ndarray, step: float) -> tuple[np.ndarray, list[str]]:
    """Tick labels of the grid: (K, 3) points on the ground along its near edge (x ticks) and its right edge
    (z ticks, as the distance ahead of the camera; the edge the viewer's eye starts near, :func:`eye_world`),
    at most :data:`_MAX_TICK_LABELS` per axis.

    >>> points, labels = grid_ticks_world(np.array([-2.0, -4.0]), np.array([2.0, 0.0]), 1.0)
    >>> labels[:5], labels[5:]
    (['x -2 m', 'x -1 m', 'x 0 m', 'x 1 m', 'x 2 m'], ['4 m ahead', '3 m ahead', '2 m ahead', '1 m ahead', '0 m ahead'])
    """
    every = _spaced(lo, hi, step, _MAX_TICK_LABELS - 1)
    xs, zs = _grid_values(lo[0], hi[0], every), _grid_values(lo[1], hi[1], every)
    points = np.concatenate([np.stack([xs, np.zeros_like(xs), np.full_like(xs, hi[1])], axis=1),
                             np.stack([np.full_like(zs, hi[0]), np.zeros_like(zs), zs], axis=1)])
    return points, [f"x {x:g} m" for x in xs] + [f"{-z + 0.0:g} m ahead" for z in zs]


def plane_quad_world(ground_of: Camera, scene: Camera, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """(4, 3) corners, in ``scene``'s world, of the ground of camera ``ground_of`` (both cameras of the one
    physical camera frame) above the rectangle ``lo``..``hi`` (x, z); None when that ground is nearly
    vertical in this world (its quad would reach to the sky).

    >>> cam = Camera((640, 480), 500.0, None, math.radians(20.0), 0.0, 5.0)
    >>> plane_quad_world(cam.replace(height_m=5.5), cam, np.array([-1.0, -4.0]), np.array([1.0, 0.0]))[:, 1].round(6).tolist()
    [-0.5, -0.5, -0.5, -0.5]
    """
    corners = np.array([[lo[0], 0.0, lo[1]], [hi[0], 0.0, lo[1]], [hi[0], 0.0, hi[1]], [lo[0], 0.0, hi[1]]])
    raised = corners + [0.0, 1.0, 0.0]
    h0 = ground_of.height_above_ground(scene.cam_from_world(corners))  # affine in y: h(y) = h0 + (h1 - h0) y
    slope = ground_of.height_above_ground(scene.cam_from_world(raised)) - h0
    if np.min(np.abs(slope)) < _STEEP_PLANE:
        return None
    corners[:, 1] = -h0 / slope
    return corners


def _sd(std: Mapping | None, key: str) -> float | None:
    """A finite positive std from ``fit.std`` (None or not a mapping: none), else None."""
    try:
        value = float((std if isinstance(std, Mapping) else {}).get(key))
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) and value > 0 else None


def uncertainty_cameras(camera: Camera, std: Mapping | None) -> dict[str, Camera]:
    """The camera at ±1 std of its height and of its pitch, one change at a time (``std``: camera.yaml's
    ``fit.std``, report units): ``{"height_minus_1sd": ..., "height_plus_1sd": ..., "pitch_minus_1sd": ...,
    "pitch_plus_1sd": ...}`` (names that are entity paths as they stand),
    without the parameters whose std is missing, zero or not finite."""
    out: dict[str, Camera] = {}
    for name, key, field, to_unit in (("height", "height_m", "height_m", 1.0), ("pitch", "pitch_deg", "pitch_rad", math.pi / 180)):
        sd = _sd(std, key)
        if sd is None:
            continue
        for sign, text in ((-1.0, "minus_1sd"), (1.0, "plus_1sd")):
            value = getattr(camera, field) + sign * sd * to_unit
            if field == "height_m" and value <= 0:
                continue
            out[f"{name}_{text}"] = camera.replace(**{field: value})
    return out


def camera_label(camera: Camera, fit: Mapping | None, source: str) -> str:
    """The camera's label: where it came from, its focal with its ±1 std range, pitch, roll and height (each
    with its std when the camera was fitted).

    >>> cam = Camera((1280, 720), 1053.0, None, math.radians(13.5), 0.0, 2.74)
    >>> camera_label(cam, {"method": "refine", "std": {"focal_px": 114.0, "pitch_deg": 1.5, "height_m": 0.17}}, "pred/camera.yaml")
    'camera (refine fit, pred/camera.yaml): f 1053 ± 114 px (939-1167) · pitch 13.5 ± 1.5° · roll 0.0° · height 2.74 ± 0.17 m'
    >>> camera_label(cam, {}, "gt/camera.yaml")
    'camera (given, gt/camera.yaml): f 1053 px · pitch 13.5° · roll 0.0° · height 2.74 m'
    """
    std = (fit or {}).get("std")
    method = (fit or {}).get("method")
    parts = []
    f_sd = _sd(std, "focal_px")
    parts.append(f"f {camera.focal_px:.0f} ± {f_sd:.0f} px ({camera.focal_px - f_sd:.0f}-{camera.focal_px + f_sd:.0f})"
                 if f_sd else f"f {camera.focal_px:.0f} px")
    for name, key, value, fmt, unit in (("pitch", "pitch_deg", math.degrees(camera.pitch_rad), ".1f", "°"),
                                        ("roll", "roll_deg", math.degrees(camera.roll_rad), ".1f", "°"),
                                        ("height", "height_m", camera.height_m, ".2f", " m")):
        sd = _sd(std, key)
        parts.append(f"{name} {value:{fmt}} ± {sd:{fmt}}{unit}" if sd else f"{name} {value:{fmt}}{unit}")
    return f"camera ({f'{method} fit' if method else 'given'}, {source}): " + " · ".join(parts)


def track_strips(frame_index: np.ndarray, points: np.ndarray, max_gap: int = 1) -> list[np.ndarray]:
    """A track's path as line strips: (N,) frame indices (increasing) and (N, 3) points -> strips of >= 2
    points, cut where the track skips more than ``max_gap`` frames or a point is not finite.

    >>> [s[:, 0].tolist() for s in track_strips(np.array([0, 1, 2, 5, 6, 9]), np.arange(18.0).reshape(6, 3))]
    [[0.0, 3.0, 6.0], [9.0, 12.0]]
    """
    index = np.asarray(frame_index, dtype=np.int64)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    ok = np.isfinite(p).all(axis=1)
    index, p = index[ok], p[ok]
    cuts = np.flatnonzero(np.diff(index) > max_gap) + 1
    return [piece for piece in np.split(p, cuts) if len(piece) >= 2]


def tilted_square_world(centre: np.ndarray, normal: np.ndarray, half_m: float) -> np.ndarray:
    """(4, 3) corners of a square of side ``2 half_m`` centred on ``centre`` (3,) in the plane of ``normal`` (3,),
    its sides along the plane's slopes across and along world Z (a level normal, +Y, gives a square on the
    ground with sides along X and Z): a tool's ground, tilted by its up.

    >>> tilted_square_world(np.array([1.0, 0.0, -5.0]), np.array([0.0, 1.0, 0.0]), 1.0).tolist()
    [[0.0, 0.0, -6.0], [2.0, 0.0, -6.0], [2.0, 0.0, -4.0], [0.0, 0.0, -4.0]]
    """
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    across = np.cross(n, [0.0, 0.0, 1.0])  # the in-plane direction across world Z (along X when level)
    across /= np.linalg.norm(across)
    along = np.cross(across, n)  # in the plane, toward +Z when level
    c = np.asarray(centre, dtype=np.float64)
    return np.array([c + half_m * (-across - along), c + half_m * (across - along), c + half_m * (across + along),
                     c + half_m * (-across + along)])


EYE_FOV_Y_DEG = 55.0  # the Rerun viewer's vertical field of view (its default eye)
_EYE_ASPECT = 1.4  # the 3D panel's width over height, at least (3/4 of a 16:9 window, under the timeline)
_EYE_FROM = np.array([0.9, 0.4, 0.35]) / np.linalg.norm([0.9, 0.4, 0.35])  # from the target toward the eye
_EYE_MARGIN = 1.1  # the framed points fill the view but for this much room
_EYE_STEPS = 4  # rounds of fitting the distance and centring the target (perspective makes them depend on each other)


def eye_world(points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the viewer's eye starts: (position, look target), world metres, framing the (N, 3) points (NaN rows
    ignored; none: 10 m ahead of the camera). It looks at them from the right (the camera's x), a little above and
    toward the camera, as close as lets every point fit the viewer's field of view (:data:`EYE_FOV_Y_DEG`; 10 %
    room), its target where they show centred: floating, sunk and leaning bodies show from there.

    >>> box = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (0.0, 1.8) for z in (-9.0, -7.0)])
    >>> position, target = eye_world(box)
    >>> target.round(2).tolist(), bool(position[1] > target[1]) and bool(position[2] > target[2]), round(float(np.linalg.norm(position - target)), 2)
    ([0.19, 0.58, -8.12], True, 3.13)
    """
    p = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if not len(p):
        p = np.array([[-5.0, 0.0, -10.0], [5.0, 2.0, 0.0]])
    right = np.cross(-_EYE_FROM, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -_EYE_FROM)
    tan_v = math.tan(math.radians(EYE_FOV_Y_DEG) / 2)
    half = np.array([_EYE_ASPECT * tan_v, tan_v])  # the view's half width and height at unit depth
    target = 0.5 * (p.min(axis=0) + p.max(axis=0))
    for _ in range(_EYE_STEPS):  # the eye as close as fits, then the target moved to the middle of what it sees
        rel = p - target
        toward, across = rel @ _EYE_FROM, np.stack([rel @ right, rel @ up], axis=1)  # (N,), (N, 2)
        distance = max(_EYE_MARGIN * float(np.max(toward + np.max(np.abs(across) / half, axis=1))), 1.0)
        seen = across / (distance - toward)[:, None]  # (N, 2) on the view at unit depth
        target = target + distance * (0.5 * (seen.min(axis=0) + seen.max(axis=0))) @ np.stack([right, up])
    return target + distance * _EYE_FROM, target


_ANCHOR_POINTS = 256  # a label's place is found from about this many of a person's points


def label_anchors_world(points_world: np.ndarray) -> np.ndarray:
    """(P, N, 3) each person's points (world) -> (P, 3) where its label goes: above its highest point, at
    the mean of its x and z (NaN for a person without finite points); from every k-th point of a large
    mesh (the label floats 15 cm above: a centimetre of the top missed does not show)."""
    p = np.asarray(points_world, dtype=np.float64)
    p = p[:, ::max(1, p.shape[1] // _ANCHOR_POINTS)] if p.ndim == 3 else p
    out = np.full((p.shape[0], 3), np.nan)
    if p.shape[0] == 0 or p.shape[1] == 0:
        return out
    finite = np.isfinite(p).all(axis=-1)  # (P, N)
    has = finite.any(axis=1)
    safe = np.where(finite[..., None], p, 0.0)
    count = np.maximum(finite.sum(axis=1), 1)[:, None]
    out[:, [0, 2]] = safe[..., [0, 2]].sum(axis=1) / count
    out[:, 1] = np.where(finite, p[..., 1], -np.inf).max(axis=1) + _LABEL_RAISE_M
    out[~has] = np.nan
    return out
