"""SLAHMR results: the ``*_world_results.npz`` its optimisation phases save, with ``track_info.json``.

Source (vye16/slahmr; file @ the commit read, function):

- ``slahmr/run_opt.py`` @483e946 ``run_opt``, ``main``: phases ``root_fit``, ``smpl_fit``,
  ``smooth_fit``, then ``motion_chunks`` (``motion_fit`` when configured), each in its own folder of
  the run folder, which also holds ``track_info.json`` (``save_track_info``).
- ``slahmr/optim/optimizers.py`` @2cc9262 ``StageOptimizer.save_results``:
  ``np.savez(f"{out_dir}/{seq_name}_{i:06d}_{name}_results.npz", **results)`` for every name of
  ``model.get_optim_result()``; ``run_vis.py`` @08ef916 renders the last iteration
  (``optim/output.py`` @483e946 ``get_results_paths``: ``<seq>_<iteration>_<world|prior>_results.npz``).
- ``slahmr/optim/base_scene.py`` @1da179e ``get_optim_result`` and ``optim/params.py`` @483e946
  ``CameraParams``: ``"world"`` = every optimised parameter (``trans`` (B, T, 3), ``root_orient``
  (B, T, 3), ``latent_pose``, ``betas`` (B, 16), ``world_scale``, ...) plus ``pose_body`` (B, T, 63)
  axis-angle, ``cam_R`` (B, T, 3, 3) and ``cam_t`` (B, T, 3) (``get_cameras``: world -> camera, the
  translation already times ``world_scale``) and ``intrins`` (4,) = (fx, fy, cx, cy) px.
  ``optim/moving_scene.py`` @483e946 ``get_optim_result``: the motion phases overwrite ``trans``,
  ``root_orient``, ``pose_body`` with the rolled-out world trajectories (``rollout_latent_motion``:
  "cam_dict", the inverse of the prior transform) and add ``track_mask`` (B, T); ``"prior"`` is the
  motion prior's canonical frame (not read here).
- Body model: ``util/loaders.py`` @483e946 ``load_smpl_body_model`` (SMPL-H, 16 betas,
  ``confs/config.yaml``: ``body_models/smplh/neutral/model.npz``); ``body_model/utils.py`` @483e946
  ``run_smpl``: ``root_orient``, 21 body joints, no hand pose, ``trans`` added after skinning
  (SMPL's ``transl``).
- Camera: ``geometry/camera.py`` @483e946 ``reproject``: ``X_cam = cam_R X_world + cam_t``,
  ``u = f x / z + c``: OpenCV axes, metres. ``data/dataset.py`` @483e946 ``CameraData.load_data``:
  without SLAM cameras (static) ``cam_R = I``, ``cam_t = 0`` and intrinsics
  ``(F, F, W/2, H/2)`` with ``F = (W + H) / 2``; with ``cameras.npz`` (``preproc/run_slam.py``
  @43d5c9b ``get_hwf``, ``load_intrins``, ``save_cameras``) the same default unless an intrinsics
  file was given (``--intrins_path``, e.g. a dataset's calibration); DROID-SLAM keeps them fixed.
- Tracks: ``track_info.json`` ``tracks`` = ``{track id: {"index": row in B, "vis_mask": [bool per
  image of the data interval]}}``, ``meta`` = ``seq_interval`` (first, last + 1 image of the
  optimised window inside the data interval) and ``data_interval``; ``data/dataset.py``
  ``get_ternary_mask`` and ``vis/tools.py`` @483e946 ``filter_visible_meshes`` (-1 out of the
  scene, 0 occluded, 1 visible).

Conversion:

- Frame ``t`` (``t = 0 .. T-1``, image ``data_interval[0] + seq_interval[0] + t`` of the shot; the
  image names are not stored, so frames are named by that index): every track visible there
  (``vis_mask`` 1: keypoints in that image; occluded frames, where SLAHMR shows its motion prior's
  guess, are left out). Without ``track_info.json``: ``track_mask`` (the track's interval,
  occlusions included), else every track (a warning says which).
- Meshes: SMPL-H(``root_orient``, ``pose_body``, hands at rest, ``betas``) + ``trans`` in the world,
  then ``cam_R[t] X + cam_t[t]``: the camera frame of image ``t``. ``--smpl-model`` is required:
  the file holds parameters only, no joints and no 2D keypoints. An SMPL (24-joint) model is
  accepted as an approximation (its 10 betas, hand joints at rest; a warning says so).
- Focal: ``intrins`` (fx, fy averaged); principal point (cx, cy); image size ``2 (cx, cy)`` (the
  loader's W/2, H/2) unless ``--image-size``. When the focal is SLAHMR's default ``(W + H) / 2`` it is
  declared ``assumed`` with ``focal_rule: slahmr``; otherwise it came from an intrinsics file (or
  ``opt_cams`` optimised it: ``cam_f``, per frame): ``assumed`` without a rule, and a warning says
  to pass ``calibrate --focal`` if it is the camera's own calibration.
- ``person_ids``: SLAHMR's track ids (``track_info.json``), else the row index.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..settings import limits
from ..geometry.camera import world_to_cam
from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.npz import load_npz
from .content import as_array, get
from .files import npz_has_keys
from .frame_names import frame_names
from .frames import people_frame
from .ids import int64_ids
from .image_size import centre_image_size
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces, require_model
from .smpl import BodyModel, joints_to_smpl24, lbs, pose_from_body

__all__ = ["PHASES", "READERS", "find_results", "read_slahmr", "sniff"]

# Phase folders of a run, last optimisation stage first (run_opt order reversed; run_vis renders motion_chunks).
PHASES = ("motion_chunks", "motion_fit", "smooth_fit", "smpl_fit", "root_fit")
_WORLD_SUFFIX = "_world_results.npz"
_PRIOR_SUFFIX = "_prior_results.npz"
_KEYS = {"trans", "root_orient", "pose_body", "betas", "cam_R", "cam_t", "intrins"}
_N_BODY_JOINTS = 21  # pose_body: the 21 body joints after the root (body_model/specs.py SMPL_JOINTS minus the root)
_FOCAL_RTOL = 1e-4  # float32 storage of a focal of ~1000 px: equal to the default rule up to ~0.1 px


# ---- pure helpers (shared with GLAMR, which also stores world bodies and world -> camera poses) ------
# ---- locating the results ------------------------------------------------------------------------
def _iteration(path: Path) -> int:
    """The optimisation step in '<seq>_<step>_world_results.npz' (-1 when the name has none)."""
    parts = path.name.split("_")
    return int(parts[-3]) if len(parts) >= 3 and parts[-3].isdigit() else -1


def _has_keys(path: Path) -> bool:
    """True for an .npz holding SLAHMR's world results and cameras (False for unreadable zips)."""
    try:
        return npz_has_keys(path, _KEYS)
    except (zipfile.BadZipFile, OSError, ValueError):
        return False


