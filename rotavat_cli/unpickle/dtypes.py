"""Pickled numpy dtypes: the state a pickle gives a dtype is never handed to numpy as it stands.

numpy pickles a dtype as ``numpy.dtype(typestr, align, copy)`` then ``BUILD`` with the state
``(version, endian, subarray, names, fields, elsize, alignment, flags[, metadata])``.
``dtype.__setstate__`` trusts that state: a hostile one makes numpy crash the process (a 6-item
version-3 tuple on an ``int32`` dtype is a segmentation fault in numpy 2.4), or describe fields
and flags that do not match the bytes. Here the state is read for what it describes (the byte order,
the sub-array, the fields with their offsets and titles, datetime units, metadata) and that dtype is
built with numpy's public constructor, which checks it; the dtype being built then gets the state
numpy itself pickles for the result, and only when it is of the same type (``typestr``). The flags
and sizes the pickle states are never used.

>>> import numpy as np
>>> record = np.dtype([("x", "<f4"), ("n", "<i8")])
>>> checked_dtype_state(np.dtype("V12"), record.__reduce__()[2]) == record.__reduce__()[2]
True
>>> checked_dtype_state(np.dtype("i4"), (3, "<", None, -1, -1, 0))
Traceback (most recent call last):
...
rotavat_cli.unpickle.refusal.Refused: malformed dtype state
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .refusal import Refused

__all__ = ["checked_dtype_state", "typestr"]

_ALIGNED_STRUCT = 0x80  # NPY_ALIGNED_STRUCT: the dtype was made with align=True


def _int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _text(value: Any) -> str:
    """A name as a Python 2 pickle may give it (bytes) or a Python 3 one (str)."""
    if isinstance(value, bytes):
        return value.decode("latin1")
    if not isinstance(value, str):
        raise Refused("malformed dtype state (a name is not text)")
    return value


def typestr(dtype: np.dtype) -> str:
    """The type string numpy pickles a dtype with (``'f8'``, ``'U5'``, ``'V12'``, ``'M8'``)."""
    return dtype.__reduce__()[1][0]


def _subarray(subarray: Any) -> np.dtype:
    if not (isinstance(subarray, tuple) and len(subarray) == 2 and isinstance(subarray[0], np.dtype)
            and isinstance(subarray[1], tuple) and all(_int(n) and n >= 0 for n in subarray[1])):
        raise Refused("malformed dtype state (sub-array)")
    return np.dtype((subarray[0], subarray[1]))


def _structured(names: Any, fields: Any, elsize: int, aligned: bool) -> np.dtype:
    if not isinstance(names, tuple) or not isinstance(fields, dict):
        raise Refused("malformed dtype state (fields)")
    formats, offsets, titles = [], [], []
    for name in names:
        entry = fields.get(name) if isinstance(name, (str, bytes)) else None
        if not (isinstance(entry, tuple) and len(entry) in (2, 3) and isinstance(entry[0], np.dtype)
                and _int(entry[1])):
            raise Refused("malformed dtype state (fields)")
        formats.append(entry[0])
        offsets.append(entry[1])
        titles.append(None if len(entry) == 2 or entry[2] is None else _text(entry[2]))
    spec = {"names": [_text(n) for n in names], "formats": formats, "offsets": offsets, "itemsize": elsize}
    if any(t is not None for t in titles):
        spec["titles"] = titles
    return np.dtype(spec, align=aligned)


def _datetime(code: str, metadata: Any) -> np.dtype:
    """``M8`` / ``m8`` with the unit numpy keeps in the state's metadata:
    ``(dict or None, (unit, num, den, events))``."""
    if not (isinstance(metadata, tuple) and len(metadata) == 2 and isinstance(metadata[1], tuple)
            and len(metadata[1]) == 4 and (metadata[0] is None or isinstance(metadata[0], dict))):
        raise Refused("malformed dtype state (datetime unit)")
    unit, num = _text(metadata[1][0]), metadata[1][1]
    if not (_int(num) and num > 0) or not unit.isalpha():
        raise Refused("malformed dtype state (datetime unit)")
    described = np.dtype(code if unit == "generic" else f"{code}[{num}{unit}]")
    return np.dtype(described, metadata=metadata[0]) if metadata[0] else described


def checked_dtype_state(dtype: np.dtype, state: Any) -> tuple:
    """The state to give ``dtype`` at ``BUILD``: what numpy pickles for the dtype ``state`` describes,
    built by numpy's constructor; Refused when ``state`` is malformed or describes another type."""
    if not isinstance(state, tuple) or len(state) not in (8, 9) or state[0] != len(state) - 5:
        raise Refused("malformed dtype state")
    endian, subarray, names, fields, elsize, alignment, flags = state[1:8]
    metadata = state[8] if len(state) == 9 else None
    if endian not in ("<", ">", "|", "=") or not all(_int(v) for v in (elsize, alignment, flags)):
        raise Refused("malformed dtype state")
    code = typestr(dtype)
    if subarray is not None:
        described = _subarray(subarray)
    elif names is not None or fields is not None:
        described = _structured(names, fields, elsize, bool(flags & _ALIGNED_STRUCT))
    elif code in ("M8", "m8"):
        described, metadata = _datetime(code, metadata), None
    else:
        described = np.dtype(code)
    if metadata is not None:
        if not isinstance(metadata, dict):
            raise Refused("malformed dtype state (metadata)")
        described = np.dtype(described, metadata=metadata)
    if endian in "<>" and described.byteorder not in ("|", endian):
        described = described.newbyteorder(endian)
    if typestr(described) != code:
        raise Refused(f"malformed dtype state (it describes a {typestr(described)}, not a {code})")
    return described.__reduce__()[2]
