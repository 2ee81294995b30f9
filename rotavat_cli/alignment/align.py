"""RotAvat on frames and whole sequences: transformed frames, camera.yaml and a per-person table.

The output mirrors the input's form and keys (npz -> npz, obj -> obj); ``vertices`` and ``joints``
are transformed, every other key is copied through, float32 stays float32. A frame without meshes
is aligned at joint level: its joints with the mid-sole and crown pixels of its ``feet_2d`` and
``heads_2d`` (:func:`frame_foot_head_cam`).

The meshes of the input were made with the focal its HPS method assumed (per frame or per
person); the output lives in the camera (the calibrated or given one) and says so: its frames'
``focal_length``/``K``/``principal_point`` and its meta.yaml are the camera's, with
``focal_kind: camera``. Each person keeps the foot and crown pixels the method drew
(:func:`rotavat_cli.alignment.transform.method_rays_cam`).
"""

from __future__ import annotations

import csv
import io
import warnings
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..atomic import atomic_open, staged_directory
from ..camera import Camera, project_cam_to_px
from ..errors import InputError
from ..frame_points import MeshIntrinsics, frame_foot_head_cam
from ..focal import CAMERA
from ..outputs import check_output_dir
from ..parallel import cap_workers, ordered_map
from ..plain import csv_cell
from ..posture import POSTURES, postures
from ..sequence import Frame, Intrinsics, Sequence, write_camera_yaml, write_frame, write_meta
from .options import AlignOptions
from .transform import (FLAGS, AlignTransform, apply_transforms, method_rays_cam, points_from_coords,
                        rotavat_transforms, transformed_blocks)

__all__ = ["PEOPLE_COLUMNS", "IMPLAUSIBLE_STATURE", "NOT_STANDING", "ALIGNED_FLAGS", "AlignSummary",
           "align_frame", "track_statures", "align_sequence", "summarize_people_csv"]

PEOPLE_COLUMNS = (
    "frame", "person_id", "x_world_m", "z_world_m", "stature_m", "depth_scale", "rotation_deg",
    "final_scale", "mesh_focal_px", "drift_mean_px", "drift_max_px", "head_drift_px", "flag",
)
IMPLAUSIBLE_STATURE = "implausible_stature"  # aligned, but the stature is outside the plausible range (AlignOptions)
# Aligned, but the joints say the person does not stand (rotavat_cli.posture): a sitting body has no stature.
NOT_STANDING = tuple(name for name in POSTURES if name not in ("standing", "unknown"))
ALIGNED_FLAGS = ("", IMPLAUSIBLE_STATURE, *NOT_STANDING)  # flags of people that were transformed


def _frame_transform(frame: Frame, camera: Camera, upright: str, stature_by_id: dict[int, float] | None,
                     mesh: MeshIntrinsics) -> tuple[AlignTransform, np.ndarray, np.ndarray]:
    """Transforms for a frame's people plus their original feet/heads (P, 3)."""
    feet_cam, heads_cam = frame_foot_head_cam(frame, mesh)
    stature = None
    if stature_by_id is not None:
        stature = np.array([stature_by_id.get(int(i), np.nan) for i in frame.person_ids])
    rays = (None, None)
    if not mesh.same_as(camera):
        rays = tuple(method_rays_cam(points, mesh.focal_px, mesh.principal_point, camera.focal_px,
                                     camera.principal_point) for points in (feet_cam, heads_cam))
    transform = rotavat_transforms(feet_cam, heads_cam, camera.up_cam, camera.ground_offset_m, upright, stature, *rays)
    return transform, feet_cam, heads_cam


