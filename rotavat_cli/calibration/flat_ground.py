"""One flat ground, checked: does a fitted camera's world hold upright people of one stature on one plane?

The calibration's model is upright people of similar stature on one flat ground. Stairs, a raised
back row, a person held in arms, a giant (a detection that is not a whole person) or a model that
does not fit at all break it, and the fit still returns a camera. What that camera implies says so:
each pair's **implied stature** (:func:`rotavat_cli.bodies.measure.statures_from_camera_m`: the height of
the point of the person's vertical nearest the head pixel, over the stature the fit assumed), looked
at three ways (:func:`ground_findings`):

- **as a whole**: the head residual against the people's own pixel heights: the robust spread of
  the implied statures. Real adults spread by 4% (sd 7 cm); noise and posture add a little; a
  spread of :data:`WHOLE_SPREAD_MAX` (25%) means the model does not describe these people at all
  (a wrong body model, people cut by the border, a wrong camera family);
- **by region**: the pairs' feet binned in a 3 x 3 grid over the image, and split in two at each
  decile of their image rows (a back row on a step is a band of rows, not a cell); a cell or a side
  holding :data:`REGION_MIN_PEOPLE` people or more whose median implied stature differs from the
  others' by over :data:`REGION_SHIFT_MIN` (8%: ~14 cm, three times the spread of a group's mean of 3
  adults) and by over :data:`SIGNIFICANCE` times its standard error: people there stand higher or
  lower than the rest (steps, stairs, a stage, a raised row);
- **by person**: a person (a track, else a pair) whose median implied stature lies beyond
  :data:`PERSON_RATIO_RANGE` of the median person (0.75-1.33: a 1.70 m median reads under 1.28 m or
  over 2.26 m): a child, a person held in arms or sitting, a detection of part of a person.

Each finding names the people or the region, says what it may be and what to do. A finding weighs
on the camera when the people it concerns hold :data:`IMPLAUSIBLE_SHARE` (a quarter) of the pairs
the fit kept (and, for a region, stand :data:`IMPLAUSIBLE_SHIFT`, 10%, or more off the others, with five
people on each side), or
always for the whole-model spread: it is then also a plausibility finding (:mod:`.plausibility`).

>>> from rotavat_cli.geometry.camera import Camera
>>> cam = Camera((1280, 720), 900.0, None, np.deg2rad(20.0), 0.0, 4.0)
>>> rng = np.random.default_rng(0)
>>> feet = np.stack([rng.uniform(100, 1180, 60), rng.uniform(400, 700, 60)], 1)
>>> ground = cam.backproject_px_to_ground(feet)
>>> heads = cam.project(ground + 1.7 * cam.up_cam)
>>> ground_findings(feet, heads, cam, 1.7, np.arange(60), np.ones(60, bool))
()
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera
from ..bodies.measure import statures_by_track, statures_from_camera_m

__all__ = ["WHOLE_SPREAD_MAX", "REGION_SHIFT_MIN", "REGION_MIN_PEOPLE", "SIGNIFICANCE", "PERSON_RATIO_RANGE",
           "IMPLAUSIBLE_SHARE", "IMPLAUSIBLE_SHIFT", "IMPLAUSIBLE_MIN_PEOPLE", "GroundFinding", "implied_ratios", "ground_findings"]

WHOLE_SPREAD_MAX = 0.25  # robust sd of the implied stature ratios beyond which the model does not hold
REGION_SHIFT_MIN = 0.08  # a region's median implied stature this far (ratio) from the others'
REGION_MIN_PEOPLE = 3  # people (tracks, else pairs) a region needs to be judged
SIGNIFICANCE = 4.0  # ... and its shift over its standard error
PERSON_RATIO_RANGE = (0.75, 1.0 / 0.75)  # a person's implied stature over the median person's
IMPLAUSIBLE_SHARE = 0.25  # findings about people holding this share of the kept pairs make the camera implausible
IMPLAUSIBLE_SHIFT = 0.10  # ... for a region, when its people stand this much higher or lower (~17 cm: a step) ...
IMPLAUSIBLE_MIN_PEOPLE = 5  # ... and each side holds this many people (3 short people near the camera are a warning)
_GRID = 3  # regions: a 3 x 3 grid over the image
_MAD_TO_SD = 1.4826  # median absolute deviation -> sd for normal data
# The spread the significance uses is at least real adults' (a sd of 7 cm on 1.70 m, the stature prior's): a few
# people's own spread about their median says little (12 walkers in one frame: 1 clean scene of 72 had 4 people
# "10% shorter" at 4 of their own sd); a median of n people has a standard error 1.2533 sd / sqrt(n).
_MIN_SPREAD = 0.07 / 1.70
_MEDIAN_SE = 1.2533
_SHOWN = 8  # ids named in a message


@dataclass(frozen=True)
class GroundFinding:
    """One finding: its message, the share of the kept pairs it concerns, and whether it weighs on the camera."""

    message: str
    share: float
    implausible: bool


def implied_ratios(feet_px: np.ndarray, heads_px: np.ndarray, camera: Camera, stature_m: float) -> np.ndarray:
    """(N,) each pair's implied stature under ``camera`` over ``stature_m`` (NaN where it cannot be measured)."""
    return statures_from_camera_m(feet_px, heads_px, camera) / stature_m


