"""The pairs a fit receives, checked: shapes, finiteness, usable pairs, the point model, degenerate scenes.

Options are checked when a :class:`~.options.CalibrateOptions` is made; what depends on the data
(image size, pixels, frame and track indices, a principal point inside the image, whether the
people can determine a camera at all) is checked here, once, into a :class:`PairsInput`.

>>> feet = np.array([[100.0, 400.0], [300.0, 420.0], [500.0, 380.0]])
>>> box_derived(feet, feet - [0.0, 150.0]), box_derived(feet, feet - [2.0, 150.0])
(True, False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DegenerateSceneError
from .options import CalibrateOptions
from .params import param_vector
from .priors import Priors, default_priors
from .residuals import ResidualKind, residual_kind

__all__ = ["BOX_COLUMN_TOL_PX", "BOX_RESIDUAL", "PairsInput", "check_inputs", "free_slots", "at_one_depth",
           "box_derived", "resolve_points", "check_index"]

# Box-derived points: a box's top- and bottom-centre share one column exactly; landmark points
# (mid-sole, crown) of real people never do all at once (verticals converge, people sway).
BOX_COLUMN_TOL_PX = 0.5
BOX_RESIDUAL = "vertical"  # box-derived points use the head row only: a box's two centres share one column
# People at one depth (feet along one image row, up to a tilt of the roll's size) cannot tell the
# camera: no depth spread, no perspective. Why these numbers: a receding ground line images steeper
# than 10 deg; the feet of people at one depth scatter by their detection noise only (a few px),
# well under 10% of a person's pixel height.
_ONE_DEPTH_MAX_SLOPE = math.tan(math.radians(10.0))
_ONE_DEPTH_SPREAD = 0.10
# A box's bottom is the nearest toe or heel, up to ~0.45 m nearer than the mid-sole with the stride and the heading:
# people within that of one depth spread their box bottoms over ~30% of their pixel height for a camera looking
# 15-35 deg down at them (synthetic rows and walkers 4.3-5.0 m away, 3 m up: 10-13%; steeper cameras more).
_ONE_DEPTH_SPREAD_BOXES = 0.30


@dataclass(frozen=True)
class PairsInput:
    """Validated inputs of one fit."""

    size: tuple[int, int]  # (W, H) px
    feet: np.ndarray  # (N, 2) float64 px
    heads: np.ndarray  # (N, 2) float64 px
    usable: np.ndarray  # (N,) bool: head above the foot
    frames: np.ndarray | None  # (N,) int64
    tracks: np.ndarray | None  # (N,) int64
    pp: np.ndarray  # (2,) px: the given principal point, or the image centre
    priors: Priors | None  # the refinement's priors on the camera (None: the people alone, the grid)
    residual: ResidualKind  # as used: the head row for boxes
    points: str  # "landmarks" | "boxes" (auto resolved)
    one_depth: bool = False  # the usable pairs stand at about one depth (no perspective of their own)

    @property
    def n_usable(self) -> int:
        """Usable pairs."""
        return int(self.usable.sum())


def free_slots(options: CalibrateOptions, method: str) -> np.ndarray:
    """(6,) bool: the slots ``method`` estimates under ``options`` (the grid: focal unless given, pitch, height)."""
    refine = method == "refine"
    return param_vector(focal=options.focal_px is None, pitch=options.pitch_deg is None or not refine,
                        roll=refine and options.estimate_roll, height=True, distortion=refine and options.distortion,
                        box_depth=False, dtype=bool)


def fit_priors(options: CalibrateOptions, image_size: tuple[int, int]) -> Priors | None:
    """The refinement's priors on the camera (:mod:`.priors`); None for the paper grid."""
    if options.method != "refine":
        return None
    fov = None if options.fov_prior_deg is None else (options.fov_prior_deg, options.fov_prior_sd_deg)
    return default_priors(image_size, focal_prior=options.focal_prior, fov_prior_deg=fov,
                          camera_height_m=options.camera_height_m, person_height_m=options.person_height_m)


def check_inputs(feet_px, heads_px, image_size, options: CalibrateOptions, points: str, frame_index,
                 track_id) -> PairsInput:
    """The pairs as a :class:`PairsInput`, or ValueError (malformed) / DegenerateSceneError (no camera possible).

    feet_px, heads_px: (N, 2) px; image_size: (W, H) px; points: the point model, auto resolved;
    frame_index, track_id: (N,) int or None. With the priors on every free camera parameter (the
    refinement's default) one usable pair is enough: the priors answer what the pairs cannot, and
    the result says so; the people alone (the grid, ``focal_prior="none"``) need 3 pairs at 3
    places and some depth.
    """
    residual = residual_kind(BOX_RESIDUAL if points == "boxes" else options.residual)
    size = _check_image_size(image_size)
    feet, heads, usable = _check_points(feet_px, heads_px)
    frames = check_index(frame_index, len(feet), "frame_index")
    tracks = check_index(track_id, len(feet), "track_id")
    pp = np.array([size[0] / 2.0, size[1] / 2.0]) if options.principal_point is None \
        else np.asarray(options.principal_point, float)
    if not (0 <= pp[0] <= size[0] and 0 <= pp[1] <= size[1]):
        raise ValueError(f"principal_point ({pp[0]:g}, {pp[1]:g}) must lie inside the {size[0]}x{size[1]} image")
    priors = fit_priors(options, size)
    n_usable = int(usable.sum())
    free = free_slots(options, options.method)
    one_depth = at_one_depth(feet[usable], heads[usable],
                             _ONE_DEPTH_SPREAD_BOXES if points == "boxes" else _ONE_DEPTH_SPREAD)
    if n_usable == 0:
        raise DegenerateSceneError(f"no usable foot-head pair (of {len(feet)}): no one stands with the head above "
                                   "the foot")
    if priors is None or not priors.cover(free):
        _people_alone(feet[usable], heads[usable], n_usable, one_depth, residual, int(free.sum()))
    return PairsInput(size, feet, heads, usable, frames, tracks, pp, priors, residual, points, one_depth)


