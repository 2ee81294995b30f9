"""Sequence-level calibration: pool the foot/head pairs of every frame, apply the focal policy, fit.

Focal policy (docs/calibration.md, "The focal length"): the camera's focal is estimated from the
people unless it is known:

- ``focal_px`` given (``--focal``): fixed to it ("given");
- the sequence's focal is the camera's own (meta.yaml ``focal_kind: camera``: ground truth, a
  calibrated camera, rotavat's aligned output): fixed to it ("declared"), unless ``estimate_focal``;
- otherwise estimated ("estimated"). A focal an HPS method assumed is never taken for the
  camera's: it is only the focal the meshes were made with (reported as ``mesh_focal_px``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .calibrate import CalibrationResult, GridSpec, fit_camera, fit_per_frame
from .errors import DegenerateSceneError, InputError
from .focal import CAMERA
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
    mesh_focal_px: float | None = None  # the focal the sequence's meshes were made with (median over people)
    mesh_focal_kind: str | None = None  # "camera" | "assumed" (None: no focal stated)

    def fit_dict(self) -> dict:
        """The camera.yaml ``fit:`` block: the fit's own, plus the focal policy and the meshes' focal."""
        fit = {**self.result.fit_dict(), "focal_policy": self.focal_policy}
        if self.mesh_focal_px is not None:
            fit.update(mesh_focal_px=float(self.mesh_focal_px), mesh_focal_kind=self.mesh_focal_kind)
        return fit


def declared_focal(seq: Sequence) -> float | None:
    """Focal length (px) the sequence says its meshes were made with, if any (median over a frame's people
    when the method used one per person)."""
    if seq.intrinsics.focal_px is not None:
        return seq.intrinsics.focal_px
    for frame in seq.frames():  # the first frame with people, or the first that states a focal
        intrinsics = frame.intrinsics
        if intrinsics.focal_px is not None:
            return intrinsics.focal_px
        if intrinsics.person_focal_px:
            return float(np.median(intrinsics.person_focal_px))
        if frame.n_people:
            return None
    return None


def grid_from_config(grid: dict) -> GridSpec:
    """GridSpec from the ``calibrate.grid`` config section; InputError (exit 2) when it is invalid or
    larger than ``limits.max_grid_cells`` (checked before anything is allocated)."""
    try:
        return GridSpec(**grid)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc) if "calibrate.grid" in str(exc) else f"calibrate.grid: {exc}") from None


def calibrate_sequence(seq: Sequence, options: dict) -> SequenceCalibration:
    """Calibrate a sequence from its people with the ``calibrate`` config section ``options``."""
    image_size = seq.require_image_size()
    try:
        grid = grid_from_config(options["grid"])  # checked before any frame is read
    except (TypeError, ValueError) as exc:
        raise InputError(f"calibrate.grid: {exc}") from None
    pairs = gather_pairs(seq)
    mesh_focal = declared_focal(seq)
    mesh_kind = seq.focal_kind if mesh_focal is not None else None
    if options["focal_px"] is not None:
        focal, policy = float(options["focal_px"]), "given"
    elif mesh_kind == CAMERA and not options["estimate_focal"] and options["method"] != "grid":
        focal, policy = mesh_focal, "declared"
    else:
        focal, policy = None, "estimated"
    pp = options["principal_point"]
    if pp is None and seq.intrinsics.principal_point is not None and mesh_kind == CAMERA:
        pp = seq.intrinsics.principal_point
    kwargs = dict(
        method=options["method"], frame_index=pairs.frame_index,
        track_id=pairs.person_ids if pairs.tracked else None, focal_px=focal,
        estimate_roll=options["estimate_roll"], principal_point=tuple(pp) if pp is not None else None,
        person_height_m=options["person_height_m"], person_height_sd_m=options["person_height_sd_m"],
        camera_height_m=options["camera_height_m"],
        residual=options["residual"], points=options["points"], box_depth_m=options["box_depth_m"],
        distortion=options["distortion"], fov_prior_deg=options["fov_prior_deg"], grid=grid,
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
    if "focal_px" in result.fixed:
        result = replace(result, fixed={**result.fixed, "focal_px": policy})
    return SequenceCalibration(result, pairs, policy, per_frame, mesh_focal, mesh_kind)
