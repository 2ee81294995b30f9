"""GVHMR (``tools/demo/demo.py``): ``hmr4d_results.pt``, a ``torch.save`` of SMPL-X parameters.

Source: zju3dv/GVHMR @cb702cd ``tools/demo/demo.py`` (``load_data_dict``: ``K_fullimg =
estimate_K(width, height).repeat(length, 1, 1)``; ``__main__``: ``torch.save(pred,
paths.hmr4d_results)``; ``render_incam``: ``smplx(**pred["smpl_params_incam"])`` rendered with
``K = pred["K_fullimg"][0]``), ``hmr4d/model/gvhmr/gvhmr_pl_demo.py`` (``DemoPL.predict``: the
keys of ``pred``), ``hmr4d/model/gvhmr/pipeline/gvhmr_pipeline.py`` (``Pipeline.forward``:
``pred_smpl_params_incam`` = ``body_pose`` (63), ``betas`` (10), ``global_orient`` (3),
``transl = compute_transl_full_cam(pred_cam, bbx_xys, K_fullimg)``), ``hmr4d/utils/geo/hmr_cam.py``
(``estimate_focal_length``, ``estimate_K``, ``compute_transl_full_cam``),
``hmr4d/utils/smplx_utils.py`` (``make_smplx("supermotion")``: neutral SMPL-X, 10 betas, hand PCA
with ``flat_hand_mean=False``), ``hmr4d/configs/demo.yaml`` (``paths.hmr4d_results =
outputs/demo/<video>/hmr4d_results.pt``).

- File: a torch zip archive (read by :func:`rotavat_cli.unpickle.torch_files.load_torch`, without torch)
  holding ``{"smpl_params_global": {...}, "smpl_params_incam": {"body_pose" (L, 63),
  "betas" (L, 10), "global_orient" (L, 3), "transl" (L, 3)}, "K_fullimg" (L, 3, 3),
  "net_outputs": {...}}``, L = the video's frames. One person: GVHMR follows the one track of
  ``Tracker.get_one_track`` (``person_ids`` = 0).
- Frame: ``SMPL-X(global_orient, body_pose, betas) + transl`` (``smpl_params_incam``, axis-angle)
  is the camera frame: OpenCV axes, metres.
- Its world, kept as GVHMR's claim beside the camera frame (``tool_world_*`` keys, docs/conventions.md):
  ``smpl_params_global`` holds the same ``body_pose`` and ``betas`` with a world ``global_orient`` and
  ``transl`` (SMPL-X's own ``transl``). ``get_smpl_params_w_Rt_v2`` (``gvhmr_pipeline.py``) builds them in
  the gravity-view frame, whose y axis is gravity (``get_R_c2gv``: ``R_w2c @ axis_gravity``, pointing
  down), and turns them by ``get_tgtcoord_rootparam(..., tsf="any->ay")``, R_z(pi): the saved world is
  **Y-up** ("ay"; ``render_global`` puts the ground at the lowest vertex's y), origin where the
  rollout starts (x = z = 0 at the first frame), heading that of the first frame's gravity-view
  frame (the camera's view axis on the ground). The pelvis in that world is exact: the root turns
  about itself, so it sits at ``J0(betas) + transl``.
- Focal: ``K_fullimg`` = ``estimate_K``: f = sqrt(W^2 + H^2) (the ``cliff`` rule), principal point
  = image centre. It is GVHMR's guess, never the camera's: ``focal_kind: assumed``, with
  ``focal_rule: cliff`` when K equals the rule (a K edited into the demo is kept, without a rule).
- Image size: twice K's principal point (estimate_K puts it at (W/2, H/2)), or ``--image-size``.
- Nothing else is stored: no joints, no 2D keypoints (VitPose's are in ``preprocess/vitpose.pt``),
  so the import needs ``--smpl-model`` (SMPL-X, e.g. ``SMPLX_NEUTRAL.npz``); joints are SMPL-X's
  mapped to SMPL-24. Jaw, eyes and hands are posed at rest with a zero hand pose (flat hands), where
  GVHMR's renderer shows its model's mean hand pose: only finger vertices differ.
- The person's crop box, recovered: ``transl = compute_transl_full_cam(pred_cam, bbx_xys, K_fullimg)``
  (``hmr_cam.py``; ``pred_cam`` = (s, tx, ty) is ``net_outputs.model_output.pred_cam``, ``bbx_xys`` the
  square crop: centre and side, 1.2 x the tracked box, ``get_bbx_xys_from_xyxy``) inverts to side
  ``b = 2 f / (s tz)`` and centre ``(cx, cy) + f (transl_xy - (tx, ty)) / tz`` (GVHMR's
  ``get_a_pred_cam`` solves the same equations for ``pred_cam``). Written as ``boxes_2d`` [x1, y1,
  x2, y2] px: the only 2D evidence the file holds that the meshes, posed with ``--smpl-model``, land
  where GVHMR saw the person (:mod:`.model_fit`). Without ``pred_cam`` no boxes are written.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.torch_files import load_torch
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .image_size import centre_image_size
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces, require_model
from .row_blocks import RowBlocks, posing_block_rows
from .smpl import joints_to_smpl24, lbs, pose_from_body, smpl_param_arrays

_RESULTS = "hmr4d_results.pt"
_PARAMS = ("global_orient", "body_pose", "betas", "transl")
_RULE_RTOL = 1e-5  # K is float32: the rule's focal comes back within a few 1e-7 of itself
UP_AXIS = (0.0, 1.0, 0.0)  # GVHMR's saved world ("ay") is Y-up


def _results_file(path: Path) -> Path | None:
    """The results file of ``path``: itself (a .pt/.pth file), or ``hmr4d_results.pt`` inside a folder."""
    if path.is_dir():
        path = path / _RESULTS
    return path if path.is_file() and path.suffix in (".pt", ".pth") else None


def sniff(path: Path) -> str | None:
    """'gvhmr' for a torch archive whose pickle names ``smpl_params_incam`` and ``K_fullimg`` (read
    from the zip's ``data.pkl`` record alone: no tensor is loaded)."""
    file = _results_file(path)
    if file is None or not zipfile.is_zipfile(file):
        return None
    with zipfile.ZipFile(file) as archive:
        pickles = [info for info in archive.infolist() if info.filename.count("/") == 1 and info.filename.endswith("/data.pkl")]
        if len(pickles) != 1 or pickles[0].file_size > 16 << 20:
            return None
        text = archive.read(pickles[0])
    return "gvhmr" if b"smpl_params_incam" in text and b"K_fullimg" in text else None


def _per_frame(value: object, name: str, source: Path, width: int, group: str = "smpl_params_incam") -> np.ndarray:
    """A parameter as (L, width): GVHMR's (L, width), or with the batch axis (1, L, width) of ``net_outputs``."""
    array = as_array(value, f"{group}.{name}", source)
    if array.ndim == 3 and array.shape[0] == 1:
        array = array[0]
    if array.ndim != 2 or array.shape[1] < width:
        raise file_error(source, f"'{group}.{name}' must be (L, {width}), got {list(array.shape)}")
    return array


def _world_params(data: Mapping, source: Path, n_frames: int) -> dict[str, np.ndarray] | None:
    """``smpl_params_global``'s ``global_orient`` and ``transl`` as (L, 3), or None when the file has none."""
    world = data.get("smpl_params_global")
    if world is None:
        return None
    if not isinstance(world, Mapping):
        raise file_error(source, "'smpl_params_global' is not a dict of parameters")
    out = {name: _per_frame(get(world, name, source), name, source, 3, "smpl_params_global")[:, :3]
           for name in ("global_orient", "transl")}
    for name, array in out.items():
        if len(array) != n_frames:
            raise file_error(source, f"'smpl_params_global.{name}' has {len(array)} frames, 'transl' {n_frames}")
    return out


def world_arrays(root_cam: np.ndarray, transl_cam: np.ndarray, root_world: np.ndarray, transl_world: np.ndarray,
                 pelvis_cam: np.ndarray) -> dict[str, np.ndarray]:
    """GVHMR's world for P people, as frame keys (float64, (P, 3) each): ``tool_cam_global_orient`` and
    ``tool_world_global_orient`` (the root in the camera and in GVHMR's world, axis-angle), ``tool_world_transl``
    (SMPL-X's ``transl`` there) and ``tool_world_pelvis``: the root joint, ``pelvis_cam - transl_cam + transl_world``
    (the root turns about itself, so ``J0(betas)`` is the same offset in both frames).

    >>> keys = world_arrays(np.zeros((1, 3)), np.array([[0.0, 0.4, 4.0]]), np.zeros((1, 3)), np.array([[0.0, 1.3, 0.0]]),
    ...                     np.array([[0.0, 0.05, 4.0]]))
    >>> keys["tool_world_pelvis"].round(6).tolist()
    [[0.0, 0.95, 0.0]]
    """
    transl_world = np.asarray(transl_world, dtype=np.float64)
    return {"tool_cam_global_orient": np.asarray(root_cam, dtype=np.float64),
            "tool_world_global_orient": np.asarray(root_world, dtype=np.float64),
            "tool_world_transl": transl_world,
            "tool_world_pelvis": np.asarray(pelvis_cam, dtype=np.float64) - np.asarray(transl_cam, dtype=np.float64) + transl_world}


def tool_world_meta() -> dict:
    """meta.yaml's ``tool_world`` block of a GVHMR import: what its ``tool_world_*`` keys are."""
    return {
        "tool": "gvhmr",
        "up_axis": list(UP_AXIS),
        "units": "m",
        "frame": "GVHMR's world (smpl_params_global, 'ay'): Y up; origin at the first frame's x = z = 0, heading "
                 "of the first frame's gravity-view frame",
        "global_orient": "smpl_params_global.global_orient (axis-angle); tool_cam_global_orient = "
                         "smpl_params_incam.global_orient",
        "transl": "smpl_params_global.transl: SMPL-X's transl",
        "pelvis": "SMPL-X joint 0: J0(betas) + smpl_params_global.transl",
        "ground": "not stored; GVHMR's renderer puts it at the lowest vertex of the sequence",
    }


def _intrinsics(K: np.ndarray, opts: ImportOptions, source: Path,
                warnings: list[str]) -> tuple[tuple[int, int], np.ndarray, np.ndarray, str]:
    """(image size, focal per frame (L,), principal point per frame (L, 2), where the size came from)."""
    focal = (K[:, 0, 0] + K[:, 1, 1]) / 2.0
    principal = K[:, :2, 2]
    if not (np.all(np.isfinite(K)) and np.all(focal > 0) and np.all(principal > 0)):
        raise file_error(source, "'K_fullimg' must hold positive, finite focal lengths and principal points")
    if np.any(np.abs(K[:, 0, 0] - K[:, 1, 1]) > 1e-6 * focal):
        warnings.append(f"{source}: K_fullimg has fx != fy; using their mean")
    centre = np.median(principal, axis=0)
    stored = centre_image_size(centre[0], centre[1], source, "K_fullimg's principal point") \
        if opts.image_size is None else tuple(round(2 * float(c)) for c in centre)
    if opts.image_size is not None:
        if stored != opts.image_size:
            warnings.append(f"{source}: --image-size {opts.image_size[0]}x{opts.image_size[1]} differs from the "
                            f"{stored[0]}x{stored[1]} of K_fullimg's principal point; using --image-size")
        return opts.image_size, focal, principal, "--image-size"
    return (stored[0], stored[1]), focal, principal, "K_fullimg principal point (estimate_K: the image centre)"


def crop_boxes_px(pred_cam: np.ndarray, transl: np.ndarray, K: np.ndarray) -> np.ndarray:
    """GVHMR's square crops (L, 4) [x1, y1, x2, y2] px from its weak-perspective cameras ``pred_cam`` (L, 3)
    (s, tx, ty), the translations they made ``transl`` (L, 3) m and ``K`` (L, 3, 3), inverting
    ``compute_transl_full_cam``; NaN rows where ``s tz`` is not positive and finite.

    >>> K = np.array([[[1000.0, 0, 320], [0, 1000.0, 240], [0, 0, 1]]])
    >>> crop_boxes_px(np.array([[0.8, 0.1, 0.2]]), np.array([[0.6, 0.7, 5.0]]), K).round(1).tolist()
    [[170.0, 90.0, 670.0, 590.0]]
    """
    s, t_xy = pred_cam[:, 0], pred_cam[:, 1:3]
    focal, principal = K[:, 0, 0], K[:, :2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        side = 2.0 * focal / (s * transl[:, 2])
        centre = principal + focal[:, None] * (transl[:, :2] - t_xy) / transl[:, 2:3]
    boxes = np.concatenate([centre - side[:, None] / 2.0, centre + side[:, None] / 2.0], axis=1)
    boxes[~(np.isfinite(boxes).all(axis=1) & (side > 0))] = np.nan
    return boxes


def _pred_cam(data: Mapping, n_frames: int) -> np.ndarray | None:
    """``net_outputs.model_output.pred_cam`` as (L, 3), or None when the file does not hold it as such."""
    value: object = data
    for key in ("net_outputs", "model_output", "pred_cam"):
        value = value.get(key) if isinstance(value, Mapping) else None
    if not isinstance(value, np.ndarray) or value.dtype.kind != "f":
        return None
    array = value[0] if value.ndim == 3 and value.shape[0] == 1 else value
    return array.astype(np.float64) if array.shape == (n_frames, 3) else None


def read_gvhmr(src: Path, opts: ImportOptions) -> ImportedSequence:
    """GVHMR ``hmr4d_results.pt`` (or its output folder) -> contract frames, one person per frame."""
    path = _results_file(src)
    if path is None:
        raise file_error(src, f"no GVHMR results: expected a .pt file or a folder holding {_RESULTS}")
    data = load_torch(path)
    incam = get(data, "smpl_params_incam", path)
    if not isinstance(incam, Mapping):
        raise file_error(path, "'smpl_params_incam' is not a dict of parameters")
    params = {name: _per_frame(get(incam, name, path), name, path, width)
              for name, width in (("global_orient", 3), ("body_pose", 63), ("betas", 1), ("transl", 3))}
    K = as_array(get(data, "K_fullimg", path), "K_fullimg", path, last=(3, 3))
    n_frames = len(params["transl"])
    K = np.broadcast_to(K.reshape(-1, 3, 3), (n_frames, 3, 3)) if K.size == 9 else K.reshape(-1, 3, 3)
    for name, array in [*params.items(), ("K_fullimg", K)]:
        if len(array) != n_frames:
            raise file_error(path, f"'{name}' has {len(array)} frames, 'transl' {n_frames}")
    if n_frames == 0:
        raise file_error(path, "no frames in the results")
    world = _world_params(data, path, n_frames)

    warnings: list[str] = []
    image_size, focal, principal, size_from = _intrinsics(K, opts, path, warnings)
    constant = bool(np.ptp(focal) <= 1e-6 * focal.max() and np.ptp(principal, axis=0).max() <= 1e-6)
    rule_focal = focal_from_rule("cliff", image_size)
    rule = "cliff" if constant and abs(float(focal[0]) - rule_focal) <= _RULE_RTOL * rule_focal else None
    if rule is None:
        warnings.append(f"{path}: K_fullimg is not GVHMR's estimate_K (f = sqrt(W^2 + H^2) = {rule_focal:.1f} px): "
                        "its focal is kept as the method's own (focal_kind: assumed, no focal_rule)")

    pred_cam = _pred_cam(data, n_frames)
    boxes = None if pred_cam is None else crop_boxes_px(pred_cam, params["transl"][:, :3], K.astype(np.float64))
    model = opts.body_model
    require_model(model, path, "GVHMR", "smplx")
    layout = joints_to_smpl24(np.zeros((0, model.n_joints, 3)))[1]
    faces = model_faces(model, model.n_verts)
    names = frame_names([f"{i:06d}" for i in range(n_frames)], warnings)

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Frames [start, stop) posed at once (one person each): vertices, SMPL-24 joints and the frame keys."""
        pose = pose_from_body(params["global_orient"][start:stop, :3], params["body_pose"][start:stop, :63],
                              model.n_joints)
        betas, transl = params["betas"][start:stop], params["transl"][start:stop, :3]
        vertices, joints55 = lbs(model, betas, pose, transl)
        body = smpl_param_arrays(model, betas, pose, transl, joints55)
        if world is not None:
            body.update(world_arrays(pose[:, 0], transl, world["global_orient"][start:stop],
                                     world["transl"][start:stop], joints55[:, 0]))
        return {"vertices": vertices, "joints": joints_to_smpl24(joints55)[0], **body}

    posed_rows = RowBlocks(n_frames, posed, posing_block_rows(model))  # a long clip posed in batches, not frame by frame

    def build(index: int, notes: FrameNotes) -> Frame:
        body = posed_rows.rows(index, index + 1)
        vertices, joints = body.pop("vertices"), body.pop("joints")
        extra = {} if constant else {"focal_length": np.float64(focal[index]),
                                     "principal_point": principal[index].astype(np.float64)}
        return people_frame(names[index], f"{path} [frame {index}]", notes.warnings, vertices=vertices,
                            joints=joints, person_ids=np.zeros(1, np.int64), faces=faces,
                            boxes_2d=None if boxes is None else boxes[index, None], extra=extra, body_params=body)

    meta = base_meta("gvhmr", path, opts, image_size, float(focal[0]) if constant else None,
                     (float(principal[0, 0]), float(principal[0, 1])) if constant else None,
                     focal_kind=ASSUMED, focal_rule=rule)
    meta["import"].update({
        "source_frames": list(range(n_frames)),
        "image_size_from": size_from,
        "joints_layout": layout,
        "root_joint": 0,
        "keypoints_2d_layout": None,
        "feet_heads_from": feet_heads_from(None, True),
        "boxes_2d_from": None if boxes is None else "GVHMR's square crops, recovered from net_outputs.model_output."
                                                     "pred_cam and transl (compute_transl_full_cam inverted)",
        "person_ids": "0: GVHMR reconstructs one tracked person per video",
        "conventions": "camera frame = OpenCV, metres; vertices = SMPL-X(global_orient, body_pose, betas) + transl "
                       "(smpl_params_incam); focal = K_fullimg (GVHMR's estimate_K: sqrt(W^2 + H^2)); jaw, eyes and "
                       "hands at rest (flat hands)",
    })
    if world is not None:
        meta["tool_world"] = tool_world_meta()
    else:
        meta["import"]["tool_world"] = "none: the file has no smpl_params_global"
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"gvhmr": read_gvhmr}
