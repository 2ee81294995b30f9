"""Sequence-level evaluation: match people per frame, score every matched pair, aggregate.

One :func:`evaluate` call scores one prediction directory against the ground truth, streaming
frame by frame. Metric names (all mm unless stated):

- ``mpjpe`` / ``pve``: pelvis-aligned; ``pa_mpjpe`` / ``pa_pve``: per-person similarity;
- ``w_mpjpe`` / ``w_pve``: no alignment at all (the seed paper's definition);
- ``w_mpjpe_spec`` / ``w_pve_spec``: SPEC's variant (gravity frames from both cameras, then
  pelvis-aligned); only when the prediction and the ground truth both have a camera.yaml;
- with the true camera: ``root_err`` (pelvis position error), ``foot_height`` (|height of the
  predicted foot point above the true ground|), ``lean_deg`` (predicted foot->crown axis vs the
  true vertical), ``stature_err`` (|predicted - true sole->crown length|);
- detection: matched, missed, false positives, precision, recall, f1, and AGORA's
  ``nmje = mpjpe / f1`` and ``nmve = pve / f1``;
- camera errors (``cam_focal_pct``, ``cam_pitch_deg``, ``cam_roll_deg``, ``cam_height_pct``)
  when both directories have a camera.yaml;
- temporal metrics of tracks (a ground-truth person id's matched frames in order): ``accel_err``,
  ``jitter``, ``foot_sliding`` (:mod:`.temporal`);
- a frame's matched people together (:mod:`.multi_person`): ``group_pa_mpjpe`` (one similarity for
  all of them, averaged over frames) and ``pcrd`` (share of pairs whose depth order is right, a share
  of 1, higher is better).

Those are the ``paper`` protocol's. ``EvalOptions(protocol=...)`` picks another benchmark's
definitions, root, joint set, matching and rounding (:mod:`.protocols`): ``spec``, ``agora``,
``bedlam``, ``wham``; a result names its protocol, the units of each metric, and notes on what
was skipped.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Callable
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..files.atomic import atomic_open
from ..geometry.camera import Camera, camera_parameters, project_cam_to_px
from ..errors import InputError, input_errors
from ..bodies.joint_layouts import LAYOUT_NAMES, layout_key
from ..bodies.landmarks import SMPL_JOINT_NAMES
from ..bodies.measure import scale_source
from ..settings.option_rules import Rule, check_fields
from ..plain import csv_cell
from ..sequence import Frame, Intrinsics, Sequence
from .fused import ENGINES, resolve_engine
from .matching import match_agora, match_by_ids, match_hungarian
from .points import mpjpe
from .person_metrics import PERSON_METRIC_FAMILIES, PERSON_METRICS, MatchedPairs, concat_pairs
from .protocols import (CONTACT_M, GVHMR_FPS, HIP_JOINTS, PROTOCOL_NAMES, SMPL_VERTICES, Protocol, aggregate, protocol,
                        root_points)
from .scene import camera_errors
from .temporal import TrackSeries

__all__ = ["EvalOptions", "EvalResult", "evaluate", "evaluate_frame", "frame_w_mpjpe", "match_frame", "merge_results",
           "pairing_options", "parse_joints"]

MATCHES = ("auto", "ids", "hungarian", "agora")  # how people are matched (docs/metrics.md)
MAX_JOINTS = 1000  # a joint set is at most this long (SMPL-X with hands and face: 144)


@dataclass(frozen=True)
class EvalOptions:
    """How to match and which joints to use."""

    match: str = "auto"  # auto | ids | hungarian | agora
    threshold_px: float = 100.0
    iou_threshold: float = 0.1
    joints: tuple[int, ...] | None = None  # subset of joint indices (both sides)
    engine: str = "auto"  # vertex metrics: auto | numpy | numba (see metrics.ENGINES)
    protocol: str = "paper"  # whose definitions: paper | spec | agora | bedlam | wham (metrics.protocols)

    RULES: ClassVar[dict[str, Rule]] = {  # the ``eval`` keys' bounds and names (rotavat_cli/settings/option_rules.py)
        "match": Rule(names=MATCHES), "engine": Rule(names=ENGINES), "protocol": Rule(names=PROTOCOL_NAMES),
        "threshold_px": Rule(low=0, open_low=True, unit="px"), "iou_threshold": Rule(low=0, high=1),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.RULES)

    @classmethod
    def from_config(cls, section: dict, joints: tuple[int, ...] | None = None) -> EvalOptions:
        """Options from the ``eval`` config section (match, thresholds, engine, protocol)."""
        return cls(section["match"], float(section["threshold_px"]), float(section["iou_threshold"]), joints,
                   str(section["engine"]), str(section["protocol"]))


@dataclass
class EvalResult:
    """Scores of one prediction directory."""

    pred: str
    gt: str
    frames: int = 0
    frames_pred_only: int = 0
    frames_gt_only: int = 0
    people_gt: int = 0
    people_pred: int = 0
    matched: int = 0
    missed: int = 0
    false_positives: int = 0
    track_pairs: int = 0  # matched pairs fed to tracks (temporal metrics)
    track_pairs_without_feet: int = 0  # of those, pairs without foot points (left out of foot sliding)
    protocol: str = "paper"
    metrics: dict[str, float] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)  # metric -> unit ('' for ratios)
    notes: list[str] = field(default_factory=list)  # what was skipped or left out, and why
    camera: dict[str, float] = field(default_factory=dict)
    per_person: dict[str, list] = field(default_factory=dict)
    tracks: TrackSeries | None = None  # the tracks' temporal state (merged by merge_results; not reported)
    fps: float | None = None  # the ground truth's meta.yaml fps
    stature_from: str | None = None  # where the prediction's camera scale comes from (measure.SCALE_SOURCES); None: no camera
    tool_world: dict | None = None  # the tool's own world against rotavat's (metrics.tool_world), None without one

    def as_dict(self, per_person: bool = False) -> dict:
        """Plain dict for JSON (per-person rows only when asked)."""
        d = {k: v for k, v in vars(self).items() if k not in ("per_person", "tracks", "fps")}
        return {**d, "per_person": self.per_person} if per_person else d


def parse_joints(spec: str | None, n_joints: int | None = None) -> tuple[int, ...] | None:
    """``"0,1,2"`` or ``"0-23"`` or SMPL joint names -> joint indices."""
    if not spec:
        return None

    out: list[int] = []
    for token in (t.strip() for t in spec.split(",") if t.strip()):
        if token in SMPL_JOINT_NAMES:
            out.append(SMPL_JOINT_NAMES.index(token))
        elif re.fullmatch(r"\d+-\d+", token):
            lo, hi = (int(v) for v in token.split("-"))
            if hi < lo or hi - lo >= MAX_JOINTS:
                raise InputError(f"--joints: range '{token}' must go up, over at most {MAX_JOINTS} joints")
            out.extend(range(lo, hi + 1))
        elif token.lstrip("-").isdigit():
            out.append(int(token))
        else:
            raise InputError(f"--joints: '{token[:40]}' is neither an index, a range nor an SMPL joint name")
        if len(out) > MAX_JOINTS:
            raise InputError(f"--joints: more than {MAX_JOINTS} joints")
    if n_joints is not None and any(not 0 <= j < n_joints for j in out):
        raise InputError(f"--joints: indices must be within 0..{n_joints - 1}")
    return tuple(out)


def _people_px(frame: Frame, intrinsics: Intrinsics, joints: tuple[int, ...] | None,
               lens: Camera | None = None) -> np.ndarray | None:
    """2D points per person used for matching, in image pixels: projected joints (through ``lens``, the sequence's
    camera when its frames are in it: ``Sequence.image_lens``), else 2D keypoints, else foot/head."""
    focals = intrinsics.focals_px(frame.n_people)
    if frame.get("joints") is not None and focals is not None:
        j = frame.data["joints"]
        px = project_cam_to_px(j[:, list(joints)] if joints else j, focals[:, None], intrinsics.principal_point)
        return px if lens is None else lens.distort_px(px)
    if frame.get("keypoints_2d") is not None:
        return frame.data["keypoints_2d"].astype(np.float64)
    if frame.get("feet_2d") is not None and frame.get("heads_2d") is not None:
        return np.stack([frame.data["feet_2d"], frame.data["heads_2d"]], axis=1).astype(np.float64)
    return None


def _match(pred: Frame, gt: Frame, pred_intr: Intrinsics, gt_intr: Intrinsics, opts: EvalOptions,
           lenses: tuple[Camera | None, Camera | None] = (None, None)) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame one-to-one matching (pred_idx, gt_idx); ``opts`` as :func:`_effective` makes them; ``lenses``:
    each side's ``Sequence.image_lens``."""
    both_ids = pred.get("person_ids") is not None and gt.get("person_ids") is not None
    if opts.match == "ids" or (opts.match == "auto" and both_ids):
        if not both_ids:
            raise InputError(f"{pred.source}: --match ids needs 'person_ids' on both sides")
        return match_by_ids(pred.person_ids, gt.person_ids)
    pred_px, gt_px = _people_px(pred, pred_intr, opts.joints, lenses[0]), _people_px(gt, gt_intr, opts.joints, lenses[1])
    if pred_px is None or gt_px is None or pred_px.shape[1] != gt_px.shape[1]:
        raise InputError(f"{pred.source}: cannot match people in 2D (need joints with a known focal, "
                         "keypoints_2d or feet_2d/heads_2d with the same count on both sides; or use --joints)")
    if opts.match == "agora":
        return match_agora(pred_px, gt_px, opts.iou_threshold)
    return match_hungarian(pred_px, gt_px, opts.threshold_px)


