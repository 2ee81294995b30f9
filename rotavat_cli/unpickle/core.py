"""The restricted unpickler: every global a pickle asks for is looked up in the allow-list
(:data:`~rotavat_cli.unpickle.allowed.ALLOWED`, plus what a subclass adds in
:meth:`RestrictedUnpickler.find_extra_global`), and every opcode, every call that copies a
container and every array is counted or sized against the pickle's :class:`~.checks.Budget` before
it runs. joblib's array placeholders are replaced by the arrays whose bytes follow them.

It raises :class:`~.refusal.Refused` (and what malformed bytes raise); the readers above it turn
that into an error naming the file (:func:`~.refusal.unpickling_errors`).

>>> import io, pickle
>>> RestrictedUnpickler(io.BytesIO(pickle.dumps({"a": (1, 2.5)}))).load()
{'a': (1, 2.5)}
"""

from __future__ import annotations

import _compat_pickle
import math
import pickle
import struct
import sys
from collections import OrderedDict
from typing import Any, BinaryIO

import numpy as np

from .allowed import ALLOWED, JoblibArrayWrapper, codecs_encode, frombuffer, reconstructor
from .checks import TEXT, Budget, check_array, check_shape, invalid_text
from .dtypes import checked_dtype_state
from .refusal import Refused
from .streams import CHUNK, fill, read_up_to

__all__ = ["RestrictedUnpickler"]

_MAX_FRAME = 1 << 24  # pickle writes frames of about 64 KiB (pickle._Framer, _pickle.c FRAME_SIZE_TARGET)
_REFUSAL = "(only numpy arrays, numpy scalars and builtin containers are allowed)"
# Allowed types whose call (or __new__) copies its first argument: the copy is sized first, so
# ``list(range(10**9))``, ``tuple.__new__(tuple, range(...))`` or ``bytes(10**9)`` never run.
_COPYING = (list, tuple, set, frozenset, dict, OrderedDict)


class _CountingDispatch(dict):
    """The opcode table, counting each opcode run against the pickle's object budget."""

    __slots__ = ("budget",)

    def __getitem__(self, key: int) -> Any:
        budget = self.budget
        budget.items += 1
        if budget.items > budget.max_items:
            budget.add_items(1, "pickle")
        return dict.__getitem__(self, key)


