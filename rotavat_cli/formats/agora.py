"""AGORA ground truth / predictions in AGORA's per-person ``<image>_personId_<k>.pkl`` format.

Source: pixelite1201/agora_evaluation ``docs/prediction_format.md`` (per-person dicts),
``docs/gt_dataframe.md`` (``gt_joints_3d`` / ``gt_verts`` in camera coordinates, ``gt_joints_2d``
at 3840x2160), ``agora_evaluation/projection.py`` (``project2d``: ``smpl2opencv``, ``unreal2cv2``,
``focalLength_mm2px``, the focal length of each scene type).

- Files: one pickle per person, named ``<image stem>_personId_<k>.pkl``; a dict with ``verts``
  (V, 3; 6890 SMPL or 10475 SMPL-X) and ``allSmplJoints3d`` (24 or 127, 3) in the camera frame,
  ``joints`` (24, 2) in pixels *of the 3840x2160 image*; or, instead of ``verts``, ``params``
  (``transl``, ``global_orient``, ``body_pose``, ``betas`` [, SMPL-X hands/jaw/eyes/expression];
  ``pose2rot`` says axis-angle (True) or rotation matrices) to pose with ``--smpl-model``.
- Frame: camera coordinates after ``smpl2opencv`` and ``unreal2cv2``: OpenCV axes, metres.
- Focal: a 36 x 20.25 mm sensor; f_px = focal_mm / 36 * W with focal_mm chosen from the image
  name as ``project_2d`` does: ``hdri`` 50 mm, ``cam00``-``cam03`` 18 mm, ``ag2`` 28 mm, else
  28 mm. Principal point = image centre. Default image size 3840x2160 (``--image-size 1280 720``
  for the small release: 2D joints are rescaled by W / 3840).
- 2D: ``joints`` hold as many points as the model's joints: 24 (the prediction format's SMPL
  joints), 45 (``smplx.create(model_type='smpl')``: SMPL-24 + 21 vertex joints, as AGORA's own
  ground truth and sample predictions) or 127 / 144 (SMPL-X); the ``keypoints_2d_layout`` says
  which (formats/keypoints.py) and, without meshes, gives the feet and heads.
- Placement: AGORA's evaluation aligns roots, so a prediction may be root-centred (``transl`` = 0,
  as its own sample predictions are): such people sit at the camera centre, half behind it; the
  import says how many (``sequence.people_not_placed``), and calibrate/align cannot use them.
- No track ids: AGORA images are independent (person ids are per image).
- One body model per sequence: a folder that mixes SMPL and SMPL-X predictions (as AGORA's own
  ``sample_pred_format/`` does: ``smpl_*`` and ``smplx_*`` files) is refused in one line naming the
  kinds and the two imports that read it, each with ``--model-kind smpl|smplx`` (which reads only that
  model's files: every file is opened once more to tell its model, by its vertex count, its
  parameters' joints and keys, else its joints' count). A mix that imports anyway (meshes only) is a
  warning with the same advice.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import InputError, file_error
from ..geometry.focal import CAMERA
from ..bodies.joint_layouts import layout_by_count
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names, natural_key
from .frames import people_frame
from .imported import Conclusion, FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces
from .smpl import joints_to_smpl24, lbs

SENSOR_WIDTH_MM = 36.0  # projection.py dslr_sens_width
REFERENCE_SIZE = (3840, 2160)  # resolution of 'joints' / gt_joints_2d
_PERSON = re.compile(r"^(?P<image>.+)_personId_(?P<k>\d+)\.pkl$")


def focal_mm(image_name: str) -> float:
    """Focal length (mm) of the AGORA scene an image comes from (projection.py ``project_2d``)."""
    if "hdri" in image_name:
        return 50.0
    if any(f"cam0{i}" in image_name for i in range(4)):
        return 18.0
    return 28.0  # 'ag2' scenes and the rest


def sniff(path: Path) -> str | None:
    """'agora' for *_personId_*.pkl files (or a directory of them)."""
    if path.is_file():
        return "agora" if _PERSON.match(path.name) else None
    if path.is_dir():
        return "agora" if any(_PERSON.match(p.name) for p in path.glob("*_personId_*.pkl")) else None
    return None


def _groups(src: Path) -> list[tuple[str, list[Path]]]:
    """(image stem, per-person files sorted by person id) in image order."""
    files = [src] if src.is_file() else list(src.glob("*_personId_*.pkl"))
    groups: dict[str, list[tuple[int, Path]]] = {}
    for path in files:
        match = _PERSON.match(path.name)
        if match is None:
            raise file_error(path, "AGORA files must be named <image>_personId_<k>.pkl")
        groups.setdefault(match["image"], []).append((int(match["k"]), path))
    if not groups:
        raise file_error(src, "no <image>_personId_<k>.pkl files found")
    return [(image, [p for _, p in sorted(items)]) for image, items in sorted(groups.items(), key=lambda kv: natural_key(kv[0]))]


# ---- which body model a prediction was made with ---------------------------------------------------
MODEL_NAMES = {"smpl": "SMPL", "smplx": "SMPL-X"}
_MODEL_FILE = {"smpl": "SMPL_NEUTRAL.npz", "smplx": "SMPLX_NEUTRAL.npz"}  # as the models' releases name them
_KIND_BY_VERTS = {6890: "smpl", 10475: "smplx"}
_KIND_BY_JOINTS = {24: "smpl", 45: "smpl", 127: "smplx", 144: "smplx"}  # allSmplJoints3d / 'joints' counts
_KIND_BY_BODY_POSE = {23 * 3: "smpl", 23 * 9: "smpl", 21 * 3: "smplx", 21 * 9: "smplx"}  # axis-angle or matrices
_SMPLX_ONLY = ("jaw_pose", "leye_pose", "reye_pose", "left_hand_pose", "right_hand_pose", "expression")


def _count(value: object, axis: int) -> int | None:
    """The length of ``value`` along ``axis`` (from the end), or None when it has no such axis."""
    shape = np.shape(value) if isinstance(value, (np.ndarray, list, tuple)) else ()
    return int(shape[axis]) if len(shape) >= -axis else None


def model_kind_of(data: object) -> str | None:
    """The body model of one AGORA prediction (a per-person dict): 'smpl', 'smplx', or None when nothing
    tells (its vertex count; its parameters' SMPL-X-only keys or body-pose joints; its joints' count)."""
    if not isinstance(data, Mapping):
        return None
    kind = _KIND_BY_VERTS.get(_count(data.get("verts"), -2))
    params = data.get("params")
    if kind is None and isinstance(params, Mapping):
        if any(key in params for key in _SMPLX_ONLY):
            return "smplx"
        body = params.get("body_pose")
        kind = _KIND_BY_BODY_POSE.get(int(np.size(body))) if isinstance(body, (np.ndarray, list, tuple)) else None
    for key in ("allSmplJoints3d", "joints"):
        kind = kind or _KIND_BY_JOINTS.get(_count(data.get(key), -2))
    return kind


def _kinds(paths: list[Path]) -> dict[str | None, list[Path]]:
    """The files by the body model of their prediction (None: not told, or not readable), in file order."""
    found: dict[str | None, list[Path]] = {}
    for path in paths:
        try:
            kind = model_kind_of(load_file(path))
        except (InputError, OSError, ValueError, TypeError, KeyError, EOFError):
            kind = None
        found.setdefault(kind, []).append(path)
    return found


def _import_command(src: Path, kind: str, needs_model: bool, opts: ImportOptions) -> str:
    """The import of one body model's predictions of a mixed folder (``--model-kind``)."""
    model = opts.body_model.name if opts.body_model is not None and opts.body_model.kind == kind else _MODEL_FILE[kind]
    size = ["--image-size", *map(str, opts.image_size)] if opts.image_size else []
    return shlex.join(["rotavat", "import", "--from", "agora", str(src), f"{src.name}_{kind}", "--model-kind", kind,
                       *(["--smpl-model", model] if needs_model else []), *size])