def _check_joint_order(seq: Sequence, proto: Protocol) -> None:
    """InputError when a protocol that scores SMPL's joints by index (the first N, or the hips as root)
    meets a sequence whose meta.yaml says its joints are in another order (an import's own layout)."""
    block = seq.meta.get("import")
    layout = block.get("joints_layout") if isinstance(block, dict) else None
    if layout is None or (proto.first_joints is None and proto.root != "hips"):
        return
    names = LAYOUT_NAMES.get(layout_key(layout))
    n = proto.first_joints or max(HIP_JOINTS) + 1
    if names is not None and tuple(names[:n]) != tuple(SMPL_JOINT_NAMES[:n]):
        raise InputError(f"{seq.label}: --protocol {proto.name} scores SMPL's joints by index, but its joints are "
                         f"in the layout {layout_key(layout)} (meta.yaml import.joints_layout): import it with "
                         "--smpl-model to get SMPL-24 joints")


def _check_joints(frame: Frame, opts: EvalOptions) -> None:
    """InputError unless the frame's joints hold every joint the options ask for (``--joints``, or the
    protocol's first N joints, or the hips its root needs)."""
    joints = frame.get("joints")
    if joints is None or frame.n_people == 0:
        return
    n_joints = joints.shape[1]
    proto = protocol(opts.protocol)
    needed = max(proto.first_joints or 1, max(HIP_JOINTS) + 1 if proto.root == "hips" else 1)
    if n_joints < needed:
        raise InputError(f"{frame.source}: --protocol {proto.name} scores the first {needed} joints (SMPL order) "
                         f"but the frame has {n_joints}")
    if opts.joints and (max(opts.joints) >= n_joints or min(opts.joints) < -n_joints):
        bad = max(opts.joints) if max(opts.joints) >= n_joints else min(opts.joints)
        raise InputError(f"{frame.source}: --joints asks for joint {bad} but the frame has {n_joints} joints "
                         f"(0..{n_joints - 1})")


