"""PyTorch files (``torch.save``) read without torch and without running pickled code.

Several HPS demos save their results with ``torch.save`` (GVHMR's ``hmr4d_results.pt``) or
``np.save`` a dict of torch tensors (TRAM's ``hps_track_{k}.npy``). Both are pickles that name
torch's functions to rebuild each tensor; this module maps an explicit allow-list of those names
(:data:`TORCH_GLOBALS`) to inert numpy builders, and refuses any other global, exactly as
:mod:`rotavat_cli.safe_pickle` does for plain pickles. The result is plain nested containers of
numpy arrays (one independent array per tensor, in the tensor's own shape and dtype; bfloat16
becomes float32).

The layouts, read from PyTorch's own code (pytorch/pytorch @000a1a5 ``torch/serialization.py``:
``_save``, ``_legacy_save``, ``_load``, ``_legacy_load``; @e8c9164 ``torch/_utils.py``:
``_rebuild_tensor_v2``, ``_rebuild_tensor_v3``, ``_rebuild_parameter``; @529d1f9
``torch/storage.py``: ``TypedStorage.__reduce__``, ``_load_from_bytes``,
``_dtype_to_storage_type_map``; ``torch/_tensor.py``: ``Tensor._reduce_ex_internal``,
``_rebuild_from_type_v2``), and checked against what torch 2.13 writes:

- **zip archive** (the default since PyTorch 1.6): ``<name>/data.pkl`` is the pickle; each storage
  is the record ``<name>/data/<key>`` (raw little-endian bytes, ``<name>/byteorder`` says otherwise
  when ``big``); ``<name>/version`` and ``.data/serialization_id`` are bookkeeping. In ``data.pkl``
  a storage is the persistent id ``('storage', storage_type, key, location, numel)`` with
  ``storage_type`` a global such as ``torch.FloatStorage`` (numel in elements) or
  ``torch.UntypedStorage`` (numel in bytes; the tensor then names its dtype).
- **legacy stream** (``_use_new_zipfile_serialization=False``, and every storage pickled inside a
  plain pickle): pickles of the magic number ``0x1950A86A20F9469CFC6C``, protocol version 1001 and
  a ``sys_info`` dict, then the object pickle (persistent ids ``('storage', storage_type, key,
  location, numel, view_metadata)``), then the sorted list of storage keys, then per key an int64
  element count and the raw bytes. The pre-1.0 *tar* layout is refused with a message.
- **tensors**: ``torch._utils._rebuild_tensor_v2(storage, storage_offset, size, stride,
  requires_grad, backward_hooks[, metadata])`` (``_rebuild_tensor_v3`` adds the dtype for
  untyped storages; ``_rebuild_parameter`` wraps a tensor; ``torch._tensor._rebuild_from_type_v2``
  wraps either). A tensor pickled by plain ``pickle`` (``np.save`` of a dict of tensors) carries its
  storage as ``torch.storage._load_from_bytes(b)``, ``b`` being a legacy stream of that storage.

Every declared size is checked before anything is allocated: a storage's bytes against
``limits.max_array_mb`` and against the record (or stream) that should hold them, a tensor's
elements against its storage (offset + extent of every stride) and its own size against
``limits.max_array_mb``, the total against the pickle budget (:class:`safe_pickle._Budget`).
Errors are one-line :class:`~rotavat_cli.errors.InputError` that say the file is a torch archive
and what was refused, never "a bad pickle".

>>> load_torch_bytes(b"PK\\x05\\x06" + bytes(18), "empty.pt")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: empty.pt: torch archive: no '<name>/data.pkl' record (the pickle of a torch.save archive)
"""

from __future__ import annotations

import io
import math
import struct
import zipfile
import zlib
from collections import OrderedDict, defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import limits as _limits
from . import safe_pickle as _sp
from .errors import InputError
from .limits import human_bytes

__all__ = ["MAGIC_NUMBER", "TORCH_GLOBALS", "is_legacy_torch", "is_torch_zip", "load_torch", "load_torch_bytes"]

MAGIC_NUMBER = 0x1950A86A20F9469CFC6C  # torch/serialization.py
PROTOCOL_VERSION = 1001  # torch/serialization.py (legacy stream)
_TORCH_REFUSAL = "(only tensors, numpy arrays and builtin containers are allowed)"
_MAX_NESTING = 4  # storages pickled inside storages (a real file has 1 level)


