"""RotAvat on frames and whole sequences: transformed frames, camera.yaml and a per-person table.

The output mirrors the input's form and keys (npz -> npz, obj -> obj); ``vertices`` and ``joints``
are transformed, every other key is copied through, float32 stays float32.
"""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import atomic_open, staged_directory
from .parallel import ordered_map
from .camera import Camera
from .errors import InputError
from .landmarks import foot_head_points
from .rotavat import FLAGS, AlignTransform, apply_transforms, points_from_coords, rotavat_transforms, transformed_blocks
from .sequence import Frame, Sequence, write_camera_yaml, write_frame, write_meta

__all__ = ["PEOPLE_COLUMNS", "AlignSummary", "align_frame", "track_statures", "align_sequence"]

PEOPLE_COLUMNS = (
    "frame", "person_id", "x_world_m", "z_world_m", "stature_m", "depth_scale", "rotation_deg",
    "final_scale", "drift_mean_px", "drift_max_px", "head_drift_px", "flag",
)


def _frame_transform(frame: Frame, camera: Camera, upright: str,
                     stature_by_id: dict[int, float] | None) -> tuple[AlignTransform, np.ndarray, np.ndarray]:
    """Transforms for a frame's people plus their original feet/heads (P, 3)."""
    verts = frame.get("vertices")
    if verts is None:
        raise InputError(f"{frame.source}: align needs 'vertices' (meshes) in every frame with people")
    feet_cam, heads_cam = foot_head_points(verts)
    stature = None
    if stature_by_id is not None:
        stature = np.array([stature_by_id.get(int(i), np.nan) for i in frame.person_ids])
    transform = rotavat_transforms(feet_cam, heads_cam, camera.up_cam, camera.ground_offset_m, upright, stature)
    return transform, feet_cam, heads_cam


