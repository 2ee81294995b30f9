"""RotAvat on frames and whole sequences: transformed frames, camera.yaml and a per-person table.

The output mirrors the input's form and keys (npz -> npz, obj -> obj); ``vertices`` and ``joints``
are transformed, every other key is copied through, float32 stays float32. A frame without meshes
is aligned at joint level: its joints with the foot and crown pixels of its ``feet_2d`` and
``heads_2d`` (:func:`frame_foot_head_cam`).

Each person's foot point (the ground contact: on the lower sole's level) goes on the ground, except
a tracked person in the air: after the frames are written, each track's frames are checked for
flight (:mod:`.flight`: the foot's elevation that the track's stature and the foot and crown pixels
imply, against the track's own noise); a run of airborne frames is flagged ``flight`` and those
frames are aligned again with the foot at its elevation (read, aligned and written a second time:
only frames with someone in flight).

The meshes of the input were made with the focal its HPS method assumed (per frame or per
person); the output lives in the camera (the calibrated or given one) and says so: its frames'
``focal_length``/``K``/``principal_point`` and its meta.yaml are the camera's, with
``focal_kind: camera``. Each person keeps the foot and crown pixels the method drew
(:func:`rotavat_cli.alignment.transform.method_rays_cam`).

A camera with a lens (camera.yaml's ``distortion``): the method drew its people in the (distorted)
image with its own pinhole, so each person's foot and crown rays are the camera's rays through
those pixels, the lens removed (:meth:`rotavat_cli.geometry.camera.Camera.pixel_rays_cam`), and
the drifts are measured in the image (:meth:`~rotavat_cli.geometry.camera.Camera.project`). The
body itself stays rigid: only its foot and crown pixels are kept exactly; its other points move
with the lens's local stretch (a pinhole mesh cannot bend). The output frames'
``focal_length``/``K``/``principal_point`` are the camera's pinhole; the lens is in the output's
camera.yaml (``distortion``) only.
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

from ..files.atomic import atomic_open, staged_directory
from ..geometry.camera import Camera, project_cam_to_px
from ..errors import InputError
from ..bodies.frame_points import MeshIntrinsics, frame_foot_head_cam, in_view
from ..geometry.focal import CAMERA
from ..files.outputs import check_output_dir
from ..bodies.measure import scale_source
from ..parallel import cap_workers, ordered_map
from ..plain import csv_cell
from ..bodies.posture import POSTURES, postures
from ..sequence import Frame, Intrinsics, Sequence, write_camera_yaml, write_frame, write_meta
from .flight import TrackRows, flight_rows
from .options import AlignOptions
from .body_params import aligned_body_params
from .transform import (FLAGS, AlignTransform, apply_transforms, method_rays_cam, points_from_coords,
                        rotavat_transforms, transformed_blocks)

__all__ = ["PEOPLE_COLUMNS", "IMPLAUSIBLE_STATURE", "NOT_STANDING", "FLIGHT", "ALIGNED_FLAGS", "AlignSummary",
           "align_frame", "track_statures", "flight_plan", "align_sequence", "summarize_people_csv"]

PEOPLE_COLUMNS = (
    "frame", "person_id", "x_world_m", "z_world_m", "foot_height_m", "stature_m", "depth_scale", "rotation_deg",
    "final_scale", "mesh_focal_px", "drift_mean_px", "drift_max_px", "head_drift_px", "flag", "stature_from",
)
IMPLAUSIBLE_STATURE = "implausible_stature"  # aligned, but the stature is outside the plausible range (AlignOptions)
# Aligned, but the joints say the person does not stand (rotavat_cli.bodies.posture): a sitting body has no stature.
NOT_STANDING = tuple(name for name in POSTURES if name not in ("standing", "unknown"))
CUT_BY_BORDER = FLAGS[5]  # left unchanged: the image border cuts the person (no seen foot to re-seat it by)
FLIGHT = "flight"  # aligned in the air: a run of a track's frames whose foot is above the ground (.flight)
ALIGNED_FLAGS = ("", IMPLAUSIBLE_STATURE, *NOT_STANDING, FLIGHT)  # flags of people that were transformed


@dataclass(frozen=True)
class _FramePeople:
    """A frame's people before RotAvat: foot and crown points (P, 3) in the method's camera frame, the rays
    (P, 3) of their pixels in the camera (the points themselves when the intrinsics are the camera's)."""

    feet_cam: np.ndarray
    heads_cam: np.ndarray
    foot_rays_cam: np.ndarray
    head_rays_cam: np.ndarray


def _frame_people(frame: Frame, camera: Camera, mesh: MeshIntrinsics) -> _FramePeople:
    """Foot and crown points of a frame's people and the rays they keep in ``camera``: the camera's rays
    (its lens included) through the pixels the method drew with its own pinhole."""
    feet_cam, heads_cam = frame_foot_head_cam(frame, mesh)
    rays = (feet_cam, heads_cam)
    if camera.distortion != 0.0:
        rays = tuple(camera.pixel_rays_cam(project_cam_to_px(points, mesh.focal_px, mesh.principal_point))
                     for points in (feet_cam, heads_cam))
    elif not mesh.same_as(camera):
        rays = tuple(method_rays_cam(points, mesh.focal_px, mesh.principal_point, camera.focal_px,
                                     camera.principal_point) for points in (feet_cam, heads_cam))
    return _FramePeople(feet_cam, heads_cam, *rays)


def _frame_transform(frame: Frame, camera: Camera, upright: str, stature_by_id: dict[int, float] | None,
                     mesh: MeshIntrinsics, elevation_m: np.ndarray | None = None) -> tuple[AlignTransform, _FramePeople]:
    """Transforms for a frame's people and their points before (``elevation_m`` (P,): feet off the ground).
    People whose foot or crown pixel, as their tool drew it, is not seen whole are left unchanged
    (``cut_by_border``): no one is re-seated by an invisible foot."""
    (transform,), (people,) = _frames_transforms([frame], camera, upright, stature_by_id, [mesh], [elevation_m])
    return transform, people


def _frames_transforms(frames: list[Frame], camera: Camera, upright: str, stature_by_id: dict[int, float] | None,
                       meshes: list[MeshIntrinsics], elevations: list[np.ndarray | None]
                       ) -> tuple[list[AlignTransform], list[_FramePeople]]:
    """:func:`_frame_transform` of several frames (frames with people), their people's transforms computed at once:
    row by row, the same numbers as frame by frame, for one call's overhead instead of one per frame."""
    if not frames:
        return [], []
    people = [_frame_people(frame, camera, mesh) for frame, mesh in zip(frames, meshes)]
    seen = []
    for group, mesh in zip(people, meshes):
        drawn = [project_cam_to_px(p, mesh.focal_px, mesh.principal_point) for p in (group.feet_cam, group.heads_cam)]
        seen.append(in_view(drawn[0], camera.image_size) & in_view(drawn[1], camera.image_size))
    stature = None
    if stature_by_id is not None:
        stature = np.array([stature_by_id.get(int(i), np.nan) for frame in frames for i in frame.person_ids])
    elevation = None
    if any(e is not None for e in elevations):  # NaN: on the ground, as no elevation at all
        elevation = np.concatenate([np.full(frame.n_people, np.nan) if e is None else np.asarray(e, np.float64)
                                    for frame, e in zip(frames, elevations)])
    joined = [np.concatenate([getattr(group, name) for group in people])
              for name in ("feet_cam", "heads_cam", "foot_rays_cam", "head_rays_cam")]
    transform = rotavat_transforms(joined[0], joined[1], camera.up_cam, camera.ground_offset_m, upright, stature,
                                   joined[2], joined[3], elevation, np.concatenate(seen))
    bounds = np.cumsum([0] + [frame.n_people for frame in frames])
    return [transform.rows(slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:])], people


