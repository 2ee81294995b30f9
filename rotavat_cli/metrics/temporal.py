"""Temporal and trajectory metrics of tracks: pure arrays, plus a streaming per-track accumulator.

A *track* is one ground-truth person id's matched frames in frame order; frames where that person
is not matched are skipped, not interpolated (GVHMR's ``compute_global_metrics`` likewise runs on
"the input [that] has skipped invalid frames"). Points are ``(T, N, 3)``: ``T`` frames of one
track, ``N`` joints or foot points, metres, one fixed frame (the static camera's frame is a world
frame: every metric here is unchanged by one rigid motion of a whole track, so the camera frame
and a gravity-aligned world frame give the same numbers).

Window metrics, one value per window of consecutive track frames (metres per frame^k; the
protocols scale them, :mod:`.protocols`):

- :func:`accel_errors`: ``mean_j |(p[t] - 2p[t+1] + p[t+2]) - (g[t] - 2g[t+1] + g[t+2])|`` (T-2,)
  (:func:`second_differences` of each side),
  as ``compute_error_accel`` (zju3dv/GVHMR @cb702cd, ``hmr4d/utils/eval/eval_utils.py``; the
  same formula as VIBE/WHAM);
- :func:`jitter`: ``mean_j |p[t+3] - 3p[t+2] + 3p[t+1] - p[t]|`` of the prediction alone (T-3,),
  as GVHMR's ``compute_jitter`` before its ``fps**3 / 10``;
- :func:`foot_sliding`: the predicted displacement ``|p[t+1] - p[t]|`` of every foot point whose
  true displacement is below a threshold (in contact), as GVHMR's ``compute_foot_sliding``.

Whole-track metrics (GVHMR's ``compute_global_metrics``): :func:`first_frames_aligned_errors`
(W-MPJPE: per 100-frame chunk, a similarity fitted on the chunk's first two frames),
:func:`chunk_aligned_errors` (WA-MPJPE: fitted on the whole chunk) and :func:`rte` (root
trajectory error after a rigid fit over the whole track, over the true path length).

:class:`TrackSeries` accumulates the window metrics of many tracks frame by frame with bounded
memory (per track: sums, counts and the first and last three frames of the few points needed,
never meshes) and merges exactly across consecutive frame ranges (``rotavat batch`` evaluates a
sequence in chunks); with ``keep_all`` it also keeps every frame's points for the whole-track
metrics.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ._common import _pair
from ._kernels import _similarity

__all__ = ["WINDOWS", "CHUNK_FRAMES", "hips_relative", "second_differences", "accel_errors", "jitter", "foot_sliding", "first_frames_aligned_errors",
           "chunk_aligned_errors", "rte", "TrackSeries"]

# Frames per window of each window metric (accel: 3, jitter: 4, foot sliding: 2).
WINDOWS: dict[str, int] = {"accel": 3, "jitter": 4, "foot_sliding": 2}
_KEEP = max(WINDOWS.values()) - 1  # frames a window can reach back: the head and tail kept per track
CHUNK_FRAMES = 100  # GVHMR's chunk_length for W-MPJPE / WA-MPJPE


def _track(points: np.ndarray, name: str) -> np.ndarray:
    """``points`` as float64 (T, N, 3), else ValueError."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (T, N, 3), got {arr.shape}")
    return arr


def second_differences(points: np.ndarray) -> np.ndarray:
    """``p[t] - 2 p[t+1] + p[t+2]`` along the first axis (frames), metres/frame^2: (T, ...) -> (max(T-2, 0), ...).

    The acceleration of every point at frame ``t+1`` times the squared frame interval; float64.
    """
    p = np.asarray(points, dtype=np.float64)
    return p[:-2] - 2.0 * p[1:-1] + p[2:]


