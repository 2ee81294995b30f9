"""Sequence-level calibration: pool the foot/head pairs of every frame, apply the focal policy, fit.

Focal policy (docs/calibration.md, "The focal length"): the camera's focal is estimated from the
people unless it is known:

- ``focal_px`` given (``--focal``), or ``focal_mm`` (``--focal-mm``, a 35 mm-equivalent focal converted at the
  sequence's image size): fixed to it ("given"), and the fit block says where it came from (``focal_source``);
- the sequence's focal is the camera's own (meta.yaml ``focal_kind: camera``: ground truth, a
  calibrated camera, rotavat's aligned output): fixed to it ("declared"), unless ``estimate_focal``
  (the paper grid always grids it);
- otherwise estimated ("estimated"). A focal an HPS method assumed is never taken for the
  camera's: it is only the focal the meshes were made with (reported as ``mesh_focal_px``).

The principal point is the one given, else the sequence's declared one (what the HPS tool projected
with; a note says so when it is off the image centre), else the image centre. ``tracks`` keeps the
pairs of those person ids only (one person of known stature: ``person_height_m`` and a small
``person_height_sd_m``). Standing bodies' own vertical (:class:`~.objective.BodyAxes`) goes to the
fit, which uses it where the pairs leave the pitch undetermined.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import DegenerateSceneError, InputError
from ..geometry.focal import CAMERA
from ..bodies.frame_points import edge_margin_px
from ..bodies.measure import REFERENCE_SD_MAX_M
from ..bodies.posture import summarize_postures
from ..sequence import Sequence
from ..words import count
from .fit import CalibrationResult, fit_camera, fit_per_frame
from .objective import BodyAxes
from .options import CalibrateOptions
from .pairs import FootHeadPairs, gather_pairs
from .refine import import_least_squares

__all__ = ["FOCAL_POLICIES", "SequenceCalibration", "declared_focal", "calibrate_sequence", "fit_pooled_pairs",
           "still_people_as_one", "whole_people"]

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
    scale_from: str = "prior"  # where the camera's scale comes from (rotavat_cli.bodies.measure.SCALE_SOURCES)
    focal_source: str | None = None  # where a given focal came from (CalibrateOptions.given_focal_source)

    def fit_dict(self) -> dict:
        """The camera.yaml ``fit:`` block: the fit's own, plus the focal policy, the meshes' focal and
        (``per_frame``) the spread of the frames calibrated alone."""
        fit = {**self.result.fit_dict(), "focal_policy": self.focal_policy, "scale_from": self.scale_from}
        if self.focal_source is not None:
            fit["focal_source"] = self.focal_source
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
    pairs = gather_pairs(seq, meanwhile=import_least_squares if options.method == "refine" else None)
    notes: list[str] = []
    if options.tracks is not None:
        pairs = _chosen_tracks(seq, pairs, options.tracks)
    pairs, note = whole_people(seq, pairs, image_size)
    notes += [note] if note else []
    if options.standing_only:
        pairs, note = _standing(seq, pairs)
        notes += [note] if note else []
    mesh_focal = declared_focal(seq)
    mesh_kind = seq.focal_kind if mesh_focal is not None else None
    given_focal = options.given_focal_px(image_size)
    if given_focal is not None:
        focal, policy = given_focal, "given"
    elif mesh_kind == CAMERA and not options.estimate_focal and options.method != "grid":
        focal, policy = mesh_focal, "declared"
    else:
        focal, policy = None, "estimated"
    pp = options.principal_point
    declared_pp = seq.intrinsics.principal_point
    if pp is None and declared_pp is not None and (options.method != "grid" or mesh_kind == CAMERA):
        pp = tuple(float(v) for v in declared_pp)
        if math.dist(pp, (image_size[0] / 2.0, image_size[1] / 2.0)) > _PP_NOTE_PX:
            notes.append(f"principal point ({pp[0]:g}, {pp[1]:g}) from the sequence (what its HPS tool projected "
                         "with), not the image centre (--principal-point CX CY to override)")
    try:
        fit_options = replace(options, focal_px=focal, focal_mm=None, focal_source=None, principal_point=pp)
        result, pairs = fit_pooled_pairs(pairs, image_size, fit_options)
        tracks = pairs.person_ids if pairs.tracked else None
        per_frame = None
        if options.per_frame:
            spread = fit_per_frame(pairs.feet_px, pairs.heads_px, image_size, pairs.frame_index, fit_options,
                                   track_id=tracks)
            per_frame = {"frames_fitted": len(spread.frame_ids), "frames_skipped": len(spread.skipped),
                         "median": spread.median, "iqr": spread.iqr}
    except DegenerateSceneError as exc:
        if pairs.not_in_front and not len(pairs.feet_px):
            noun = "person is" if pairs.not_in_front == 1 else "people are"
            raise DegenerateSceneError(
                f"{seq.label}: its {pairs.not_in_front} {noun} not placed in the camera frame (root-centred or behind "
                f"the camera: rotavat info {seq.label}), so no camera can be calibrated from them, nor can they be "
                f"aligned; root-aligned metrics still apply: rotavat eval {seq.label} --gt GT") from None
        why = (f"; {count(pairs.not_in_front, 'person was', 'people were')} left out, root-centred or behind the camera (not placed in the "
               "camera frame: see rotavat info)") if pairs.not_in_front else ""
        raise DegenerateSceneError(f"{seq.label}: {exc}{why}") from None
    except ValueError as exc:
        raise InputError(f"{seq.path}: {exc}") from None
    if "focal_px" in result.fixed:
        result = replace(result, fixed={**result.fixed, "focal_px": policy},
                         determined_by={**result.determined_by, "focal_px": policy})
    if notes:
        result = replace(result, notes=tuple(notes) + result.notes)
    scale_from = ("camera_height" if options.camera_height_m is not None else "reference"
                  if options.tracks is not None and options.person_height_sd_m <= REFERENCE_SD_MAX_M else "prior")
    source = options.given_focal_source() if policy == "given" else None
    return SequenceCalibration(result, pairs, policy, per_frame, mesh_focal, mesh_kind, scale_from, source)


_PP_NOTE_PX = 0.5  # a declared principal point this far from the image centre is named in a note
_MAX_IDS_SHOWN = 12


def _standing(seq: Sequence, pairs: FootHeadPairs) -> tuple[FootHeadPairs, str | None]:
    """The pairs of people who stand (or whose posture is unknown: no joints), and a note counting the others.

    DegenerateSceneError when no one stands: sitting people are not 1.70 m verticals on the ground."""
    if pairs.postures is None:
        return pairs, None
    away = ~np.isin(pairs.postures, ("standing", "unknown"))
    if not away.any():
        return pairs, None
    if pairs.tracked:  # one posture per person: the commonest of their frames left out
        away_ids, inverse = np.unique(pairs.person_ids[away], return_inverse=True)
        names = pairs.postures[away]
        what = summarize_postures([max(set(names[inverse == k].tolist()), key=names[inverse == k].tolist().count)
                                   for k in range(len(away_ids))])
        people = len(away_ids)
    else:
        people, what = int(away.sum()), summarize_postures(pairs.postures[away].tolist())
    if away.all():
        raise DegenerateSceneError(f"{seq.label}: no one stands ({what}, by what their joints say supports them): "
                                   "sitting or kneeling people are not verticals of known height; give the camera "
                                   f"(rotavat align {seq.label} --camera FILE, docs/conventions.md#camerayaml), or "
                                   f"calibrate from them anyway (rotavat calibrate {seq.label} --all-people)")
    who = "person who does not stand" if people == 1 else "people who do not stand"
    note = (f"left out {people} {who} ({what}; {int(away.sum())} of {len(away)} pairs, by what their joints say "
            "supports them; --all-people keeps them)")
    return pairs.subset(~away), note


def whole_people(seq: Sequence, pairs: FootHeadPairs, image_size: tuple[int, int]) -> tuple[FootHeadPairs, str | None]:
    """The pairs of people seen whole (``FootHeadPairs.cut``, :func:`.pairs.in_view`) and a note counting the others.

    A person cut by the image border has no seen foot or crown: their pair is not a foot/head pair. When no
    one is whole, DegenerateSceneError names how far beyond the border their points lie and what can be
    done without them."""
    if pairs.cut is None or not pairs.cut.any():
        return pairs, None
    cut = pairs.cut
    people = len(np.unique(pairs.person_ids[cut])) if pairs.tracked else int(cut.sum())
    beyond = pairs.cut_depth_px[cut]
    outside = beyond[beyond >= 1.0]
    where = (f"their feet or crowns up to {float(np.max(outside)):.0f} px beyond the {image_size[0]}x{image_size[1]} "
             f"image's border" if len(outside) else
             f"their feet or crowns within {edge_margin_px(image_size):.0f} px of the image's border")
    if cut.all():
        raise DegenerateSceneError(
            f"{seq.label}: everyone is cut by the image border ({count(people, 'person', 'people')}, {where}): no "
            "one is seen from sole to crown, so no camera can be calibrated from them, nor can they be placed on the "
            f"ground; root-aligned metrics still apply: rotavat eval {seq.label} --gt GT")
    note = (f"left out {count(people, 'person', 'people')} cut by the image border ({int(cut.sum())} of {len(cut)} "
            f"pairs, {where}): not foot/head pairs")
    return pairs.subset(~cut), note


_STILL_SPREAD = 0.10  # a track whose feet all lie within this fraction of its pixel height of their median stands still


def still_people_as_one(pairs: FootHeadPairs) -> tuple[FootHeadPairs, str | None]:
    """Each tracked person who stands still (feet within a tenth of their pixel height of their median
    in every frame) as one pair: the median foot and head, and a note counting them.

    A still person's frames repeat one observation; their pixel noise is not perspective. Fitted
    frame by frame, the noise of the foot pixels, carried through the ground's perspective, reads as
    evidence of pitch and height (synthetic: a person still at 5 m, pitch 25 deg: fitted at -7 +- 6
    deg); as one pair, the pitch is what the pair and the priors allow.
    """
    if not pairs.tracked or len(pairs.feet_px) == 0:
        return pairs, None
    ids, inverse = np.unique(pairs.person_ids, return_inverse=True)
    median_feet = np.stack([np.median(pairs.feet_px[inverse == k], axis=0) for k in range(len(ids))])
    length = np.linalg.norm(pairs.feet_px - pairs.heads_px, axis=1)
    spread = np.linalg.norm(pairs.feet_px - median_feet[inverse], axis=1) / np.maximum(length, 1e-9)
    still = np.bincount(inverse, spread > _STILL_SPREAD, len(ids)) == 0
    still &= np.bincount(inverse, minlength=len(ids)) > 1
    if not still.any():
        return pairs, None
    keep = ~still[inverse]
    first = np.array([np.flatnonzero(inverse == k)[0] for k in np.flatnonzero(still)])
    merged = pairs.subset(first)
    for k, row in zip(np.flatnonzero(still), range(len(first))):
        sel = inverse == k
        merged.feet_px[row], merged.heads_px[row] = np.median(pairs.feet_px[sel], 0), np.median(pairs.heads_px[sel], 0)
        if merged.axes_cam is not None:
            merged.axes_cam[row] = np.median(pairs.axes_cam[sel], axis=0)
    out = pairs.subset(keep)
    out = replace(out, **{name: np.concatenate([getattr(out, name), getattr(merged, name)])
                          for name in ("feet_px", "heads_px", "frame_index", "person_ids")},
                  axes_cam=None if out.axes_cam is None else np.concatenate([out.axes_cam, merged.axes_cam]),
                  postures=None if out.postures is None else np.concatenate([out.postures, merged.postures]))
    people = int(still.sum())
    return out, (f"{people} {'person stands' if people == 1 else 'people stand'} still: "
                 f"{'their' if people > 1 else 'its'} {int((~keep).sum())} pairs count as {people} (the median foot "
                 "and head), not one per frame")


def fit_pooled_pairs(pairs: FootHeadPairs, image_size: tuple[int, int], options: CalibrateOptions
                     ) -> tuple[CalibrationResult, FootHeadPairs]:
    """The fit of a sequence's pooled pairs (:func:`calibrate_sequence` after its focal and posture policies):
    each still person as one pair (:func:`still_people_as_one`, noted in the result), their track ids, the
    standing bodies' own vertical. Returns the result and the pairs it was given."""
    pairs, note = still_people_as_one(pairs)
    result = fit_camera(pairs.feet_px, pairs.heads_px, image_size, options, frame_index=pairs.frame_index,
                        track_id=pairs.person_ids if pairs.tracked else None, body=body_axes(pairs))
    if note:
        result = replace(result, notes=(note,) + result.notes)
    return result, pairs


