"""TRAM (``scripts/estimate_camera.py`` then ``scripts/estimate_humans.py``): ``results/<seq>/``.

Source: yufu-wang/tram @0b1d844 ``scripts/estimate_camera.py`` (``camera = {'pred_cam_R',
'pred_cam_T', 'img_focal': cam_int[0], 'img_center': cam_int[2:]}``; ``np.save(f'{seq_folder}/
camera.npy', camera)``), ``scripts/estimate_humans.py`` (tracks sorted longest first, then
``np.save(f'{hps_folder}/hps_track_{k}.npy', results)`` for at most ``--max_humans``),
``lib/models/hmr_vimo.py`` (``HMR_VIMO.inference``: the ``results`` dict; ``get_trans``:
``tz = 2 img_focal / (b s)``, the translation in the full image's camera),
``lib/camera/masked_droid_slam.py`` (``calibrate_intrinsics``, ``run_metric_slam``),
``lib/camera/slam_utils.py`` (``est_calib``: focal = max(H, W), centre = (W/2, H/2)),
``lib/pipeline/visualization.py`` (``visualize_tram``: ``smpl(body_pose=pred_rotmat[:, 1:],
global_orient=pred_rotmat[:, [0]], betas=pred_shape, transl=pred_trans)`` is the camera frame,
``pred_cam_R @ v + pred_cam_T`` the SLAM world), @82fd0db ``lib/models/smpl.py`` (neutral SMPL).

- ``camera.npy``: ``np.save`` of a dict (a pickled 0-d object array, read with the restricted
  unpickler): ``pred_cam_R`` (T, 3, 3), ``pred_cam_T`` (T, 3) (camera-to-world, metric SLAM; the
  identity and zero for a static camera), ``img_focal`` (px), ``img_center`` (2,) px.
- ``hps/hps_track_{k}.npy``: ``np.save`` of a dict of **torch tensors** (each storage a
  ``torch.storage._load_from_bytes`` blob, read by :mod:`rotavat_cli.unpickle.torch_files` without torch):
  ``pred_rotmat`` (N, 24, 3, 3), ``pred_shape`` (N, 10), ``pred_trans`` (N, 1, 3), ``frame`` (N,)
  image indices, ``pred_cam`` (N, 3), ``pred_pose`` (N, 144, 6D). ``k`` ranks tracks by length
  (not DEVA's track id): ``person_ids`` = k, people grouped by ``frame`` into multi-person frames.
- Frame: ``SMPL(pred_rotmat, pred_shape) + pred_trans`` is the camera frame of that image (OpenCV,
  metres), with each frame's own ``pred_shape`` (TRAM's visualiser averages the shape per track).
  The SLAM world (``pred_cam_R``, ``pred_cam_T``) is not used; a moving camera is reported.
- Focal: ``img_focal``, the one ``pred_trans`` was made with, and ``img_center``. TRAM guesses it:
  ``est_calib``'s max(W, H) when the camera is static (``focal_rule: tram``), else the value its
  SLAM reprojection search picked among max(W, H), 500, 600 ... 1400 px (a coarse estimate from the
  video, not a calibration): ``focal_kind: assumed`` either way, a rule only when it is max(W, H).
- Image size: ``--image-size``, else the first image of ``images/`` (``*.jpg`` header), else
  twice ``img_center`` (``est_calib`` puts it at the centre). Frame names: the images' stems, else
  the frame index.
- Parameters only: vertices and joints need ``--smpl-model`` (SMPL); nothing else is stored.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.npy import load_npy
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .ids import check_frame_range
from .image_size import centre_image_size, image_size_from_header
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces, require_model
from .row_blocks import RowBlocks, frame_offsets, posing_block_rows
from .smpl import lbs, smpl_param_arrays

_TRACK = re.compile(r"hps_track_(\d+)\.npy$")
_MOVING_M, _MOVING_DEG = 1e-3, 0.05  # SLAM motion under these is a static camera (TRAM writes exact zeros then)


def _folder(path: Path) -> Path | None:
    """The ``results/<seq>`` folder of ``path`` (itself, or the parent of its ``hps`` folder)."""
    if path.is_dir() and path.name == "hps" and (path.parent / "camera.npy").is_file():
        path = path.parent
    if path.is_dir() and (path / "camera.npy").is_file() and (path / "hps").is_dir():
        return path
    return None


def _track_files(folder: Path) -> list[tuple[int, Path]]:
    """(k, hps_track_{k}.npy) in k order."""
    found = [(int(m.group(1)), p) for p in (folder / "hps").iterdir() if (m := _TRACK.match(p.name))]
    return sorted(found)


def sniff(path: Path) -> str | None:
    """'tram' for a TRAM results folder (``camera.npy`` and ``hps/hps_track_*.npy``)."""
    folder = _folder(path)
    return "tram" if folder is not None and _track_files(folder) else None


def _dict_npy(path: Path) -> Mapping:
    """The dict an ``np.save(path, dict)`` holds."""
    content = load_npy(path)
    value = content.item() if content.dtype.hasobject and content.shape == () else content
    if not isinstance(value, Mapping):
        raise file_error(path, f"expected np.save of a dict, got {type(value).__name__}")
    return value


def _scalar_array(value: object) -> object:
    """A numpy or Python number as a 0-d array (``cam_int[0]`` is a numpy scalar); anything else unchanged."""
    is_number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    return np.asarray(value) if is_number else value


def _camera(folder: Path) -> tuple[float, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """(img_focal px, img_center (2,) px, pred_cam_R (T, 3, 3) or None, pred_cam_T (T, 3) or None)."""
    path = folder / "camera.npy"
    camera = _dict_npy(path)
    focal = as_array(_scalar_array(get(camera, "img_focal", path)), "img_focal", path).reshape(-1)
    center = as_array(_scalar_array(get(camera, "img_center", path)), "img_center", path).reshape(-1)
    if focal.size != 1 or not np.isfinite(focal[0]) or focal[0] <= 0:
        raise file_error(path, "'img_focal' must be one positive focal length (px)")
    if center.size != 2 or not np.all(np.isfinite(center)) or np.any(center <= 0):
        raise file_error(path, "'img_center' must be two positive pixel coordinates")
    rotation = camera.get("pred_cam_R")
    translation = camera.get("pred_cam_T")
    rotation = None if rotation is None else as_array(rotation, "pred_cam_R", path, ndim=3, last=(3, 3))
    translation = None if translation is None else as_array(translation, "pred_cam_T", path, ndim=2, last=(3,))
    return float(focal[0]), center.astype(np.float64), rotation, translation


def _track(path: Path) -> dict[str, np.ndarray]:
    """One track's parameters, checked: pred_rotmat (N, 24, 3, 3), pred_shape (N, B), pred_trans (N, 3), frame (N,)."""
    track = _dict_npy(path)
    rotmat = as_array(get(track, "pred_rotmat", path), "pred_rotmat", path, ndim=4, last=(24, 3, 3))
    n = len(rotmat)
    shape = as_array(get(track, "pred_shape", path), "pred_shape", path, ndim=2)
    trans = as_array(get(track, "pred_trans", path), "pred_trans", path, last=(3,)).reshape(-1, 3)
    frame = as_array(get(track, "frame", path), "frame", path, kinds="iu").reshape(-1)
    for name, array in (("pred_shape", shape), ("pred_trans", trans), ("frame", frame)):
        if len(array) != n:
            raise file_error(path, f"'{name}' has {len(array)} rows, 'pred_rotmat' {n}")
    if n and (frame.min() < 0 or len(np.unique(frame)) != n):
        raise file_error(path, "'frame' must hold distinct, non-negative image indices")
    return {"rotmat": rotmat, "shape": shape, "trans": trans, "frame": frame.astype(np.int64)}


