"""Calibrate a static camera from the people it sees: foot (mid-sole) and head (crown) pixels only.

Two methods (conventions: docs/conventions.md; the model: :mod:`.model`, the grid: :mod:`.grid`):

- ``"grid"``: the seed paper exactly. Focal, pitch and camera height on a 50^3 grid, roll 0,
  principal point at the image centre, stature 1.70 m, least squares on the head pixels; the
  result is the grid's best cell.
- ``"refine"`` (default): a robust (truncated) grid on an order-independent subsample seeds a few
  starts along the focal/pitch valley; each is refined continuously (:mod:`.refine`) over
  log-focal, pitch, roll and log-height, with rounds of outlier rejection; the best start is
  refined on all pairs. The residual kind (:mod:`.residuals`; default ``full``: along and across
  each person's image axis) says what is compared. The stature prior ``N(S, sd_S)`` enters in two
  ways: a tracked person (track id >= 0) has its own stature, profiled out with that prior, so a
  person walking through the scene constrains the perspective whatever their height; an untracked
  pair carries the spread in its along-the-person weight ``sqrt(noise^2 + (L sd_S / S)^2)`` (``L``
  its pixel length). Optional: known principal point, fixed focal, no roll, a weak prior on the
  vertical field of view, radial lens distortion (one-parameter division model, fitted), and
  box-derived points (``points="boxes"``: the box top stands a box depth, 0.25 m, farther from the
  camera than the bottom; the head row only, since a box's two centres share one column).

From upright people on a plane the horizon (~ f tan(pitch)) and the camera height are well
determined, but focal and pitch slide along a valley. :class:`CalibrationResult` reports standard
deviations and warnings in plain words (:mod:`.uncertainty`). Every option is a field of
:class:`~.options.CalibrateOptions`.

Examples
--------
>>> cam = Camera((640, 480), 500.0, None, np.deg2rad(30.0), 0.0, 5.0)
>>> feet_px = np.array([[100.0, 300.0], [320.0, 400.0], [500.0, 350.0], [250.0, 460.0], [600.0, 420.0]])
>>> heads_px = cam.project(cam.backproject_px_to_ground(feet_px) + 1.7 * cam.up_cam)
>>> res = fit_camera(feet_px, heads_px, (640, 480), CalibrateOptions(focal_px=500.0))
>>> round(float(np.rad2deg(res.camera.pitch_rad)), 2), round(res.camera.height_m, 2), res.inliers
(30.0, 5.0, 5)
>>> fit_camera(feet_px, heads_px, (640, 480), focal_px=500.0).camera == res.camera  # options as keywords
True
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from ..geometry.camera import Camera, camera_parameters
from ..errors import DegenerateSceneError
from .flat_ground import ground_findings
from .given_lens import fit_through_lens
from ..geometry.camera_covariance import CameraCovariance
from .footprint import footprint_polygon_px, report_covariance
from .grid import paper_grid_search
from .inputs import PairsInput, check_index, check_inputs, free_slots, resolve_points
from .objective import MIN_NOISE_PX, BodyAxes, Problem, design_effect, make_problem, profiled
from .options import CalibrateOptions
from .params import (BOX_DEPTH, DISTORTION, FOCAL, HEIGHT, MODEL_NAMES, PARAM_NAMES, PITCH, ROLL, SLOT_LABELS, describe,
                     param_bounds, param_vector, to_internal)
from .plausibility import implausible_findings
from .priors import LEAN_SD_DEG, MEASURED_STATURE_SD_M, MOUNTED_ROLL_SD_DEG
from .refine import fit_with_rejection, refine_fit
from .uncertainty import Systematics, covariances, fit_warnings, moved_by_data, std_and_corr

__all__ = ["CalibrationResult", "PerFrameSummary", "fit_camera", "calibrate", "fit_per_frame"]

# A refined parameter closer than this to its start (internal units: log f, rad, rad, log h, ...)
# did not move: the pairs did not constrain the refinement.
_UNMOVED_TOL = 1e-4
_BOUND_TOL = 1e-3  # a refined parameter this close to its search bound (internal units) "ran to the end"
_REWEIGHT_ROUNDS = 2  # rejection rounds of the refits with the design effect and with the bodies' axis
# Fewer usable pairs than this are "few": the fit of one reference person's clicks (CCVS: tens per subject), where the
# few-pairs policy (options.few_pairs, :func:`_few_pairs_policy`) may hold the roll. Its rule is measured on 10-40 pairs
# (benchmarks/bench_reference.py); above 50 it is not applied, and fits of many pairs are as before.
FEW_PAIRS = 50
_SLOT_NAMES = {FOCAL: "focal_px", PITCH: "pitch_deg", ROLL: "roll_deg", HEIGHT: "height_m", DISTORTION: "distortion"}


@dataclass(frozen=True)
class CalibrationResult:
    """An estimated camera with the diagnostics of its fit (never a silent default camera)."""

    camera: Camera
    method: str  # "grid" | "refine"
    person_height_m: float
    pairs: int  # foot-head pairs offered
    inliers: int  # pairs kept by the fit
    frames: int  # distinct frames among the pairs
    rmse_px: float  # head reprojection residual over the inliers (the residual kind's pixel axes)
    std: dict[str, float]  # focal_px, pitch_deg, roll_deg, height_m (and distortion when fitted); NaN when fixed
    corr_focal_pitch: float  # NaN when either is fixed
    inlier_mask: np.ndarray  # (N,) bool
    warnings: tuple[str, ...] = ()
    residual: str = "full"  # the residual kind used (residuals.RESIDUALS)
    std_statistical: dict[str, float] = field(default_factory=dict)  # the fit's own part of ``std``
    points: str = "landmarks"  # "landmarks" (mid-sole, crown) | "boxes" (box bottom- and top-centre)
    distortion: float = math.nan  # fitted division-model coefficient (NaN: not fitted)
    box_depth_m: float = 0.0  # assumed box depth, m (boxes only; 0 for landmarks)
    fixed: dict[str, str] = field(default_factory=dict)  # parameter -> why it was not estimated
    notes: tuple[str, ...] = ()  # what rotavat decided on its own (e.g. box-derived points detected)
    person_height_estimated: bool = False  # the mean stature was estimated (camera height given), not assumed
    person_height_std_m: float = math.nan  # its std when estimated
    determined_by: dict[str, str] = field(default_factory=dict)  # parameter -> "people", "prior", "people+prior", ...
    implausible: tuple[str, ...] = ()  # plausibility findings (:mod:`.plausibility`); empty: plausible
    design_effect: float = 1.0  # how many tracked pairs one independent pair is worth (objective.design_effect)
    body_axes: int = 0  # standing people whose own vertical axis entered the fit (0: not used)
    focal_prior: str = "none"  # the focal's prior: "lens", "fov" (the user's) or "none"
    covariance: CameraCovariance | None = None  # the estimated camera parameters', report units (.footprint)
    footprint_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (V, 2) px: the inliers' feet hull
    lens: dict | None = None  # a given lens (.given_lens): from ("given", "lines FILE"), distortion, sd

    @property
    def horizon_v_px(self) -> float:
        """Image row of the horizon at the image's centre column."""
        cam = self.camera
        return float(cam.horizon_v_px(cam.image_size[0] / 2.0))

    def fit_dict(self) -> dict:
        """Plain-typed ``fit:`` block of camera.yaml (docs/conventions.md); NaN becomes None."""
        return {
            "method": self.method,
            "residual": self.residual,
            "person_height_m": float(self.person_height_m),
            "pairs": int(self.pairs),
            "inliers": int(self.inliers),
            "frames": int(self.frames),
            "rmse_px": _plain(self.rmse_px),
            "std": {**{k: _plain(self.std.get(k, math.nan)) for k in MODEL_NAMES if k in PARAM_NAMES or k in self.std},
                    **({"person_height_m": _plain(self.person_height_std_m)} if self.person_height_estimated else {})},
            "fixed": dict(self.fixed),
            "determined_by": dict(self.determined_by),
            "implausible": list(self.implausible),
            "focal_prior": self.focal_prior,
            "design_effect": float(self.design_effect),
            "body_axes": int(self.body_axes),
            "person_height": "estimated" if self.person_height_estimated else "assumed",
            "corr_focal_pitch": _plain(self.corr_focal_pitch),
            "horizon_v_px": _plain(self.horizon_v_px),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "points": self.points,
            **({"distortion": float(self.distortion)} if math.isfinite(self.distortion) else {}),
            **({"box_depth_m": float(self.box_depth_m)} if self.points == "boxes" else {}),
            **({"covariance": self.covariance.to_dict()} if self.covariance is not None and self.covariance.names
               else {}),
            **({"footprint_px": [[float(u), float(v)] for u, v in self.footprint_px]} if len(self.footprint_px) else {}),
            **({"lens": dict(self.lens)} if self.lens else {}),
        }