def _frames_postures(frames: list[Frame], joints_layout: str | None) -> list[np.ndarray | None]:
    """Each frame's postures (:func:`rotavat_cli.bodies.posture.postures`, None without joints or for a layout
    without them), the frames whose joints share one shape classified at once."""
    out: list[np.ndarray | None] = [None] * len(frames)
    with_joints = [i for i, frame in enumerate(frames) if frame.get("joints") is not None]
    shapes = {frames[i].data["joints"].shape[1:] for i in with_joints}
    if len(shapes) > 1:  # joints of several layouts: frame by frame
        return [None if i not in with_joints else postures(frames[i].data["joints"], joints_layout)
                for i in range(len(frames))]
    if with_joints:
        names = postures(np.concatenate([frames[i].data["joints"] for i in with_joints]), joints_layout)
        bounds = np.cumsum([0] + [frames[i].n_people for i in with_joints])
        for i, a, b in zip(with_joints, bounds[:-1], bounds[1:]):
            out[i] = None if names is None else names[a:b]
    return out


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


def _lens_pixel_drift_px(before_cam: np.ndarray, after_cam: np.ndarray, mesh_focal_px: np.ndarray,
                         mesh_principal_point: tuple[float, float], camera: Camera) -> np.ndarray:
    """:func:`_pixel_drift_px` through a camera with a lens (p, N) px: the pixels the method drew (its pinhole)
    against the camera's image pixels (:meth:`Camera.project`, the distortion applied); coordinates first (p, 3, N)."""
    before = np.moveaxis(np.asarray(before_cam, dtype=np.float64), 1, -1)  # (p, N, 3)
    after = np.moveaxis(np.asarray(after_cam, dtype=np.float64), 1, -1)
    drawn = project_cam_to_px(before, np.asarray(mesh_focal_px, dtype=np.float64)[:, None], mesh_principal_point)
    return np.linalg.norm(camera.project(after) - drawn, axis=-1).astype(np.float32)


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
        drift = (_pixel_drift_px(before, after, focal, camera.focal_px, shift) if camera.distortion == 0.0
                 else _lens_pixel_drift_px(before, after, focal, mesh.principal_point, camera))
        mean, peak = _nan_mean_max(drift)
        moved.append(after)
        means.append(mean)
        peaks.append(peak)
    return points_from_coords(moved, V, dtype), np.concatenate(means), np.concatenate(peaks)


