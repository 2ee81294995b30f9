"""torch's tensors and storages as inert numpy stand-ins: the allow-list of torch's globals
(:data:`TORCH_GLOBALS`) that a restricted unpickler may hand a pickle, the builders they map to, and
:func:`resolve`, which turns what was built into plain numpy arrays (one independent array per
tensor, in the tensor's own shape and dtype; bfloat16 becomes float32). torch is never imported.

The names, read from PyTorch's own code (pytorch/pytorch @e8c9164 ``torch/_utils.py``:
``_rebuild_tensor_v2``, ``_rebuild_tensor_v3``, ``_rebuild_parameter``; @529d1f9
``torch/storage.py``: ``TypedStorage.__reduce__``, ``_load_from_bytes``,
``_dtype_to_storage_type_map``; ``torch/_tensor.py``: ``Tensor._reduce_ex_internal``,
``_rebuild_from_type_v2``):

- **tensors**: ``torch._utils._rebuild_tensor_v2(storage, storage_offset, size, stride,
  requires_grad, backward_hooks[, metadata])`` (``_rebuild_tensor_v3`` adds the dtype for
  untyped storages; ``_rebuild_parameter`` wraps a tensor; ``torch._tensor._rebuild_from_type_v2``
  wraps either). A tensor pickled by plain ``pickle`` (``np.save`` of a dict of tensors) carries its
  storage as ``torch.storage._load_from_bytes(b)``, ``b`` being a legacy stream of that storage
  (read by the loader the :class:`Builder` is given: ``torch_files``).
- **storages** are named by a global such as ``torch.FloatStorage`` (numel in elements) or
  ``torch.UntypedStorage`` (numel in bytes; the tensor then names its dtype).

A tensor's elements are checked against its storage (offset + extent of every stride) and its own
size against ``limits.max_array_mb``, the total against the pickle's budget
(:class:`~.checks.Budget`), before anything is allocated.

>>> torch_global("torch", "float32", None).stored
dtype('float32')
>>> torch_global("torch", "load", None) is None
True
"""

from __future__ import annotations

import math
from collections import OrderedDict, defaultdict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..settings import limits as _limits
from ..settings.limits import human_bytes
from .checks import Budget, check_array
from .refusal import Refused, shown

__all__ = ["TORCH_GLOBALS", "BlobLoader", "Builder", "Storage", "StorageType", "TorchDtype", "check_storage_bytes",
           "non_negative_int", "resolve", "torch_global"]

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
class StorageType:
    """Inert stand-in for ``torch.FloatStorage`` & co. (a persistent id names one)."""

    name: str
    dtype: TorchDtype

    @property
    def untyped(self) -> bool:
        return self.name == "UntypedStorage"


class Storage:
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

    storage: Storage
    offset: int
    size: tuple[int, ...]
    stride: tuple[int, ...]
    dtype: TorchDtype
    negate: bool
    conjugate: bool


