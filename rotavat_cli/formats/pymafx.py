"""PyMAF-X demo results (``apps/demo_smplx.py``): one joblib ``output.pkl`` for a video or an image folder.

Source: HongwenZhang/PyMAF @8368538 (branch ``smplx``) ``apps/demo_smplx.py`` (``run_demo``: the
``pred_results`` dict, ``joblib.dump(pred_results, <output>/output.pkl)``, and the renderer call with
``crop_info={'opt_cam_t': orig_cam_t}``), ``utils/demo_utils.py`` @e8ee107 (``convert_crop_cam_to_orig_img``);
the smplx branch's model and renderer as vendored in YuliangXiu/ECON @2e20b83 ``lib/pymafx/models/pymaf_net.py``
(the ``output`` dict: ``theta = [pred_cam, pred_shape, pose]``, ``verts``, ``smplx_verts``, ``kp_3d``),
``lib/pymafx/models/smpl.py`` (``SMPLX_ALL.forward``), @620bf08 ``lib/pymafx/utils/geometry.py``
(``convert_to_full_img_cam``) and @487ee6d ``lib/pymafx/utils/renderer.py`` (``PyRenderer.__call__``).

- File: a dict of per-detection rows (N of them, every person of every frame): ``orig_cam_t`` (N, 3),
  ``smplx_verts`` (N, 10475, 3) the SMPL-X mesh, ``verts`` (N, 6890, 3) the same mesh on SMPL's topology
  (``smplx_to_smpl`` regression), ``joints3d`` (N, 49, 3) SPIN's joints (OpenPose-25 + 24), ``pose``
  (N, 72) axis-angle of 24 "SMPL" joints (SMPL-X uses the first 22), ``betas`` (N, 10) SMPL-X shape,
  ``pred_cam`` (N, 3) the crop's weak-perspective ``[s, tx, ty]``, ``orig_cam`` (N, 4) ``[sx, sy, tx, ty]``,
  ``bboxes`` (N, 4) ``[cx, cy, h, ...]`` (the crop side ``h`` that camera used), ``joints2d`` (list of (17, 3)) openpifpaf's COCO-17 detections
  ``(x, y, confidence)`` in original-image pixels, ``frame_ids`` (N,), ``person_ids`` (N,) strings
  ``<image stem>_f<frame>_p<detection>`` (detections are not tracked), ``smplx_params`` (torch tensors).
- Frame: meshes and joints are the body model's output without translation; ``X + orig_cam_t`` is the
  camera frame (OpenCV axes, metres). ``orig_cam_t = [tx + 2 (cx - W/2) / (s b), ty + 2 (cy - H/2) / (s b),
  2 f / (s b)]`` (b: the crop's side in px) places the crop's weak-perspective body in the full image.
- Focal: f = 5000 px on the full image whatever its size (``focal_length=5000.``), principal point at the
  image centre (the renderer's ``IntrinsicsCamera(fx=5000, cx=W/2, cy=H/2)``): focal rule ``pymafx``.
- Frames: 0 to the last frame with a detection (the frame count is not stored), named by the image stem
  of their detections for an image folder, by index (``000000``) for a video (its detections all carry
  the frames folder's name).
- Image size: not stored; ``--image-size``, else recovered from ``orig_cam``: ``sx = s h / W`` and
  ``sy = s h / H`` with ``s = pred_cam[:, 0]`` and ``h = bboxes[:, 2]``.
- Meshes: stored. ``--smpl-model`` picks the topology and gives faces and SMPL-24 joints: an SMPL-X model
  (55 joints) keeps ``smplx_verts`` and poses the kinematic joints from ``pose`` (first 22) and ``betas``; an
  SMPL model keeps ``verts`` and regresses the 24 joints from them (its ``J_regressor``, an approximation
  of the kinematic joints). Without a model: ``smplx_verts`` and the file's 49 SPIN joints (pelvis = 8).
- ``smplx_params`` holds the demo's torch tensors as they were (on the GPU where it ran), pickled by plain
  pickle (``torch._utils._rebuild_tensor_v2`` over ``torch.storage._load_from_bytes``): the restricted
  unpickler rebuilds them as numpy arrays (:mod:`rotavat_cli.unpickle.torch_tensors`); nothing here uses them.
"""

from __future__ import annotations

import mmap
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .ids import check_frame_range
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces
from .smpl import BodyModel, joints_to_smpl24, pose_from_body, posed_joints

