"""Sequence I/O for the data contract: per-frame ``.npz`` or per-frame folders of per-person ``.obj``.

A sequence is opened lazily (:func:`open_sequence` lists frames and reads ``meta.yaml`` and
``camera.yaml``) and iterated one frame at a time, so memory stays bounded whatever its length.
Its frames come from a :class:`FrameSource`: a directory's files (:class:`DirectorySource`), or an
HPS tool's own output converted frame by frame (``rotavat_cli.formats.imported_sequence``).
Every reader validates what it reads and raises :class:`~rotavat_cli.errors.InputError` naming
the file, the key and the problem. Every writer is atomic (temporary file, then rename).
"""

from __future__ import annotations

import io
import re
import shlex
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from .settings import limits
from .files.atomic import atomic_open
from .geometry.camera import MAX_IMAGE_SIDE_PX, Camera, camera_from_yaml_dict, camera_to_yaml_dict, people_not_in_front
from .errors import InputError, file_error, input_errors
from .geometry.focal import CAMERA as CAMERA_FOCAL, focal_kind_or_default
from .unpickle.npz import load_npz
from .files.yaml_io import read_yaml, write_yaml

__all__ = [
    "Frame",
    "Intrinsics",
    "Sequence",
    "FrameSource",
    "DirectorySource",
    "PER_PERSON_KEYS",
    "SMPL_PARAM_KEYS",
    "WORLD_PARAM_KEYS",
    "open_sequence",
    "is_sequence_dir",
    "read_frame_npz",
    "read_frame_obj",
    "write_frame",
    "write_meta",
    "read_yaml",
    "read_camera_yaml",
    "write_camera_yaml",
    "validate_frame",
    "summarize_sequence",
]

# Per-person keys: trailing shape after the leading P axis (None = any size >= 1).
PER_PERSON_KEYS: dict[str, tuple[int | None | tuple[int, ...], ...]] = {
    "vertices": (None, (3,)),
    "joints": (None, (3,)),
    "keypoints_2d": (None, (2, 3)),
    "feet_2d": ((2,),),
    "heads_2d": ((2,),),
    "boxes_2d": ((4,),),
    "person_ids": (),
    # body-model parameters (docs/conventions.md, "Body-model parameters"): camera frame, then world (aligned)
    "smpl_global_orient": ((3,),),
    "smpl_body_pose": (None,),
    "smpl_betas": (None,),
    "smpl_transl": ((3,),),
    "smpl_pelvis": ((3,),),
    "smpl_scale": (),
    "world_global_orient": ((3,),),
    "world_transl": ((3,),),
    # the tool's own world (WHAM, GVHMR; meta.yaml ``tool_world``): its claim, copied through by align unchanged
    "tool_cam_global_orient": ((3,),),
    "tool_world_global_orient": ((3,),),
    "tool_world_transl": ((3,),),
    "tool_world_pelvis": ((3,),),
}
# The body-model parameters a frame may carry: all five or none (docs/conventions.md, "Body-model parameters").
SMPL_PARAM_KEYS = ("smpl_global_orient", "smpl_body_pose", "smpl_betas", "smpl_transl", "smpl_pelvis")
# What an aligned frame adds to them: the scale about the pelvis and the world-frame root.
WORLD_PARAM_KEYS = ("smpl_scale", "world_global_orient", "world_transl")
# Keys where NaN marks a missing value instead of an error (undetected 2D keypoints).
_NAN_ALLOWED = {"keypoints_2d", "feet_2d", "heads_2d", "boxes_2d"}  # a person may lack a keypoint or box (NaN row)
META_FILE = "meta.yaml"
CAMERA_FILE = "camera.yaml"


@dataclass(frozen=True)
class Intrinsics:
    """What is known of the camera the HPS method used: image size, focal, principal point.

    ``focal_px`` is one focal for the whole frame; ``person_focal_px`` one per person (P,) where
    the method used one per person (HybrIK); at most one of the two is set.
    """

    image_size: tuple[int, int] | None = None
    focal_px: float | None = None
    principal_point: tuple[float, float] | None = None
    person_focal_px: tuple[float, ...] | None = None

    def with_defaults(self) -> "Intrinsics":
        """Principal point defaulted to the image centre when the image size is known."""
        if self.principal_point is None and self.image_size is not None:
            return replace(self, principal_point=(self.image_size[0] / 2.0, self.image_size[1] / 2.0))
        return self

    def override(self, other: "Intrinsics") -> "Intrinsics":
        """Fields of ``other`` that are set take precedence over ours (a focal of either form replaces both)."""
        focal_set = other.focal_px is not None or other.person_focal_px is not None
        return Intrinsics(
            other.image_size if other.image_size is not None else self.image_size,
            other.focal_px if focal_set else self.focal_px,
            other.principal_point if other.principal_point is not None else self.principal_point,
            other.person_focal_px if focal_set else self.person_focal_px,
        )

    def focals_px(self, n_people: int) -> np.ndarray | None:
        """(P,) float64 focal of each person's mesh, or None when no focal is stated."""
        if self.person_focal_px is not None:
            return np.asarray(self.person_focal_px, dtype=np.float64)
        if self.focal_px is None:
            return None
        return np.full(n_people, float(self.focal_px))