def _chosen_tracks(seq: Sequence, pairs: FootHeadPairs, ids: tuple[int, ...]) -> FootHeadPairs:
    """The pairs of the person ids ``ids``; InputError naming the ids the sequence has when one is missing."""
    if not pairs.tracked:
        raise InputError(f"{seq.path}: --track needs person_ids in every frame with people; this sequence has none")
    present = np.unique(pairs.person_ids)
    missing = sorted(set(ids) - set(present.tolist()))
    if missing:
        shown = ", ".join(str(i) for i in present[:_MAX_IDS_SHOWN]) + (" ..." if len(present) > _MAX_IDS_SHOWN else "")
        raise InputError(f"{seq.path}: no person_id {', '.join(map(str, missing))} with foot-head pairs (ids: {shown})")
    return pairs.subset(np.isin(pairs.person_ids, ids))


def body_axes(pairs: FootHeadPairs) -> BodyAxes | None:
    """The standing people's own vertical (a robust mean of their sole->crown axes in the camera frame:
    each person's median over their frames, then the median over people), or None without 3D people.

    The sd is the fit's (``CalibrateOptions.body_axis_sd_deg``); it is set there."""
    if pairs.axes_cam is None:
        return None
    ok = np.isfinite(pairs.axes_cam).all(axis=1)
    if not ok.any():
        return None
    axes, ids = pairs.axes_cam[ok], pairs.person_ids[ok] if pairs.tracked else np.arange(int(ok.sum()))
    labels, inverse = np.unique(ids, return_inverse=True)
    per_person = np.stack([np.median(axes[inverse == k], axis=0) for k in range(len(labels))])
    up = np.median(per_person, axis=0)
    norm = float(np.linalg.norm(up))
    if not norm > 0:
        return None
    return BodyAxes(up / norm, math.radians(10.0), len(labels))
