"""Sequence-level calibration: pool the foot/head pairs of every frame, apply the focal policy, fit.

Focal policy (docs/calibration.md, "The focal length"): the camera's focal is estimated from the
people unless it is known:

- ``focal_px`` given (``--focal``): fixed to it ("given");
- the sequence's focal is the camera's own (meta.yaml ``focal_kind: camera``: ground truth, a
  calibrated camera, rotavat's aligned output): fixed to it ("declared"), unless ``estimate_focal``
  (the paper grid always grids it);
- otherwise estimated ("estimated"). A focal an HPS method assumed is never taken for the
  camera's: it is only the focal the meshes were made with (reported as ``mesh_focal_px``).

A sequence whose focal is the camera's own also lends its principal point, unless one is given.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import DegenerateSceneError, InputError
from ..focal import CAMERA
from ..sequence import Sequence
from .fit import CalibrationResult, fit_camera, fit_per_frame
from .options import CalibrateOptions
from .pairs import FootHeadPairs, gather_pairs

__all__ = ["FOCAL_POLICIES", "SequenceCalibration", "declared_focal", "calibrate_sequence"]

FOCAL_POLICIES = ("given", "declared", "estimated")


@dataclass(frozen=True)
class SequenceCalibration:
    """A sequence's calibration, the pairs it used and how the focal length was chosen."""

    result: CalibrationResult
    pairs: FootHeadPairs
    focal_policy: str  # one of FOCAL_POLICIES
    per_frame: dict | None = None  # spread of per-frame estimates when asked
    mesh_focal_px: float | None = None  # the focal the sequence's meshes were made with (median over people)
    mesh_focal_kind: str | None = None  # "camera" | "assumed" (None: no focal stated)

    def fit_dict(self) -> dict:
        """The camera.yaml ``fit:`` block: the fit's own, plus the focal policy, the meshes' focal and
        (``per_frame``) the spread of the frames calibrated alone."""
        fit = {**self.result.fit_dict(), "focal_policy": self.focal_policy}
        if self.mesh_focal_px is not None:
            fit.update(mesh_focal_px=float(self.mesh_focal_px), mesh_focal_kind=self.mesh_focal_kind)
        if self.per_frame is not None:
            fit["per_frame"] = self.per_frame
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


def calibrate_sequence(seq: Sequence, options: CalibrateOptions) -> SequenceCalibration:
    """Calibrate a sequence from its people (``CalibrateOptions.from_config(section)`` for a config section).

    Errors name the sequence: InputError for unusable input, DegenerateSceneError when the people
    cannot determine a camera.
    """
    if not isinstance(options, CalibrateOptions):
        raise TypeError(f"options must be a CalibrateOptions (CalibrateOptions.from_config(section) for a config "
                        f"section), got {type(options).__name__}")
    image_size = seq.require_image_size()
    pairs = gather_pairs(seq)
    mesh_focal = declared_focal(seq)
    mesh_kind = seq.focal_kind if mesh_focal is not None else None
    if options.focal_px is not None:
        focal, policy = options.focal_px, "given"
    elif mesh_kind == CAMERA and not options.estimate_focal and options.method != "grid":
        focal, policy = mesh_focal, "declared"
    else:
        focal, policy = None, "estimated"
    pp = options.principal_point
    if pp is None and seq.intrinsics.principal_point is not None and mesh_kind == CAMERA:
        pp = seq.intrinsics.principal_point
    tracks = pairs.person_ids if pairs.tracked else None
    try:
        fit_options = replace(options, focal_px=focal, principal_point=pp)
        result = fit_camera(pairs.feet_px, pairs.heads_px, image_size, fit_options, frame_index=pairs.frame_index,
                            track_id=tracks)
        per_frame = None
        if options.per_frame:
            spread = fit_per_frame(pairs.feet_px, pairs.heads_px, image_size, pairs.frame_index, fit_options,
                                   track_id=tracks)
            per_frame = {"frames_fitted": len(spread.frame_ids), "frames_skipped": len(spread.skipped),
                         "median": spread.median, "iqr": spread.iqr}
    except DegenerateSceneError as exc:
        why = (f"; {pairs.not_in_front} people were left out, root-centred or behind the camera (not placed in the "
               "camera frame: see rotavat info)") if pairs.not_in_front else ""
        raise DegenerateSceneError(f"{seq.label}: {exc}{why}") from None
    except ValueError as exc:
        raise InputError(f"{seq.path}: {exc}") from None
    if "focal_px" in result.fixed:
        result = replace(result, fixed={**result.fixed, "focal_px": policy})
    return SequenceCalibration(result, pairs, policy, per_frame, mesh_focal, mesh_kind)