def _gather_pairs(pred: Frame, gt: Frame, pi: np.ndarray, gi: np.ndarray, opts: EvalOptions,
                  vertices: bool = True) -> MatchedPairs:
    """The matched people's joints (the protocol's set or ``--joints``) with their roots (from all the
    joints, so ``--joints`` never moves the root) and vertices (``vertices=False``: left out, their counts
    still checked), checked for equal point counts."""
    pj, gj = pred.get("joints"), gt.get("joints")
    pr = gr = None
    if pj is not None and gj is not None:
        pj, gj = pj[pi], gj[gi]
        rule = protocol(opts.protocol).root
        pr, gr = root_points(pj, rule), root_points(gj, rule)
        if opts.joints:
            pj, gj = pj[:, list(opts.joints)], gj[:, list(opts.joints)]
        if pj.shape[1] != gj.shape[1]:
            raise InputError(f"{pred.source}: prediction has {pj.shape[1]} joints, ground truth {gj.shape[1]}: "
                             "pass --joints to choose a common subset")
    else:
        pj = gj = None
    pv, gv = pred.get("vertices"), gt.get("vertices")
    if pv is not None and gv is not None and pv.shape[1] != gv.shape[1]:
        raise InputError(f"{pred.source}: PVE needs equal vertex counts ({pv.shape[1]} vs {gv.shape[1]} in ground truth)")
    if vertices and pv is not None and gv is not None and pv.shape[1] > 0:
        pv, gv = pv[pi], gv[gi]  # the matched people, gathered once
    else:
        pv = gv = None
    return MatchedPairs(pj, gj, pv, gv, pr, gr, frames=np.zeros(len(pi), np.int64))


