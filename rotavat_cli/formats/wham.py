"""WHAM (``--from wham``): the ``wham_output.pkl`` that ``demo.py --save_pkl`` writes.

Source: yohanshin/WHAM @2b54f77 ``demo.py`` (``run``: ``results = defaultdict(dict)`` filled per
track, ``joblib.dump(results, 'wham_output.pkl')``), ``lib/models/smpl.py`` (``SMPL.get_output``:
the hip-centred ``offset``; ``convert_pare_to_full_img_cam``, ``full_perspective_projection``),
``lib/models/wham.py`` (``Network.forward_smpl``: ``trans_cam = output.full_cam``),
``lib/data/datasets/dataset_custom.py`` (``CustomDataset``: the intrinsics), ``lib/utils/imutils.py``
(``compute_cam_intrinsics``), ``lib/vis/run_vis.py`` (``run_vis_on_demo``: renders ``verts`` as they
are with that camera).

- File: a joblib dump of a ``defaultdict`` keyed by track id; per track, N = the frames it was
  seen in: ``pose`` (N, 72) SMPL axis-angle, global orientation in the camera frame; ``trans``
  (N, 3); ``betas`` (N, 10); ``verts`` (N, 6890, 3); ``frame_ids`` (N,) 0-based video frame
  indices; ``pose_world`` / ``trans_world`` (N, 72) / (N, 3): WHAM's own world trajectory (below).
- Frame: ``verts = SMPL(pose, betas) - offset + trans_cam`` and ``trans = trans_cam - offset``
  (``offset`` = the mid-hip of WHAM's joint regressor), so ``verts = SMPL(pose, betas) + trans``:
  ``trans`` is SMPL's ``transl`` in the camera frame. OpenCV axes (``full_perspective_projection``
  divides by z and applies K), metres.
- Focal: ``compute_cam_intrinsics``: f = sqrt(W^2 + H^2), principal point = image centre
  (rule ``cliff``; ``--calib`` only reaches the SLAM, never these intrinsics).
- Image size: not stored (the demo reads it from the video): ``--image-size`` is required.
- Stored: meshes, not joints, no 2D keypoints (ViTPose's are in ``tracking_results.pth``). Joints
  (SMPL-24) come from posing ``--smpl-model`` with ``pose``, ``betas``, ``trans``; without it the
  frames hold the meshes only (feet and heads from their landmarks).
- Frames: one per video frame index seen in any track (frames where WHAM tracked nobody are
  not in the file and not imported), named by that index; ``person_ids`` = track ids.
- Its world, kept as WHAM's claim beside the camera frame (``tool_world_*`` keys, docs/conventions.md):
  ``demo.py`` runs the network with ``return_y_up=True``; ``Network.rollout`` (``lib/models/wham.py``)
  integrates each track's root velocities from zero in its Y-down gravity frame and turns the result by
  ``yup2ydown = R_x(pi)``: ``pose_world[:, :3]`` is the root orientation in a **Y-up** world (gravity
  along -y; ``run_vis_on_demo`` puts the ground at the lowest vertex's y), ``trans_world`` where that
  world puts the mid-hip of ``SMPL.get_output`` (the mean of WHAM's regressor's hips 11 and 12, the
  ``offset``), metres. Each track has its own world: origin at its first frame, heading from its
  first camera-frame root (``CustomDataset``: ``init_root``). ``pose_world[:, 3:]`` repeats ``pose``'s
  body pose and is not kept. With ``--smpl-model`` the pelvis (SMPL joint 0) in WHAM's world is
  ``trans_world`` moved by the body's own pelvis - mid-hip offset, the mid-hip taken as the mean of
  SMPL's hip joints (1, 2): a stand-in for WHAM's regressor, a few centimetres off it.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..geometry.rotations import axis_angle_to_matrix
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .ids import int64_ids
from .image_size import need_image_size
from .imported import Conclusion, FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces
from .row_blocks import RowBlocks, frame_offsets, posing_block_rows
from .smpl import BodyModel, lbs, smpl_param_arrays

__all__ = ["sniff", "read_wham", "READERS"]

_MAX_SNIFF_BYTES = 512 << 20
_POSED_MISMATCH_M = 0.01  # the model reproduces WHAM's own meshes to float32 round-off when it is WHAM's SMPL
_WORLD_KEYS = ("pose_world", "trans_world")
UP_AXIS = (0.0, 1.0, 0.0)  # WHAM's saved world is Y-up (demo.py: return_y_up=True)


def sniff(path: Path) -> str | None:
    """'wham' for a pickle whose values are per-track dicts holding ``frame_ids`` and ``verts``."""
    if not (path.is_file() and path.suffix == ".pkl") or path.stat().st_size > _MAX_SNIFF_BYTES:
        return None
    data = load_file(path)
    if isinstance(data, Mapping) and data and all(
            isinstance(track, Mapping) and "frame_ids" in track and "verts" in track for track in data.values()):
        return "wham"
    return None


def _track_id(key: object, source: Path) -> int:
    """A track key as an int (WHAM's keys are the tracker's integer ids)."""
    if isinstance(key, (bool, np.bool_)) or not isinstance(key, (int, np.integer)):
        raise file_error(source, f"track key {key!r} is not an integer track id")
    return int(int64_ids([int(key)], "track id", source)[0])


def _track_arrays(track: Mapping, source: str, model: BodyModel | None) -> dict[str, np.ndarray]:
    """One track's arrays, validated: verts (N, V, 3), frame_ids (N,), and pose/betas/trans for a model."""
    verts = as_array(get(track, "verts", source), "verts", source, ndim=3, last=(3,))
    frame_ids = as_array(get(track, "frame_ids", source), "frame_ids", source, ndim=1, kinds="iu")
    n_rows = len(verts)
    if len(frame_ids) != n_rows:
        raise file_error(source, f"'frame_ids' has {len(frame_ids)} rows but 'verts' has {n_rows}")
    if n_rows and frame_ids.min() < 0:
        raise file_error(source, "'frame_ids' holds negative frame indices")
    out = {"verts": verts, "frame_ids": frame_ids.astype(np.int64)}
    given = [key for key in _WORLD_KEYS if key in track]
    if given and len(given) < len(_WORLD_KEYS):
        missing = [key for key in _WORLD_KEYS if key not in track]
        raise file_error(source, f"has '{given[0]}' but not '{missing[0]}' (WHAM writes its world trajectory as both)")
    if given:  # WHAM's world, kept beside the camera frame: its root orientations need the camera-frame ones
        for key, width in (("pose", 72), ("pose_world", 72), ("trans_world", 3)):
            out[key] = as_array(get(track, key, source), key, source, ndim=2, last=(width,))
            if len(out[key]) != n_rows:
                raise file_error(source, f"'{key}' has {len(out[key])} rows but 'verts' has {n_rows}")
    if model is not None:
        if verts.shape[1] != model.n_verts:
            raise file_error(source, f"'verts' have {verts.shape[1]} vertices but --smpl-model {model.name} has {model.n_verts}")
        for key, width in (("pose", 72), ("trans", 3)):
            out[key] = as_array(get(track, key, source), key, source, ndim=2, last=(width,))
        out["betas"] = as_array(get(track, "betas", source), "betas", source, ndim=2)
        for key in ("pose", "betas", "trans"):
            if len(out[key]) != n_rows:
                raise file_error(source, f"'{key}' has {len(out[key])} rows but 'verts' has {n_rows}")
    return out