def output_dtype(points: np.ndarray) -> np.dtype:
    """Aligned coordinates keep a float dtype; integer coordinates become float64 (never rounded back)."""
    return points.dtype if points.dtype.kind == "f" else np.dtype(np.float64)


def _person_flags(transform: AlignTransform, posture: np.ndarray | None, stature_range_m: tuple[float, float],
                  elevation_m: np.ndarray | None) -> np.ndarray:
    """(P,) people.csv flags (object): why a person was left unchanged (:data:`FLAGS`); else ``flight`` for the
    people placed in the air (``elevation_m`` (P,) finite), their posture (``posture`` (P,), None: unknown) for
    those whose joints say they do not stand, ``implausible_stature`` for a stature outside ``stature_range_m``,
    "" for everyone else."""
    ok = transform.ok
    flags = np.array([FLAGS[int(c)] for c in transform.flag], dtype=object)
    with np.errstate(invalid="ignore"):
        implausible = ok & ((transform.stature_m < stature_range_m[0]) | (transform.stature_m > stature_range_m[1]))
    flags[implausible] = IMPLAUSIBLE_STATURE
    if posture is not None:
        seated = ok & np.isin(posture, NOT_STANDING)
        flags[seated] = posture[seated]
    if elevation_m is not None:
        flags[ok & np.isfinite(elevation_m)] = FLIGHT
    return flags