def _pair_metrics(pairs: MatchedPairs, n_pairs: int, pred_cam: Camera | None, gt_cam: Camera | None,
                  opts: EvalOptions) -> dict[str, np.ndarray]:
    """Every per-person metric of the protocol for ``n_pairs`` gathered pairs, (M,) each, under its report
    names (e.g. SPEC's ``w_mpjpe`` is the gravity-frame error); NaN where not computable or not reported."""
    proto = protocol(opts.protocol)
    computed: dict[str, np.ndarray] = {}
    for family in PERSON_METRIC_FAMILIES:
        if any(source in family.names for source in proto.pair_metrics.values()):
            computed.update({k: v for k, v in family.compute(pairs, pred_cam, gt_cam, opts.engine).items()
                             if k in family.names})
    out = {name: np.full(n_pairs, np.nan) for name in PERSON_METRICS}
    out.update({name: computed[source] for name, source in proto.pair_metrics.items() if source in computed})
    return out


# Matched people scored per metrics call, across consecutive frames: a frame has ~10 people, and
# per-call costs dominate at that size (docs/metrics.md, "Measured"). 128 SMPL people hold ~21 MB
# of float32 vertices per side.
SCORE_BATCH_PEOPLE = 128


@dataclass
class _ScoreBatch:
    """Matched pairs of consecutive frames, scored together into ``columns`` in frame order."""

    pred_cam: Camera | None
    gt_cam: Camera | None
    opts: EvalOptions
    columns: dict[str, list]
    queue: list[tuple[str, np.ndarray, np.ndarray, np.ndarray, MatchedPairs]] = field(default_factory=list)  # frame, pi, gi, ids

    def add(self, frame: str, pi: np.ndarray, gi: np.ndarray, person_ids: np.ndarray, pairs: MatchedPairs) -> None:
        """Queue one frame's matched pairs; score the queue when full or when the kind of arrays changes."""
        if self.queue and self.queue[0][4].kind() != pairs.kind():
            self.flush()
        self.queue.append((frame, pi, gi, person_ids, pairs))
        if self._queued_people() >= SCORE_BATCH_PEOPLE:
            self.flush()

    def _queued_people(self) -> int:
        """Matched pairs waiting in the queue."""
        return sum(len(pi) for _, pi, _, _, _ in self.queue)

    def flush(self) -> None:
        """Score the queued pairs in one call and append their rows to ``columns``."""
        if not self.queue:
            return
        pairs = concat_pairs([item[4] for item in self.queue])
        values = _pair_metrics(pairs, self._queued_people(), self.pred_cam, self.gt_cam, self.opts)
        for frame, pi, gi, person_ids, _ in self.queue:
            self.columns["frame"].extend([frame] * len(pi))
            self.columns["pred_index"].extend(pi.tolist())
            self.columns["gt_index"].extend(gi.tolist())
            self.columns["person_id"].extend(person_ids.tolist())
        for key in PERSON_METRICS:
            self.columns[key].extend(np.asarray(values[key], dtype=np.float64).tolist())
        self.queue = []


