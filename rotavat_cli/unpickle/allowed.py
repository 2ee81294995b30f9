"""The allow-list of the restricted unpickler: every global a pickle may name, mapped to the object
handed to it (:data:`ALLOWED`). Each allowed callable is a wrapper that checks its arguments before
building anything: numpy arrays and scalars, builtin containers, ``collections.defaultdict`` with a
builtin type as its factory, and joblib's array placeholder (an inert stand-in).

>>> ALLOWED[("collections", "OrderedDict")].__name__
'OrderedDict'
>>> ("builtins", "eval") in ALLOWED
False
"""

from __future__ import annotations

import builtins
import math
import pickle
from collections import OrderedDict, defaultdict
from typing import Any

import numpy as np

from .checks import check_array, check_shape
from .refusal import Refused, shown

__all__ = ["ALLOWED", "JoblibArrayWrapper", "StandIn", "codecs_encode", "dtype", "frombuffer", "numpy_multiarray",
           "reconstruct", "reconstructor", "scalar"]


def numpy_multiarray() -> Any:
    """numpy's multiarray module under its numpy 2 or numpy 1 name."""
    core = getattr(np, "_core", None) or np.core
    return core.multiarray


def reconstruct(subtype: Any, shape: Any, typecode: Any) -> np.ndarray:
    """``numpy.core.multiarray._reconstruct`` for plain ndarrays only (no subclasses)."""
    if subtype is not np.ndarray:
        raise Refused(f"array subclass {shown(subtype)} is not allowed")
    if not isinstance(shape, tuple) or not all(isinstance(s, int) for s in shape):
        raise Refused("malformed ndarray reconstruction arguments")
    if not isinstance(typecode, (bytes, str)):
        raise Refused("malformed ndarray reconstruction arguments")
    if shape != (0,):  # numpy always pickles (0,) with b'b' and sets the real shape in BUILD
        try:
            dtype = np.dtype(typecode.decode("latin1") if isinstance(typecode, bytes) else typecode)
        except (TypeError, ValueError):
            raise Refused("malformed ndarray reconstruction arguments") from None
        check_array(dtype, check_shape(shape, "ndarray"))
    return numpy_multiarray()._reconstruct(np.ndarray, shape, typecode)


def dtype(obj: Any, align: Any = False, copy: Any = True) -> np.dtype:
    """``numpy.dtype(typestr, align, copy)`` as numpy pickles a dtype: from a type string only, and always
    a new dtype (``copy`` is ignored): ``BUILD`` then gives it a state (checked: ``dtypes``), which must
    never reach one of numpy's shared builtin dtypes."""
    if isinstance(obj, bytes):
        obj = obj.decode("latin1")
    if not isinstance(obj, str) or not isinstance(align, int) or not isinstance(copy, int):
        raise Refused("malformed dtype (numpy pickles a dtype from its type string)")
    return np.dtype(obj, align=bool(align), copy=True)


def scalar(dtype: Any, data: Any = None) -> Any:
    """``numpy.core.multiarray.scalar``: a numpy scalar from its dtype and raw bytes."""
    if not isinstance(dtype, np.dtype):
        raise Refused("malformed numpy scalar")
    if dtype.hasobject:
        return data  # numpy returns the stored (already unpickled, hence allowed) object itself
    if isinstance(data, str):  # Python 2 pickles store the bytes as a latin-1 str
        data = data.encode("latin1")
    if not isinstance(data, (bytes, bytearray)) or len(data) != dtype.itemsize:
        raise Refused("malformed numpy scalar")
    return np.frombuffer(bytes(data), dtype=dtype, count=1)[0]


def frombuffer(buf: Any, dtype: Any, shape: Any, order: Any) -> np.ndarray:
    """``numpy.core.numeric._frombuffer`` (pickle protocol 5 arrays)."""
    if not isinstance(dtype, np.dtype) or dtype.hasobject:
        raise Refused("malformed protocol-5 array")
    if not isinstance(shape, tuple) or order not in ("C", "F"):
        raise Refused("malformed protocol-5 array")
    if not isinstance(buf, (bytes, bytearray, pickle.PickleBuffer)):
        raise Refused("malformed protocol-5 array buffer")
    check_array(dtype, check_shape(shape, "protocol-5 array"))
    data = bytes(buf.raw() if isinstance(buf, pickle.PickleBuffer) else buf)
    if math.prod(shape) * dtype.itemsize != len(data):
        raise Refused("protocol-5 array size does not match its shape")
    return np.frombuffer(data, dtype=dtype).reshape(shape, order=order).copy()


