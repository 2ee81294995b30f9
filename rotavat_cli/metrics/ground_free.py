"""Ground-free world measures of people filmed by a static camera: pure arrays, no I/O.

Without ground truth a reconstruction can still be held to what the scene says of itself: people
stand on the ground and upright, a foot in contact with the ground stays put, a person's stature
does not change, and bodies do not shake. Every function takes **people-frames as rows**: one row
per person and frame, in any order, in the world frame of the scene camera (docs/conventions.md,
"World frame": metres, ``Y`` up, the ground is ``Y = 0``); the temporal ones also take each row's
track id and frame index (the frame's position in the sequence). They are vectorised over rows,
people and frames at once (a sort, never a loop over people), compute in float64, and leave NaN
rows (a person without a foot point) out of each measure.

The measures (docs/metrics.md, "Without ground truth", defines them with their sources):

- :func:`feet_height_summary`: the foot point's height above the ground (mean and median of its
  magnitude, the share floating over :data:`FLOATING_M`, the share sunk under :data:`SINKING_M`, the
  mean depth under the ground);
- :func:`contact_sliding_m`: horizontal displacement of each sole between consecutive frames of a
  track while both frames have it within :data:`CONTACT_M` of the ground (GMD's contact rule, both ways);
- :func:`acceleration_m`: mean over points of ``|p[t] - 2 p[t+1] + p[t+2]|`` over three consecutive
  frames of a track (:func:`.temporal.second_differences`);
- :func:`lean_summary`: the foot -> crown axis's angle from world up, mean and 90th percentile;
- :func:`stature_summary`: each track's median foot -> crown length and its spread, and the spread
  across people (:func:`rotavat_cli.bodies.measure.statures_by_track`).

Examples
--------
A person 10 cm in the air in one frame and 3 cm in the ground in the next (rows: foot heights, m):

>>> {k: round(v, 6) for k, v in feet_height_summary(np.array([0.10, -0.03])).items()}
{'feet_height': 65.0, 'feet_height_median': 65.0, 'floating_pct': 50.0, 'penetration_pct': 50.0, 'penetration_depth': 15.0}
"""

from __future__ import annotations

import numpy as np

from ..bodies.measure import TrackStatures, statures_by_track
from .temporal import second_differences

__all__ = ["FLOATING_M", "SINKING_M", "CONTACT_M", "UP_WORLD", "consecutive_windows", "feet_height_summary",
           "contact_sliding_m", "acceleration_m", "lean_summary", "stature_summary"]

# A foot point more than this above the ground floats: align's own threshold for a person in the air
# (alignment/flight.py: 5 cm and 3 times the track's noise).
FLOATING_M = 0.05
# A foot point more than this under the ground is sunk into it: a sole is ~1 cm thick, and an aligned
# foot point is on the ground to float32 storage (~1e-6 m), so nothing aligned counts as sunk.
SINKING_M = 0.01
# A sole this close to the ground (above or under it) in two consecutive frames is in contact: GMD's
# ``thresh_height`` (korrawe/guided-motion-diffusion @7bc73c0, data_loaders/humanml/utils/metrics.py,
# ``calculate_skating_ratio``).
CONTACT_M = 0.05
UP_WORLD = np.array([0.0, 1.0, 0.0])  # world up (docs/conventions.md): heights are Y


