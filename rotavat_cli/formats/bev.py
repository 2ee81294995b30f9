"""BEV and ROMP (``simple_romp``: the ``bev`` / ``romp`` commands): one ``.npz`` per image.

Source: Arthur151/ROMP ``simple_romp/bev/main.py``, ``simple_romp/bev/post_parser.py``
(``denormalize_cam_params_to_trans``, ``body_mesh_projection2image``, ``SMPLA_parser``),
``simple_romp/romp/main.py``, ``simple_romp/romp/post_parser.py``, ``simple_romp/romp/utils.py``
(``padding_image``, ``ResultSaver``, ``save_video_results``), ``simple_romp/romp/smpl.py``,
``simple_romp/vis_human/pyrenderer.py``.

- File: ``np.savez(path, results=outputs)``: a 0-d *object* array holding a dict (read here with
  the restricted unpickler). Video mode also writes ``video_results.npz`` (``results`` = dict
  image name -> that dict). Keys: ``verts`` (P, 6890, 3), ``joints`` (P, 71 or 54, 3; SMPL-24
  first), ``cam`` (P, 3), ``cam_trans`` (P, 3), ``pj2d_org`` (P, J, 2), ``smpl_thetas`` (P, 72),
  ``smpl_betas`` (P, 11 for BEV's SMPL+A, 10 for ROMP), ``center_confs``, ``track_ids`` (with
  ``--temporal_optimize``).
- Frame: ``verts`` and ``joints`` do *not* include the translation: camera frame = ``verts +
  cam_trans``, OpenCV axes (x right, y down, z forward), metres. BEV root-aligns them first (minus
  the mean of joints 45 and 46), ROMP does not; either way ``+ cam_trans`` is the camera frame.
- Focal: the network sees the image zero-padded to a centred square of side S = max(W, H)
  (``padding_image``) resized to 512, with a fixed 60 degree field of view: BEV projects with
  f = 443.4 px on 512 (``perspective_projection(..., focal_length=443.4)``), i.e.
  f = 443.4 / 512 * S ~= S / (2 tan 30 deg) on the original image; principal point = centre of the
  padded square, ``(S/2 - left, S/2 - top)``. ROMP's renderer uses the same 60 degree camera.
- ROMP is weak-perspective: its ``cam_trans = 2 (tx/s, ty/s, 1/s)`` is a rough conversion, so its
  meshes only approximately reproject onto the image in that camera.
- 2D: ``pj2d_org`` are in original-image pixels (``convert_proejection_from_input_to_orgimg``).
- Image size: not stored; ``--image-size``, else inferred from ``pj2d_org`` against the 3D joints
  (exact for BEV up to one pixel of padding parity): once for a video, per file in image mode. When
  the photos differ in size, each frame states its own ``image_size``, ``focal_length`` and
  ``principal_point`` (contract frame keys) and meta.yaml none; a frame whose size cannot be
  inferred among photos of different sizes is refused.
- Names (``ResultSaver.__call__``, Arthur151/ROMP @012086a simple_romp/romp/utils.py:
  ``splitext(save_path)[0] + f'_{prefix}'``): image mode ``<image>_<center_thresh>.npz``
  (``image_1_0.08.npz``), video mode ``<frame>__<model id>_<center_thresh>.npz``; frame names drop
  the suffix.
- BEV or ROMP: ``smpl_betas`` has 11 values (SMPL+A) for BEV, 10 for ROMP; reading a file with the
  other's reader is refused, saying which it is. Both write 71 joints (``romp/smpl.py``
  ``VertexJointSelector``: SMPL-24, 21 vertex joints, 9 regressed extra, 17 H36M; layout ``romp71``,
  formats/keypoints.py), which give ``feet_2d``/``heads_2d`` for frames without ``verts``.
"""

from __future__ import annotations

import re
import zipfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, BEV_FOCAL_ON_512, focal_from_rule
from ..sequence import Frame
from ..unpickle.npz import load_npz
from .content import as_array, get
from .frame_names import frame_names, natural_key
from .frames import people_frame
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces
from .smpl import lbs

