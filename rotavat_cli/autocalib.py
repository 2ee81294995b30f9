"""Sequence-level calibration: pool the foot/head pairs of every frame, apply the focal policy, fit.

Focal policy: an explicit ``focal_px`` fixes f. Otherwise, when the sequence declares the focal
length its meshes were made with (meta.yaml or frame ``focal_length``/``K``), f is fixed to it
(the meshes are consistent with it) unless ``estimate_focal``; else f is estimated.
"""

from __future__ import annotations

from dataclasses import dataclass

from .calibrate import CalibrationResult, GridSpec, fit_camera, fit_per_frame
from .errors import DegenerateSceneError, InputError
from .people import FootHeadPairs, gather_pairs
from .sequence import Sequence

__all__ = ["SequenceCalibration", "declared_focal", "grid_from_config", "calibrate_sequence"]


@dataclass(frozen=True)
class SequenceCalibration:
    """A sequence's calibration, the pairs it used and how the focal length was chosen."""

    result: CalibrationResult
    pairs: FootHeadPairs
    focal_policy: str  # "given" | "declared" | "estimated"
    per_frame: dict | None = None  # spread of per-frame estimates when asked


def declared_focal(seq: Sequence) -> float | None:
    """Focal length (px) the sequence says its meshes were made with, if any."""
    if seq.intrinsics.focal_px is not None:
        return seq.intrinsics.focal_px
    for frame in seq.frames():
        return frame.intrinsics.focal_px
    return None


def grid_from_config(grid: dict) -> GridSpec:
    """GridSpec from the ``calibrate.grid`` config section."""
    return GridSpec(**grid)


def calibrate_sequence(seq: Sequence, options: dict) -> SequenceCalibration:
    """Calibrate a sequence from its people with the ``calibrate`` config section ``options``."""
    image_size = seq.require_image_size()
    pairs = gather_pairs(seq)
    if options["focal_px"] is not None:
        focal, policy = float(options["focal_px"]), "given"
    elif not options["estimate_focal"] and options["method"] != "grid" and declared_focal(seq) is not None:
        focal, policy = declared_focal(seq), "declared"
    else:
        focal, policy = None, "estimated"
    pp = options["principal_point"]
    if pp is None and seq.intrinsics.principal_point is not None:
        pp = seq.intrinsics.principal_point
    kwargs = dict(
        method=options["method"], frame_index=pairs.frame_index,
        track_id=pairs.person_ids if pairs.tracked else None, focal_px=focal,
        estimate_roll=options["estimate_roll"], principal_point=tuple(pp) if pp is not None else None,
        person_height_m=options["person_height_m"], person_height_sd_m=options["person_height_sd_m"],
        residual=options["residual"], points=options["points"], box_depth_m=options["box_depth_m"],
        distortion=options["distortion"], fov_prior_deg=options["fov_prior_deg"], grid=grid_from_config(options["grid"]),
    )
    try:
        result = fit_camera(pairs.feet_px, pairs.heads_px, image_size, **kwargs)
        per_frame = None
        if options["per_frame"]:
            per_frame_kwargs = {k: v for k, v in kwargs.items() if k != "frame_index"}
            spread = fit_per_frame(pairs.feet_px, pairs.heads_px, image_size, pairs.frame_index, **per_frame_kwargs)
            per_frame = {"frames_fitted": len(spread.frame_ids), "frames_skipped": len(spread.skipped),
                         "median": spread.median, "iqr": spread.iqr}
    except DegenerateSceneError as exc:
        raise DegenerateSceneError(f"{seq.path}: {exc}") from None
    except ValueError as exc:
        raise InputError(f"{seq.path}: {exc}") from None
    return SequenceCalibration(result, pairs, policy, per_frame)

