"""CLIFF demo results (``demo.py --save_results``): one ``.npz`` for all images.

Source: huawei-noah/noah-research ``CLIFF/demo.py`` (and the multi-person fork haofanwang/CLIFF
``demo.py``), ``CLIFF/common/utils.py`` (``cam_crop2full``, ``estimate_focal_length``).

- Keys: ``imgname`` (N_img,) image paths; ``detection_all`` (N, 8) rows ``[image index, x1, y1,
  x2, y2, det score, nms score, class id]`` (the fork stores the *track id* in the last column);
  per detection row: ``pose`` (N, 72) axis-angle or (N, 24, 3, 3) rotation matrices (``--pose_format``),
  ``shape`` (N, 10) betas, ``global_t`` (N, 3) = ``pred_cam_full``, ``pred_joints`` (N, J, 3),
  ``focal_l`` (N,).
- Frame: ``smpl(pose, shape, transl=global_t)`` is already in the full-image camera frame:
  OpenCV axes (x right, y down, z forward), metres. ``pred_joints`` include the translation
  (J = 45 with ``smplx.create``: SMPL-24 first; J = 49 in the fork: SPIN order).
- Focal: ``sqrt(W^2 + H^2)`` pixels (the image diagonal), principal point at the image centre.
- Image size: not stored; read from the image files' headers when ``imgname`` paths exist,
  else ``--image-size`` is required.
- Meshes: CLIFF stores parameters only; vertices need ``--smpl-model`` (an SMPL model).
- Without a model: ``keypoints_2d`` are CLIFF's ``pred_joints`` projected with its own camera (the
  pixels it drew), in their layout (``smpl45``, or ``spin49`` for the fork: formats/keypoints.py),
  and give ``feet_2d``/``heads_2d``. With a model the meshes give them (mesh landmarks) and no
  keypoints are written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..geometry.camera import project_cam_to_px
from ..errors import file_error
from ..geometry.focal import ASSUMED
from ..bodies.joint_layouts import layout_by_count
from ..sequence import Frame
from ..unpickle.npz import load_npz
from .content import as_array
from .files import npz_has_keys, single_file
from .frame_names import frame_names
from .frames import people_frame
from .image_size import image_size_from_header
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces, no_model_warning
from .row_blocks import RowBlocks, frame_offsets, posing_block_rows
from .smpl import joints_to_smpl24, lbs, pose_to_matrices, posed_joints, smpl_param_arrays

_KEYS = {"imgname", "pose", "shape", "global_t", "pred_joints", "focal_l", "detection_all"}


def sniff(path: Path) -> str | None:
    """'cliff' for an .npz holding CLIFF's keys."""
    return "cliff" if npz_has_keys(path, _KEYS) else None


def _image_size(src: Path, imgnames: np.ndarray, opts: ImportOptions) -> tuple[tuple[int, int], str]:
    """--image-size, else the header of the first image file found."""
    if opts.image_size is not None:
        return opts.image_size, "--image-size"
    for name in imgnames[:1]:
        for candidate in (Path(str(name)), src.parent / str(name), src.parent / Path(str(name)).name):
            size = image_size_from_header(candidate)
            if size is not None:
                return size, f"header of {candidate}"
    raise file_error(src, "the image size is not stored in CLIFF results and the images were not found; "
                          "pass --image-size W H")