def _latest(folder: Path) -> Path | None:
    """The last iteration's world results in ``folder`` (files with SLAHMR's camera keys only)."""
    found = [p for p in folder.glob(f"*{_WORLD_SUFFIX}") if _has_keys(p)]
    return max(found, key=lambda p: (_iteration(p), p.name)) if found else None


def find_results(src: Path) -> Path | None:
    """The world results SLAHMR saved under ``src``: the file itself (checked when read), the last
    iteration in a phase folder, or in a run folder the last iteration of its last phase (:data:`PHASES`)."""
    if src.is_file():
        return src
    if not src.is_dir():
        return None
    found = _latest(src)
    for phase in PHASES:
        if found is not None:
            break
        if (src / phase).is_dir():
            found = _latest(src / phase)
    return found


def sniff(path: Path) -> str | None:
    """'slahmr' for a SLAHMR world results file, phase folder or run folder."""
    found = find_results(path)
    return "slahmr" if found is not None and found.name.endswith(_WORLD_SUFFIX) and _has_keys(found) else None


# ---- tracks ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Tracks:
    """Per track (row of B): its id, and whether it is in each result frame (B, T) bool."""

    ids: np.ndarray  # (B,) int64
    present: np.ndarray  # (B, T) bool
    first_image: int  # index in the shot's images of result frame 0
    source: str  # where presence came from, for meta.yaml


