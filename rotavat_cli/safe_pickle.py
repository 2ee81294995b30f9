"""Restricted unpickling of untrusted files: numpy arrays, numpy scalars and builtin containers only
(``collections.defaultdict`` too, with a builtin type as its factory).

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
  bytes are read into the array it declares, refused when fewer follow;
- ``.npy``/``.npz`` files whose members may be object arrays (``np.savez(..., results=dict)``);
- PyTorch files: ``torch.save`` archives (zip, or the legacy stream) through :func:`load_torch` or
  transparently through :func:`load_file`, and torch tensors inside plain pickles (``np.save`` of a
  dict of tensors). torch's tensor-rebuilding globals are an allow-list of inert numpy builders
  (:mod:`rotavat_cli.safe_torch`): tensors come back as numpy arrays; torch is never imported.

Sizes are checked before anything is allocated, against :mod:`rotavat_cli.limits` (the config's
``limits:`` section): files and decompressed streams (``max_file_mb``), every array a header or a
pickle declares (``max_array_mb``), the objects a pickle builds and the items its shared
references add when expanded (``max_pickle_items``). A compressed pickle (joblib's, an ``.npz``
member, a torch archive's ``data.pkl``) is unpickled as it inflates, never inflated whole first: a
decompression bomb is refused at its first byte that is not a pickle's, or once ``max_file_mb`` came
out, holding one chunk; a compressed file costs what the objects it holds cost, as an uncompressed
one does. :func:`open_npz` is the one place that reads
``.npz`` members (declared zip sizes, ``.npy`` headers, then the data in bounded chunks); contract
frames (``sequence.read_frame_npz``) use it too, with ``allow_pickle=False``.

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
import itertools
import lzma
import math
import pickle
import struct
import sys
import zipfile
import zlib
from collections import OrderedDict, defaultdict
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from . import limits as _limits
from .errors import InputError
from .limits import human_bytes

__all__ = ["loads", "load_file", "load_torch", "load_npy", "load_npy_bytes", "load_npz", "open_npz", "NpzArchive", "unpickling_errors"]

_MAX_NPY_HEADER = 10_000  # numpy's own default limit for .npy headers
_CHUNK = 1 << 24  # bytes copied at a time
_INFLATE_CHUNK = 1 << 20  # bytes a compressed stream inflates (or a zip member yields) at a time
_MAX_FRAME = 1 << 24  # pickle writes frames of about 64 KiB (pickle._Framer, _pickle.c FRAME_SIZE_TARGET)
_REFUSAL = "(only numpy arrays, numpy scalars and builtin containers are allowed)"


class _Refused(Exception):
    """Raised inside the unpickler; turned into an InputError naming the file."""


# ---- size checks --------------------------------------------------------------------------------
def _array_bytes(dtype: np.dtype, shape: tuple[int, ...]) -> int:
    """Bytes an array of ``shape`` takes (a reference per element for object arrays; at least one
    byte per element, so zero-size dtypes cannot declare billions of elements for free)."""
    return math.prod(shape) * max(1, 8 if dtype.hasobject else dtype.itemsize)


def _array_refusal(dtype: np.dtype, shape: tuple[int, ...]) -> str | None:
    """Why an array of this dtype and shape is refused (``limits.max_array_mb``), or None."""
    nbytes, limit = _array_bytes(dtype, shape), _limits.current().max_array_bytes
    if nbytes <= limit:
        return None
    return f"declares {human_bytes(nbytes)} ({dtype} {tuple(shape)}; limit {human_bytes(limit)}: limits.max_array_mb)"


def _check_shape(shape: Any, what: str) -> tuple[int, ...]:
    """``shape`` as a tuple of non-negative ints, or _Refused."""
    if not isinstance(shape, tuple) or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape):
        raise _Refused(f"malformed {what} shape")
    return shape


def _check_array(dtype: np.dtype, shape: tuple[int, ...]) -> None:
    """_Refused when the declared array is over ``limits.max_array_mb``."""
    why = _array_refusal(dtype, shape)
    if why is not None:
        raise _Refused(f"array {why}")


class _Budget:
    """What one pickle may build: objects (every opcode run, every item a container is built from)
    and bytes of data (arrays, bytes and strings made by calls), against the limits in force."""

    def __init__(self) -> None:
        lim = _limits.current()
        self.max_items, self.max_data, self.max_array = lim.max_pickle_items, lim.max_file_bytes, lim.max_array_bytes
        self.items = self.data = 0

    def add_items(self, n: int, what: str) -> None:
        self.items += n
        if self.items > self.max_items:
            raise _Refused(f"{what} would build {n:,} items (limit {self.max_items:,}: limits.max_pickle_items)"
                           if n > self.max_items else
                           f"pickle builds more than {self.max_items:,} objects (limits.max_pickle_items)")

    def add_data(self, nbytes: int) -> None:
        self.data += nbytes
        if self.data > self.max_data:
            raise _Refused(f"pickle builds more than {human_bytes(self.max_data)} of arrays and strings "
                           f"(limit: limits.max_file_mb)")


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
    if shape != (0,):  # numpy always pickles (0,) with b'b' and sets the real shape in BUILD
        try:
            dtype = np.dtype(typecode.decode("latin1") if isinstance(typecode, bytes) else typecode)
        except (TypeError, ValueError):
            raise _Refused("malformed ndarray reconstruction arguments") from None
        _check_array(dtype, _check_shape(shape, "ndarray"))
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
    if not isinstance(buf, (bytes, bytearray, pickle.PickleBuffer)):
        raise _Refused("malformed protocol-5 array buffer")
    _check_array(dtype, _check_shape(shape, "protocol-5 array"))
    data = bytes(buf.raw() if isinstance(buf, pickle.PickleBuffer) else buf)
    if math.prod(shape) * dtype.itemsize != len(data):
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


# Factories a pickled ``collections.defaultdict`` may name: builtin types, whose call builds an empty value.
_DEFAULT_FACTORIES = (list, dict, set, frozenset, tuple, int, float, complex, str, bytes, bool, OrderedDict)


def _defaultdict(factory: Any = None, *rest: Any) -> defaultdict:
    """``collections.defaultdict(factory)`` as a pickle rebuilds it (items are set afterwards), for a
    builtin factory only: any other callable would run code on every missing key."""
    if rest or not (factory is None or factory in _DEFAULT_FACTORIES):
        raise _Refused(f"defaultdict with factory {getattr(factory, '__name__', type(factory).__name__)!r} "
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
# Allowed types whose call (or __new__) copies its first argument: the copy is sized first, so
# ``list(range(10**9))``, ``tuple.__new__(tuple, range(...))`` or ``bytes(10**9)`` never run.
_COPYING = (list, tuple, set, frozenset, dict, OrderedDict)
_TEXT = (str, bytes, bytearray)


# ---- the unpickler ---------------------------------------------------------------------------
class _CountingDispatch(dict):
    """The opcode table, counting each opcode run against the pickle's object budget."""

    __slots__ = ("budget",)

    def __getitem__(self, key: int) -> Any:
        budget = self.budget
        budget.items += 1
        if budget.items > budget.max_items:
            budget.add_items(1, "pickle")
        return dict.__getitem__(self, key)