def align_frame(frame: Frame, camera: Camera, options: AlignOptions | None = None,
                stature_by_id: dict[int, float] | None = None,
                intrinsics: Intrinsics | None = None,
                joints_layout: str | None = None,
                elevation_m: np.ndarray | None = None,
                stature_from: str = "given_camera") -> tuple[Frame, dict[str, np.ndarray]]:
    """Align one frame into ``camera``: the new frame and per-person columns (``PEOPLE_COLUMNS``, plus
    ``foot_ray_cam``/``head_ray_cam`` (P, 3): the rays the foot and crown keep, for flight detection).

    options: ``upright`` and ``stature_range_m`` are read (default :class:`AlignOptions`);
    stature_by_id: per person_id stature to keep (``height_from: track``, :func:`track_statures`);
    intrinsics: what the frame's meshes were made with (``Sequence.frame_intrinsics``; None: the
    frame's own keys); what is not stated is the camera's own; joints_layout: the layout of the
    frame's ``joints`` (``Sequence.joints_layout``; None: SMPL's by count); elevation_m: (P,) the
    height above the ground of the people in the air (NaN: on the ground), flagged ``flight``;
    stature_from: where the camera's scale comes from (:func:`rotavat_cli.bodies.measure.scale_source` of its fit
    block), the people.csv column that says whether the statures are measured. People aligned to a stature
    outside ``options.stature_range_m`` are flagged ``implausible_stature``, people whose joints say they
    sit, kneel or bend by their posture (``sitting``, ...); all are aligned. People cut by the image border
    are left unchanged (``cut_by_border``).
    """
    options = AlignOptions() if options is None else options
    (aligned,) = _align_frames([frame], camera, options, stature_by_id, [intrinsics], joints_layout, [elevation_m],
                               stature_from)
    return aligned


def _align_frames(frames: list[Frame], camera: Camera, options: AlignOptions, stature_by_id: dict[int, float] | None,
                  intrinsics: list[Intrinsics | None], joints_layout: str | None,
                  elevations: list[np.ndarray | None], stature_from: str) -> list[tuple[Frame, dict[str, np.ndarray]]]:
    """:func:`align_frame` of several frames (arguments per frame in lists): their people's transforms and postures
    computed at once (:func:`_frames_transforms`, :func:`_frames_postures`), the same numbers as frame by frame."""
    intrinsics = [frame.intrinsics if given is None else given for frame, given in zip(frames, intrinsics)]
    busy = [i for i, frame in enumerate(frames) if frame.n_people]
    meshes = {i: MeshIntrinsics.of_frame(frames[i], intrinsics[i], camera) for i in busy}
    transforms, people = _frames_transforms([frames[i] for i in busy], camera, options.upright, stature_by_id,
                                            [meshes[i] for i in busy], [elevations[i] for i in busy])
    posture = _frames_postures([frames[i] for i in busy], joints_layout)
    prepared = {i: (transforms[k], people[k], posture[k]) for k, i in enumerate(busy)}
    return [_align_prepared(frame, camera, options, meshes[i], *prepared[i], elevations[i], stature_from)
            if i in prepared else _no_one(frame, camera) for i, frame in enumerate(frames)]


def _no_one(frame: Frame, camera: Camera) -> tuple[Frame, dict[str, np.ndarray]]:
    """:func:`align_frame` of a frame without people: its intrinsics the camera's, empty columns."""
    empty = {c: np.zeros(0, dtype=object if c in ("frame", "flag", "stature_from") else np.float64)
             for c in PEOPLE_COLUMNS}
    return _in_camera(frame, camera), {**empty, "foot_ray_cam": np.zeros((0, 3)), "head_ray_cam": np.zeros((0, 3))}