def _track_info_path(results: Path) -> Path | None:
    """track_info.json of the run: next to the phase folder (or the results file)."""
    for folder in (results.parent, results.parent.parent):
        if (folder / "track_info.json").is_file():
            return folder / "track_info.json"
    return None


def _read_track_info(path: Path, n_tracks: int, n_frames: int) -> _Tracks:
    """Track ids and visibility (B, T) from SLAHMR's track_info.json."""
    if path.stat().st_size > limits.current().max_file_bytes:
        raise file_error(path, "larger than limits.max_file_mb")
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise file_error(path, f"not valid JSON ({exc})") from None
    tracks = get(info, "tracks", path)
    meta = get(info, "meta", path)
    try:
        seq_start = int(get(meta, "seq_interval", path)[0])
        data_start = int(get(meta, "data_interval", path)[0])
        rows = {int(get(track, "index", path)): (int(tid), [bool(v) for v in get(track, "vis_mask", path)])
                for tid, track in tracks.items()}
    except (TypeError, ValueError, IndexError, AttributeError, OverflowError):
        raise file_error(path, "malformed 'tracks' or 'meta' (expected SLAHMR's track_info.json)") from None
    if sorted(rows) != list(range(n_tracks)):
        raise file_error(path, f"lists tracks {sorted(rows)}, the results hold {n_tracks} (not the same run?)")
    masks = [rows[i][1] for i in range(n_tracks)]
    if seq_start < 0 or any(len(m) < seq_start + n_frames for m in masks):
        raise file_error(path, f"'vis_mask' shorter than seq_interval start {seq_start} + {n_frames} result frames")
    present = np.array([m[seq_start:seq_start + n_frames] for m in masks], dtype=bool).reshape(n_tracks, n_frames)
    ids = int64_ids([rows[i][0] for i in range(n_tracks)], "track id", path)
    return _Tracks(ids, present, data_start + seq_start, "track_info.json vis_mask (visible frames only)")


def _tracks(results: Path, data: dict, n_tracks: int, n_frames: int, warnings: list[str]) -> _Tracks:
    """Which track is in which frame: track_info.json, else the results' track_mask, else every frame."""
    path = _track_info_path(results)
    if path is not None:
        return _read_track_info(path, n_tracks, n_frames)
    ids = np.arange(n_tracks, dtype=np.int64)
    if "track_mask" in data:
        mask = as_array(data["track_mask"], "track_mask", results, ndim=2, kinds="fiub")
        if mask.shape != (n_tracks, n_frames):
            raise file_error(results, f"'track_mask' must be (B, T) = ({n_tracks}, {n_frames}), got {list(mask.shape)}")
        warnings.append(f"{results}: no track_info.json beside the phase folder: people are imported over their "
                        "whole track interval ('track_mask', occluded frames included) with row indices as ids")
        return _Tracks(ids, mask > 0, 0, "track_mask (track intervals, occlusions included)")
    warnings.append(f"{results}: no track_info.json beside the phase folder and no 'track_mask': every track is "
                    "imported in every frame, with row indices as ids")
    return _Tracks(ids, np.ones((n_tracks, n_frames), dtype=bool), 0, "none (every track in every frame)")


# ---- reading -----------------------------------------------------------------------------------------
def _per_frame(arr: np.ndarray, name: str, source: Path, n_frames: int, trailing: tuple[int, ...]) -> np.ndarray:
    """A camera array stored (T', *trailing) or per track (B, T', *trailing) -> (T, *trailing), T' >= T."""
    if arr.ndim == len(trailing) + 2:  # the same camera repeated per track (get_cameras); no track: no person to place
        arr = arr[0] if len(arr) else np.zeros(arr.shape[1:])
    if arr.ndim != len(trailing) + 1 or arr.shape[1:] != trailing or len(arr) < n_frames:
        raise file_error(source, f"'{name}' must be (B, T, {', '.join(map(str, trailing))}) with T >= {n_frames}, "
                                 f"got {list(arr.shape)}")
    return arr[:n_frames]


