"""Readers for the files HPS methods actually write, converted into the data contract.

One module per external tool; each exports ``READERS = {"name": read_name}`` (trimesh's loader
registry) and a ``sniff(path) -> name | None`` used by :func:`detect_format`. Every reader takes the
source path and :class:`ImportOptions` and returns the same type, :class:`ImportedSequence`: contract
:class:`~rotavat_cli.sequence.Frame` objects (OpenCV camera frame, metres, float32) built one at a
time on demand from what the reader loaded, the sequence-level ``meta.yaml`` content, and (SPEC
only) a camera. :func:`import_sequence` writes them as a sequence directory; :func:`imported_sequence`
reads them as a :class:`~rotavat_cli.sequence.Sequence` without writing anything
(:mod:`rotavat_cli.formats.source`). Conventions of each tool, with the source files they were
read from, are in ``docs/formats.md``.

Frame keys written: ``vertices`` (P, V, 3) when meshes are known (given by the tool, or posed from
its SMPL parameters with ``--smpl-model``), ``faces`` when the model file gives them, ``joints``
(P, J, 3) in SMPL-24 order whenever possible (``meta.yaml`` ``import.joints_layout`` says which),
``keypoints_2d`` (P, K, 2) in original-image pixels, ``person_ids`` (P,) for tracked sources, and
per-frame ``focal_length`` / ``principal_point`` / ``image_size`` only when they vary per frame.
"""

from __future__ import annotations

import contextlib
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..atomic import staged_directory
from ..errors import InputError
from ..outputs import check_output_dir
from ..plain import to_plain
from ..sequence import Sequence, write_camera_yaml, write_frame, write_meta
from . import agora, bedlam, bev, cliff, fourdhumans, glamr, gvhmr, hybrik, multihmr, pymafx, slahmr, spec, tram, trace, wham
from ._common import ImportedSequence, ImportOptions, tool_name, wrong_kind
from .smpl import BodyModel, load_body_model
from .source import forget, open_imported

__all__ = [
    "ImportOptions",
    "ImportedSequence",
    "available_formats",
    "detect_format",
    "other_format",
    "read_format",
    "import_sequence",
    "imported_sequence",
    "reading_errors",
]


# ---- registry: one module per tool, each exporting READERS and sniff ---------------------------
_MODULES = (cliff, bev, fourdhumans, multihmr, spec, agora, bedlam, wham, gvhmr, tram, hybrik, pymafx, slahmr, glamr, trace)
READERS: dict[str, Callable[[Path, ImportOptions], ImportedSequence]] = {}
for _module in _MODULES:
    READERS.update(_module.READERS)


def available_formats() -> list[str]:
    """Names accepted by ``--from``."""
    return sorted(READERS)


_MODULE_OF = {name: module for module in _MODULES for name in module.READERS}
# What a sniffer meets in a file of another format (or a damaged one): "not mine", never an error.
_SNIFF_ERRORS = (InputError, OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, EOFError,
                 zipfile.BadZipFile, RecursionError, OverflowError, MemoryError, SystemError, UnicodeError)


def _sniffed(module: Any, path: Path) -> str | None:
    try:
        return module.sniff(path) or None
    except _SNIFF_ERRORS:
        return None


def detect_format(path: str | Path) -> str | None:
    """Guess the format of a file or directory from its names and keys (None if unknown)."""
    path = Path(path)
    if not path.exists():
        return None
    for module in _MODULES:
        found = _sniffed(module, path)
        if found:
            return found
    return None


def other_format(path: str | Path, fmt: str) -> str | None:
    """The format ``path`` looks like when it is not ``fmt``'s (what ``--from fmt`` failed on): the one
    :func:`detect_format` finds, unless ``fmt``'s own sniffer recognises the file (then the failure is the
    file's, not the choice of reader); None when nothing recognises it."""
    path = Path(path)
    module = _MODULE_OF.get(fmt)
    if module is None or not path.exists() or _sniffed(module, path) == fmt:
        return None
    found = detect_format(path)
    return found if found != fmt else None


def read_format(src: str | Path, fmt: str, *, image_size: tuple[int, int] | None = None,
                smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None,
                video: str | None = None) -> ImportedSequence:
    """Open ``src`` with the reader of ``fmt`` (frames are read lazily); ``video``: only that video of a
    file holding several (HybrIK's ``res.pk``: the image names' prefix)."""
    src = Path(src)
    if fmt not in READERS:
        raise InputError(f"unknown format '{fmt}' (known: {', '.join(available_formats())})")
    if not src.exists():
        raise InputError(f"{src}: no such file or directory")
    wrong = wrong_kind(src, fmt)  # a JSON file, an image, a video, ...: said before any reader's own complaint
    if wrong is not None:
        raise wrong
    if video is not None and fmt not in _VIDEO_FORMATS:
        raise InputError(f"--video selects one video of a file that holds several ({', '.join(_VIDEO_FORMATS)}); "
                         f"{tool_name(fmt)} output holds one")
    if image_size is not None:
        if len(image_size) != 2 or any(int(v) != v or v <= 0 for v in image_size):
            raise InputError(f"--image-size must be two positive integers W H, got {image_size!r}")
        image_size = (int(image_size[0]), int(image_size[1]))
    if fov_deg is not None and not 0 < fov_deg < 180:
        raise InputError(f"--fov must be in (0, 180) degrees, got {fov_deg}")
    model = smpl_model if isinstance(smpl_model, BodyModel) or smpl_model is None else load_body_model(smpl_model)
    imported = READERS[fmt](src, ImportOptions(image_size, model, fov_deg, video))
    if fov_deg is not None and fmt not in _FOV_FORMATS:
        imported.warnings.append(f"--fov is ignored for {fmt} (its focal length is fixed by the method)")
    return imported


