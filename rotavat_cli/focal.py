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
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["FOCAL_KINDS", "CAMERA", "ASSUMED", "BEV_FOCAL_ON_512", "FocalRule", "FOCAL_RULES", "focal_from_rule", "hybrik_focal_px",
           "focal_kind_or_default"]

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
    FocalRule("tram", "max(W, H) (its est_calib default: a static camera, or when its SLAM focal search keeps it)", "TRAM",
              lambda width, height: float(max(width, height))),
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
