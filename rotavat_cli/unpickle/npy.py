"""``.npy`` arrays read with their header checked first: the declared array against
``limits.max_array_mb`` and against the data that follows; numeric data read in bounded chunks;
object arrays through the restricted unpickler (:func:`~.pickles.load_stream`) or refused.

>>> import io
>>> buf = io.BytesIO()
>>> np.save(buf, np.arange(3))
>>> load_npy_bytes(buf.getvalue(), "x.npy").tolist()
[0, 1, 2]
"""

from __future__ import annotations

import ast
import io
import math
from pathlib import Path
from typing import BinaryIO

import numpy as np

from ..errors import InputError
from .checks import array_refusal, invalid_text
from .pickles import load_stream
from .streams import chunked, file_size, fill

__all__ = ["load_npy", "load_npy_bytes", "read_npy", "read_npy_header"]

_MAX_NPY_HEADER = 10_000  # numpy's own default limit for .npy headers


def read_npy_header(stream: BinaryIO, source: str) -> tuple[np.dtype, tuple[int, ...], bool, int]:
    """(dtype, shape, fortran_order, data offset) read from the start of a ``.npy`` stream."""
    magic = stream.read(8)
    if len(magic) < 8 or magic[:6] != b"\x93NUMPY":
        raise InputError(f"{source}: not a .npy array (bad magic)")
    major = magic[6]
    if major == 1:
        size_bytes, enc = 2, "latin1"
    elif major in (2, 3):
        size_bytes, enc = 4, "latin1" if major == 2 else "utf8"
    else:
        raise InputError(f"{source}: unsupported .npy format version {major}")
    raw_len = stream.read(size_bytes)
    hlen = int.from_bytes(raw_len, "little")
    if len(raw_len) < size_bytes or hlen > _MAX_NPY_HEADER:
        raise InputError(f"{source}: malformed .npy header")
    raw = stream.read(hlen)
    if len(raw) < hlen:
        raise InputError(f"{source}: malformed .npy header")
    try:
        header = ast.literal_eval(raw.decode(enc))
        dtype = np.lib.format.descr_to_dtype(header["descr"])
        shape = tuple(int(s) for s in header["shape"])
        fortran = bool(header["fortran_order"])
    except (ValueError, SyntaxError, KeyError, TypeError, UnicodeDecodeError, MemoryError, RecursionError):
        raise InputError(f"{source}: malformed .npy header") from None
    if any(s < 0 for s in shape):
        raise InputError(f"{source}: malformed .npy header (negative shape)")
    return dtype, shape, fortran, 8 + size_bytes + hlen


def read_npy(stream: BinaryIO, size: int, source: str, what: str, objects: bool) -> np.ndarray:
    """One array from a ``.npy`` stream of ``size`` bytes (a file, a zip member, bytes).

    The header is checked before any data is read: the declared array against
    ``limits.max_array_mb``, and against ``size`` (a header may not announce more data than the
    stream holds). Numeric data is read in bounded chunks into an array of exactly the declared
    size; object arrays go through the restricted unpickler (``objects``) or are refused.
    ``what`` names the array in size messages (``path`` or ``path: member 'key'``).
    """
    dtype, shape, fortran, offset = read_npy_header(stream, source)
    why = array_refusal(dtype, shape)
    if why is not None:
        raise InputError(f"{what} {why}")
    if dtype.hasobject:
        if not objects:
            raise InputError(f"{what} is an object array: cannot read without pickle (only numeric arrays are allowed here)")
        array = load_stream(chunked(stream), source, drain=True)  # unpickled as it is read (a deflated member)
        if not isinstance(array, np.ndarray) or array.shape != shape:
            raise InputError(f"{source}: object array does not match its header")
        return array
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    if offset + nbytes > size:
        raise InputError(f"{source}: corrupt or truncated array (its header declares {nbytes:,} bytes of data, "
                         f"{max(0, size - offset):,} follow)")
    array = np.empty(count, dtype)
    pos = fill(stream.read, array.view(np.uint8)) if nbytes else 0
    if pos < nbytes:
        raise InputError(f"{source}: corrupt or truncated array (data ends after {pos:,} of {nbytes:,} bytes)")
    _check_text(array, what)
    if fortran:
        return array.reshape(shape[::-1]).transpose()
    return array.reshape(shape)


def _check_text(array: np.ndarray, what: str) -> np.ndarray:
    """``array`` unless it holds invalid text (:func:`~.checks.invalid_text`): InputError naming ``what``."""
    if invalid_text(array):
        raise InputError(f"{what} holds invalid text (a code point beyond U+10FFFF)")
    return array


def load_npy_bytes(raw: bytes, source: str) -> np.ndarray:
    """Array from ``.npy`` bytes; object arrays go through the restricted unpickler."""
    return read_npy(io.BytesIO(raw), len(raw), source, source, objects=True)


def load_npy(path: str | Path) -> np.ndarray:
    """Read a ``.npy`` file (object arrays through the restricted unpickler); header checked first."""
    path = Path(path)
    size = file_size(path)
    try:
        with open(path, "rb") as handle:
            return read_npy(handle, size, str(path), str(path), objects=True)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
