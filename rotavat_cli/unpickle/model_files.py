"""The official SMPL-family model pickles (``basicModel_neutral_lbs_10_207_0_v1.0.0.pkl``,
``SMPL_NEUTRAL.pkl``, ``SMPLH_male.pkl``, ``SMPLX_NEUTRAL.pkl``) read without chumpy and scipy.

MPI released these models as Python 2 pickles (smpl_webuser ``serialization.save_model``:
``pickle.dump(model_dict, f, -1)``, protocol 2; strings are read as latin-1) of a dict whose values
are numpy arrays, strings, and two kinds of objects, each pickled as an empty instance of its class
(``NEWOBJ`` with no arguments, or ``copy_reg._reconstructor(cls, object, None)`` in protocols 0-1)
followed by ``BUILD`` with its state:

- ``chumpy.ch.Ch`` (``v_template``, ``shapedirs``, ``posedirs``, ``weights``, ``J``, ... depending on
  the file): the state is ``Ch.__getstate__()``, the object's ``__dict__`` less its weak caches
  (mattloper/chumpy ``ch.py``), whose key ``x`` holds the value as a numpy array (``_dirty_vars``,
  ``_itr``, ``_make_dense``, ``_depends_on_deps`` are bookkeeping);
- ``scipy.sparse`` ``csc_matrix`` (``J_regressor``, ``J_regressor_prior``; csr too): the state is
  the ``__dict__``, ``data``, ``indices``, ``indptr`` and the shape (``_shape``; ``shape`` in old
  scipy), plus bookkeeping (``maxprint``, ``format``). The class is ``scipy.sparse.csc`` in the
  released files, ``scipy.sparse._csc`` in pickles written by scipy >= 1.8 (e.g. re-saved by
  ``vchoutas/smplx`` ``tools/clean_ch.py``, which keeps the sparse matrices).

:class:`ModelUnpickler` is the restricted unpickler (:mod:`~rotavat_cli.unpickle.core`) plus
those class names, each mapped to an inert :class:`~.allowed.StandIn`: at ``BUILD`` the stand-in
is replaced (on the stack and in the memo) by a numpy array made from its state alone: a ``Ch`` by
its numeric ``x``; a sparse matrix by the dense array it stands for, its declared size checked
against ``limits.max_array_mb`` and the pickle's budget before anything is allocated, its index
arrays checked before they are used. No chumpy or scipy class is imported or built, nothing of the
file runs; any other class (a chumpy operation such as ``chumpy.ch_ops.add``, ``os.system``) is
refused, as for every pickle.

>>> import pickle
>>> value = pickle.dumps(np.arange(3.0), protocol=2)[2:-1]  # an array's opcodes
>>> ch = b"\\x80\\x02cchumpy.ch\\nCh\\n)\\x81}X\\x01\\x00\\x00\\x00x" + value + b"sb."  # Ch() with {'x': value}
>>> loads_model(ch, "model.pkl")
array([0., 1., 2.])
>>> loads_model(b"\\x80\\x02cchumpy.ch_ops\\nadd\\n)\\x81.", "model.pkl")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: model.pkl: refused to unpickle global 'chumpy.ch_ops.add' (only numpy arrays, numpy scalars, builtin containers, chumpy.ch.Ch and scipy csc/csr matrices are allowed in a model file)
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from ..errors import InputError
from .allowed import StandIn
from .checks import Budget, array_refusal, check_shape
from .core import RestrictedUnpickler
from .expansion import check_expansion
from .pickles import decompressed
from .refusal import Refused, unpickling_errors
from .streams import INFLATE_CHUNK, Stream, read_bytes

__all__ = ["MODEL_GLOBALS", "ModelUnpickler", "load_model_pickle", "loads_model"]

_NUMERIC = "biuf"  # dtype kinds a model array may have
_REFUSAL = ("(only numpy arrays, numpy scalars, builtin containers, chumpy.ch.Ch and scipy csc/csr matrices are "
            "allowed in a model file)")


def _what(value: Any) -> str:
    """'a float64 array', 'an object array', 'a dict' ... for messages."""
    what = f"{value.dtype} array" if isinstance(value, np.ndarray) else type(value).__name__
    return f"{'an' if what[0] in 'aeiou' else 'a'} {what}"


class ChumpyArray(StandIn):
    """Stands in for a ``chumpy.ch.Ch``: becomes its value ``x`` (a numeric numpy array)."""

    __slots__ = ()

    @staticmethod
    def build(state: Any, budget: Budget) -> np.ndarray:
        """The array a ``Ch`` holds, from its pickled ``__dict__``."""
        if not isinstance(state, dict) or "x" not in state:
            raise Refused("malformed chumpy array (a Ch's state holds its value under 'x')")
        value = state["x"]
        if not isinstance(value, np.ndarray) or value.dtype.kind not in _NUMERIC:
            raise Refused(f"malformed chumpy array ('x' is {_what(value)}, not a numeric numpy array)")
        return value


def _sparse_shape(state: dict) -> tuple[int, int]:
    """The declared (rows, cols) of a pickled sparse matrix."""
    shape = state.get("_shape", state.get("shape"))
    if isinstance(shape, tuple):
        shape = tuple(int(s) if isinstance(s, np.integer) else s for s in shape)
    shape = check_shape(shape, "sparse matrix")
    if len(shape) != 2:
        raise Refused(f"malformed sparse matrix shape ({len(shape)} dimensions)")
    return shape


def _sparse_part(state: dict, key: str, kinds: str) -> np.ndarray:
    """One of a sparse matrix's 1-D arrays (``data``, ``indices``, ``indptr``)."""
    value = state.get(key)
    if not isinstance(value, np.ndarray) or value.ndim != 1 or value.dtype.kind not in kinds:
        raise Refused(f"malformed sparse matrix ('{key}' is {_what(value)})")
    return value


