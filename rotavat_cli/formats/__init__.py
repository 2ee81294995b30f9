"""Readers for the files HPS methods actually write, converted into the data contract.

One module per external tool; each exports ``READERS = {"name": read_name}`` (trimesh's loader
registry) and a ``sniff(path) -> name | None`` used by :func:`detect_format`. Every reader takes the
source path and :class:`ImportOptions` and returns the same type, :class:`ImportedSequence`: lazily
produced contract :class:`~rotavat_cli.sequence.Frame` objects (OpenCV camera frame, metres,
float32), the sequence-level ``meta.yaml`` content, and (SPEC only) a camera. Conventions of each
tool, with the source files they were read from, are in ``docs/formats.md``.

Frame keys written: ``vertices`` (P, V, 3) when meshes are known (given by the tool, or posed from
its SMPL parameters with ``--smpl-model``), ``faces`` when the model file gives them, ``joints``
(P, J, 3) in SMPL-24 order whenever possible (``meta.yaml`` ``import.joints_layout`` says which),
``keypoints_2d`` (P, K, 2) in original-image pixels, ``person_ids`` (P,) for tracked sources, and
per-frame ``focal_length`` / ``principal_point`` / ``image_size`` only when they vary per frame.
"""

from __future__ import annotations

import contextlib
import os
import re
import struct
import tempfile
import zipfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import staged_directory
from ..camera import Camera, project_cam_to_px
from ..errors import InputError
from ..outputs import check_output_dir
from ..plain import to_plain
from ..sequence import Frame, Sequence, open_sequence, validate_frame, write_camera_yaml, write_frame, write_meta
from ..smpl import BodyModel, load_body_model

__all__ = [
    "ImportOptions",
    "ImportedSequence",
    "available_formats",
    "detect_format",
    "read_format",
    "import_sequence",
    "imported_sequence",
]


# ---- shared types --------------------------------------------------------------------------
@dataclass(frozen=True)
class ImportOptions:
    """What the user told us: image size (W, H) px, a posable body model, a field of view (deg)."""

    image_size: tuple[int, int] | None = None
    body_model: BodyModel | None = None
    fov_deg: float | None = None


@dataclass
class ImportedSequence:
    """A converted sequence: frames (lazy, one pass), meta.yaml content, optional camera.

    Readers may fill ``warnings``, ``meta`` and ``camera`` while ``frames`` is being consumed;
    read them after the iterator is exhausted.
    """

    frames: Iterator[Frame]
    n_frames: int
    meta: dict
    warnings: list[str] = field(default_factory=list)
    camera: Camera | None = None
    camera_fit: dict | None = None


# ---- helpers shared by the readers -----------------------------------------------------------
def fail(source: Any, message: str) -> InputError:
    """InputError whose message starts with the file name."""
    return InputError(f"{source}: {message}")


def npz_has_keys(path: Path, keys: set[str]) -> bool:
    """True for an .npz file holding at least ``keys`` (read from the zip index, no arrays loaded)."""
    if not (path.is_file() and path.suffix == ".npz"):
        return False
    with zipfile.ZipFile(path) as archive:
        return keys <= {n[:-4] for n in archive.namelist()}


def single_file(src: Path, sniff: Callable[[Path], str | None], what: str, hint: str = "") -> Path:
    """``src`` itself, or the one file in directory ``src`` that ``sniff`` recognises."""
    if src.is_file():
        return src
    candidates = [p for p in sorted(src.glob("*.npz")) if sniff(p)]
    if len(candidates) != 1:
        raise fail(src, f"expected one {what} in the directory, found {len(candidates)}{hint}")
    return candidates[0]


def need_image_size(opts: ImportOptions, source: Any, why: str) -> tuple[int, int]:
    """The user's --image-size, or an InputError saying to pass it."""
    if opts.image_size is None:
        raise fail(source, f"the image size is not stored in this file ({why}); pass --image-size W H")
    return opts.image_size