@dataclass(frozen=True)
class Frame:
    """One frame: contract arrays (plus any extra keys, copied through) and where it came from."""

    name: str
    data: Mapping[str, np.ndarray]
    source: str = ""

    @property
    def n_people(self) -> int:
        """Number of people P (0 for an empty frame)."""
        for key in PER_PERSON_KEYS:
            if key in self.data:
                return int(self.data[key].shape[0])
        return 0

    def get(self, key: str) -> np.ndarray | None:
        """Array under ``key`` or None."""
        return self.data.get(key)

    @property
    def person_ids(self) -> np.ndarray:
        """(P,) int64 track ids; frame-local 0..P-1 when the frame has none."""
        ids = self.data.get("person_ids")
        return np.arange(self.n_people, dtype=np.int64) if ids is None else ids.astype(np.int64)

    @cached_property
    def intrinsics(self) -> Intrinsics:
        """Intrinsics stated by the frame itself (``image_size``, ``focal_length`` or ``K``)."""
        return _intrinsics_from_mapping(self.data, self.source, self.n_people)

    def replace(self, **arrays: np.ndarray) -> "Frame":
        """Copy with some arrays replaced or added."""
        data = dict(self.data)
        data.update(arrays)
        return Frame(self.name, data, self.source)


# ---- validation ------------------------------------------------------------------------------
_KEY_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]{0,127}")  # a frame key: a plain name, never a path


def validate_frame(data: Mapping[str, np.ndarray], source: str) -> None:
    """Check contract keys for shape, dtype, finiteness and a consistent people count; every key a plain name."""
    for key in data:
        if not _KEY_NAME.fullmatch(str(key)):
            raise file_error(source, f"member name {str(key)[:60]!r} is not a plain key name (letters, digits, _ . -)")
    counts: dict[str, int] = {}
    for key, trailing in PER_PERSON_KEYS.items():
        if key not in data:
            continue
        arr = data[key]
        if arr.dtype.kind not in "fiu":
            raise file_error(source, f"key '{key}' must be numeric, got dtype {arr.dtype}")
        if arr.ndim != 1 + len(trailing):
            raise file_error(source, f"key '{key}' must have {1 + len(trailing)} dimensions (P, ...), got shape {list(arr.shape)}")
        for dim, allowed in zip(arr.shape[1:], trailing):
            if isinstance(allowed, tuple) and dim not in allowed and arr.shape[0] > 0:
                raise file_error(source, f"key '{key}' has shape {list(arr.shape)}; expected last axis in {list(allowed)}")
        if key == "person_ids":
            if arr.dtype.kind == "f" and arr.size and not np.all(arr == np.round(arr)):
                raise file_error(source, "key 'person_ids' must hold integers")
            if arr.size and (np.any(arr > np.iinfo(np.int64).max) if arr.dtype.kind in "uf" else False):
                raise file_error(source, "key 'person_ids' has ids beyond the int64 range")
            if arr.dtype.kind == "f" and arr.size and np.any(np.abs(arr) > 2.0**53):
                raise file_error(source, "key 'person_ids' has ids too large to be stored exactly as floats")
            if len(np.unique(arr)) != len(arr):
                raise file_error(source, "key 'person_ids' has duplicate ids in one frame")
        if key not in _NAN_ALLOWED and arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
            raise file_error(source, f"key '{key}' has non-finite values (NaN or inf)")
        counts[key] = arr.shape[0]
    if len(set(counts.values())) > 1:
        detail = ", ".join(f"{k}={v}" for k, v in counts.items())
        raise file_error(source, f"inconsistent people counts between keys ({detail})")
    n_people = next(iter(counts.values()), 0)
    _check_param_groups(data, source)
    if "faces" in data:
        faces = data["faces"]
        if faces.dtype.kind not in "iu" or faces.ndim != 2 or faces.shape[1] != 3:
            raise file_error(source, f"key 'faces' must be an (F, 3) integer array, got {faces.dtype} {list(faces.shape)}")
        verts = data.get("vertices")
        if verts is not None and faces.size and verts.shape[0] and (faces.min() < 0 or faces.max() >= verts.shape[1]):
            raise file_error(source, f"key 'faces' indexes vertices outside 0..{verts.shape[1] - 1}")
    _intrinsics_from_mapping(data, source, n_people)


