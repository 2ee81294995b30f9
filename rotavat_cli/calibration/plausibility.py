"""Is a calibrated camera one that exists? Checks on every result, before anything is aligned.

A fit can end with a camera no one films with (a focal of 96 px on a 1280-wide video, a camera
11 cm above the floor), with a parameter the evidence left wide open, or with a world the people
do not fit (:mod:`.flat_ground`). Such a camera is never used silently: every finding is a
warning, a line of ``fit.implausible`` in camera.yaml, and ``align``, ``render`` and ``batch``
refuse the camera unless told ``--accept-camera``.

A camera is judged by what it implies as well as by the priors' ranges: a focal the people
determine, in a world where they stand as people of one stature on one ground, passes whatever its
value (a 28-person group photo whose people put the focal at 1557 +- 375 px, outside the lens
prior's range, and whose standing people then measure 1.75 m, is a camera, not a refusal).

=========================  ==================================================================
check                      implausible when
=========================  ==================================================================
lens                       an estimated focal outside the lens prior's +-3 sd (0.30-1.84 x the
                           image diagonal: :mod:`.priors`), unless the people determine it
                           and the world it implies holds (no ground finding below)
the people's world         a :mod:`.flat_ground` finding that weighs on the camera: implied
                           statures spread beyond 25%, or a region or people off the others'
                           ground holding a quarter of the pairs
camera height              an estimated height under 0.3 m or over 100 m
mean stature               with ``--camera-height``: the people's estimated mean stature outside
                           1.4-2.1 m (adult group means span 1.55-1.85 m)
pitch, roll                std over 10 deg: the evidence leaves the angle open (the priors' own
                           sds are 25 and 10 deg), so the value is not an estimate
camera height (std)        std over half the height
focal (std)                undetermined (infinite std: no prior, the people do not fix it)
=========================  ==================================================================

>>> from rotavat_cli.geometry.camera import Camera
>>> cam = Camera((1280, 720), 96.0, None, 0.3, 0.0, 0.11)
>>> for line in implausible_findings(cam, {"focal_px": 20.0, "pitch_deg": 2.0, "roll_deg": 1.0, "height_m": 0.05},
...                                  focal_estimated=True):
...     print(line)
focal length 96 px is outside the lens prior's +-3 sd (448-2709 px for a 1280x720 image)
camera height 0.11 m is under 0.3 m
"""

from __future__ import annotations

import math

from ..geometry.camera import Camera
from .flat_ground import GroundFinding
from .priors import lens_range_px

__all__ = ["CAMERA_HEIGHT_RANGE_M", "MEAN_STATURE_RANGE_M", "MAX_ANGLE_SD_DEG", "MAX_HEIGHT_REL_SD",
           "LENS_SD_LIMIT", "implausible_findings"]

CAMERA_HEIGHT_RANGE_M = (0.3, 100.0)
MEAN_STATURE_RANGE_M = (1.4, 2.1)
MAX_ANGLE_SD_DEG = 10.0
MAX_HEIGHT_REL_SD = 0.5
LENS_SD_LIMIT = 3.0


def implausible_findings(camera: Camera, std: dict[str, float], *, focal_estimated: bool,
                         height_estimated: bool = True, mean_stature_m: float | None = None,
                         focal_from_people: bool = False, ground: tuple[GroundFinding, ...] = ()) -> tuple[str, ...]:
    """Plain-words findings (empty: plausible) for a calibrated camera and its std (report units:
    focal_px, pitch_deg, roll_deg, height_m; NaN for a fixed parameter, inf when undetermined).

    focal_estimated: the focal came from the fit (a given or declared focal is the user's);
    height_estimated: likewise the height; mean_stature_m: the people's estimated mean stature
    when the camera height was given; focal_from_people: the people determine the focal
    (``fit.determined_by``); ground: the world's findings (:func:`.flat_ground.ground_findings`).
    """
    weighing = [g.message for g in ground if g.implausible]
    out = []
    if focal_estimated:
        lo, hi = lens_range_px(camera.image_size, LENS_SD_LIMIT)
        judged_by_consequences = focal_from_people and not weighing and math.isfinite(std.get("focal_px", math.inf))
        if not lo <= camera.focal_px <= hi and not judged_by_consequences:
            out.append(f"focal length {camera.focal_px:.0f} px is outside the lens prior's +-{LENS_SD_LIMIT:g} sd "
                       f"({lo:.0f}-{hi:.0f} px for a {camera.image_size[0]}x{camera.image_size[1]} image)")
        if math.isinf(std.get("focal_px", math.nan)):
            out.append("focal length undetermined")
    lo, hi = CAMERA_HEIGHT_RANGE_M
    if height_estimated and not lo <= camera.height_m <= hi:
        out.append(f"camera height {camera.height_m:.2f} m is {'under' if camera.height_m < lo else 'over'} "
                   f"{lo if camera.height_m < lo else hi:g} m")
    if mean_stature_m is not None:
        lo, hi = MEAN_STATURE_RANGE_M
        if not lo <= mean_stature_m <= hi:
            out.append(f"the people's mean stature {mean_stature_m:.2f} m (from the given camera height) is outside "
                       f"{lo:g}-{hi:g} m")
    for key, label in (("pitch_deg", "pitch"), ("roll_deg", "roll")):
        sd = std.get(key, math.nan)
        if sd > MAX_ANGLE_SD_DEG:
            out.append(f"{label} undetermined (+-{sd:.0f} deg)" if math.isfinite(sd) else f"{label} undetermined")
    sd = std.get("height_m", math.nan)
    if height_estimated and sd > MAX_HEIGHT_REL_SD * camera.height_m:
        out.append(f"camera height undetermined ({camera.height_m:.2f} +- {sd:.2f} m)" if math.isfinite(sd)
                   else "camera height undetermined")
    return tuple(out + weighing)