def _rows_by_frame(tracks: dict[int, dict[str, np.ndarray]]) -> dict[int, list[tuple[int, int]]]:
    """Video frame index -> [(track id, row)] in track-id order."""
    rows: dict[int, list[tuple[int, int]]] = {}
    for tid in sorted(tracks):
        for row, frame_id in enumerate(tracks[tid]["frame_ids"].tolist()):
            rows.setdefault(frame_id, []).append((tid, row))
    return rows


def _posed_joints(model: BodyModel, tracks: dict, picks: list[tuple[int, int]],
                  verts_cam: np.ndarray) -> dict[str, np.ndarray]:
    """``picks`` (P rows, any frames) posed on ``model``: ``joints`` (P, 24, 3) SMPL-24 in the camera frame, their
    body-model parameters (:func:`.smpl.smpl_param_arrays`), and ``mismatch_m`` (P,): how far (m) each posed mesh
    lies from WHAM's own ``verts_cam`` (P, V, 3) at worst (0 for a mesh all NaN)."""
    pose = np.stack([tracks[t]["pose"][r] for t, r in picks])
    betas = np.stack([tracks[t]["betas"][r] for t, r in picks])
    trans = np.stack([tracks[t]["trans"][r] for t, r in picks])
    posed_verts, joints = lbs(model, betas, pose, trans)
    params = smpl_param_arrays(model, betas, pose, trans, joints)
    mismatch = np.nanmax(np.linalg.norm(posed_verts - verts_cam, axis=-1), axis=1, initial=0.0)
    return {"joints": joints, **params, "mismatch_m": mismatch}


