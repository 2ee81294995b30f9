"""TRACE (``simple_romp``'s ``trace2`` command): one ``<sequence>.npz`` per video or frame folder.

Source: Arthur151/ROMP @39aa59c ``simple_romp/trace2/main.py`` (``TRACE.save_results``:
``np.savez(<results_save_dir>/<seq>.npz, outputs=remove_large_keys(outputs), imgpaths=imgpaths)``),
@7fc29c8 ``simple_romp/trace2/utils/infer_utils.py`` (``merge_output``, ``remove_large_keys``: ``verts``
and the ``world_*`` meshes are dropped), ``results_parser/smpl_wrapper_relative_temp.py``
(``SMPLWrapper.forward``), ``utils/load_data.py`` (``img_preprocess``: ``image_pad_white_bg`` to a square,
resized to 512); @25dec9d ``utils/utils.py`` (``focal_length = 548``, ``tan_fov = tan(25 deg)``,
``denormalize_cam_params_to_trans``, ``vertices_kp3d_projection``, ``convert_kp2d_from_input_to_orgimg``);
@72e6625 ``models/smpl.py`` (``SMPL.forward``: root-aligned on joints 35, 36; ``VertexJointSelector``),
``models/model.py`` (``track_ids``); @596682 ``utils/infer_settings.py`` (``--FOV 50``); the joint names of
@42cbb20 ``romp/lib/constants.py`` (``SMPL_24``, ``SMPL_EXTRA_21``, ``SMPL_EXTRA_30``); the padding split of
aleju/imgaug @a216652 ``imgaug/augmenters/size.py`` (``compute_paddings_to_reach_aspect_ratio``: the odd
pixel goes right / bottom).

- File: ``outputs`` (0-d object array: a dict, read with the restricted unpickler) and ``imgpaths``
  (T,) every frame's image path in time order. Per detection row (N): ``reorganize_idx`` (frame index
  into ``imgpaths``), ``track_ids``, ``cam_trans`` (N, 3), ``j3d`` (N, 44, 3), ``pj2d`` (N, 44, 2) in the
  512 px input normalised to [-1, 1], ``pj2d_org`` (N, 44, 2) original-image pixels, ``smpl_thetas``
  (N, 72) SMPL axis-angle, ``smpl_betas`` (N, 10); also ``world_*`` (TRACE's moving-camera world frame,
  not read), ``joints_h36m17``, ``pj2d_org_h36m17``, ``center_confs``.
- Joints: ``j3d`` = SMPL-24 + 11 vertex joints (nose, eyes, ears, big toes, small toes, heels) + 9 extra
  (hips, LSP neck, head top, pelvis, MPII thorax, H36M spine, jaw, head), root-aligned on the mean of the
  two hips (35, 36); ``j3d + cam_trans`` is the camera frame: OpenCV axes, metres.
- Meshes: not stored; with ``--smpl-model`` (SMPL) they are ``SMPL(smpl_thetas, smpl_betas)`` moved so
  that its pelvis lands on ``j3d[:, 0] + cam_trans`` (the hips' mean, the root TRACE aligns on, comes from
  a regressor of its own).
- Focal: the network sees the image padded to a centred square of side S = max(W, H), resized to 512, with
  f = 548 px on 512 (a 50 degree field of view): f = 548 / 512 * S on the original image; principal point
  = centre of the padded square, ``(S/2 - left, S/2 - top)``: focal rule ``trace``.
- Image size: ``--image-size``, else the header of the first image in ``imgpaths`` (when it exists),
  else fitted from ``pj2d`` against ``pj2d_org`` (exact up to one pixel of padding parity).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.npz import load_npz
from .bev import _infer_image_size
from .content import as_array, get
from .files import npz_has_keys, single_file
from .frame_names import frame_names
from .frames import people_frame
from .image_size import image_size_from_header, padded_square
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces, no_model_warning
from .smpl import lbs, posed_joints

_KEYS = {"outputs", "imgpaths"}
_KEYPOINTS_LAYOUT = "trace44 (SMPL-24, 11 face/feet vertex joints, 9 extra; ROMP SMPL_ALL_44)"
_JOINT_GAP_M = 0.02  # the model's joints vs TRACE's: more means another body model


def _is_results_npz(path: Path) -> bool:
    """Whether ``path`` is an .npz with TRACE's members (read from the zip index; unreadable files are not)."""
    try:
        return npz_has_keys(path, _KEYS)
    except (OSError, zipfile.BadZipFile):
        return False