_NET_INPUT = 512
# simple_romp's joints (romp/smpl.py VertexJointSelector): SMPL-24, 21 vertex joints, 9 regressed extra, 17 H36M;
# older ROMP releases stop at 54 (formats/keypoints.py)
_LAYOUT_BEV = "romp71 (SMPL-24, 21 vertex joints, 9 extra, 17 H36M)"
# ROMP's camera, as rotavat reads it: its keypoints are the weak-perspective projection it predicted, its meshes
# sit at cam_trans = 2 (tx/s, ty/s, 1/s) in the 60-degree camera, which draws them smaller and nearer the centre
_ROMP_REPROJECTS = ("only approximately in the 60-degree camera (cam_trans is its rough depth 2/s; its 2D keypoints "
                    "are the weak-perspective projection)")
_LAYOUT_ROMP = _LAYOUT_BEV


def _is_results_npz(path: Path) -> bool:
    with zipfile.ZipFile(path) as archive:
        return "results.npy" in archive.namelist()


def sniff(path: Path) -> str | None:
    """'bev' or 'romp' for a results .npz (or a directory of them): SMPL+A betas (11) mean BEV."""
    files = [path] if path.is_file() else sorted(path.glob("*.npz"))[:3] if path.is_dir() else []
    for file in files:
        if file.suffix == ".npz" and _is_results_npz(file):
            results = load_npz(file, keys=("results",))["results"].item()
            if isinstance(results, dict) and results and all(isinstance(v, dict) for v in results.values()):
                results = next(iter(results.values()))  # video_results.npz
            betas = results.get("smpl_betas") if isinstance(results, dict) else None
            return "bev" if betas is not None and np.shape(betas)[-1] == 11 else "romp"
    return None


def _sources(src: Path) -> list[tuple[str, Callable[[], dict]]]:
    """(image name, loader of its results dict) in image order."""
    if src.is_dir():
        files = [p for p in src.glob("*.npz") if p.name != "video_results.npz"]
        if not files and (src / "video_results.npz").exists():
            files = [src / "video_results.npz"]
        files.sort(key=lambda p: natural_key(p.name))
    else:
        files = [src]
    if not files:
        raise file_error(src, "no .npz result files found")
    if len(files) == 1 and files[0].name == "video_results.npz":
        results = _load_results(files[0])
        if not all(isinstance(v, dict) for v in results.values()):
            raise file_error(files[0], "'results' must map image names to result dicts")
        return [(name, (lambda v=value: v)) for name, value in sorted(results.items(), key=lambda kv: natural_key(str(kv[0])))]
    return [(p.stem, (lambda p=p: _load_results(p))) for p in files]


def _image_stem(name: str) -> str:
    """Image stem of a result name: drop the extension and the suffix simple_romp's ``ResultSaver`` adds
    (``save_path = <image stem>_<prefix>``): ``_<center_thresh>`` in image mode (``image_1_0.08`` ->
    ``image_1``), ``__<model id>_<center_thresh>`` in video mode. Other names are kept."""
    stem = Path(name).stem if Path(name).suffix.lower() in (".png", ".jpg", ".jpeg", ".npz") else name
    stem = re.sub(r"__\d+_\d+(\.\d+)?$", "", stem)
    return re.sub(r"(?<=.)_\d*\.\d+$", "", stem)


def _load_results(path: Path) -> dict:
    """The dict stored in an .npz's 'results' object array."""
    data = load_npz(path, keys=("results",))  # other members are never read
    if "results" not in data:
        raise file_error(path, "not a ROMP/BEV result file (no 'results' array)")
    results = data["results"]
    if results.shape != () or not isinstance(results.item(), dict):
        raise file_error(path, "'results' must hold a dict")
    return results.item()