def _plain(x: float) -> float | None:
    """Float for YAML, None for NaN (a fixed parameter); an undetermined std stays inf (YAML .inf)."""
    x = float(x)
    return None if math.isnan(x) else x


@dataclass(frozen=True)
class PerFrameSummary:
    """Every frame calibrated alone: per-frame results and the spread of each parameter."""

    frame_ids: tuple[int, ...]  # frames that were fitted
    results: tuple[CalibrationResult, ...]
    skipped: dict[int, str]  # frame id -> why it could not be fitted
    median: dict[str, float]  # per parameter (PARAM_NAMES), over the fitted frames
    iqr: dict[str, float]  # 75th minus 25th percentile


# ---- public API -----------------------------------------------------------------------------------
def fit_camera(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
               options: CalibrateOptions | None = None, *, frame_index: np.ndarray | None = None,
               track_id: np.ndarray | None = None, body: BodyAxes | None = None, workers: int | None = None,
               **changes) -> CalibrationResult:
    """Estimate the static camera from foot/head pixel pairs pooled over all frames.

    feet_px, heads_px: (N, 2) px, mid-sole and crown; image_size: (W, H) px.
    options: :class:`CalibrateOptions` (default: the defaults), with ``changes`` (any of its
    fields as keywords, e.g. ``focal_px=900.0``) applied on top.
    frame_index, track_id: (N,) int, optional (frame count and time order; clusters for the
    uncertainty; a track's stature is its own). body: standing bodies' own vertical
    (:class:`~.objective.BodyAxes`), used where the pairs leave the pitch undetermined.
    workers: grid threads (None = auto).

    ``refine`` (default) is a maximum a posteriori estimate: the pairs, weighted by what they carry
    (tracked pairs by their design effect), plus the priors of :mod:`.priors`; it answers whenever
    one pair is usable, and ``determined_by`` / ``implausible`` say what the answer rests on and
    whether it is a camera at all (:mod:`.plausibility`). With ``camera_height_m`` the scale moves
    to the people's mean stature, which is estimated (``person_height_m`` with
    ``person_height_std_m``). Without priors (``method="grid"``, or ``focal_prior="none"`` with the
    focal free) the people must determine the camera alone: a refinement that ends where it
    started falls back to the paper grid's best cell, with a warning, and a parameter running to its
    search bound is refused.
    Raises ValueError for malformed input and DegenerateSceneError when no camera can be given.
    """
    options = _focal_in_px(_with_changes(options, changes), image_size)
    if options.lens_distortion is not None:  # a known lens: undistort, fit the pinhole, give the camera the lens
        return fit_through_lens(fit_camera, feet_px, heads_px, image_size, options, frame_index=frame_index,
                                track_id=track_id, body=body, workers=workers)
    method = options.method
    points, notes = resolve_points(feet_px, heads_px, options.points, method)
    with _naming_the_chosen_model(notes, points):
        inp = check_inputs(feet_px, heads_px, image_size, options, points, frame_index, track_id)
        idx = np.flatnonzero(inp.usable)
        n_frames = 1 if inp.frames is None else len(np.unique(inp.frames[inp.usable]))
        if _tries_the_lens(options, method, inp, len(idx)):
            lensed = _with_the_lens_tried(feet_px, heads_px, image_size, options, frame_index=frame_index,
                                          track_id=track_id, body=body, workers=workers)
            if lensed is not None:
                return lensed
        prob = make_problem(inp.feet[idx], inp.heads[idx], inp.pp, options.person_height_m,
                            options.person_height_sd_m, options.noise_px, inp.residual, inp.size, inp.priors,
                            None if inp.tracks is None or method == "grid" else inp.tracks[idx],
                            foot_noise=options.errors_in_variables)
        extra: list[str] = []
        asked = options  # what the caller asked, before a slot is held at its prior (the pinhole refit starts there)
        held = held_at_prior(inp, options, method)
        if held:  # what the people at one depth say nothing first-order of: the prior's median, its spread carried
            options = options.replace(**{_HELD_OPTION[slot]: value for slot, value in
                                         _held_values(inp.priors, held).items()})
        if method == "refine":
            free = free_slots(options, method)
            box = options.box_depth_m if points == "boxes" else 0.0
            params, mask_u, scale, start = refine_fit(prob, inp.feet[idx], inp.heads[idx], inp.pp, inp.size,
                                                      options.focal_px, free, box, _seed_grid(options),
                                                      options.max_rounds)
            if inp.priors is None or not inp.priors.cover(free):  # the people alone: no answer is better than a confident wrong one
                if _unmoved(params, start, free):
                    method = "grid"
                    extra = [f"the refinement ended where it started (pitch {math.degrees(params[PITCH]):.5f} deg, "
                             f"height {params[HEIGHT]:.5f} m): the pairs do not constrain it; falling back to the "
                             "paper grid's best cell"]
                else:
                    _refuse_bounds(params, free, inp.size[1])
            else:
                frames_u = None if inp.frames is None else inp.frames[idx]
                tracks_u = None if inp.tracks is None else inp.tracks[idx]
                if options.few_pairs and len(idx) < FEW_PAIRS:
                    prob, params, mask_u, scale = _few_pairs_policy(prob, params, free, mask_u, scale, tracks_u,
                                                                    options, notes)
                prob, params, mask_u, scale = _weigh_correlated_pairs(prob, params, free, mask_u, scale, frames_u)
                if body is not None and options.body_axes and free[PITCH]:
                    prob, params, mask_u, scale = _with_bodies(prob, params, free, mask_u, scale, body, options,
                                                               tracks_u)
        if method == "grid":
            params, mask_u, free, scale, prob = _grid_fit(inp, idx, options, workers, prob)
        result = _result(inp, idx, options, method, points, notes, extra, prob, params, free, mask_u, scale,
                         n_frames, held)
        if method == "refine" and (inp.priors is None or not inp.priors.cover(free)):
            _refuse_undetermined(result)
        if options.distortion and not _lens_significant(result):
            return _without_the_lens(result, fit_camera(feet_px, heads_px, image_size, asked.replace(distortion=False),
                                                        frame_index=frame_index, track_id=track_id, body=body,
                                                        workers=workers))
        return result