def as_array(obj: Any, name: str, source: Any, ndim: int | None = None, last: tuple[int, ...] | None = None,
             kinds: str = "fiu") -> np.ndarray:
    """Validate ``obj`` as a numeric ndarray (float64 copy for floats); InputError naming ``name``."""
    if isinstance(obj, (list, tuple)):
        try:
            obj = np.asarray(obj)
        except (ValueError, TypeError):
            raise fail(source, f"'{name}' is not a numeric array") from None
    if not isinstance(obj, np.ndarray) or obj.dtype.kind not in kinds:
        got = obj.dtype if isinstance(obj, np.ndarray) else type(obj).__name__
        raise fail(source, f"'{name}' must be a numeric array, got {got}")
    if ndim is not None and obj.ndim != ndim:
        raise fail(source, f"'{name}' must have {ndim} dimensions, got shape {list(obj.shape)}")
    if last is not None and obj.shape[obj.ndim - len(last):] != last:
        raise fail(source, f"'{name}' must end with shape {list(last)}, got {list(obj.shape)}")
    return obj.astype(np.float64) if obj.dtype.kind == "f" else obj


def get(mapping: Any, key: str, source: Any, required: bool = True) -> Any:
    """``mapping[key]`` with InputErrors for non-mappings and missing keys."""
    if not isinstance(mapping, Mapping):
        raise fail(source, f"expected a dict of results, got {type(mapping).__name__}")
    if key not in mapping:
        if required:
            raise fail(source, f"missing key '{key}'")
        return None
    return mapping[key]


def padded_square(image_size: tuple[int, int]) -> tuple[int, int, int]:
    """(S, left, top) of the centred zero-padding to a square used by ROMP/BEV/PHALP: S = max(W, H)."""
    width, height = image_size
    side = max(width, height)
    return side, (side - width) // 2, (side - height) // 2


def project_px(points_cam: np.ndarray, focal_px: float, principal_point: tuple[float, float]) -> np.ndarray:
    """Camera-frame points (..., 3) -> pixels (..., 2) (NaN behind the camera)."""
    return project_cam_to_px(points_cam, focal_px, principal_point)


def image_size_from_header(path: Path) -> tuple[int, int] | None:
    """(W, H) read from a PNG or JPEG header, or None (missing, unreadable or other formats)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(32)
            if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
                return struct.unpack(">II", head[16:24])
            if head[:2] != b"\xff\xd8":
                return None
            handle.seek(2)
            for _ in range(1000):  # walk the JPEG segments to the first start-of-frame marker
                marker = handle.read(2)
                if len(marker) < 2 or marker[0] != 0xFF:
                    return None
                length = struct.unpack(">H", handle.read(2))[0]
                if marker[1] in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF):
                    height, width = struct.unpack(">HH", handle.read(5)[1:5])
                    return (width, height)
                handle.seek(length - 2, os.SEEK_CUR)
    except (OSError, struct.error):
        return None
    return None


def people_frame(name: str, source: Any, warnings: list[str], *, vertices: np.ndarray | None = None,
                 joints: np.ndarray | None = None, keypoints_2d: np.ndarray | None = None,
                 person_ids: np.ndarray | None = None, faces: np.ndarray | None = None,
                 n_verts: int | None = None, extra: Mapping[str, np.ndarray] | None = None) -> Frame:
    """A validated contract frame; people with non-finite vertices or joints are dropped (with a warning)."""
    arrays = {"vertices": vertices, "joints": joints, "keypoints_2d": keypoints_2d, "person_ids": person_ids}
    counts = {k: len(v) for k, v in arrays.items() if v is not None}
    if len(set(counts.values())) > 1:
        raise fail(source, f"inconsistent people counts ({', '.join(f'{k}={v}' for k, v in counts.items())})")
    n_people = next(iter(counts.values()), 0)
    keep = np.ones(n_people, dtype=bool)
    for key in ("vertices", "joints"):
        if arrays[key] is not None and n_people:
            keep &= np.isfinite(arrays[key]).reshape(n_people, -1).all(axis=1)
    if not keep.all():
        warnings.append(f"{source}: dropped {int((~keep).sum())} person(s) with non-finite vertices or joints")
    data: dict[str, np.ndarray] = {}
    for key, value in arrays.items():
        if value is None:
            continue
        value = value[keep]
        with np.errstate(over="ignore", invalid="ignore"):  # out-of-range values become inf: refused below
            data[key] = value.astype(np.int64) if key == "person_ids" else value.astype(np.float32)
    if "vertices" not in data and n_verts is not None and not keep.any():
        data["vertices"] = np.zeros((0, n_verts, 3), np.float32)
    if faces is not None and "vertices" in data and data["vertices"].shape[1] == 0:
        faces = None
    if faces is not None:
        data["faces"] = faces.astype(np.int32)
    if "person_ids" in data and len(np.unique(data["person_ids"])) != len(data["person_ids"]):
        warnings.append(f"{source}: duplicate person ids in one frame; ids dropped for this frame")
        del data["person_ids"]
    if not data:
        data["person_ids"] = np.zeros(0, np.int64)
    data.update(extra or {})
    validate_frame(data, str(source))
    return Frame(name, data, str(source))


def frame_names(sources: list[str], warnings: list[str]) -> list[str]:
    """Contract frame names from the tool's image stems (no extension), in the tool's (time) order.

    The image stem is kept (characters outside ``[A-Za-z0-9._-]`` become ``_``) so sequences
    imported from two tools run on the same images line up frame by frame in ``eval``. When stems
    repeat, or sorting them by name would not give the tool's order (``img_2`` after ``img_10``),
    names become ``<zero-padded index>_<stem>`` instead (order kept, cross-tool matching lost).
    """
    stems = [re.sub(r"[^A-Za-z0-9._-]", "_", str(s)) or "frame" for s in sources]
    if len(set(stems)) == len(stems) and stems == sorted(stems) and not any(s.startswith(".") for s in stems):
        return stems
    width = max(6, len(str(len(stems))))
    warnings.append("frame names are the image names prefixed by their index (the image names repeat or do not "
                    "sort in time order)")
    return [f"{i:0{width}d}_{stem.lstrip('.')}" for i, stem in enumerate(stems)]


def natural_key(name: str) -> tuple:
    """Sort key that orders 'img_2' before 'img_10'."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))


