"""Helpers shared by the format readers: the import options and result types, validation of what a
file holds, the contract frame a reader builds, frame names and meta.yaml content."""

from __future__ import annotations

import codecs
import os
import re
import struct
import zipfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..camera import MAX_IMAGE_SIDE_PX, Camera, project_cam_to_px
from ..errors import InputError
from ..joint_layouts import layout_key
from ..sequence import Frame, people_not_placed, validate_frame
from .keypoints import feet_heads_px, recipe_for
from .smpl import BodyModel

__all__ = [
    "Conclusion",
    "FrameNotes",
    "ImportOptions",
    "ImportedSequence",
    "as_array",
    "base_meta",
    "check_model_kind",
    "conclude_placement",
    "fail",
    "feet_heads_from",
    "file_kind",
    "frame_names",
    "get",
    "image_size_from_header",
    "model_faces",
    "natural_key",
    "need_image_size",
    "no_model_warning",
    "npz_has_keys",
    "padded_square",
    "people_frame",
    "placement_warnings",
    "project_px",
    "require_model",
    "single_file",
    "tool_name",
    "wrong_kind",
]


# ---- shared types --------------------------------------------------------------------------
@dataclass(frozen=True)
class ImportOptions:
    """What the user told us: image size (W, H) px, a posable body model, a field of view (deg), and
    which video to read of a file that holds several (HybrIK's ``res.pk``)."""

    image_size: tuple[int, int] | None = None
    body_model: BodyModel | None = None
    fov_deg: float | None = None
    video: str | None = None


@dataclass
class FrameNotes:
    """What building one frame found besides the frame: its warnings (dropped people, duplicate
    ids), and facts the reader sums up over every frame (``ImportedSequence.conclude``), e.g. the
    joints layout the frame showed or its people's heights above the ground. Plain, picklable data."""

    warnings: list[str] = field(default_factory=list)
    facts: dict[str, Any] = field(default_factory=dict)


@dataclass
class Conclusion:
    """The part of an import that depends on every frame: entries of meta.yaml's ``import:`` block,
    warnings, and (SPEC) the camera."""

    import_meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    camera: Camera | None = None
    camera_fit: dict | None = None


@dataclass
class ImportedSequence:
    """A converted sequence: frame names, any frame built on demand, meta.yaml content, optional camera.

    ``build(i, notes)`` builds frame ``i`` from what the reader loaded (kept in its closure: the
    parsed files, never the frames) and records what it found in ``notes``; frames can be built
    in any order, again, or in another process with the same reader. ``meta`` and ``warnings``
    hold what is known before any frame is built; ``conclude`` (optional) turns the notes of
    every frame, in frame order, into the rest (:class:`Conclusion`).

    Iterating ``frames`` builds every frame in order and then completes ``warnings``, ``meta``
    and ``camera`` as ``rotavat import`` writes them: read those after the iterator is exhausted.
    """

    names: tuple[str, ...]
    build: Callable[[int, FrameNotes], Frame]
    meta: dict
    warnings: list[str] = field(default_factory=list)
    camera: Camera | None = None
    camera_fit: dict | None = None
    conclude: Callable[[list[FrameNotes]], Conclusion] | None = None
    camera_from_frames: bool = False  # the conclusion holds the camera (SPEC): reading one needs every frame

    @property
    def n_frames(self) -> int:
        return len(self.names)

    def frame_at(self, index: int) -> tuple[Frame, FrameNotes]:
        """Frame ``index`` (0-based, frame order) and what building it found, including how many of its
        people are not placed in the camera (:func:`rotavat_cli.sequence.people_not_placed`), whatever the reader."""
        notes = FrameNotes()
        frame = self.build(index, notes)
        notes.facts["unplaced"] = [int(np.logical_or(*people_not_placed(frame)).sum()), frame.n_people]
        return frame, notes

    def concluded(self, notes: list[FrameNotes]) -> Conclusion:
        """The frame-dependent part of the import from every frame's notes, in frame order: the
        reader's own (``conclude``), and one warning for the people not placed in the camera."""
        conclusion = self.conclude(notes) if self.conclude is not None else Conclusion()
        source = self.meta.get("import", {}).get("source_path", "the import")
        conclusion.warnings.extend(conclude_placement(notes, source))
        return conclusion

    def apply(self, conclusion: Conclusion) -> None:
        """Complete ``meta``, ``warnings`` and the camera with a conclusion."""
        self.meta.setdefault("import", {}).update(conclusion.import_meta)
        self.warnings.extend(conclusion.warnings)
        if conclusion.camera is not None:
            self.camera, self.camera_fit = conclusion.camera, conclusion.camera_fit

    @property
    def frames(self) -> Iterator[Frame]:
        """Every frame in order, one at a time (one pass; see the class docstring)."""
        return self._frames()

    def _frames(self) -> Iterator[Frame]:
        notes = []
        for index in range(self.n_frames):
            frame, found = self.frame_at(index)
            self.warnings.extend(found.warnings)
            notes.append(found)
            yield frame
        self.apply(self.concluded(notes))