class SparseMatrix(StandIn):
    """Stands in for a scipy compressed sparse matrix: becomes the dense array it stands for (entries
    given twice are summed, as ``toarray`` does). ``axis``: 1 for csc (``indptr`` runs over the
    columns), 0 for csr."""

    __slots__ = ()
    axis = 1
    kind = "csc"

    @classmethod
    def build(cls, state: Any, budget: Budget) -> np.ndarray:
        """The dense array of a pickled ``__dict__``; its size checked before it is made."""
        if not isinstance(state, dict):
            raise Refused(f"malformed sparse {cls.kind} matrix state")
        shape = _sparse_shape(state)
        data = _sparse_part(state, "data", _NUMERIC)
        why = array_refusal(data.dtype, shape)
        if why is not None:
            raise Refused(f"sparse {cls.kind} matrix {why}")
        indices = _sparse_part(state, "indices", "iu").astype(np.int64)
        indptr = _sparse_part(state, "indptr", "iu").astype(np.int64)
        n_major, n_minor = shape[cls.axis], shape[1 - cls.axis]
        if indptr.size != n_major + 1 or indices.size != data.size:
            raise Refused(f"malformed sparse {cls.kind} matrix (indptr of {indptr.size}, indices of {indices.size} "
                          f"and data of {data.size} for shape {shape})")
        nnz = int(indptr[-1])
        if indptr[0] != 0 or np.any(np.diff(indptr) < 0) or nnz > data.size:
            raise Refused(f"malformed sparse {cls.kind} matrix (indptr is not a running count of its entries)")
        indices, values = indices[:nnz], data[:nnz]
        if nnz and (indices.min() < 0 or indices.max() >= n_minor):
            raise Refused(f"malformed sparse {cls.kind} matrix (an index is outside its {n_minor} rows/columns)")
        budget.add_data(math.prod(shape) * data.dtype.itemsize)
        dense = np.zeros(shape, data.dtype)
        major = np.repeat(np.arange(n_major), np.diff(indptr))
        np.add.at(dense, (indices, major) if cls.axis == 1 else (major, indices), values)
        return dense


class CsrMatrix(SparseMatrix):
    """Stands in for a scipy ``csr_matrix``: ``indptr`` runs over the rows."""

    __slots__ = ()
    axis = 0
    kind = "csr"