def _check_model(model: BodyModel | None, source: Path, warnings: list[str]) -> BodyModel:
    """SMPL-H (exact) or SMPL (approximation, with a warning); anything else refused."""
    if model is not None and model.kind == "smpl":  # SMPL-H's body without hands: accepted, said
        warnings.append(f"SLAHMR fits SMPL-H; --smpl-model {model.name} is SMPL: posed with its first "
                        f"{min(16, model.shapedirs.shape[2])} betas and hand joints at rest (an approximation)")
        return model
    return require_model(model, source, "SLAHMR", "smplh")


def _focal(intrins: np.ndarray, cam_f: np.ndarray | None, image_size: tuple[int, int], source: Path,
           warnings: list[str]) -> tuple[float, np.ndarray | None, str | None]:
    """(focal px, per-frame focal (T,) or None, focal rule or None) of SLAHMR's intrinsics."""
    fx, fy, cx, cy = (float(v) for v in intrins)
    per_frame = None
    if cam_f is not None and not np.allclose(cam_f, [fx, fy], rtol=_FOCAL_RTOL):
        per_frame = cam_f.mean(axis=1)
    rule_focal = focal_from_rule("slahmr", image_size)
    centred = np.allclose([2 * cx, 2 * cy], image_size, atol=1.0)
    if per_frame is None and centred and np.allclose([fx, fy], rule_focal, rtol=_FOCAL_RTOL):
        return 0.5 * (fx + fy), None, "slahmr"
    origin = ("optimised per frame (opt_cams: 'cam_f')" if per_frame is not None
              else "given to SLAHMR (an intrinsics file)")
    warnings.append(f"{source}: focal {0.5 * (fx + fy):.1f} px is not SLAHMR's default (W + H) / 2 = {rule_focal:.1f} "
                    f"px: {origin}; declared assumed; pass calibrate --focal if it is your camera's calibration")
    return 0.5 * (fx + fy), per_frame, None


@dataclass(frozen=True)
class _Params:
    """SLAHMR's world results, validated: B tracks over T frames."""

    trans: np.ndarray  # (B, T, 3) SMPL-H transl, world, metres
    root_orient: np.ndarray  # (B, T, 3) axis-angle, world
    pose_body: np.ndarray  # (B, T, 63) axis-angle, body joints 1..21
    betas: np.ndarray  # (B, S)
    cam_R: np.ndarray  # (T, 3, 3) world -> camera
    cam_t: np.ndarray  # (T, 3) world -> camera, metres
    intrins: np.ndarray  # (4,) fx, fy, cx, cy px
    cam_f: np.ndarray | None  # (T, 2) px when SLAHMR optimised the focal (opt_cams)


def _params(data: dict, path: Path) -> _Params:
    """Validate the arrays of a world results file (shapes named in each refusal)."""
    missing = sorted(_KEYS - set(data))
    if missing:
        raise file_error(path, f"not SLAHMR world results with cameras (missing {', '.join(missing)})")
    trans = as_array(data["trans"], "trans", path, ndim=3, last=(3,))
    n_tracks, n_frames = trans.shape[:2]
    root_orient = as_array(data["root_orient"], "root_orient", path, ndim=3, last=(3,))
    pose_body = as_array(data["pose_body"], "pose_body", path)
    if root_orient.shape[:2] != (n_tracks, n_frames) or pose_body.size != n_tracks * n_frames * 3 * _N_BODY_JOINTS:
        raise file_error(path, f"'root_orient' and 'pose_body' must be (B, T, 3) and (B, T, 63) with (B, T) = "
                               f"({n_tracks}, {n_frames}) of 'trans'")
    betas = as_array(data["betas"], "betas", path, ndim=2)
    if len(betas) != n_tracks:
        raise file_error(path, f"'betas' must be (B, S) with B = {n_tracks}, got {list(betas.shape)}")
    intrins = as_array(data["intrins"], "intrins", path).reshape(-1)
    if intrins.size < 4 or intrins.size % 4 or not np.all(np.isfinite(intrins[:4])) or np.any(intrins[:4] <= 0):
        raise file_error(path, "'intrins' must hold positive (fx, fy, cx, cy)")
    cam_f = None
    if "cam_f" in data:
        cam_f = _per_frame(as_array(data["cam_f"], "cam_f", path), "cam_f", path, n_frames, (2,))
    return _Params(trans, root_orient, pose_body.reshape(n_tracks, n_frames, 3 * _N_BODY_JOINTS), betas,
                   _per_frame(as_array(data["cam_R"], "cam_R", path), "cam_R", path, n_frames, (3, 3)),
                   _per_frame(as_array(data["cam_t"], "cam_t", path), "cam_t", path, n_frames, (3,)),
                   intrins[:4], cam_f)