class _RestrictedUnpickler(pickle._Unpickler):  # noqa: SLF001 -- pure-Python unpickler: BUILD is overridable
    """Pure-Python unpickler with an allow-list ``find_class``, joblib's array placeholders and a
    budget: every opcode, every call that copies a container and every array is counted or sized
    before it runs (``limits``)."""

    dispatch = pickle._Unpickler.dispatch.copy()  # noqa: SLF001

    def __init__(self, file: BinaryIO, budget: _Budget | None = None, depth: int = 0) -> None:
        super().__init__(file, encoding="latin1")
        self._raw = file
        self._budget = budget or _Budget()
        self._depth = depth  # storages pickled inside storages (safe_torch)
        self._torch_builder: Any = None
        self.dispatch = _CountingDispatch(type(self).dispatch)
        self.dispatch.budget = self._budget

    def find_class(self, module: str, name: str) -> Any:
        if self.proto < 3 and self.fix_imports:  # Python 2 names (e.g. __builtin__.set)
            if (module, name) in _compat_pickle.NAME_MAPPING:
                module, name = _compat_pickle.NAME_MAPPING[(module, name)]
            elif module in _compat_pickle.IMPORT_MAPPING:
                module = _compat_pickle.IMPORT_MAPPING[module]
        try:
            return _ALLOWED[(module, name)]
        except (KeyError, TypeError):
            pass
        found = self._torch_global(module, name) if isinstance(module, str) and module.startswith("torch") else None
        if found is None:
            raise _Refused(f"refused to unpickle global '{module}.{name}' {_REFUSAL}")
        return found

    def _torch_global(self, module: str, name: str) -> Any:
        """torch's tensor-rebuilding globals, mapped to inert numpy builders (:mod:`rotavat_cli.safe_torch`)."""
        from . import safe_torch  # safe_torch builds on this module: imported when a pickle names torch

        if self._torch_builder is None:
            self._torch_builder = safe_torch._Builder(self._budget, self._depth)
        return safe_torch.torch_global(module, name, self._torch_builder)

    @property
    def named_torch(self) -> bool:
        """Whether the pickle named one of torch's globals (its result may hold storages to resolve)."""
        return self._torch_builder is not None

    def persistent_load(self, pid: Any) -> Any:
        raise _Refused("refused a persistent id (pickles that reference external objects are not allowed)")

    # -- calls: size what a call would copy before making it
    def _check_call(self, func: Any, args: Any) -> None:
        if not isinstance(args, tuple):
            raise _Refused("malformed call arguments")
        if func is np.ndarray:
            raise _Refused("numpy.ndarray may not be called directly (arrays are rebuilt with _reconstruct)")
        if func is _reconstructor and len(args) >= 3 and args[2] is not None:
            self._check_call(args[1], (args[2],))
        elif func is _frombuffer and args and isinstance(args[0], (bytes, bytearray)):
            self._budget.add_data(2 * len(args[0]))  # copied, then copied into the array
        elif func is _codecs_encode and args and isinstance(args[0], str):
            self._budget.add_data(len(args[0]))
        if not args or not isinstance(func, type):
            return
        name = getattr(func, "__name__", "call")
        if issubclass(func, _TEXT):
            if not isinstance(args[0], _TEXT):  # str(a list) or bytes(10**9) would expand or allocate
                raise _Refused(f"{name}() of a {type(args[0]).__name__} is not allowed")
            self._budget.add_data(len(args[0]))
        elif issubclass(func, _COPYING):
            try:
                n = len(args[0])
            except TypeError:  # not a container: the call raises TypeError itself, or copies nothing
                return
            except OverflowError:
                n = sys.maxsize
            self._budget.add_items(n, f"{name}()")

    def load_reduce(self) -> None:
        args = self.stack.pop()
        func = self.stack[-1]
        self._check_call(func, args)
        self.stack[-1] = func(*args)

    dispatch[pickle.REDUCE[0]] = load_reduce

    def load_newobj(self) -> None:
        args = self.stack.pop()
        cls = self.stack.pop()
        self._check_call(cls, args)
        self.append(cls.__new__(cls, *args))

    dispatch[pickle.NEWOBJ[0]] = load_newobj

    def load_newobj_ex(self) -> None:
        kwargs = self.stack.pop()
        args = self.stack.pop()
        cls = self.stack.pop()
        if not isinstance(kwargs, dict):
            raise _Refused("malformed call arguments")
        self._check_call(cls, args)
        self.append(cls.__new__(cls, *args, **kwargs))

    dispatch[pickle.NEWOBJ_EX[0]] = load_newobj_ex

    def _instantiate(self, klass: Any, args: list) -> None:  # INST and OBJ
        self._check_call(klass, tuple(args))
        super()._instantiate(klass, args)

    def load_bytearray8(self) -> None:
        """BYTEARRAY8 allocates its announced size before reading: read the bytes that are there first."""
        (size,) = struct.unpack("<Q", self.read(8))
        data = _read_up_to(self.read, size)
        if len(data) < size:
            raise _Refused(f"truncated pickle (a bytearray of {size:,} bytes announced)")
        self._budget.add_data(size)
        self.append(bytearray(data))

    dispatch[pickle.BYTEARRAY8[0]] = load_bytearray8

    def load_frame(self) -> None:
        """A FRAME is read whole before its opcodes run: one larger than any pickler writes is refused unread."""
        (size,) = struct.unpack("<Q", self.read(8))
        if size > _MAX_FRAME:
            raise _Refused(f"malformed pickle (a frame of {size:,} bytes; pickle writes frames of about 64 KiB)")
        self._unframer.load_frame(size)

    dispatch[pickle.FRAME[0]] = load_frame

    def load_build(self) -> None:
        state, inst = self.stack[-1], self.stack[-2]
        if callable(inst):  # a class or function of the allow-list: never give it attributes
            raise _Refused(f"malformed pickle (BUILD on {getattr(inst, '__name__', 'a callable')})")
        if isinstance(inst, np.ndarray):
            self._check_array_state(state)
        super().load_build()
        if isinstance(self.stack[-1], _JoblibArrayWrapper):
            self.stack[-1] = self._read_joblib_array(self.stack[-1])
        if isinstance(self.stack[-1], np.ndarray) and _invalid_text(self.stack[-1]):
            raise _Refused("an array holds invalid text (a code point beyond U+10FFFF)")

    dispatch[pickle.BUILD[0]] = load_build

    def _check_array_state(self, state: Any) -> None:
        """``ndarray.__setstate__`` allocates (and zeroes) the declared shape: size it first."""
        if not isinstance(state, tuple) or len(state) not in (4, 5):
            raise _Refused("malformed ndarray state")
        shape, dtype, _fortran, raw = state[-4:]
        if not isinstance(dtype, np.dtype):
            raise _Refused("malformed ndarray state")
        shape = _check_shape(shape, "ndarray")
        count = math.prod(shape)
        if count * max(1, 8 if dtype.hasobject else dtype.itemsize) > self._budget.max_array:
            _check_array(dtype, shape)
        if dtype.hasobject:
            if not isinstance(raw, list) or len(raw) != count:
                raise _Refused("object array data does not match its shape")
            self._budget.add_items(count, "object array")
            return
        try:
            size = len(raw) if isinstance(raw, str) else memoryview(raw).nbytes
        except TypeError:
            raise _Refused("malformed ndarray state") from None
        if size != count * dtype.itemsize:
            raise _Refused("array data does not match its shape")
        self._budget.add_data(size)

    def _read_joblib_array(self, wrapper: _JoblibArrayWrapper) -> np.ndarray:
        """Raw array bytes that joblib writes right after the placeholder."""
        if not hasattr(wrapper, "dtype"):
            raise _Refused("malformed joblib array wrapper")
        _check_array(wrapper.dtype, wrapper.shape)
        if wrapper.dtype.hasobject:  # joblib pickles object arrays with plain pickle (protocol 2)
            array = _RestrictedUnpickler(self._raw, self._budget).load()
            if not isinstance(array, np.ndarray):
                raise _Refused("joblib object array is not an array")
            return array
        if wrapper.alignment is not None:
            pad = self._raw.read(1)
            if len(pad) != 1:
                raise _Refused("truncated joblib array")
            self._raw.read(pad[0])
        count = math.prod(wrapper.shape)
        nbytes = count * wrapper.dtype.itemsize
        if nbytes <= _CHUNK:  # one read (the usual small array): it holds what is there, at most a chunk
            raw = self._raw.read(nbytes)
            got = len(raw)
            array = np.frombuffer(raw, wrapper.dtype, count).copy() if got == nbytes else None
        else:  # memory is taken as the bytes arrive, never for what is missing
            array = np.empty(count, wrapper.dtype)
            got = _fill(self._raw.read, array.view(np.uint8))
        if got < nbytes:
            raise _Refused(f"truncated joblib array ({nbytes} bytes announced, {got} left)")
        self._budget.add_data(nbytes)
        if wrapper.order == "F":
            return array.reshape(wrapper.shape[::-1]).transpose().copy()
        return array.reshape(wrapper.shape)


