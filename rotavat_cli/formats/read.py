"""Opening a tool's output with the reader of its format (:func:`read_format`), and what goes wrong
while a reader reads or builds frames said in one line naming the file (:func:`reading_errors`): a
failure on a file that looks like another format's output names that format and its ``--from``."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

from ..errors import InputError, file_error
from .file_kinds import wrong_kind
from .imported import ImportedSequence, ImportOptions
from .registry import READERS, available_formats, other_format
from .smpl import BodyModel, load_body_model
from .tools import tool_name

__all__ = ["read_format", "reading_errors"]


def read_format(src: str | Path, fmt: str, *, image_size: tuple[int, int] | None = None,
                smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None,
                video: str | None = None, model_kind: str | None = None) -> ImportedSequence:
    """Open ``src`` with the reader of ``fmt`` (frames are read lazily); ``video``: only that video of a
    file holding several (HybrIK's ``res.pk``: the image names' prefix); ``model_kind``: only the predictions
    of that body model (``smpl``, ``smplx``) of a folder that mixes them (AGORA's)."""
    src = Path(src)
    if fmt not in READERS:
        raise InputError(f"unknown format '{fmt}' (known: {', '.join(available_formats())})")
    if not src.exists():
        raise file_error(src, "no such file or directory")
    wrong = wrong_kind(src, fmt)  # a JSON file, an image, a video, ...: said before any reader's own complaint
    if wrong is not None:
        raise wrong
    if video is not None and fmt not in _VIDEO_FORMATS:
        raise InputError(f"--video selects one video of a file that holds several ({', '.join(_VIDEO_FORMATS)}); "
                         f"{tool_name(fmt)} output holds one")
    if model_kind is not None and fmt not in _MODEL_KIND_FORMATS:
        raise InputError(f"--model-kind selects one body model's predictions of a folder that mixes them "
                         f"({', '.join(_MODEL_KIND_FORMATS)}); {tool_name(fmt)} output holds one")
    if model_kind is not None and model_kind not in MODEL_KINDS:
        raise InputError(f"--model-kind must be one of {', '.join(MODEL_KINDS)}, got {model_kind!r}")
    if image_size is not None:
        if len(image_size) != 2 or any(int(v) != v or v <= 0 for v in image_size):
            raise InputError(f"--image-size must be two positive integers W H, got {image_size!r}")
        image_size = (int(image_size[0]), int(image_size[1]))
    if fov_deg is not None and not 0 < fov_deg < 180:
        raise InputError(f"--fov must be in (0, 180) degrees, got {fov_deg}")
    model = smpl_model if isinstance(smpl_model, BodyModel) or smpl_model is None else load_body_model(smpl_model)
    imported = READERS[fmt](src, ImportOptions(image_size, model, fov_deg, video, model_kind))
    if fov_deg is not None and fmt not in _FOV_FORMATS:
        imported.warnings.append(f"--fov is ignored for {fmt} (its focal length is fixed by the method)")
    return imported


_FOV_FORMATS = ("multihmr",)  # formats whose field of view is a user setting of the method
_VIDEO_FORMATS = ("hybrik",)  # formats whose one file can hold several videos (--video picks one)
_MODEL_KIND_FORMATS = ("agora",)  # formats whose folder can mix body models' predictions (--model-kind picks one)
MODEL_KINDS = ("smpl", "smplx")  # what --model-kind takes
# What malformed content raises in numpy and the readers (a unicode array holding invalid code points
# raises SystemError when read as text).
_READ_ERRORS = (ValueError, TypeError, KeyError, IndexError, AttributeError, OverflowError, MemoryError, SystemError,
                UnicodeError)


def _invalid(src: Path, fmt: str, exc: BaseException) -> InputError:
    """A one-line InputError for content that does not fit the format (wrong types, shapes, keys)."""
    detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    if isinstance(exc, KeyError):
        detail = f"missing key {detail}"
    return file_error(src, f"not a valid {fmt} output ({detail})")


def _pointing_elsewhere(src: Path, fmt: str, failure: InputError) -> InputError:
    """``failure`` (reading ``src`` as ``fmt``), or when ``src`` looks like another format's output, one
    line saying which and the ``--from`` that reads it, then what failed."""
    message = str(failure)
    found = other_format(src, fmt) if fmt in READERS else None
    if found is None or f"--from {found}" in message:  # the reader said it already (BEV read as ROMP)
        return failure
    detail = message.removeprefix(f"{src}: ")
    return file_error(src, f"this looks like {tool_name(found)} output (--from {found}), not {tool_name(fmt)} "
                           f"one (read as {fmt}: {detail})")


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
        failure = exc if str(src) in str(exc) else file_error(src, str(exc))
    except _READ_ERRORS as exc:
        failure = _invalid(src, fmt, exc)
    else:
        return
    # Dropped before sniffing the file again: the traceback holds what the failed reader loaded.
    failure.__traceback__ = failure.__context__ = failure.__cause__ = None
    raise _pointing_elsewhere(Path(src), fmt, failure) from None