# ---- checks -----------------------------------------------------------------------------------
def non_negative_int(value: Any, what: str) -> int:
    """``value`` if it is a non-negative int (a tensor's or storage's size, offset, stride), else Refused."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise Refused(f"malformed tensor {what} {shown(value)}")
    return value


def _ints(value: Any, what: str) -> tuple[int, ...]:
    if not isinstance(value, (tuple, list)):
        raise Refused(f"malformed tensor {what}")
    return tuple(non_negative_int(v, what) for v in value)


def check_storage_bytes(dtype: TorchDtype, numel: int) -> None:
    """Refused when a storage declares more than ``limits.max_array_mb``."""
    nbytes, limit = numel * dtype.stored.itemsize, _limits.current().max_array_bytes
    if nbytes > limit:
        raise Refused(f"storage declares {human_bytes(nbytes)} ({dtype} x {numel:,}; limit {human_bytes(limit)}: "
                      f"limits.max_array_mb)")


def _decode(flat: np.ndarray, dtype: TorchDtype) -> np.ndarray:
    """Stored elements -> numpy values (bfloat16: the upper half of a float32)."""
    if dtype.is_bfloat16:
        return (flat.astype("<u4") << np.uint32(16)).view("<f4").astype(np.float32)
    return flat.astype(flat.dtype.newbyteorder("="), copy=False)


def _tensor_array(storage: Storage, offset: int, size: tuple[int, ...], stride: tuple[int, ...], dtype: TorchDtype,
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


# A torch file's bytes, the budget and the nesting depth -> its object (torch_files.load_blob).
BlobLoader = Callable[[bytes, Budget, int], Any]


class Builder:
    """The allow-listed torch callables, bound to one load (its budget, and ``load_blob`` for a
    storage pickled inside a plain pickle, at nesting ``depth``)."""

    def __init__(self, budget: Budget, depth: int, load_blob: BlobLoader) -> None:
        self.budget, self.depth, self.load_blob = budget, depth, load_blob

    def tensor(self, storage: Any, offset: Any, size: Any, stride: Any, dtype: TorchDtype | None = None,
               metadata: Any = None) -> np.ndarray | _Deferred:
        if not isinstance(storage, Storage):
            raise Refused("malformed tensor (its storage is not a torch storage)")
        offset, size, stride = non_negative_int(offset, "storage offset"), _ints(size, "size"), _ints(stride, "stride")
        if len(stride) != len(size):
            raise Refused(f"malformed tensor (size {list(size)} with stride {list(stride)})")
        if dtype is None:
            dtype = storage.dtype
        elif not isinstance(dtype, TorchDtype) or not storage.untyped:
            raise Refused("malformed tensor dtype")
        check_array(dtype.stored, size)
        count = math.prod(size)
        available = storage.nbytes // dtype.stored.itemsize if storage.untyped else storage.numel
        if count:
            last = offset + sum((n - 1) * s for n, s in zip(size, stride))
            if last >= available:
                raise Refused(f"tensor of size {list(size)} (offset {offset}, stride {list(stride)}) reaches element "
                              f"{last:,} of storage '{storage.key}', which holds {available:,}")
        self.budget.add_data(count * dtype.stored.itemsize)
        negate = conjugate = False
        if metadata is not None:
            if not isinstance(metadata, dict) or not set(metadata) <= {"neg", "conj"}:
                raise Refused("malformed tensor metadata")
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
            raise Refused("malformed parameter (not a tensor)")
        return data

    def from_type(self, func: Any, new_type: Any, args: Any, state: Any = None) -> Any:
        """``torch._tensor._rebuild_from_type_v2``: only plain tensors and parameters, rebuilt by an allowed function."""
        if new_type not in (_TENSOR, _PARAMETER) or not isinstance(args, tuple):
            raise Refused(f"tensor subclass {shown(getattr(new_type, 'name', new_type))} is not allowed")
        if getattr(func, "__self__", None) is not self:
            raise Refused("malformed tensor (rebuilt by a function other than torch's)")
        return func(*args)

    def load_from_bytes(self, blob: Any) -> Storage:
        """``torch.storage._load_from_bytes``: a storage saved by ``torch.save`` inside a plain pickle."""
        if not isinstance(blob, (bytes, bytearray)):
            raise Refused("malformed pickled storage (not bytes)")
        if self.depth >= _MAX_NESTING:
            raise Refused("pickled storages nest too deeply")
        value = self.load_blob(bytes(blob), self.budget, self.depth + 1)
        if not isinstance(value, Storage):
            raise Refused("a pickled storage holds something other than a storage")
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
            table[(module, name)] = StorageType(name, _DTYPES[dtype_name])
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


def torch_global(module: str, name: str, builder: Builder) -> Any:
    """The inert stand-in for an allowed torch global, or None."""
    method = _REBUILDERS.get((module, name))
    if method is not None:
        return getattr(builder, method)
    return _STATIC.get((module, name))


def resolve(value: Any) -> Any:
    """Replace deferred tensors by arrays and bare storages by their 1-D arrays (shared objects once)."""
    done: dict[int, Any] = {}

    def walk(obj: Any) -> Any:
        key = id(obj)
        if key in done:
            return done[key]
        if isinstance(obj, _Deferred):
            out = _tensor_array(obj.storage, obj.offset, obj.size, obj.stride, obj.dtype, obj.negate, obj.conjugate)
        elif isinstance(obj, Storage):
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