def sniff(path: Path) -> str | None:
    """'trace' for an .npz holding TRACE's ``outputs`` and ``imgpaths`` (or a directory with one)."""
    files = [path] if path.is_file() else sorted(path.glob("*.npz"))[:20] if path.is_dir() else []
    return "trace" if any(_is_results_npz(file) for file in files) else None


def _outputs(path: Path) -> tuple[dict, list[str]]:
    """The results dict and the frames' image paths."""
    content = load_npz(path, keys=tuple(sorted(_KEYS)))  # other members are never read
    missing = sorted(_KEYS - set(content))
    if missing:
        raise file_error(path, f"not a TRACE results file (missing {', '.join(missing)})")
    outputs = content["outputs"]
    if outputs.shape != () or not isinstance(outputs.item(), dict):
        raise file_error(path, "'outputs' must hold a dict")
    imgpaths = np.asarray(content["imgpaths"]).reshape(-1)
    if imgpaths.dtype.kind not in "UO" or not all(isinstance(p, str) for p in imgpaths.tolist()):
        raise file_error(path, "'imgpaths' must hold image paths")
    return outputs.item(), [str(p) for p in imgpaths.tolist()]


def _rows(outputs: dict, key: str, path: Path, n_rows: int, ndim: int, last: tuple[int, ...] | None) -> np.ndarray:
    """Per-detection array ``key`` validated to (N, ...) with N = n_rows."""
    arr = as_array(get(outputs, key, path), key, path, ndim=ndim, last=last)
    if len(arr) != n_rows:
        raise file_error(path, f"'{key}' has {len(arr)} rows but 'cam_trans' has {n_rows}")
    return arr


def _image_size(outputs: dict, imgpaths: list[str], path: Path, n_rows: int, opts: ImportOptions,
                warnings: list[str]) -> tuple[tuple[int, int], int, int, str]:
    """((W, H), left, top, origin): --image-size, the first image's header, else the fit of pj2d to pj2d_org."""
    if opts.image_size is not None:
        return (*_with_padding(opts.image_size), "--image-size")
    for name in imgpaths[:1]:
        for candidate in (Path(name), path.parent / Path(name).name):
            size = image_size_from_header(candidate)
            if size is not None:
                return (*_with_padding(size), f"header of {candidate}")
    if outputs.get("pj2d") is not None and outputs.get("pj2d_org") is not None and n_rows:
        found = _infer_image_size(_rows(outputs, "pj2d", path, n_rows, 3, (2,)),
                                  _rows(outputs, "pj2d_org", path, n_rows, 3, (2,)), str(path))
        if found is not None:
            (width, height), left, top = found
            warnings.append(f"{path}: image size {width}x{height} fitted from pj2d and pj2d_org (+-1 px when the "
                            "padding is odd); pass --image-size W H to be exact")
            return (width, height), left, top, "fitted from pj2d / pj2d_org"
    raise file_error(path, "the image size is not stored in TRACE results, its images were not found and it could not "
                           "be fitted from 'pj2d_org'; pass --image-size W H")


def _with_padding(image_size: tuple[int, int]) -> tuple[tuple[int, int], int, int]:
    """((W, H), left, top) of the centred square padding (imgaug: the odd pixel goes right / bottom)."""
    _, left, top = padded_square(image_size)
    return (int(image_size[0]), int(image_size[1])), left, top