def _motion(rotation: np.ndarray | None, translation: np.ndarray | None) -> tuple[float, float]:
    """Largest SLAM camera translation (m) and rotation (deg) away from the first frame's."""
    moved_m = float(np.max(np.linalg.norm(translation - translation[:1], axis=1))) if translation is not None and len(translation) else 0.0
    turned_deg = 0.0
    if rotation is not None and len(rotation):
        relative = np.einsum("ji,tjk->tik", rotation[0], rotation)  # R_0^T R_t
        cosine = np.clip((np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
        turned_deg = float(np.degrees(np.max(np.arccos(cosine))))
    return moved_m, turned_deg


def _images(folder: Path) -> list[Path]:
    """``images/*.jpg`` in TRAM's order (``sorted(glob)``: the frame indices of ``frame``)."""
    return sorted((folder / "images").glob("*.jpg")) if (folder / "images").is_dir() else []


def _frame_stems(images: list[Path], n_slam: int | None, tracks: list[dict]) -> list[str]:
    """Frame names: the images' stems when they cover every frame, else zero-padded indices."""
    last = max((int(t["frame"].max()) for t in tracks if len(t["frame"])), default=-1)
    n_frames = max(last + 1, n_slam or 0, len(images))
    if len(images) == n_frames:
        return [p.stem for p in images]
    return [f"{i:06d}" for i in range(n_frames)]


def read_tram(src: Path, opts: ImportOptions) -> ImportedSequence:
    """TRAM results folder -> contract frames (all tracks of an image in one frame, ``person_ids`` = track k)."""
    folder = _folder(src)
    if folder is None:
        raise file_error(src, "not a TRAM results folder (expected camera.npy and hps/hps_track_*.npy)")
    files = _track_files(folder)
    if not files:
        raise file_error(folder / "hps", "no hps_track_*.npy files")
    focal, center, rotation, translation = _camera(folder)
    tracks = [_track(path) for _, path in files]
    ids = [k for k, _ in files]
    warnings: list[str] = []

    check_frame_range(1 + max((int(t["frame"].max()) for t in tracks if len(t["frame"])), default=-1),
                      sum(len(t["frame"]) for t in tracks), folder / "hps", "frame")
    images = _images(folder)
    stems = _frame_stems(images, None if rotation is None else len(rotation), tracks)
    header = image_size_from_header(images[0]) if images else None
    centre_size = centre_image_size(center[0], center[1], folder / "camera.npy", "'img_center'") \
        if not (opts.image_size or header) else (round(2 * float(center[0])), round(2 * float(center[1])))
    image_size = opts.image_size or header or centre_size
    size_from = "--image-size" if opts.image_size else "images/ header" if header else "2 x img_center (est_calib)"
    if image_size != centre_size:
        warnings.append(f"{folder}: img_center {center.tolist()} is not the centre of the {image_size[0]}x{image_size[1]} "
                        "image; kept as the principal point")
    rule = "tram" if abs(focal - focal_from_rule("tram", image_size)) <= 1e-6 * focal else None
    moved_m, turned_deg = _motion(rotation, translation)
    if moved_m > _MOVING_M or turned_deg > _MOVING_DEG:
        warnings.append(f"{folder}: TRAM's SLAM found the camera moving (up to {moved_m:.2f} m, {turned_deg:.1f} deg): "
                        "rotavat assumes a static camera; each frame is imported in its own camera frame")

    model = opts.body_model
    require_model(model, folder, "TRAM", "smpl")
    faces = model_faces(model, model.n_verts)
    names = frame_names(stems, warnings)
    rows_by_frame: dict[int, list[tuple[int, int]]] = {}
    for t, track in enumerate(tracks):
        for row, frame in enumerate(track["frame"].tolist()):
            rows_by_frame.setdefault(frame, []).append((t, row))

    table = [pick for index in range(len(names)) for pick in rows_by_frame.get(index, [])]  # (track, row), frame by frame
    offsets = frame_offsets([len(rows_by_frame.get(index, [])) for index in range(len(names))])

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the table posed at once (frames posed in batches, not one by one)."""
        rows = table[start:stop]
        rotmat = np.stack([tracks[t]["rotmat"][r] for t, r in rows]) if rows else np.zeros((0, 24, 3, 3))
        shape = np.stack([tracks[t]["shape"][r] for t, r in rows]) if rows else np.zeros((0, 10))
        trans = np.stack([tracks[t]["trans"][r] for t, r in rows]) if rows else np.zeros((0, 3))
        vertices, joints = lbs(model, shape, rotmat, trans)
        return {"vertices": vertices, "joints": joints, **smpl_param_arrays(model, shape, rotmat, trans, joints)}

    posed_rows = RowBlocks(len(table), posed, posing_block_rows(model))

    def build(index: int, notes: FrameNotes) -> Frame:
        rows = rows_by_frame.get(index, [])
        body = posed_rows.rows(int(offsets[index]), int(offsets[index + 1]))
        vertices, joints = body.pop("vertices"), body.pop("joints")
        return people_frame(names[index], f"{folder} [frame {index}]", notes.warnings, vertices=vertices, joints=joints,
                            person_ids=np.array([ids[t] for t, _ in rows], np.int64), faces=faces, n_verts=model.n_verts,
                            body_params=body)

    meta = base_meta("tram", folder, opts, image_size, focal, (float(center[0]), float(center[1])), focal_kind=ASSUMED,
                     focal_rule=rule)
    meta["import"].update({
        "source_frames": stems,
        "image_size_from": size_from,
        "focal_from": "img_focal = max(W, H) (est_calib)" if rule else
                      "img_focal chosen by TRAM's SLAM reprojection search (500-1400 px in 100 px steps, or max(W, H))",
        "joints_layout": "smpl24",
        "root_joint": 0,
        "keypoints_2d_layout": None,
        "feet_heads_from": feet_heads_from(None, True),
        "person_ids": "k of hps_track_{k}.npy (TRAM numbers tracks longest first)",
        "camera_motion": {"max_translation_m": round(moved_m, 6), "max_rotation_deg": round(turned_deg, 6)},
        "conventions": "camera frame = OpenCV, metres; vertices = SMPL(pred_rotmat, pred_shape) + pred_trans, each "
                       "frame's own shape; focal = img_focal, principal point = img_center",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"tram": read_tram}
