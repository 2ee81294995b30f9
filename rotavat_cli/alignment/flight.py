"""Who is in the air: a tracked person's foot elevation from the pixels, and the frames it is off the ground.

RotAvat puts every person's foot point on the ground. A person who jumps (or runs through a flight
phase, or is lifted) is not on it: flattened onto the ground, the body slides away along the foot's
ray and its implied stature swings (on a jump, 1.55-1.80 m). With a track and a camera, the track's
own stature says where the person is instead.

**Elevation.** A person of stature ``S`` standing upright (along the ground normal ``n``) with the foot
point at height ``e`` above the ground has its foot on the foot pixel's ray at ``F(e) = a + e b``
(``a`` where the ray meets the ground, ``b = r / (n . r)``) and its crown at ``F(e) + S n``. The
elevation that puts the crown nearest the crown pixel's ray (least squares on the distance to that
ray, closed form, vectorised over rows) is the person's height above the ground in that frame:
:func:`foot_elevation_m`. On the ground (the pixels of a person of stature ``S``) it is 0.

**Noise.** A frame's stature as drawn wobbles (the HPS tool's size and pose noise); at elevation 0
that wobble reads as an elevation ``dS * de/dS``, and ``de/dS`` grows as the camera looks more
steeply down (the foot's ray then runs along the vertical). The track's stature is the median of its
standing frames' ground statures (people.csv's ``stature_m`` of rows without a flag) and its wobble
``sigma_S`` their MAD (x 1.4826; at least :data:`MIN_STATURE_SD_M`), both taken again without the
frames that first look airborne (a jump's own frames would raise both). A frame is **airborne** when
its elevation exceeds both :data:`MIN_ELEVATION_M` and :data:`NOISE_SIGMAS` ``sigma_S |de/dS|``.

**Landing.** Two pixels cannot tell a person lifted by ``e`` from one drawn a little taller (an HPS
tool's size error): both move the crown's pixel away from the foot's. The frames around can: a jump
lifts the foot's pixel while the person stays over the spot of its take-off and landing frames, so
read as on the ground its frames slide away along the foot's ray; a person drawn taller keeps its
foot pixel, so read as in the air it slides toward the camera. A run of at least
:data:`MIN_FLIGHT_FRAMES` consecutive airborne frames of the track (a gap in the track ends a run; a
10 cm jump is 0.29 s in the air, 8 frames at 30 fps) is a **flight** when its positions in the air
stay nearer that spot (interpolated between the frames just before and after the run, or the one
there is) than its positions on the ground.

Measured (tests/test_support.py): a synthetic 0.40 m jump seen from 5 m up, 25 deg down (|de/dS| 2.7),
its stature drawn with 0.5 % noise: the threshold is 9-10 cm, frames 1-8 of its 10 in the air are
flight, placed within 4.6 cm of their height (the track's stature is 1 cm off: x2.7); with 1 % noise,
frames 2-7 (within 10 cm); with 2 %, none. On /work/shared/realfiles: HybrIK's dancer reads 7-11 cm up
in its first 6 frames (threshold 7 cm, |de/dS| 0.7), but those frames stay where they are on the ground:
a size error, not flight; 4D-Humans' walker: none (threshold 7.7 cm); GVHMR's tennis player: none (its
wobble through his crouches, 6.3 cm x |de/dS| 1.5, puts the threshold at 28.5 cm; one frame over it).

Limits: a person must have a track (``person_ids``) with standing frames; a run shorter than
:data:`MIN_FLIGHT_FRAMES` is not flagged (a runner's flight phase at a low frame rate); the
elevation assumes the body upright at the track's stature, so a tucked jump reads lower than it is.

>>> up = np.array([0.0, -1.0, 0.0])                                    # camera 3 m up, level
>>> foot = np.array([[0.0, 3.0, 10.0], [0.0, 2.7, 10.0]])             # a foot on the ground; one 0.3 m up
>>> crown = foot - [0.0, 1.7, 0.0]
>>> e, slope = foot_elevation_m(foot, crown, up, 3.0, np.array([1.7, 1.7]))
>>> e.round(6).tolist()
[0.0, 0.3]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MIN_ELEVATION_M", "MIN_FLIGHT_FRAMES", "MIN_STATURE_SD_M", "NOISE_SIGMAS", "TrackRows", "flight_rows",
           "foot_elevation_m"]

MIN_ELEVATION_M = 0.05  # below this nobody is "in the air" for the picture (a heel lift, a sole's thickness)
NOISE_SIGMAS = 3.0  # an elevation this many noise sigmas above 0 is not the track's wobble
MIN_STATURE_SD_M = 0.01  # the wobble of a track drawn without noise (synthetic) is not 0 for the rule
MIN_FLIGHT_FRAMES = 3  # consecutive airborne frames: one or two over the line are noise
_MAD_TO_SD = 1.4826


def _ground_and_lift(foot_rays_cam: np.ndarray, up_cam: np.ndarray, ground_offset_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Where each foot ray (N, 3) meets the ground, ``a`` (N, 3), and how the foot moves along its ray per metre
    above the ground, ``b = r / (n . r)`` (N, 3); NaN rows for rays that never meet the ground in front."""
    foot = np.asarray(foot_rays_cam, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        along = foot @ up_cam
        per_m = np.where((along < 0)[:, None], foot / along[:, None], np.nan)
    return -ground_offset_m * per_m, per_m


def foot_elevation_m(foot_rays_cam: np.ndarray, head_rays_cam: np.ndarray, up_cam: np.ndarray,
                     ground_offset_m: float, stature_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foot height above the ground (N,) of upright people of stature (N,) drawn on these rays, and its
    sensitivity de/dS (N,) to the stature (module docstring).

    foot_rays_cam, head_rays_cam: (N, 3) directions (any norm) of the foot and crown pixels, camera frame;
    up_cam: (3,) ground normal; ground_offset_m: ``h`` in ``n . X + h = 0`` (the camera's height).
    NaN for rays that never meet the ground in front of the camera, or parallel foot and crown rays.
    """
    n = np.asarray(up_cam, dtype=np.float64)
    n = n / np.linalg.norm(n)
    ground, per_m = _ground_and_lift(foot_rays_cam, n, ground_offset_m)
    head = np.asarray(head_rays_cam, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        head = head / np.linalg.norm(head, axis=-1, keepdims=True)

        def off_ray(v: np.ndarray) -> np.ndarray:  # the part of v (N, 3) across the crown ray
            return v - np.einsum("ni,ni->n", v, head)[:, None] * head

        b_perp = off_ray(per_m)
        denom = np.einsum("ni,ni->n", b_perp, b_perp)
        crown_at_ground = off_ray(ground + np.asarray(stature_m, dtype=np.float64)[:, None] * n)
        elevation = -np.einsum("ni,ni->n", b_perp, crown_at_ground) / denom
        slope = -np.einsum("ni,ni->n", b_perp, off_ray(np.broadcast_to(n, head.shape))) / denom
    ok = np.isfinite(elevation) & np.isfinite(slope) & (denom > 0)
    return np.where(ok, elevation, np.nan), np.where(ok, slope, np.nan)


@dataclass(frozen=True)
class TrackRows:
    """What flight detection reads of every person-frame of a sequence (people.csv rows, in order).

    frame_index: (N,) int, the frame's position in the sequence; person_id: (N,) int, the track;
    standing: (N,) bool, aligned with no flag (the rows the track's stature comes from);
    candidate: (N,) bool, rows that may be airborne (aligned, standing by their joints);
    stature_m: (N,) float, the stature with the foot on the ground; foot_rays_cam, head_rays_cam: (N, 3).
    """

    frame_index: np.ndarray
    person_id: np.ndarray
    standing: np.ndarray
    candidate: np.ndarray
    stature_m: np.ndarray
    foot_rays_cam: np.ndarray
    head_rays_cam: np.ndarray


def _group_median(values: np.ndarray, groups: np.ndarray, n_groups: int) -> np.ndarray:
    """(G,) the median of ``values`` (N,) within each group (``groups`` (N,) in [0, G)); NaN for an empty group.
    Vectorised: one sort by (group, value), then each group's middle element(s)."""
    order = np.lexsort((values, groups))
    counts = np.bincount(groups, minlength=n_groups)
    starts = np.cumsum(counts) - counts
    sorted_values = values[order]
    lo, hi = starts + (counts - 1) // 2, starts + counts // 2
    filled = counts > 0
    median = np.full(n_groups, np.nan)
    median[filled] = 0.5 * (sorted_values[lo[filled]] + sorted_values[hi[filled]])
    return median


def _track_stature_m(stature_m: np.ndarray, usable: np.ndarray, inverse: np.ndarray,
                     n_tracks: int) -> tuple[np.ndarray, np.ndarray]:
    """Each track's stature (median of its ``usable`` rows' statures) and wobble (MAD x 1.4826, floored): (T,)
    each; NaN for a track without usable rows."""
    usable = usable & np.isfinite(stature_m)
    values, groups = stature_m[usable], inverse[usable]
    stature = _group_median(values, groups, n_tracks)
    spread = _group_median(np.abs(values - stature[groups]), groups, n_tracks)
    return stature, np.maximum(_MAD_TO_SD * spread, MIN_STATURE_SD_M)


def _runs(flags: np.ndarray, breaks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and lengths (R,) of the runs of equal ``flags`` (N,); a run also ends where ``breaks`` (N,) is True
    (a new track, a gap in frames)."""
    starts = np.flatnonzero(breaks | np.r_[True, flags[1:] != flags[:-1]])
    return starts, np.diff(np.r_[starts, len(flags)])


def _landing_checked(runs: tuple[np.ndarray, np.ndarray], breaks: np.ndarray, on_ground: np.ndarray,
                     in_air: np.ndarray) -> np.ndarray:
    """(R,) bool: runs whose people stay where their neighbouring frames stand if they are in the air, rather
    than if they are on the ground.

    The pixels alone cannot tell a person lifted by ``e`` from one drawn a little taller; the frames around
    can: a jump leaves the foot's pixel rising while the person stays over the same spot (the take-off and
    landing frames' spot, interpolated), so put on the ground its frames slide away along the foot's ray; a
    person drawn taller keeps its foot pixel, so put in the air it slides toward the camera. on_ground,
    in_air: (N, 3) horizontal positions of each row's foot under the two readings, sorted like ``breaks``.
    """
    starts, lengths = runs
    stops = starts + lengths
    n_rows = len(breaks)
    before = np.where((starts > 0) & ~breaks[starts], starts - 1, -1)  # the track's frame just before the run
    after = np.where(stops < n_rows, stops, -1)
    after = np.where((after >= 0) & ~breaks[np.clip(after, 0, n_rows - 1)], after, -1)
    run = np.repeat(np.arange(len(starts)), lengths)
    share = (np.arange(n_rows) - starts[run] + 1) / (lengths[run] + 1.0)  # where in the run, 0..1
    first, last = on_ground[before[run]], on_ground[after[run]]
    first = np.where((before[run] >= 0)[:, None], first, last)  # one side only: that side's spot
    last = np.where((after[run] >= 0)[:, None], last, first)
    spot = first + share[:, None] * (last - first)
    alone = (before[run] < 0) & (after[run] < 0)  # no neighbouring frame: nothing to compare with
    air_off = np.where(alone, np.inf, np.linalg.norm(in_air - spot, axis=-1))
    ground_off = np.where(alone, 0.0, np.linalg.norm(on_ground - spot, axis=-1))
    with np.errstate(invalid="ignore"):
        return np.add.reduceat(air_off, starts) < np.add.reduceat(ground_off, starts)


def flight_rows(rows: TrackRows, up_cam: np.ndarray, ground_offset_m: float) -> np.ndarray:
    """(N,) the foot's elevation (m) of rows in flight (module docstring), NaN for every other row."""
    n_rows = len(rows.frame_index)
    if n_rows == 0:
        return np.zeros(0)
    n = np.asarray(up_cam, dtype=np.float64) / np.linalg.norm(up_cam)
    tracks, inverse = np.unique(rows.person_id, return_inverse=True)
    usable = rows.standing
    for _ in range(2):  # the track's stature from its standing rows, then from those of them that look grounded
        stature, wobble = _track_stature_m(rows.stature_m, usable, inverse, len(tracks))
        elevation, slope = foot_elevation_m(rows.foot_rays_cam, rows.head_rays_cam, n, ground_offset_m,
                                            stature[inverse])
        with np.errstate(invalid="ignore"):
            above = elevation > np.maximum(MIN_ELEVATION_M, NOISE_SIGMAS * wobble[inverse] * np.abs(slope))
        usable = rows.standing & ~above
    airborne = rows.candidate & above
    ground, per_m = _ground_and_lift(rows.foot_rays_cam, n, ground_offset_m)
    flat = lambda p: p - (p @ n)[:, None] * n  # noqa: E731  (horizontal part)
    on_ground, in_air = flat(ground), flat(ground + np.nan_to_num(elevation)[:, None] * per_m)
    order = np.lexsort((rows.frame_index, inverse))  # by track, then by frame
    track_sorted, frame_sorted = inverse[order], rows.frame_index[order]
    breaks = np.r_[True, (track_sorted[1:] != track_sorted[:-1]) | (np.diff(frame_sorted) != 1)]
    starts, lengths = _runs(airborne[order], breaks)
    in_flight = airborne[order][starts] & (lengths >= MIN_FLIGHT_FRAMES)
    in_flight &= _landing_checked((starts, lengths), breaks, on_ground[order], in_air[order])
    flight = np.zeros(n_rows, dtype=bool)
    flight[order] = np.repeat(in_flight, lengths)
    return np.where(flight, elevation, np.nan)