def accel_errors(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Acceleration error per window, metres/frame^2: (T, N, 3) x2 -> (max(T-2, 0),)."""
    p, g = _pair(pred, gt, "track")
    if p.shape[0] < 3:
        return np.zeros(0)
    acc = second_differences(p) - second_differences(g)
    return np.linalg.norm(acc, axis=-1).mean(axis=-1)


def jitter(points: np.ndarray) -> np.ndarray:
    """Jerk magnitude per window of one track, metres/frame^3: (T, N, 3) -> (max(T-3, 0),)."""
    p = _track(points, "points")
    if p.shape[0] < 4:
        return np.zeros(0)
    return np.linalg.norm(p[3:] - 3.0 * p[2:-1] + 3.0 * p[1:-2] - p[:-3], axis=-1).mean(axis=-1)


def foot_sliding(pred_feet: np.ndarray, gt_feet: np.ndarray, contact_m: float) -> np.ndarray:
    """Predicted foot displacement where the true foot is in contact, metres/frame: (T, F, 3) x2 -> (C,).

    Contact: the true point moved less than ``contact_m`` since the previous frame (GVHMR: 1 cm).
    One value per (frame pair, foot point) in contact, frame-major.
    """
    p, g = _pair(pred_feet, gt_feet, "feet")
    if p.shape[0] < 2:
        return np.zeros(0)
    contact = np.linalg.norm(g[1:] - g[:-1], axis=-1) < contact_m
    return np.linalg.norm(p[1:] - p[:-1], axis=-1)[contact]


def _fit(src: np.ndarray, dst: np.ndarray, with_scale: bool) -> tuple[float, np.ndarray, np.ndarray]:
    """Umeyama ``dst ≈ s R src + t`` over (N, 3) point sets: s (1 when not ``with_scale``), R (3, 3), t (3,)."""
    scale, rot, mu_src, mu_dst = _similarity(src[None], dst[None])
    s = float(scale[0]) if with_scale else 1.0
    return s, rot[0], mu_dst[0] - s * rot[0] @ mu_src[0]


def _aligned_errors(pred: np.ndarray, gt: np.ndarray, s: float, rot: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Mean point error per frame after ``s R pred + t``, metres: (T, N, 3) x2 -> (T,)."""
    return np.linalg.norm(s * pred @ rot.T + t - gt, axis=-1).mean(axis=-1)


def first_frames_aligned_errors(pred: np.ndarray, gt: np.ndarray, chunk: int = CHUNK_FRAMES) -> np.ndarray:
    """GVHMR's W-MPJPE per frame, metres: (T, J, 3) x2 -> (T,).

    Per chunk of ``chunk`` frames (the last may be shorter), one similarity fitted on the
    joints of the chunk's first two frames (``first_align_joints``) moves the whole chunk.
    """
    p, g = _pair(pred, gt, "track")
    out = []
    for start in range(0, p.shape[0], chunk):
        cp, cg = p[start:start + chunk], g[start:start + chunk]
        out.append(_aligned_errors(cp, cg, *_fit(cp[:2].reshape(-1, 3), cg[:2].reshape(-1, 3), True)))
    return np.concatenate(out) if out else np.zeros(0)


def chunk_aligned_errors(pred: np.ndarray, gt: np.ndarray, chunk: int = CHUNK_FRAMES) -> np.ndarray:
    """GVHMR's WA-MPJPE per frame, metres: one similarity per chunk fitted on all of its joints
    (``global_align_joints``): (T, J, 3) x2 -> (T,)."""
    p, g = _pair(pred, gt, "track")
    out = []
    for start in range(0, p.shape[0], chunk):
        cp, cg = p[start:start + chunk], g[start:start + chunk]
        out.append(_aligned_errors(cp, cg, *_fit(cp.reshape(-1, 3), cg.reshape(-1, 3), True)))
    return np.concatenate(out) if out else np.zeros(0)


def rte(pred_root: np.ndarray, gt_root: np.ndarray) -> np.ndarray:
    """Root translation error per frame over the true path length (a fraction): (T, 3) x2 -> (T,).

    A rigid fit (rotation and translation, no scale) of the whole predicted root trajectory onto
    the true one, then ``|gt - fitted pred| / sum_t |gt[t+1] - gt[t]|`` (GVHMR's ``compute_rte``).
    inf/NaN when the true root never moves (a path length of 0).
    """
    p, g = _pair(np.asarray(pred_root)[None], np.asarray(gt_root)[None], "root")
    p, g = p[0], g[0]
    if p.shape[0] == 0:
        return np.zeros(0)
    _, rot, t = _fit(p, g, False)
    path = np.linalg.norm(np.diff(g, axis=0), axis=-1).sum()
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.linalg.norm(g - (p @ rot.T + t), axis=-1) / path


# ---- streaming accumulation ------------------------------------------------------------------------


def hips_relative(joints: np.ndarray) -> np.ndarray:
    """Joints minus the midpoint of joints 1 and 2 (SMPL hips) of each frame: (T, J, 3) -> (T, J, 3) float64."""
    j = _track(joints, "joints")
    return j - 0.5 * (j[:, 1:2] + j[:, 2:3])


def _window_values(metric: str, items: Mapping[str, np.ndarray], contact_m: float, accel_hips: bool) -> np.ndarray:
    """Values of ``metric`` over every window of consecutive frames in ``items`` (T frames), metres/frame^k.

    items: 'pred', 'gt' (T, J, 3) joints; 'pred_feet', 'gt_feet' (T, F, 3) foot points (may be absent).
    accel_hips: the acceleration error of joints relative to the hips' midpoint (GVHMR's camera-frame
    accel), else of the joints as they are. Foot sliding gives one value per foot point in contact
    and frame pair, the others one value per window.
    """
    if metric == "accel":
        if accel_hips:
            return accel_errors(hips_relative(items["pred"]), hips_relative(items["gt"]))
        return accel_errors(items["pred"], items["gt"])
    if metric == "jitter":
        return jitter(items["pred"])
    return foot_sliding(items["pred_feet"], items["gt_feet"], contact_m)


_KEYS = {"accel": ("pred", "gt"), "jitter": ("pred",), "foot_sliding": ("pred_feet", "gt_feet")}  # what each reads


def _new_windows(metric: str, before: Mapping[str, np.ndarray], after: Mapping[str, np.ndarray],
                 contact_m: float, accel_hips: bool) -> np.ndarray:
    """Values of the windows that start in ``before`` (<= 3 frames) or later and end in ``after``."""
    n_before = len(before["pred"]) if before else 0
    joined = {k: np.concatenate([before[k], after[k]]) if before else after[k] for k in _KEYS[metric]}
    values = _window_values(metric, joined, contact_m, accel_hips)
    done = max(0, n_before - WINDOWS[metric] + 1)  # windows entirely inside ``before``: counted already
    if metric == "foot_sliding" and done:  # F values per frame pair, frame-major: drop whole frame pairs
        contact = np.linalg.norm(np.diff(joined["gt_feet"][:done + 1], axis=0), axis=-1) < contact_m
        return values[int(contact.sum()):]
    return values[done:]


@dataclass
class _Track:
    """One track's running sums, counts, its first and last ``_KEEP`` frames, and (optionally) every frame."""

    sums: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    head: dict[str, np.ndarray] = field(default_factory=dict)
    tail: dict[str, np.ndarray] = field(default_factory=dict)
    frames: list[dict[str, np.ndarray]] = field(default_factory=list)  # keep_all: every flushed block


@dataclass
class TrackSeries:
    """Window metrics of many tracks, fed one frame of matched pairs at a time; mergeable.

    metrics: names of :data:`WINDOWS` to accumulate; contact_m: the foot-contact threshold;
    keep_all: also keep every frame's points (for :func:`first_frames_aligned_errors`, ...);
    accel_hips: acceleration error of hips-relative joints (see :func:`_window_values`).
    Each frame's items (``add``) are (M, N, 3) arrays per key for its M matched pairs, with the
    pairs' track ids (M,). Buffered and processed per track in blocks (one numpy pass per track
    and block, not per frame).
    """

    metrics: tuple[str, ...]
    contact_m: float = 0.01
    keep_all: bool = False
    accel_hips: bool = False
    tracks: dict[int, _Track] = field(default_factory=dict)
    _pending: list[tuple[np.ndarray, dict[str, np.ndarray]]] = field(default_factory=list)
    _pending_pairs: int = 0

    FLUSH_PAIRS = 4096  # matched pairs buffered before a flush (~2 MB of 24-joint pairs in float64)

    def add(self, track_ids: np.ndarray, items: dict[str, np.ndarray]) -> None:
        """Queue one frame's matched pairs: track_ids (M,), items key -> (M, N, 3)."""
        if len(track_ids) == 0:
            return
        self._pending.append((np.asarray(track_ids, dtype=np.int64), items))
        self._pending_pairs += len(track_ids)
        if self._pending_pairs >= self.FLUSH_PAIRS:
            self.flush()

    def flush(self) -> None:
        """Fold the queued frames into the tracks, one vectorised pass per track."""
        if not self._pending:
            return
        ids = np.concatenate([ids for ids, _ in self._pending])
        keys = self._pending[0][1].keys()
        stacked = {k: np.concatenate([items[k] for _, items in self._pending]) for k in keys}
        self._pending, self._pending_pairs = [], 0
        order = np.argsort(ids, kind="stable")  # grouped by track, frame order kept inside a track
        uniq, starts = np.unique(ids[order], return_index=True)
        for track_id, rows in zip(uniq.tolist(), np.split(order, starts[1:])):
            self._extend(self.tracks.setdefault(track_id, _Track()), {k: v[rows] for k, v in stacked.items()})

    def _extend(self, track: _Track, new: dict[str, np.ndarray]) -> None:
        """Append frames ``new`` (T, ...) to ``track``: the windows they close, then head and tail."""
        for metric in self.metrics:
            values = _new_windows(metric, track.tail, new, self.contact_m, self.accel_hips)
            track.sums[metric] = track.sums.get(metric, 0.0) + float(values.sum())
            track.counts[metric] = track.counts.get(metric, 0) + int(values.size)
        _append_frames(track, new, self.keep_all)

    def merge(self, later: "TrackSeries") -> "TrackSeries":
        """These tracks followed by ``later``'s (the next frame range of the same sequences): a new series."""
        self.flush()
        later.flush()
        out = TrackSeries(self.metrics, self.contact_m, self.keep_all, self.accel_hips)
        for track_id, first in self.tracks.items():
            out.tracks[track_id] = _copy(first)
        for track_id, second in later.tracks.items():
            if track_id not in out.tracks:
                out.tracks[track_id] = _copy(second)
                continue
            track = out.tracks[track_id]
            for metric in self.metrics:  # the windows spanning the boundary: tail of the first, head of the second
                span = _new_windows(metric, track.tail, second.head, self.contact_m, self.accel_hips)
                inside_head = _window_values(metric, second.head, self.contact_m, self.accel_hips)
                track.sums[metric] = track.sums.get(metric, 0.0) + float(span.sum() - inside_head.sum()) \
                    + second.sums.get(metric, 0.0)
                track.counts[metric] = track.counts.get(metric, 0) + int(span.size - inside_head.size) \
                    + second.counts.get(metric, 0)
            head_n = len(track.head["pred"]) if track.head else 0
            if head_n < _KEEP:
                track.head = {k: np.concatenate([track.head[k], v])[:_KEEP] if track.head else v[:_KEEP]
                              for k, v in second.head.items()}
            track.tail = {k: np.concatenate([track.tail[k], v])[-_KEEP:] for k, v in second.tail.items()}
            track.frames = track.frames + second.frames
        return out

    def per_track(self, metric: str) -> dict[int, tuple[float, int]]:
        """Track id -> (sum, count) of ``metric``'s window values (metres/frame^k)."""
        self.flush()
        return {k: (t.sums.get(metric, 0.0), t.counts.get(metric, 0)) for k, t in self.tracks.items()}

    def frames_of(self, track_id: int) -> dict[str, np.ndarray]:
        """Every kept frame of one track (``keep_all``), key -> (T, N, 3)."""
        self.flush()
        blocks = self.tracks[track_id].frames
        return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]} if blocks else {}


def _append_frames(track: _Track, new: dict[str, np.ndarray], keep_all: bool) -> None:
    """Update a track's head (first frames), tail (last frames) and kept frames with ``new``."""
    head_n = len(track.head["pred"]) if track.head else 0
    if head_n < _KEEP:
        track.head = {k: (np.concatenate([track.head[k], v]) if track.head else v)[:_KEEP].copy()
                      for k, v in new.items()}
    track.tail = {k: (np.concatenate([track.tail[k], v]) if track.tail else v)[-_KEEP:].copy()
                  for k, v in new.items()}
    if keep_all:
        track.frames.append(new)


def _copy(track: _Track) -> _Track:
    """A shallow copy whose dicts and lists can be changed without touching ``track``."""
    return _Track(dict(track.sums), dict(track.counts), dict(track.head), dict(track.tail), list(track.frames))
