"""PromptHMR (``scripts/demo_video.py``, ``--static_camera`` for a static camera): ``results/<video>/results.pkl``.

Source: yufu-wang/PromptHMR @1dd6453 ``scripts/demo_video.py`` (``Pipeline(static_cam=static_camera)``,
``save_only_essential=True``); @d8f4031 ``pipeline/pipeline.py`` (``Pipeline.__call__``: ``joblib.dump(self.results,
f'{seq_folder}/results.pkl')`` after ``cvt_to_numpy``, then the Meshcapade scene ``world4d.mcs`` copied to
``world4d.glb``; ``camera_motion_estimation``: static camera: ``cam_int = est_calib(images)``, ``pred_cam_R`` the
identity and ``pred_cam_T`` zero per frame, ``camera = {'pred_cam_R', 'pred_cam_T', 'img_focal': cam_int[0],
'img_center': cam_int[2:]}``), ``pipeline/tools.py`` (``est_calib``: focal = max(H, W), centre = (W/2, H/2)
of the frames), ``pipeline/utils.py`` (``load_video_frames``: videos taller than ``max_height`` = 896 px are resized
to 896 px, at most ``max_fps`` = 60 fps), ``pipeline/phmr_vid.py`` (``PromptHMR_Video.run``: ``smplx_cam = {'rotmat'
(N, 55, 3, 3), 'pose' (N, 75) = [global_orient, body_pose (63), 9 zeros], 'shape' (N, 10), 'trans' (N, 3),
'contact', 'static_conf_logits'}``, from ``pred_smpl_params_incam`` of its GVHMR-style video head run with
``K_fullimg`` = (img_focal, img_center)), ``pipeline/world.py`` (``world_hps_estimation``: ``smplx_world = {'pose'
(N, 165), 'shape' (N, 10) the track's mean, 'trans' (N, 3)}``, ``camera_world``), ``pipeline/postprocessing.py``
(``post_optimization``: refines ``smplx_world.trans`` and the world camera against the 2D keypoints; ``smplx_cam``
unchanged), ``pipeline/mcs_export_cam.py`` (the scene: ``smplx_world`` bodies, 22 joints and the mean shape, and
the camera), ``pipeline/config.yaml`` (``use_spec_calib: true``, ``run_post_opt: true``, ``hand_pose: false``).

- File: a joblib pickle (read with the restricted unpickler) of ``{'camera': {...}, 'people': {track id: {'frames'
  (N,), 'bboxes' (N, 4) xyxy px, 'track_id', 'smplx_cam', 'smplx_world', ...}}, 'camera_world': {...}, ...}``;
  several people, ``person_ids`` = the ``people`` keys (SAM2 object ids from 1, or ByteTrack ids). The Meshcapade
  scene beside it (``world4d.mcs``/``.glb``) exports ``smplx_world`` and ``camera_world`` (22 body joints, the
  mean shape): the pickle holds all of it and the camera-frame bodies besides, so only the pickle is read.
- Frame: ``SMPL-X(smplx_cam.pose[:3], smplx_cam.pose[3:66], shape) + trans`` is the camera frame (OpenCV axes,
  metres), each frame's own shape. Jaw, eyes and hands at rest: PromptHMR gives none (zeros; its SMPL-X uses
  ``flat_hand_mean=True``, flat hands as here).
- Its world, kept as PromptHMR's claim beside the camera frame (``tool_world_*`` keys): one world shared by every
  person: the first frame's camera turned by SPEC's pitch and roll (``use_spec_calib``; the identity and zero
  camera motion with ``--static_camera``), then by ``R_x(pi)`` to **Y up** (x right, z toward the camera), the
  floor it fits to the people's lowest vertices (``fit_floor_height``, RANSAC) at y = 0, x = z = 0 under the
  camera; ``post_optimization`` then refines each ``trans`` (and the world camera) against the 2D keypoints.
  ``smplx_world.pose[:, :3]`` is the root there, ``trans`` SMPL-X's ``transl`` with the track's mean shape, so the
  pelvis is ``J0(shape) + trans`` exactly.
- Focal: ``img_focal`` and ``img_center``, the ones ``smplx_cam`` was made with, on the frames PromptHMR ran on.
  ``est_calib``'s max(W, H) with ``--static_camera`` (rule ``tram``, TRAM's: the same authors' code); else its SLAM's
  calibration, or the user's ``calib`` / ``focal`` (no rule). A guess either way: ``focal_kind: assumed``.
- Image size: 2 x ``img_center`` (the centre of its frames, up to 896 px high); ``--image-size`` of the original
  video (a resize of those frames) carries the focal, principal point and boxes to it (the 3D is unchanged).
- Frames: those PromptHMR processed (``len(pred_cam_R)``), named by index; a moving SLAM camera is warned of.
- 2D: ``bboxes`` (the tracker's boxes, on its frames) as ``boxes_2d``: evidence the meshes fit the image.
- Parameters only: vertices and joints need ``--smpl-model`` (SMPL-X); joints are SMPL-X's mapped to SMPL-24.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule, focal_px_at_size
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .ids import check_frame_range, int64_ids
from .image_size import centre_image_size
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces, require_model
from .row_blocks import RowBlocks, frame_offsets, posing_block_rows
from .smpl import BodyModel, joints_to_smpl24, lbs, pose_from_body, smpl_param_arrays

__all__ = ["sniff", "read_prompthmr", "world_arrays", "tool_world_meta", "READERS"]

_RESULTS = "results.pkl"
_MAX_SNIFF_BYTES = 512 << 20
_RULE_RTOL = 1e-6
_MOVING_M, _MOVING_DEG = 1e-3, 0.05  # SLAM motion under these is a static camera (--static_camera writes exact zeros)
UP_AXIS = (0.0, 1.0, 0.0)  # PromptHMR's world is Y-up (world.py: R_x(pi) of its gravity-rectified camera)


def _results_file(path: Path) -> Path | None:
    """The results file of ``path``: itself (a .pkl file), or ``results.pkl`` inside a folder."""
    if path.is_dir():
        path = path / _RESULTS
    return path if path.is_file() and path.suffix == ".pkl" else None


def _is_prompthmr(data: object) -> bool:
    return (isinstance(data, Mapping) and isinstance(data.get("people"), Mapping)
            and isinstance(data.get("camera"), Mapping) and all(isinstance(t, Mapping) and "smplx_cam" in t and "frames" in t for t in data["people"].values()))


def sniff(path: Path) -> str | None:
    """'prompthmr' for a pickle (or a folder's ``results.pkl``) holding ``camera`` and ``people`` whose tracks have
    ``frames`` and ``smplx_cam``."""
    file = _results_file(path)
    if file is None or file.stat().st_size > _MAX_SNIFF_BYTES:
        return None
    return "prompthmr" if _is_prompthmr(load_file(file)) else None


# ---- what the file holds, checked ---------------------------------------------------------------------
def _scalar(value: object, name: str, source: Path) -> float:
    """``img_focal``: a number, a numpy scalar (est_calib's ``np.max``) or a one-element array."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
        value = np.asarray(value)
    array = as_array(value, name, source).reshape(-1)
    if array.size != 1 or not np.isfinite(array[0]) or array[0] <= 0:
        raise file_error(source, f"'{name}' must be one positive focal length (px)")
    return float(array[0])


def _camera(data: Mapping, path: Path) -> dict:
    """``camera``: img_focal px, img_center (2,) px, pred_cam_R (T, 3, 3) and pred_cam_T (T, 3) or None."""
    camera = get(data, "camera", path)
    focal = _scalar(get(camera, "img_focal", path), "camera.img_focal", path)
    center = as_array(get(camera, "img_center", path), "camera.img_center", path).reshape(-1).astype(np.float64)
    if center.size != 2 or not np.all(np.isfinite(center)) or np.any(center <= 0):
        raise file_error(path, "'camera.img_center' must be two positive pixel coordinates")
    rotation, translation = camera.get("pred_cam_R"), camera.get("pred_cam_T")
    rotation = None if rotation is None else as_array(rotation, "camera.pred_cam_R", path, ndim=3, last=(3, 3))
    translation = None if translation is None else as_array(translation, "camera.pred_cam_T", path, ndim=2, last=(3,))
    return {"focal": focal, "center": center, "R": rotation, "T": translation}


def _params(group: object, name: str, source: str, n_rows: int, pose_width: int) -> dict[str, np.ndarray]:
    """``smplx_cam`` or ``smplx_world``: pose (N, >= pose_width) axis-angle, shape (N, B), trans (N, 3)."""
    if not isinstance(group, Mapping):
        raise file_error(source, f"'{name}' is not a dict of parameters")
    out = {"pose": as_array(get(group, "pose", source), f"{name}.pose", source, ndim=2),
           "shape": as_array(get(group, "shape", source), f"{name}.shape", source, ndim=2),
           "trans": as_array(get(group, "trans", source), f"{name}.trans", source, last=(3,)).reshape(-1, 3)}
    if out["pose"].shape[1] < pose_width:
        raise file_error(source, f"'{name}.pose' must be (N, {pose_width} or more) axis-angle, "
                                 f"got {list(out['pose'].shape)}")
    for key, array in out.items():
        if len(array) != n_rows:
            raise file_error(source, f"'{name}.{key}' has {len(array)} rows, 'frames' {n_rows}")
    return out


def _track(track: object, source: str) -> dict:
    """One track, checked: frames (N,), cam (smplx_cam), world (smplx_world) or None, boxes (N, 4) or None."""
    if not isinstance(track, Mapping):
        raise file_error(source, "is not a dict")
    frames = as_array(get(track, "frames", source), "frames", source, ndim=1, kinds="iu")
    n_rows = len(frames)
    if n_rows and (frames.min() < 0 or len(np.unique(frames)) != n_rows):
        raise file_error(source, "'frames' must hold distinct, non-negative frame indices")
    out = {"frames": frames.astype(np.int64), "world": None, "boxes": None,
           "cam": _params(get(track, "smplx_cam", source), "smplx_cam", source, n_rows, 66)}
    if track.get("smplx_world") is not None:
        out["world"] = _params(track["smplx_world"], "smplx_world", source, n_rows, 3)
    boxes = track.get("bboxes")
    if boxes is not None:
        boxes = as_array(boxes, "bboxes", source, ndim=2, last=(4,))
        if len(boxes) != n_rows:
            raise file_error(source, f"'bboxes' has {len(boxes)} rows, 'frames' {n_rows}")
        out["boxes"] = boxes
    return out


def _tracks(data: Mapping, path: Path) -> dict[int, dict]:
    """``people``: track id -> :func:`_track`."""
    people = get(data, "people", path)
    if not isinstance(people, Mapping) or not people:
        raise file_error(path, "'people' must be a non-empty dict of tracks")
    tracks = {}
    for key, track in people.items():
        if isinstance(key, (bool, np.bool_)) or not isinstance(key, (int, np.integer)):
            raise file_error(path, f"track key {key!r} is not an integer track id")
        tid = int(int64_ids([int(key)], "track id", path)[0])
        tracks[tid] = _track(track, f"{path} [track {tid}]")
    return tracks


def _motion(rotation: np.ndarray | None, translation: np.ndarray | None) -> tuple[float, float]:
    """Largest SLAM camera translation (m) and rotation (deg) away from the first frame's."""
    moved_m = 0.0
    if translation is not None and len(translation):
        moved_m = float(np.max(np.linalg.norm(translation - translation[:1], axis=1)))
    turned_deg = 0.0
    if rotation is not None and len(rotation):
        cosine = (np.trace(np.einsum("ji,tjk->tik", rotation[0], rotation), axis1=1, axis2=2) - 1.0) / 2.0
        turned_deg = float(np.degrees(np.max(np.arccos(np.clip(cosine, -1.0, 1.0)))))
    return moved_m, turned_deg


def _intrinsics(camera: dict, opts: ImportOptions, path: Path,
                warnings: list[str]) -> tuple[tuple[int, int], float, np.ndarray, float, str]:
    """(image size, focal px, principal point (2,) px, scale from PromptHMR's frames to that size, where the size
    came from). ``--image-size`` of a resize of PromptHMR's frames (2 x img_center: the original video) carries
    the intrinsics to it."""
    focal, center = camera["focal"], camera["center"]
    if opts.image_size is None:
        size = centre_image_size(center[0], center[1], path, "'camera.img_center'")
        return size, focal, center, 1.0, "2 x camera.img_center (est_calib: the centre of the frames PromptHMR ran on)"
    size = opts.image_size
    frames_size = (max(1, round(2 * center[0])), max(1, round(2 * center[1])))
    if frames_size == tuple(size):
        return size, focal, center, 1.0, "--image-size"
    try:
        scale = focal_px_at_size(1.0, frames_size, size)
    except ValueError:
        warnings.append(f"{path}: img_center {center.tolist()} is not the centre of the {size[0]}x{size[1]} image "
                        "(--image-size) nor of a resize of it; kept as the principal point")
        return size, focal, center, 1.0, "--image-size"
    warnings.append(f"{path}: PromptHMR ran on {frames_size[0]}x{frames_size[1]} frames (2 x img_center; it resizes "
                    f"videos taller than 896 px): its focal, principal point and boxes are carried to --image-size "
                    f"{size[0]}x{size[1]} (x {scale:.6g})")
    return (size, focal * scale, center * scale, scale,
            f"--image-size (PromptHMR's {frames_size[0]}x{frames_size[1]} frames resized)")


# ---- its world --------------------------------------------------------------------------------------
def rest_root(model: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """The model's root joint at rest, linear in the shape: (template (3,), directions (3, S)), so that
    ``J0(betas) = template + directions[:, :B] @ betas`` (SMPL-X: shape columns before 300, as :func:`.smpl.lbs`)."""
    n_shape = min(300, model.shapedirs.shape[2])
    return (model.J_regressor[0] @ model.v_template,
            np.einsum("v,vcs->cs", model.J_regressor[0], model.shapedirs[:, :, :n_shape]))


def world_arrays(root_cam: np.ndarray, root_world: np.ndarray, transl_world: np.ndarray,
                 pelvis_world: np.ndarray | None) -> dict[str, np.ndarray]:
    """PromptHMR's world for P people, as frame keys (float64, (P, 3) each): ``tool_cam_global_orient`` and
    ``tool_world_global_orient`` (the root in the camera and in its world, axis-angle), ``tool_world_transl``
    (SMPL-X's ``transl`` there) and, when given, ``tool_world_pelvis`` (``J0(shape) + transl``).

    >>> keys = world_arrays(np.zeros((1, 3)), np.array([[np.pi, 0.0, 0.0]]), np.ones((1, 3)), None)
    >>> sorted(keys), keys["tool_world_transl"].tolist()
    (['tool_cam_global_orient', 'tool_world_global_orient', 'tool_world_transl'], [[1.0, 1.0, 1.0]])
    """
    out = {"tool_cam_global_orient": np.asarray(root_cam, dtype=np.float64),
           "tool_world_global_orient": np.asarray(root_world, dtype=np.float64),
           "tool_world_transl": np.asarray(transl_world, dtype=np.float64)}
    if pelvis_world is not None:
        out["tool_world_pelvis"] = np.asarray(pelvis_world, dtype=np.float64)
    return out


def tool_world_meta() -> dict:
    """meta.yaml's ``tool_world`` block of a PromptHMR import: what its ``tool_world_*`` keys are."""
    return {
        "tool": "prompthmr",
        "up_axis": list(UP_AXIS),
        "units": "m",
        "frame": "PromptHMR's world (pipeline/world.py), one for every person: the first camera turned by SPEC's pitch "
                 "and roll, then R_x(pi): Y up, x right, z toward the camera; floor at y = 0, x = z = 0 under the camera; "
                 "trans refined by post_optimization",
        "global_orient": "smplx_world.pose[:, :3] (axis-angle); tool_cam_global_orient = smplx_cam.pose[:, :3]",
        "transl": "smplx_world.trans: SMPL-X's transl, with the track's mean shape (smplx_world.shape)",
        "pelvis": "SMPL-X joint 0: J0(smplx_world.shape) + smplx_world.trans",
        "ground": "y = 0: the floor PromptHMR fits to the people's lowest vertices (fit_floor_height, RANSAC)",
    }


# ---- the reader -------------------------------------------------------------------------------------
def read_prompthmr(src: Path, opts: ImportOptions) -> ImportedSequence:
    """PromptHMR ``results.pkl`` (or its folder) -> contract frames (camera frame; its world kept as ``tool_world_*``)."""
    path = _results_file(src)
    if path is None:
        raise file_error(src, f"no PromptHMR results: expected a .pkl file or a folder holding {_RESULTS}")
    data = load_file(path)
    if not isinstance(data, Mapping):
        raise file_error(path, f"not a PromptHMR results.pkl (expected a dict, got {type(data).__name__})")
    camera = _camera(data, path)
    tracks = _tracks(data, path)
    model = opts.body_model
    require_model(model, path, "PromptHMR", "smplx")
    has_world = all(t["world"] is not None for t in tracks.values())
    if not has_world and any(t["world"] is not None for t in tracks.values()):
        raise file_error(path, "some tracks have PromptHMR's world (smplx_world) and others not")
    has_boxes = all(t["boxes"] is not None for t in tracks.values())

    warnings: list[str] = []
    image_size, focal, principal, scale, size_from = _intrinsics(camera, opts, path, warnings)
    rule_focal = focal_from_rule("tram", image_size)
    rule = "tram" if abs(focal - rule_focal) <= _RULE_RTOL * rule_focal else None
    if rule is None:
        warnings.append(f"{path}: img_focal is not est_calib's max(W, H) = {rule_focal:.1f} px (PromptHMR run without "
                        "--static_camera, or with its own calib): kept as the method's own (focal_kind: assumed, "
                        "no focal_rule)")
    moved_m, turned_deg = _motion(camera["R"], camera["T"])
    if moved_m > _MOVING_M or turned_deg > _MOVING_DEG:
        warnings.append(f"{path}: PromptHMR's SLAM found the camera moving (up to {moved_m:.2f} m, {turned_deg:.1f} deg): "
                        "rotavat assumes a static camera; each frame is imported in its own camera frame")

    last = max((int(t["frames"].max()) for t in tracks.values() if len(t["frames"])), default=-1)
    n_rows = sum(len(t["frames"]) for t in tracks.values())
    n_frames = check_frame_range(max(last + 1, 0 if camera["R"] is None else len(camera["R"])), n_rows, path, "frames")
    if n_frames == 0:
        raise file_error(path, "no frames in the results")
    rows_by_frame: dict[int, list[tuple[int, int]]] = {}
    for tid in sorted(tracks):
        for row, frame in enumerate(tracks[tid]["frames"].tolist()):
            rows_by_frame.setdefault(frame, []).append((tid, row))
    layout = joints_to_smpl24(np.zeros((0, model.n_joints, 3)))[1]
    root_template, root_dirs = rest_root(model)
    faces = model_faces(model, model.n_verts)
    width = max(6, len(str(n_frames - 1)))
    names = frame_names([f"{i:0{width}d}" for i in range(n_frames)], warnings)

    table = [pick for index in range(n_frames) for pick in rows_by_frame.get(index, [])]  # (track, row), frame by frame
    offsets = frame_offsets([len(rows_by_frame.get(index, [])) for index in range(n_frames)])

    def stacked(picks: list[tuple[int, int]], group: str, key: str, width: int) -> np.ndarray:
        """``tracks[t][group][key][r]`` of each (t, r) in ``picks``, stacked: (len(picks), ...)."""
        return np.stack([tracks[t][group][key][r] for t, r in picks]) if picks else np.zeros((0, width))

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the table posed at once (frames posed in batches, not one by one): vertices,
        SMPL-24 joints and the SMPL-X parameter keys."""
        picks = table[start:stop]
        cam_pose = stacked(picks, "cam", "pose", 66)
        betas, transl = stacked(picks, "cam", "shape", 10), stacked(picks, "cam", "trans", 3)
        pose = pose_from_body(cam_pose[:, :3], cam_pose[:, 3:66], model.n_joints)
        vertices, joints55 = lbs(model, betas, pose, transl)
        return {"vertices": vertices, "joints": joints_to_smpl24(joints55)[0],
                **smpl_param_arrays(model, betas, pose, transl, joints55)}

    posed_rows = RowBlocks(len(table), posed, posing_block_rows(model))

    def build(index: int, notes: FrameNotes) -> Frame:
        picks = rows_by_frame.get(index, [])
        start, stop = int(offsets[index]), int(offsets[index + 1])
        body = posed_rows.rows(start, stop)
        vertices, joints = body.pop("vertices"), body.pop("joints")
        if has_world:
            world = {key: stacked(picks, "world", key, 3) for key in ("pose", "shape", "trans")}
            n_shape = min(world["shape"].shape[1], root_dirs.shape[1])
            pelvis = root_template + world["shape"][:, :n_shape] @ root_dirs[:, :n_shape].T + world["trans"]
            body.update(world_arrays(stacked(picks, "cam", "pose", 66)[:, :3], world["pose"][:, :3], world["trans"],
                                     pelvis))
        boxes = None
        if has_boxes:
            boxes = np.stack([tracks[t]["boxes"][r] for t, r in picks]) * scale if picks else np.zeros((0, 4))
        return people_frame(names[index], f"{path} [frame {index}]", notes.warnings, vertices=vertices,
                            joints=joints, person_ids=np.array([t for t, _ in picks], np.int64),
                            faces=faces, n_verts=model.n_verts, boxes_2d=boxes, body_params=body)

    meta = base_meta("prompthmr", path, opts, image_size, focal, (float(principal[0]), float(principal[1])),
                     focal_kind=ASSUMED, focal_rule=rule)
    meta["import"].update({
        "source_frames": list(range(n_frames)),
        "image_size_from": size_from,
        "focal_from": "camera.img_focal = max(W, H) (est_calib, --static_camera)" if rule else
                      "camera.img_focal: PromptHMR's SLAM calibration, or its calib / focal setting",
        "frame_indices": "the frames PromptHMR processed (load_video_frames: at most 60 fps)",
        "joints_layout": layout,
        "root_joint": 0,
        "keypoints_2d_layout": None,
        "feet_heads_from": feet_heads_from(None, True),
        "boxes_2d_from": "people[id].bboxes: the tracker's boxes" if has_boxes else None,
        "person_ids": "PromptHMR track ids (the keys of results['people'])",
        "camera_motion": {"max_translation_m": round(moved_m, 6), "max_rotation_deg": round(turned_deg, 6)},
        "conventions": "camera frame = OpenCV, metres; vertices = SMPL-X(smplx_cam.pose[:3], smplx_cam.pose[3:66], "
                       "smplx_cam.shape) + smplx_cam.trans; focal = camera.img_focal, principal point = camera.img_center; "
                       "jaw, eyes and hands at rest (flat hands)",
    })
    if has_world:
        meta["tool_world"] = tool_world_meta()
    else:
        meta["import"]["tool_world"] = "none: the tracks have no smplx_world"
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"prompthmr": read_prompthmr}
