"""Multi-HMR: per-image arrays of its ``humans`` outputs (SMPL-X meshes in the camera frame).

Source: naver/multi-hmr ``demo.py`` (``open_image``: ``ImageOps.contain`` + ``ImageOps.pad`` to an
``img_size`` square; ``get_camera_parameters``; ``--save_mesh`` writes ``<image>.npy`` =
``[h['verts_smplx'] for h in humans]``), ``utils/camera.py`` (``get_focalLength_from_fieldOfView``,
``perspective_projection``), ``model.py`` (per-person keys ``scores``, ``loc``, ``transl``,
``transl_pelvis``, ``rotvec`` (55, 3), ``shape``, ``expression``, ``verts_smplx`` (10475, 3),
``j3d_smplx`` (127, 3), ``j2d_smplx`` (127, 2)).

- Files read: ``<image>_<model name>.png.npy`` (P, V, 3) vertex arrays (the demo's ``--save_mesh``:
  ``save_fn = f"{Path(img_path).stem}_{model_name}.png"``, ``mesh_fn = save_fn + '.npy'``; the frame
  name is the image stem: the ``.png`` and the ``_multiHMR...`` model suffix are dropped), older
  demos' ``<image>.npy``, or ``<image>.npz`` / ``<image>.pkl`` holding those per-person keys
  (stacked arrays, or a list of per-person dicts).
- Frame: ``verts_smplx`` and ``j3d_smplx`` are in the camera frame: OpenCV axes
  (``perspective_projection`` divides by +z and applies K; rendering flips to OpenGL with
  ``OPENCV_TO_OPENGL_CAMERA_CONVENTION``), metres.
- Focal: K is built for the square network input (``img_size`` 896 or 672) from ``--fov``
  (default 60 deg): f_in = img_size / (2 tan(fov/2)). The image was scaled by img_size / max(W, H)
  and padded symmetrically, so on the original image f = max(W, H) / (2 tan(fov/2)) and the
  principal point is the image centre (to within half an input pixel).
- 2D: ``j2d_smplx`` live in the *padded network input*, not the image: they are not used;
  ``keypoints_2d`` are ``j3d_smplx`` reprojected with the original-image intrinsics above.
- Image size: never stored: ``--image-size`` is required. ``--fov`` if the demo ran with one.
- Feet and heads: meshes give them (mesh landmarks); the reprojected ``j3d_smplx`` (SMPL-X 127) are
  the ``keypoints_2d`` (layout ``smplx127``, formats/keypoints.py).
"""

from __future__ import annotations

import re
import zipfile
from collections import Counter
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..geometry.camera import project_cam_to_px
from ..errors import file_error
from ..geometry.focal import ASSUMED
from ..bodies.joint_layouts import layout_by_count
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from ..unpickle.npy import load_npy
from ..unpickle.npz import load_npz
from .content import as_array
from .file_kinds import wrong_kind
from .frame_names import frame_names, natural_key
from .frames import people_frame
from .image_size import need_image_size
from .imported import Conclusion, FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces
from .smpl import joints_to_smpl24

DEFAULT_FOV_DEG = 60.0  # demo.py --fov default
_SUFFIXES = (".npy", ".npz", ".pkl")


def sniff(path: Path) -> str | None:
    """'multihmr' for a directory of per-image .npy meshes or files with a 'verts_smplx' key."""
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix in _SUFFIXES)
        if not files:
            return None
        path = files[0]
    if path.suffix == ".npy":
        arr = load_npy(path)
        return "multihmr" if arr.ndim == 3 and arr.shape[-1] == 3 and arr.shape[1] in (10475, 6890) else None
    if path.suffix == ".npz":
        with zipfile.ZipFile(path) as archive:
            return "multihmr" if "verts_smplx.npy" in archive.namelist() else None
    return None


_IMAGE_SUFFIX = re.compile(r"\.(png|jpe?g|webp)$", re.IGNORECASE)
_MODEL_SUFFIX = re.compile(r"_multiHMR[A-Za-z0-9_.-]*$", re.IGNORECASE)  # demo.py: f"{stem}_{model_name}.png"


def image_stem(path: Path) -> str:
    """The image stem a result file belongs to: ``img_multiHMR_896_L.png.npy`` -> ``img``; ``img.npz`` -> ``img``."""
    stem = _IMAGE_SUFFIX.sub("", path.stem)
    return _MODEL_SUFFIX.sub("", stem) if stem != path.stem else stem


def _files(src: Path) -> list[Path]:
    files = [src] if src.is_file() else [p for p in src.iterdir() if p.suffix in _SUFFIXES and not p.name.startswith(".")]
    if not files:
        others = Counter(p.suffix or p.name for p in src.iterdir() if p.is_file() and not p.name.startswith("."))
        held = ", ".join(f"{n} {suffix}" for suffix, n in sorted(others.items())) or "no files"
        raise file_error(src, f"no Multi-HMR result files (.npy, .npz or .pkl) found (it holds {held})")
    return sorted(files, key=lambda p: natural_key(p.name))