class TorchDtype(str):
    """A torch dtype as a pickle names it (``torch.float32``): the string ``'torch.float32'``, plus
    how its elements are stored (``stored``, little-endian numpy dtype; bfloat16: ``<u2``)."""

    stored: np.dtype

    def __new__(cls, name: str, stored: str) -> TorchDtype:
        self = super().__new__(cls, f"torch.{name}")
        self.stored = np.dtype(stored)
        return self

    @property
    def is_bfloat16(self) -> bool:
        return self == "torch.bfloat16"


# torch dtype name -> little-endian storage dtype (torch/storage.py _dtype_to_storage_type_map and _new_dtypes;
# quantized, float8, bits and complex32 dtypes have no numpy equivalent and are refused when used)
_DTYPES = {name: TorchDtype(name, stored) for name, stored in (
    ("float64", "<f8"), ("float32", "<f4"), ("float16", "<f2"), ("bfloat16", "<u2"), ("int64", "<i8"),
    ("int32", "<i4"), ("int16", "<i2"), ("int8", "i1"), ("uint8", "u1"), ("bool", "?"), ("complex64", "<c8"),
    ("complex128", "<c16"), ("uint16", "<u2"), ("uint32", "<u4"), ("uint64", "<u8"))}
_DTYPE_ALIASES = {"double": "float64", "float": "float32", "half": "float16", "long": "int64", "int": "int32",
                  "short": "int16", "cdouble": "complex128", "cfloat": "complex64"}
_STORAGE_TYPES = {"DoubleStorage": "float64", "FloatStorage": "float32", "HalfStorage": "float16",
                  "BFloat16Storage": "bfloat16", "LongStorage": "int64", "IntStorage": "int32", "ShortStorage": "int16",
                  "CharStorage": "int8", "ByteStorage": "uint8", "BoolStorage": "bool",
                  "ComplexDoubleStorage": "complex128", "ComplexFloatStorage": "complex64", "UntypedStorage": "uint8"}


@dataclass(frozen=True)
class _StorageType:
    """Inert stand-in for ``torch.FloatStorage`` & co. (a persistent id names one)."""

    name: str
    dtype: TorchDtype

    @property
    def untyped(self) -> bool:
        return self.name == "UntypedStorage"


class _Storage:
    """One storage: ``numel`` elements of ``dtype`` (bytes for an untyped one); ``data`` (1-D, stored
    dtype) once read. Inert: nothing here runs code."""

    def __init__(self, dtype: TorchDtype, numel: int, key: str, untyped: bool) -> None:
        self.dtype, self.numel, self.key, self.untyped = dtype, numel, key, untyped
        self.data: np.ndarray | None = None

    @property
    def nbytes(self) -> int:
        return self.numel * self.dtype.stored.itemsize


@dataclass
class _Deferred:
    """A tensor whose storage bytes come later in a legacy stream (resolved after they are read)."""

    storage: _Storage
    offset: int
    size: tuple[int, ...]
    stride: tuple[int, ...]
    dtype: TorchDtype
    negate: bool
    conjugate: bool