# ---- shared references ----------------------------------------------------------------------
def _leaf_weight(obj: Any) -> tuple[int, int] | None:
    """(expanded, held) items of an object that is not walked into; None for containers."""
    if isinstance(obj, np.ndarray):
        return None if obj.dtype.hasobject else (max(1, obj.size), max(1, obj.size))
    if isinstance(obj, (list, tuple, set, frozenset, dict)):
        return None
    if isinstance(obj, _TEXT):
        return 1 + len(obj) // 8, 1 + len(obj) // 8
    if isinstance(obj, range):  # lazy: one object, but np.asarray or list() would make len(range) items
        try:
            return 1 + len(obj), 1
        except OverflowError:
            return sys.maxsize, 1
    return 1, 1


def _children(obj: Any) -> tuple[Iterator[Any], int]:
    """Iterator over a container's references and their number."""
    if isinstance(obj, dict):
        return itertools.chain.from_iterable(obj.items()), 2 * len(obj)
    if isinstance(obj, np.ndarray):
        return iter(obj.flat), obj.size
    return iter(obj), len(obj)


_PLAIN_SCALARS = frozenset({int, float, bool, complex, type(None)})  # one item each, never walked into


def _expansion(root: Any) -> tuple[int, int]:
    """(expanded, held): items a full conversion of ``root`` makes (to_plain, np.asarray, str: a shared
    object once per reference) and items the unpickled objects hold (each object once).

    Iterative (no recursion limit), linear in what is held; _Refused on a reference cycle.
    """
    leaf = _leaf_weight(root)
    if leaf is not None:
        return leaf
    done: dict[int, int] = {}  # id -> expanded size of a finished object (and of sized leaves)
    on_path: set[int] = {id(root)}
    children, held = _children(root)
    held += 1
    stack: list[list[Any]] = [[root, children, 1]]
    while stack:
        frame = stack[-1]
        acc, pushed = 0, False
        for child in frame[1]:
            if type(child) in _PLAIN_SCALARS:
                acc += 1
                continue
            key = id(child)
            weight = done.get(key)
            if weight is not None:
                acc += weight
                continue
            leaf = _leaf_weight(child)
            if leaf is not None:
                acc += leaf[0]
                if leaf[1] > 1 or leaf[0] > 1:  # arrays, strings, ranges: held once, expanded per reference
                    done[key] = leaf[0]
                    held += leaf[1]
                continue
            if key in on_path:
                raise _Refused("pickle contains a reference cycle")
            on_path.add(key)
            grandchildren, n = _children(child)
            held += 1 + n
            stack.append([child, grandchildren, 1])
            pushed = True
            break
        frame[2] += acc
        if not pushed:
            stack.pop()
            on_path.discard(id(frame[0]))
            done[id(frame[0])] = frame[2]
            if stack:
                stack[-1][2] += frame[2]
    return done[id(root)], held