# ---- helpers shared by the readers -----------------------------------------------------------
def fail(source: Any, message: str) -> InputError:
    """InputError whose message starts with the file name."""
    return InputError(f"{source}: {message}")


# ---- files that are no tool's output ---------------------------------------------------------
_TOOL_NAMES = {"cliff": "CLIFF", "bev": "BEV", "romp": "ROMP", "4dhumans": "4D-Humans", "multihmr": "Multi-HMR",
               "spec": "SPEC", "agora": "AGORA", "bedlam": "BEDLAM", "wham": "WHAM", "gvhmr": "GVHMR", "tram": "TRAM",
               "hybrik": "HybrIK", "pymafx": "PyMAF-X", "slahmr": "SLAHMR", "glamr": "GLAMR", "trace": "TRACE"}


def tool_name(fmt: str) -> str:
    """How messages name the tool of format ``fmt``, with its article: 'a HybrIK', 'an AGORA'."""
    name = _TOOL_NAMES.get(fmt, fmt)
    return f"{'an' if name[:1] in 'AEIOU' else 'a'} {name}"


# (magic bytes at offset 0, what the file is): formats no reader takes as its source
_MAGIC = ((b"\x89PNG\r\n\x1a\n", "a PNG image"), (b"\xff\xd8\xff", "a JPEG image"), (b"GIF87a", "a GIF image"),
          (b"GIF89a", "a GIF image"), (b"II*\x00", "a TIFF image"), (b"MM\x00*", "a TIFF image"),
          (b"%PDF-", "a PDF document"), (b"\x1aE\xdf\xa3", "a Matroska/WebM video"), (b"%YAML", "a YAML file"),
          (b"---", "a YAML file"))
_RIFF = {b"WEBP": "a WebP image", b"AVI ": "an AVI video", b"WAVE": "a WAV audio file"}
_IMAGE_BRANDS = (b"heic", b"heix", b"mif1", b"avif")  # ISO media files that are still images


def file_kind(path: Path) -> str | None:
    """What ``path`` is when its first bytes show it is no HPS tool's output ('a JSON file', 'a PNG image',
    'an MP4/MOV video', 'a zip archive', 'an empty file', ...); None for what the readers read (pickles,
    compressed joblib, .npy, .npz, torch archives), for directories, and for anything not recognised.

    JSON: the first byte after white space (and a UTF-8 byte-order mark) is ``{`` or ``[``, which no
    pickle, .npy or compressed stream starts with. A zip archive holding no ``.npy`` member (an npz)
    and no ``data.pkl`` (a torch archive) is just a zip archive.
    """
    try:
        if not path.is_file():
            return None
        with open(path, "rb") as handle:
            head = handle.read(64)
    except OSError:
        return None
    if not head:
        return "an empty file"
    text = head.removeprefix(b"\xef\xbb\xbf").lstrip(b" \t\r\n")
    if text[:1] in (b"{", b"[") and _is_text(text):
        return "a JSON file"
    for magic, kind in _MAGIC:
        if head.startswith(magic):
            return kind
    if head[:4] == b"RIFF" and head[8:12] in _RIFF:
        return _RIFF[head[8:12]]
    if head[4:8] == b"ftyp":
        return "a HEIC/AVIF image" if head[8:12] in _IMAGE_BRANDS else "an MP4/MOV video"
    if path.suffix.lower() in (".yaml", ".yml") and text[:1].isalpha() and _is_text(text):
        return "a YAML file"
    if head[:4] in (b"PK\x03\x04", b"PK\x05\x06"):
        try:
            with zipfile.ZipFile(path) as archive:
                names = archive.namelist()
        except (zipfile.BadZipFile, OSError, ValueError):
            return None  # a damaged npz or torch archive: its reader says what is wrong
        if not any(n.endswith(".npy") or n.endswith("data.pkl") for n in names):
            return "a zip archive"
    return None


