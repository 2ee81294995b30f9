"""HybrIK (``--from hybrik``): the ``res.pk`` that ``scripts/demo_video.py --save-pk`` writes.

Source: Jeff-sjtu/HybrIK @802e1b8 ``scripts/demo_video.py`` (``res_db``, ``xyxy2xywh``, the
per-person ``focal``, ``pk.dump(res_db)``), ``configs/256x192_adam_lr1e-3-hrw48_cam_2x_w_pw3d_3dhp.yaml``
(the demo's config: ``FOCAL_LENGTH: 1000``, ``IMAGE_SIZE: [256, 256]``, ``BBOX_3D_SHAPE: 2200``),
@403d1ae ``hybrik/models/HRNetWithCam.py`` (``HRNetSMPLCam.forward``: uvd -> camera xyz,
``cam_root``, ``transl``), ``hybrik/utils/presets/simple_transform_3d_smpl_cam.py``
(``test_transform``: the box, ``img_center``), @9bf86ce ``hybrik/models/layers/smpl/SMPL.py``
(``SMPL_layer.hybrik``: ``JOINT_NAMES`` of the 29 joints, root-centred outputs); the 5 leaf joints
are SMPL vertices 411 (head top), 2445 / 5905 (middle fingertips), 3216 / 6617 (big toes)
(``hybrik/models/layers/smpl/lbs.py``, ``leaf_number``).

- File: a plain pickle of a dict of stacked arrays, one row per processed image (the demo
  follows one person: the first detection, then the box of largest IoU with the previous one;
  images with no detection are skipped): ``pred_xyz_29`` (N, 29, 3) root-relative, in units of
  the depth factor ``bbox_3d_shape / 1000`` m; ``pred_uvd`` (N, 29, 3): u, v in [-0.5, 0.5] of
  the crop box, d root-relative depth; ``pred_cam_root`` (N, 3) the root joint in the camera
  frame (m); ``transl`` (N, 3) = ``cam_root`` minus the (zero) root of the root-centred SMPL
  output; ``pred_thetas`` (N, 216) = 24 rotation matrices (older versions: (N, 96) quaternions);
  ``pred_betas`` (N, 10); ``bbox`` (N, 4) xyxy of the square crop box (detection x 1.25);
  ``height``, ``width`` (N,) px; ``img_path`` (N,); and ``pred_xyz_17``, ``pred_xyz_24_struct``,
  ``pred_scores``, ``pred_camera``, ``pred_phi``, ``transl_camsys`` (not needed here).
- Frame: camera-frame joints = ``pred_xyz_29 * depth_factor + pred_cam_root``; OpenCV axes (the
  heatmap's u right, v down, depth forward), metres.
- Focal: 1000 px for the 256 px input, so f = 1000 / 256 * box width px on the original image,
  **one per person** (``focal_length`` (P,) in each frame); principal point = image centre.
- 2D: ``(cx, cy) + uv * w`` (box centre and side w; the box is square), exactly the projection
  of the camera-frame joints with that focal.
- Depth factor: 2.2 m in the demo's config, 2.0 m in configs without ``BBOX_3D_SHAPE``
  (``HRNetSMPLCam.__init__`` default); read here from the file itself, as the value for which
  the camera-frame joints reproject onto ``pred_uvd``.
- Meshes: ``SMPL(pred_thetas, pred_betas)`` with ``--smpl-model``, placed with its pelvis joint at
  ``transl`` (meshes and joints then agree). HybrIK's own render centres the mesh on the
  H36M-regressed pelvis instead (``J_regressor_h36m``, not part of SMPL's ``.npz``): the two
  differ by the offset between the two pelvis definitions.
- Joints: SMPL-24 = the first 24 of the 29 (``JOINT_NAMES``), or the posed model's with
  ``--smpl-model``. 2D layout ``hybrik29``: SMPL-24, then head (top), left/right middle
  (fingertips), left/right big toe.
- HybrIK-X (``scripts/demo_video_x.py``, SMPL-X) writes a ``res.pk`` too, without
  ``pred_xyz_29``: refused (its SMPL-X pose needs HybrIK-X's own kid shape space).
- Rows sharing an ``img_path`` are people of one frame (the demo writes one per image); with
  one person per frame the demo's single tracked person gets ``person_ids`` 0 (its video's index
  when the file holds several).
- Several videos: the demo extracts ``<out-dir>/raw_images/<video>-%06d.png`` and processes every
  image in that folder, so runs sharing an ``--out-dir`` write one ``res.pk`` of several videos
  (several cameras, perhaps of several image sizes). They import as one sequence (frame names keep
  the video's name; each frame its own ``image_size`` and ``principal_point`` when the sizes differ)
  with a warning naming ``--video NAME``, which imports one video's rows only.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..geometry.camera import MAX_IMAGE_SIDE_PX, project_cam_to_px
from ..errors import file_error
from ..geometry.focal import ASSUMED, hybrik_focal_px
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces, no_model_warning
from .smpl import lbs, pose_to_matrices, smpl_param_arrays

__all__ = ["sniff", "read_hybrik", "READERS", "HYBRIK29_JOINT_NAMES", "fitted_depth_factor_m", "uvd_to_px", "video_of"]

# SMPL_layer.JOINT_NAMES: SMPL's 24 in SMPL's order, named HybrIK's way (15 'jaw' is SMPL's 'head' joint,
# 22/23 'left_thumb'/'right_thumb' SMPL's 'left_hand'/'right_hand'), then the 5 leaves (24 'head' = head top).
HYBRIK29_JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
    "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "jaw",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_thumb", "right_thumb", "head", "left_middle", "right_middle", "left_bigtoe", "right_bigtoe",
)
_N_JOINTS = len(HYBRIK29_JOINT_NAMES)
_KEYPOINTS_LAYOUT = "hybrik29 (SMPL-24 + head top, middle fingertips, big toes)"
# bbox_3d_shape / 1000 (m) of HybrIK's configs: 2200 (the demo's hrw48 config), 2000 (the default).
_DEPTH_FACTORS_M = (2.2, 2.0)
_DEPTH_FACTOR_SNAP = 0.01  # a fitted factor within 1 % of a config's is that config's
_REPROJECTION_TOL_PX = 1.0  # the demo's own joints reproject to ~1e-4 px (float32); anything near 1 px is another camera
_DEMO_DEPTH_FACTOR_M = 2.2  # used when the file has no pred_uvd to recover it from
_MAX_SNIFF_BYTES = 512 << 20


def sniff(path: Path) -> str | None:
    """'hybrik' for a pickle of HybrIK's ``res_db``: a dict with ``pred_uvd``, ``transl`` and ``img_path``."""
    if not (path.is_file() and path.suffix in (".pk", ".pkl")) or path.stat().st_size > _MAX_SNIFF_BYTES:
        return None
    data = load_file(path)
    if isinstance(data, Mapping) and "img_path" in data and "transl" in data and (
            "pred_xyz_29" in data or "pred_uvd" in data):
        return "hybrik"
    return None