def _check_expansion(obj: Any) -> None:
    """_Refused when shared references would add more than ``max_pickle_items`` items on conversion."""
    expanded, held = _expansion(obj)
    limit = _limits.current().max_pickle_items
    if expanded - held > limit:
        raise _Refused(f"shared references expand the pickle to {expanded:,} items, {expanded - held:,} more than it "
                       f"holds (limit {limit:,} more: limits.max_pickle_items)")


# What malformed pickle bytes raise in the pure-Python unpickler and the builders it calls.
_MALFORMED = (pickle.UnpicklingError, ValueError, TypeError, IndexError, AttributeError, struct.error, UnicodeDecodeError,
              OverflowError)


@contextmanager
def unpickling_errors(source: str, what: str = "") -> Iterator[None]:
    """Context: every way unpickling hostile or broken bytes fails becomes a one-line InputError naming
    ``source`` (and ``what`` was read, e.g. ``"torch archive: "``)."""
    prefix = f"{source}: {what}"
    try:
        yield
    except _Refused as exc:
        raise InputError(f"{prefix}{exc}") from None
    except EOFError:
        raise InputError(f"{prefix}truncated pickle (unexpected end of data)") from None
    except RecursionError:
        raise InputError(f"{prefix}pickle nests too deeply") from None
    except MemoryError:
        raise InputError(f"{prefix}pickle needs more memory than available") from None
    except KeyError:  # the dispatch table has no entry for the byte read
        raise InputError(f"{prefix}not a readable pickle (invalid opcode)") from None
    except _MALFORMED as exc:
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{prefix}not a readable pickle ({detail})") from None