def base_meta(fmt: str, src: Path, opts: ImportOptions, image_size: tuple[int, int] | None,
              focal_px: float | None, principal_point: tuple[float, float] | None, *, focal_kind: str,
              focal_rule: str | None = None) -> dict:
    """meta.yaml content common to all formats (plain types only).

    focal_kind: ``camera`` when the tool's focal is the camera's own (ground truth), ``assumed``
    when the tool guessed it (its documented rule, ``focal_rule``; rotavat.focal).
    """
    meta: dict[str, Any] = {"source": fmt, "focal_kind": focal_kind}
    if focal_rule is not None:
        meta["focal_rule"] = focal_rule
    if image_size is not None:
        meta["image_size"] = [int(image_size[0]), int(image_size[1])]
    if focal_px is not None:
        meta["focal_length"] = float(focal_px)
    if principal_point is not None:
        meta["principal_point"] = [float(principal_point[0]), float(principal_point[1])]
    meta["import"] = {
        "format": fmt,
        "source_path": str(src.resolve()),
        "body_model": opts.body_model.name if opts.body_model is not None else None,
    }
    return meta


def no_model_warning(fmt: str) -> str:
    """The message for parameter-only formats imported without --smpl-model."""
    return (f"{fmt} stores SMPL parameters, not meshes, and no --smpl-model was given: imported joints only; "
            "PVE/W-PVE and align (which needs meshes) will be unavailable")


def model_faces(model: BodyModel | None, n_verts: int | None) -> np.ndarray | None:
    """The body model's triangles when they fit meshes of ``n_verts`` vertices."""
    if model is None or model.faces is None or n_verts is None or model.n_verts != n_verts:
        return None
    return model.faces


# ---- registry (modules import the helpers above) ---------------------------------------------
from . import agora, bedlam, bev, cliff, fourdhumans, multihmr, spec  # noqa: E402

_MODULES = (cliff, bev, fourdhumans, multihmr, spec, agora, bedlam)
READERS: dict[str, Callable[[Path, ImportOptions], ImportedSequence]] = {}
for _module in _MODULES:
    READERS.update(_module.READERS)


def available_formats() -> list[str]:
    """Names accepted by ``--from``."""
    return sorted(READERS)


def detect_format(path: str | Path) -> str | None:
    """Guess the format of a file or directory from its names and keys (None if unknown)."""
    path = Path(path)
    if not path.exists():
        return None
    for module in _MODULES:
        try:
            found = module.sniff(path)
        except (InputError, OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, EOFError,
                zipfile.BadZipFile, RecursionError):
            found = None
        if found:
            return found
    return None