def _camera_errors(pred_cam: Camera, gt_cam: Camera) -> dict[str, float]:
    """Camera errors under report names."""
    err = camera_errors(camera_parameters(pred_cam), camera_parameters(gt_cam))
    return {f"cam_{k}": float(v) for k, v in err.items()}


def _effective(opts: EvalOptions) -> EvalOptions:
    """The options with the protocol's own matching and joint set (each option's range: EvalOptions.RULES);
    InputError for an uninstalled engine or clashing options."""
    with input_errors("--engine"):
        resolve_engine(opts.engine)  # an uninstalled engine fails here, before any output
    proto = protocol(opts.protocol)
    if proto.match and opts.match not in ("auto", proto.match):
        raise InputError(f"--protocol {proto.name} matches people its own way ({proto.match}); drop --match {opts.match}")
    if proto.first_joints is None:
        return opts
    if opts.joints:
        raise InputError(f"--joints applies to --protocol paper; {proto.name} scores its own joint set "
                         f"(the first {proto.first_joints}, SMPL order)")
    return replace(opts, match=proto.match or opts.match, joints=tuple(range(proto.first_joints)))


def _check_frame_names(pred_seq: Sequence, gt_seq: Sequence, pred_names: set, gt_names: set) -> None:
    """InputError when the two sides share no frame name (frames are paired by name: nothing could be scored)."""
    if pred_names and gt_names and not pred_names & gt_names:
        raise InputError(f"{pred_seq.label}: none of its {len(pred_names)} frame names (e.g. '{min(pred_names)}') is "
                         f"among the ground truth's {len(gt_names)} ({gt_seq.label}, e.g. '{min(gt_names)}'); "
                         "frames are paired by name")


def _track_series(proto: Protocol) -> TrackSeries | None:
    """The temporal accumulator a protocol needs, or None."""
    if not proto.track_metrics:
        return None
    return TrackSeries(("accel", "jitter", "foot_sliding"), CONTACT_M, keep_all=proto.whole_tracks,
                       accel_hips=proto.root == "hips")


def pairing_options(pred_seq: Sequence, gt_seq: Sequence, options: EvalOptions | None = None) -> EvalOptions:
    """What :func:`evaluate` checks of two sequences before reading a frame: the effective options (the protocol's
    own matching and joint set); InputError when the two cannot be compared (no frame name in common, a protocol
    scoring SMPL's joints by index on another layout, an uninstalled engine, clashing options)."""
    opts = _effective(options or EvalOptions())
    _check_frame_names(pred_seq, gt_seq, set(pred_seq.frame_names), set(gt_seq.frame_names))
    for seq in (pred_seq, gt_seq):
        _check_joint_order(seq, protocol(opts.protocol))
    return opts


def evaluate(pred_seq: Sequence, gt_seq: Sequence, options: EvalOptions | None = None,
             progress: Callable[[], None] | None = None, frames: tuple[int, int] | None = None) -> EvalResult:
    """Score one prediction sequence against the ground truth, frame by frame (both opened:
    :func:`~rotavat_cli.sequence.open_sequence`), by the rules of ``options.protocol``.

    ``frames=(start, stop)`` scores only that range of the sorted union of both sides' frame
    names; :func:`merge_results` joins the results of consecutive ranges into the whole one.
    """
    names = sorted(set(pred_seq.frame_names) | set(gt_seq.frame_names))
    return _evaluate(pred_seq, gt_seq, options, names if frames is None else names[frames[0]:frames[1]], progress,
                     lambda seq, name: seq.read_frame(name))