def _load_stream(file: BinaryIO, source: str, drain: bool = False) -> Any:
    """Unpickle one object from ``file``; every failure becomes a one-line InputError. ``drain``: read
    the rest of the stream too (a compressed stream's checksum and size are checked at its end)."""
    with unpickling_errors(source):
        unpickler = _RestrictedUnpickler(file)
        value = unpickler.load()
        if drain:
            while file.read(_INFLATE_CHUNK):
                pass
        if unpickler.named_torch:  # torch tensors pickled by plain pickle (np.save of a dict of tensors)
            from .safe_torch import resolve

            value = resolve(value)
        _check_expansion(value)
        return value


def loads(data: bytes, source: str) -> Any:
    """Unpickle ``data`` (plain pickle or uncompressed joblib) with the allow-list."""
    return _load_stream(io.BytesIO(data), source)


# ---- files -----------------------------------------------------------------------------------
def _file_size(path: Path) -> int:
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


def _read_bytes(path: Path) -> bytes:
    """Whole file, refusing missing, unreadable or oversized files."""
    _file_size(path)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, expected a file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


class _Stream:
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


def _chunked(stream: BinaryIO) -> _Stream:
    """``stream`` (a zip member, a file) read a chunk at a time (see :class:`_Stream`)."""
    return _Stream(lambda: stream.read(_INFLATE_CHUNK))