def _tries_the_lens(options: CalibrateOptions, method: str, inp: PairsInput, n_usable: int) -> bool:
    """Whether the few-pairs policy fits the lens on its own (``options.distortion`` None): fewer than
    :data:`FEW_PAIRS` usable pairs of people of measured stature (``priors.MEASURED_STATURE_SD_M``: a reference
    person's clicks, where a pinhole fit of a barrel-distorted camera costs centimetres:
    benchmarks/bench_reference.py), the refinement with its priors (the lens prior among them), and no lens given.
    The lens is then kept only when the pairs tell it from none (:data:`LENS_SIGNIFICANCE`)."""
    return (options.distortion is None and options.few_pairs and method == "refine" and n_usable < FEW_PAIRS
            and options.person_height_sd_m <= MEASURED_STATURE_SD_M and inp.priors is not None
            and options.lens_distortion is None)


def _with_the_lens_tried(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
                         options: CalibrateOptions, **kwargs) -> CalibrationResult | None:
    """:func:`fit_camera` with the lens fitted (``distortion=True``: the pinhole fit with a note when the lens is not
    significant), a note saying why a lens was fitted when it is kept; None when the fit with the lens refuses the
    pairs (the pinhole fit is then the answer)."""
    try:
        result = fit_camera(feet_px, heads_px, image_size, options.replace(distortion=True), **kwargs)
    except DegenerateSceneError:
        return None
    if not math.isfinite(result.distortion):
        return result
    note = (f"lens fitted: the pairs tell a division coefficient {result.distortion:+.3f} +- "
            f"{result.std.get('distortion', math.nan):.3f} from none (with fewer than {FEW_PAIRS} pairs the lens is "
            "tried unless --no-distortion; a known lens: --lens K, or --lens-lines FILE)")
    return replace(result, notes=result.notes + (note,))


