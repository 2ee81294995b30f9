"""Restricted unpickling of untrusted files: numpy arrays, numpy scalars and builtin containers only.

HPS demos save results as pickles (plain ``pickle``, ``joblib.dump``, or object arrays inside
``np.savez``). Unpickling runs whatever callable the file names, so a hostile file can execute
code. This module never hands user data to the standard unpickler (nor lets numpy unpickle):
every global a pickle asks for is looked up in an explicit allow-list (``_ALLOWED``), and each
allowed callable is a wrapper that checks its arguments before building anything. Anything else
(``os.system``, ``builtins.eval``, ``torch``, ``pandas``, ``numpy.ma`` ...) raises an
:class:`~rotavat_cli.errors.InputError` whose one-line message names the file and the refused global.

Supported containers:

- plain pickles, protocols 0-5 (Python 2 pickles are read with ``encoding='latin1'``);
- ``joblib.dump`` files, uncompressed or zlib/gzip/bz2/xz/lzma-compressed: joblib writes each
  numpy array as a ``joblib.numpy_pickle.NumpyArrayWrapper`` placeholder followed by the raw array
  bytes (``joblib/numpy_pickle.py``); the placeholder is replaced here by an inert stand-in and the
  bytes are read with their size checked against what is left of the file;
- ``.npy``/``.npz`` files whose members may be object arrays (``np.savez(..., results=dict)``).

Examples
--------
>>> import pickle
>>> loads(pickle.dumps({"a": [1, 2.5], "b": np.arange(3)}), "demo.pkl")["b"].tolist()
[0, 1, 2]
>>> import os
>>> class Evil:
...     def __reduce__(self):
...         return (os.system, ("echo pwned",))
>>> loads(pickle.dumps(Evil()), "evil.pkl")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: evil.pkl: refused to unpickle global 'posix.system' (only numpy arrays, numpy scalars and builtin containers are allowed)
"""

from __future__ import annotations

import _compat_pickle
import ast
import builtins
import bz2
import io
import lzma
import pickle
import struct
import zipfile
import zlib
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["MAX_BYTES", "loads", "load_file", "load_npy", "load_npy_bytes", "load_npz"]

# Largest file, decompressed stream or npz member accepted (a guard against compression bombs).
MAX_BYTES = 4 << 30
_MAX_NPY_HEADER = 10_000  # numpy's own default limit for .npy headers
_REFUSAL = "(only numpy arrays, numpy scalars and builtin containers are allowed)"


class _Refused(Exception):
    """Raised inside the unpickler; turned into an InputError naming the file."""


# ---- allowed callables (each checks its arguments) ------------------------------------------
def _numpy_multiarray() -> Any:
    """numpy's multiarray module under its numpy 2 or numpy 1 name."""
    core = getattr(np, "_core", None) or np.core
    return core.multiarray


def _reconstruct(subtype: Any, shape: Any, typecode: Any) -> np.ndarray:
    """``numpy.core.multiarray._reconstruct`` for plain ndarrays only (no subclasses)."""
    if subtype is not np.ndarray:
        raise _Refused(f"array subclass {getattr(subtype, '__name__', subtype)!r} is not allowed")
    if not isinstance(shape, tuple) or not all(isinstance(s, int) for s in shape):
        raise _Refused("malformed ndarray reconstruction arguments")
    if not isinstance(typecode, (bytes, str)):
        raise _Refused("malformed ndarray reconstruction arguments")
    return _numpy_multiarray()._reconstruct(np.ndarray, shape, typecode)


def _scalar(dtype: Any, data: Any = None) -> Any:
    """``numpy.core.multiarray.scalar``: a numpy scalar from its dtype and raw bytes."""
    if not isinstance(dtype, np.dtype):
        raise _Refused("malformed numpy scalar")
    if dtype.hasobject:
        return data  # numpy returns the stored (already unpickled, hence allowed) object itself
    if isinstance(data, str):  # Python 2 pickles store the bytes as a latin-1 str
        data = data.encode("latin1")
    if not isinstance(data, (bytes, bytearray)) or len(data) != dtype.itemsize:
        raise _Refused("malformed numpy scalar")
    return np.frombuffer(bytes(data), dtype=dtype, count=1)[0]