def _people(results: dict, source: str, fmt: str, opts: ImportOptions) -> dict[str, np.ndarray | None]:
    """Camera-frame vertices/joints, 2D keypoints, ids and the projection inputs of one result dict."""
    cam_trans = as_array(get(results, "cam_trans", source), "cam_trans", source, ndim=2, last=(3,))
    n_people = len(cam_trans)
    verts = results.get("verts")
    joints = results.get("joints")
    out: dict[str, np.ndarray | None] = {"vertices": None, "joints": None, "keypoints_2d": None, "person_ids": None}
    if verts is not None:
        out["vertices"] = as_array(verts, "verts", source, ndim=3, last=(3,)) + cam_trans[:, None]
    if joints is not None:
        joints = as_array(joints, "joints", source, ndim=3, last=(3,))
        if joints.shape[1] < 24:
            raise file_error(source, f"'joints' must hold at least the 24 SMPL joints, got {joints.shape[1]}")
        out["joints"] = joints[:, :24] + cam_trans[:, None]
        out["_joints_all_cam"] = joints + cam_trans[:, None]
        out["_joints_rel"] = joints
    model = opts.body_model
    if model is not None and (out["vertices"] is None or out["joints"] is None) and fmt == "romp":
        thetas = as_array(get(results, "smpl_thetas", source), "smpl_thetas", source, ndim=2)
        betas = as_array(get(results, "smpl_betas", source), "smpl_betas", source, ndim=2)
        v, j = lbs(model, betas[:, :10], thetas, cam_trans)  # ROMP's meshes are not root-aligned
        out["vertices"] = v if out["vertices"] is None else out["vertices"]
        out["joints"] = j[:, :24] if out["joints"] is None else out["joints"]
    if out["vertices"] is None and out["joints"] is None:
        raise file_error(source, "holds neither 'verts' nor 'joints' (was it run with --calc_smpl?)")
    if results.get("pj2d_org") is not None:
        out["keypoints_2d"] = as_array(results["pj2d_org"], "pj2d_org", source, ndim=3, last=(2,))
    if results.get("track_ids") is not None:
        out["person_ids"] = as_array(results["track_ids"], "track_ids", source, kinds="iu").reshape(-1)
    if results.get("cam") is not None:
        out["_cam"] = as_array(results["cam"], "cam", source, ndim=2, last=(3,))
    for key, value in out.items():
        if value is not None and len(value) != n_people:
            raise file_error(source, f"'{key}' has {len(value)} people but 'cam_trans' has {n_people}")
    return out


def _normalized_xy(people: dict, fmt: str) -> np.ndarray | None:
    """Joint positions in the network's normalized [-1, 1] square, as the tool computed pj2d."""
    if fmt == "bev" and people.get("_joints_all_cam") is not None:
        joints = people["_joints_all_cam"]
        return BEV_FOCAL_ON_512 / (_NET_INPUT / 2) * joints[..., :2] / joints[..., 2:3]
    if fmt == "romp" and people.get("_joints_rel") is not None and people.get("_cam") is not None:
        cam = people["_cam"]
        return people["_joints_rel"][..., :2] * cam[:, None, :1] + cam[:, None, 1:]
    return None


def _infer_image_size(norm: np.ndarray, pix: np.ndarray, source: str) -> tuple[tuple[int, int], int, int] | None:
    """Fit u = (n_x + 1) S/2 - left, v = (n_y + 1) S/2 - top: -> ((W, H), left, top) or None."""
    n = norm.reshape(-1, 2)
    p = pix[..., :2].reshape(-1, 2)
    ok = np.isfinite(n).all(axis=1) & np.isfinite(p).all(axis=1)
    n, p = n[ok], p[ok]
    if len(n) < 2 or np.ptp(n) < 1e-6:
        return None
    A = np.zeros((2 * len(n), 3))
    A[0::2, 0], A[0::2, 1] = n[:, 0], 1.0
    A[1::2, 0], A[1::2, 2] = n[:, 1], 1.0
    coef, *_ = np.linalg.lstsq(A, p.reshape(-1), rcond=None)
    if np.max(np.abs(A @ coef - p.reshape(-1))) > 1.0 or coef[0] <= 0:
        return None
    side = int(round(2 * coef[0]))
    left, top = int(round(side / 2 - coef[1])), int(round(side / 2 - coef[2]))
    if min(left, top) != 0 or max(left, top) < 0 or max(left, top) > side // 2:
        return None
    return (side - 2 * left, side - 2 * top), left, top