def evaluate_frame(pred_seq: Sequence, gt_seq: Sequence, name: str, pred_frame: Frame | None = None,
                   gt_frame: Frame | None = None, options: EvalOptions | None = None) -> EvalResult:
    """:func:`evaluate` on frame ``name`` alone (``frames=(k, k + 1)`` of its index ``k``), from the frames the caller
    has read already (``pred_frame``, ``gt_frame``: that frame of each side; None: read it): each frame read once."""
    names = [name] if name in pred_seq.frame_names or name in gt_seq.frame_names else []

    def read(seq: Sequence, frame_name: str) -> Frame:
        frame = pred_frame if seq is pred_seq else gt_frame
        return seq.read_frame(frame_name) if frame is None else frame
    return _evaluate(pred_seq, gt_seq, options, names, None, read)


def _evaluate(pred_seq: Sequence, gt_seq: Sequence, options: EvalOptions | None, names: list[str],
              progress: Callable[[], None] | None, read: Callable[[Sequence, str], Frame]) -> EvalResult:
    """:func:`evaluate` over the frame ``names`` (in order), each side's frame got by ``read(seq, name)``."""
    opts = pairing_options(pred_seq, gt_seq, options)
    proto = protocol(opts.protocol)
    pred_names, gt_names = set(pred_seq.frame_names), set(gt_seq.frame_names)
    fps = gt_seq.meta.get("fps")
    result = EvalResult(pred_seq.label, gt_seq.label, protocol=proto.name, tracks=_track_series(proto),
                        fps=float(fps) if fps else None)
    pred_cam, gt_cam = pred_seq.camera, gt_seq.camera
    if pred_cam is not None and gt_cam is not None:
        result.camera = _camera_errors(pred_cam, gt_cam)
    if pred_cam is not None:
        result.stature_from = scale_source(pred_seq.camera_fit)
    columns: dict[str, list] = {k: [] for k in ("frame", "pred_index", "gt_index", "person_id", *PERSON_METRICS)}
    batch = _ScoreBatch(pred_cam, gt_cam, opts, columns)
    for name in names:
        _score_frame(name, pred_seq, gt_seq, pred_names, gt_names, opts, result, batch, read)
        if progress:
            progress()
    batch.flush()
    if result.tracks is not None:
        result.tracks.flush()
    result.per_person = columns
    _aggregate(result, columns)
    return result


def match_frame(pred: Frame, gt: Frame, pred_intr: Intrinsics, gt_intr: Intrinsics, opts: EvalOptions,
                vertices: bool = True, lenses: tuple[Camera | None, Camera | None] = (None, None)
                ) -> tuple[np.ndarray, np.ndarray, MatchedPairs | None]:
    """One frame's people matched and gathered as :func:`evaluate` scores them (``opts``: :func:`pairing_options`'):
    (M,) prediction indices, (M,) ground-truth indices, the matched pairs (None when M = 0; ``vertices=False``:
    without their vertices); ``lenses``: each side's ``Sequence.image_lens``; InputError as :func:`evaluate` (joints
    missing, people not matchable, point counts)."""
    _check_joints(pred, opts)
    _check_joints(gt, opts)
    if pred.n_people == 0 or gt.n_people == 0:
        pi = gi = np.zeros(0, dtype=np.int64)
    else:
        pi, gi = _match(pred, gt, pred_intr, gt_intr, opts, lenses)
    return pi, gi, _gather_pairs(pred, gt, pi, gi, opts, vertices) if len(pi) else None