# A fitted lens is kept when it is this many of its std from none: a lens is a claim about the camera, made at 3 std
# (a 0.3% false alarm where the std is right). From a few tens of clicks the lens trades off with the focal and the
# pitch, and a coefficient the pairs cannot tell from 0 moved the statures of undistorted cameras by up to 9.6 cm.
# benchmarks/bench_reference.py, 5 draws, 220 calibrations of undistorted cameras (the lens against none): at 2 std
# worse in 13 (+0.06 cm on average, once +3.5 cm), at 2.5 in 7, at 3 in 3 (+0.004 cm, at most +0.31); on the
# distorted cameras -2.17, -2.05 and -1.91 cm (docs/calibration.md, "Few pairs").
LENS_SIGNIFICANCE = 3.0


def _lens_significant(result: CalibrationResult) -> bool:
    """Whether the fitted lens differs from none by :data:`LENS_SIGNIFICANCE` of its std."""
    sd = result.std.get("distortion", math.nan)
    return bool(math.isfinite(result.distortion) and math.isfinite(sd)
                and abs(result.distortion) > LENS_SIGNIFICANCE * sd)


def _without_the_lens(lensed: CalibrationResult, pinhole: CalibrationResult) -> CalibrationResult:
    """The fit without the lens (``pinhole``), saying which lens the pairs suggested and why it is not applied."""
    note = (f"lens not applied: the pairs suggest a division coefficient {lensed.distortion:+.3f} +- "
            f"{lensed.std.get('distortion', math.nan):.3f}, within {LENS_SIGNIFICANCE:g} std of none (a known lens: "
            "--lens K, or --lens-lines FILE from the scene's straight edges)")
    return replace(pinhole, notes=pinhole.notes + (note,),
                   fixed={**pinhole.fixed, "distortion": "not significant"})


_HELD_OPTION = {FOCAL: "focal_px", PITCH: "pitch_deg"}  # the option that holds a slot at its prior's median


def held_at_prior(inp: PairsInput, options: CalibrateOptions, method: str) -> dict[int, float]:
    """The slots held at their prior's median, each with the prior's sd (internal units): {} for most fits.

    People at one depth constrain some parameters only through second-order effects, which pixel
    noise and the point model's small errors bias by far more than the prior's spread; the honest
    answer is then the prior's, with its spread carried into the other parameters:

    - an estimated focal (how a person's image tilts and shrinks across the view; synthetic walkers:
      -45% for a camera 25 deg down, +20% for a level one), unless the people's statures are measured
      (``priors.MEASURED_STATURE_SD_M``: a reference person of known stature, whose clicks' second-order effects
      are not blurred by a population's spread of statures): the focal is then estimated under its prior
      (benchmarks/bench_reference.py: held at the prior's median, a reference walking one depth band measured the
      others 0.1 cm worse over the study, 2.3 cm worse on its long-lens camera);
    - an estimated pitch when only the head rows are compared (box points, ``--residual vertical``):
      without the columns, nothing says how the verticals converge, and a row of box-annotated people
      with the focal known fits a level camera at head height to a fraction of a pixel (synthetic: a
      camera 15 deg down, 3.0 m up, answered -1.4 +- 1.6 deg and 1.70 m).
    """
    if method != "refine" or not inp.one_depth or inp.priors is None:
        return {}
    held = {}
    if options.focal_px is None and np.isfinite(inp.priors.sd[FOCAL]) and \
            options.person_height_sd_m > MEASURED_STATURE_SD_M:
        held[FOCAL] = float(inp.priors.sd[FOCAL])
    if options.pitch_deg is None and inp.residual.dof == 1 and np.isfinite(inp.priors.sd[PITCH]):
        held[PITCH] = float(inp.priors.sd[PITCH])
    return held


