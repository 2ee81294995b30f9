"""Evaluation protocols: which root, joints, alignment, matching and rounding each benchmark's own code uses.

The field uses one name for different quantities ("W-MPJPE" is three different things), so
``rotavat eval --protocol NAME`` picks whose definitions every reported number follows, and the
reports name the protocol beside each number. Each protocol is read from the benchmark's own
evaluation code (cited below and in docs/metrics.md); where it needs data the rotavat contract
does not carry (a joint regressor, a vertex subset), the metric is skipped with a note, never
approximated.

- ``paper`` (default): the seed paper's definitions, as rotavat always reported them (SMPL joint 0
  as the root, every joint or ``--joints``, unaligned W-metrics), plus temporal metrics of tracks
  in frame units (mm/frame^k; acceleration error and jitter of unaligned camera-frame joints, foot
  sliding of the SMPL ankle and foot joints), averaged per track, then over tracks, and the
  multi-person ``group_pa_mpjpe`` (per frame) and ``pcrd`` (per pair of people; :mod:`.multi_person`).
- ``spec``: mkocabas/SPEC @308fd4a, ``spec/utils/compute_error.py``, ``compute_error`` and
  ``eval_j_24`` (the 24-joint SPEC-SYN/SPEC-MTP protocol): root SMPL joint 0; ``mpjpe`` in the
  camera frame, ``w_mpjpe`` in each side's gravity-aligned frame (needs both camera.yaml),
  both pelvis-subtracted; ``pa_mpjpe``. Its V2V/W-V2V subtract the pelvis of the H36M regressor
  (``eval_single``): skipped.
- ``agora``: pixelite1201/agora_evaluation @c72c4a9 (``calculate_v2v_error.py``,
  ``compute_errors_joints_verts``, ``align_by_pelvis``; ``matching.py``, ``match_2d_greedy``) and
  @bf7cc6b (``compute_average_error.py``, ``compute_prf1``, ``compute_avg_error``): AGORA's greedy
  matching; 24 SMPL joints, pelvis = midpoint of the hips (joints 1, 2); MPJPE and NMJE rounded
  to 0.1 mm, precision/recall/F1 to 2 decimals, NMJE = rounded MPJPE / rounded F1; predictions on
  images without ground truth are ignored. MVE/NMVE and the PA-PVE (similarity fitted on the
  joints) use AGORA's body-vertex subset (``utils/body_verts_smpl.npy``): skipped.
- ``bedlam``: pixelite1201/BEDLAM @c79a9c8, ``train/core/hmr_trainer.py``, ``validation_step``
  (its ``bedlam`` branch) with ``train/utils/eval_utils.py``, ``reconstruction_error``: the first
  24 joints, pelvis = midpoint of the hips, vertices offset by that pelvis; ``mpjpe``,
  ``pa_mpjpe``, ``pve``.
- ``wham``: zju3dv/GVHMR @cb702cd, ``hmr4d/utils/eval/eval_utils.py`` (``compute_camcoord_metrics``,
  ``compute_global_metrics`` and their helpers) as run by ``hmr4d/model/gvhmr/callbacks/metric_emdb.py``
  (the world protocol WHAM/TRAM/EMDB numbers follow): 24 SMPL joints; ``mpjpe``, ``pa_mpjpe``,
  ``pve`` about the hips' midpoint; ``accel_err`` (m/s^2, hips-relative joints); per track
  ``w_mpjpe`` / ``wa_mpjpe`` (similarity on the first two frames / all frames of each 100-frame
  chunk, mm), ``rte`` (% of the true path length; root = SMPL joint 0), ``jitter`` (10 m/s^3),
  ``foot_sliding`` (mm; SMPL vertices 3216, 3387, 6617, 6787: 6,890-vertex meshes only); every
  per-frame value pooled over all tracks, as ``on_predict_epoch_end`` does. Frame rate: meta.yaml
  ``fps`` of the ground truth, else GVHMR's 30.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..bodies.landmarks import SMPL_JOINT_NAMES
from .person_metrics import PERSON_METRIC_POOLS, PERSON_METRICS
from .scene import detection_scores, normalize_by_f1
from .temporal import WINDOWS, TrackSeries, chunk_aligned_errors, first_frames_aligned_errors, rte

__all__ = ["PROTOCOLS", "PROTOCOL_NAMES", "Protocol", "FootPoints", "root_points", "agora_prf1", "agora_round",
           "protocol", "detection", "aggregate"]

MM_PER_M = 1000.0
HIP_JOINTS = (SMPL_JOINT_NAMES.index("left_hip"), SMPL_JOINT_NAMES.index("right_hip"))
# The paper's foot points for foot sliding: SMPL ankles and feet (toe bases).
FOOT_JOINTS = tuple(SMPL_JOINT_NAMES.index(n) for n in ("left_ankle", "right_ankle", "left_foot", "right_foot"))
# GVHMR's compute_foot_sliding: SMPL (6,890-vertex) heel and toe vertices of both feet.
GVHMR_FOOT_VERTICES = (3216, 3387, 6617, 6787)
SMPL_VERTICES = 6890
GVHMR_FPS = 30.0  # compute_camcoord_metrics / compute_jitter default
CONTACT_M = 0.01  # compute_foot_sliding: in contact when the true point moves < 1 cm per frame


@dataclass(frozen=True)
class FootPoints:
    """The points of each person that foot sliding follows, and why it is skipped when no matched pair has them."""

    indices: tuple[int, ...]  # joint or vertex indices, (4,)
    vertices: bool  # SMPL vertices (6,890-vertex meshes only), else joints
    missing: str  # the skip note when no matched pair has them on both sides


SMPL_FOOT_JOINTS = FootPoints(FOOT_JOINTS, False, "the joints have no SMPL ankles and feet (joints 7, 8, 10, 11)")
GVHMR_FOOT_POINTS = FootPoints(GVHMR_FOOT_VERTICES, True, "GVHMR's foot vertices 3216, 3387, 6617, 6787 need "
                               "6,890-vertex SMPL meshes on both sides")


@dataclass(frozen=True)
class Protocol:
    """One benchmark's rules. Names are the report's (metrics.json keys)."""

    name: str
    source: str  # repo @commit, file, function
    root: str  # "pelvis" (SMPL joint 0) | "hips" (midpoint of SMPL joints 1 and 2)
    first_joints: int | None  # the joint set: the first N joints (SMPL order); None = all or --joints
    match: str | None  # the matching it fixes (None: --match)
    pairs: Mapping[str, str] | None  # report name -> per-pair metric it is; None: every registered one (evaluate)
    track_metrics: tuple[str, ...]  # metrics of tracks (temporal.py)
    units: Mapping[str, str]  # unit of each reported metric (default_unit for the others)
    default_unit: str = ""
    skipped: Mapping[str, str] = field(default_factory=dict)  # metric -> why it is never computed here
    detection: str | None = None  # None | "rotavat" | "agora"
    pooled: bool = False  # track metrics pooled over every window (GVHMR), else per track then averaged
    pred_only_frames_count: bool = True  # False: predictions on frames without ground truth are ignored
    pred_only_frames_note: str = ""  # the note saying so (when pred_only_frames_count is False)
    camera_notes: Mapping[str, str] = field(default_factory=dict)  # metric -> note when either side has no camera
    feet: FootPoints = SMPL_FOOT_JOINTS  # foot sliding's points
    whole_tracks: bool = False  # W-MPJPE, WA-MPJPE, RTE of every frame of each track (GVHMR): tracks keep all frames
    per_second: bool = False  # window metrics per second at the ground truth's fps (GVHMR's units), else per frame

    @property
    def pair_metrics(self) -> Mapping[str, str]:
        """Report name -> per-pair metric (``person_metrics.PERSON_METRICS``) it is. The paper reports every
        registered per-person metric under its own name, so a new registry entry is reported at once."""
        if self.pairs is not None:
            return self.pairs
        return {name: name for name in PERSON_METRICS}

    def unit(self, name: str) -> str:
        """The unit a metric is reported in under this protocol ('' for ratios and counts)."""
        return self.units.get(name, self.default_unit if name in self.pair_metrics else "")


_MM = "mm"

PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (
    Protocol("paper", "the seed paper's definitions (docs/metrics.md)", "pelvis", None, None,
             None, ("accel_err", "jitter", "foot_sliding"),
             {"lean_deg": "deg", "accel_err": "mm/frame^2", "jitter": "mm/frame^3", "foot_sliding": "mm/frame",
              "nmje": _MM, "nmve": _MM, "pcrd": ""}, default_unit=_MM, detection="rotavat"),
    Protocol("spec", "mkocabas/SPEC@308fd4a spec/utils/compute_error.py compute_error, eval_j_24", "pelvis", 24, None,
             {"mpjpe": "mpjpe", "pa_mpjpe": "pa_mpjpe", "w_mpjpe": "w_mpjpe_spec"}, (),
             {"mpjpe": _MM, "pa_mpjpe": _MM, "w_mpjpe": _MM},
             camera_notes={"w_mpjpe": "needs a camera.yaml on both sides (each side's gravity frame)"},
             skipped={"pve": "SPEC's V2V subtracts the pelvis of the H36M joint regressor (data/J_regressor_h36m.npy, "
                             "eval_single), which the sequence does not carry",
                      "w_pve": "SPEC's W-V2V subtracts the pelvis of the H36M joint regressor (eval_single), which the "
                               "sequence does not carry"}),
    Protocol("agora", "pixelite1201/agora_evaluation@c72c4a9 calculate_v2v_error.py compute_errors_joints_verts, "
             "matching.py match_2d_greedy; @bf7cc6b compute_average_error.py compute_avg_error, compute_prf1",
             "hips", 24, "agora", {"mpjpe": "mpjpe", "pa_mpjpe": "pa_mpjpe"}, (),
             {"mpjpe": _MM, "pa_mpjpe": _MM, "nmje": _MM},
             skipped={k: "AGORA's MVE uses its SMPL body-vertex subset (agora_evaluation utils/body_verts_smpl.npy), "
                         "which rotavat does not ship" for k in ("pve", "pa_pve", "nmve")},
             detection="agora", pred_only_frames_count=False, pred_only_frames_note="as AGORA does"),
    Protocol("bedlam", "pixelite1201/BEDLAM@c79a9c8 train/core/hmr_trainer.py validation_step, "
             "train/utils/eval_utils.py reconstruction_error", "hips", 24, None,
             {"mpjpe": "mpjpe", "pa_mpjpe": "pa_mpjpe", "pve": "pve"}, (),
             {"mpjpe": _MM, "pa_mpjpe": _MM, "pve": _MM}),
    Protocol("wham", "zju3dv/GVHMR@cb702cd hmr4d/utils/eval/eval_utils.py compute_camcoord_metrics, "
             "compute_global_metrics; hmr4d/model/gvhmr/callbacks/metric_emdb.py", "hips", 24, None,
             {"mpjpe": "mpjpe", "pa_mpjpe": "pa_mpjpe", "pve": "pve"},
             ("w_mpjpe", "wa_mpjpe", "rte", "jitter", "accel_err", "foot_sliding"),
             {"mpjpe": _MM, "pa_mpjpe": _MM, "pve": _MM, "accel_err": "m/s^2", "w_mpjpe": _MM, "wa_mpjpe": _MM,
              "rte": "%", "jitter": "10 m/s^3", "foot_sliding": _MM},
             pooled=True, feet=GVHMR_FOOT_POINTS, whole_tracks=True, per_second=True),
)}
PROTOCOL_NAMES: tuple[str, ...] = tuple(PROTOCOLS)


def protocol(name: str) -> Protocol:
    """The protocol called ``name``; ValueError listing the known ones."""
    if name not in PROTOCOLS:
        raise ValueError(f"unknown protocol {name!r} (known: {', '.join(PROTOCOL_NAMES)})")
    return PROTOCOLS[name]


def root_points(joints: np.ndarray, rule: str) -> np.ndarray:
    """Each person's root by a protocol's rule, from all of its joints: (P, J, 3) -> (P, 3) float64.

    ``pelvis``: SMPL joint 0; ``hips``: the midpoint of joints 1 and 2 (left and right hip), as
    AGORA's ``align_by_pelvis``, BEDLAM's ``validation_step`` and GVHMR's ``batch_align_by_pelvis``.
    """
    j = np.asarray(joints, dtype=np.float64)
    if rule == "pelvis":
        return j[:, 0]
    return 0.5 * (j[:, HIP_JOINTS[0]] + j[:, HIP_JOINTS[1]])


def agora_round(value: float, digits: int) -> float:
    """``round`` of a numpy float64, as AGORA applies it to pandas means (numpy's rounding rule)."""
    return float(round(np.float64(value), digits))


def agora_prf1(matched: int, missed: int, false_positives: int) -> dict[str, float]:
    """AGORA's ``compute_prf1``: precision, recall, F1 rounded to 2 decimals (Python floats);
    all 0 without ground truth; NaN where AGORA's division by zero would raise."""
    count = matched + missed
    if count == 0:
        return {"precision": 0.0, "recall": 0.0, "f1": 0.0}
    tp, fn, fp = matched, missed, false_positives

    def ratio(num: float, den: float) -> float:
        return round(num / den, 2) if den else math.nan

    return {"precision": ratio(tp, tp + fp), "recall": ratio(tp, tp + fn), "f1": ratio(tp, tp + 0.5 * (fp + fn))}


def _agora_normalised(err_mm: float, f1: float) -> float:
    """AGORA's NMJE: ``round(rounded error / rounded F1, 1)``; inf where AGORA divides by an F1 of 0."""
    if not math.isfinite(f1):
        return math.nan
    if f1 == 0.0:
        return math.nan if math.isnan(err_mm) else math.inf
    return agora_round(np.float64(err_mm) / f1, 1)


def _mean(values: np.ndarray) -> float:
    """Mean of the finite values; NaN when none."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else math.nan


def detection(proto: Protocol, means: Mapping[str, float], counts: Mapping[str, int]) -> dict[str, float]:
    """The protocol's detection scores and error-over-F1 numbers from the per-pair means (mm) and the
    match counts (matched, missed, false_positives); AGORA's also round its MPJPE (returned too)."""
    if proto.detection == "rotavat":
        out = detection_scores(counts["matched"], counts["missed"], counts["false_positives"])
        out["nmje"] = float(normalize_by_f1(means.get("mpjpe", math.nan), out["f1"]))
        out["nmve"] = float(normalize_by_f1(means.get("pve", math.nan), out["f1"]))
        return out
    if proto.detection == "agora":
        mpjpe = means.get("mpjpe", math.nan)
        out = {"mpjpe": agora_round(mpjpe, 1) if math.isfinite(mpjpe) else mpjpe,
               **agora_prf1(counts["matched"], counts["missed"], counts["false_positives"])}
        out["nmje"] = _agora_normalised(out["mpjpe"], out["f1"])
        return out
    return {}


def aggregate(proto: Protocol, columns: Mapping[str, list], counts: Mapping[str, int],
              tracks: TrackSeries | None, fps: float,
              skipped: Mapping[str, str] | None = None) -> tuple[dict[str, float], list[str]]:
    """The protocol's reported metrics from per-pair columns, match counts and tracks, and notes.

    columns: per-pair values under their report names, and ``frame`` (each pair's frame name: the
    metrics of a frame's group pool by it, :data:`~.person_metrics.PERSON_METRIC_POOLS`); counts:
    matched, missed, false_positives; tracks: the accumulated tracks or None (no track ids); fps:
    frames per second (GVHMR's units); skipped: metrics this data cannot give (beyond the protocol's
    own), with why.
    """
    out, empty = {}, {}
    for name, source in proto.pair_metrics.items():
        values = np.asarray(columns[name], dtype=np.float64)
        pool, no_value = PERSON_METRIC_POOLS.get(source, (None, ""))
        out[name] = _mean(values) if pool is None else pool(values, np.asarray(columns["frame"]))
        if pool is not None and len(values) and math.isnan(out[name]):
            empty.setdefault(no_value, []).append(name)
    skipped = {**proto.skipped, **(skipped or {})}
    reasons: dict[str, list[str]] = {}
    for name, why in skipped.items():
        reasons.setdefault(why, []).append(name)
    notes = [f"{', '.join(names)}: skipped: {why}" for why, names in reasons.items()]
    notes += [f"{', '.join(names)}: no value: {why}" for why, names in empty.items()]
    out.update(detection(proto, out, counts))
    if proto.track_metrics:
        track_values, track_notes = _track_metrics(proto, tracks, fps, skipped)
        out.update(track_values)
        notes += track_notes
    return out, notes


def _track_metrics(proto: Protocol, tracks: TrackSeries | None, fps: float,
                   skipped: Mapping[str, str]) -> tuple[dict[str, float], list[str]]:
    """The protocol's temporal/trajectory metrics; NaN with a note where they cannot be computed."""
    out = {name: math.nan for name in proto.track_metrics}
    if tracks is None:
        return out, [f"{', '.join(proto.track_metrics)}: skipped: no tracks (no matched pair whose ground truth "
                     "has person_ids and joints)"]
    notes = []
    windows = {"accel_err": "accel", "jitter": "jitter", "foot_sliding": "foot_sliding"}
    scale = _window_scales(proto, fps)
    for name, metric in windows.items():
        if metric not in tracks.metrics or name in skipped:
            continue
        sums = tracks.per_track(metric)
        if not any(c for _, c in sums.values()):
            notes.append(f"{name}: no value: " + (
                "no true foot point is in contact (moves < 1 cm per frame) in any track" if metric == "foot_sliding"
                else f"no track has {WINDOWS[metric]} matched frames"))
            continue
        if proto.pooled:
            total, n = sum(s for s, _ in sums.values()), sum(c for _, c in sums.values())
            out[name] = total / n * scale[name] if n else math.nan
        else:
            means = [s / c for s, c in sums.values() if c]
            out[name] = float(np.mean(means)) * scale[name] if means else math.nan
    if proto.whole_tracks:
        whole, whole_notes = _whole_track_metrics(tracks)
        out.update(whole)
        notes += whole_notes
    return out, notes


def _window_scales(proto: Protocol, fps: float) -> dict[str, float]:
    """Metres/frame^k -> the protocol's units: mm/frame^k, or with ``per_second`` GVHMR's m/s^2, 10 m/s^3, mm (wham)."""
    if proto.per_second:
        return {"accel_err": fps ** 2, "jitter": fps ** 3 / 10.0, "foot_sliding": MM_PER_M}
    return {"accel_err": MM_PER_M, "jitter": MM_PER_M, "foot_sliding": MM_PER_M}


def _whole_track_metrics(tracks: TrackSeries) -> tuple[dict[str, float], list[str]]:
    """GVHMR's W-MPJPE, WA-MPJPE (mm) and RTE (%), every per-frame value pooled over the tracks."""
    w, wa, rtes, still = [], [], [], 0
    for track_id in sorted(tracks.tracks):
        frames = tracks.frames_of(track_id)
        if not frames:
            continue
        w.append(first_frames_aligned_errors(frames["pred"], frames["gt"]))
        wa.append(chunk_aligned_errors(frames["pred"], frames["gt"]))
        if not np.linalg.norm(np.diff(frames["gt"][:, 0], axis=0), axis=-1).sum() > 0.0:
            still += 1  # a path length of 0 (or one frame): GVHMR's RTE divides by it
            continue
        rtes.append(rte(frames["pred"][:, 0], frames["gt"][:, 0]))
    out = {"w_mpjpe": _pooled(w) * MM_PER_M, "wa_mpjpe": _pooled(wa) * MM_PER_M, "rte": _pooled(rtes) * 100.0}
    notes = [f"rte: {still} track(s) left out: the true root never moves (a path length of 0; GVHMR divides by it)"] \
        if still else []
    return out, notes


def _pooled(parts: list[np.ndarray]) -> float:
    """Mean of every value of every part; NaN when there are none."""
    values = np.concatenate(parts) if parts else np.zeros(0)
    return float(values.mean()) if values.size else math.nan
