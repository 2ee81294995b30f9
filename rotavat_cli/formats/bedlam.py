"""BEDLAM ground truth: the per-scene ``.npz`` made by BEDLAM's ``data_processing`` scripts.

Source: pixelite1201/BEDLAM ``data_processing/df_full_body.py`` (``get_params``, ``project``,
``get_cam_int``, ``focalLength_mm2px``, the ``np.savez`` call), ``data_processing/ReadMe.md``
(field list; BEDLAM2 variant), ``df_full_body_smpl.py`` (SMPL variant).

- Keys, one row per (image, person): ``imgname`` ('<seq>/<seq>_<frame>.png'), ``pose_cam``
  (N, 165) SMPL-X axis-angle (global, 21 body, jaw, leye, reye, 15 + 15 hand joints; flat hand
  mean) or (N, 72) for the SMPL variant, ``shape`` (N, 10 / 11 / 16) betas, ``trans_cam`` (N, 3),
  ``cam_ext`` (N, 4, 4), ``cam_int`` (N, 3, 3), ``gtkps`` (N, K, 2 or 3) projected joints,
  ``sub`` (N,) subject names, ``gender``, ``center``, ``scale``.
- Frame: ``smplx(pose_cam, shape, transl=trans_cam) + cam_ext[:3, 3]`` is the camera frame
  (``project``: ``points + cam_trans`` then ``K``): OpenCV axes, metres.
- Focal: ``cam_int`` (fx = focal_mm / 36 * W on the 1280x720 renders, or sensor 20.25 x 36 for the
  rotated 720x1280 close-ups); image size = 2 x its principal point.
- Meshes need ``--smpl-model`` (SMPLX_NEUTRAL.npz; BEDLAM uses the neutral model with 11 betas,
  BEDLAM2 16). Without it only the 2D keypoints are imported.
- ``person_ids``: the subject names (``sub``) mapped to integers in sorted order.
- ``gtkps``: ``project(joints3d, cam_trans, CAM_INT)`` of the posed model's joints, homogeneous
  (x, y, 1): 127 SMPL-X joints (``smplx.create`` without face contour), 45 for the SMPL variant;
  without ``--smpl-model`` they give the feet and heads (formats/keypoints.py, layout by count).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import CAMERA
from ..bodies.joint_layouts import layout_by_count
from ..sequence import Frame
from ..unpickle.npz import load_npz
from .content import as_array
from .files import npz_has_keys, single_file
from .frame_names import frame_names, natural_key
from .frames import people_frame
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces
from .row_blocks import RowBlocks, frame_offsets, posing_block_rows
from .smpl import joints_to_smpl24, lbs, smpl_param_arrays

_KEYS = {"imgname", "pose_cam", "shape", "trans_cam", "cam_int", "cam_ext"}


def sniff(path: Path) -> str | None:
    """'bedlam' for a per-scene .npz with BEDLAM's keys."""
    return "bedlam" if npz_has_keys(path, _KEYS) else None