def _rotvec_matrices(rotvec: np.ndarray) -> np.ndarray:
    """Axis-angle (P, 3) -> rotation matrices (P, 3, 3)."""
    return axis_angle_to_matrix(rotvec, np.linalg.norm(rotvec, axis=-1))


def world_arrays(root_cam: np.ndarray, root_world: np.ndarray, trans_world: np.ndarray,
                 joints_cam: np.ndarray | None) -> dict[str, np.ndarray]:
    """WHAM's world for P people, as frame keys (float64): ``tool_cam_global_orient`` (P, 3) = ``pose[:, :3]``
    (root orientation, camera frame), ``tool_world_global_orient`` (P, 3) = ``pose_world[:, :3]``,
    ``tool_world_transl`` (P, 3) = ``trans_world`` (WHAM's mid-hip in its world), and, given the posed SMPL-24
    ``joints_cam`` (P, 24, 3), ``tool_world_pelvis`` (P, 3): joint 0 in WHAM's world, ``trans_world`` plus the
    pelvis - mid-hip offset turned from the camera into WHAM's world (mid-hip = mean of joints 1 and 2).

    >>> joints = np.zeros((1, 24, 3)); joints[0, 1:3] = [[0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]]   # hips 10 cm below (y down)
    >>> flip = np.array([[np.pi, 0.0, 0.0]])                       # the body upright in a Y-up world, upside down in the camera
    >>> world_arrays(flip, np.zeros((1, 3)), np.array([[1.0, 0.9, 2.0]]), joints)["tool_world_pelvis"].round(6).tolist()
    [[1.0, 1.0, 2.0]]
    """
    out = {"tool_cam_global_orient": np.asarray(root_cam, dtype=np.float64),
           "tool_world_global_orient": np.asarray(root_world, dtype=np.float64),
           "tool_world_transl": np.asarray(trans_world, dtype=np.float64)}
    if joints_cam is not None:
        root_cam_m = _rotvec_matrices(out["tool_cam_global_orient"])
        world_from_cam = _rotvec_matrices(out["tool_world_global_orient"]) @ root_cam_m.transpose(0, 2, 1)
        offset_cam = joints_cam[:, 0] - (joints_cam[:, 1] + joints_cam[:, 2]) / 2.0
        out["tool_world_pelvis"] = out["tool_world_transl"] + np.einsum("pij,pj->pi", world_from_cam, offset_cam)
    return out