_KEYPOINTS_LAYOUT = "coco17 (openpifpaf detections: x, y, confidence)"
_SPIN49_LAYOUT = "spin49 (OpenPose-25 + 24 SPIN joints)"
_SPIN49_PELVIS = 8  # OpenPose MidHip
_SMPLX_BODY_JOINTS = 22  # global orientation + 21 body joints: the part of ``pose`` SMPL-X uses
_KEY_NAMES = (b"orig_cam_t", b"smplx_verts", b"frame_ids")  # pickled key names of the results dict
_PERSON_ID = re.compile(r"^(?P<stem>.*)_f(?P<frame>\d+)_p\d+$")  # demo_smplx.py: f'{stem}_f{frame_i}_p{pid}'
_JOINT_GAP_M = 0.02  # posed pelvis vs the mesh's regressed pelvis: more means another body model


def _names_pymafx_keys(path: Path) -> bool:
    """Whether an uncompressed pickle mentions PyMAF-X's key names (bytes searched, nothing unpickled)."""
    with open(path, "rb") as handle:
        if handle.read(1) != b"\x80":  # pickle protocol >= 2 (joblib.dump without compression)
            return False
        with mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
            return all(data.find(name) >= 0 for name in _KEY_NAMES)


def sniff(path: Path) -> str | None:
    """'pymafx' for an ``output.pkl`` naming PyMAF-X's keys (``orig_cam_t``, ``smplx_verts``, ``frame_ids``)."""
    if path.is_dir():
        path = path / "output.pkl"
    if path.is_file() and path.suffix == ".pkl" and _names_pymafx_keys(path):
        return "pymafx"
    return None


def _results_file(src: Path) -> Path:
    """``src`` itself, or the demo's ``output.pkl`` in directory ``src``."""
    if src.is_dir():
        src = src / "output.pkl"
        if not src.is_file():
            raise file_error(src.parent, "no PyMAF-X output.pkl in the directory")
    return src


def _load(path: Path) -> Mapping:
    """The results dict (its torch tensors, ``smplx_params``, come back as inert numpy arrays; unused)."""
    data = load_file(path)
    if not isinstance(data, Mapping) or "orig_cam_t" not in data:
        raise file_error(path, "not a PyMAF-X output.pkl (expected a dict with 'orig_cam_t')")
    return data


def _rows(data: Mapping, key: str, path: Path, n_rows: int, ndim: int, last: tuple[int, ...] | None) -> np.ndarray:
    """Per-detection array ``key`` validated to (N, ...) with N = n_rows."""
    arr = as_array(get(data, key, path), key, path, ndim=ndim, last=last)
    if len(arr) != n_rows:
        raise file_error(path, f"'{key}' has {len(arr)} rows but 'orig_cam_t' has {n_rows}")
    return arr


def image_size_from_cams(pred_cam: np.ndarray, orig_cam: np.ndarray, bboxes: np.ndarray) -> tuple[int, int] | None:
    """(W, H) px undone from ``convert_crop_cam_to_orig_img``: sx = s h / W, sy = s h / H, or None.

    pred_cam: (N, 3) crop camera [s, tx, ty]; orig_cam: (N, 4) [sx, sy, tx, ty]; bboxes: (N, >= 3) [cx, cy, h, ...].
    Every row must give the same size (within half a pixel).
    """
    if bboxes.shape[1] < 3:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        scale_px = pred_cam[:, 0] * bboxes[:, 2]  # (N,)
        sizes = np.stack([scale_px / orig_cam[:, 0], scale_px / orig_cam[:, 1]], axis=1)  # (N, 2)
    if not len(sizes) or not np.all(np.isfinite(sizes)) or np.any(sizes < 1) or np.ptp(sizes, axis=0).max() > 0.5:
        return None
    width, height = np.round(np.median(sizes, axis=0)).astype(int)
    return int(width), int(height)