class _Inflater:
    """The next decompressed chunk of ``data`` at each call (b'' at the end, or where the data is
    truncated): _Refused as soon as more than ``limits.max_file_mb`` came out, or for corrupt data."""

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
                    given = self._data[self._fed:self._fed + _INFLATE_CHUNK]
                    self._fed += len(given)
                else:
                    return b""
                out = d.decompress(given, _INFLATE_CHUNK)
                self._pending = len(out) == _INFLATE_CHUNK
                if out:
                    self._out += len(out)
                    if self._out > self._limit:
                        raise _Refused(f"decompresses to more than {human_bytes(self._limit)} "
                                       "(limit: limits.max_file_mb)")
                    return out
        except (zlib.error, OSError, lzma.LZMAError, EOFError, ValueError) as exc:
            raise _Refused(f"corrupt compressed data ({exc})") from None
        return b""


def _decompressed(data: bytes, source: str) -> BinaryIO:
    """The pickle stream of a file's bytes: joblib's optional compression undone as it is read
    (detected from the magic bytes, as joblib does)."""
    for magic, make in ((b"\x1f\x8b", lambda: zlib.decompressobj(16 + zlib.MAX_WBITS)), (b"BZh", bz2.BZ2Decompressor),
                        (b"\xfd7zXZ\x00", lambda: lzma.LZMADecompressor(format=lzma.FORMAT_XZ)),
                        (b"]\x00\x00\x80\x00", lambda: lzma.LZMADecompressor(format=lzma.FORMAT_ALONE)),
                        (b"x", zlib.decompressobj)):  # zlib header (joblib's default compressor)
        if data.startswith(magic):
            return _Stream(_Inflater(make, data))
    if data[:4] == b'\x04"M\x18':
        raise InputError(f"{source}: lz4-compressed joblib files are not supported; re-save with compress=3 (zlib)")
    return io.BytesIO(data)


def load_file(path: str | Path) -> Any:
    """Unpickle a ``.pkl`` file written by ``pickle.dump`` or ``joblib.dump`` (any compression), or a
    ``torch.save`` file (zip archive or legacy stream: :func:`load_torch`)."""
    path = Path(path)
    data = _read_bytes(path)
    if not data:
        raise InputError(f"{path}: empty file")
    from . import safe_torch

    if safe_torch.is_torch_zip(data) or safe_torch.is_legacy_torch(data):
        return safe_torch.load_torch_bytes(data, str(path))
    stream = _decompressed(data, str(path))
    return _load_stream(stream, str(path), drain=isinstance(stream, _Stream))


def load_torch(path: str | Path) -> Any:
    """Read a ``torch.save`` file without torch: plain containers of numpy arrays (:mod:`rotavat_cli.safe_torch`)."""
    from .safe_torch import load_torch as _load

    return _load(path)


# ---- .npy ------------------------------------------------------------------------------------
def _read_npy_header(stream: BinaryIO, source: str) -> tuple[np.dtype, tuple[int, ...], bool, int]:
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