_FOV_FORMATS = ("multihmr",)  # formats whose field of view is a user setting of the method
_VIDEO_FORMATS = ("hybrik",)  # formats whose one file can hold several videos (--video picks one)
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


def _pointing_elsewhere(src: Path, fmt: str, failure: InputError) -> InputError:
    """``failure`` (reading ``src`` as ``fmt``), or when ``src`` looks like another format's output, one
    line saying which and the ``--from`` that reads it, then what failed."""
    message = str(failure)
    found = other_format(src, fmt) if fmt in READERS else None
    if found is None or f"--from {found}" in message:  # the reader said it already (BEV read as ROMP)
        return failure
    detail = message.removeprefix(f"{src}: ")
    return InputError(f"{src}: this looks like {tool_name(found)} output (--from {found}), not {tool_name(fmt)} "
                      f"one (read as {fmt}: {detail})")


def import_sequence(src: str | Path, out: str | Path, fmt: str, *, image_size: tuple[int, int] | None = None,
                    smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None,
                    video: str | None = None, progress: Callable[[], None] | None = None,
                    overwrite: bool = False) -> dict:
    """Convert ``src`` (format ``fmt``) into a contract sequence directory ``out``.

    Frames are written to a staging directory beside ``out`` and swapped in whole only when every
    frame converted, so a failed import leaves ``out`` untouched. An existing ``out`` is replaced
    only when it is empty or rotavat's own output, or with ``overwrite``; never when it is, holds or
    lies inside ``src`` (:func:`rotavat_cli.outputs.check_output_dir`). ``progress()`` is called
    after each frame.

    Returns a summary: out, format, frames, people, empty_frames, image_size, focal_px,
    has_vertices, joints_layout, camera_yaml, warnings.
    """
    src, out = Path(src), Path(out)
    check_output_dir(out, [src], overwrite)
    with reading_errors(src, fmt):
        imported = read_format(src, fmt, image_size=image_size, smpl_model=smpl_model, fov_deg=fov_deg, video=video)
    with staged_directory(out, "import") as staging:
        frames = people = empty = 0
        has_vertices = False
        with reading_errors(src, fmt):
            for frame in imported.frames:
                write_frame(staging, frame, "npz")
                frames += 1
                people += frame.n_people
                empty += frame.n_people == 0
                has_vertices |= frame.n_people > 0 and frame.get("vertices") is not None
                if progress is not None:
                    progress()
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
def reading_errors(src: Path, fmt: str) -> Iterator[None]:
    """Context: what malformed content raises while a reader reads or builds frames (wrong types,
    shapes, keys) becomes a one-line InputError naming ``src``, as ``import_sequence`` reports it;
    an InputError that does not name ``src`` (a size limit met while posing) is prefixed with it.

    Every reader runs in it (``import``, and ``--from`` on every command: :mod:`.source`), so this is
    where a failure on a file that looks like another format's output (``--from 4dhumans`` on a
    HybrIK ``res.pk``) names that format and the ``--from`` that reads it."""
    try:
        yield
    except InputError as exc:  # already one line; named by the file if what raised it could not name it
        failure = exc if str(src) in str(exc) else InputError(f"{src}: {exc}")
    except _READ_ERRORS as exc:
        failure = _invalid(src, fmt, exc)
    else:
        return
    # Dropped before sniffing the file again: the traceback holds what the failed reader loaded.
    failure.__traceback__ = failure.__context__ = failure.__cause__ = None
    raise _pointing_elsewhere(Path(src), fmt, failure) from None


@contextlib.contextmanager
def imported_sequence(src: str | Path, fmt: str, *, read_camera: bool = True, **options: Any) -> Iterator[Sequence]:
    """Convert on the fly (``--from`` in calibrate/align/eval): ``src`` read as a Sequence whose
    frames are converted when read; no file is written.

    The sequence is named by ``src`` (its ``path``, ``origin`` and ``label``) and says form 'npz'
    (what ``align`` writes for it). Its frames, ``meta`` and camera are those ``rotavat import``
    would write and :func:`~rotavat_cli.sequence.open_sequence` read back, so every command gives
    the same results either way; ``meta['import']`` (joints layout, warnings) is complete once
    every frame was read, and ``seq.warnings`` lists what the user should hear of. ``options``:
    ``image_size``, ``smpl_model``, ``fov_deg``, ``video`` as for :func:`read_format`; ``read_camera``: include
    a camera the format carries (SPEC's: it needs every frame once). Worker processes re-read the
    source from its recipe, once each (:mod:`rotavat_cli.formats.source`); on exit this process
    forgets what it loaded.
    """
    seq = open_imported(src, fmt, read_camera=read_camera, **options)
    try:
        yield seq
    finally:
        forget(seq.frame_source.recipe)