# ---- checks -----------------------------------------------------------------------------------
def _int(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise _sp._Refused(f"malformed tensor {what} {value!r}")
    return value


def _ints(value: Any, what: str) -> tuple[int, ...]:
    if not isinstance(value, (tuple, list)):
        raise _sp._Refused(f"malformed tensor {what}")
    return tuple(_int(v, what) for v in value)


def _storage_bytes_refusal(dtype: TorchDtype, numel: int) -> None:
    """_Refused when a storage declares more than ``limits.max_array_mb``."""
    nbytes, limit = numel * dtype.stored.itemsize, _limits.current().max_array_bytes
    if nbytes > limit:
        raise _sp._Refused(f"storage declares {human_bytes(nbytes)} ({dtype} x {numel:,}; limit {human_bytes(limit)}: "
                           f"limits.max_array_mb)")


def _decode(flat: np.ndarray, dtype: TorchDtype) -> np.ndarray:
    """Stored elements -> numpy values (bfloat16: the upper half of a float32)."""
    if dtype.is_bfloat16:
        return (flat.astype("<u4") << np.uint32(16)).view("<f4").astype(np.float32)
    return flat.astype(flat.dtype.newbyteorder("="), copy=False)


def _tensor_array(storage: _Storage, offset: int, size: tuple[int, ...], stride: tuple[int, ...], dtype: TorchDtype,
                  negate: bool, conjugate: bool) -> np.ndarray:
    """An independent array for a view of a read storage (bounds already checked)."""
    data = storage.data
    if storage.untyped and dtype.stored != data.dtype:  # v3: bytes reinterpreted as the tensor's dtype
        usable = (len(data) // dtype.stored.itemsize) * dtype.stored.itemsize
        data = data[:usable].view(dtype.stored)
    if math.prod(size) == 0:
        out = np.zeros(size, dtype.stored)
    else:
        base = data[offset:]
        view = np.lib.stride_tricks.as_strided(base, shape=size, strides=tuple(s * base.itemsize for s in stride),
                                               writeable=False)
        out = np.array(view)
    out = _decode(out, dtype)
    if conjugate and out.dtype.kind == "c":
        out = np.conj(out)
    if negate:
        out = np.negative(out) if out.dtype != np.bool_ else out
    return out


class _Builder:
    """The allow-listed torch callables, bound to one load (its budget)."""

    def __init__(self, budget: _sp._Budget, depth: int) -> None:
        self.budget, self.depth = budget, depth

    def tensor(self, storage: Any, offset: Any, size: Any, stride: Any, dtype: TorchDtype | None = None,
               metadata: Any = None) -> np.ndarray | _Deferred:
        if not isinstance(storage, _Storage):
            raise _sp._Refused("malformed tensor (its storage is not a torch storage)")
        offset, size, stride = _int(offset, "storage offset"), _ints(size, "size"), _ints(stride, "stride")
        if len(stride) != len(size):
            raise _sp._Refused(f"malformed tensor (size {list(size)} with stride {list(stride)})")
        if dtype is None:
            dtype = storage.dtype
        elif not isinstance(dtype, TorchDtype) or not storage.untyped:
            raise _sp._Refused("malformed tensor dtype")
        _sp._check_array(dtype.stored, size)
        count = math.prod(size)
        available = storage.nbytes // dtype.stored.itemsize if storage.untyped else storage.numel
        if count:
            last = offset + sum((n - 1) * s for n, s in zip(size, stride))
            if last >= available:
                raise _sp._Refused(f"tensor of size {list(size)} (offset {offset}, stride {list(stride)}) reaches element "
                                   f"{last:,} of storage '{storage.key}', which holds {available:,}")
        self.budget.add_data(count * dtype.stored.itemsize)
        negate = conjugate = False
        if metadata is not None:
            if not isinstance(metadata, dict) or not set(metadata) <= {"neg", "conj"}:
                raise _sp._Refused("malformed tensor metadata")
            negate, conjugate = bool(metadata.get("neg")), bool(metadata.get("conj"))
        if storage.data is None:
            return _Deferred(storage, offset, size, stride, dtype, negate, conjugate)
        return _tensor_array(storage, offset, size, stride, dtype, negate, conjugate)

    def rebuild_v1(self, storage: Any, offset: Any, size: Any, stride: Any) -> Any:
        """``torch._utils._rebuild_tensor``."""
        return self.tensor(storage, offset, size, stride)

    def rebuild_v2(self, storage: Any, offset: Any, size: Any, stride: Any, requires_grad: Any = False,
                   backward_hooks: Any = None, metadata: Any = None) -> Any:
        """``torch._utils._rebuild_tensor_v2``: requires_grad and the (empty) hooks are dropped."""
        return self.tensor(storage, offset, size, stride, None, metadata)

    def rebuild_v3(self, storage: Any, offset: Any, size: Any, stride: Any, requires_grad: Any, backward_hooks: Any,
                   dtype: Any, metadata: Any = None) -> Any:
        """``torch._utils._rebuild_tensor_v3`` (untyped storage + dtype)."""
        return self.tensor(storage, offset, size, stride, dtype, metadata)

    def parameter(self, data: Any, requires_grad: Any = False, backward_hooks: Any = None, state: Any = None) -> Any:
        """``torch._utils._rebuild_parameter[_with_state]``: the tensor itself."""
        if not isinstance(data, (np.ndarray, _Deferred)):
            raise _sp._Refused("malformed parameter (not a tensor)")
        return data

    def from_type(self, func: Any, new_type: Any, args: Any, state: Any = None) -> Any:
        """``torch._tensor._rebuild_from_type_v2``: only plain tensors and parameters, rebuilt by an allowed function."""
        if new_type not in (_TENSOR, _PARAMETER) or not isinstance(args, tuple):
            raise _sp._Refused(f"tensor subclass {getattr(new_type, 'name', new_type)!r} is not allowed")
        if getattr(func, "__self__", None) is not self:
            raise _sp._Refused("malformed tensor (rebuilt by a function other than torch's)")
        return func(*args)

    def load_from_bytes(self, blob: Any) -> _Storage:
        """``torch.storage._load_from_bytes``: a storage saved by ``torch.save`` inside a plain pickle."""
        if not isinstance(blob, (bytes, bytearray)):
            raise _sp._Refused("malformed pickled storage (not bytes)")
        if self.depth >= _MAX_NESTING:
            raise _sp._Refused("pickled storages nest too deeply")
        value = _load_blob(bytes(blob), self.budget, self.depth + 1)
        if not isinstance(value, _Storage):
            raise _sp._Refused("a pickled storage holds something other than a storage")
        return value


def _torch_size(dims: Any = ()) -> tuple[int, ...]:
    """``torch.Size`` -> a tuple of ints."""
    return _ints(dims, "torch.Size")


@dataclass(frozen=True)
class _TensorType:
    """Inert stand-in for ``torch.Tensor`` / ``torch.nn.Parameter`` (only named, never called)."""

    name: str


_TENSOR, _PARAMETER = _TensorType("torch.Tensor"), _TensorType("torch.nn.Parameter")
_REBUILDERS = {("torch._utils", "_rebuild_tensor"): "rebuild_v1", ("torch._utils", "_rebuild_tensor_v2"): "rebuild_v2",
               ("torch._utils", "_rebuild_tensor_v3"): "rebuild_v3", ("torch._utils", "_rebuild_parameter"): "parameter",
               ("torch._utils", "_rebuild_parameter_with_state"): "parameter",
               ("torch._tensor", "_rebuild_from_type_v2"): "from_type", ("torch.tensor", "_rebuild_from_type_v2"): "from_type",
               ("torch.storage", "_load_from_bytes"): "load_from_bytes"}


def _static_globals() -> dict[tuple[str, str], Any]:
    """(module, name) -> inert object, for the torch names that build nothing themselves."""
    table: dict[tuple[str, str], Any] = {}
    for name, dtype_name in _STORAGE_TYPES.items():
        for module in ("torch", "torch.cuda"):  # torch < 1.? pickled GPU storages as torch.cuda.FloatStorage
            table[(module, name)] = _StorageType(name, _DTYPES[dtype_name])
    for name, dtype in _DTYPES.items():
        table[("torch", name)] = dtype
    for alias, name in _DTYPE_ALIASES.items():
        table[("torch", alias)] = _DTYPES[name]
    table[("torch.storage", "UntypedStorage")] = table[("torch", "UntypedStorage")]  # how torch >= 2.0 names it
    table[("torch", "Size")] = _torch_size
    table[("torch", "Tensor")] = table[("torch._tensor", "Tensor")] = _TENSOR
    table[("torch.nn.parameter", "Parameter")] = _PARAMETER
    return table


_STATIC = _static_globals()
TORCH_GLOBALS = frozenset(_STATIC) | frozenset(_REBUILDERS)


def torch_global(module: str, name: str, builder: _Builder) -> Any:
    """The inert stand-in for an allowed torch global, or None."""
    method = _REBUILDERS.get((module, name))
    if method is not None:
        return getattr(builder, method)
    return _STATIC.get((module, name))


# ---- unpicklers ----------------------------------------------------------------------------------
class _TorchUnpickler(_sp._RestrictedUnpickler):
    """The restricted unpickler plus torch's storage persistent ids (``data.pkl``, legacy streams)."""

    def __init__(self, file: Any, budget: _sp._Budget, depth: int, storage: Any) -> None:
        super().__init__(file, budget, depth)
        self._storage = storage  # pid tuple -> _Storage

    def find_class(self, module: str, name: str) -> Any:
        try:
            return super().find_class(module, name)
        except _sp._Refused:
            raise _sp._Refused(f"refused to unpickle global '{module}.{name}' {_TORCH_REFUSAL}") from None

    def persistent_load(self, pid: Any) -> Any:
        if not isinstance(pid, tuple) or not pid:
            raise _sp._Refused("malformed persistent id")
        kind = pid[0].decode("ascii", "replace") if isinstance(pid[0], bytes) else pid[0]
        if kind != "storage":
            raise _sp._Refused(f"refused persistent id '{kind}' (only storages are allowed)")
        return self._storage(pid)


def _storage_from_pid(pid: tuple, legacy: bool, registry: dict[str, _Storage]) -> _Storage:
    """Validate a storage persistent id; the same key gives the same storage."""
    if len(pid) != (6 if legacy else 5):
        raise _sp._Refused("malformed storage id")
    storage_type, key, _location, numel = pid[1:5]
    if legacy and pid[5] is not None:
        raise _sp._Refused("storage views of the pre-1.0 format are not supported")
    if not isinstance(storage_type, _StorageType):
        raise _sp._Refused("malformed storage id (unknown storage type)")
    if isinstance(key, bytes):
        key = key.decode("ascii", "replace")
    if not isinstance(key, str):
        raise _sp._Refused("malformed storage key")
    numel = _int(numel, "storage size")
    known = registry.get(key)
    if known is not None:
        if known.nbytes != numel * storage_type.dtype.stored.itemsize:
            raise _sp._Refused(f"storage '{key}' is declared with two sizes")
        return known
    _storage_bytes_refusal(storage_type.dtype, numel)
    registry[key] = _Storage(storage_type.dtype, numel, key, storage_type.untyped)
    return registry[key]


def _open_record(archive: zipfile.ZipFile, name: str, declared: int | None = None,
                 at_most: int | None = None) -> tuple[Any, int]:
    """One zip record opened for reading (inflated as it is read) and its size, the declared size
    checked (and equal to ``declared`` when given, at most ``at_most`` bytes for a small record) first."""
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise _sp._Refused(f"record '{name}' is missing") from None
    limit = _limits.current().max_file_bytes
    if info.file_size > limit:
        raise _sp._Refused(f"record '{name}' holds {human_bytes(info.file_size)} (limit {human_bytes(limit)}: "
                           "limits.max_file_mb)")
    if at_most is not None and info.file_size > at_most:
        raise _sp._Refused(f"record '{name}' holds {info.file_size:,} bytes (at most {at_most} expected)")
    if declared is not None and info.file_size != declared:
        raise _sp._Refused(f"record '{name}' holds {info.file_size:,} bytes, its storage declares {declared:,}")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise _sp._Refused(f"record '{name}' uses an unsupported compression method ({info.compress_type})")
    return archive.open(info), info.file_size


def _read_record(archive: zipfile.ZipFile, name: str, at_most: int) -> bytes:
    """A small zip record whole (see :func:`_open_record`)."""
    stream, size = _open_record(archive, name, at_most=at_most)
    with stream:
        data = stream.read()
    if len(data) != size:
        raise _sp._Refused(f"record '{name}' is truncated")
    return data


def _read_storage(archive: zipfile.ZipFile, name: str, found: _Storage, stored: np.dtype,
                  budget: _sp._Budget) -> np.ndarray:
    """A storage's elements from its record, read in chunks into their array: held once, never also
    as the record's bytes (reading the record's last byte checks its CRC)."""
    stream, size = _open_record(archive, name, declared=found.nbytes)
    with stream:
        budget.add_data(size)
        data = np.empty(found.numel, stored)
        if size and _sp._fill(stream.read, data.view(np.uint8)) != size:
            raise _sp._Refused(f"record '{name}' is truncated")
    return data


def _archive_prefix(archive: zipfile.ZipFile) -> str:
    """The ``<name>`` of ``<name>/data.pkl`` (torch names the archive after the file)."""
    names = archive.namelist()
    if any(n.count("/") == 1 and n.endswith("/constants.pkl") for n in names):  # torch's _is_torchscript_zip
        raise _sp._Refused("a TorchScript model archive (torch.jit.save), not data saved with torch.save")
    pickles = [n for n in names if n.count("/") == 1 and n.endswith("/data.pkl")]
    if not pickles:
        raise _sp._Refused("no '<name>/data.pkl' record (the pickle of a torch.save archive)")
    if len(pickles) > 1:
        raise _sp._Refused(f"{len(pickles)} data.pkl records (expected one)")
    return pickles[0][:-len("/data.pkl")]


def _load_zip(data: bytes, budget: _sp._Budget, depth: int) -> Any:
    """A torch zip archive -> its object, storages read from the records as the pickle names them."""
    archive = zipfile.ZipFile(io.BytesIO(data))
    prefix = _archive_prefix(archive)
    order_record = f"{prefix}/byteorder"
    byteorder = _read_record(archive, order_record, 16) if order_record in archive.namelist() else b"little"
    if byteorder not in (b"little", b"big"):
        raise _sp._Refused(f"unknown byte order {byteorder[:16]!r}")
    registry: dict[str, _Storage] = {}

    def storage(pid: tuple) -> _Storage:
        found = _storage_from_pid(pid, False, registry)
        if found.data is None:
            stored = found.dtype.stored.newbyteorder(">" if byteorder == b"big" else "<")
            found.data = _read_storage(archive, f"{prefix}/data/{found.key}", found, stored, budget)
        return found

    # data.pkl is unpickled as it inflates (a deflated record can hold a gigabyte in a megabyte)
    pickled, _ = _open_record(archive, f"{prefix}/data.pkl")
    with pickled:
        stream = _sp._chunked(pickled)
        value = _TorchUnpickler(stream, budget, depth, storage).load()
        while stream.read(_sp._INFLATE_CHUNK):  # the end of the record: its CRC is checked there
            pass
    return value


def _load_legacy(data: bytes, budget: _sp._Budget, depth: int) -> Any:
    """A legacy torch stream -> its object (storages follow the object pickle, so tensors are resolved last)."""
    stream = io.BytesIO(data)

    def header() -> Any:
        return _sp._RestrictedUnpickler(stream, budget, depth).load()

    if header() != MAGIC_NUMBER:
        raise _sp._Refused("not a torch stream (bad magic number)")
    version = header()
    if version != PROTOCOL_VERSION:
        raise _sp._Refused(f"unsupported legacy torch protocol version {version!r}")
    sys_info = header()
    if not isinstance(sys_info, dict):
        raise _sp._Refused("malformed legacy torch header")
    order = "<" if sys_info.get("little_endian", True) else ">"
    registry: dict[str, _Storage] = {}
    value = _TorchUnpickler(stream, budget, depth, lambda pid: _storage_from_pid(pid, True, registry)).load()
    keys = header()
    if not isinstance(keys, list) or not all(isinstance(k, str) for k in keys):
        raise _sp._Refused("malformed legacy torch storage list")
    for key in keys:
        if key not in registry:
            raise _sp._Refused(f"storage '{key}' is listed but never used")
        found = registry[key]
        head = stream.read(8)
        if len(head) != 8:
            raise _sp._Refused(f"truncated torch stream (storage '{key}' missing)")
        (numel,) = struct.unpack(order + "q", head)
        if numel != found.numel:
            raise _sp._Refused(f"storage '{key}' holds {numel:,} elements, its tensors declare {found.numel:,}")
        left = len(data) - stream.tell()
        if found.nbytes > left:
            raise _sp._Refused(f"truncated torch stream (storage '{key}' declares {found.nbytes:,} bytes, {left:,} follow)")
        budget.add_data(found.nbytes)
        found.data = np.frombuffer(stream.read(found.nbytes), found.dtype.stored.newbyteorder(order)).copy()
    missing = sorted(set(registry) - set(keys))
    if missing:
        raise _sp._Refused(f"storage '{missing[0]}' is used but its data is missing")
    return value


_FIRST_RECORDS = (b"data.pkl", b".format_version", b".storage_alignment", b"byteorder", b"version")


def is_torch_zip(data: bytes) -> bool:
    """True for a zip archive whose first record is one of ``torch.save``'s (``<name>/data.pkl``, or
    ``<name>/.format_version`` & co.), read from the first local header: a truncated archive, or one
    missing records, is still recognised (and reported) as a torch archive."""
    if len(data) < 30 or data[:4] != b"PK\x03\x04":
        return False
    (name_length,) = struct.unpack("<H", data[26:28])
    first = data[30:30 + name_length].split(b"/")
    return len(first) == 2 and bool(first[0]) and first[1] in _FIRST_RECORDS


def is_legacy_torch(data: bytes) -> bool:
    """True for bytes starting with the pickled legacy magic number (``torch.save(...,
    _use_new_zipfile_serialization=False)``): ``PROTO n``, a ``FRAME`` from protocol 4 on, ``LONG1``."""
    if len(data) < 4 or data[0] != 0x80 or not 2 <= data[1] <= 5:
        return False
    position = 11 if data[2] == 0x95 else 2  # FRAME + its 8-byte length
    body = MAGIC_NUMBER.to_bytes((MAGIC_NUMBER.bit_length() + 8) // 8, "little", signed=True)
    return data[position:position + 2 + len(body)] == bytes([0x8A, len(body)]) + body


def _is_tar(data: bytes) -> bool:
    return len(data) > 262 and data[257:262] == b"ustar"


def _load_blob(data: bytes, budget: _sp._Budget, depth: int) -> Any:
    """A torch file's bytes (zip archive or legacy stream) -> its object, storages read (tensors of a legacy
    stream may still be deferred: :func:`resolve`)."""
    if _is_tar(data):
        raise _sp._Refused("the pre-1.0 tar layout of torch.save is not supported (re-save with a recent PyTorch)")
    if data[:2] == b"PK":
        value = _load_zip(data, budget, depth)
    elif is_legacy_torch(data):
        value = _load_legacy(data, budget, depth)
    else:
        raise _sp._Refused("neither a torch zip archive nor a legacy torch stream")
    return value


def resolve(value: Any) -> Any:
    """Replace deferred tensors by arrays and bare storages by their 1-D arrays (shared objects once)."""
    done: dict[int, Any] = {}

    def walk(obj: Any) -> Any:
        key = id(obj)
        if key in done:
            return done[key]
        if isinstance(obj, _Deferred):
            out = _tensor_array(obj.storage, obj.offset, obj.size, obj.stride, obj.dtype, obj.negate, obj.conjugate)
        elif isinstance(obj, _Storage):
            out = _decode(obj.data, obj.dtype) if obj.data is not None else np.zeros(0)
        elif isinstance(obj, (dict, OrderedDict, defaultdict)):
            out = obj
            for k in list(obj):
                obj[k] = walk(obj[k])
        elif isinstance(obj, list):
            out = obj
            obj[:] = [walk(v) for v in obj]
        elif isinstance(obj, tuple):
            out = tuple(walk(v) for v in obj)
        elif isinstance(obj, np.ndarray) and obj.dtype.hasobject:
            out = obj
            for index in np.ndindex(obj.shape):
                obj[index] = walk(obj[index])
        else:
            out = obj
        done[key] = out
        return out

    return walk(value)


# ---- public ------------------------------------------------------------------------------------
_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, NotImplementedError, RuntimeError, EOFError)


def load_torch_bytes(data: bytes, source: str) -> Any:
    """The object a ``torch.save`` file holds (bytes of a zip archive or a legacy stream), as plain
    containers of numpy arrays; every failure is a one-line InputError naming ``source``."""
    budget = _sp._Budget()
    try:
        with _sp.unpickling_errors(source, "torch archive: "):
            value = resolve(_load_blob(data, budget, 0))
            _sp._check_expansion(value)
            return value
    except _ERRORS as exc:  # the archive around the pickle
        raise InputError(f"{source}: torch archive: corrupt ({str(exc).splitlines()[0] or type(exc).__name__})") from None


def load_torch(path: str | Path) -> Any:
    """Read a ``torch.save`` file (``.pt``/``.pth``: zip archive or legacy stream) without torch."""
    path = Path(path)
    data = _sp._read_bytes(path)
    if not data:
        raise InputError(f"{path}: empty file")
    return load_torch_bytes(data, str(path))