def read_format(src: str | Path, fmt: str, *, image_size: tuple[int, int] | None = None,
                smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None) -> ImportedSequence:
    """Open ``src`` with the reader of ``fmt`` (frames are read lazily)."""
    src = Path(src)
    if fmt not in READERS:
        raise InputError(f"unknown format '{fmt}' (known: {', '.join(available_formats())})")
    if not src.exists():
        raise InputError(f"{src}: no such file or directory")
    if image_size is not None:
        if len(image_size) != 2 or any(int(v) != v or v <= 0 for v in image_size):
            raise InputError(f"--image-size must be two positive integers W H, got {image_size!r}")
        image_size = (int(image_size[0]), int(image_size[1]))
    if fov_deg is not None and not 0 < fov_deg < 180:
        raise InputError(f"--fov must be in (0, 180) degrees, got {fov_deg}")
    model = smpl_model if isinstance(smpl_model, BodyModel) or smpl_model is None else load_body_model(smpl_model)
    imported = READERS[fmt](src, ImportOptions(image_size, model, fov_deg))
    if fov_deg is not None and fmt not in _FOV_FORMATS:
        imported.warnings.append(f"--fov is ignored for {fmt} (its focal length is fixed by the method)")
    return imported


_FOV_FORMATS = ("multihmr",)  # formats whose field of view is a user setting of the method
# What malformed content raises in numpy and the readers (a unicode array holding invalid code points
# raises SystemError when read as text).
_READ_ERRORS = (ValueError, TypeError, KeyError, IndexError, AttributeError, OverflowError, MemoryError, SystemError,
                UnicodeError)


def _invalid(src: Path, fmt: str, exc: BaseException) -> InputError:
    """A one-line InputError for content that does not fit the format (wrong types, shapes, keys)."""
    detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    if isinstance(exc, KeyError):
        detail = f"missing key {detail}"
    return InputError(f"{src}: not a valid {fmt} output ({detail})")


def import_sequence(src: str | Path, out: str | Path, fmt: str, *, image_size: tuple[int, int] | None = None,
                    smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None,
                    progress: Callable[[int], Any] | None = None, overwrite: bool = False) -> dict:
    """Convert ``src`` (format ``fmt``) into a contract sequence directory ``out``.

    Frames are written to a staging directory beside ``out`` and swapped in whole only when every
    frame converted, so a failed import leaves ``out`` untouched. An existing ``out`` is replaced
    only when it is empty or rotavat's own output, or with ``overwrite``; never when it is, holds or
    lies inside ``src`` (:func:`rotavat_cli.outputs.check_output_dir`). ``progress(n)`` is called
    after each frame.

    Returns a summary: out, format, frames, people, empty_frames, image_size, focal_px,
    has_vertices, joints_layout, camera_yaml, warnings.
    """
    src, out = Path(src), Path(out)
    check_output_dir(out, [src], overwrite)
    try:
        imported = read_format(src, fmt, image_size=image_size, smpl_model=smpl_model, fov_deg=fov_deg)
    except _READ_ERRORS as exc:
        raise _invalid(src, fmt, exc) from None
    with staged_directory(out, "import") as staging:
        frames = people = empty = 0
        has_vertices = False
        try:
            for frame in imported.frames:
                write_frame(staging, frame, "npz")
                frames += 1
                people += frame.n_people
                empty += frame.n_people == 0
                has_vertices |= frame.n_people > 0 and frame.get("vertices") is not None
                if progress is not None:
                    progress(1)
        except _READ_ERRORS as exc:
            raise _invalid(src, fmt, exc) from None
        if frames == 0:
            raise InputError(f"{src}: no frames found for format '{fmt}'")
        meta = to_plain(dict(imported.meta))
        meta.setdefault("import", {})["warnings"] = [str(w) for w in imported.warnings]
        write_meta(staging, meta)
        if imported.camera is not None:
            write_camera_yaml(staging / "camera.yaml", imported.camera, imported.camera_fit)
    info = meta.get("import", {})
    return {
        "out": str(out),
        "format": fmt,
        "frames": frames,
        "people": people,
        "empty_frames": empty,
        "image_size": meta.get("image_size"),
        "focal_px": meta.get("focal_length"),
        "has_vertices": has_vertices,
        "joints_layout": info.get("joints_layout"),
        "camera_yaml": imported.camera is not None,
        "warnings": list(imported.warnings),
    }


@contextlib.contextmanager
def imported_sequence(src: str | Path, fmt: str, **options: Any) -> Iterator[Sequence]:
    """Convert on the fly: import into a temporary directory and yield it opened (for --from in
    calibrate/align/eval). The directory is deleted on exit. ``options`` as for import_sequence."""
    with tempfile.TemporaryDirectory(prefix="rotavat-import-") as tmp:
        out = Path(tmp) / "seq"
        import_sequence(src, out, fmt, **options)
        yield open_sequence(out)
