"""Focal lengths: the rules HPS methods use to guess one, and what a sequence says about its own.

An HPS method never knows the camera. It assumes a focal length ``F`` by a fixed rule and makes
its meshes with it: they project onto the image only through ``F`` (and the method's principal
point). The real camera has another focal ``f``. A sequence therefore states two things
(docs/conventions.md, "Focal length"):

- ``focal_length``: the focal its meshes were made with (meta.yaml, or per frame; per person as
  a ``(P,)`` array where the method uses one per person, as HybrIK does);
- ``focal_kind``: ``camera`` when that focal is the camera's own (ground truth, a calibrated
  camera, rotavat's aligned output), ``assumed`` when it is a method's guess. A sequence that
  does not say is ``assumed``: rotavat never takes an undeclared focal for the camera's.

Examples
--------
>>> round(focal_from_rule("cliff", (1920, 1080)), 1)    # CLIFF, WHAM, GVHMR: the image diagonal
2202.9
>>> round(focal_from_rule("4dhumans", (1920, 1080)))    # 4D-Humans/PHALP: 5000 px on a 256 px crop
37500
>>> round(float(np.degrees(2 * np.arctan(1920 / 2 / focal_from_rule("romp", (1920, 1080))))), 3)
60.0

The camera's own focal as people know it, a 35 mm-equivalent focal length (what phones and EXIF
state), in px: :func:`focal_px_from_35mm`; the same camera's focal on a resized image:
:func:`focal_px_at_size`.

>>> round(focal_px_from_35mm(26.0, (4032, 3024)), 2)     # a phone's main camera, 4:3 photo
3028.66
>>> round(focal_px_at_size(3028.66, (4032, 3024), (1440, 1080)), 2)    # the same camera, resized
1081.66
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["FOCAL_KINDS", "CAMERA", "ASSUMED", "BEV_FOCAL_ON_512", "FocalRule", "FOCAL_RULES", "focal_from_rule", "hybrik_focal_px",
           "focal_kind_or_default", "FULL_FRAME_DIAGONAL_MM", "ASPECT_TOLERANCE", "focal_px_from_35mm", "focal_px_at_size"]

CAMERA = "camera"  # the focal is the camera's own: ground truth, a calibrated camera, rotavat's aligned output
ASSUMED = "assumed"  # the focal is an HPS method's guess
FOCAL_KINDS = (CAMERA, ASSUMED)

BEV_FOCAL_ON_512 = 443.4  # ROMP simple_romp/bev/post_parser.py: perspective_projection(focal_length=443.4), 512 px input
_PHALP_FOCAL_ON_256 = 5000.0  # 4D-Humans hmr2/configs: EXTRA.FOCAL_LENGTH 5000 at MODEL.IMAGE_SIZE 256
_HYBRIK_FOCAL_ON_256 = 1000.0  # HybrIK scripts/demo_video.py: focal 1000 for a 256 px box
_TRACE_FOCAL_ON_512 = 548.0  # ROMP simple_romp/trace2/utils/utils.py: focal_length = 548 on the 512 px input (50 deg)
_PYMAFX_FOCAL_PX = 5000.0  # PyMAF-X apps/demo_smplx.py: convert_to_full_img_cam(focal_length=5000.) on the full image
_GLAMR_FOCAL_PX = 1000.0  # GLAMR pose_est/hybrik_demo/demo.py: cam_K focal 1000 on the full image (HybrIK inside)


@dataclass(frozen=True)
class FocalRule:
    """How one family of HPS methods guesses the focal from the image size (W, H) px."""

    name: str
    formula: str  # in words, for reports and docs
    methods: str  # which tools use it
    focal_px: Callable[[int, int], float]


def _diagonal(width: int, height: int) -> float:
    return math.hypot(width, height)


def _bev(width: int, height: int) -> float:
    return BEV_FOCAL_ON_512 / 512.0 * max(width, height)


def _fov60_square(width: int, height: int) -> float:
    return max(width, height) / (2.0 * math.tan(math.radians(30.0)))


def _phalp(width: int, height: int) -> float:
    return _PHALP_FOCAL_ON_256 / 256.0 * max(width, height)


def _trace(width: int, height: int) -> float:
    return _TRACE_FOCAL_ON_512 / 512.0 * max(width, height)


def _pymafx(width: int, height: int) -> float:
    return _PYMAFX_FOCAL_PX  # the same on every image, whatever its size


def _half_sum(width: int, height: int) -> float:
    return 0.5 * (width + height)


def _glamr(width: int, height: int) -> float:
    return _GLAMR_FOCAL_PX  # the same on every image, whatever its size


FOCAL_RULES: dict[str, FocalRule] = {rule.name: rule for rule in (
    FocalRule("cliff", "sqrt(W^2 + H^2) (the image diagonal)", "CLIFF, WHAM, GVHMR", _diagonal),
    FocalRule("bev", "443.4 / 512 * max(W, H) (60 deg field of view on the padded square)", "BEV", _bev),
    FocalRule("romp", "max(W, H) / (2 tan 30 deg) (60 deg field of view on the padded square)", "ROMP", _fov60_square),
    FocalRule("4dhumans", "5000 / 256 * max(W, H)", "4D-Humans, PHALP, HMR 2.0", _phalp),
    FocalRule("trace", "548 / 512 * max(W, H) (50 deg field of view on the padded square)", "TRACE", _trace),
    FocalRule("pymafx", "5000 px whatever the image size (principal point at the image centre)", "PyMAF-X", _pymafx),
    FocalRule("slahmr", "(W + H) / 2 (its default intrinsics when none are given)", "SLAHMR", _half_sum),
    FocalRule("glamr", "1000 px whatever the image size (principal point at the image centre)", "GLAMR", _glamr),
    FocalRule("tram", "max(W, H) (its est_calib default: a static camera, or when its SLAM focal search keeps it)",
              "TRAM, PromptHMR", lambda width, height: float(max(width, height))),
    FocalRule("comotion", "2 max(W, H) (get_default_K; principal point at the image centre)", "CoMotion",
              lambda width, height: 2.0 * max(width, height)),
)}


def focal_from_rule(rule: str, image_size: tuple[int, int]) -> float:
    """The focal (px) that the methods of ``rule`` assume for an image of ``image_size`` (W, H).

    Raises ValueError for an unknown rule (HybrIK's per-person rule: :func:`hybrik_focal_px`).
    """
    if rule not in FOCAL_RULES:
        raise ValueError(f"unknown focal rule {rule!r} (known: {', '.join(FOCAL_RULES)})")
    width, height = (int(v) for v in image_size)
    return float(FOCAL_RULES[rule].focal_px(width, height))


def hybrik_focal_px(box_width_px: np.ndarray) -> np.ndarray:
    """HybrIK's per-person focal (P,) px: 1000 px for a 256 px box, scaled by each box width (P,) px."""
    return _HYBRIK_FOCAL_ON_256 / 256.0 * np.asarray(box_width_px, dtype=np.float64)


def focal_kind_or_default(value: object) -> str:
    """A meta.yaml ``focal_kind`` validated (None -> ``assumed``); ValueError naming the allowed values."""
    if value is None:
        return ASSUMED
    if value not in FOCAL_KINDS:
        raise ValueError(f"key 'focal_kind' must be one of {', '.join(FOCAL_KINDS)}, got {value!r}")
    return str(value)


# ---- the camera's own focal as people know it ------------------------------------------------------
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)  # 43.27 mm: the diagonal of a 36 x 24 mm ("35 mm") frame
# Two image sizes are one camera's pictures resized when their aspect ratios agree this closely (relative):
# rounding each side to whole pixels moves it by under 1% down to 100 px sides; a crop (4:3 photo, 16:9 video) by 33%.
ASPECT_TOLERANCE = 0.01