def read_bedlam(src: Path, opts: ImportOptions) -> ImportedSequence:
    """BEDLAM per-scene .npz -> contract frames (one frame per image)."""
    path = single_file(src, sniff, "BEDLAM scene .npz", ' (import one scene at a time: a sequence is one camera)')
    data = load_npz(path, keys=_KEYS | {"gtkps", "sub"})  # other members are never read
    missing = sorted(_KEYS - set(data))
    if missing:
        raise file_error(path, f"not a BEDLAM scene file (missing {', '.join(missing)})")
    imgname = np.asarray(data["imgname"]).reshape(-1).astype(str)
    n_rows = len(imgname)
    pose = as_array(data["pose_cam"], "pose_cam", path, ndim=2)
    betas = as_array(data["shape"], "shape", path, ndim=2)
    trans = as_array(data["trans_cam"], "trans_cam", path, ndim=2, last=(3,))
    cam_ext = as_array(data["cam_ext"], "cam_ext", path, ndim=3)
    cam_int = as_array(data["cam_int"], "cam_int", path, ndim=3, last=(3, 3))
    if cam_ext.shape[1:] not in ((4, 4), (3, 4)):
        raise file_error(path, f"'cam_ext' must be (N, 4, 4), got {list(cam_ext.shape)}")
    for key, arr in (("pose_cam", pose), ("shape", betas), ("trans_cam", trans), ("cam_ext", cam_ext), ("cam_int", cam_int)):
        if len(arr) != n_rows:
            raise file_error(path, f"'{key}' has {len(arr)} rows, 'imgname' {n_rows}")
    gtkps = as_array(data["gtkps"], "gtkps", path, ndim=3) if "gtkps" in data else None
    warnings: list[str] = []

    stored = (int(round(2 * np.median(cam_int[:, 0, 2]))), int(round(2 * np.median(cam_int[:, 1, 2])))) if n_rows else None
    image_size = opts.image_size or stored
    if image_size is None:
        raise file_error(path, "empty scene and no --image-size W H")
    if opts.image_size is not None and stored is not None and stored != opts.image_size:
        warnings.append(f"{path}: --image-size differs from the {stored[0]}x{stored[1]} implied by cam_int; using --image-size")
    fx = cam_int[:, 0, 0]
    if n_rows and np.max(np.abs(cam_int[:, 1, 1] - fx)) > 1e-3 * np.max(fx):
        warnings.append(f"{path}: fx and fy differ; using fx")
    constant_focal = n_rows == 0 or np.ptp(fx) < 1e-6 * np.max(fx)
    principal_point = (float(np.median(cam_int[:, 0, 2])), float(np.median(cam_int[:, 1, 2]))) if n_rows else None

    model = opts.body_model
    layout = None
    if model is not None:
        n_pose = model.n_joints * 3
        if pose.shape[1] != n_pose:
            raise file_error(path, f"'pose_cam' has {pose.shape[1]} values per person but --smpl-model {model.name} "
                                   f"needs {n_pose} (SMPL-X: 165, SMPL: 72)")
        layout = joints_to_smpl24(np.zeros((0, model.n_joints, 3)))[1]
    else:
        warnings.append("BEDLAM stores SMPL-X parameters, not meshes, and no --smpl-model was given: imported 2D "
                        "keypoints only (no vertices or joints)")

    subjects = sorted(set(np.asarray(data["sub"]).reshape(-1).astype(str))) if "sub" in data else []
    sub_ids = ({n: i for i, n in enumerate(subjects)}, np.asarray(data["sub"]).reshape(-1).astype(str)) if subjects else None
    images = sorted(set(imgname), key=natural_key)
    names = frame_names([Path(i).stem for i in images], warnings)
    faces = model_faces(model, None if model is None else model.n_verts)
    kp_layout = layout_by_count(gtkps.shape[1]) if gtkps is not None else None

    image_index = {image: i for i, image in enumerate(images)}
    row_image = np.array([image_index[name] for name in imgname], np.int64)  # (N,) each row's frame
    table = np.argsort(row_image, kind="stable")  # the rows image by image, each image's in file order
    offsets = frame_offsets(np.bincount(row_image, minlength=len(images)))  # image i: table[offsets[i]:offsets[i + 1]]

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the table posed at once (images posed in batches, not one by one): vertices, SMPL-24
        joints and the parameter keys."""
        rows = table[start:stop]
        transl = trans[rows] + cam_ext[rows, :3, 3]
        vertices, joints55 = lbs(model, betas[rows], pose[rows], transl)
        return {"vertices": vertices, "joints": joints_to_smpl24(joints55)[0],
                **smpl_param_arrays(model, betas[rows], pose[rows], transl, joints55)}

    posed_rows = None if model is None else RowBlocks(len(table), posed, posing_block_rows(model))

    def build(index: int, notes: FrameNotes) -> Frame:
        image = images[index]
        rows = table[offsets[index]:offsets[index + 1]]
        ids = np.array([sub_ids[0][sub_ids[1][r]] for r in rows], dtype=np.int64) if sub_ids else None
        extra = {} if constant_focal else {"focal_length": np.float64(fx[rows[0]])}
        kp = gtkps[rows][..., :2] if gtkps is not None else None
        vertices = joints = params = None
        if posed_rows is not None:  # posed a block of rows at a time (one block kept: memory stays flat)
            params = posed_rows.rows(int(offsets[index]), int(offsets[index + 1]))
            vertices, joints = params.pop("vertices"), params.pop("joints")
        return people_frame(names[index], f"{path} [{image}]", notes.warnings, vertices=vertices, joints=joints,
                            keypoints_2d=kp, person_ids=ids, faces=faces, extra=extra, keypoints_layout=kp_layout,
                            body_params=params)

    meta = base_meta("bedlam", path, opts, image_size, float(fx[0]) if n_rows and constant_focal else None, principal_point,
                     focal_kind=CAMERA)
    meta["import"].update({
        "source_frames": images,
        "image_size_from": "--image-size" if opts.image_size else "cam_int principal point",
        "joints_layout": layout,
        "root_joint": 0,
        "keypoints_2d_layout": (f"{kp_layout or 'bedlam'} (gtkps, {gtkps.shape[1]} joints)" if gtkps is not None
                                else None),
        "feet_heads_from": feet_heads_from(kp_layout, model is not None),
        "person_ids": "subject names in sorted order: " + ", ".join(subjects) if subjects else None,
        "conventions": "camera frame = OpenCV, metres: vertices = SMPL-X(pose_cam, shape, trans_cam) + cam_ext[:3, 3]; "
                       "intrinsics = cam_int",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"bedlam": read_bedlam}