def _is_text(head: bytes) -> bool:
    """True when ``head`` (a file's first bytes) is UTF-8 text: printable characters and white space only
    (a character cut at the end is allowed)."""
    try:
        chars = codecs.getincrementaldecoder("utf-8")().decode(head, final=False)
    except UnicodeDecodeError:
        return False
    return all(c.isprintable() or c in "\t\r\n" for c in chars)


def wrong_kind(path: Path, fmt: str | None) -> InputError | None:
    """The one-line refusal for a file that is no tool's output (:func:`file_kind`), read as ``fmt``
    (None: no format was given or detected); None when ``path`` may be one."""
    kind = file_kind(path)
    if kind is None:
        return None
    from . import available_formats  # the registry imports this module

    what = "an HPS tool's output" if fmt is None else f"{tool_name(fmt)} output"
    return fail(path, f"{kind}, not {what} (rotavat reads: {', '.join(available_formats())})")


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
                 n_verts: int | None = None, extra: Mapping[str, np.ndarray] | None = None,
                 keypoints_layout: str | None = None) -> Frame:
    """A validated contract frame; people with non-finite vertices or joints are dropped (with a warning).

    keypoints_layout: the layout of ``keypoints_2d`` (:mod:`.keypoints`); when it has a recipe and
    the frame has no meshes, ``feet_2d``/``heads_2d`` (mid-sole, crown) are written from them, so
    calibration and joint-level alignment work without a body model (meshes give their own
    landmarks, which take precedence: :func:`feet_heads_from`). A person missing a recipe point
    gets a NaN row (calibration drops the pair, align flags the person).
    """
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
    if person_ids is not None:
        check_int64_ids(np.asarray(person_ids), source)
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
    if keypoints_layout is not None and "keypoints_2d" in data and "vertices" not in data:
        found = feet_heads_px(data["keypoints_2d"], keypoints_layout)
        if found is not None:
            data["feet_2d"], data["heads_2d"] = (points.astype(np.float32) for points in found[:2])
    data.update(extra or {})
    validate_frame(data, str(source))
    return Frame(name, data, str(source))


# ---- people not placed in the camera ---------------------------------------------------------
def placement_warnings(unplaced: int, people: int, source: Any) -> list[str]:
    """The warning for ``unplaced`` of ``people`` people not placed in the camera (none when 0)."""
    if unplaced == 0:
        return []
    scope = "every person" if unplaced == people else f"{unplaced} of {people} people"
    message = (f"{source}: {scope} at the camera centre or (partly) behind the camera (z <= 0): root-centred "
               "output (no translation) or another frame, not people placed in the camera; calibrate and align "
               "cannot use them (root-aligned metrics such as MPJPE, PVE and PA-MPJPE still apply)")
    return [message]


def conclude_placement(notes: list[FrameNotes], source: Any) -> list[str]:
    """Sum every frame's ``unplaced`` fact (:meth:`ImportedSequence.frame_at`) into one warning."""
    counts = [n.facts["unplaced"] for n in notes if n.facts.get("unplaced")]
    return placement_warnings(sum(c[0] for c in counts), sum(c[1] for c in counts), source)


def feet_heads_from(keypoints_layout: str | None, has_vertices: bool) -> str | None:
    """meta.yaml ``import.feet_heads_from``: which points give the foot and head pixels of an import."""
    if has_vertices:
        return "mesh landmarks (mid-sole, crown vertices)"
    recipe = recipe_for(keypoints_layout)
    return None if recipe is None else f"keypoints_2d, {layout_key(keypoints_layout)}: {recipe.describes}"


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


_INT64 = np.iinfo(np.int64)
MAX_FRAMES = 100_000  # frames a tool's frame indices may imply beyond 100 per detection row (~1 h of video)