def _held_values(priors, held: dict[int, float]) -> dict[int, float]:
    """Each held slot's prior median in its option's units (focal px, pitch deg)."""
    return {slot: float(np.exp(priors.mean[FOCAL])) if slot == FOCAL else math.degrees(priors.mean[PITCH])
            for slot in held}


def calibrate(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int],
              options: CalibrateOptions | None = None, **kwargs) -> Camera:
    """The camera of :func:`fit_camera` (same arguments), without the diagnostics."""
    return fit_camera(feet_px, heads_px, image_size, options, **kwargs).camera


def fit_per_frame(feet_px: np.ndarray, heads_px: np.ndarray, image_size: tuple[int, int], frame_index: np.ndarray,
                  options: CalibrateOptions | None = None, *, track_id: np.ndarray | None = None,
                  workers: int | None = None, **changes) -> PerFrameSummary:
    """Calibrate every frame alone (options as for :func:`fit_camera`) and summarise the spread.

    feet_px, heads_px: (N, 2) px; frame_index, track_id: (N,) int.
    """
    options = _with_changes(options, changes)
    if options.distortion is None:  # every frame alone has few pairs: the lens only when asked (--distortion)
        options = options.replace(distortion=False)
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    frames = check_index(frame_index, len(feet), "frame_index")
    if frames is None:
        raise ValueError("fit_per_frame needs frame_index")
    ids, results, skipped = [], [], {}
    for t in np.unique(frames):
        sel = frames == t
        try:
            res = fit_camera(feet[sel], heads[sel], image_size, options, frame_index=frames[sel],
                             track_id=None if track_id is None else np.asarray(track_id)[sel], workers=workers)
        except DegenerateSceneError as err:
            skipped[int(t)] = str(err)
            continue
        ids.append(int(t))
        results.append(res)
    values = {k: np.array([camera_parameters(r.camera)[k] for r in results]) for k in PARAM_NAMES}
    median = {k: float(np.median(v)) if len(v) else math.nan for k, v in values.items()}
    iqr = {k: float(np.subtract(*np.percentile(v, [75, 25]))) if len(v) else math.nan for k, v in values.items()}
    return PerFrameSummary(tuple(ids), tuple(results), skipped, median, iqr)


# ---- the steps ------------------------------------------------------------------------------------
def _with_changes(options: CalibrateOptions | None, changes: dict) -> CalibrateOptions:
    """``options`` (or the defaults) with keyword changes applied; TypeError for anything else."""
    if options is None:
        options = CalibrateOptions()
    elif not isinstance(options, CalibrateOptions):
        raise TypeError(f"options must be a CalibrateOptions (CalibrateOptions.from_config(section) for a config "
                        f"section), got {type(options).__name__}")
    return options.replace(**changes) if changes else options


def _focal_in_px(options: CalibrateOptions, image_size: tuple[int, int]) -> CalibrateOptions:
    """``options`` with a 35 mm-equivalent ``focal_mm`` turned into ``focal_px`` on ``image_size`` (W, H) px."""
    if options.focal_mm is None:
        return options
    try:
        focal_px = options.given_focal_px(image_size)
    except (TypeError, ValueError):
        raise ValueError(f"image_size must be (W, H) in pixels, got {image_size!r}") from None
    return options.replace(focal_px=focal_px, focal_mm=None)


@contextlib.contextmanager
def _naming_the_chosen_model(notes: list[str], points: str) -> Iterator[None]:
    """A DegenerateSceneError says so when rotavat chose the box model by itself."""
    try:
        yield
    except DegenerateSceneError as exc:
        if notes and points == "boxes":
            raise DegenerateSceneError(f"{exc} (with the box model: the points were recognised as box-derived; "
                                       "--points landmarks to override)") from None
        raise


def _unmoved(params: np.ndarray, start: np.ndarray, free: np.ndarray) -> bool:
    """True when every refined parameter is still at its start (internal units)."""
    moved = np.abs(to_internal(params) - to_internal(start))[free]
    return bool(moved.size) and bool(np.all(moved < _UNMOVED_TOL))


def _refuse_bounds(params: np.ndarray, free: np.ndarray, image_height_px: float) -> None:
    """DegenerateSceneError when a refined parameter ran to its search bound: the pairs do not
    determine it, and a camera at the bound would be a confident wrong answer."""
    lo, hi = param_bounds(image_height_px)
    x = to_internal(params)
    values = describe(params)
    hit = [i for i in range(len(SLOT_LABELS)) if free[i] and min(x[i] - lo[i], hi[i] - x[i]) < _BOUND_TOL]
    if hit:
        what = ", ".join(f"the {SLOT_LABELS[i]} ({values[i]})" for i in hit)
        raise DegenerateSceneError(f"the pairs cannot determine {what}: the fit ran to the end of its search "
                                   "range; give what is known (--focal, --camera-height, --no-roll) or more people "
                                   "at different depths")