def _frombuffer(buf: Any, dtype: Any, shape: Any, order: Any) -> np.ndarray:
    """``numpy.core.numeric._frombuffer`` (pickle protocol 5 arrays)."""
    if not isinstance(dtype, np.dtype) or dtype.hasobject:
        raise _Refused("malformed protocol-5 array")
    if not isinstance(shape, tuple) or order not in ("C", "F"):
        raise _Refused("malformed protocol-5 array")
    data = bytes(buf.raw() if isinstance(buf, pickle.PickleBuffer) else buf)
    count = int(np.prod(shape, dtype=np.int64)) if shape else 1
    if count * dtype.itemsize != len(data):
        raise _Refused("protocol-5 array size does not match its shape")
    return np.frombuffer(data, dtype=dtype).reshape(shape, order=order).copy()


def _codecs_encode(text: Any, encoding: str = "utf-8", errors: str = "strict") -> bytes:
    """``_codecs.encode`` as pickle protocol 2 uses it for bytes: str -> bytes, latin-1/utf-8 only."""
    if not isinstance(text, str) or encoding.lower().replace("_", "-") not in ("latin1", "latin-1", "utf-8", "utf8"):
        raise _Refused("malformed bytes object")
    return text.encode(encoding, errors)


_CONTAINER_TYPES = (dict, list, tuple, set, frozenset, str, bytes, bytearray, int, float, complex, bool, OrderedDict)


def _reconstructor(cls: Any, base: Any, state: Any = None) -> Any:
    """``copyreg._reconstructor`` (protocol 0/1 objects), for builtin container types only."""
    if cls not in _CONTAINER_TYPES or base not in _CONTAINER_TYPES + (object,):
        raise _Refused(f"object of type {getattr(cls, '__name__', cls)!r} is not allowed")
    if base is object:
        return object.__new__(cls)
    return base.__new__(cls, state) if state is not None else base.__new__(cls)


class _JoblibArrayWrapper:
    """Inert stand-in for ``joblib.numpy_pickle.NumpyArrayWrapper`` (metadata of one array)."""

    _FIELDS = {"subclass", "shape", "order", "dtype", "allow_mmap", "numpy_array_alignment_bytes"}

    def __setstate__(self, state: Any) -> None:
        if not isinstance(state, dict) or not set(state) <= self._FIELDS:
            raise _Refused("malformed joblib array wrapper")
        if state.get("subclass", np.ndarray) is not np.ndarray:
            raise _Refused("joblib array of a numpy subclass is not allowed")
        shape, dtype, order = state.get("shape"), state.get("dtype"), state.get("order", "C")
        if not isinstance(shape, tuple) or not all(isinstance(s, int) and s >= 0 for s in shape):
            raise _Refused("malformed joblib array shape")
        if not isinstance(dtype, np.dtype) or order not in ("C", "F"):
            raise _Refused("malformed joblib array dtype/order")
        self.shape, self.dtype, self.order = shape, dtype, order
        self.alignment = state.get("numpy_array_alignment_bytes")


def _allowed() -> dict[tuple[str, str], Any]:
    """(module, name) -> object handed to the unpickler."""
    table: dict[tuple[str, str], Any] = {}
    for name in ("dict", "list", "tuple", "set", "frozenset", "str", "bytes", "bytearray", "int", "float",
                 "complex", "bool", "slice", "range"):
        table[("builtins", name)] = getattr(builtins, name)
    table[("collections", "OrderedDict")] = OrderedDict
    table[("copyreg", "_reconstructor")] = _reconstructor
    table[("_codecs", "encode")] = _codecs_encode
    for core in ("numpy.core", "numpy._core"):
        table[(f"{core}.multiarray", "_reconstruct")] = _reconstruct
        table[(f"{core}.multiarray", "scalar")] = _scalar
        table[(f"{core}.numeric", "_frombuffer")] = _frombuffer
    table[("numpy", "ndarray")] = np.ndarray
    table[("numpy", "dtype")] = np.dtype
    table[("joblib.numpy_pickle", "NumpyArrayWrapper")] = _JoblibArrayWrapper
    return table


_ALLOWED = _allowed()