def read_wham(src: Path, opts: ImportOptions) -> ImportedSequence:
    """WHAM ``wham_output.pkl`` -> contract frames (camera frame; WHAM's world trajectory kept as ``tool_world_*``)."""
    image_size = need_image_size(opts, src, "WHAM reads it from the video")
    data = load_file(src)
    if not isinstance(data, Mapping) or not data:
        raise file_error(src, "not a WHAM output (expected a non-empty dict of tracks)")
    model = opts.body_model
    check_model_kind(model, src, "WHAM", "smpl")
    tracks: dict[int, dict[str, np.ndarray]] = {}
    for key, track in data.items():
        tid = _track_id(key, src)
        if not isinstance(track, Mapping):
            raise file_error(src, f"track {tid} is not a dict")
        tracks[tid] = _track_arrays(track, f"{src} [track {tid}]", model)
    rows = _rows_by_frame(tracks)
    if not rows:
        raise file_error(src, "no tracked frames (every track is empty)")
    frame_ids = sorted(rows)
    width = max(6, len(str(frame_ids[-1])))
    warnings: list[str] = []
    names = frame_names([f"{i:0{width}d}" for i in frame_ids], warnings)
    faces = model_faces(model, model.n_verts if model is not None else None)
    has_world = all("pose_world" in track for track in tracks.values())
    if not has_world and any("pose_world" in track for track in tracks.values()):
        raise file_error(src, "some tracks have WHAM's world trajectory (pose_world, trans_world) and others not")
    if model is None:
        warnings.append("wham stores meshes but no joints, and no --smpl-model was given: imported meshes only "
                        "(no joints: MPJPE-type metrics are unavailable; pass the SMPL model WHAM used for SMPL-24 joints)")

    table = [pick for frame_id in frame_ids for pick in rows[frame_id]]  # every (track, row), frame by frame
    offsets = frame_offsets([len(rows[frame_id]) for frame_id in frame_ids])

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the table posed at once (frames posed in batches, not one by one)."""
        verts = np.stack([tracks[t]["verts"][r] for t, r in table[start:stop]])
        return {"verts": verts, **_posed_joints(model, tracks, table[start:stop], verts)}

    posed_rows = None if model is None else RowBlocks(len(table), posed, posing_block_rows(model))

    def build(index: int, notes: FrameNotes) -> Frame:
        frame_id = frame_ids[index]
        picks = rows[frame_id]
        source = f"{src} [frame {frame_id}]"
        joints, params = None, {}
        if posed_rows is None:
            verts = np.stack([tracks[t]["verts"][r] for t, r in picks])
        else:
            params = posed_rows.rows(int(offsets[index]), int(offsets[index + 1]))
            verts, joints = params.pop("verts"), params.pop("joints")
            notes.facts["posed_mismatch_m"] = float(np.max(params.pop("mismatch_m"), initial=0.0))
        if has_world:
            pose, pose_world, trans_world = (np.stack([tracks[t][key][r] for t, r in picks])
                                             for key in ("pose", "pose_world", "trans_world"))
            params = {**params, **world_arrays(pose[:, :3], pose_world[:, :3], trans_world, joints)}
        return people_frame(names[index], source, notes.warnings, vertices=verts, joints=joints,
                            person_ids=np.array([t for t, _ in picks], dtype=np.int64), faces=faces,
                            body_params=params or None)

    def conclude(all_notes: list[FrameNotes]) -> Conclusion:
        worst = max((n.facts.get("posed_mismatch_m", 0.0) for n in all_notes), default=0.0)
        found = Conclusion()
        if model is not None:
            found.import_meta["model_vs_wham_verts_max_m"] = round(worst, 6)
            if worst > _POSED_MISMATCH_M:
                found.warnings.append(f"{src}: --smpl-model {model.name} posed with WHAM's pose/betas/trans lies up to "
                                      f"{100 * worst:.1f} cm from WHAM's own meshes (another model or gender?): "
                                      "meshes are WHAM's, joints the model's")
        return found

    focal = focal_from_rule("cliff", image_size)
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)
    meta = base_meta("wham", src, opts, image_size, focal, principal_point, focal_kind=ASSUMED, focal_rule="cliff")
    meta["import"].update({
        "source_frames": [int(i) for i in frame_ids],
        "image_size_from": "--image-size",
        "joints_layout": "smpl24" if model is not None else None,
        "root_joint": 0 if model is not None else None,
        "keypoints_2d_layout": None,
        "feet_heads_from": feet_heads_from(None, True),
        "person_ids": "WHAM track ids",
        "conventions": "camera frame = OpenCV, metres; vertices = WHAM 'verts' (= SMPL(pose, betas) + trans); "
                       "focal = sqrt(W^2 + H^2), principal point = image centre; frames = video frame indices "
                       "with at least one track",
    })
    if has_world:
        meta["tool_world"] = tool_world_meta(model is not None)
    else:
        meta["import"]["tool_world"] = "none: the file has no pose_world / trans_world"
    return ImportedSequence(tuple(names), build, meta, warnings, conclude=conclude)


def tool_world_meta(has_pelvis: bool) -> dict:
    """meta.yaml's ``tool_world`` block of a WHAM import: what its ``tool_world_*`` keys are."""
    return {
        "tool": "wham",
        "up_axis": list(UP_AXIS),
        "units": "m",
        "frame": "WHAM's world (demo.py, return_y_up=True): Y up, gravity along -y; one world per track, origin "
                 "and heading from its first frame",
        "global_orient": "pose_world[:, :3], root orientation (axis-angle); tool_cam_global_orient = pose[:, :3]",
        "transl": "trans_world: WHAM's mid-hip (its regressor's hips 11, 12), not SMPL's transl",
        "pelvis": "SMPL joint 0: trans_world + (pelvis - mid-hip of SMPL's hip joints 1, 2) turned into WHAM's world"
                  if has_pelvis else None,
        "ground": "not stored; WHAM's renderer puts it at the lowest vertex of the track",
    }


READERS = {"wham": read_wham}