def int64_ids(ids: list[int], what: str, source: Any) -> np.ndarray:
    """Track / person ids (P,) as int64; InputError naming ``what`` when one does not fit 64 bits."""
    bad = [i for i in ids if not _INT64.min <= i <= _INT64.max]
    if bad:
        raise fail(source, f"{what} {bad[0]} does not fit in a 64-bit integer")
    return np.asarray(ids, dtype=np.int64)


def check_int64_ids(ids: np.ndarray, source: Any) -> None:
    """InputError when track ids (P,) do not fit a 64-bit signed integer (uint64 beyond 2^63 - 1, inf,
    huge floats): ``astype(int64)`` would wrap them silently into other ids."""
    if ids.size and ids.dtype.kind in "uf":
        with np.errstate(invalid="ignore"):
            bad = ids > _INT64.max if ids.dtype.kind == "u" else ~np.isfinite(ids) | (np.abs(ids) >= 2.0 ** 63)
        if np.any(bad):
            raise fail(source, f"person id {ids[np.argmax(bad)]} does not fit in a 64-bit integer")


def check_frame_range(n_frames: int, n_rows: int, source: Any, key: str) -> int:
    """``n_frames`` (1 + the largest frame index), unless it implies far more frames than the file has
    detection rows (a few KB naming frame 10^12 would make 10^12 frames)."""
    if n_frames > MAX_FRAMES + 100 * n_rows:
        raise fail(source, f"'{key}' reaches frame {n_frames - 1:,} with {n_rows:,} detection rows: not the frame "
                           "indices of one video")
    return n_frames


def centre_image_size(cx: float, cy: float, source: Any, what: str) -> tuple[int, int]:
    """(W, H) = (2 cx, 2 cy) px rounded, for tools whose principal point is the image centre; InputError
    unless both are within 1..MAX_IMAGE_SIDE_PX (the contract's bound)."""
    size = (2.0 * float(cx), 2.0 * float(cy))
    if not all(np.isfinite(v) and 1 <= v <= MAX_IMAGE_SIDE_PX for v in size):
        raise fail(source, f"{what} ({float(cx):.6g}, {float(cy):.6g}) px is not the centre of an image of at most "
                           f"{MAX_IMAGE_SIDE_PX} px: pass --image-size W H")
    return round(size[0]), round(size[1])


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


_MODEL_FILES = {"smpl": ("SMPL", 24, "SMPL_NEUTRAL.npz"), "smplx": ("SMPL-X", 55, "SMPLX_NEUTRAL.npz"),
                "smplh": ("SMPL-H", 52, "the SMPL-H model.npz")}


def check_model_kind(model: BodyModel | None, source: Any, tool: str, kind: str) -> BodyModel | None:
    """``model`` when it is of the family the tool's parameters are (``kind``: smpl | smplx | smplh)
    or None; an InputError naming the file, the tool and the joint count it needs otherwise."""
    family, joints, _ = _MODEL_FILES[kind]
    if model is not None and model.kind != kind:
        raise fail(source, f"{tool} uses {family}; --smpl-model {model.name} has {model.n_joints} joints (need {joints})")
    return model


def require_model(model: BodyModel | None, source: Any, tool: str, kind: str) -> BodyModel:
    """The body model a format that stores nothing but parameters needs (:func:`check_model_kind`);
    an InputError saying to pass it when it is missing."""
    family, _, file_name = _MODEL_FILES[kind]
    if model is None:
        raise fail(source, f"{tool} stores {family} parameters only (no joints, no 2D keypoints): pass --smpl-model "
                           f"{file_name} (the {family} model file) to pose them")
    return check_model_kind(model, source, tool, kind)


def no_model_warning(fmt: str) -> str:
    """The message for parameter-only formats imported without --smpl-model."""
    return (f"{fmt} stores SMPL parameters, not meshes, and no --smpl-model was given: imported joints only; "
            "PVE/W-PVE are unavailable and align works at joint level (from the 2D keypoints' feet and heads)")


def model_faces(model: BodyModel | None, n_verts: int | None) -> np.ndarray | None:
    """The body model's triangles when they fit meshes of ``n_verts`` vertices."""
    if model is None or model.faces is None or n_verts is None or model.n_verts != n_verts:
        return None
    return model.faces