# ---- the unpickler ---------------------------------------------------------------------------
class _RestrictedUnpickler(pickle._Unpickler):  # noqa: SLF001 -- pure-Python unpickler: BUILD is overridable
    """Pure-Python unpickler with an allow-list ``find_class`` and joblib's array placeholders."""

    dispatch = pickle._Unpickler.dispatch.copy()  # noqa: SLF001

    def __init__(self, file: io.BytesIO) -> None:
        super().__init__(file, encoding="latin1")
        self._raw = file

    def find_class(self, module: str, name: str) -> Any:
        if self.proto < 3 and self.fix_imports:  # Python 2 names (e.g. __builtin__.set)
            if (module, name) in _compat_pickle.NAME_MAPPING:
                module, name = _compat_pickle.NAME_MAPPING[(module, name)]
            elif module in _compat_pickle.IMPORT_MAPPING:
                module = _compat_pickle.IMPORT_MAPPING[module]
        try:
            return _ALLOWED[(module, name)]
        except (KeyError, TypeError):
            raise _Refused(f"refused to unpickle global '{module}.{name}' {_REFUSAL}") from None

    def persistent_load(self, pid: Any) -> Any:
        raise _Refused("refused a persistent id (pickles that reference external objects are not allowed)")

    def load_build(self) -> None:
        super().load_build()
        if isinstance(self.stack[-1], _JoblibArrayWrapper):
            self.stack[-1] = self._read_joblib_array(self.stack[-1])

    dispatch[pickle.BUILD[0]] = load_build

    def _read_joblib_array(self, wrapper: _JoblibArrayWrapper) -> np.ndarray:
        """Raw array bytes that joblib writes right after the placeholder."""
        if not hasattr(wrapper, "dtype"):
            raise _Refused("malformed joblib array wrapper")
        if wrapper.dtype.hasobject:  # joblib pickles object arrays with plain pickle (protocol 2)
            array = _RestrictedUnpickler(self._raw).load()
            if not isinstance(array, np.ndarray):
                raise _Refused("joblib object array is not an array")
            return array
        if wrapper.alignment is not None:
            pad = self._raw.read(1)
            if len(pad) != 1:
                raise _Refused("truncated joblib array")
            self._raw.read(pad[0])
        count = int(np.prod(wrapper.shape, dtype=np.int64)) if wrapper.shape else 1
        nbytes = count * wrapper.dtype.itemsize
        remaining = len(self._raw.getbuffer()) - self._raw.tell()
        if nbytes > remaining:
            raise _Refused(f"truncated joblib array ({nbytes} bytes announced, {remaining} left)")
        array = np.frombuffer(self._raw.read(nbytes), dtype=wrapper.dtype, count=count)
        if wrapper.order == "F":
            return array.reshape(wrapper.shape[::-1]).transpose().copy()
        return array.reshape(wrapper.shape).copy()


def _load_stream(file: io.BytesIO, source: str) -> Any:
    """Unpickle one object from ``file``; every failure becomes a one-line InputError."""
    try:
        return _RestrictedUnpickler(file).load()
    except _Refused as exc:
        raise InputError(f"{source}: {exc}") from None
    except EOFError:
        raise InputError(f"{source}: truncated pickle (unexpected end of data)") from None
    except RecursionError:
        raise InputError(f"{source}: pickle nests too deeply") from None
    except MemoryError:
        raise InputError(f"{source}: pickle needs more memory than available") from None
    except KeyError:  # the dispatch table has no entry for the byte read
        raise InputError(f"{source}: not a readable pickle (invalid opcode)") from None
    except (pickle.UnpicklingError, ValueError, TypeError, IndexError, AttributeError,
            struct.error, UnicodeDecodeError, OverflowError) as exc:
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{source}: not a readable pickle ({detail})") from None


def loads(data: bytes, source: str) -> Any:
    """Unpickle ``data`` (plain pickle or uncompressed joblib) with the allow-list."""
    return _load_stream(io.BytesIO(data), source)


# ---- files -----------------------------------------------------------------------------------
def _read_bytes(path: Path) -> bytes:
    """Whole file, refusing missing, unreadable or oversized files."""
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise InputError(f"{path}: file is larger than {MAX_BYTES >> 30} GiB")
        return path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, expected a file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


def _bounded(decompressor: Any, data: bytes, source: str) -> bytes:
    """Decompress ``data`` with an output cap (compression bombs)."""
    out = decompressor.decompress(data, MAX_BYTES + 1)
    if len(out) > MAX_BYTES:
        raise InputError(f"{source}: decompresses to more than {MAX_BYTES >> 30} GiB")
    return out


