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
import re
from pathlib import Path
from typing import BinaryIO

import numpy as np

from ..errors import InputError
from .checks import array_refusal, invalid_text
from .pickles import load_stream
from .streams import chunked, file_size, fill

__all__ = ["load_npy", "load_npy_bytes", "parse_npy_header", "read_npy", "read_npy_data", "read_npy_header"]

_MAX_NPY_HEADER = 10_000  # numpy's own default limit for .npy headers
# The header numpy itself writes for a plain dtype (np.lib.format.header_data_from_array_1_0, keys sorted, padded
# with spaces to a 64-byte boundary and a newline): read by this pattern without compiling anything; any other
# header (record dtypes, another key order, Python literals numpy never writes) goes through ast.literal_eval.
_NUMPY_HEADER = re.compile(r"\{'descr': '([<>|=]?[A-Za-z][A-Za-z0-9]*(?:\[[A-Za-z]+\])?)', 'fortran_order': (True|False), "
                           r"'shape': \((\d+,|\d+(?:, \d+)+|)\), \} *\n?\Z")  # one dimension: "(3,)"


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
        dtype, shape, fortran = parse_npy_header(raw.decode(enc))
    except (ValueError, SyntaxError, KeyError, TypeError, UnicodeDecodeError, MemoryError, RecursionError):
        raise InputError(f"{source}: malformed .npy header") from None
    if any(s < 0 for s in shape):
        raise InputError(f"{source}: malformed .npy header (negative shape)")
    return dtype, shape, fortran, 8 + size_bytes + hlen


def parse_npy_header(text: str) -> tuple[np.dtype, tuple[int, ...], bool]:
    """(dtype, shape, fortran_order) of a ``.npy`` header's text: numpy's own layout by a pattern, anything else as
    a Python literal (``ast.literal_eval``); ValueError, SyntaxError, KeyError or TypeError when it is not one.

    >>> parse_npy_header("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }" + " " * 3 + "\\n")
    (dtype('float32'), (3, 4), False)
    >>> parse_npy_header("{'shape': (2,), 'fortran_order': True, 'descr': '|u1'}")  # not numpy's order: the literal
    (dtype('uint8'), (2,), True)
    """
    found = _NUMPY_HEADER.match(text)
    if found is not None:
        descr, fortran, dims = found.groups()
        return (np.lib.format.descr_to_dtype(descr), tuple(int(d) for d in dims.split(",") if d.strip()),
                fortran == "True")
    header = ast.literal_eval(text)
    return (np.lib.format.descr_to_dtype(header["descr"]), tuple(int(s) for s in header["shape"]),
            bool(header["fortran_order"]))


def read_npy(stream: BinaryIO, size: int, source: str, what: str, objects: bool) -> np.ndarray:
    """One array from a ``.npy`` stream of ``size`` bytes (a file, a zip member, bytes).

    The header is checked before any data is read: the declared array against
    ``limits.max_array_mb``, and against ``size`` (a header may not announce more data than the
    stream holds). Numeric data is read in bounded chunks into an array of exactly the declared
    size; object arrays go through the restricted unpickler (``objects``) or are refused.
    ``what`` names the array in size messages (``path`` or ``path: member 'key'``).
    """
    header = read_npy_header(stream, source)
    why = array_refusal(header[0], header[1])
    if why is not None:
        raise InputError(f"{what} {why}")
    return read_npy_data(stream, size, header, source, what, objects)


def read_npy_data(stream: BinaryIO, size: int, header: tuple[np.dtype, tuple[int, ...], bool, int], source: str,
                  what: str, objects: bool) -> np.ndarray:
    """The array of a ``.npy`` stream positioned after its ``header`` (:func:`read_npy_header`, already checked
    against ``limits.max_array_mb``): as :func:`read_npy` from there."""
    dtype, shape, fortran, offset = header
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