_VIDEO_NAME = re.compile(r"__\d+_\d+(\.\d+)?$")  # ResultSaver's video-mode suffix: one video, one image size


def _check_family(results: dict, fmt: str, source: str) -> None:
    """InputError for a BEV result read as ROMP or the other way round (SMPL+A betas: 11 = BEV, 10 = ROMP)."""
    betas = results.get("smpl_betas") if isinstance(results, dict) else None
    n_betas = np.shape(betas)[-1] if betas is not None and np.ndim(betas) >= 1 else None
    joints = results.get("joints") if isinstance(results, dict) else None
    n_joints = np.shape(joints)[1] if joints is not None and np.ndim(joints) == 3 else "no"
    if fmt == "romp" and n_betas == 11:
        raise file_error(source, f"this is a BEV result (11 SMPL+A shape parameters, {n_joints} joints), not ROMP's: "
                                 "read it with --from bev")
    if fmt == "bev" and n_betas == 10:
        raise file_error(source, f"this is a ROMP result (10 SMPL shape parameters, {n_joints} joints), not BEV's: "
                                 "read it with --from romp")


def _frame_geometry(results: dict, source: str, fmt: str, opts: ImportOptions) -> tuple[tuple[int, int], int, int] | None:
    """((W, H), left, top) of one result's image, fitted from its pj2d_org (None when it cannot be)."""
    people = _people(results, source, fmt, opts)
    norm = _normalized_xy(people, fmt)
    if norm is None or people["keypoints_2d"] is None or not len(norm):
        return None
    return _infer_image_size(norm, people["keypoints_2d"], source)


def _geometry_of(size: tuple[int, int]) -> tuple[tuple[int, int], int, int]:
    side = max(size)
    return tuple(size), (side - size[0]) // 2, (side - size[1]) // 2


def _geometries(src: Path, sources: list, fmt: str, opts: ImportOptions, warnings: list[str]) -> tuple[list, str]:
    """Every frame's ((W, H), left, top) and where the sizes came from.

    --image-size: that size for every frame. A video (``video_results.npz`` or video-mode file names):
    one size, fitted on the first frames that allow it. Otherwise (image mode: photos, perhaps of
    different sizes) each frame's own size, fitted on its own 2D keypoints; a frame whose size cannot
    be fitted takes the others' when they agree, else the import is refused.
    """
    if opts.image_size is not None:
        return [_geometry_of(opts.image_size)] * len(sources), "--image-size"
    per_image_files = [src] if src.is_file() else [p for p in src.glob("*.npz") if p.name != "video_results.npz"]
    video = not per_image_files or per_image_files == [src] and src.name == "video_results.npz" or (
        len(sources) > 1 and all(_VIDEO_NAME.search(Path(name).stem) for name, _ in sources))
    found: list = []
    for name, load in (sources[:50] if video else sources):
        results = load()
        _check_family(results, fmt, f"{src} [{name}]")
        found.append(_frame_geometry(results, f"{src} [{name}]", fmt, opts))
        if video and found[-1] is not None:
            break
    known = {g for g in found if g is not None}
    if not known:
        raise file_error(src, f"the image size is not stored in {fmt} results and could not be inferred from "
                              "'pj2d_org'; pass --image-size W H")
    if video or len(known) == 1:
        (geometry,) = known if len(known) == 1 else [next(g for g in found if g is not None)]
        size = geometry[0]
        warnings.append(f"{src}: image size {size[0]}x{size[1]} inferred from the 2D keypoints "
                        "(+-1 px when the padding is odd); pass --image-size W H to be exact")
        return [geometry] * len(sources), "inferred from pj2d_org"
    missing = [sources[i][0] for i, g in enumerate(found) if g is None]
    if missing:
        raise file_error(src, f"the images differ in size and the size of '{missing[0]}' could not be inferred from "
                              "its 'pj2d_org' (one --image-size cannot serve images of different sizes): import the "
                              "images of each size separately with --image-size W H")
    sizes = ", ".join(sorted({f"{g[0][0]}x{g[0][1]}" for g in found}))
    warnings.append(f"{src}: the images differ in size ({sizes}): each frame carries its own image_size, "
                    "focal_length and principal_point, inferred from its 2D keypoints (+-1 px when the padding is "
                    "odd); a static-camera calibration needs the frames of one size")
    return found, "inferred from pj2d_org, per image (the images differ in size)"