def _read_npy(stream: BinaryIO, size: int, source: str, what: str, allow_pickle: bool) -> np.ndarray:
    """One array from a ``.npy`` stream of ``size`` bytes (a file, a zip member, bytes).

    The header is checked before any data is read: the declared array against
    ``limits.max_array_mb``, and against ``size`` (a header may not announce more data than the
    stream holds). Numeric data is read in bounded chunks into an array of exactly the declared
    size; object arrays go through the restricted unpickler (``allow_pickle``) or are refused.
    ``what`` names the array in size messages (``path`` or ``path: member 'key'``).
    """
    dtype, shape, fortran, offset = _read_npy_header(stream, source)
    why = _array_refusal(dtype, shape)
    if why is not None:
        raise InputError(f"{what} {why}")
    if dtype.hasobject:
        if not allow_pickle:
            raise InputError(f"{what} is an object array: cannot read without pickle (only numeric arrays are allowed here)")
        array = _load_stream(_chunked(stream), source, drain=True)  # unpickled as it is read (a deflated member)
        if not isinstance(array, np.ndarray) or array.shape != shape:
            raise InputError(f"{source}: object array does not match its header")
        return array
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    if offset + nbytes > size:
        raise InputError(f"{source}: corrupt or truncated array (its header declares {nbytes:,} bytes of data, "
                         f"{max(0, size - offset):,} follow)")
    array = np.empty(count, dtype)
    pos = _fill(stream.read, array.view(np.uint8)) if nbytes else 0
    if pos < nbytes:
        raise InputError(f"{source}: corrupt or truncated array (data ends after {pos:,} of {nbytes:,} bytes)")
    _check_text(array, what)
    if fortran:
        return array.reshape(shape[::-1]).transpose()
    return array.reshape(shape)


def _invalid_text(array: np.ndarray) -> bool:
    """Whether a unicode array holds a code point beyond U+10FFFF (numpy reads those into broken strs:
    SystemError once the text is used), wherever the array was read from (npy, pickle)."""
    if array.dtype.kind != "U" or not array.size:
        return False
    return int(np.frombuffer(array.tobytes(), array.dtype.str[0] + "u4").max()) > sys.maxunicode


def _check_text(array: np.ndarray, what: str) -> np.ndarray:
    """``array`` unless it holds invalid text (:func:`_invalid_text`): InputError naming ``what``."""
    if _invalid_text(array):
        raise InputError(f"{what} holds invalid text (a code point beyond U+10FFFF)")
    return array


def _read_up_to(read: Any, n: int) -> bytes:
    """The next ``n`` bytes from ``read`` (fewer where the data ends), in chunks: only what is there is held."""
    parts, left = [], max(0, n)
    while left:
        chunk = read(min(_CHUNK, left))
        if not chunk:
            break
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def _fill(read: Any, out: np.ndarray) -> int:
    """Fill the uint8 array ``out`` from ``read`` in chunks; how many bytes came (fewer where the data ends)."""
    pos = 0
    while pos < len(out):
        chunk = read(min(_CHUNK, len(out) - pos))
        if not chunk:
            break
        out[pos:pos + len(chunk)] = np.frombuffer(chunk, np.uint8)
        pos += len(chunk)
    return pos


def load_npy_bytes(raw: bytes, source: str) -> np.ndarray:
    """Array from ``.npy`` bytes; object arrays go through the restricted unpickler."""
    return _read_npy(io.BytesIO(raw), len(raw), source, source, allow_pickle=True)


def load_npy(path: str | Path) -> np.ndarray:
    """Read a ``.npy`` file (object arrays through the restricted unpickler); header checked first."""
    path = Path(path)
    size = _file_size(path)
    try:
        with open(path, "rb") as handle:
            return _read_npy(handle, size, str(path), str(path), allow_pickle=True)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


# ---- .npz ------------------------------------------------------------------------------------
_NPZ_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, zlib.error, NotImplementedError, RuntimeError)
_NPZ_COMPRESSION = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)  # what np.savez / np.savez_compressed write