def _decompress(data: bytes, source: str) -> bytes:
    """Undo joblib's optional compression (detected from the magic bytes, as joblib does)."""
    try:
        if data[:2] == b"\x1f\x8b":
            return _bounded(zlib.decompressobj(16 + zlib.MAX_WBITS), data, source)
        if data[:3] == b"BZh":
            return _bounded(bz2.BZ2Decompressor(), data, source)
        if data[:6] == b"\xfd7zXZ\x00":
            return _bounded(lzma.LZMADecompressor(format=lzma.FORMAT_XZ), data, source)
        if data[:5] == b"]\x00\x00\x80\x00":
            return _bounded(lzma.LZMADecompressor(format=lzma.FORMAT_ALONE), data, source)
        if data[:1] == b"x":  # zlib header (joblib's default compressor)
            return _bounded(zlib.decompressobj(), data, source)
    except (zlib.error, OSError, lzma.LZMAError, EOFError, ValueError) as exc:
        raise InputError(f"{source}: corrupt compressed data ({exc})") from None
    if data[:4] == b'\x04"M\x18':
        raise InputError(f"{source}: lz4-compressed joblib files are not supported; re-save with compress=3 (zlib)")
    return data


def load_file(path: str | Path) -> Any:
    """Unpickle a ``.pkl`` file written by ``pickle.dump`` or ``joblib.dump`` (any compression)."""
    path = Path(path)
    data = _read_bytes(path)
    if not data:
        raise InputError(f"{path}: empty file")
    return _load_stream(io.BytesIO(_decompress(data, str(path))), str(path))


def _parse_npy_header(raw: bytes, source: str) -> tuple[np.dtype, tuple[int, ...], bool, int]:
    """(dtype, shape, fortran_order, data offset) of a ``.npy`` byte string."""
    if raw[:6] != b"\x93NUMPY" or len(raw) < 10:
        raise InputError(f"{source}: not a .npy array (bad magic)")
    major = raw[6]
    if major == 1:
        hlen, start, enc = int.from_bytes(raw[8:10], "little"), 10, "latin1"
    elif major in (2, 3):
        hlen, start, enc = int.from_bytes(raw[8:12], "little"), 12, "latin1" if major == 2 else "utf8"
    else:
        raise InputError(f"{source}: unsupported .npy format version {major}")
    if hlen > _MAX_NPY_HEADER or start + hlen > len(raw):
        raise InputError(f"{source}: malformed .npy header")
    try:
        header = ast.literal_eval(raw[start:start + hlen].decode(enc))
        dtype = np.lib.format.descr_to_dtype(header["descr"])
        shape = tuple(int(s) for s in header["shape"])
        fortran = bool(header["fortran_order"])
    except (ValueError, SyntaxError, KeyError, TypeError, UnicodeDecodeError, MemoryError, RecursionError):
        raise InputError(f"{source}: malformed .npy header") from None
    if any(s < 0 for s in shape):
        raise InputError(f"{source}: malformed .npy header (negative shape)")
    return dtype, shape, fortran, start + hlen


def load_npy_bytes(raw: bytes, source: str) -> np.ndarray:
    """Array from ``.npy`` bytes; object arrays go through the restricted unpickler."""
    dtype, shape, fortran, offset = _parse_npy_header(raw, source)
    if not dtype.hasobject:
        try:
            return np.lib.format.read_array(io.BytesIO(raw), allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise InputError(f"{source}: corrupt or truncated array ({str(exc).splitlines()[0]})") from None
    array = _load_stream(io.BytesIO(raw[offset:]), source)
    if not isinstance(array, np.ndarray) or array.shape != shape:
        raise InputError(f"{source}: object array does not match its header")
    return array


def load_npy(path: str | Path) -> np.ndarray:
    """Read a ``.npy`` file (object arrays through the restricted unpickler)."""
    path = Path(path)
    return load_npy_bytes(_read_bytes(path), str(path))


def load_npz(path: str | Path) -> dict[str, np.ndarray]:
    """Read every member of an ``.npz`` file (object arrays through the restricted unpickler)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found" if not path.exists() else f"{path}: expected a .npz file")
    try:
        with zipfile.ZipFile(path) as archive:
            members = [info for info in archive.infolist() if info.filename.endswith(".npy")]
            if sum(info.file_size for info in members) > MAX_BYTES:
                raise InputError(f"{path}: arrays total more than {MAX_BYTES >> 30} GiB")
            out = {}
            for info in members:
                key = info.filename[:-4]
                out[key] = load_npy_bytes(archive.read(info), f"{path} ['{key}']")
            return out
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, zlib.error, NotImplementedError) as exc:
        raise InputError(f"{path}: not a readable .npz file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