def _pixel_drift_px(before_cam: np.ndarray, after_cam: np.ndarray, focal_px: float) -> np.ndarray:
    """Image motion (p, N) in px of points that moved, given coordinates first (p, 3, N); float32 suffices."""
    a = np.asarray(before_cam, dtype=np.float32)
    b = np.asarray(after_cam, dtype=np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_a, inv_b = 1.0 / a[:, 2], 1.0 / b[:, 2]
        du = b[:, 0] * inv_b - a[:, 0] * inv_a
        dv = b[:, 1] * inv_b - a[:, 1] * inv_a
    return np.float32(focal_px) * _hypot_f32(du, dv)


def _hypot_f32(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``np.hypot`` of float32 arrays (...,) -> float32 (...,), bit for bit, several times faster.

    A float32 value squared is exact in float64, so the sum of squares rounded once, its root and
    one rounding to float32 is what glibc's ``hypotf`` (hence ``np.hypot`` on Linux) computes.
    As in ``hypot``, an infinite side gives inf even when the other one is NaN.
    """
    squares = np.square(x, dtype=np.float64)
    squares += np.square(y, dtype=np.float64)
    length = np.sqrt(squares, out=squares).astype(np.float32)
    if np.isnan(length).any():
        length[np.isinf(x) | np.isinf(y)] = np.inf
    return length


def _nan_mean_max(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row means and maxima (p,) of (p, V) ignoring NaN, as ``np.nanmean``/``np.nanmax``.

    Without NaN the plain reductions give the same numbers (same pairwise sums, one correctly
    rounded division) for a fraction of the passes; a row with NaN takes the nan-aware ones.
    """
    mean = values.mean(axis=1)
    if np.isnan(mean).any():
        return np.nanmean(values, axis=1), np.nanmax(values, axis=1)
    return mean, values.max(axis=1)


def _align_points(verts_cam: np.ndarray, transform: AlignTransform,
                  focal_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Transformed vertices (P, V, 3) in their dtype, and each person's mean and max drift (P,) in px.

    A block of people's drift is measured on the values written, right after they are computed,
    while both are in cache (:func:`transformed_blocks`); NaN drifts are ignored; 0 if V == 0.
    """
    P, V = verts_cam.shape[:2]
    if V == 0:
        return verts_cam.copy(), np.zeros(P), np.zeros(P)
    moved, means, peaks = [], [], []
    for before, after in transformed_blocks(verts_cam, transform, verts_cam.dtype):  # (p, 3, V) each
        mean, peak = _nan_mean_max(_pixel_drift_px(before, after, focal_px))
        moved.append(after)
        means.append(mean)
        peaks.append(peak)
    return points_from_coords(moved, V, verts_cam.dtype), np.concatenate(means), np.concatenate(peaks)


def align_frame(frame: Frame, camera: Camera, upright: str = "paper",
                stature_by_id: dict[int, float] | None = None) -> tuple[Frame, dict[str, np.ndarray]]:
    """Align one frame: the new frame and per-person columns (see ``PEOPLE_COLUMNS``)."""
    P = frame.n_people
    if P == 0:
        return frame, {c: np.zeros(0) for c in PEOPLE_COLUMNS}
    transform, feet_cam, heads_cam = _frame_transform(frame, camera, upright, stature_by_id)
    verts = frame.data["vertices"]
    new_verts, drift_mean, drift_max = _align_points(verts, transform, camera.focal_px)
    arrays = {"vertices": new_verts}
    if frame.get("joints") is not None:
        arrays["joints"] = apply_transforms(frame.data["joints"], transform, frame.data["joints"].dtype)
    new_heads = apply_transforms(heads_cam[:, None], transform)[:, 0]
    foot_world = camera.world_from_cam(transform.pivot_cam)
    ok = transform.ok
    columns = {
        "frame": np.full(P, frame.name, dtype=object),
        "person_id": frame.person_ids,
        "x_world_m": np.where(ok, foot_world[:, 0], np.nan),
        "z_world_m": np.where(ok, foot_world[:, 2], np.nan),
        "stature_m": transform.stature_m,
        "depth_scale": transform.depth_scale,
        "rotation_deg": transform.rotation_deg,
        "final_scale": transform.final_scale,
        "drift_mean_px": drift_mean,
        "drift_max_px": drift_max,
        "head_drift_px": np.linalg.norm(camera.project(new_heads) - camera.project(heads_cam), axis=-1),
        "flag": np.array([FLAGS[int(c)] for c in transform.flag], dtype=object),
    }
    return frame.replace(**arrays), columns


def track_statures(seq: Sequence, camera: Camera, upright: str = "paper") -> dict[int, float]:
    """Median RotAvat stature per ``person_id`` over the sequence (one landmark pass, no writing)."""
    samples: dict[int, list[float]] = defaultdict(list)
    for frame in seq.frames():
        if frame.n_people == 0:
            continue
        if frame.get("person_ids") is None:
            raise InputError(f"{frame.source}: --height-from track needs 'person_ids' (track ids) in every frame")
        transform, _, _ = _frame_transform(frame, camera, upright, None)
        for pid, stature in zip(frame.person_ids, transform.stature_m):
            if np.isfinite(stature):
                samples[int(pid)].append(float(stature))
    return {pid: float(np.median(values)) for pid, values in samples.items()}


_CHUNK_FRAMES = 8  # frames per worker task: amortises task overhead, keeps memory bounded


def _align_chunk(task: tuple) -> list[tuple[int, dict[str, np.ndarray], str]]:
    """Read, align and write a few frames; per frame its people count, columns and people.csv rows."""
    seq, names, camera, out, upright, stature_by_id = task
    results = []
    for name in names:
        frame = seq.read_frame(name)
        new_frame, cols = align_frame(frame, camera, upright, stature_by_id)
        write_frame(out, new_frame, seq.form)
        results.append((frame.n_people, cols, _csv_rows(cols)))
    return results


@dataclass
class AlignSummary:
    """What ``align_sequence`` did (``add`` per frame, then ``finish``)."""

    out: Path
    frames: int = 0
    people: int = 0
    aligned: int = 0
    flagged: dict[str, int] = field(default_factory=dict)
    median_depth_scale: float = float("nan")
    median_abs_depth_change_pct: float = float("nan")
    median_rotation_deg: float = float("nan")
    median_stature_m: float = float("nan")
    max_head_drift_px: float = 0.0
    _aligned_columns: list[dict[str, np.ndarray]] = field(default_factory=list, repr=False)

    def add(self, n_people: int, cols: dict[str, np.ndarray]) -> None:
        """Count one frame's people and keep the aligned people's factors."""
        ok = cols["flag"] == ""
        self.frames += 1
        self.people += n_people
        self.aligned += int(ok.sum())
        for name in cols["flag"][~ok]:
            self.flagged[str(name)] = self.flagged.get(str(name), 0) + 1
        self._aligned_columns.append({k: cols[k][ok] for k in ("depth_scale", "rotation_deg", "stature_m", "head_drift_px")})

    def finish(self) -> None:
        """Medians over every aligned person (small: four floats per person)."""
        if not self.aligned:
            return
        col = {k: np.concatenate([c[k] for c in self._aligned_columns]) for k in self._aligned_columns[0]}
        self.median_depth_scale = float(np.median(col["depth_scale"]))
        self.median_abs_depth_change_pct = float(np.median(np.abs(col["depth_scale"] - 1.0)) * 100.0)
        self.median_rotation_deg = float(np.median(np.abs(col["rotation_deg"])))
        self.median_stature_m = float(np.median(col["stature_m"]))
        self.max_head_drift_px = float(np.max(col["head_drift_px"]))
        self._aligned_columns.clear()


def align_sequence(seq: Sequence, camera: Camera, out: str | Path, upright: str = "paper", height_from: str = "frame",
                   camera_fit: dict | None = None, progress: Callable[[], None] | None = None,
                   workers: int = 2) -> AlignSummary:
    """Align every frame of ``seq`` into ``out`` (mirrored form) with camera.yaml and people.csv.

    Frames stream through ``workers`` processes, a bounded window ahead of the in-order writer of
    people.csv, so memory stays flat and both cores work (``workers=1``: in this process).
    """
    out = Path(out)
    if out.resolve() == seq.path.resolve():
        raise InputError(f"{out}: the output directory must differ from the input sequence")
    if height_from not in ("frame", "track"):
        raise InputError(f"height_from must be 'frame' or 'track', got {height_from!r}")
    if upright not in ("paper", "full"):
        raise InputError(f"upright must be 'paper' or 'full', got {upright!r}")
    stature_by_id = track_statures(seq, camera, upright) if height_from == "track" else None
    summary = AlignSummary(out)
    names = seq.frame_names
    chunks = [names[i:i + _CHUNK_FRAMES] for i in range(0, len(names), _CHUNK_FRAMES)]
    with staged_directory(out) as stage:
        tasks = ((seq, chunk, camera, stage, upright, stature_by_id) for chunk in chunks)
        with atomic_open(stage / "people.csv", "w") as handle:
            csv.writer(handle, lineterminator="\n").writerow(PEOPLE_COLUMNS)
            for results in ordered_map(_align_chunk, tasks, workers, processes=True):
                for n_people, cols, rows in results:
                    handle.write(rows)
                    summary.add(n_people, cols)
                    if progress:
                        progress()
        write_camera_yaml(stage / "camera.yaml", camera, camera_fit)
        if seq.meta:
            write_meta(stage, seq.meta)
    summary.finish()
    return summary


def _csv_rows(cols: dict[str, np.ndarray]) -> str:
    """A frame's people.csv rows (one per person), floats with 6 significant digits, NaN as empty."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(zip(*(_cells(cols[c]) for c in PEOPLE_COLUMNS)))
    return buffer.getvalue()


def _cells(column: np.ndarray) -> list[str]:
    """CSV cells of one column (P,): a loop over people is formatting here, not numerics."""
    values = column.tolist()
    if column.dtype.kind == "f":
        return ["" if not math.isfinite(v) else f"{v:.6g}" for v in values]
    return [str(v) for v in values]