def _model_globals() -> dict[tuple[str, str], type[StandIn]]:
    """(module, name) -> stand-in: chumpy's array and scipy's compressed matrices under the module
    names scipy has used (``scipy.sparse.csc`` up to 1.7, ``scipy.sparse._csc`` from 1.8; the
    ``*_array`` classes from 1.8)."""
    table: dict[tuple[str, str], type[StandIn]] = {("chumpy.ch", "Ch"): ChumpyArray}
    for fmt, stand_in in (("csc", SparseMatrix), ("csr", CsrMatrix)):
        for module in (f"scipy.sparse.{fmt}", f"scipy.sparse._{fmt}"):
            table[(module, f"{fmt}_matrix")] = stand_in
        table[(f"scipy.sparse._{fmt}", f"{fmt}_array")] = stand_in
    return table


MODEL_GLOBALS = _model_globals()


class _Memo(dict):
    """The unpickler's memo, noting where it keeps a stand-in, so that ``BUILD`` replaces it there too."""

    def __init__(self) -> None:
        super().__init__()
        self.stand_ins: dict[int, list[Any]] = {}  # id(stand-in) -> memo keys

    def __setitem__(self, key: Any, value: Any) -> None:
        if isinstance(value, StandIn):
            self.stand_ins.setdefault(id(value), []).append(key)
        dict.__setitem__(self, key, value)

    def replace(self, stand_in: StandIn, value: Any) -> None:
        for key in self.stand_ins.pop(id(stand_in), ()):
            if dict.get(self, key) is stand_in:
                dict.__setitem__(self, key, value)


class ModelUnpickler(RestrictedUnpickler):
    """The restricted unpickler plus chumpy's ``Ch`` and scipy's csc/csr matrices, each rebuilt as a
    numpy array from its pickled state (:data:`MODEL_GLOBALS`)."""

    dispatch = RestrictedUnpickler.dispatch.copy()

    def __init__(self, file: BinaryIO, budget: Budget | None = None) -> None:
        super().__init__(file, budget)
        self.memo = _Memo()

    def find_class(self, module: str, name: str) -> Any:
        try:
            return super().find_class(module, name)
        except Refused:
            raise Refused(f"refused to unpickle global '{module}.{name}' {_REFUSAL}") from None

    def find_extra_global(self, module: str, name: str) -> Any:
        if (module, name) == ("builtins", "object"):  # protocols 0-1: copy_reg._reconstructor(Ch, object, None)
            return object
        return MODEL_GLOBALS.get((module, name))

    def nested_unpickler(self) -> ModelUnpickler:
        return ModelUnpickler(self.raw, self.budget)

    def load_build(self) -> None:
        """``BUILD`` on a stand-in: the array made from the state replaces it, on the stack and in the memo."""
        stand_in = self.stack[-2] if len(self.stack) >= 2 else None
        if not isinstance(stand_in, StandIn):
            super().load_build()
            return
        state = self.stack.pop()
        array = type(stand_in).build(state, self.budget)
        self.stack[-1] = array
        self.memo.replace(stand_in, array)

    dispatch[pickle.BUILD[0]] = load_build


def loads_model(data: bytes, source: str) -> Any:
    """Unpickle a model file's bytes with :class:`ModelUnpickler` (a plain pickle of any protocol, or
    joblib's, any compression); every failure is one line naming ``source``."""
    stream = decompressed(data, source)
    with unpickling_errors(source):
        value = ModelUnpickler(stream).load()
        if isinstance(stream, Stream):  # a compressed stream's checksum and size are checked at its end
            while stream.read(INFLATE_CHUNK):
                pass
        check_expansion(value)
        return value


def load_model_pickle(path: str | Path) -> Any:
    """Unpickle a ``.pkl`` body-model file (Python 2 files included: :func:`loads_model`)."""
    path = Path(path)
    data = read_bytes(path)
    if not data:
        raise InputError(f"{path}: empty file")
    return loads_model(data, str(path))