def read_slahmr(src: Path, opts: ImportOptions) -> ImportedSequence:
    """SLAHMR world results (file, phase folder or run folder) -> contract frames in each image's camera."""
    path = find_results(src)
    if path is None:
        raise file_error(src, f"no SLAHMR *{_WORLD_SUFFIX} with cameras (cam_R, cam_t, intrins) found: give the file, "
                              "a phase folder (e.g. motion_chunks/) or the run folder")
    if path.name.endswith(_PRIOR_SUFFIX):
        raise file_error(path, "SLAHMR's motion-prior results are in the prior's canonical frame: import the "
                               f"matching *{_WORLD_SUFFIX} instead")
    data = load_npz(path, keys=_KEYS | {"track_mask", "cam_f"})  # other members are never read
    params = _params(data, path)
    warnings: list[str] = []
    model = _check_model(opts.body_model, path, warnings)
    n_tracks, n_frames = params.trans.shape[:2]
    tracks = _tracks(path, data, n_tracks, n_frames, warnings)

    intrins = params.intrins
    image_size = opts.image_size or centre_image_size(intrins[2], intrins[3], path, "'intrins' (cx, cy)")
    focal, focal_per_frame, rule = _focal(intrins, params.cam_f, image_size, path, warnings)
    principal_point = (float(intrins[2]), float(intrins[3]))
    faces = model_faces(model, model.n_verts)
    names = frame_names([f"{tracks.first_image + t:06d}" for t in range(n_frames)], warnings)

    def build(index: int, notes: FrameNotes) -> Frame:
        keep = np.flatnonzero(tracks.present[:, index])
        pose = pose_from_body(params.root_orient[keep, index], params.pose_body[keep, index], model.n_joints)
        verts_world, joints_world = lbs(model, params.betas[keep], pose, params.trans[keep, index])
        R_cam_from_world, t_cam_from_world = params.cam_R[index], params.cam_t[index]
        verts_cam = world_to_cam(verts_world, R_cam_from_world, t_cam_from_world)
        joints_cam, _ = joints_to_smpl24(world_to_cam(joints_world, R_cam_from_world, t_cam_from_world))
        extra = {} if focal_per_frame is None else {"focal_length": np.float64(focal_per_frame[index])}
        return people_frame(names[index], f"{path} [frame {index}]", notes.warnings, vertices=verts_cam,
                            joints=joints_cam, person_ids=tracks.ids[keep], faces=faces, n_verts=model.n_verts,
                            extra=extra)

    meta = base_meta("slahmr", path, opts, image_size, None if focal_per_frame is not None else focal, principal_point,
                     focal_kind=ASSUMED, focal_rule=rule)
    meta["import"].update({
        "source_frames": names,
        "image_size_from": ("--image-size" if opts.image_size
                            else "2 x principal point (SLAHMR's intrins cx, cy = W/2, H/2)"),
        "joints_layout": joints_to_smpl24(np.zeros((0, model.n_joints, 3)))[1],
        "root_joint": 0,
        "keypoints_2d_layout": None,
        "feet_heads_from": feet_heads_from(None, True),
        "person_ids": f"SLAHMR track ids; people per frame from {tracks.source}",
        "conventions": "camera frame = OpenCV, metres; vertices = cam_R[t] (SMPL-H(root_orient, pose_body, betas) "
                       "+ trans) + cam_t[t] (world -> camera of image t); focal = intrins (SLAHMR default (W + H) / 2); "
                       "frames named by image index in the shot (image names are not stored)",
    })

    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"slahmr": read_slahmr}