def _mix_advice(src: Path, kinds: dict[str | None, list[Path]], opts: ImportOptions) -> str:
    """'mixes SMPL predictions (2 files, e.g. a.pkl) and SMPL-X ones (...): ...' with the imports that read each."""
    told = [kind for kind in MODEL_NAMES if kinds.get(kind)]
    described = " and ".join(f"{MODEL_NAMES[k]} {'predictions' if i == 0 else 'ones'} ({len(kinds[k])} "
                             f"file{'s' * (len(kinds[k]) > 1)}, e.g. {kinds[k][0].name})" for i, k in enumerate(told))
    commands = "; ".join(_import_command(src, k, any(_has_params(p) for p in kinds[k]), opts) for k in told)
    return (f"mixes {described}: one sequence holds one body model's, so import each on its own: {commands}")


def _has_params(path: Path) -> bool:
    """True when a prediction file holds parameters only (posing it needs --smpl-model)."""
    try:
        data = load_file(path)
    except (InputError, OSError, ValueError, TypeError, KeyError, EOFError):
        return False
    return isinstance(data, Mapping) and data.get("verts") is None and data.get("params") is not None


def _mixed(src: Path, opts: ImportOptions) -> InputError | None:
    """The one-line refusal of a folder that mixes SMPL and SMPL-X predictions (None when it does not, or
    when ``--model-kind`` already picked one)."""
    if not src.is_dir() or opts.model_kind is not None:
        return None
    kinds = _kinds(sorted(src.glob("*_personId_*.pkl")))
    if sum(1 for kind in MODEL_NAMES if kinds.get(kind)) < 2:
        return None
    return file_error(src, _mix_advice(src, kinds, opts))