class RestrictedUnpickler(pickle._Unpickler):  # noqa: SLF001 -- pure-Python unpickler: BUILD is overridable
    """Pure-Python unpickler with an allow-list ``find_class``, joblib's array placeholders and a
    budget: every opcode, every call that copies a container and every array is counted or sized
    before it runs (``limits``).

    ``raw`` is the stream unpickled (joblib's array bytes are read from it directly); ``budget`` is
    shared by every unpickler of one file."""

    dispatch = pickle._Unpickler.dispatch.copy()  # noqa: SLF001

    def __init__(self, file: BinaryIO, budget: Budget | None = None) -> None:
        super().__init__(file, encoding="latin1")
        self.raw = file
        self.budget = budget or Budget()
        self.dispatch = _CountingDispatch(type(self).dispatch)
        self.dispatch.budget = self.budget

    def find_class(self, module: str, name: str) -> Any:
        if self.proto < 3 and self.fix_imports:  # Python 2 names (e.g. __builtin__.set)
            if (module, name) in _compat_pickle.NAME_MAPPING:
                module, name = _compat_pickle.NAME_MAPPING[(module, name)]
            elif module in _compat_pickle.IMPORT_MAPPING:
                module = _compat_pickle.IMPORT_MAPPING[module]
        try:
            return ALLOWED[(module, name)]
        except (KeyError, TypeError):
            pass
        found = self.find_extra_global(module, name)
        if found is None:
            raise Refused(f"refused to unpickle global '{module}.{name}' {_REFUSAL}")
        return found

    def find_extra_global(self, module: str, name: str) -> Any:
        """A global beyond the allow-list, or None (refused). The core allows none; a subclass
        extends the allow-list here (torch's tensor builders: ``torch_files.TensorUnpickler``)."""
        return None

    def nested_unpickler(self) -> RestrictedUnpickler:
        """An unpickler of this kind on the same stream and budget, for a pickle inside the pickle
        (joblib writes an object array as a plain pickle after its placeholder)."""
        return RestrictedUnpickler(self.raw, self.budget)

    def persistent_load(self, pid: Any) -> Any:
        raise Refused("refused a persistent id (pickles that reference external objects are not allowed)")

    # -- calls: size what a call would copy before making it
    def _check_call(self, func: Any, args: Any) -> None:
        if not isinstance(args, tuple):
            raise Refused("malformed call arguments")
        if func is np.ndarray:
            raise Refused("numpy.ndarray may not be called directly (arrays are rebuilt with _reconstruct)")
        if func is reconstructor and len(args) >= 3 and args[2] is not None:
            self._check_call(args[1], (args[2],))
        elif func is frombuffer and args and isinstance(args[0], (bytes, bytearray)):
            self.budget.add_data(2 * len(args[0]))  # copied, then copied into the array
        elif func is codecs_encode and args and isinstance(args[0], str):
            self.budget.add_data(len(args[0]))
        if not args or not isinstance(func, type):
            return
        name = getattr(func, "__name__", "call")
        if issubclass(func, TEXT):
            if not isinstance(args[0], TEXT):  # str(a list) or bytes(10**9) would expand or allocate
                raise Refused(f"{name}() of a {type(args[0]).__name__} is not allowed")
            self.budget.add_data(len(args[0]))
        elif issubclass(func, _COPYING):
            try:
                n = len(args[0])
            except TypeError:  # not a container: the call raises TypeError itself, or copies nothing
                return
            except OverflowError:
                n = sys.maxsize
            self.budget.add_items(n, f"{name}()")

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
            raise Refused("malformed call arguments")
        self._check_call(cls, args)
        self.append(cls.__new__(cls, *args, **kwargs))

    dispatch[pickle.NEWOBJ_EX[0]] = load_newobj_ex

    def _instantiate(self, klass: Any, args: list) -> None:  # INST and OBJ
        self._check_call(klass, tuple(args))
        super()._instantiate(klass, args)

    def load_bytearray8(self) -> None:
        """BYTEARRAY8 allocates its announced size before reading: read the bytes that are there first."""
        (size,) = struct.unpack("<Q", self.read(8))
        data = read_up_to(self.read, size)
        if len(data) < size:
            raise Refused(f"truncated pickle (a bytearray of {size:,} bytes announced)")
        self.budget.add_data(size)
        self.append(bytearray(data))

    dispatch[pickle.BYTEARRAY8[0]] = load_bytearray8

    def load_frame(self) -> None:
        """A FRAME is read whole before its opcodes run: one larger than any pickler writes is refused unread."""
        (size,) = struct.unpack("<Q", self.read(8))
        if size > _MAX_FRAME:
            raise Refused(f"malformed pickle (a frame of {size:,} bytes; pickle writes frames of about 64 KiB)")
        self._unframer.load_frame(size)

    dispatch[pickle.FRAME[0]] = load_frame

    def load_build(self) -> None:
        state, inst = self.stack[-1], self.stack[-2]
        if callable(inst):  # a class or function of the allow-list: never give it attributes
            raise Refused(f"malformed pickle (BUILD on {getattr(inst, '__name__', 'a callable')})")
        if isinstance(inst, np.ndarray):
            self._check_array_state(state)
        elif isinstance(inst, np.dtype):  # numpy trusts a dtype's state: give it the one numpy makes (dtypes.py)
            self.stack[-1] = checked_dtype_state(inst, state)
        super().load_build()
        if isinstance(self.stack[-1], JoblibArrayWrapper):
            self.stack[-1] = self._read_joblib_array(self.stack[-1])
        if isinstance(self.stack[-1], np.ndarray) and invalid_text(self.stack[-1]):
            raise Refused("an array holds invalid text (a code point beyond U+10FFFF)")

    dispatch[pickle.BUILD[0]] = load_build

    def _check_array_state(self, state: Any) -> None:
        """``ndarray.__setstate__`` allocates (and zeroes) the declared shape: size it first."""
        if not isinstance(state, tuple) or len(state) not in (4, 5):
            raise Refused("malformed ndarray state")
        shape, dtype, _fortran, raw = state[-4:]
        if not isinstance(dtype, np.dtype):
            raise Refused("malformed ndarray state")
        shape = check_shape(shape, "ndarray")
        count = math.prod(shape)
        if count * max(1, 8 if dtype.hasobject else dtype.itemsize) > self.budget.max_array:
            check_array(dtype, shape)
        if dtype.hasobject:
            if not isinstance(raw, list) or len(raw) != count:
                raise Refused("object array data does not match its shape")
            self.budget.add_items(count, "object array")
            return
        try:
            size = len(raw) if isinstance(raw, str) else memoryview(raw).nbytes
        except TypeError:
            raise Refused("malformed ndarray state") from None
        if size != count * dtype.itemsize:
            raise Refused("array data does not match its shape")
        self.budget.add_data(size)

    def _read_joblib_array(self, wrapper: JoblibArrayWrapper) -> np.ndarray:
        """Raw array bytes that joblib writes right after the placeholder."""
        if not hasattr(wrapper, "dtype"):
            raise Refused("malformed joblib array wrapper")
        check_array(wrapper.dtype, wrapper.shape)
        if wrapper.dtype.hasobject:  # joblib pickles object arrays with plain pickle (protocol 2)
            array = self.nested_unpickler().load()
            if not isinstance(array, np.ndarray):
                raise Refused("joblib object array is not an array")
            return array
        if wrapper.alignment is not None:
            pad = self.raw.read(1)
            if len(pad) != 1:
                raise Refused("truncated joblib array")
            self.raw.read(pad[0])
        count = math.prod(wrapper.shape)
        nbytes = count * wrapper.dtype.itemsize
        if nbytes <= CHUNK:  # one read (the usual small array): it holds what is there, at most a chunk
            raw = self.raw.read(nbytes)
            got = len(raw)
            array = np.frombuffer(raw, wrapper.dtype, count).copy() if got == nbytes else None
        else:  # memory is taken as the bytes arrive, never for what is missing
            array = np.empty(count, wrapper.dtype)
            got = fill(self.raw.read, array.view(np.uint8))
        if got < nbytes:
            raise Refused(f"truncated joblib array ({nbytes} bytes announced, {got} left)")
        self.budget.add_data(nbytes)
        if wrapper.order == "F":
            return array.reshape(wrapper.shape[::-1]).transpose().copy()
        return array.reshape(wrapper.shape)