# ---- geometry (pure) -------------------------------------------------------------------------
def box_geometry(bbox_xyxy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (N, 2) px and widths (N,) px of xyxy boxes (N, 4)."""
    return 0.5 * (bbox_xyxy[:, :2] + bbox_xyxy[:, 2:]), bbox_xyxy[:, 2] - bbox_xyxy[:, 0]


def uvd_to_px(uvd: np.ndarray, bbox_xyxy: np.ndarray) -> np.ndarray:
    """HybrIK's box-normalised uv (N, K, 2|3) -> original-image pixels (N, K, 2): centre + uv * side."""
    centre, side = box_geometry(bbox_xyxy)
    return centre[:, None] + uvd[..., :2] * side[:, None, None]


def joints_cam(xyz_rel: np.ndarray, root_cam: np.ndarray, depth_factor_m: float) -> np.ndarray:
    """Camera-frame joints (N, K, 3) m from root-relative ``xyz_rel`` (N, K, 3, depth-factor units)
    and the camera-frame root (N, 3) m."""
    return xyz_rel * depth_factor_m + root_cam[:, None]


def fitted_depth_factor_m(xyz_rel: np.ndarray, uv_px: np.ndarray, root_cam: np.ndarray, focal_px: np.ndarray,
                          principal_point: tuple[float, float] | np.ndarray) -> float:
    """The depth factor s (m) for which ``xyz_rel * s + root_cam`` projects onto ``uv_px``.

    xyz_rel: (N, K, 3); uv_px: (N, K, 2); root_cam: (N, 3) m; focal_px: (N,); principal_point: (2,)
    or (N, 2) px (one per row: rows of images of different sizes). Linear least squares of
    ``(u - c) (Z s + R_z) = f (X s + R_x)`` (and the same in v) over every joint.
    """
    centre = np.broadcast_to(np.asarray(principal_point, np.float64), (len(xyz_rel), 2))
    rows, rhs = [], []
    for axis in (0, 1):
        offset = uv_px[..., axis] - centre[:, None, axis]  # (N, K)
        rows.append(offset * xyz_rel[..., 2] - focal_px[:, None] * xyz_rel[..., axis])
        rhs.append(focal_px[:, None] * root_cam[:, None, axis] - offset * root_cam[:, None, 2])
    a, b = np.concatenate(rows).ravel(), np.concatenate(rhs).ravel()
    ok = np.isfinite(a) & np.isfinite(b)
    denominator = float(a[ok] @ a[ok])
    return float(a[ok] @ b[ok]) / denominator if denominator > 0 else float("nan")


def reprojection_rms_px(xyz_rel, uv_px, root_cam, focal_px, principal_point, depth_factor_m: float) -> float:
    """RMS (px) between ``uv_px`` (N, K, 2) and the camera-frame joints projected with ``focal_px`` (N,)
    and ``principal_point`` (2,) or (N, 2)."""
    centre = np.broadcast_to(np.asarray(principal_point, np.float64), (len(xyz_rel), 2))
    projected = project_cam_to_px(joints_cam(xyz_rel, root_cam, depth_factor_m), focal_px[:, None], centre[:, None])
    return float(np.sqrt(np.nanmean(np.sum((projected - uv_px) ** 2, axis=-1))))


def choose_depth_factor_m(xyz_rel, uv_px, root_cam, focal_px, principal_point) -> tuple[float, float]:
    """(depth factor m, its reprojection RMS px): a config's value when the fit is within 1 % of it.

    Raises ValueError when no factor makes the joints reproject onto ``uv_px``.
    """
    fitted = fitted_depth_factor_m(xyz_rel, uv_px, root_cam, focal_px, principal_point)
    if not np.isfinite(fitted) or fitted <= 0:
        raise ValueError("pred_xyz_29 and pred_uvd do not determine a depth factor")
    known = [s for s in _DEPTH_FACTORS_M if abs(fitted - s) <= _DEPTH_FACTOR_SNAP * s]
    factor = known[0] if known else fitted
    rms = reprojection_rms_px(xyz_rel, uv_px, root_cam, focal_px, principal_point, factor)
    if not rms <= _REPROJECTION_TOL_PX:
        raise ValueError(f"pred_xyz_29 does not reproject onto pred_uvd through HybrIK's camera (best depth "
                         f"factor {fitted:.3f} m leaves {rms:.1f} px)")
    return factor, rms


# ---- reading ---------------------------------------------------------------------------------
_VIDEO_FRAME = re.compile(r"^(?P<video>.+)-\d+$")  # demo_video.py: ffmpeg writes <video basename>-%06d.png


def video_of(img_path: str) -> str:
    """The video an image of HybrIK's demo was extracted from: ``raw_images/IMG_6412-000001.png`` ->
    ``IMG_6412`` (``demo_video.py`` extracts ``<video basename>-%06d.png``); '' for other names."""
    match = _VIDEO_FRAME.match(Path(img_path).stem)
    return match["video"] if match else ""


def _image_sizes(data: Mapping, n_rows: int, src: Path) -> np.ndarray:
    """(N, 2) int (W, H) px of each row's image, from 'width' / 'height'."""
    widths = as_array(get(data, "width", src), "width", src, ndim=1).reshape(-1)
    heights = as_array(get(data, "height", src), "height", src, ndim=1).reshape(-1)
    if len(widths) != n_rows or len(heights) != n_rows:
        raise file_error(src, f"'width'/'height' must have one entry per row ({n_rows})")
    sizes = np.stack([widths, heights], axis=1)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(sizes) & (sizes >= 1) & (sizes <= MAX_IMAGE_SIDE_PX)
    if not valid.all():
        bad = sizes[np.argmin(valid.all(axis=1))].tolist()
        raise file_error(src, f"'width'/'height' must be image sizes of 1 to {MAX_IMAGE_SIDE_PX} px, got {bad}")
    return sizes.astype(np.int64)


def _videos(videos: list[str], sizes: np.ndarray, frames: list[tuple[str, list[int]]]) -> dict[str, str]:
    """Each video's description, in file order: ``'IMG_6412': '135 frames, 384x640'``."""
    found: dict[str, list] = {}
    for path, picks in frames:
        entry = found.setdefault(videos[picks[0]], [0, set()])
        entry[0] += 1
        entry[1].add(tuple(sizes[picks[0]].tolist()))
    return {video: f"{n} frames, {', '.join(f'{w}x{h}' for w, h in sorted(shapes))}"
            for video, (n, shapes) in found.items()}


def _listed(described: dict[str, str]) -> str:
    """'IMG_6412: 135 frames, 384x640; dance: 80 frames, 1280x720' (messages, meta.yaml)."""
    return "; ".join(f"{name or '(no video name)'}: {what}" for name, what in described.items())


def _select_video(videos: list[str], video: str | None, src: Path, described: dict[str, str]) -> np.ndarray:
    """Indices of the rows to import: every row, or those of ``video`` (``--video``)."""
    if video is None:
        return np.arange(len(videos))
    picked = np.flatnonzero(np.asarray(videos) == video)
    if not picked.size:
        raise file_error(src, f"holds no video named '{video}' (--video); its videos: {_listed(described)}")
    return picked


def _several_videos_warning(src: Path, described: dict[str, str], per_frame_sizes: bool) -> str:
    """The import note for a res.pk holding several videos: what was done and how to get one sequence each."""
    listed = _listed(described)
    named = [name for name in described if name]
    how = (f"import each as a sequence of its own: rotavat import {src} OUT --video NAME "
           f"({', '.join(named)})" if named else "split its frames into one sequence per video")
    return (f"{src}: holds {len(described)} videos ({listed}; demo_video.py run on each with one --out-dir): "
            f"{len(described)} cameras imported as one sequence, frame names keeping each video's name"
            + (", each frame its own image_size and principal_point" if per_frame_sizes else "")
            + f"; calibrate and align need one camera: {how}")


def _person_ids_note(video_ids: dict[str, int]) -> str:
    """meta.yaml ``import.person_ids`` for the demo's one tracked person (one per video)."""
    if len(video_ids) == 1:
        return "0: the demo's one tracked person"
    ids = ", ".join(f"{name or '(no video name)'}: {i}" for name, i in video_ids.items())
    return f"the demo's one tracked person of each video: the video's index in res.pk ({ids})"


def _rows(data: Mapping, src: Path) -> dict[str, np.ndarray]:
    """The arrays the import needs, validated: one row per (image, person)."""
    if "pred_xyz_29" not in data and "pred_uvd" in data:
        raise file_error(src, "a HybrIK-X (SMPL-X, demo_video_x.py) res.pk: it has no 'pred_xyz_29' camera joints and "
                              "its SMPL-X pose uses HybrIK-X's own kid shape space; not supported")
    xyz = as_array(get(data, "pred_xyz_29", src), "pred_xyz_29", src, ndim=3, last=(_N_JOINTS, 3))
    n_rows = len(xyz)
    out = {"xyz": xyz}
    out["transl"] = as_array(get(data, "transl", src), "transl", src, ndim=2, last=(3,))
    root = data.get("pred_cam_root")
    out["root"] = out["transl"] if root is None else as_array(root, "pred_cam_root", src, ndim=2, last=(3,))
    out["bbox"] = as_array(get(data, "bbox", src), "bbox", src, ndim=2, last=(4,))
    if data.get("pred_uvd") is not None:
        out["uvd"] = as_array(data["pred_uvd"], "pred_uvd", src, ndim=3, last=(_N_JOINTS, 3))
    paths = get(data, "img_path", src)
    if not isinstance(paths, (np.ndarray, list, tuple)) or np.ndim(paths) != 1 or not all(isinstance(p, str) for p in paths):
        raise file_error(src, "'img_path' must be a list of image paths")
    try:  # corrupt unicode arrays hold code points no string may (SystemError once the text is read)
        out["img_path"] = np.asarray([str(p).encode("utf-8").decode("utf-8") for p in paths])
    except (UnicodeError, SystemError):
        raise file_error(src, "'img_path' holds invalid text") from None
    for key, value in out.items():
        if len(value) != n_rows:
            raise file_error(src, f"'{key if key != 'xyz' else 'pred_xyz_29'}' has {len(value)} rows but 'pred_xyz_29' has {n_rows}")
    widths = box_geometry(out["bbox"])[1]
    if n_rows and not (np.all(np.isfinite(widths)) and widths.min() > 0):
        raise file_error(src, "'bbox' must hold boxes [x1, y1, x2, y2] with x2 > x1 (HybrIK's focal scales with the box width)")
    return out


def _pose_params(data: Mapping, n_rows: int, src: Path, warnings: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
    """(rotations (N, 24, 3, 3), betas (N, B)) or None (warned) when the thetas are quaternions."""
    thetas = as_array(get(data, "pred_thetas", src), "pred_thetas", src)
    betas = as_array(get(data, "pred_betas", src), "pred_betas", src, ndim=2)
    if len(thetas) != n_rows or len(betas) != n_rows:
        raise file_error(src, f"'pred_thetas'/'pred_betas' must have {n_rows} rows")
    if thetas.reshape(n_rows, -1).shape[1] == 24 * 4:
        warnings.append(f"{src}: 'pred_thetas' holds quaternions (an older HybrIK); they are not read: joints only, "
                        "no meshes")
        return None
    try:
        return pose_to_matrices(thetas.reshape(n_rows, -1), 24), betas
    except ValueError:
        raise file_error(src, f"'pred_thetas' must be 24 rotation matrices per row, got shape {list(thetas.shape)}") from None


def _frames(img_paths: np.ndarray) -> list[tuple[str, list[int]]]:
    """(image path, its rows) in first-appearance order."""
    groups: dict[str, list[int]] = {}
    for row, path in enumerate(img_paths.tolist()):
        groups.setdefault(path, []).append(row)
    return list(groups.items())


def read_hybrik(src: Path, opts: ImportOptions) -> ImportedSequence:
    """HybrIK ``res.pk`` -> contract frames with one focal per person."""
    data = load_file(src)
    if not isinstance(data, Mapping):
        raise file_error(src, f"not a HybrIK res.pk (expected a dict of arrays, got {type(data).__name__})")
    rows = _rows(data, src)
    n_rows = len(rows["xyz"])
    if n_rows == 0:
        raise file_error(src, "holds no detections")
    sizes = _image_sizes(data, n_rows, src)  # (N, 2)
    videos = [video_of(path) for path in rows["img_path"].tolist()]
    described = _videos(videos, sizes, _frames(rows["img_path"]))
    keep = _select_video(videos, opts.video, src, described)
    video_ids = {name: i for i, name in enumerate(described)}  # person id of the demo's one tracked person
    row_video = np.asarray([video_ids[v] for v in videos], np.int64)[keep]
    rows, sizes = {key: value[keep] for key, value in rows.items()}, sizes[keep]
    frames = _frames(rows["img_path"])
    for path, picks in frames:
        if len(np.unique(sizes[picks], axis=0)) > 1:
            raise file_error(src, f"the rows of image '{path}' state different image sizes ('width'/'height')")
    warnings: list[str] = []
    stored = sorted({tuple(size) for size in sizes.tolist()})
    per_frame_sizes = len(stored) > 1  # images of several sizes: each frame states its own (contract keys)
    if opts.image_size is not None and [tuple(opts.image_size)] != stored:
        warnings.append(f"{src}: --image-size {opts.image_size[0]}x{opts.image_size[1]} ignored: HybrIK ran on "
                        f"{', '.join(f'{w}x{h}' for w, h in stored)} images (its stored 'width'/'height')")
    if len(np.unique(row_video)) > 1:
        warnings.append(_several_videos_warning(src, described, per_frame_sizes))
    elif per_frame_sizes:
        warnings.append(f"{src}: the images differ in size ({', '.join(f'{w}x{h}' for w, h in stored)}): each frame "
                        "carries its own image_size and principal_point; a static-camera calibration needs the "
                        "frames of one size")
    centres = sizes / 2.0  # (N, 2) principal point of each row: its image's centre
    focal_px = hybrik_focal_px(box_geometry(rows["bbox"])[1])  # (N,)
    if "uvd" in rows:
        uv_px = uvd_to_px(rows["uvd"], rows["bbox"])
        try:
            depth_factor, rms = choose_depth_factor_m(rows["xyz"], uv_px, rows["root"], focal_px, centres)
        except ValueError as exc:
            raise file_error(src, str(exc)) from None
        depth_from = f"fitted to pred_uvd (reprojection rms {rms:.2g} px)"
    else:
        uv_px, depth_factor, depth_from = None, _DEMO_DEPTH_FACTOR_M, "demo_video.py's config (no pred_uvd to check it)"
        warnings.append(f"{src}: no 'pred_uvd': depth factor {depth_factor} m assumed (demo_video.py's config); "
                        "2D keypoints are the projected joints")
    if depth_factor not in _DEPTH_FACTORS_M:
        warnings.append(f"{src}: depth factor {depth_factor:.4f} m is none of HybrIK's configs' ({_DEPTH_FACTORS_M}); "
                        "used as fitted")
    joints29 = joints_cam(rows["xyz"], rows["root"], depth_factor)
    if uv_px is None:
        uv_px = project_cam_to_px(joints29, focal_px[:, None], centres[:, None])
    model = opts.body_model
    pose = None
    if model is not None:
        check_model_kind(model, src, "HybrIK", "smpl")
        pose = _pose_params(data, n_rows, src, warnings)
        pose = None if pose is None else (pose[0][keep], pose[1][keep])
    elif "pred_thetas" in data:
        warnings.append(no_model_warning("HybrIK"))
    names = frame_names([Path(path).stem for path, _ in frames], warnings)
    tracked = all(len(picks) == 1 for _, picks in frames)  # the demo's single IoU-tracked person (per video)
    faces = model_faces(model, None if pose is None else model.n_verts)

    def posed(picks: list[int]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Camera-frame meshes, SMPL-24 joints (the model's pelvis joint at ``transl``) and body parameters."""
        rot, betas = pose
        verts, joints = lbs(model, betas[picks], rot[picks])
        shift = rows["transl"][picks] - joints[:, 0]
        joints = joints + shift[:, None]
        return verts + shift[:, None], joints, smpl_param_arrays(model, betas[picks], rot[picks], shift, joints)

    def build(index: int, notes: FrameNotes) -> Frame:
        path, picks = frames[index]
        source = f"{src} [{path}]"
        verts, joints, params = posed(picks) if pose is not None else (None, joints29[picks, :24], None)
        # people_frame drops people with non-finite joints or vertices: their focals go with them
        kept = np.isfinite(joints).reshape(len(picks), -1).all(axis=1)
        if verts is not None:
            kept &= np.isfinite(verts).reshape(len(picks), -1).all(axis=1)
        extra = {"focal_length": focal_px[picks][kept]} if kept.any() else {}
        if per_frame_sizes:  # images of several sizes: each frame states its own (contract frame keys)
            extra.update(image_size=sizes[picks[0]].copy(), principal_point=centres[picks[0]].copy())
        return people_frame(names[index], source, notes.warnings, vertices=verts, joints=joints,
                            keypoints_2d=uv_px[picks], faces=faces,
                            person_ids=row_video[picks] if tracked else None,
                            extra=extra or None, keypoints_layout=_KEYPOINTS_LAYOUT, body_params=params)

    size, centre = (None, None) if per_frame_sizes else (stored[0], (stored[0][0] / 2.0, stored[0][1] / 2.0))
    meta = base_meta("hybrik", src, opts, size, None, centre, focal_kind=ASSUMED)
    read = set(row_video.tolist())
    meta["import"].update({
        "source_frames": [Path(path).name for path, _ in frames],
        "image_size_from": "HybrIK 'width'/'height'" + (", per image (the images differ in size)" if per_frame_sizes else ""),
        "videos": {name: what for name, what in described.items() if video_ids[name] in read},
        "video": opts.video,
        "joints_layout": "smpl24",
        "root_joint": 0,
        "keypoints_2d_layout": _KEYPOINTS_LAYOUT,
        "feet_heads_from": feet_heads_from(_KEYPOINTS_LAYOUT, pose is not None),
        "focal_per_person": "1000 / 256 * bbox width (frame key focal_length, one per person)",
        "depth_factor_m": float(depth_factor),
        "depth_factor_from": depth_from,
        "person_ids": _person_ids_note(video_ids) if tracked else None,
        "conventions": "camera frame = OpenCV, metres; joints = pred_xyz_29 * depth factor + pred_cam_root"
                       + ("; vertices = SMPL(pred_thetas, pred_betas), pelvis joint at transl" if pose is not None else "")
                       + "; principal point = image centre",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"hybrik": read_hybrik}