def _select_kind(groups: list[tuple[str, list[Path]]], src: Path, opts: ImportOptions,
                 warnings: list[str]) -> list[tuple[str, list[Path]]]:
    """The groups holding only the files of ``opts.model_kind`` (``--model-kind``); every group with ``None``."""
    if opts.model_kind is None:
        return groups
    kinds = _kinds([path for _, paths in groups for path in paths])
    keep = set(kinds.get(opts.model_kind, []))
    if not keep:
        found = ", ".join(f"{MODEL_NAMES.get(k, 'not told')} {len(v)}" for k, v in kinds.items())
        raise file_error(src, f"holds no {MODEL_NAMES[opts.model_kind]} predictions (--model-kind {opts.model_kind}); "
                              f"its files by body model: {found}")
    if kinds.get(None):
        warnings.append(f"{src}: {len(kinds[None])} files whose body model could not be told (e.g. "
                        f"{kinds[None][0].name}) left out by --model-kind {opts.model_kind}")
    picked = [(image, [p for p in paths if p in keep]) for image, paths in groups]
    return [(image, paths) for image, paths in picked if paths]


def _params_refusal(path: Path, data: Mapping, model: object, src: Path, opts: ImportOptions) -> InputError | None:
    """Why a parameter file cannot be posed with ``model`` (None: it can): the folder mixes body models
    (:func:`_mixed`), no model was given, or the model is of the other kind; each naming what to pass."""
    kind = model_kind_of(data)
    if model is not None and (kind is None or model.kind == kind):
        return None
    mixed = _mixed(src, opts)
    if mixed is not None:
        return mixed
    if kind is None:
        return None if model is not None else file_error(
            path, "holds SMPL/SMPL-X parameters only: pass --smpl-model (the model AGORA used)")
    family = MODEL_NAMES[kind]
    if model is None:
        return file_error(path, f"holds {family} parameters only: pass --smpl-model {_MODEL_FILE[kind]} (the {family} "
                                "model file) to pose them")
    return file_error(path, f"holds {family} parameters; --smpl-model {model.name} is "
                            f"{MODEL_NAMES.get(model.kind, model.kind)} ({model.n_joints} joints): pass the {family} "
                            f"model ({_MODEL_FILE[kind]})")