def _read(src: Path, opts: ImportOptions, fmt: str) -> ImportedSequence:
    sources = _sources(src)
    warnings: list[str] = []
    if opts.image_size is not None:  # the geometry needs no frame: check the family on the first one
        _check_family(sources[0][1](), fmt, f"{src} [{sources[0][0]}]")
    geometries, size_origin = _geometries(src, sources, fmt, opts, warnings)
    per_frame = len({g[0] for g in geometries}) > 1
    intrinsics = [(focal_from_rule(fmt, size), (max(size) / 2.0 - left, max(size) / 2.0 - top))
                  for size, left, top in geometries]
    if fmt == "romp":
        warnings.append(f"romp is weak-perspective: its meshes reproject {_ROMP_REPROJECTS}")
    model = opts.body_model
    names = frame_names([_image_stem(name) for name, _ in sources], warnings)
    # BEV's meshes come whole: of the model, only its triangles are used (the rest need not stay loaded)
    people_opts = opts if fmt == "romp" else replace(opts, body_model=None)
    model_verts = None if model is None else model.n_verts
    faces = model_faces(model, model_verts)
    layout = _LAYOUT_BEV if fmt == "bev" else _LAYOUT_ROMP

    def build(index: int, notes: FrameNotes) -> Frame:
        name, load = sources[index]
        source = f"{src} [{name}]"
        people = _people(load(), source, fmt, people_opts)
        verts = people["vertices"]
        extra = {}
        if per_frame:  # photos of different sizes: each frame states its own intrinsics (contract frame keys)
            focal, principal_point = intrinsics[index]
            extra = {"image_size": np.asarray(geometries[index][0], np.int64), "focal_length": np.float64(focal),
                     "principal_point": np.asarray(principal_point, np.float64)}
        kp = people["keypoints_2d"]
        return people_frame(names[index], source, notes.warnings, vertices=verts, joints=people["joints"],
                            keypoints_2d=kp, person_ids=people["person_ids"],
                            faces=faces if verts is not None and verts.shape[1] == model_verts else None, extra=extra,
                            keypoints_layout=layout if kp is None or kp.shape[1] != 54 else "romp54")

    size, focal, principal_point = (None, None, None) if per_frame else (geometries[0][0], *intrinsics[0])
    meta = base_meta(fmt, src, opts, size, focal, principal_point, focal_kind=ASSUMED, focal_rule=fmt)
    sides = sorted({max(g[0]) for g in geometries})
    meta["import"].update({
        "source_frames": [name for name, _ in sources],
        "image_size_from": size_origin,
        "joints_layout": "smpl24",
        "root_joint": 0,
        "keypoints_2d_layout": layout,
        "feet_heads_from": feet_heads_from(None, True) + "; keypoints_2d for frames without meshes: "
                           + str(feet_heads_from(layout, False)),
        "conventions": f"camera frame = OpenCV, metres; vertices = verts + cam_trans; 60-degree FOV on the "
                       f"centred padded square (S = {', '.join(map(str, sides))})",
    })
    if fmt == "romp":  # what model_fit names when the meshes miss their own keypoints
        meta["import"]["meshes_reproject"] = _ROMP_REPROJECTS
    return ImportedSequence(tuple(names), build, meta, warnings)


def read_bev(src: Path, opts: ImportOptions) -> ImportedSequence:
    """BEV per-image .npz results -> contract frames."""
    return _read(src, opts, "bev")


def read_romp(src: Path, opts: ImportOptions) -> ImportedSequence:
    """ROMP (simple_romp) per-image .npz results -> contract frames."""
    return _read(src, opts, "romp")


READERS = {"bev": read_bev, "romp": read_romp}