def _people_alone(feet: np.ndarray, heads: np.ndarray, n_usable: int, one_depth: bool, residual: ResidualKind,
                  n_free: int) -> None:
    """DegenerateSceneError when the usable pairs (N, 2) cannot determine a camera without priors."""
    if n_usable < 3:
        raise DegenerateSceneError(f"only {n_usable} usable foot-head pair{'s' * (n_usable != 1)} (need >= 3 "
                                   "without the lens prior)")
    n_places = len(np.unique(np.round(feet * 2.0), axis=0))
    if n_places < 3:
        raise DegenerateSceneError(f"the {n_usable} usable pairs stand at only {n_places} distinct foot positions "
                                   "(need >= 3 without the lens prior)")
    if one_depth:
        raise DegenerateSceneError(f"all {n_usable} usable pairs stand at about one depth (their feet lie along one "
                                   "image row): without the lens prior the people cannot determine the camera; give "
                                   "--focal, or use the lens prior (--focal-prior lens)")
    if n_usable * residual.dof < n_free:
        raise DegenerateSceneError(f"{n_usable} usable pairs with {residual.name} residuals cannot determine "
                                   f"{n_free} parameters; fix the focal length or add pairs")


def _check_image_size(image_size) -> tuple[int, int]:
    """(W, H) as positive ints, or ValueError."""
    try:
        w, h = (float(v) for v in image_size)
    except (TypeError, ValueError):
        raise ValueError(f"image_size must be [W, H] in pixels, got {image_size!r}") from None
    if not (math.isfinite(w) and math.isfinite(h) and w >= 1 and h >= 1):
        raise ValueError(f"image_size must be two positive numbers [W, H], got {image_size!r}")
    return int(round(w)), int(round(h))


def _check_points(feet_px, heads_px) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Float64 (N, 2) feet and heads and the (N,) mask of usable pairs (head above the foot)."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    if feet.ndim != 2 or feet.shape[1:] != (2,) or heads.shape != feet.shape:
        raise ValueError(f"feet_px and heads_px must both have shape (N, 2), got {feet.shape} and {heads.shape}")
    bad = ~(np.isfinite(feet).all(axis=1) & np.isfinite(heads).all(axis=1))
    if bad.any():
        raise ValueError(f"{int(bad.sum())} foot-head pairs have NaN or infinite pixels (first: pair "
                         f"{int(np.flatnonzero(bad)[0])}); drop them before calibrating")
    below = heads[:, 1] >= feet[:, 1]
    if len(feet) and below.sum() * 2 > len(feet):
        raise ValueError(f"the head is not above the foot (head v >= foot v) in {int(below.sum())} of {len(feet)} "
                         "pairs; image v points down, so heads need smaller v: are feet and heads swapped?")
    return feet, heads, ~below


def check_index(values, n: int, name: str) -> np.ndarray | None:
    """(N,) int64 array or None, or ValueError."""
    if values is None:
        return None
    arr = np.asarray(values)
    if arr.shape != (n,) or not (np.issubdtype(arr.dtype, np.integer) or n == 0):
        raise ValueError(f"{name} must be an (N,) integer array matching the {n} pairs, got {arr.dtype} {arr.shape}")
    return arr.astype(np.int64)


def at_one_depth(feet_px: np.ndarray, heads_px: np.ndarray, spread_fraction: float = _ONE_DEPTH_SPREAD) -> bool:
    """True when the feet (N, 2) px lie along one nearly level image line, within ``spread_fraction`` of a person's
    pixel height (a tenth for mid-sole points; box bottoms move with the stride)."""
    u, v = feet_px[:, 0], feet_px[:, 1]
    if len(u) < 3 or np.ptp(u) == 0:
        return len(u) >= 3 and np.ptp(v) < spread_fraction * np.median(np.linalg.norm(feet_px - heads_px, axis=1))
    slope, offset = np.polyfit(u, v, 1)
    residual = v - (slope * u + offset)
    spread = float(np.subtract(*np.percentile(residual, [95, 5])))
    length = float(np.median(np.linalg.norm(feet_px - heads_px, axis=1)))
    return abs(slope) < _ONE_DEPTH_MAX_SLOPE and spread < spread_fraction * length


def box_derived(feet_px: np.ndarray, heads_px: np.ndarray, tol_px: float = BOX_COLUMN_TOL_PX) -> bool:
    """True when every finite pair (N, 2) px has its head in its foot's column (boxes' centres), N >= 3."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    finite = np.all(np.isfinite(feet), axis=1) & np.all(np.isfinite(heads), axis=1) if feet.ndim == 2 else []
    du = np.abs(feet[finite, 0] - heads[finite, 0]) if len(finite) else np.zeros(0)
    return len(du) >= 3 and bool(np.all(du <= tol_px))


def resolve_points(feet_px: np.ndarray, heads_px: np.ndarray, points: str, method: str) -> tuple[str, list[str]]:
    """The point model (``points``, or for ``"auto"`` what the pairs look like) and a note saying what
    was decided, if anything."""
    if points != "auto":
        return points, []
    if not box_derived(feet_px, heads_px):
        return "landmarks", []
    if method == "grid":
        return "landmarks", ["every pair's head is in its foot's column (box-derived points?), but the paper grid "
                             "knows only mid-sole and crown points: use --method refine for the box model"]
    return "boxes", ["every pair's head is in its foot's column: box-derived points (bottom- and top-centre of "
                     "person boxes); using the box model (--points landmarks to override)"]