def _image_size(data: Mapping, path: Path, n_rows: int, opts: ImportOptions,
                warnings: list[str]) -> tuple[tuple[int, int], str]:
    """--image-size, else the size ``orig_cam`` was made for."""
    recovered = None
    if all(data.get(k) is not None for k in ("pred_cam", "orig_cam", "bboxes")):
        recovered = image_size_from_cams(_rows(data, "pred_cam", path, n_rows, 2, (3,)),
                                         _rows(data, "orig_cam", path, n_rows, 2, (4,)),
                                         _rows(data, "bboxes", path, n_rows, 2, None))
    if opts.image_size is not None:
        if recovered is not None and recovered != tuple(opts.image_size):
            warnings.append(f"{path}: --image-size {opts.image_size[0]}x{opts.image_size[1]} differs from the "
                            f"{recovered[0]}x{recovered[1]} of 'orig_cam'; using --image-size")
        return opts.image_size, "--image-size"
    if recovered is None:
        raise file_error(path, "the image size is not stored in PyMAF-X results and could not be recovered from "
                               "'orig_cam'; pass --image-size W H")
    return recovered, "recovered from orig_cam (sx = s h / W, sy = s h / H)"


def _mesh_key(data: Mapping, model: BodyModel | None, path: Path) -> str:
    """The mesh array imported: the model's topology (SMPL: 'verts'), else PyMAF-X's own SMPL-X mesh."""
    wanted = ("verts",) if model is not None and model.kind == "smpl" else \
        ("smplx_verts",) if model is not None else ("smplx_verts", "verts")
    for key in wanted:
        if data.get(key) is not None:
            return key
    raise file_error(path, f"holds no '{wanted[0]}' meshes")


def _frame_sources(person_ids: list | None, frame_ids: np.ndarray, n_frames: int) -> list[str]:
    """Per frame, the image stem the demo named its detections with (image folders), else the frame index.

    A video's detections all carry the video's folder name, so stems name frames only when frames and
    stems match one to one.
    """
    index_names = [f"{i:06d}" for i in range(n_frames)]
    if person_ids is None or len(person_ids) != len(frame_ids):
        return index_names
    stem_of: dict[int, str] = {}
    for pid, frame in zip(person_ids, frame_ids):
        match = _PERSON_ID.match(str(pid))
        if match is None or int(match["frame"]) != int(frame):
            return index_names
        if stem_of.setdefault(int(frame), match["stem"]) != match["stem"]:
            return index_names
    if len(set(stem_of.values())) != len(stem_of):
        return index_names
    return [stem_of.get(i, name) for i, name in enumerate(index_names)]


def _keypoints(entries: list, source: str) -> np.ndarray:
    """(P, K, 2 or 3) keypoints from the detections' 'joints2d' entries, each (K, 2 or 3) px (+ confidence)."""
    if not entries:
        return np.zeros((0, 17, 3))
    arrays = [as_array(entry, "joints2d", source, ndim=2) for entry in entries]
    if len({a.shape for a in arrays}) != 1 or arrays[0].shape[1] not in (2, 3):
        raise file_error(source, "'joints2d' entries must share one (K, 2) or (K, 3) shape")
    return np.stack(arrays)