def read_trace(src: Path, opts: ImportOptions) -> ImportedSequence:
    """TRACE ``<sequence>.npz`` -> contract frames (see the module docstring for the conventions)."""
    path = single_file(src, sniff, "TRACE results .npz", " (pass the file)")
    outputs, imgpaths = _outputs(path)
    cam_trans = as_array(get(outputs, "cam_trans", path), "cam_trans", path, ndim=2, last=(3,))
    n_rows = len(cam_trans)
    frame_index = _rows(outputs, "reorganize_idx", path, n_rows, 1, None)
    if frame_index.dtype.kind == "f" and not np.all(frame_index == np.round(frame_index)):
        raise file_error(path, "'reorganize_idx' must hold frame indices")
    frame_index = frame_index.astype(np.int64)
    if n_rows and (frame_index.min() < 0 or frame_index.max() >= len(imgpaths)):
        raise file_error(path, f"'reorganize_idx' refers to frames outside 'imgpaths' ({len(imgpaths)} frames)")
    j3d = _rows(outputs, "j3d", path, n_rows, 3, (3,))
    if j3d.shape[1] < 24:
        raise file_error(path, f"'j3d' must hold at least the 24 SMPL joints, got {j3d.shape[1]}")
    joints_cam = j3d[:, :24] + cam_trans[:, None]  # (N, 24, 3)
    keypoints = _rows(outputs, "pj2d_org", path, n_rows, 3, (2,)) if outputs.get("pj2d_org") is not None else None
    track_ids = None
    if outputs.get("track_ids") is not None:
        track_ids = as_array(outputs["track_ids"], "track_ids", path, kinds="iu").reshape(-1)
        if len(track_ids) != n_rows:
            raise file_error(path, f"'track_ids' has {len(track_ids)} entries but 'cam_trans' has {n_rows}")
    warnings: list[str] = []
    image_size, left, top, size_origin = _image_size(outputs, imgpaths, path, n_rows, opts, warnings)
    side = max(image_size)
    focal = focal_from_rule("trace", image_size)
    principal_point = (side / 2.0 - left, side / 2.0 - top)

    model = opts.body_model
    thetas = betas = None
    if check_model_kind(model, path, "TRACE", "smpl") is None:
        warnings.append(no_model_warning("TRACE"))
    else:
        thetas = _rows(outputs, "smpl_thetas", path, n_rows, 2, (72,))
        betas = _rows(outputs, "smpl_betas", path, n_rows, 2, None)
        posed = posed_joints(model, betas, thetas)  # (N, 24, 3), model frame
        gap = np.linalg.norm((posed - posed[:, :1]) - (j3d[:, :24] - j3d[:, :1]), axis=-1)
        if n_rows and gap.max() > _JOINT_GAP_M:
            warnings.append(f"{path}: joints posed with {model.name} differ from TRACE's j3d by up to "
                            f"{gap.max() * 100:.1f} cm: is it the SMPL model TRACE used?")
    names = frame_names([Path(p).stem for p in imgpaths], warnings)
    faces = model_faces(model, None if model is None else model.n_verts)

    def build(index: int, notes: FrameNotes) -> Frame:
        rows = np.flatnonzero(frame_index == index)
        vertices = None
        if thetas is not None:  # posed here, one frame's people at a time: memory stays that of the file
            vertices, joints_model = lbs(model, betas[rows], thetas[rows])
            vertices = vertices + (joints_cam[rows, 0] - joints_model[:, 0])[:, None]  # pelvis on j3d[0] + cam_trans
        return people_frame(names[index], f"{path} [{Path(imgpaths[index]).name}]", notes.warnings, vertices=vertices,
                            joints=joints_cam[rows], keypoints_2d=None if keypoints is None else keypoints[rows],
                            person_ids=None if track_ids is None else track_ids[rows], faces=faces,
                            n_verts=None if model is None else model.n_verts, keypoints_layout=_KEYPOINTS_LAYOUT)

    meta = base_meta("trace", path, opts, image_size, focal, principal_point, focal_kind=ASSUMED, focal_rule="trace")
    meta["import"].update({
        "source_frames": [Path(p).name for p in imgpaths],
        "image_size_from": size_origin,
        "joints_layout": "smpl24",
        "root_joint": 0,
        "keypoints_2d_layout": _KEYPOINTS_LAYOUT if keypoints is not None else None,
        "feet_heads_from": feet_heads_from(_KEYPOINTS_LAYOUT, model is not None),
        "conventions": f"camera frame = OpenCV, metres; joints = j3d + cam_trans; vertices = SMPL(smpl_thetas, "
                       f"smpl_betas) with its pelvis on j3d[0] + cam_trans; 50-degree FOV on the centred padded "
                       f"square (S = {side}); world_* (moving camera) not read",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"trace": read_trace}