def frame_w_mpjpe(pred: Frame, gt: Frame, pred_intr: Intrinsics, gt_intr: Intrinsics,
                  opts: EvalOptions) -> tuple[np.ndarray, np.ndarray]:
    """One frame's W-MPJPE per matched person, the ``w_mpjpe`` column :func:`evaluate` gives under the ``paper``
    protocol (no alignment: :func:`.points.mpjpe` with ``alignment="none"``): (M,) ground-truth person ids and (M,)
    mm, NaN when a side has no joints; ``opts`` and errors as :func:`match_frame`."""
    pi, gi, pairs = match_frame(pred, gt, pred_intr, gt_intr, opts, vertices=False)
    if pairs is None or pairs.pred_joints is None:
        return gt.person_ids[gi], np.full(len(gi), np.nan)
    return gt.person_ids[gi], mpjpe(pairs.pred_joints, pairs.gt_joints, "none")


_COUNTS = ("frames", "frames_pred_only", "frames_gt_only", "people_gt", "people_pred", "matched", "missed",
           "false_positives", "track_pairs", "track_pairs_without_feet")


def merge_results(parts: Seq[EvalResult]) -> EvalResult:
    """One result from the results of consecutive frame ranges of the same two sequences, in order.

    Counts are summed, per-person rows concatenated and tracks continued across the ranges, so the
    metrics are the same numbers one :func:`evaluate` call over the whole range gives (the track
    metrics up to float rounding of their sums).
    """
    if not parts:
        raise ValueError("merge_results needs at least one part")
    first = parts[0]
    result = EvalResult(first.pred, first.gt, protocol=first.protocol, camera=dict(first.camera), fps=first.fps,
                        stature_from=first.stature_from)
    for name in _COUNTS:
        setattr(result, name, sum(getattr(part, name) for part in parts))
    result.per_person = {key: [v for part in parts for v in part.per_person[key]] for key in first.per_person}
    if first.tracks is not None:
        result.tracks = first.tracks
        for part in parts[1:]:
            result.tracks = result.tracks.merge(part.tracks)
    _aggregate(result, result.per_person)
    return result


def _score_frame(name: str, pred_seq: Sequence, gt_seq: Sequence, pred_names: set, gt_names: set,
                 opts: EvalOptions, result: EvalResult, batch: _ScoreBatch,
                 read: Callable[[Sequence, str], Frame]) -> None:
    """Match one frame (each side's got by ``read``) into ``result`` counts and queue its matched pairs on ``batch``
    for scoring."""
    if name not in gt_names or name not in pred_names:  # unpaired: all false positives or all missed
        side = "pred" if name in pred_names else "gt"
        n = read(pred_seq if side == "pred" else gt_seq, name).n_people
        setattr(result, f"frames_{side}_only", getattr(result, f"frames_{side}_only") + 1)
        setattr(result, f"people_{side}", getattr(result, f"people_{side}") + n)
        if side == "pred" and protocol(opts.protocol).pred_only_frames_count:
            result.false_positives += n
        elif side == "gt":
            result.missed += n
        return
    pred, gt = read(pred_seq, name), read(gt_seq, name)
    result.frames += 1
    result.people_pred += pred.n_people
    result.people_gt += gt.n_people
    pi, gi, pairs = match_frame(pred, gt, pred_seq.frame_intrinsics(pred), gt_seq.frame_intrinsics(gt), opts,
                                lenses=(pred_seq.image_lens, gt_seq.image_lens))
    result.matched += len(pi)
    result.missed += gt.n_people - len(gi)
    result.false_positives += pred.n_people - len(pi)
    if pairs is None:
        return
    batch.add(name, pi, gi, gt.person_ids[gi], pairs)
    if result.tracks is not None and gt.get("person_ids") is not None and pairs.pred_joints is not None:
        _add_to_tracks(result, pred, gt, pi, gi, pairs, opts)