def read_cliff(src: Path, opts: ImportOptions) -> ImportedSequence:
    """CLIFF demo .npz -> contract frames (see the module docstring for the conventions)."""
    path = single_file(src, sniff, "CLIFF results .npz")
    data = load_npz(path, keys=_KEYS)  # other members are never read
    missing = sorted(k for k in ("imgname", "detection_all", "global_t", "focal_l", "pred_joints") if k not in data)
    if missing:
        raise file_error(path, f"not a CLIFF results file (missing {', '.join(missing)})")
    imgnames = np.asarray(data["imgname"]).reshape(-1)
    det = as_array(data["detection_all"], "detection_all", path)
    n_det = det.shape[0] if det.size else 0
    det = det.reshape(n_det, -1) if n_det else np.zeros((0, 8))
    if det.shape[1] < 8:
        raise file_error(path, f"'detection_all' must have 8 columns, got {det.shape[1]}")
    pred_joints = as_array(data["pred_joints"], "pred_joints", path, ndim=3, last=(3,)) if n_det else np.zeros((0, 24, 3))
    global_t = as_array(data["global_t"], "global_t", path).reshape(-1, 3) if n_det else np.zeros((0, 3))
    focal_l = as_array(data["focal_l"], "focal_l", path).reshape(-1) if n_det else np.zeros(0)
    if not np.all(np.isfinite(focal_l) & (focal_l > 0)):
        raise file_error(path, "'focal_l' must hold positive focal lengths (px)")
    if len(pred_joints) != n_det:
        raise file_error(path, f"'pred_joints' has {len(pred_joints)} rows but 'detection_all' has {n_det}")
    frame_index = det[:, 0].astype(np.int64)
    if n_det and (frame_index.min() < 0 or frame_index.max() >= len(imgnames)):
        raise file_error(path, "'detection_all' refers to images outside 'imgname'")

    image_size, size_origin = _image_size(path, imgnames, opts)
    diagonal = float(np.hypot(*image_size))
    warnings: list[str] = []
    focal = float(np.median(focal_l)) if len(focal_l) else diagonal
    if len(focal_l) and abs(focal - diagonal) > 1e-3 * diagonal:
        warnings.append(f"{path}: focal_l = {focal:.1f} px but the diagonal of {image_size[0]}x{image_size[1]} "
                        f"({size_origin}) is {diagonal:.1f} px; using focal_l (what CLIFF used)")
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)

    model = opts.body_model
    rot = betas = None  # per detection row: SMPL pose as rotation matrices, shape (posed a block of rows at a time)
    joints = None
    layout = "smpl24"
    n_params = 0
    if model is not None:
        check_model_kind(model, path, "CLIFF", "smpl")
        pose = np.asarray(data.get("pose"))
        betas = as_array(data.get("shape"), "shape", path)
        n_params = min(len(pose), len(betas), len(global_t))
        try:
            rot = pose_to_matrices(pose[:n_params], model.n_joints)
            posed = posed_joints(model, betas[:n_params], rot, global_t[:n_params])
        except ValueError as exc:
            raise file_error(path, str(exc)) from None
        if n_params < n_det:
            warnings.append(f"{path}: {n_det - n_params} detections without SMPL parameters (--infill rows) "
                            "were skipped")
        if pred_joints.shape[1] in (24, 45) and n_params:
            gap = float(np.max(np.linalg.norm(posed - pred_joints[:n_params, :24], axis=-1)))
            if gap > 0.02:
                warnings.append(f"{path}: joints posed with {model.name} differ from CLIFF's pred_joints by up to "
                                f"{gap * 100:.1f} cm: is it the SMPL model CLIFF used?")
    else:
        warnings.append(no_model_warning("CLIFF"))
        try:
            joints, layout = joints_to_smpl24(pred_joints)
        except ValueError:
            joints = pred_joints
            layout = "spin49" if pred_joints.shape[1] == 49 else f"cliff{pred_joints.shape[1]}"
    track_col = det[:, 7].astype(np.int64)
    use_ids = all(len(np.unique(track_col[frame_index == i])) == int((frame_index == i).sum())
                  for i in np.unique(frame_index))
    n_rows = n_params if model is not None else n_det
    kp_layout = None if model is not None else layout_by_count(pred_joints.shape[1])
    faces = model_faces(model, None if model is None else model.n_verts)
    names = frame_names([Path(str(n)).stem for n in imgnames], warnings)

    table = np.argsort(frame_index[:n_rows], kind="stable")  # the rows image by image, each image's in file order
    offsets = frame_offsets(np.bincount(frame_index[:n_rows], minlength=len(imgnames)))  # image i: its table rows

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the table posed at once (images posed in batches, not one by one)."""
        rows = table[start:stop]
        try:
            vertices, frame_joints = lbs(model, betas[rows], rot[rows], global_t[rows])
        except ValueError as exc:
            raise file_error(path, str(exc)) from None
        return {"vertices": vertices, "joints": frame_joints,
                **smpl_param_arrays(model, betas[rows], rot[rows], global_t[rows], frame_joints)}

    posed_rows = None if model is None else RowBlocks(len(table), posed, posing_block_rows(model))

    def build(i: int, notes: FrameNotes) -> Frame:
        rows = table[offsets[i]:offsets[i + 1]]
        params = None
        if posed_rows is not None:  # posed a block of rows at a time (one block kept: memory stays flat)
            start, stop = int(offsets[i]), int(offsets[i + 1])
            params = posed_rows.rows(start, stop)
            vertices, frame_joints = params.pop("vertices"), params.pop("joints")
        else:
            vertices, frame_joints = None, joints[rows]
        keypoints = None if model is not None else project_cam_to_px(pred_joints[rows], focal, principal_point)
        return people_frame(
            names[i], f"{path} [image {i}]", notes.warnings, vertices=vertices, joints=frame_joints,
            keypoints_2d=keypoints, person_ids=track_col[rows] if use_ids else None,
            faces=faces, n_verts=None if vertices is None else vertices.shape[1], keypoints_layout=kp_layout,
            body_params=params)

    meta = base_meta("cliff", path, opts, image_size, focal, principal_point, focal_kind=ASSUMED, focal_rule="cliff")
    meta["import"].update({
        "source_frames": [Path(str(n)).name for n in imgnames],
        "image_size_from": size_origin,
        "joints_layout": layout,
        "root_joint": 8 if layout == "spin49" else 0,
        "keypoints_2d_layout": None if kp_layout is None else f"{kp_layout} (pred_joints projected with focal_l)",
        "feet_heads_from": feet_heads_from(kp_layout, model is not None),
        "conventions": "camera frame = OpenCV, metres; focal = image diagonal; vertices = SMPL(pose, shape) + global_t",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"cliff": read_cliff}
