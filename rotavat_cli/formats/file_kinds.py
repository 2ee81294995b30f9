"""Files that are no HPS tool's output (a JSON file, an image, a video, an empty file, ...), told from
their first bytes, and the one-line refusal that says so before any reader's own complaint."""

from __future__ import annotations

import codecs
import zipfile
from pathlib import Path

from ..errors import InputError, file_error
from .tools import FORMATS, tool_name

__all__ = ["file_kind", "wrong_kind"]

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
    what = "an HPS tool's output" if fmt is None else f"{tool_name(fmt)} output"
    return file_error(path, f"{kind}, not {what} (rotavat reads: {', '.join(FORMATS)})")