def _pixel_drift_px(before_cam: np.ndarray, after_cam: np.ndarray, mesh_focal_px: np.ndarray, focal_px: float,
                    pp_shift_px: np.ndarray) -> np.ndarray:
    """Image motion (p, N) in px of points that moved, given coordinates first (p, 3, N); float32 suffices.

    Before: the pixels the method drew (its focal per person, (p,)); after: the camera's pixels
    (``focal_px``); pp_shift_px (2,): the camera's principal point minus the method's.
    """
    a = np.asarray(before_cam, dtype=np.float32)
    b = np.asarray(after_cam, dtype=np.float32)
    fa = np.asarray(mesh_focal_px, dtype=np.float32)[:, None]
    fb = np.float32(focal_px)
    shift = np.asarray(pp_shift_px, dtype=np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_a, inv_b = fa / a[:, 2], fb / b[:, 2]
        du = b[:, 0] * inv_b
        du -= a[:, 0] * inv_a
        dv = b[:, 1] * inv_b
        dv -= a[:, 1] * inv_a
    if shift.any():  # the camera's principal point is not the method's
        du += shift[0]
        dv += shift[1]
    return _hypot_f32(du, dv)


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


def _align_points(verts_cam: np.ndarray, transform: AlignTransform, mesh: MeshIntrinsics,
                  camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Transformed points (P, V, 3) (vertices, or joints) in their dtype, and each person's mean and max drift (P,) in px.

    A block of people's drift is measured on the values written, right after they are computed,
    while both are in cache (:func:`transformed_blocks`); NaN drifts are ignored; 0 if V == 0.
    """
    P, V = verts_cam.shape[:2]
    dtype = output_dtype(verts_cam)
    if V == 0:
        return verts_cam.astype(dtype), np.zeros(P), np.zeros(P)
    moved, means, peaks = [], [], []
    shift = np.subtract(camera.principal_point, mesh.principal_point)
    start = 0
    for before, after in transformed_blocks(verts_cam, transform, dtype):  # (p, 3, V) each
        focal = mesh.focal_px[start:start + len(before)]
        start += len(before)
        mean, peak = _nan_mean_max(_pixel_drift_px(before, after, focal, camera.focal_px, shift))
        moved.append(after)
        means.append(mean)
        peaks.append(peak)
    return points_from_coords(moved, V, dtype), np.concatenate(means), np.concatenate(peaks)


def output_dtype(points: np.ndarray) -> np.dtype:
    """Aligned coordinates keep a float dtype; integer coordinates become float64 (never rounded back)."""
    return points.dtype if points.dtype.kind == "f" else np.dtype(np.float64)


def align_frame(frame: Frame, camera: Camera, options: AlignOptions | None = None,
                stature_by_id: dict[int, float] | None = None,
                intrinsics: Intrinsics | None = None,
                joints_layout: str | None = None) -> tuple[Frame, dict[str, np.ndarray]]:
    """Align one frame into ``camera``: the new frame and per-person columns (see ``PEOPLE_COLUMNS``).

    options: ``upright`` and ``stature_range_m`` are read (default :class:`AlignOptions`);
    stature_by_id: per person_id stature to keep (``height_from: track``, :func:`track_statures`);
    intrinsics: what the frame's meshes were made with (``Sequence.frame_intrinsics``; None: the
    frame's own keys); what is not stated is the camera's own; joints_layout: the layout of the
    frame's ``joints`` (``Sequence.joints_layout``; None: SMPL's by count). People aligned to a
    stature outside ``options.stature_range_m`` are flagged ``implausible_stature``, people whose
    joints say they sit, kneel or bend by their posture (``sitting``, ...); both are still aligned.
    """
    options = AlignOptions() if options is None else options
    upright, stature_range_m = options.upright, options.stature_range_m
    intrinsics = frame.intrinsics if intrinsics is None else intrinsics
    P = frame.n_people
    if P == 0:
        return _in_camera(frame, camera), {c: np.zeros(0) for c in PEOPLE_COLUMNS}
    mesh = MeshIntrinsics.of_frame(frame, intrinsics, camera)
    transform, feet_cam, heads_cam = _frame_transform(frame, camera, upright, stature_by_id, mesh)
    if frame.get("vertices") is not None:
        new_verts, drift_mean, drift_max = _align_points(frame.data["vertices"], transform, mesh, camera)
        arrays = {"vertices": new_verts}
        if frame.get("joints") is not None:
            arrays["joints"] = apply_transforms(frame.data["joints"], transform, output_dtype(frame.data["joints"]))
    else:  # joint-level alignment: the joints are the points, and their drift is measured
        new_joints, drift_mean, drift_max = _align_points(frame.data["joints"], transform, mesh, camera)
        arrays = {"joints": new_joints}
    new_heads = apply_transforms(heads_cam[:, None], transform)[:, 0]
    heads_drawn_px = project_cam_to_px(heads_cam, mesh.focal_px, mesh.principal_point)
    foot_world = camera.world_from_cam(transform.pivot_cam)
    ok = transform.ok
    flags = np.array([FLAGS[int(c)] for c in transform.flag], dtype=object)
    with np.errstate(invalid="ignore"):
        implausible = ok & ((transform.stature_m < stature_range_m[0]) | (transform.stature_m > stature_range_m[1]))
    flags[implausible] = IMPLAUSIBLE_STATURE
    posture = None if frame.get("joints") is None else postures(frame.data["joints"], joints_layout)
    if posture is not None:
        seated = ok & np.isin(posture, NOT_STANDING)
        flags[seated] = posture[seated]
    columns = {
        "frame": np.full(P, frame.name, dtype=object),
        "person_id": frame.person_ids,
        "x_world_m": np.where(ok, foot_world[:, 0], np.nan),
        "z_world_m": np.where(ok, foot_world[:, 2], np.nan),
        "stature_m": transform.stature_m,
        "depth_scale": transform.depth_scale,
        "rotation_deg": transform.rotation_deg,
        "final_scale": transform.final_scale,
        "mesh_focal_px": mesh.focal_px,
        "drift_mean_px": drift_mean,
        "drift_max_px": drift_max,
        "head_drift_px": np.linalg.norm(camera.project(new_heads) - heads_drawn_px, axis=-1),
        "flag": flags,
    }
    return _in_camera(frame.replace(**arrays), camera), columns


_INTRINSIC_KEYS = ("focal_length", "K", "principal_point")


def _in_camera(frame: Frame, camera: Camera) -> Frame:
    """The frame's own intrinsics keys (if any) replaced by the camera's: its meshes now live in it."""
    stated = {key: frame.data[key] for key in _INTRINSIC_KEYS if key in frame.data}
    if not stated:
        return frame
    values = {"focal_length": np.float64(camera.focal_px), "K": np.asarray(camera.K, dtype=np.float64),
              "principal_point": np.asarray(camera.principal_point, dtype=np.float64)}
    return frame.replace(**{key: values[key] for key in stated})


def aligned_meta(meta: dict, camera: Camera) -> dict:
    """meta.yaml of an aligned sequence: the camera's intrinsics, ``focal_kind: camera``, the input's in ``aligned_from``."""
    out = {k: v for k, v in meta.items() if k not in ("focal_length", "K", "principal_point", "focal_kind", "focal_rule")}
    out.update({"image_size": [int(v) for v in camera.image_size], "focal_length": float(camera.focal_px),
                "principal_point": [float(v) for v in camera.principal_point], "focal_kind": CAMERA})
    out["aligned_from"] = {k: meta.get(k) for k in ("focal_length", "focal_kind", "focal_rule") if meta.get(k) is not None}
    return out


def track_statures(seq: Sequence, camera: Camera, upright: str = "paper") -> dict[int, float]:
    """Median RotAvat stature per ``person_id`` over the sequence (one landmark pass, no writing)."""
    samples: dict[int, list[float]] = defaultdict(list)
    for frame in seq.frames():
        if frame.n_people == 0:
            continue
        if frame.get("person_ids") is None:
            raise InputError(f"{frame.source}: --height-from track needs 'person_ids' (track ids) in every frame")
        mesh = MeshIntrinsics.of_frame(frame, seq.frame_intrinsics(frame), camera)
        transform, _, _ = _frame_transform(frame, camera, upright, None, mesh)
        for pid, stature in zip(frame.person_ids, transform.stature_m):
            if np.isfinite(stature):
                samples[int(pid)].append(float(stature))
    return {pid: float(np.median(values)) for pid, values in samples.items()}


_CHUNK_FRAMES = 8  # frames per worker task: amortises task overhead, keeps memory bounded


def _align_chunk(task: tuple) -> tuple[list[tuple[int, dict[str, np.ndarray], str]], object]:
    """Read, align and write a few frames: per frame its people count, columns and people.csv rows; and
    what reading them found (``Sequence.frame_notes``: an imported sequence's warnings, from a worker)."""
    seq, names, camera, out, options, stature_by_id = task
    results = []
    for name in names:
        frame = seq.read_frame(name)
        seq.require_static_frame(frame, camera.image_size)
        new_frame, cols = align_frame(frame, camera, options, stature_by_id, seq.frame_intrinsics(frame),
                                      seq.joints_layout)
        write_frame(out, new_frame, seq.form)
        results.append((frame.n_people, cols, _csv_rows(cols)))
    return results, seq.frame_notes(names)


_SUMMARY_COLUMNS = ("depth_scale", "rotation_deg", "stature_m", "head_drift_px", "drift_mean_px", "drift_max_px")


@dataclass
class AlignSummary:
    """What ``align_sequence`` did (``add`` per frame, then ``finish``).

    ``aligned`` counts the people that were transformed (``implausible`` of them with a stature
    outside the plausible range, ``not_standing`` of them sitting, kneeling or bending); ``flagged``
    counts every flag, including those. The medians are over the aligned people who stand.
    """

    out: Path
    frames: int = 0
    people: int = 0
    aligned: int = 0
    implausible: int = 0
    not_standing: int = 0
    flagged: dict[str, int] = field(default_factory=dict)
    median_depth_scale: float = float("nan")
    median_abs_depth_change_pct: float = float("nan")
    median_rotation_deg: float = float("nan")
    median_stature_m: float = float("nan")
    median_drift_px: float = float("nan")  # median over people of their mean vertex motion in the picture
    max_drift_px: float = float("nan")  # the largest motion of any vertex (foot and crown stay: 0)
    max_head_drift_px: float = 0.0
    _aligned_columns: list[dict[str, np.ndarray]] = field(default_factory=list, repr=False)

    def add(self, n_people: int, cols: dict[str, np.ndarray]) -> None:
        """Count one frame's people and keep the aligned people's factors."""
        flag = np.asarray(cols["flag"], dtype=object)
        ok = (flag == "") | (flag == IMPLAUSIBLE_STATURE)  # aligned and standing: the medians
        seated = np.isin(flag, NOT_STANDING)
        self.frames += 1
        self.people += n_people
        self.aligned += int(ok.sum() + seated.sum())
        self.implausible += int((flag == IMPLAUSIBLE_STATURE).sum())
        self.not_standing += int(seated.sum())
        for name in flag[flag != ""]:
            self.flagged[str(name)] = self.flagged.get(str(name), 0) + 1
        self._aligned_columns.append({k: np.asarray(cols[k], dtype=np.float64)[ok]
                                      for k in _SUMMARY_COLUMNS})

    def finish(self) -> None:
        """Medians over every aligned person who stands (small: four floats per person)."""
        if not self._aligned_columns or not sum(len(c["stature_m"]) for c in self._aligned_columns):
            self._aligned_columns.clear()
            return
        col = {k: np.concatenate([c[k] for c in self._aligned_columns]) for k in self._aligned_columns[0]}
        self.median_depth_scale = float(np.median(col["depth_scale"]))
        self.median_abs_depth_change_pct = float(np.median(np.abs(col["depth_scale"] - 1.0)) * 100.0)
        self.median_rotation_deg = float(np.median(np.abs(col["rotation_deg"])))
        self.median_stature_m = float(np.median(col["stature_m"]))
        self.max_head_drift_px = float(np.nanmax(col["head_drift_px"]))
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN drift columns stay NaN
            self.median_drift_px = float(np.nanmedian(col["drift_mean_px"]))
            self.max_drift_px = float(np.nanmax(col["drift_max_px"]))
        self._aligned_columns.clear()


def summarize_people_csv(people_csv: str | Path) -> AlignSummary:
    """The :class:`AlignSummary` of a written people.csv (same numbers as the run that wrote it)."""
    people_csv = Path(people_csv)
    summary = AlignSummary(people_csv.parent)
    with open(people_csv, encoding="utf-8", newline="") as handle:
        rows = list(csv.DictReader(handle))
    for frame, group in _group_rows(rows):
        cols = {"flag": np.array([r["flag"] for r in group], dtype=object)}
        for key in _SUMMARY_COLUMNS:
            cols[key] = np.array([float(r[key]) if r[key] else np.nan for r in group])
        summary.add(len(group), cols)
    summary.finish()
    return summary


def _group_rows(rows: list[dict]) -> list[tuple[str, list[dict]]]:
    """people.csv rows grouped by consecutive frame name."""
    groups: list[tuple[str, list[dict]]] = []
    for row in rows:
        if not groups or groups[-1][0] != row["frame"]:
            groups.append((row["frame"], []))
        groups[-1][1].append(row)
    return groups


def align_sequence(seq: Sequence, camera: Camera, out: str | Path, options: AlignOptions | None = None, *,
                   camera_fit: dict | None = None, progress: Callable[[], None] | None = None,
                   force: bool = False) -> AlignSummary:
    """Align every frame of ``seq`` into ``out`` (mirrored form) with camera.yaml and people.csv.

    Frames stream through ``options.jobs`` processes (0: one per core; never more than the cores or
    the chunks of frames), a bounded window ahead of the in-order writer of people.csv, so memory
    stays flat and every core works (``jobs=1``: in this process). ``camera_fit`` is written as
    camera.yaml's fit block. ``out`` is replaced only when it is rotavat's own output or empty
    (``force``: any folder that is not and does not hold an input;
    :func:`rotavat_cli.outputs.check_output_dir`).
    """
    options = AlignOptions() if options is None else options
    out = Path(out)
    check_output_dir(out, [seq.path], force)
    upright = options.upright
    stature_by_id = track_statures(seq, camera, upright) if options.height_from == "track" else None
    summary = AlignSummary(out)
    names = seq.frame_names
    chunks = [names[i:i + _CHUNK_FRAMES] for i in range(0, len(names), _CHUNK_FRAMES)]
    with staged_directory(out, "align") as stage:
        tasks = ((seq, chunk, camera, stage, options, stature_by_id) for chunk in chunks)
        with atomic_open(stage / "people.csv", "w") as handle:
            csv.writer(handle, lineterminator="\n").writerow(PEOPLE_COLUMNS)
            for results, notes in ordered_map(_align_chunk, tasks, cap_workers(options.jobs, len(chunks)), processes=True):
                seq.add_frame_notes(notes)
                for n_people, cols, rows in results:
                    handle.write(rows)
                    summary.add(n_people, cols)
                    if progress:
                        progress()
        write_camera_yaml(stage / "camera.yaml", camera, camera_fit)
        write_meta(stage, aligned_meta(seq.meta, camera))
    summary.finish()
    return summary


def _csv_rows(cols: dict[str, np.ndarray]) -> str:
    """A frame's people.csv rows (one per person), floats with 6 significant digits, NaN as empty."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(zip(*(_cells(cols[c]) for c in PEOPLE_COLUMNS)))
    return buffer.getvalue()


def _cells(column: np.ndarray) -> list[str]:
    """CSV cells of one column (P,): a loop over people is formatting here, not numerics."""
    return [csv_cell(v) for v in column.tolist()]
