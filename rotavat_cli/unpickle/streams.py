"""Bounded reading: a file within ``limits.max_file_mb``, a stream read a chunk at a time (only what
is there is held, never a buffer of what a file announces), and a compressed stream inflated as it
is read (:class:`Inflater`, refused once more than ``limits.max_file_mb`` came out).

>>> import io
>>> stream = chunked(io.BytesIO(b"line one\\nline two"))
>>> stream.readline(), stream.read(4), stream.read()
(b'line one\\n', b'line', b' two')
"""

from __future__ import annotations

import lzma
import sys
import zlib
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from ..settings import limits as _limits
from ..errors import InputError
from ..settings.limits import human_bytes
from .refusal import Refused

__all__ = ["CHUNK", "INFLATE_CHUNK", "Inflater", "Stream", "chunked", "file_size", "fill", "read_bytes", "read_up_to"]

CHUNK = 1 << 24  # bytes copied at a time
INFLATE_CHUNK = 1 << 20  # bytes a compressed stream inflates (or a zip member yields) at a time


# ---- files -----------------------------------------------------------------------------------
def file_size(path: Path) -> int:
    """Size of a regular file, refusing missing files, directories and files over ``max_file_mb``."""
    try:
        if path.is_dir():
            raise InputError(f"{path}: is a directory, expected a file")
        size = path.stat().st_size
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    limit = _limits.current().max_file_bytes
    if size > limit:
        raise InputError(f"{path}: file is {human_bytes(size)} (limit {human_bytes(limit)}: limits.max_file_mb)")
    return size


def read_bytes(path: Path) -> bytes:
    """Whole file, refusing missing, unreadable or oversized files."""
    file_size(path)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, expected a file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


# ---- streams ---------------------------------------------------------------------------------
class Stream:
    """A binary stream (``read``, ``readline``) over ``pull``, which returns the next chunk of bytes
    (b'' at the end): a read of n bytes holds the bytes that are there, never a buffer of the n a file
    announces, and nothing ahead of the reader but one chunk."""

    def __init__(self, pull: Any) -> None:
        self._pull, self._chunk, self._at = pull, b"", 0

    def _next(self) -> bool:
        self._chunk, self._at = self._pull(), 0
        return bool(self._chunk)

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0:
            n = sys.maxsize
        if self._at + n <= len(self._chunk):
            self._at += n
            return self._chunk[self._at - n:self._at]
        parts = []
        while n > 0 and (self._at < len(self._chunk) or self._next()):
            part = self._chunk[self._at:self._at + n]
            self._at += len(part)
            n -= len(part)
            parts.append(part)
        return b"".join(parts)

    def readline(self) -> bytes:
        parts = []
        while self._at < len(self._chunk) or self._next():
            end = self._chunk.find(b"\n", self._at)
            stop = len(self._chunk) if end < 0 else end + 1
            parts.append(self._chunk[self._at:stop])
            self._at = stop
            if end >= 0:
                break
        return b"".join(parts)


def chunked(stream: BinaryIO) -> Stream:
    """``stream`` (a zip member, a file) read a chunk at a time (see :class:`Stream`)."""
    return Stream(lambda: stream.read(INFLATE_CHUNK))


class Inflater:
    """The next decompressed chunk of ``data`` at each call (b'' at the end, or where the data is
    truncated): Refused as soon as more than ``limits.max_file_mb`` came out, or for corrupt data."""

    def __init__(self, make: Any, data: bytes) -> None:
        self._decompressor, self._data, self._fed = make(), memoryview(data), 0
        self._out, self._limit, self._pending = 0, _limits.current().max_file_bytes, False

    def __call__(self) -> bytes:
        d = self._decompressor
        try:
            while not d.eof:
                tail = getattr(d, "unconsumed_tail", b"")  # zlib: input the last call had no room for
                if tail:
                    given = tail
                elif self._pending:  # the last call filled its chunk: more output may wait, with no new input
                    given = b""
                elif self._fed < len(self._data):
                    given = self._data[self._fed:self._fed + INFLATE_CHUNK]
                    self._fed += len(given)
                else:
                    return b""
                out = d.decompress(given, INFLATE_CHUNK)
                self._pending = len(out) == INFLATE_CHUNK
                if out:
                    self._out += len(out)
                    if self._out > self._limit:
                        raise Refused(f"decompresses to more than {human_bytes(self._limit)} "
                                      "(limit: limits.max_file_mb)")
                    return out
        except (zlib.error, OSError, lzma.LZMAError, EOFError, ValueError) as exc:
            raise Refused(f"corrupt compressed data ({exc})") from None
        return b""


# ---- bounded copies --------------------------------------------------------------------------
def read_up_to(read: Any, n: int) -> bytes:
    """The next ``n`` bytes from ``read`` (fewer where the data ends), in chunks: only what is there is held."""
    parts, left = [], max(0, n)
    while left:
        chunk = read(min(CHUNK, left))
        if not chunk:
            break
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def fill(read: Any, out: np.ndarray) -> int:
    """Fill the uint8 array ``out`` from ``read`` in chunks; how many bytes came (fewer where the data ends)."""
    pos = 0
    while pos < len(out):
        chunk = read(min(CHUNK, len(out) - pos))
        if not chunk:
            break
        out[pos:pos + len(chunk)] = np.frombuffer(chunk, np.uint8)
        pos += len(chunk)
    return pos
