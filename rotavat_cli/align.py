"""RotAvat on frames and whole sequences: transformed frames, camera.yaml and a per-person table.

The output mirrors the input's form and keys (npz -> npz, obj -> obj); ``vertices`` and ``joints``
are transformed, every other key is copied through, float32 stays float32.
"""

from __future__ import annotations

import csv
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
from .rotavat import FLAGS, AlignTransform, apply_transforms, person_blocks, rotavat_transforms
from .sequence import Frame, Sequence, write_camera_yaml, write_frame, write_meta

__all__ = ["PEOPLE_COLUMNS", "AlignSummary", "align_frame", "track_statures", "align_sequence"]

PEOPLE_COLUMNS = (
    "frame", "person_id", "x_world_m", "z_world_m", "stature_m", "depth_scale", "rotation_deg",
    "final_scale", "drift_mean_px", "drift_max_px", "head_drift_px", "flag",
)


def _frame_transform(frame: Frame, camera: Camera, upright: str, stature_by_id: dict[int, float] | None) -> tuple[AlignTransform, np.ndarray, np.ndarray]:
    """Transforms for a frame's people plus their original feet/heads (P, 3)."""
    verts = frame.get("vertices")
    if verts is None:
        raise InputError(f"{frame.source}: align needs 'vertices' (meshes) in every frame with people")
    feet_cam, heads_cam = foot_head_points(verts)
    stature = None
    if stature_by_id is not None:
        stature = np.array([stature_by_id.get(int(i), np.nan) for i in frame.person_ids])
    return rotavat_transforms(feet_cam, heads_cam, camera.up_cam, camera.ground_offset_m, upright, stature), feet_cam, heads_cam


def _pixel_drift_px(before_cam: np.ndarray, after_cam: np.ndarray, focal_px: float) -> np.ndarray:
    """Image motion (P, V) in px of points (P, V, 3) that moved; float32 suffices for a report."""
    drift = np.empty(before_cam.shape[:2], dtype=np.float32)
    for block in person_blocks(before_cam.shape[0], before_cam.shape[1] * 4 * 8):
        a = np.asarray(before_cam[block], dtype=np.float32)
        b = np.asarray(after_cam[block], dtype=np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_a, inv_b = 1.0 / a[..., 2], 1.0 / b[..., 2]
            du = b[..., 0] * inv_b - a[..., 0] * inv_a
            dv = b[..., 1] * inv_b - a[..., 1] * inv_a
        drift[block] = np.hypot(du, dv)
    return np.float32(focal_px) * drift


def align_frame(frame: Frame, camera: Camera, upright: str = "paper",
                stature_by_id: dict[int, float] | None = None) -> tuple[Frame, dict[str, np.ndarray]]:
    """Align one frame: the new frame and per-person columns (see ``PEOPLE_COLUMNS``)."""
    P = frame.n_people
    if P == 0:
        return frame, {c: np.zeros(0) for c in PEOPLE_COLUMNS}
    transform, feet_cam, heads_cam = _frame_transform(frame, camera, upright, stature_by_id)
    verts = frame.data["vertices"]
    new_verts = apply_transforms(verts, transform, verts.dtype)
    arrays = {"vertices": new_verts}
    if frame.get("joints") is not None:
        arrays["joints"] = apply_transforms(frame.data["joints"], transform, frame.data["joints"].dtype)
    drift = _pixel_drift_px(verts, new_verts, camera.focal_px)  # (P, V)
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
        "drift_mean_px": np.nanmean(drift, axis=1) if drift.shape[1] else np.zeros(P),
        "drift_max_px": np.nanmax(drift, axis=1) if drift.shape[1] else np.zeros(P),
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


def _align_chunk(task: tuple) -> list[tuple[int, dict[str, np.ndarray]]]:
    """Read, align and write a few frames; per frame its people count and per-person columns."""
    seq, names, camera, out, upright, stature_by_id = task
    results = []
    for name in names:
        frame = seq.read_frame(name)
        new_frame, cols = align_frame(frame, camera, upright, stature_by_id)
        write_frame(out, new_frame, seq.form)
        results.append((frame.n_people, cols))
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
            writer = csv.writer(handle, lineterminator="\n")
            writer.writerow(PEOPLE_COLUMNS)
            for results in ordered_map(_align_chunk, tasks, workers, processes=True):
                for n_people, cols in results:
                    _write_rows(writer, cols)
                    summary.add(n_people, cols)
                    if progress:
                        progress()
        write_camera_yaml(stage / "camera.yaml", camera, camera_fit)
        if seq.meta:
            write_meta(stage, seq.meta)
    summary.finish()
    return summary


def _write_rows(writer: "csv._writer", cols: dict[str, np.ndarray]) -> None:
    """Write a frame's per-person columns, floats with 6 significant digits, NaN as empty."""
    n = len(cols["frame"])
    for i in range(n):  # one row per person: a loop over people is I/O here, not numerics
        writer.writerow([_cell(cols[c][i]) for c in PEOPLE_COLUMNS])


def _cell(value: object) -> str:
    """CSV cell text."""
    if isinstance(value, (float, np.floating)):
        return "" if not np.isfinite(value) else f"{float(value):.6g}"
    return str(value)