def focal_px_from_35mm(focal_35mm_mm: float, image_size: tuple[int, int]) -> float:
    """The focal (px) on an image of ``image_size`` (W, H) px of a 35 mm-equivalent focal length (mm).

    35 mm equivalent (EXIF FocalLengthIn35mmFilm, what phones state): the focal giving the same
    diagonal field of view on a 36 x 24 mm frame, so ``f_px = MM / 43.27 mm * sqrt(W^2 + H^2)``.
    ValueError unless ``focal_35mm_mm`` is positive and finite.

    >>> round(focal_px_from_35mm(43.266615305567875, (1920, 1080)), 6) == round(math.hypot(1920, 1080), 6)
    True
    """
    if isinstance(focal_35mm_mm, bool) or not isinstance(focal_35mm_mm, (int, float, np.number)) \
            or not math.isfinite(focal_35mm_mm) or focal_35mm_mm <= 0:
        raise ValueError(f"a 35 mm-equivalent focal must be a positive number of mm, got {focal_35mm_mm!r}")
    width, height = (int(v) for v in image_size)
    return float(focal_35mm_mm) / FULL_FRAME_DIAGONAL_MM * math.hypot(width, height)


def focal_px_at_size(focal_px: float, from_size: tuple[int, int], to_size: tuple[int, int]) -> float:
    """A focal (px) on an image of ``from_size`` (W, H) carried to the same camera's image resized to ``to_size``,
    held either way (a portrait photo of a landscape video's camera): scaled by the ratio of the long sides.
    ValueError when the shapes differ by more than :data:`ASPECT_TOLERANCE` (another crop of the sensor, e.g. a
    4:3 photo and a 16:9 video: the focal does not carry over).

    >>> focal_px_at_size(1000.0, (4000, 3000), (2000, 1500)), focal_px_at_size(1000.0, (3000, 4000), (2000, 1500))
    (500.0, 500.0)
    >>> focal_px_at_size(1000.0, (4000, 3000), (1920, 1080))
    Traceback (most recent call last):
    ...
    ValueError: a 4000x3000 image (aspect 1.333) is not a resize of a 1920x1080 one (aspect 1.778)
    """
    (w0, h0), (w1, h1) = ((int(v) for v in size) for size in (from_size, to_size))
    long0, short0, long1, short1 = max(w0, h0), min(w0, h0), max(w1, h1), min(w1, h1)
    if abs((long0 / short0) / (long1 / short1) - 1.0) > ASPECT_TOLERANCE:
        raise ValueError(f"a {w0}x{h0} image (aspect {w0 / h0:.3f}) is not a resize of a {w1}x{h1} one "
                         f"(aspect {w1 / h1:.3f})")
    return float(focal_px) * long1 / long0