def _robust_sd(values: np.ndarray) -> float:
    """Scaled median absolute deviation of (n,) values (NaN for none)."""
    if not len(values):
        return math.nan
    return float(_MAD_TO_SD * np.median(np.abs(values - np.median(values))))


def _per_person(log_ratio: np.ndarray, people: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each person's median log ratio: (ids (T,), medians (T,), pair counts (T,)) (:func:`statures_by_track`)."""
    per = statures_by_track(log_ratio, np.asarray(people, dtype=np.int64))
    return per.ids, per.median_m, per.pairs


def _whole(log_ratio: np.ndarray) -> GroundFinding | None:
    """The implied statures' spread as a whole (module docstring)."""
    spread = math.expm1(_robust_sd(log_ratio))
    if not spread > WHOLE_SPREAD_MAX:
        return None
    return GroundFinding(f"the people's implied statures spread by {100 * spread:.0f}% (robust sd; real adults: 4%): "
                         "upright people of one stature on one flat ground do not describe these pairs (people cut "
                         "by the image border, not standing, a wrong body model or image size: rotavat info, "
                         "rotavat render)", 1.0, True)


def _regions(feet_px: np.ndarray, log_ratio: np.ndarray, people: np.ndarray, image_size: tuple[int, int],
             n_kept: int) -> list[GroundFinding]:
    """Grid cells whose people stand higher or lower than the others (module docstring)."""
    W, H = image_size
    col = np.clip((feet_px[:, 0] / W * _GRID).astype(int), 0, _GRID - 1)
    row = np.clip((feet_px[:, 1] / H * _GRID).astype(int), 0, _GRID - 1)
    cell = row * _GRID + col
    out = []
    for c in np.unique(cell):
        inside = cell == c
        n_people = len(np.unique(people[inside]))
        found = _shift(log_ratio, people, inside)
        if found is None:
            continue
        shift, fewer = found[0], found[2]
        r, k = divmod(int(c), _GRID)
        x0, x1, y0, y1 = (round(k * W / _GRID), round((k + 1) * W / _GRID), round(r * H / _GRID),
                          round((r + 1) * H / _GRID))
        share = float(inside.sum()) / n_kept
        what = "taller" if shift > 0 else "shorter"
        why = "higher" if shift > 0 else "lower"
        out.append(GroundFinding(
            f"the {n_people} people with their feet in the image region x {x0}-{x1}, y {y0}-{y1} px measure "
            f"{100 * math.expm1(abs(shift)):.0f}% {what} than the others: they stand {why} than the ground the "
            "others share (a step, stairs, a stage or a raised row), or the ground is not flat; calibrate from "
            "the people on one level (--track ID ...)", share, _weighs(share, shift, fewer)))
    return out


def _shift(log_ratio: np.ndarray, people: np.ndarray, inside: np.ndarray) -> tuple[float, float, int] | None:
    """The median person's log ratio inside minus outside (``inside`` (N,) bool), when both sides hold
    :data:`REGION_MIN_PEOPLE` people and it passes both thresholds (module docstring); else None. Its
    standard error comes from the people's spread about their own side's median (a two-sample test: the
    shift itself is not spread)."""
    if inside.all() or not inside.any():
        return None
    _, here, _ = _per_person(log_ratio[inside], people[inside])
    _, there, _ = _per_person(log_ratio[~inside], people[~inside])
    if len(here) < REGION_MIN_PEOPLE or len(there) < REGION_MIN_PEOPLE:
        return None
    shift = float(np.median(here) - np.median(there))
    spread = max(_robust_sd(np.concatenate([here - np.median(here), there - np.median(there)])), _MIN_SPREAD)
    error = _MEDIAN_SE * spread * math.sqrt(1.0 / len(here) + 1.0 / len(there))
    if abs(shift) < math.log1p(REGION_SHIFT_MIN) or abs(shift) < SIGNIFICANCE * error:
        return None
    return shift, abs(shift) / error, min(len(here), len(there))


def _weighs(share: float, shift: float, fewer: int) -> bool:
    """Whether a region's finding weighs on the camera: its people hold a quarter of the pairs and stand
    :data:`IMPLAUSIBLE_SHIFT` or more off the others, with :data:`IMPLAUSIBLE_MIN_PEOPLE` people on each side
    (``fewer``: the smaller side). Three short people near the camera, 13% under the other 6 of a synthetic crowd
    under its right camera, are a warning; a back row of 10 on a 0.35 m step, 11-13% over the front row of 10
    under the camera the step bent (pitch 13-17 deg for a true 6 with the focal given), weighs."""
    return share >= IMPLAUSIBLE_SHARE and abs(shift) >= math.log1p(IMPLAUSIBLE_SHIFT) and fewer >= IMPLAUSIBLE_MIN_PEOPLE


def _split_rows(rows_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Candidate rows (px) to split the feet at: the middles of the three widest gaps between the feet's rows
    inside their 20-80% quantiles (a back row is a gap, wherever it falls), then those quantiles in steps of 5%."""
    lo, hi = np.percentile(rows_px, [20, 80])
    inner = np.unique(rows_px[(rows_px >= lo) & (rows_px <= hi)])
    gaps = np.argsort(np.diff(inner))[-3:]
    middles = 0.5 * (inner[gaps] + inner[gaps + 1]) if len(inner) > 1 else np.zeros(0)
    return middles, np.unique(np.percentile(rows_px, np.arange(20, 81, 5)))


def _row_split(feet_px: np.ndarray, log_ratio: np.ndarray, people: np.ndarray, n_kept: int) -> GroundFinding | None:
    """The split of the people by their feet's image row (:func:`_split_rows`) whose two sides differ most
    significantly, when they do: a raised back row, a terrace, a flight of stairs seen from below or above."""
    best = None
    for candidates in _split_rows(feet_px[:, 1]):  # a gap first: where a step is, if it is significant there
        for row in candidates:
            upper = feet_px[:, 1] < row  # farther up the image: farther, or higher
            found = _shift(log_ratio, people, upper)
            if found is not None and (best is None or found[1] > best[1]):
                best = (found[0], found[1], found[2], float(row), upper)
        if best is not None:
            break
    if best is None:
        return None
    shift, _, fewer, row, upper = best
    what = "taller" if shift > 0 else "shorter"
    share = float(upper.sum()) / n_kept if shift > 0 else float((~upper).sum()) / n_kept
    return GroundFinding(
        f"the {len(np.unique(people[upper]))} people with their feet above image row {row:.0f} px measure "
        f"{100 * math.expm1(abs(shift)):.0f}% {what} than the {len(np.unique(people[~upper]))} below: the ground "
        "is not one plane (a step, a raised back row, stairs, a slope); calibrate from the people on one level "
        "(--track ID ...)", share, _weighs(share, shift, fewer))


def _people(log_ratio: np.ndarray, people: np.ndarray, tracked: bool, n_kept: int) -> GroundFinding | None:
    """People whose implied stature is far from the median person's (module docstring)."""
    ids, medians, counts = _per_person(log_ratio, people)
    if len(ids) < 3:
        return None
    centre = float(np.median(medians))
    lo, hi = (math.log(r) for r in PERSON_RATIO_RANGE)
    off = (medians - centre < lo) | (medians - centre > hi)
    if not off.any():
        return None
    ratios = np.exp(medians[off] - centre)
    named = ", ".join(f"{'person ' if tracked else 'pair '}{int(i)} x{r:.2f}" for i, r in
                      zip(ids[off][:_SHOWN], ratios[:_SHOWN])) + (" ..." if off.sum() > _SHOWN else "")
    share = float(counts[off].sum()) / n_kept
    who = "people" if off.sum() > 1 else "person"
    return GroundFinding(
        f"{int(off.sum())} {who} of {len(ids)} measure far from the median person ({named} the median stature): "
        "a child, a person held, sitting or on a raised place, or part of a person"
        + ("; calibrate without them (--track ID ...)" if tracked else ""), share, share >= IMPLAUSIBLE_SHARE)


def ground_findings(feet_px: np.ndarray, heads_px: np.ndarray, camera: Camera, stature_m: float,
                    people: np.ndarray, kept: np.ndarray, tracked: bool = True) -> tuple[GroundFinding, ...]:
    """Findings (module docstring) about the pairs a fit kept under its camera; () when one flat ground holds.

    feet_px, heads_px: (N, 2) px; stature_m: the stature the fit assumed (or estimated); people: (N,) int,
    each pair's person (track id, or any unique id per pair); kept: (N,) bool, the fit's inliers;
    tracked: whether ``people`` are track ids (messages name persons) or pair indices.
    """
    ratio = implied_ratios(feet_px[kept], heads_px[kept], camera, stature_m)
    ok = np.isfinite(ratio) & (ratio > 0)
    if ok.sum() < 3:
        return ()
    log_ratio = np.log(ratio[ok])
    feet, who, n_kept = feet_px[kept][ok], np.asarray(people)[kept][ok], int(ok.sum())
    whole = _whole(log_ratio)
    if whole is not None:  # nothing else is meaningful when the model describes none of them
        return (whole,)
    found = _regions(feet, log_ratio, who, camera.image_size, n_kept)
    if not found:  # a band of rows, where no one cell stands out
        split = _row_split(feet, log_ratio, who, n_kept)
        found = [split] if split is not None else []
    person = _people(log_ratio, who, tracked, n_kept)
    return tuple(found + ([person] if person is not None else []))