def read_pymafx(src: Path, opts: ImportOptions) -> ImportedSequence:
    """PyMAF-X demo ``output.pkl`` -> contract frames (see the module docstring for the conventions)."""
    path = _results_file(src)
    data = _load(path)
    cam_t = as_array(data["orig_cam_t"], "orig_cam_t", path, ndim=2, last=(3,))
    n_rows = len(cam_t)
    if not n_rows:
        raise file_error(path, "holds no detections")
    frame_ids = as_array(get(data, "frame_ids", path), "frame_ids", path, kinds="iu").reshape(-1)
    if len(frame_ids) != n_rows or frame_ids.min() < 0:
        raise file_error(path, f"'frame_ids' must hold {n_rows} frame indices >= 0")
    warnings: list[str] = []
    image_size, size_origin = _image_size(data, path, n_rows, opts, warnings)
    focal = focal_from_rule("pymafx", image_size)
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)

    model = opts.body_model
    if model is not None and model.kind not in ("smpl", "smplx"):
        raise file_error(path, f"PyMAF-X meshes are SMPL-X (or SMPL topology); --smpl-model {model.name} has "
                               f"{model.n_joints} joints (need 55 or 24)")
    mesh_key = _mesh_key(data, model, path)
    meshes = _rows(data, mesh_key, path, n_rows, 3, (3,))
    if model is not None and model.n_verts != meshes.shape[1]:
        raise file_error(path, f"--smpl-model {model.name} has {model.n_verts} vertices but '{mesh_key}' has "
                               f"{meshes.shape[1]}")
    pose = betas = spin_joints = None
    if model is not None and model.kind == "smplx":
        pose72 = _rows(data, "pose", path, n_rows, 2, (72,))  # SMPL's 24 joints: SMPL-X takes the first 22
        pose = pose_from_body(pose72[:, :3], pose72[:, 3:3 * _SMPLX_BODY_JOINTS], model.n_joints)
        betas = _rows(data, "betas", path, n_rows, 2, None)
        mesh_pelvis = np.einsum("v,pvc->pc", model.J_regressor[0], meshes)  # (N, 3), model frame
        gap = np.linalg.norm(posed_joints(model, betas, pose)[:, 0] - mesh_pelvis, axis=-1)
        if gap.max() > _JOINT_GAP_M:
            warnings.append(f"{path}: joints posed with {model.name} are up to {gap.max() * 100:.1f} cm from PyMAF-X's "
                            "meshes: is it the SMPL-X model PyMAF-X used (SMPLX_NEUTRAL, 10 betas)?")
        layout = "smpl24 (posed from pose[:22] and betas; hands = SMPL-X middle1 joints)"
    elif model is not None:
        layout = "smpl24 (J_regressor of --smpl-model on PyMAF-X's SMPL-topology mesh)"
    elif data.get("joints3d") is not None:
        spin_joints = _rows(data, "joints3d", path, n_rows, 3, (3,))
        layout = _SPIN49_LAYOUT if spin_joints.shape[1] == 49 else f"pymafx{spin_joints.shape[1]}"
        warnings.append(f"{path}: no --smpl-model: joints are PyMAF-X's {spin_joints.shape[1]} SPIN joints "
                        "(OpenPose-25 first), not SMPL-24; pass --smpl-model SMPLX_NEUTRAL.npz for SMPL-24 joints")
    else:
        layout = None
    keypoints = data.get("joints2d")
    if keypoints is not None and (not isinstance(keypoints, (list, tuple, np.ndarray)) or len(keypoints) != n_rows):
        warnings.append(f"{path}: 'joints2d' does not hold one entry per detection ({n_rows}); 2D keypoints "
                        "not imported")
        keypoints = None
    person_ids = data.get("person_ids")
    n_frames = check_frame_range(int(frame_ids.max()) + 1, n_rows, path, "frame_ids")
    sources = _frame_sources(list(person_ids) if isinstance(person_ids, (list, tuple, np.ndarray)) else None,
                             frame_ids, n_frames)
    names = frame_names(sources, warnings)
    faces = model_faces(model, meshes.shape[1])

    def joints_of(rows: np.ndarray) -> np.ndarray | None:
        """Camera-frame joints (P, J, 3) of detection rows, without translation, by the rule above."""
        if pose is not None:
            return joints_to_smpl24(posed_joints(model, betas[rows], pose[rows]))[0]
        if model is not None:
            return np.einsum("jv,pvc->pjc", model.J_regressor, meshes[rows])
        return None if spin_joints is None else spin_joints[rows]

    def build(index: int, notes: FrameNotes) -> Frame:
        rows = np.flatnonzero(frame_ids == index)
        source = f"{path} [frame {index}]"
        shift = cam_t[rows, None]  # (P, 1, 3)
        joints = joints_of(rows)
        kp = None if keypoints is None else _keypoints([keypoints[r] for r in rows], source)
        return people_frame(names[index], source, notes.warnings, vertices=meshes[rows] + shift,
                            joints=None if joints is None else joints + shift, keypoints_2d=kp, faces=faces,
                            n_verts=meshes.shape[1], keypoints_layout=_KEYPOINTS_LAYOUT)

    meta = base_meta("pymafx", path, opts, image_size, focal, principal_point, focal_kind=ASSUMED, focal_rule="pymafx")
    meta["import"].update({
        "source_frames": sources,
        "image_size_from": size_origin,
        "joints_layout": layout,
        "root_joint": None if layout is None else (_SPIN49_PELVIS if spin_joints is not None else 0),
        "keypoints_2d_layout": _KEYPOINTS_LAYOUT if keypoints is not None else None,
        "feet_heads_from": feet_heads_from(_KEYPOINTS_LAYOUT, True),
        "conventions": f"camera frame = OpenCV, metres; vertices = {mesh_key} + orig_cam_t; focal 5000 px, principal "
                       "point = image centre; one row per detection (not tracked: no person_ids)",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"pymafx": read_pymafx}