def _refuse_undetermined(result: CalibrationResult) -> None:
    """DegenerateSceneError when the people alone (no prior on a free parameter) leave a parameter
    undetermined (infinite std): its value is wherever the refinement stopped in a flat valley."""
    lost = [PARAM_NAMES.index(key) for key in PARAM_NAMES if result.std.get(key, math.nan) == math.inf]
    if lost:
        cam = result.camera
        values = describe(param_vector(focal=cam.focal_px, pitch=cam.pitch_rad, roll=cam.roll_rad, height=cam.height_m))
        what = ", ".join(f"the {SLOT_LABELS[slot]} ({values[slot]})" for slot in lost)
        raise DegenerateSceneError(f"the pairs cannot determine {what}: without a prior, any value of "
                                   f"{'them' if len(lost) > 1 else 'it'} fits as well; give what is known (--focal, "
                                   "--camera-height, --pitch) or use the lens prior (--focal-prior lens)")


def _seed_grid(options: CalibrateOptions):
    """The refinement's seeding grid: the configured one, with a given pitch as its only pitch."""
    if options.pitch_deg is None:
        return options.grid
    steps = options.grid.steps
    return replace(options.grid, pitch_range_deg=(options.pitch_deg, options.pitch_deg), steps=(steps[0], 1, steps[2]))


def _few_pairs_policy(prob: Problem, params: np.ndarray, free: np.ndarray, mask: np.ndarray, scale: float,
                      tracks: np.ndarray | None, options: CalibrateOptions, notes: list[str]
                      ) -> tuple[Problem, np.ndarray, np.ndarray, float]:
    """The fit of fewer than :data:`FEW_PAIRS` usable pairs (``prob``; the refinement's fit ``params`` (6,) with its
    inliers ``mask`` (N,) and ``scale``): the roll held near 0 by the mounting prior (``priors.MOUNTED_ROLL_SD_DEG``)
    when the pairs cannot determine it (:func:`_roll_undetermined`), with a note; unchanged otherwise. A prior, not a
    fixed 0, so that pairs which do determine the roll still move it. Outliers stay rejected as in any fit: a soft
    (Cauchy) loss on every pair instead lost to rejection (benchmarks/bench_reference.py, docs/calibration.md
    "Few pairs: one reference person")."""
    if not free[ROLL] or prob.priors is None:
        return prob, params, mask, scale
    roll_sd_deg, people = _roll_sd_deg(prob, params, free, mask, scale, tracks)
    if not _roll_undetermined(roll_sd_deg):
        return prob, params, mask, scale
    prob = replace(prob, priors=prob.priors.with_sd(ROLL, math.radians(MOUNTED_ROLL_SD_DEG)))
    params, mask, scale = fit_with_rejection(prob, params, free, mask, options.max_rounds)
    n = len(prob.rel_feet)
    notes.append(f"roll held near 0 (prior sd {MOUNTED_ROLL_SD_DEG:g}°): {n} pairs (< {FEW_PAIRS}) of {people} "
                 f"{'person' if people == 1 else 'people'} cannot determine it (its std {roll_sd_deg:.1f}° with "
                 f"a {LEAN_SD_DEG:g}° lean per person > {0.5 * MOUNTED_ROLL_SD_DEG:g}°)")
    return prob, params, mask, scale


def _roll_sd_deg(prob: Problem, params: np.ndarray, free: np.ndarray, mask: np.ndarray, scale: float,
                 tracks: np.ndarray | None) -> tuple[float, int]:
    """The roll's std (deg) the pairs ``mask`` (N,) give with the default priors, and the people they come from
    (tracks; untracked pairs count one person each): the fit's statistical std combined with the people's
    lean (``priors.LEAN_SD_DEG / sqrt(people)``), which the head columns of one person share."""
    inl = prob.subset(np.flatnonzero(mask))
    clusters = None if tracks is None else tracks[mask]
    _, cov, _, _ = covariances(inl, params, free, scale, clusters, Systematics(0.0, 0.0, 0.0, 0.0), False)
    people = int(mask.sum()) if tracks is None else len(np.unique(tracks[mask]))
    stat_deg = math.degrees(math.sqrt(max(cov[ROLL, ROLL], 0.0)))
    return math.hypot(stat_deg, LEAN_SD_DEG / math.sqrt(max(people, 1))), people


def _roll_undetermined(roll_sd_deg: float) -> bool:
    """True when the pairs' roll std (deg) exceeds half the mounting prior's sd: the prior would then carry at
    least a fifth of the roll's information (its weight ``sd^2 / (sd^2 + prior_sd^2)`` >= 0.2), so the pairs
    do not determine the roll by themselves. With the 1 deg prior that is always so for one to four people (the lean
    alone is 1.0 deg / sqrt(people) >= 0.5 deg); from five, only when their clicks leave the roll uncertain."""
    return roll_sd_deg > 0.5 * MOUNTED_ROLL_SD_DEG