def codecs_encode(text: Any, encoding: str = "utf-8", errors: str = "strict") -> bytes:
    """``_codecs.encode`` as pickle protocol 2 uses it for bytes: str -> bytes, latin-1/utf-8 only."""
    if not isinstance(text, str) or encoding.lower().replace("_", "-") not in ("latin1", "latin-1", "utf-8", "utf8"):
        raise Refused("malformed bytes object")
    return text.encode(encoding, errors)


_CONTAINER_TYPES = (dict, list, tuple, set, frozenset, str, bytes, bytearray, int, float, complex, bool, OrderedDict)


class StandIn:
    """Base of the inert stand-ins an unpickler may hand out for a class it allows by name (a model
    file's chumpy arrays and scipy sparse matrices: ``model_files``): made empty (``NEWOBJ`` with no
    arguments, or ``copyreg._reconstructor(cls, object, None)``), given no attributes, and replaced by
    what the unpickler builds from their state at ``BUILD``."""

    __slots__ = ()


def reconstructor(cls: Any, base: Any, state: Any = None) -> Any:
    """``copyreg._reconstructor`` (protocol 0/1 objects), for builtin container types and the inert
    :class:`StandIn` classes only."""
    if isinstance(cls, type) and issubclass(cls, StandIn):
        if base is not object or state is not None:
            raise Refused(f"malformed {cls.__name__} reconstruction")
        return object.__new__(cls)
    if cls not in _CONTAINER_TYPES or base not in _CONTAINER_TYPES + (object,):
        raise Refused(f"object of type {shown(cls)} is not allowed")
    if base is object:
        return object.__new__(cls)
    return base.__new__(cls, state) if state is not None else base.__new__(cls)


class JoblibArrayWrapper:
    """Inert stand-in for ``joblib.numpy_pickle.NumpyArrayWrapper`` (metadata of one array)."""

    _FIELDS = {"subclass", "shape", "order", "dtype", "allow_mmap", "numpy_array_alignment_bytes"}

    def __setstate__(self, state: Any) -> None:
        if not isinstance(state, dict) or not set(state) <= self._FIELDS:
            raise Refused("malformed joblib array wrapper")
        if state.get("subclass", np.ndarray) is not np.ndarray:
            raise Refused("joblib array of a numpy subclass is not allowed")
        shape, dtype, order = state.get("shape"), state.get("dtype"), state.get("order", "C")
        if not isinstance(shape, tuple) or not all(isinstance(s, int) and s >= 0 for s in shape):
            raise Refused("malformed joblib array shape")
        if not isinstance(dtype, np.dtype) or order not in ("C", "F"):
            raise Refused("malformed joblib array dtype/order")
        self.shape, self.dtype, self.order = shape, dtype, order
        self.alignment = state.get("numpy_array_alignment_bytes")


# Factories a pickled ``collections.defaultdict`` may name: builtin types, whose call builds an empty value.
_DEFAULT_FACTORIES = (list, dict, set, frozenset, tuple, int, float, complex, str, bytes, bool, OrderedDict)


def _defaultdict(factory: Any = None, *rest: Any) -> defaultdict:
    """``collections.defaultdict(factory)`` as a pickle rebuilds it (items are set afterwards), for a
    builtin factory only: any other callable would run code on every missing key."""
    if rest or not (factory is None or factory in _DEFAULT_FACTORIES):
        raise Refused(f"defaultdict with factory {getattr(factory, '__name__', type(factory).__name__)!r} "
                      "is not allowed (only builtin types)")
    return defaultdict(factory)


def _allowed() -> dict[tuple[str, str], Any]:
    """(module, name) -> object handed to the unpickler."""
    table: dict[tuple[str, str], Any] = {}
    for name in ("dict", "list", "tuple", "set", "frozenset", "str", "bytes", "bytearray", "int", "float",
                 "complex", "bool", "slice", "range"):
        table[("builtins", name)] = getattr(builtins, name)
    table[("collections", "OrderedDict")] = OrderedDict
    table[("collections", "defaultdict")] = _defaultdict
    table[("copyreg", "_reconstructor")] = reconstructor
    table[("_codecs", "encode")] = codecs_encode
    for core in ("numpy.core", "numpy._core"):
        table[(f"{core}.multiarray", "_reconstruct")] = reconstruct
        table[(f"{core}.multiarray", "scalar")] = scalar
        table[(f"{core}.numeric", "_frombuffer")] = frombuffer
    table[("numpy", "ndarray")] = np.ndarray
    table[("numpy", "dtype")] = dtype
    table[("joblib.numpy_pickle", "NumpyArrayWrapper")] = JoblibArrayWrapper
    return table


ALLOWED = _allowed()