def _align_prepared(frame: Frame, camera: Camera, options: AlignOptions, mesh: MeshIntrinsics,
                    transform: AlignTransform, people: _FramePeople, posture: np.ndarray | None,
                    elevation_m: np.ndarray | None, stature_from: str) -> tuple[Frame, dict[str, np.ndarray]]:
    """:func:`align_frame` of a frame with people, its transforms, points and postures given."""
    P = frame.n_people
    heads_cam = people.heads_cam
    if frame.get("vertices") is not None:
        new_verts, drift_mean, drift_max = _align_points(frame.data["vertices"], transform, mesh, camera)
        arrays = {"vertices": new_verts}
        if frame.get("joints") is not None:
            arrays["joints"] = apply_transforms(frame.data["joints"], transform, output_dtype(frame.data["joints"]))
    else:  # joint-level alignment: the joints are the points, and their drift is measured
        new_joints, drift_mean, drift_max = _align_points(frame.data["joints"], transform, mesh, camera)
        arrays = {"joints": new_joints}
    arrays.update(aligned_body_params(frame.data, transform, camera))
    new_heads = apply_transforms(heads_cam[:, None], transform)[:, 0]
    heads_drawn_px = project_cam_to_px(heads_cam, mesh.focal_px, mesh.principal_point)
    foot_world = camera.world_from_cam(transform.pivot_cam)
    ok = transform.ok
    columns = {
        "frame": np.full(P, frame.name, dtype=object),
        "person_id": frame.person_ids,
        "x_world_m": np.where(ok, foot_world[:, 0], np.nan),
        "z_world_m": np.where(ok, foot_world[:, 2], np.nan),
        "foot_height_m": np.where(ok, 0.0 if elevation_m is None else np.nan_to_num(elevation_m), np.nan),
        "stature_m": transform.stature_m,
        "depth_scale": transform.depth_scale,
        "rotation_deg": transform.rotation_deg,
        "final_scale": transform.final_scale,
        "mesh_focal_px": mesh.focal_px,
        "drift_mean_px": drift_mean,
        "drift_max_px": drift_max,
        "head_drift_px": np.linalg.norm(camera.project(new_heads) - heads_drawn_px, axis=-1),
        "flag": _person_flags(transform, posture, options.stature_range_m, elevation_m),
        "stature_from": np.full(P, stature_from, dtype=object),
        "foot_ray_cam": people.foot_rays_cam,
        "head_ray_cam": people.head_rays_cam,
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
    """Median RotAvat stature per ``person_id`` over the frames where the person stands by their joints (all
    frames without joints; one landmark pass, no writing)."""
    samples: dict[int, list[float]] = defaultdict(list)
    for frame in seq.frames():
        if frame.n_people == 0:
            continue
        if frame.get("person_ids") is None:
            raise InputError(f"{frame.source}: --height-from track needs 'person_ids' (track ids) in every frame")
        mesh = MeshIntrinsics.of_frame(frame, seq.frame_intrinsics(frame), camera)
        transform, _ = _frame_transform(frame, camera, upright, None, mesh)
        posture = None if frame.get("joints") is None else postures(frame.data["joints"], seq.joints_layout)
        keep = np.isfinite(transform.stature_m) & (True if posture is None else ~np.isin(posture, NOT_STANDING))
        for pid, stature in zip(frame.person_ids[keep].tolist(), transform.stature_m[keep].tolist()):
            samples[int(pid)].append(stature)
    return {pid: float(np.median(values)) for pid, values in samples.items()}


_CHUNK_FRAMES = 8  # frames per worker task: amortises task overhead, keeps memory bounded


def _align_chunk(task: tuple) -> tuple[list[tuple[int, dict[str, np.ndarray], str, bool]], object]:
    """Read, align and write a few frames: per frame its people count, columns, people.csv rows and whether it
    carries track ids; and what reading them found (``Sequence.frame_notes``: an imported sequence's
    warnings, from a worker). ``flight``: elevations of frames known to be in flight (:func:`flight_plan`)."""
    seq, names, camera, out, options, stature_by_id, flight, stature_from = task
    frames = [seq.read_frame(name) for name in names]  # a chunk of frames (_CHUNK_FRAMES) is held at once
    for frame in frames:
        seq.require_static_frame(frame, camera.image_size)
    aligned = _align_frames(frames, camera, options, stature_by_id, [seq.frame_intrinsics(f) for f in frames],
                            seq.joints_layout, [(flight or {}).get(name) for name in names], stature_from)
    results = []
    for frame, (new_frame, cols) in zip(frames, aligned):
        write_frame(out, new_frame, seq.form)
        results.append((frame.n_people, cols, _csv_rows(cols), frame.get("person_ids") is not None))
    return results, seq.frame_notes(names)


_TRACK_KEYS = ("frame_index", "person_id", "standing", "candidate", "stature_m", "foot_rays_cam", "head_rays_cam")


def _track_columns(index: int, person_ids: np.ndarray, flags: np.ndarray, stature_m: np.ndarray,
                   foot_rays_cam: np.ndarray, head_rays_cam: np.ndarray) -> dict[str, np.ndarray]:
    """One frame's rows of :class:`~.flight.TrackRows` (as a dict of (P, ...) arrays), from its align columns."""
    flags = np.asarray(flags, dtype=object)
    return {"frame_index": np.full(len(flags), index), "person_id": np.asarray(person_ids),
            "standing": flags == "", "candidate": (flags == "") | (flags == IMPLAUSIBLE_STATURE),
            "stature_m": np.asarray(stature_m, np.float64),
            "foot_rays_cam": np.asarray(foot_rays_cam, np.float64).reshape(-1, 3),
            "head_rays_cam": np.asarray(head_rays_cam, np.float64).reshape(-1, 3)}


def _elevations(per_frame: list[dict[str, np.ndarray]], names: tuple[str, ...], camera: Camera) -> dict[str, np.ndarray]:
    """Each frame with someone in flight -> (P,) the feet's elevations (NaN: on the ground), from every frame's
    track columns (:func:`_track_columns`)."""
    rows = {key: np.concatenate([frame[key] for frame in per_frame]) for key in _TRACK_KEYS}
    elevation = flight_rows(TrackRows(*(rows[k] for k in _TRACK_KEYS)), camera.up_cam, camera.ground_offset_m)
    found: dict[str, np.ndarray] = {}
    start = 0
    for index, frame in enumerate(per_frame):  # splitting the rows back into frames
        stop = start + len(frame["frame_index"])
        if np.isfinite(elevation[start:stop]).any():
            found[names[index]] = elevation[start:stop]
        start = stop
    return found


@dataclass
class _SequenceRows:
    """What the summary and flight detection keep of each frame's columns: a few numbers per person."""

    summary: list[tuple[int, dict[str, np.ndarray]]] = field(default_factory=list)  # per frame (people, columns)
    track: list[dict[str, np.ndarray]] = field(default_factory=list)  # per frame, :func:`_track_columns`
    tracked: bool = True  # every frame with people carries track ids

    def add(self, n_people: int, cols: dict[str, np.ndarray], tracked: bool) -> None:
        """Keep one frame's summary columns and the columns flight detection reads."""
        self.summary.append((n_people, _summary_columns(cols)))
        self.tracked &= tracked or n_people == 0
        if not self.tracked:  # no tracks, no flight: nothing more to keep
            self.track.clear()
            return
        self.track.append(_track_columns(len(self.summary) - 1, cols["person_id"], cols["flag"], cols["stature_m"],
                                         cols["foot_ray_cam"], cols["head_ray_cam"]))


def _summary_columns(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns :class:`AlignSummary` reads (flag, _SUMMARY_COLUMNS) of a frame's columns."""
    return {"flag": np.asarray(cols["flag"], dtype=object),
            **{k: np.asarray(cols[k], dtype=np.float64) for k in _SUMMARY_COLUMNS}}


def flight_plan(seq: Sequence, camera: Camera, options: AlignOptions | None = None,
                stature_by_id: dict[int, float] | None = None) -> dict[str, np.ndarray]:
    """The frames where a tracked person is in flight -> (P,) the feet's elevations (NaN: on the ground), found
    by a pass over the landmarks alone (nothing transformed or written): what :func:`align_sequence` finds after
    its own pass, for work split over frames (``align_sequence(..., flight=)``: batch's chunks). {} for a
    sequence without track ids."""
    options = AlignOptions() if options is None else options
    per_frame = []
    for index, frame in enumerate(seq.frames()):
        if frame.n_people and frame.get("person_ids") is None:
            return {}
        mesh = MeshIntrinsics.of_frame(frame, seq.frame_intrinsics(frame), camera)
        transform, people = _frame_transform(frame, camera, options.upright, stature_by_id, mesh)
        posture = None if frame.get("joints") is None else postures(frame.data["joints"], seq.joints_layout)
        flags = _person_flags(transform, posture, options.stature_range_m, None)
        per_frame.append(_track_columns(index, frame.person_ids, flags, transform.stature_m, people.foot_rays_cam,
                                        people.head_rays_cam))
    return _elevations(per_frame, seq.frame_names, camera) if per_frame else {}


def _realign_in_flight(seq: Sequence, stage: Path, camera: Camera, options: AlignOptions,
                       stature_by_id: dict[int, float] | None, kept: _SequenceRows,
                       found: dict[str, np.ndarray], stature_from: str) -> dict[str, str]:
    """Align again, with the feet at their elevation, the frames where someone is in flight; update the kept
    summary columns; return those frames' new people.csv rows by frame name."""
    index_of = {name: i for i, name in enumerate(seq.frame_names)}
    replaced: dict[str, str] = {}
    for name, elevation in found.items():  # a loop over the (few) frames in flight
        frame = seq.read_frame(name)
        new_frame, cols = align_frame(frame, camera, options, stature_by_id, seq.frame_intrinsics(frame),
                                      seq.joints_layout, elevation, stature_from)
        write_frame(stage, new_frame, seq.form)
        kept.summary[index_of[name]] = (frame.n_people, _summary_columns(cols))
        replaced[name] = _csv_rows(cols)
    return replaced


def _replace_frame_rows(people_csv: Path, replaced: dict[str, str]) -> None:
    """Rewrite people.csv with the rows of the frames in ``replaced`` (frame name -> rows) swapped, streaming."""
    with open(people_csv, encoding="utf-8", newline="") as source, atomic_open(people_csv, "w") as handle:
        reader, writer = csv.reader(source), csv.writer(handle, lineterminator="\n")
        writer.writerow(next(reader))
        for row in reader:
            if row[0] not in replaced:
                writer.writerow(row)
            elif replaced[row[0]]:
                handle.write(replaced[row[0]])
                replaced[row[0]] = ""  # the frame's other rows are dropped


_SUMMARY_COLUMNS = ("depth_scale", "rotation_deg", "stature_m", "head_drift_px", "drift_mean_px", "drift_max_px")


@dataclass
class AlignSummary:
    """What ``align_sequence`` did (``add`` per frame, then ``finish``).

    ``aligned`` counts the people that were transformed (``implausible`` of them with a stature
    outside the plausible range, ``not_standing`` of them sitting, kneeling or bending, ``flight`` of
    them in the air); ``flagged`` counts every flag, including those. The medians are over the aligned
    people who stand on the ground (``in_medians`` of them).
    """

    out: Path
    frames: int = 0
    people: int = 0
    aligned: int = 0
    implausible: int = 0
    not_standing: int = 0
    flight: int = 0
    flagged: dict[str, int] = field(default_factory=dict)
    median_depth_scale: float = float("nan")
    median_abs_depth_change_pct: float = float("nan")
    median_rotation_deg: float = float("nan")
    median_stature_m: float = float("nan")
    median_drift_px: float = float("nan")  # median over people of their mean vertex motion in the picture
    max_drift_px: float = float("nan")  # the largest motion of any vertex (foot and crown stay: 0)
    max_head_drift_px: float = 0.0
    stature_from: str = "given_camera"  # where the camera's scale comes from (rotavat_cli.bodies.measure.SCALE_SOURCES)
    cut: int = 0  # people left unchanged because the image border cuts them (cut_by_border)
    _aligned_columns: list[dict[str, np.ndarray]] = field(default_factory=list, repr=False)

    def add(self, n_people: int, cols: dict[str, np.ndarray]) -> None:
        """Count one frame's people and keep the aligned people's factors."""
        flag = np.asarray(cols["flag"], dtype=object)
        ok = (flag == "") | (flag == IMPLAUSIBLE_STATURE)  # aligned and standing on the ground: the medians
        seated, airborne = np.isin(flag, NOT_STANDING), flag == FLIGHT
        self.frames += 1
        self.people += n_people
        self.aligned += int(ok.sum() + seated.sum() + airborne.sum())
        self.implausible += int((flag == IMPLAUSIBLE_STATURE).sum())
        self.not_standing += int(seated.sum())
        self.flight += int(airborne.sum())
        self.cut += int((flag == CUT_BY_BORDER).sum())
        for name in flag[flag != ""]:
            self.flagged[str(name)] = self.flagged.get(str(name), 0) + 1
        self._aligned_columns.append({k: np.asarray(cols[k], dtype=np.float64)[ok]
                                      for k in _SUMMARY_COLUMNS})

    @property
    def in_medians(self) -> int:
        """Aligned people the medians are over: standing on the ground."""
        return self.aligned - self.not_standing - self.flight

    def finish(self) -> None:
        """Medians over every aligned person who stands on the ground (small: six floats per person)."""
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
    if rows and rows[0].get("stature_from"):  # written before the column existed: the default stays
        summary.stature_from = rows[0]["stature_from"]
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
                   force: bool = False, flight: dict[str, np.ndarray] | None = None) -> AlignSummary:
    """Align every frame of ``seq`` into ``out`` (mirrored form) with camera.yaml and people.csv.

    Frames stream through ``options.jobs`` processes (0: one per core; never more than the cores or
    the chunks of frames), a bounded window ahead of the in-order writer of people.csv, so memory
    stays flat (a few numbers per person and frame are kept, for the medians and flight detection)
    and every core works (``jobs=1``: in this process). Then tracked people in the air are found
    (:mod:`.flight`) and only their frames are aligned again, at their elevation; ``flight`` (a
    :func:`flight_plan` of a whole sequence ``seq`` is part of) gives them instead, so that aligning a
    sequence in parts gives what one call does. ``camera_fit`` is written as
    camera.yaml's fit block. ``out`` is replaced only when it is rotavat's own output or empty
    (``force``: any folder that is not and does not hold an input;
    :func:`rotavat_cli.files.outputs.check_output_dir`).
    """
    options = AlignOptions() if options is None else options
    out = Path(out)
    check_output_dir(out, [seq.path], force)
    upright = options.upright
    stature_by_id = track_statures(seq, camera, upright) if options.height_from == "track" else None
    kept = _SequenceRows()
    names = seq.frame_names
    chunks = [names[i:i + _CHUNK_FRAMES] for i in range(0, len(names), _CHUNK_FRAMES)]
    stature_from = scale_source(camera_fit)
    with staged_directory(out, "align") as stage:
        tasks = ((seq, chunk, camera, stage, options, stature_by_id, flight, stature_from) for chunk in chunks)
        with atomic_open(stage / "people.csv", "w") as handle:
            csv.writer(handle, lineterminator="\n").writerow(PEOPLE_COLUMNS)
            for results, notes in ordered_map(_align_chunk, tasks, cap_workers(options.jobs, len(chunks)), processes=True):
                seq.add_frame_notes(notes)
                for n_people, cols, rows, tracked in results:
                    handle.write(rows)
                    kept.add(n_people, cols, tracked)
                    if progress:
                        progress()
        found = _elevations(kept.track, names, camera) if flight is None and kept.tracked and kept.track else {}
        if found:
            replaced = _realign_in_flight(seq, stage, camera, options, stature_by_id, kept, found, stature_from)
            _replace_frame_rows(stage / "people.csv", replaced)
        write_camera_yaml(stage / "camera.yaml", camera, camera_fit)
        write_meta(stage, aligned_meta(seq.meta, camera))
    summary = AlignSummary(out, stature_from=stature_from)
    for n_people, cols in kept.summary:
        summary.add(n_people, cols)
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