def _weigh_correlated_pairs(prob: Problem, params: np.ndarray, free: np.ndarray, mask: np.ndarray, scale: float,
                            frames: np.ndarray | None) -> tuple[Problem, np.ndarray, np.ndarray, float]:
    """Refit (:func:`.refine.fit_with_rejection`) with each tracked pair weighted by its design effect
    (:func:`.objective.design_effect`), measured on the inliers of a first fit; unchanged when the pairs are
    independent."""
    inliers = np.flatnonzero(mask)
    deff = design_effect(prob.subset(inliers), params, scale, None if frames is None else frames[inliers])
    if deff <= 1.0:
        return prob, params, mask, scale
    prob = replace(prob, deff=np.where(prob.track >= 0, deff, 1.0))
    return (prob, *fit_with_rejection(prob, params, free, mask, _REWEIGHT_ROUNDS))


def _with_bodies(prob: Problem, params: np.ndarray, free: np.ndarray, mask: np.ndarray, scale: float,
                 body: BodyAxes, options: CalibrateOptions, tracks: np.ndarray | None
                 ) -> tuple[Problem, np.ndarray, np.ndarray, float]:
    """Refit (as :func:`_weigh_correlated_pairs`) with the standing bodies' own vertical when the
    pairs (with the priors) leave the pitch's std above ``options.body_engage_pitch_sd_deg``; unchanged
    otherwise."""
    inl = prob.subset(np.flatnonzero(mask))
    clusters = None if tracks is None else tracks[mask]
    _, cov, _, _ = covariances(inl, params, free, scale, clusters, Systematics(0.0, 0.0, 0.0, 0.0), False)
    if not math.degrees(math.sqrt(max(cov[PITCH, PITCH], 0.0))) > options.body_engage_pitch_sd_deg:
        return prob, params, mask, scale
    prob = replace(prob, body=replace(body, sd_rad=math.radians(options.body_axis_sd_deg)))
    return (prob, *fit_with_rejection(prob, params, free, mask, _REWEIGHT_ROUNDS))


def _grid_fit(inp: PairsInput, idx: np.ndarray, options: CalibrateOptions, workers: int | None, prob: Problem
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, Problem]:
    """The paper's grid on the usable pairs ``idx``: (params (6,), all-inlier mask, free (6,), scale,
    unweighted problem)."""
    feet, heads, grid = inp.feet[idx], inp.heads[idx], options.grid
    focal = grid.focal_values_px(inp.size[1]) if options.focal_px is None else np.array([options.focal_px])
    fit = paper_grid_search(feet, heads, inp.pp, focal, grid.pitch_values_rad(), grid.height_values_m(),
                            options.person_height_m, inp.residual.name, 0.0, workers)
    if fit is None:
        raise DegenerateSceneError("no grid cell explains the pairs: every candidate camera puts a foot above the "
                                   "horizon or a head behind the camera (are these pixels of this image?)")
    params = param_vector(focal=fit.focal_px, pitch=fit.pitch_rad, roll=0.0, height=fit.height_m)
    free = free_slots(options, "grid")
    names = ("focal", "pitch", "height")
    edges = [names[axis] for axis, (i, n) in enumerate(zip(fit.index, fit.costs.shape)) if n > 1 and i in (0, n - 1)]
    if edges:
        raise DegenerateSceneError(f"the paper grid's best {', '.join(edges)} lies on the edge of its search range: "
                                   "the camera is outside it or the pairs do not determine it (calibrate.grid in "
                                   "the config sets the ranges)")
    # Unweighted residuals for the paper's uncertainty: equal weights, scale from the residual sum.
    flat = replace(prob, spread_px=np.zeros(len(feet)), noise_px=1.0, track=np.full(len(feet), -1), n_tracks=0,
                   priors=None, deff=None, body=None, foot_noise=False)
    dof_total = max(1, len(feet) * flat.dof - int(free.sum()))
    scale = max(math.sqrt(fit.cost / dof_total), MIN_NOISE_PX)
    return params, np.ones(len(feet), bool), free, scale, flat