class NpzArchive:
    """An open ``.npz``: its ``.npy`` members by key (from the zip directory, nothing read yet).

    :meth:`read` reads some members with every check made first: compression method, declared
    uncompressed size (``max_file_mb``, also for the members' total), ``.npy`` header
    (``max_array_mb``, and no more data than the member declares). Members whose name does not end
    in ``.npy`` are not arrays and are ignored, as ``np.savez`` never writes them.
    """

    def __init__(self, path: Path, archive: zipfile.ZipFile) -> None:
        self.path, self._archive = path, archive
        self.members = {info.filename[:-4]: info for info in archive.infolist() if info.filename.endswith(".npy")}

    def keys(self) -> list[str]:
        return list(self.members)

    def _open(self, key: str) -> tuple[BinaryIO, zipfile.ZipInfo]:
        info = self.members[key]
        if info.compress_type not in _NPZ_COMPRESSION:
            raise InputError(f"{self.path}: member '{key}' uses an unsupported compression method "
                             f"({info.compress_type}; numpy writes stored or deflated members)")
        return self._archive.open(info), info

    def _check(self, key: str, allow_pickle: bool) -> int:
        """Declared sizes of one member, checked without reading its data; its uncompressed size."""
        limit = _limits.current().max_file_bytes
        with self._open(key)[0] as stream:
            info = self.members[key]
            source = f"{self.path} ['{key}']"
            dtype, shape, _, offset = _read_npy_header(stream, source)
            what = f"{self.path}: member '{key}'"
            why = _array_refusal(dtype, shape)
            if why is not None:
                raise InputError(f"{what} {why}")
            if dtype.hasobject and not allow_pickle:
                raise InputError(f"{what} is an object array: cannot read without pickle (only numeric arrays are allowed here)")
            if info.file_size > limit:
                raise InputError(f"{what} holds {human_bytes(info.file_size)} uncompressed "
                                 f"(limit {human_bytes(limit)}: limits.max_file_mb)")
            nbytes = math.prod(shape) * dtype.itemsize
            if not dtype.hasobject and offset + nbytes > info.file_size:
                raise InputError(f"{source}: corrupt or truncated array (its header declares {nbytes:,} bytes of "
                                 f"data, the member holds {max(0, info.file_size - offset):,})")
        return info.file_size

    def read(self, keys: Iterable[str] | None = None, allow_pickle: bool = True,
             total_limit: tuple[int, str] | None = None) -> dict[str, np.ndarray]:
        """The members ``keys`` (default all; absent keys are skipped) as arrays, all checked before any is read.

        total_limit: (bytes, config key) for the members' total; default ``limits.max_file_mb``.
        """
        wanted = list(self.members) if keys is None else [k for k in dict.fromkeys(keys) if k in self.members]
        limit, key_name = total_limit or (_limits.current().max_file_bytes, "limits.max_file_mb")
        try:
            total = sum(self._check(key, allow_pickle) for key in wanted)
            if total > limit:
                raise InputError(f"{self.path}: members total {human_bytes(total)} uncompressed "
                                 f"(limit {human_bytes(limit)}: {key_name})")
            out = {}
            for key in wanted:
                stream, info = self._open(key)
                with stream:
                    out[key] = _read_npy(stream, info.file_size, f"{self.path} ['{key}']", f"{self.path}: member '{key}'",
                                         allow_pickle)
            return out
        except _NPZ_ERRORS as exc:
            raise InputError(f"{self.path}: not a readable .npz file ({exc})") from None
        except OSError as exc:
            raise InputError(f"{self.path}: cannot read ({exc.strerror or exc})") from None


@contextmanager
def open_npz(path: str | Path) -> Iterator[NpzArchive]:
    """Open an ``.npz`` (zip directory only); InputError for missing files, non-zips, broken zips."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: file not found")
    if not path.is_file():
        raise InputError(f"{path}: expected a .npz file")
    try:
        if not zipfile.is_zipfile(path):
            raise InputError(f"{path}: not a valid .npz file (not a zip archive)")
        archive = zipfile.ZipFile(path)
    except _NPZ_ERRORS as exc:
        raise InputError(f"{path}: not a readable .npz file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    with archive:
        yield NpzArchive(path, archive)


def load_npz(path: str | Path, keys: Iterable[str] | None = None, allow_pickle: bool = True,
             total_limit: tuple[int, str] | None = None) -> dict[str, np.ndarray]:
    """Read the members ``keys`` (default: all) of an ``.npz`` file, every declared size checked
    first; object arrays go through the restricted unpickler (or are refused without ``allow_pickle``).
    total_limit: as :meth:`NpzArchive.read`."""
    with open_npz(path) as npz:
        return npz.read(keys, allow_pickle, total_limit)