def _check_param_groups(data: Mapping[str, np.ndarray], source: str) -> None:
    """Body-model parameters come whole: all of :data:`SMPL_PARAM_KEYS` or none, world keys only with them."""
    given = [key for key in SMPL_PARAM_KEYS if key in data]
    if given and len(given) < len(SMPL_PARAM_KEYS):
        missing = [key for key in SMPL_PARAM_KEYS if key not in data]
        raise file_error(source, f"body-model parameters come together: has {', '.join(given)} but not {', '.join(missing)}")
    world = [key for key in WORLD_PARAM_KEYS if key in data]
    if world and (len(world) < len(WORLD_PARAM_KEYS) or not given):
        raise file_error(source, f"keys {', '.join(WORLD_PARAM_KEYS)} come together, with {', '.join(SMPL_PARAM_KEYS)}")


def _intrinsics_from_mapping(data: Mapping[str, Any], source: str, n_people: int | None = None) -> Intrinsics:
    """Parse ``image_size``, ``focal_length``/``K`` and ``principal_point`` from a frame or meta.

    In meta.yaml (``n_people`` None) ``focal_length`` is one number (or ``[fx, fy]``, averaged);
    in a frame it is one number, or one per person (P,) as HybrIK uses.
    """
    size = focal = pp = person_focal = None
    if data.get("image_size") is not None:
        try:
            arr = np.asarray(data["image_size"])
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if arr.shape != (2,) or arr.dtype.kind not in "iuf" or not np.all(np.isfinite(arr)) or np.any(arr <= 0) \
                or np.any(arr > MAX_IMAGE_SIDE_PX):
            raise file_error(source, f"key 'image_size' must be [W, H] with positive values up to {MAX_IMAGE_SIDE_PX}, "
                                f"got {str(data['image_size'])[:60]}")
        size = (int(arr[0]), int(arr[1]))
    if data.get("K") is not None:
        try:
            K = np.asarray(data["K"], dtype=np.float64)
        except (TypeError, ValueError):
            raise file_error(source, "key 'K' must be a finite 3x3 matrix of numbers") from None
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise file_error(source, "key 'K' must be a finite 3x3 matrix with positive focal lengths")
        focal = float(0.5 * (K[0, 0] + K[1, 1]))
        pp = (float(K[0, 2]), float(K[1, 2]))
    if data.get("focal_length") is not None:
        try:
            arr = np.asarray(data["focal_length"], dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise file_error(source, f"key 'focal_length' must be a number, got {data['focal_length']!r}") from None
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise file_error(source, f"key 'focal_length' must hold positive numbers, got {data['focal_length']!r}")
        if arr.size == 1 or (n_people is None and arr.size == 2):
            focal = float(arr.mean())
        elif n_people is not None and arr.size == n_people and np.ndim(data["focal_length"]) == 1:
            person_focal = tuple(float(v) for v in arr)
        else:
            expected = "one number" if n_people is None else f"one number or one per person ({n_people},)"
            raise file_error(source, f"key 'focal_length' must be {expected}, got shape {list(np.shape(data['focal_length']))}")
    if data.get("principal_point") is not None:
        try:
            arr = np.asarray(data["principal_point"], dtype=np.float64)
        except (TypeError, ValueError):
            raise file_error(source, "key 'principal_point' must be [cx, cy] in pixels") from None
        if arr.shape != (2,) or not np.all(np.isfinite(arr)):
            raise file_error(source, "key 'principal_point' must be [cx, cy]")
        pp = (float(arr[0]), float(arr[1]))
    return Intrinsics(size, focal, pp, person_focal)


# ---- frame readers ------------------------------------------------------------------------------
def read_frame_npz(path: str | Path) -> Frame:
    """Read and validate one ``.npz`` frame: numeric arrays only (no pickle), every member's declared
    size checked against ``limits`` before it is read (``unpickle.npz.open_npz``)."""
    path = Path(path)
    data = load_npz(path, objects=False, total_limit=(limits.current().max_frame_bytes, "limits.max_frame_mb"))
    validate_frame(data, str(path))
    return Frame(path.stem, data, str(path))


def read_frame_obj(folder: str | Path) -> Frame:
    """Read a frame folder of per-person OBJ files (stem = person id) into contract arrays."""
    import trimesh  # lazy: ~0.3 s to import, needed only for OBJ frame folders; every command reads sequences

    folder = Path(folder)
    files = _obj_files(folder)
    verts, faces, ids = [], None, []
    for file in files:
        try:
            text = file.read_bytes().decode("utf-8")
        except UnicodeDecodeError:
            raise file_error(str(file), "not a text OBJ file (not UTF-8)") from None
        try:
            mesh = trimesh.load(io.StringIO(text), file_type="obj", process=False, maintain_order=True, force="mesh")
        except Exception as exc:  # trimesh raises many types on broken files
            raise file_error(str(file), f"not a readable OBJ file ({exc})") from None
        v = np.asarray(mesh.vertices, dtype=np.float64)
        f = np.asarray(mesh.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[0] == 0:
            raise file_error(str(file), "OBJ has no vertices")
        if not np.all(np.isfinite(v)):
            raise file_error(str(file), "OBJ has non-finite vertices (NaN or inf)")
        if verts and v.shape != verts[0].shape:
            raise file_error(str(file), f"has {v.shape[0]} vertices but {files[0].name} has {verts[0].shape[0]}: "
                        "one frame must share one topology")
        if faces is None:
            faces = f
        verts.append(v)
        ids.append(_person_id(file))
    data: dict[str, np.ndarray] = {}
    if verts:
        data["vertices"] = np.stack(verts)
        data["faces"] = faces
        data["person_ids"] = np.asarray(ids, dtype=np.int64)
    else:
        data["vertices"] = np.zeros((0, 0, 3))
        data["person_ids"] = np.zeros((0,), dtype=np.int64)
    validate_frame(data, str(folder))
    return Frame(folder.name, data, str(folder))


def _obj_files(folder: Path) -> list[Path]:
    """The people of a frame folder: regular ``<person id>.obj`` files (or links to one), by id."""
    return sorted((p for p in _entries(folder) if _is_person_obj(p)), key=lambda p: int(p.stem))


def _entries(folder: Path) -> list[Path]:
    """Visible entries of a folder."""
    return [p for p in folder.iterdir() if not p.name.startswith(".")]


def _is_person_obj(entry: Path) -> bool:
    """A person's OBJ: a regular file (or a link to one) named ``<integer id>.obj``."""
    return entry.suffix.lower() == ".obj" and entry.is_file() and re.fullmatch(r"-?\d+", entry.stem) is not None


def _ignored_entries(folder: Path) -> list[str]:
    """What a frame folder holds besides its people's OBJ files, with why each is ignored."""
    out = []
    for entry in sorted(_entries(folder)):
        if _is_person_obj(entry):
            continue
        if entry.suffix.lower() != ".obj":
            why = "not an .obj file"
        elif entry.is_dir():
            why = "a folder, not an OBJ file"
        elif not entry.exists():
            why = "a broken link"
        elif not entry.is_file():
            why = "not a regular file"
        else:
            why = "the file name is not an integer person id (e.g. 0.obj)"
        out.append(f"{folder.name}/{entry.name}: {why}")
    return out


def _person_id(file: Path) -> int:
    """Person id from an OBJ file stem (an integer, see :func:`_is_person_obj`)."""
    return int(file.stem)


# ---- frame writers ---------------------------------------------------------------------------
def write_frame(out_dir: str | Path, frame: Frame, form: str) -> Path:
    """Write a frame atomically in ``form`` ('npz' or 'obj'); returns the written path."""
    out_dir = Path(out_dir)
    if form == "npz":
        target = out_dir / f"{frame.name}.npz"
        with atomic_open(target, "wb") as handle:
            np.savez(handle, **dict(frame.data))
        return target
    if form == "obj":
        return _write_frame_obj(out_dir / frame.name, frame)
    raise ValueError(f"unknown sequence form {form!r} (expected 'npz' or 'obj')")


def _write_frame_obj(folder: Path, frame: Frame) -> Path:
    """One OBJ per person (stem = person id); stale OBJs of that frame folder are removed."""
    folder.mkdir(parents=True, exist_ok=True)
    verts = frame.get("vertices")
    faces = frame.get("faces")
    if frame.n_people and (verts is None or faces is None):
        raise ValueError(f"frame {frame.name}: writing OBJ needs 'vertices' and 'faces'")
    keep = set()
    for pid, v in zip(frame.person_ids, verts if verts is not None else []):
        target = folder / f"{int(pid)}.obj"
        with atomic_open(target, "w") as handle:
            handle.write(_obj_text(v, faces))
        keep.add(target.name)
    for stale in _obj_files(folder):
        if stale.name not in keep:
            stale.unlink()
    return folder


def _obj_text(verts: np.ndarray, faces: np.ndarray) -> str:
    """OBJ text for one mesh: float32 sources keep 9 significant digits (exact), others 17."""
    digits = 9 if verts.dtype == np.float32 else 17
    buf = io.StringIO()
    np.savetxt(buf, np.asarray(verts, dtype=np.float64), fmt=f"v %.{digits}g %.{digits}g %.{digits}g")
    np.savetxt(buf, np.asarray(faces, dtype=np.int64) + 1, fmt="f %d %d %d")
    return buf.getvalue()


# ---- YAML helpers --------------------------------------------------------------------------
def read_camera_yaml(path: str | Path, image_size: tuple[int, int] | None = None) -> tuple[Camera, dict]:
    """Read ``camera.yaml`` -> (Camera, fit block or {})."""
    data = read_yaml(path)
    with input_errors(str(path)):
        camera = camera_from_yaml_dict(data, image_size)
    fit = data.get("fit") or {}
    return camera, fit if isinstance(fit, dict) else {}


def write_camera_yaml(path: str | Path, camera: Camera, fit: dict | None = None) -> None:
    """Write ``camera.yaml`` per docs/conventions.md atomically."""
    write_yaml(path, camera_to_yaml_dict(camera, fit))


def write_meta(out_dir: str | Path, meta: dict) -> None:
    """Write ``meta.yaml`` (plain types) atomically."""
    write_yaml(Path(out_dir) / META_FILE, meta)


# ---- sequences ----------------------------------------------------------------------------------
@runtime_checkable
class FrameSource(Protocol):
    """Where a sequence's frames come from: their names, in order, and one frame by name.

    :class:`DirectorySource` reads a sequence directory (the contract's files);
    ``rotavat_cli.formats`` has one that converts an HPS tool's own output frame by frame when it
    is read (``--from``). A source may also offer ``warnings`` (what building its frames found)
    and ``frame_notes(names)`` / ``add_frame_notes(notes)`` (the same, handed back from a copy
    of the source in a worker process).
    """

    @property
    def frame_names(self) -> tuple[str, ...]: ...

    def read_frame(self, name: str) -> Frame: ...


@dataclass(frozen=True)
class DirectorySource:
    """The frames of a sequence directory: ``NAME.npz`` files (form 'npz') or ``NAME/`` folders of
    per-person OBJ files (form 'obj'), read and validated one at a time."""

    path: Path
    form: str  # 'npz' | 'obj'
    frame_names: tuple[str, ...] = ()

    def frame_path(self, name: str) -> Path:
        """File (npz) or folder (obj) of a frame."""
        return self.path / (f"{name}.npz" if self.form == "npz" else name)

    def read_frame(self, name: str) -> Frame:
        """Read and validate one frame by name."""
        path = self.frame_path(name)
        return read_frame_npz(path) if self.form == "npz" else read_frame_obj(path)


@dataclass(frozen=True)
class Sequence:
    """A lazily read sequence: frame list, meta.yaml content, optional camera, frames read one at a time.

    Its frames come from ``source`` (a :class:`FrameSource`): by default the directory ``path``
    in ``form`` (:class:`DirectorySource`, what :func:`open_sequence` gives). A sequence read from
    an HPS tool's own output (``rotavat_cli.formats.imported_sequence``) has that output as
    ``path``, form 'npz' (what its frames would be written as) and a source converting each
    frame when it is read; no file is written.
    """

    path: Path
    form: str  # 'npz' | 'obj'
    frame_names: tuple[str, ...]
    meta: dict = field(default_factory=dict)
    camera: Camera | None = None
    camera_fit: dict = field(default_factory=dict)
    ignored: tuple[str, ...] = ()  # entries of OBJ frame folders that are not people's OBJ files, with why
    origin: str | None = None  # what the user named, when it is not ``path`` (an HPS tool's output read with --from)
    source: FrameSource | None = None  # None: DirectorySource(path, form)

    @property
    def label(self) -> str:
        """How reports name the sequence: the user's path (the tool's output for an imported one)."""
        return self.origin or str(self.path)

    def __len__(self) -> int:
        return len(self.frame_names)

    @cached_property
    def frame_source(self) -> FrameSource:
        """Where the frames are read from: ``source``, or the directory ``path`` in ``form``."""
        return self.source if self.source is not None else DirectorySource(self.path, self.form, self.frame_names)

    @property
    def _meta_name(self) -> str:
        """What errors about the sequence-level metadata name: meta.yaml, or the source it came from."""
        if isinstance(self.frame_source, DirectorySource):
            return str(self.path / META_FILE)
        return str(getattr(self.frame_source, "meta_name", self.label))

    @cached_property
    def focal_kind(self) -> str:
        """Whether the focal its meshes were made with is the camera's own ('camera') or a method's
        guess ('assumed'): meta.yaml ``focal_kind``, absent = 'assumed' (rotavat.focal)."""
        with input_errors(self._meta_name):
            return focal_kind_or_default(self.meta.get("focal_kind"))

    @property
    def image_lens(self) -> Camera | None:
        """The lens the frames' people are seen through in the image: the sequence's camera's, when its frames are in
        that camera (``focal_kind: camera``: a ground truth, an aligned output) and it has one; None otherwise (an HPS
        method's people are in its own pinhole, whose pixels are already the image's)."""
        cam = self.camera
        return cam if cam is not None and cam.distortion != 0.0 and self.focal_kind == CAMERA_FOCAL else None

    @property
    def joints_layout(self) -> str | None:
        """The layout of the frames' 3D joints, as meta.yaml's ``import.joints_layout`` names it (e.g.
        'phalp44 (OpenPose-25 + 19 extra)'); None when not named (SMPL's, by the joint count)."""
        block = self.meta.get("import") if isinstance(self.meta, dict) else None
        layout = block.get("joints_layout") if isinstance(block, dict) else None
        return layout if isinstance(layout, str) else None

    @cached_property
    def intrinsics(self) -> Intrinsics:
        """Sequence-level intrinsics from meta.yaml (frames may override)."""
        return _intrinsics_from_mapping(self.meta, self._meta_name)

    @cached_property
    def image_size(self) -> tuple[int, int] | None:
        """[W, H] from meta.yaml, else the first frame that states it, else camera.yaml (found once)."""
        if self.intrinsics.image_size is not None:
            return self.intrinsics.image_size
        for name in self.frame_names[:1]:
            size = self.read_frame(name).intrinsics.image_size
            if size is not None:
                return size
        return self.camera.image_size if self.camera is not None else None

    @property
    def camera_label(self) -> str:
        """How messages name the sequence's own camera: its camera.yaml, or the camera its format carried."""
        if isinstance(self.frame_source, DirectorySource):
            return str(self.path / "camera.yaml")
        return f"the camera imported with {self.label}"

    def require_image_size(self) -> tuple[int, int]:
        """Image size, or an InputError saying how to provide it."""
        size = self.image_size
        if size is None:
            if not isinstance(self.frame_source, DirectorySource):
                raise InputError(f"{self.label}: unknown image size: pass --image-size W H")
            raise InputError(f"{self.path}: unknown image size: add 'image_size: [W, H]' to {META_FILE} "
                             "or an 'image_size' array to the frames")
        return size

    def frame_intrinsics(self, frame: Frame) -> Intrinsics:
        """Intrinsics for one frame: meta.yaml overridden by the frame's own keys."""
        base = Intrinsics(self.image_size, self.intrinsics.focal_px, self.intrinsics.principal_point)
        return base.override(frame.intrinsics).with_defaults()

    def require_static_frame(self, frame: Frame, image_size: tuple[int, int] | None = None) -> None:
        """InputError when ``frame`` was seen by another camera than ``image_size`` (default the
        sequence's): a frame stating another image size (photos of different sizes imported as one
        sequence) cannot share a static camera with the others; nor can the frames of a tool's file that
        holds several videos (:meth:`several_videos`), whatever their sizes."""
        videos = self.several_videos()
        if videos is not None:
            raise InputError(f"{self.label}: {videos}")
        expected = self.image_size if image_size is None else tuple(image_size)
        size = frame.intrinsics.image_size
        if size is not None and expected is not None and tuple(size) != tuple(expected):
            raise InputError(f"{frame.source}: image size {size[0]}x{size[1]} differs from "
                             f"{expected[0]}x{expected[1]}: these frames are not one static camera's (e.g. photos of "
                             f"different sizes); calibrate and align each image size as a sequence of its own"
                             f"{self._split_hint(frame)}")

    def several_videos(self) -> str | None:
        """What to do with the frames of several videos imported from one tool's file (meta.yaml's
        ``import.videos``, e.g. a HybrIK ``res.pk`` of demo runs sharing an output folder), or None: several
        cameras, each imported as a sequence of its own with ``rotavat import ... --video NAME``."""
        block = self.meta.get("import") if isinstance(self.meta, Mapping) else None
        videos = block.get("videos") if isinstance(block, Mapping) else None
        src, fmt = (block.get("source_path"), block.get("format")) if isinstance(block, Mapping) else (None, None)
        if not isinstance(videos, Mapping) or len(videos) < 2 or not src:
            return None
        listed = "; ".join(f"{name or '(no video name)'}: {what}" for name, what in videos.items())
        commands = [shlex.join(["rotavat", "import", *(["--from", str(fmt)] if fmt else []), str(src),
                                f"{Path(str(src)).stem}_{name}", "--video", str(name)]) for name in videos]
        shown = "; ".join(commands[:3]) + (f"; and likewise --video NAME for {', '.join(map(str, list(videos)[3:]))}"
                                           if len(commands) > 3 else "")
        return (f"its frames come from {len(videos)} videos of one file ({listed}), {len(videos)} cameras: calibrate "
                f"and align need one; import each video as a sequence of its own: {shown}")

    def _split_hint(self, frame: Frame) -> str:
        """A command that makes ``frame`` a sequence of its own (a sequence directory's frame), or ''."""
        source = self.frame_source
        if not isinstance(source, DirectorySource) or self.form != "npz":
            return ""
        folder = shlex.quote(f"{self.path.name}_{frame.name}")
        files = [shlex.quote(str(source.frame_path(frame.name)))]
        if (self.path / META_FILE).is_file() and self.meta.get("image_size") is None:  # else it names the other size
            files.append(shlex.quote(str(self.path / META_FILE)))
        return f", e.g. mkdir {folder} && cp {' '.join(files)} {folder}/ && rotavat calibrate {folder}"

    def frame_path(self, name: str) -> Path:
        """File (npz) or folder (obj) of a frame (a sequence directory's; ValueError for other sources)."""
        source = self.frame_source
        if not isinstance(source, DirectorySource):
            raise ValueError(f"{self.label}: its frames are not files of a sequence directory")
        return source.frame_path(name)

    def read_frame(self, name: str) -> Frame:
        """Read and validate one frame by name."""
        return self.frame_source.read_frame(name)

    def frames(self) -> Iterator[Frame]:
        """Frames in file-name order, one at a time."""
        for name in self.frame_names:
            yield self.read_frame(name)

    @property
    def warnings(self) -> tuple[str, ...]:
        """What reading the frames found so far that the user should hear of (an importer's dropped
        people, ...); none for a sequence directory (its frames are refused or accepted whole)."""
        return tuple(getattr(self.frame_source, "warnings", ()))

    def frame_notes(self, names: Iterable[str]) -> Any:
        """What reading these frames taught the source (warnings, ...): picklable, for
        :meth:`add_frame_notes` in the process that owns the sequence; None when nothing is kept."""
        notes = getattr(self.frame_source, "frame_notes", None)
        return notes(tuple(names)) if notes is not None else None

    def add_frame_notes(self, notes: Any) -> None:
        """Take in the notes of frames read elsewhere (a worker process's :meth:`frame_notes`)."""
        add = getattr(self.frame_source, "add_frame_notes", None)
        if add is not None and notes is not None:
            add(notes)


def open_sequence(path: str | Path, read_camera: bool = True) -> Sequence:
    """List a sequence directory's frames and read its meta.yaml and camera.yaml (not the frames)."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such directory")
    if not path.is_dir():
        raise InputError(f"{path}: not a directory (a sequence is a directory of frames)")
    npz = sorted(p.stem for p in path.glob("*.npz") if not p.name.startswith(".") and p.is_file())
    folders = sorted(p.name for p in path.iterdir() if p.is_dir() and _is_obj_frame_dir(p))
    if npz and any(_obj_files(path / name) for name in folders):
        raise InputError(f"{path}: holds both .npz frames and OBJ frame folders; keep one form per sequence")
    if not npz and not folders:
        raise InputError(f"{path}: no frames found (expected *.npz files or frame folders of *.obj)")
    form, names = ("npz", npz) if npz else ("obj", folders)
    ignored = tuple(line for name in names for line in _ignored_entries(path / name)) if form == "obj" else ()
    meta = read_yaml(path / META_FILE) if (path / META_FILE).exists() else {}
    _check_meta(meta, path / META_FILE)
    camera, fit = None, {}
    source = DirectorySource(path, form, tuple(names))
    seq = Sequence(path, form, tuple(names), meta, source=source)
    seq.intrinsics, seq.focal_kind  # validates meta.yaml's intrinsics keys early
    if read_camera and (path / CAMERA_FILE).exists():
        camera, fit = read_camera_yaml(path / CAMERA_FILE, seq.intrinsics.image_size)
    return Sequence(path, form, tuple(names), meta, camera, fit, ignored, source=source)


def is_sequence_dir(folder: str | Path) -> bool:
    """True for a folder of frames: ``*.npz`` files, or frame folders of which one at least holds a
    person's OBJ (the rule :func:`open_sequence` reads by; ``rotavat batch`` discovers by it)."""
    folder = Path(folder)
    try:
        entries = [p for p in folder.iterdir() if not p.name.startswith(".")]
        return any(p.suffix == ".npz" and p.is_file() for p in entries) or any(
            p.is_dir() and _is_obj_frame_dir(p) and _obj_files(p) for p in entries)
    except OSError:
        return False


def _is_obj_frame_dir(folder: Path) -> bool:
    """A frame folder: a visible folder holding at least one ``.obj`` entry, or an empty one (an empty frame)."""
    if folder.name.startswith((".", "_")):
        return False
    entries = _entries(folder)
    return not entries or any(p.suffix.lower() == ".obj" for p in entries)


_META_TYPES = {"source": str, "fps": (int, float), "focal_rule": str}


def _check_meta(meta: dict, source: Path) -> None:
    """meta.yaml's informational keys have their types (a mapping where a name belongs is refused)."""
    for key, kind in _META_TYPES.items():
        value = meta.get(key)
        if value is not None and (not isinstance(value, kind) or isinstance(value, bool)):
            raise file_error(str(source), f"key '{key}' must be a {'name' if kind is str else 'number'}, got {value!r:.60}")


def people_not_placed(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """(root_centred, behind) (P,) of a frame's people: :func:`rotavat_cli.geometry.camera.people_not_in_front`
    on its meshes (else its joints), the root being joint 0 when it has joints, else the points' mean."""
    verts, joints = frame.get("vertices"), frame.get("joints")
    points = verts if verts is not None and verts.shape[1] else joints
    if points is None or frame.n_people == 0:
        return np.zeros(frame.n_people, bool), np.zeros(frame.n_people, bool)
    roots = joints[:, 0] if joints is not None and joints.shape[1] else None
    return people_not_in_front(points, roots)


def can_align(frame: Frame) -> bool:
    """Whether ``rotavat align`` can place the frame's people: meshes, or joints with their mid-sole and
    crown pixels (joint-level alignment; rotavat_cli.alignment)."""
    return frame.get("vertices") is not None or all(frame.get(k) is not None for k in ("joints", "feet_2d", "heads_2d"))


def summarize_sequence(seq: Sequence) -> dict:
    """Validate every frame and summarise: form, frames, people, keys, sizes, intrinsics, camera."""
    people, keys, verts, joints, kps, ids = [], set(), set(), set(), set(), set()
    frame_sizes = set()
    centred = behind = 0
    not_alignable, other_focal = [], []  # frame names
    meta_focal = seq.intrinsics.focal_px
    for frame in seq.frames():
        people.append(frame.n_people)
        if frame.n_people and not can_align(frame):
            not_alignable.append(frame.name)
        stated = frame.intrinsics.focals_px(frame.n_people) if frame.n_people else None
        if meta_focal is not None and stated is not None and not np.allclose(stated, meta_focal, rtol=1e-6):
            other_focal.append(frame.name)
        is_centred, is_behind = people_not_placed(frame)
        centred += int(is_centred.sum())
        behind += int((is_behind & ~is_centred).sum())
        keys.update(frame.data.keys())
        if frame.get("vertices") is not None and frame.n_people:
            verts.add(int(frame.data["vertices"].shape[1]))
        if frame.get("joints") is not None and frame.n_people:
            joints.add(int(frame.data["joints"].shape[1]))
        if frame.get("keypoints_2d") is not None and frame.n_people:
            kps.add(int(frame.data["keypoints_2d"].shape[1]))
        if frame.get("person_ids") is not None:
            ids.update(int(i) for i in frame.data["person_ids"])
        if frame.intrinsics.image_size is not None:
            frame_sizes.add(frame.intrinsics.image_size)
    counts = np.asarray(people, dtype=np.int64)
    intr = seq.intrinsics
    image_size = intr.image_size or (sorted(frame_sizes)[0] if frame_sizes else None) or (seq.camera.image_size if seq.camera else None)
    return {
        "path": str(seq.path),
        "form": seq.form,
        "frames": len(seq),
        "people_total": int(counts.sum()),
        "people_per_frame": {"min": int(counts.min()), "median": float(np.median(counts)), "max": int(counts.max())},
        "empty_frames": int((counts == 0).sum()),
        "tracks": len(ids) if ids else None,
        "keys": sorted(keys),
        "vertex_counts": sorted(verts),
        "joint_counts": sorted(joints),
        "keypoint_counts": sorted(kps),
        "image_size": list(image_size) if image_size else None,
        "image_sizes": [list(size) for size in sorted(frame_sizes)],
        "people_root_centred": centred,
        "people_behind_camera": behind,
        "frames_not_alignable": not_alignable,
        "frames_with_another_focal": other_focal,
        "focal_px": intr.focal_px,
        "focal_kind": seq.focal_kind,
        "focal_rule": seq.meta.get("focal_rule"),
        "principal_point": list(intr.principal_point) if intr.principal_point else None,
        "source": seq.meta.get("source"),
        "ignored_entries": list(seq.ignored),
        "camera": camera_to_yaml_dict(seq.camera, seq.camera_fit or None) if seq.camera else None,
    }