def _result(inp: PairsInput, idx: np.ndarray, options: CalibrateOptions, method: str, points: str, notes: list[str],
            extra: list[str], prob: Problem, params: np.ndarray, free: np.ndarray, mask_u: np.ndarray, scale: float,
            n_frames: int, held: dict[int, float] | None = None) -> CalibrationResult:
    """The camera of a fit ``params (6,)`` with its uncertainty, rmse, what determined it, warnings,
    plausibility findings and what was fixed. ``held``: the slots held at their prior's median (people at one
    depth, :func:`held_at_prior`) with the prior's sd, which the other parameters' std carry."""
    if options.focal_px is not None:
        params[FOCAL] = options.focal_px  # exactly as given (no log/exp round trip)
    if options.pitch_deg is not None and method == "refine":
        params[PITCH] = math.radians(options.pitch_deg)
    camera = Camera(inp.size, params[FOCAL], tuple(inp.pp), params[PITCH], params[ROLL], params[HEIGHT],
                    distortion=params[DISTORTION] if options.distortion else 0.0)
    inlier_mask = np.zeros(len(inp.feet), bool)
    inlier_mask[idx[mask_u]] = True
    clusters = inp.tracks if inp.tracks is not None else inp.frames
    inl = prob.subset(np.flatnonzero(mask_u))
    pp_sd = (0.02 * max(inp.size) if options.principal_point is None else 0.0) \
        if options.principal_point_sd_px is None else options.principal_point_sd_px
    height_known = options.camera_height_m is not None
    # The people's mean stature is known to the prior's own sd when that is the narrower (a reference person measured
    # with a tape, --person-height S --height-sd 0.01), else to person_height_mean_sd_m (a population's mean).
    stature_mean_sd = 0.0 if height_known else min(options.person_height_mean_sd_m, options.person_height_sd_m)
    held = held or {}
    assumed = Systematics(pp_sd, 0.0 if options.distortion else options.distortion_sd, stature_mean_sd,
                          options.box_depth_sd_m if points == "boxes" else 0.0, tuple(held.items()))
    shifts: dict = {}
    cov, cov_stat, cov_warns, by_slot = covariances(inl, params, free, scale,
                                                    None if clusters is None else clusters[idx[mask_u]], assumed,
                                                    method == "refine" and not held, shifts)
    std, corr = std_and_corr(params, cov, free)
    std_stat, _ = std_and_corr(params, cov_stat, free)
    (eu, ev), _, _, _ = profiled(inl, params[None], scale)
    sq = inp.residual.squared_px((eu[0], ev[0]))
    rmse = float(np.sqrt(np.mean(sq))) if len(sq) else math.nan
    fixed = {name: reason for name, reason, free_ in (
        ("focal_px", "given", free[FOCAL]), ("pitch_deg", "given", free[PITCH] or method == "grid"),
        ("roll_deg", "0 (not estimated)", free[ROLL]),
        ("distortion", "none", free[DISTORTION] or not options.distortion)) if not free_}
    focal_informed = "people" in by_slot.get(FOCAL, "").split("+")  # the people's information fixes the focal
    by_slot = moved_by_data(by_slot, params, inl.priors, free)  # an estimate far from its prior: the people's too
    determined = {_SLOT_NAMES[slot]: label for slot, label in by_slot.items() if slot in _SLOT_NAMES}
    for slot, sd in held.items():  # held at the prior's median: its sd is the prior's
        name = _SLOT_NAMES[slot]
        value = camera.focal_px * sd if slot == FOCAL else math.degrees(sd)
        fixed.pop(name, None)
        std, std_stat = {**std, name: value}, {**std_stat, name: value}
        determined = {name: "prior", **determined}
    stature, stature_sd = options.person_height_m, math.nan
    if height_known:  # the same fit at the known scale: the stature carries it
        ratio = options.camera_height_m / camera.height_m
        stature, stature_sd = stature * ratio, stature * ratio * std["height_m"] / camera.height_m
        camera = camera.replace(height_m=options.camera_height_m)
        std = {**std, "height_m": math.nan}
        std_stat = {**std_stat, "height_m": math.nan}
        fixed["height_m"] = "given"
        determined["person_height_m"] = determined.pop("height_m", "people")
        determined["height_m"] = "given"
    if fixed.get("pitch_deg") == "given":
        determined["pitch_deg"] = "given"
    focal_prior = "none" if inp.priors is None or not (free[FOCAL] or FOCAL in held) else inp.priors.focal_kind
    ground = ground_findings(inp.feet, inp.heads, camera, stature,
                             inp.tracks if inp.tracks is not None else np.arange(len(inp.feet)), inlier_mask,
                             inp.tracks is not None)
    implausible = implausible_findings(camera, std, focal_estimated=bool(free[FOCAL] or FOCAL in held),
                                       height_estimated=not height_known,
                                       mean_stature_m=stature if height_known else None,
                                       focal_from_people=bool(free[FOCAL]) and focal_informed,
                                       ground=ground)
    warns = extra + cov_warns + fit_warnings(camera, std, corr, int(mask_u.sum()), inp.n_usable, len(inp.feet),
                                             determined, inp.one_depth) + [g.message for g in ground
                                                                            if not g.implausible]
    if method == "refine" and inp.tracks is None and n_frames > 1:
        warns.append("no track ids: a person seen in several frames counts as a new person each time, so the std "
                     "is too small when people persist (give the person ids)")
    return CalibrationResult(camera, method, stature, len(inp.feet), int(mask_u.sum()), n_frames, rmse,
                             std, corr, inlier_mask, tuple(warns), inp.residual.name, std_stat, points,
                             float(params[DISTORTION]) if options.distortion else math.nan,
                             float(params[BOX_DEPTH]), fixed, tuple(notes), height_known, stature_sd,
                             determined, implausible, 1.0 if inl.deff is None else float(np.max(inl.deff)),
                             0 if prob.body is None else prob.body.people, focal_prior,
                             covariance=report_covariance(params, cov, free, held, height_known, shifts),
                             footprint_px=footprint_polygon_px(inp.feet[inlier_mask]))