def _one_person(array: np.ndarray, name: str, source: Path) -> np.ndarray:
    """A person's (K, D) array; AGORA's own sample predictions (agora_evaluation @8c9dece,
    sample_pred_format/) carry a leading batch axis of one, (1, K, D), which is dropped."""
    if array.ndim == 3 and array.shape[0] == 1:
        array = array[0]
    if array.ndim != 2:
        raise file_error(source, f"'{name}' must have 2 dimensions (or a leading batch axis of 1), got shape "
                                 f"{list(array.shape)}")
    return array


def _pose_params(params: Mapping, model_joints: int, pose2rot: bool, source: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """(pose (J, 3[, 3]), betas, transl, expression) from AGORA's 'params' dict."""
    names = ["global_orient", "body_pose"]
    if model_joints == 55:
        names += ["jaw_pose", "leye_pose", "reye_pose", "left_hand_pose", "right_hand_pose"]
    parts = []
    for name in names:
        value = as_array(get(params, name, source), name, source)
        parts.append(value.reshape(-1, 3) if pose2rot else value.reshape(-1, 3, 3))
    pose = np.concatenate(parts)
    if len(pose) != model_joints:
        raise file_error(source, f"'params' pose has {len(pose)} joints, the model {model_joints}")
    betas = as_array(get(params, "betas", source), "betas", source).reshape(-1)
    transl = as_array(get(params, "transl", source), "transl", source).reshape(3)
    expression = params.get("expression")
    expression = None if expression is None else as_array(expression, "expression", source).reshape(-1)
    return pose, betas, transl, expression


def _keypoints_layout(n_points: int) -> str:
    """Layout of AGORA's 'joints' (K, 2) by their count (24, 45, 127, 144), as meta.yaml states it."""
    layout = layout_by_count(n_points)
    return f"{layout} ('joints', rescaled from 3840x2160)" if layout else f"agora{n_points} ('joints', rescaled from 3840x2160)"


def read_agora(src: Path, opts: ImportOptions) -> ImportedSequence:
    """AGORA per-person pickles -> contract frames (one frame per image)."""
    warnings: list[str] = []
    groups = _select_kind(_groups(src), src, opts, warnings)
    image_size = opts.image_size or REFERENCE_SIZE
    scale_2d = image_size[0] / REFERENCE_SIZE[0]
    if abs(image_size[1] / image_size[0] - REFERENCE_SIZE[1] / REFERENCE_SIZE[0]) > 1e-3:
        warnings.append(f"--image-size {image_size[0]}x{image_size[1]} is not AGORA's 16:9")
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)
    focals = {image: focal_mm(image) / SENSOR_WIDTH_MM * image_size[0] for image, _ in groups}
    constant_focal = len(set(focals.values())) == 1
    model = opts.body_model
    names = frame_names([image for image, _ in groups], warnings)

    def person(path: Path) -> dict[str, np.ndarray | None]:
        data = load_file(path)
        if not isinstance(data, Mapping):
            raise file_error(path, f"expected a dict, got {type(data).__name__}")
        out: dict[str, np.ndarray | None] = {"vertices": None, "joints": None, "keypoints_2d": None}
        if data.get("joints") is not None:
            joints_2d = _one_person(as_array(data["joints"], "joints", path), "joints", path)
            if joints_2d.shape[1] != 2:
                raise file_error(path, f"'joints' must be (J, 2) pixels, got shape {list(joints_2d.shape)}")
            out["keypoints_2d"] = joints_2d * scale_2d
        if data.get("verts") is not None:
            out["vertices"] = _one_person(as_array(data["verts"], "verts", path, last=(3,)), "verts", path)
            if data.get("allSmplJoints3d") is not None:
                out["joints"] = as_array(data["allSmplJoints3d"], "allSmplJoints3d", path, ndim=2, last=(3,))
        elif data.get("params") is not None:
            refusal = _params_refusal(path, data, model, src, opts)
            if refusal is not None:
                raise refusal
            pose2rot = bool(data.get("pose2rot", True))
            pose, betas, transl, expression = _pose_params(data["params"], model.n_joints, pose2rot, path)
            v, j = lbs(model, betas[None], pose[None], transl[None],
                       None if expression is None else expression[None])
            out["vertices"], out["joints"] = v[0], j[0]
        else:
            raise file_error(path, "neither 'verts' nor 'params'")
        return out

    def build(index: int, notes: FrameNotes) -> Frame:
        image, paths = groups[index]
        people = [person(p) for p in paths]
        stacked: dict[str, np.ndarray | None] = {}
        layout = None
        for key in ("vertices", "joints", "keypoints_2d"):
            values = [p[key] for p in people]
            if any(v is None for v in values) or len({v.shape for v in values}) > 1:
                stacked[key] = None
                continue
            stacked[key] = np.stack(values)
        if stacked["joints"] is not None:
            try:
                stacked["joints"], layout = joints_to_smpl24(stacked["joints"])
            except ValueError:
                layout = f"agora{stacked['joints'].shape[1]}"
        notes.facts["joints_layout"] = layout
        if stacked["vertices"] is None:
            raise _mixed(src, opts) or file_error(paths[0], "people of one image must all have vertices of the same size")
        kind = _KIND_BY_VERTS.get(stacked["vertices"].shape[1])
        notes.facts["model_kinds"] = [kind] if kind else []
        n_verts = stacked["vertices"].shape[1]
        extra = {} if constant_focal else {"focal_length": np.float64(focals[image])}
        kp = stacked["keypoints_2d"]
        kp_layout = None if kp is None else _keypoints_layout(kp.shape[1])
        notes.facts["keypoints_2d_layout"] = kp_layout
        return people_frame(names[index], f"{src} [{image}]", notes.warnings, vertices=stacked["vertices"],
                            joints=stacked["joints"], keypoints_2d=kp, faces=model_faces(model, n_verts),
                            n_verts=n_verts, extra=extra, keypoints_layout=kp_layout)

    def conclude(notes: list[FrameNotes]) -> Conclusion:
        def first(key: str) -> object:
            return next((n.facts[key] for n in notes if n.facts.get(key)), None)

        kp_layout = first("keypoints_2d_layout")
        kinds = sorted({kind for n in notes for kind in n.facts.get("model_kinds", ())})
        mixed = _mixed(src, opts) if len(kinds) > 1 else None  # meshes of both models: imported, but two sequences
        return Conclusion({"joints_layout": first("joints_layout"), "keypoints_2d_layout": kp_layout,
                           "feet_heads_from": feet_heads_from(kp_layout, True),
                           **({"model_kind": opts.model_kind} if opts.model_kind else {})},
                          [str(mixed)] if mixed is not None else [])

    meta = base_meta("agora", src, opts, image_size, next(iter(focals.values())) if constant_focal else None,
                     principal_point, focal_kind=CAMERA)
    meta["import"].update({
        "source_frames": [image for image, _ in groups],
        "image_size_from": "--image-size" if opts.image_size else "AGORA default 3840x2160",
        "root_joint": 0,
        "conventions": "camera frame = OpenCV, metres; focal = focal_mm / 36 mm * W (hdri 50, cam00-03 18, "
                       "else 28 mm); principal point = image centre",
    })
    return ImportedSequence(tuple(names), build, meta, warnings, conclude=conclude)


READERS = {"agora": read_agora}