def consecutive_windows(track_ids: np.ndarray, frame_index: np.ndarray, length: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows of every window of ``length`` consecutive frames of one track.

    track_ids, frame_index: (N,) int, one per row (any order; a track appears at most once per frame).
    Returns ``order`` (N,), the rows sorted by track then frame, and ``starts`` (W,), the positions in
    ``order`` where a window starts: rows ``order[starts + k]`` for ``k < length`` are one track at frames
    ``f, f + 1, ..., f + length - 1``. A track missing from a frame breaks its windows there.

    >>> order, starts = consecutive_windows(np.array([7, 7, 7, 3, 7]), np.array([0, 1, 2, 1, 4]), 2)
    >>> order.tolist(), starts.tolist()
    ([3, 0, 1, 2, 4], [1, 2])
    """
    ids = np.asarray(track_ids).astype(np.int64, copy=False)
    frames = np.asarray(frame_index).astype(np.int64, copy=False)
    if ids.ndim != 1 or frames.shape != ids.shape:
        raise ValueError(f"track_ids and frame_index must be (N,) alike, got {ids.shape} and {frames.shape}")
    if length < 1:
        raise ValueError(f"length must be at least 1, got {length}")
    order = np.lexsort((frames, ids))
    ids, frames = ids[order], frames[order]
    n_windows = max(len(ids) - length + 1, 0)
    ok = np.ones(n_windows, dtype=bool)
    for k in range(1, length):
        ok &= (ids[k:k + n_windows] == ids[:n_windows]) & (frames[k:k + n_windows] == frames[:n_windows] + k)
    return order, np.flatnonzero(ok)


def feet_height_summary(foot_height_m: np.ndarray) -> dict[str, float]:
    """Where the foot points are against the ground: (N,) heights, m -> report values.

    foot_height_m: (N,) signed height of each row's foot point (ground contact) above the ground,
    metres; NaN rows are left out. Returns ``feet_height`` (mean ``|h|``, mm), ``feet_height_median``
    (median ``|h|``, mm), ``floating_pct`` (% of rows with ``h > FLOATING_M``), ``penetration_pct`` (% of
    rows with ``h < -SINKING_M``) and ``penetration_depth`` (mean over the rows of ``max(0, -h)``, mm: 0 for
    a row on or above the ground). All NaN when no row has a height.
    """
    h = np.asarray(foot_height_m, dtype=np.float64)
    if h.ndim != 1:
        raise ValueError(f"foot_height_m must be (N,), got {h.shape}")
    h = h[np.isfinite(h)]
    keys = ("feet_height", "feet_height_median", "floating_pct", "penetration_pct", "penetration_depth")
    if h.size == 0:
        return dict.fromkeys(keys, float("nan"))
    return {"feet_height": float(np.abs(h).mean() * 1000.0), "feet_height_median": float(np.median(np.abs(h)) * 1000.0),
            "floating_pct": float(100.0 * np.mean(h > FLOATING_M)), "penetration_pct": float(100.0 * np.mean(h < -SINKING_M)),
            "penetration_depth": float(np.maximum(-h, 0.0).mean() * 1000.0)}


def contact_sliding_m(soles_world: np.ndarray, track_ids: np.ndarray, frame_index: np.ndarray,
                      contact_m: float = CONTACT_M) -> np.ndarray:
    """Horizontal displacement of each sole in contact between consecutive frames, metres/frame.

    soles_world: (N, S, 3) the rows' sole points (S = 2: left and right; any lowest foot points),
    world frame, metres; track_ids, frame_index: (N,) int. A sole is in contact over frames ``t, t + 1``
    of a track when it is within ``contact_m`` of the ground in both, above or under it (GMD's rule, which
    has no lower bound: its motions never sink far; an HPS output can be metres under the ground, and a
    sole 10 m down is not in contact). With two soles, each is followed to the nearer of the next frame's two (the
    assignment with the smaller summed 3D distance): a mesh whose soles come from its geometry does not
    say which is left (rotavat_cli.bodies.landmarks). Returns (C,) the displacement in the ground plane
    ``|(dX, dZ)|`` of every (frame pair, sole) in contact, track-major; divide by the frame interval for m/s.
    """
    soles = np.asarray(soles_world, dtype=np.float64)
    if soles.ndim != 3 or soles.shape[-1] != 3 or soles.shape[0] != np.shape(track_ids)[0]:
        raise ValueError(f"soles_world must be (N, S, 3) with N = len(track_ids), got {soles.shape}")
    order, starts = consecutive_windows(track_ids, frame_index, 2)
    first, second = soles[order[starts]], soles[order[starts + 1]]
    if soles.shape[1] == 2:  # follow each sole to the nearer one of the next frame
        swapped = second[:, ::-1]
        with np.errstate(invalid="ignore"):
            swap = (np.linalg.norm(swapped - first, axis=-1).sum(-1) < np.linalg.norm(second - first, axis=-1).sum(-1))
        second = np.where(swap[:, None, None], swapped, second)
    with np.errstate(invalid="ignore"):
        contact = (np.abs(first[..., 1]) < contact_m) & (np.abs(second[..., 1]) < contact_m)  # NaN: not in contact
    step = second - first
    return np.hypot(step[..., 0], step[..., 2])[contact]


def acceleration_m(points_world: np.ndarray, track_ids: np.ndarray, frame_index: np.ndarray) -> np.ndarray:
    """Acceleration magnitude of each window of 3 consecutive frames of a track, metres/frame^2.

    points_world: (N, J, 3) each row's points (joints), world frame (any fixed frame: the norm does not
    change under a rigid motion), metres; track_ids, frame_index: (N,) int. Returns (W,) the mean over the
    J points of ``|p[t] - 2 p[t+1] + p[t+2]|`` (:func:`.temporal.second_differences`), one per window,
    track-major; NaN where a point is. Multiply by fps^2 for m/s^2.
    """
    points = np.asarray(points_world, dtype=np.float64)
    if points.ndim != 3 or points.shape[-1] != 3 or points.shape[0] != np.shape(track_ids)[0]:
        raise ValueError(f"points_world must be (N, J, 3) with N = len(track_ids), got {points.shape}")
    order, starts = consecutive_windows(track_ids, frame_index, 3)
    if points.shape[0] < 3:
        return np.zeros(0)
    accel = second_differences(points[order])[starts]  # (W, J, 3)
    return np.linalg.norm(accel, axis=-1).mean(axis=-1)


def lean_summary(lean_deg: np.ndarray) -> dict[str, float]:
    """Mean and 90th percentile (numpy's linear interpolation) of (N,) lean angles, degrees; NaN rows left out."""
    lean = np.asarray(lean_deg, dtype=np.float64)
    lean = lean[np.isfinite(lean)]
    if lean.size == 0:
        return {"lean": float("nan"), "lean_p90": float("nan")}
    return {"lean": float(lean.mean()), "lean_p90": float(np.percentile(lean, 90.0))}


def stature_summary(stature_m: np.ndarray, track_ids: np.ndarray | None) -> tuple[dict[str, float], TrackStatures | None]:
    """Statures pooled per track, and across the people.

    stature_m: (N,) each row's foot -> crown length, metres; track_ids: (N,) int, or None when the
    sequence has no track ids (each row is then a person of its own). Returns the report values and
    the per-track table (None without ids): ``stature`` (m, the median over tracks of each track's
    median), ``stature_spread`` (mm, the mean over tracks of each track's half interquartile range over its
    frames: 0 for a constant stature), ``stature_sd`` (mm, the standard deviation across tracks of their
    medians, ddof 0: how different the people are).

    >>> values, tracks = stature_summary(np.array([1.70, 1.70, 1.60, 1.80, 1.70, 1.90]), np.array([1, 1, 1, 2, 2, 2]))
    >>> {k: round(v, 6) for k, v in values.items()}, tracks.median_m.tolist()
    ({'stature': 1.75, 'stature_spread': 37.5, 'stature_sd': 50.0}, [1.7, 1.8])
    """
    statures = np.asarray(stature_m, dtype=np.float64)
    if statures.ndim != 1:
        raise ValueError(f"stature_m must be (N,), got {statures.shape}")
    if track_ids is None:
        finite = statures[np.isfinite(statures)]
        if finite.size == 0:
            return dict.fromkeys(("stature", "stature_spread", "stature_sd"), float("nan")), None
        return {"stature": float(np.median(finite)), "stature_spread": float("nan"),
                "stature_sd": float(np.std(finite) * 1000.0)}, None
    tracks = statures_by_track(statures, np.asarray(track_ids))
    medians, spreads = tracks.median_m[tracks.pairs > 0], tracks.spread_m[tracks.pairs > 0]
    if medians.size == 0:
        return dict.fromkeys(("stature", "stature_spread", "stature_sd"), float("nan")), tracks
    return {"stature": float(np.median(medians)), "stature_spread": float(spreads.mean() * 1000.0),
            "stature_sd": float(np.std(medians) * 1000.0)}, tracks