def _foot_points(frame: Frame, idx: np.ndarray, proto: Protocol) -> np.ndarray | None:
    """The matched people's foot points for foot sliding (M, 4, 3), or None when the frame lacks them:
    the protocol's ``feet`` (SMPL ankle and foot joints; wham: GVHMR's four SMPL foot vertices)."""
    feet = proto.feet
    if feet.vertices:
        verts = frame.get("vertices")
        ok = verts is not None and verts.shape[1] == SMPL_VERTICES
        return verts[idx][:, list(feet.indices)] if ok else None
    joints = frame.get("joints")
    return joints[idx][:, list(feet.indices)] if joints is not None and joints.shape[1] > max(feet.indices) else None


def _add_to_tracks(result: EvalResult, pred: Frame, gt: Frame, pi: np.ndarray, gi: np.ndarray, pairs: MatchedPairs,
                   opts: EvalOptions) -> None:
    """Feed one frame's matched pairs to the tracks (keyed by the ground truth's person ids)."""
    proto = protocol(opts.protocol)
    feet_p, feet_g = _foot_points(pred, pi, proto), _foot_points(gt, gi, proto)
    if feet_p is None or feet_g is None:  # NaN feet are never in contact: left out of foot sliding
        feet_p = feet_g = np.full((len(pi), len(proto.feet.indices), 3), np.nan)
        result.track_pairs_without_feet += len(pi)
    result.track_pairs += len(pi)
    result.tracks.add(gt.person_ids[gi], {"pred": pairs.pred_joints, "gt": pairs.gt_joints,
                                          "pred_feet": feet_p, "gt_feet": feet_g})


def _aggregate(result: EvalResult, columns: dict[str, list]) -> None:
    """The protocol's reported metrics, units and notes into ``result``."""
    proto = protocol(result.protocol)
    counts = {"matched": result.matched, "missed": result.missed, "false_positives": result.false_positives}
    skipped = {}
    if result.track_pairs and result.track_pairs_without_feet == result.track_pairs:
        skipped["foot_sliding"] = proto.feet.missing
    tracks = result.tracks if result.track_pairs else None
    result.metrics, notes = aggregate(proto, columns, counts, tracks, result.fps or GVHMR_FPS, skipped)
    result.units = {name: proto.unit(name) for name in result.metrics}
    if not result.camera:
        notes += [f"{name}: {note}" for name, note in proto.camera_notes.items()]
    if proto.track_metrics and result.track_pairs_without_feet and "foot_sliding" not in skipped:
        notes.append(f"foot_sliding: {result.track_pairs_without_feet} of {result.track_pairs} matched pairs lack "
                     "the foot points and are left out")
    if proto.per_second and result.tracks is not None and result.fps is None:
        notes.append(f"fps: the ground truth's meta.yaml gives none; GVHMR's {GVHMR_FPS:g} is used for accel_err "
                     "and jitter")
    if not proto.pred_only_frames_count and result.frames_pred_only:
        notes.append(f"{result.frames_pred_only} prediction frame(s) without ground truth ignored, "
                     f"{proto.pred_only_frames_note}")
    result.notes = notes


_PER_PERSON_COLUMNS = ("pred", "frame", "pred_index", "gt_index", "person_id", "protocol", *PERSON_METRICS)
# How every per-person CSV rotavat ever wrote starts (the overwrite check's signature: older files lack "protocol").
PER_PERSON_SIGNATURE = ",".join(_PER_PERSON_COLUMNS[:5])


def write_per_person_csv(path: str | Path, results: Seq[EvalResult]) -> None:
    """One row per matched pair of every prediction (atomic)."""
    with atomic_open(path, "w") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(_PER_PERSON_COLUMNS)
        for res in results:
            cols = res.per_person
            for i in range(len(cols["frame"])):
                writer.writerow([res.pred, *(csv_cell(cols[k][i]) for k in _PER_PERSON_COLUMNS[1:5]), res.protocol,
                                 *(csv_cell(cols[k][i]) for k in PERSON_METRICS)])