def _humans(path: Path) -> dict[str, np.ndarray | None]:
    """verts (P, V, 3) and j3d (P, J, 3) or None from one per-image file."""
    wrong = wrong_kind(path, "multihmr")  # a JSON file named .pkl, ...: said as such, not as a broken pickle
    if wrong is not None:
        raise wrong
    if path.suffix == ".npy":
        content: object = load_npy(path)
    elif path.suffix == ".npz":
        content = load_npz(path, keys=("humans", "verts_smplx", "j3d_smplx"))  # the members used
    else:
        content = load_file(path)
    if isinstance(content, Mapping) and "humans" in content:
        content = content["humans"]
    if isinstance(content, np.ndarray) and content.dtype.kind == "O":
        content = list(content.reshape(-1))
    if isinstance(content, np.ndarray):  # the demo's --save_mesh: vertices only
        if content.size == 0:
            return {"verts": np.zeros((0, 0, 3)), "j3d": None}
        return {"verts": as_array(content, "vertices", path, ndim=3, last=(3,)), "j3d": None}
    if isinstance(content, list):  # per-person dicts
        if not content:
            return {"verts": np.zeros((0, 0, 3)), "j3d": None}
        if not all(isinstance(h, Mapping) for h in content):
            raise file_error(path, "expected a list of per-person dicts")
        verts = np.stack([as_array(h.get("verts_smplx"), "verts_smplx", path, ndim=2, last=(3,)) for h in content])
        has_j3d = all(h.get("j3d_smplx") is not None for h in content)
        j3d = np.stack([as_array(h["j3d_smplx"], "j3d_smplx", path, ndim=2, last=(3,)) for h in content]) if has_j3d else None
        return {"verts": verts, "j3d": j3d}
    if isinstance(content, Mapping):
        if "verts_smplx" not in content:
            raise file_error(path, "no 'verts_smplx' key")
        verts = as_array(content["verts_smplx"], "verts_smplx", path)
        if verts.size == 0:
            return {"verts": np.zeros((0, 0, 3)), "j3d": None}
        verts = as_array(verts, "verts_smplx", path, ndim=3, last=(3,))
        j3d = content.get("j3d_smplx")
        j3d = as_array(j3d, "j3d_smplx", path, ndim=3, last=(3,)) if j3d is not None and np.size(j3d) else None
        return {"verts": verts, "j3d": j3d}
    raise file_error(path, f"unexpected content ({type(content).__name__})")


def read_multihmr(src: Path, opts: ImportOptions) -> ImportedSequence:
    """Multi-HMR per-image outputs -> contract frames."""
    files = _files(src)
    image_size = need_image_size(opts, src, "Multi-HMR saves meshes in the camera frame of its padded square input")
    fov = opts.fov_deg if opts.fov_deg is not None else DEFAULT_FOV_DEG
    focal = max(image_size) / (2.0 * np.tan(np.radians(fov) / 2.0))
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)
    model = opts.body_model
    warnings: list[str] = []
    names = frame_names([image_stem(p) for p in files], warnings)

    def build(index: int, notes: FrameNotes) -> Frame:
        path = files[index]
        humans = _humans(path)
        verts, j3d = humans["verts"], humans["j3d"]
        n = len(verts)
        joints = kp = layout = None
        if j3d is not None and len(j3d) != n:
            raise file_error(path, "'j3d_smplx' and 'verts_smplx' differ in their number of people")
        if j3d is None and model is not None and n and model.n_verts == verts.shape[1]:
            j3d = np.einsum("jv,pvc->pjc", model.J_regressor, verts)  # joints regressed from the posed mesh
            layout = "smpl24 (regressed from the meshes with --smpl-model)"
        if j3d is not None:
            try:
                joints, note = joints_to_smpl24(j3d)
                layout = layout or note
            except ValueError:
                joints = j3d
                layout = layout or f"multihmr{j3d.shape[1]}"
            kp = project_cam_to_px(j3d, focal, principal_point)
        notes.facts["joints_layout"] = layout
        return people_frame(names[index], path, notes.warnings, vertices=verts if verts.shape[1] else None,
                            joints=joints, keypoints_2d=kp,
                            faces=model_faces(model, verts.shape[1] if verts.shape[1] else None),
                            n_verts=verts.shape[1] if verts.shape[1] else None,
                            keypoints_layout=None if kp is None else layout_by_count(kp.shape[1]))

    def conclude(notes: list[FrameNotes]) -> Conclusion:
        layout = next((n.facts["joints_layout"] for n in notes if n.facts.get("joints_layout")), None)
        warned = [] if layout is not None else [f"{src}: no 'j3d_smplx' in the files (and no matching --smpl-model): "
                                                 "vertices only, no joints (MPJPE unavailable)"]
        return Conclusion({"joints_layout": layout}, warned)

    meta = base_meta("multihmr", src, opts, image_size, focal, principal_point, focal_kind=ASSUMED)
    meta["import"].update({
        "source_frames": [p.name for p in files],
        "fov_deg": float(fov),
        "root_joint": 0,
        "keypoints_2d_layout": "smplx127 (j3d_smplx reprojected; the file's j2d_smplx are in the padded input)",
        "feet_heads_from": feet_heads_from("smplx127", True),
        "conventions": f"camera frame = OpenCV, metres; focal = max(W, H) / (2 tan({fov:g} deg / 2)); "
                       "principal point = image centre",
    })
    return ImportedSequence(tuple(names), build, meta, warnings, conclude=conclude)


READERS = {"multihmr": read_multihmr}
