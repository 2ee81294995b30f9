"""Checks made before anything is allocated: the size an array declares (``limits.max_array_mb``),
its shape, the text it holds, and the :class:`Budget` of one pickle (objects and bytes it builds,
``limits.max_pickle_items`` and ``limits.max_file_mb``).

>>> array_bytes(np.dtype("<f4"), (1000, 3))
12000
>>> array_refusal(np.dtype("<f4"), (1000, 3)) is None
True
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from ..settings import limits as _limits
from ..settings.limits import human_bytes
from .refusal import Refused

__all__ = ["TEXT", "Budget", "array_bytes", "array_refusal", "check_array", "check_shape", "invalid_text"]

TEXT = (str, bytes, bytearray)  # types whose size is their length


def array_bytes(dtype: np.dtype, shape: tuple[int, ...]) -> int:
    """Bytes an array of ``shape`` takes (a reference per element for object arrays; at least one
    byte per element, so zero-size dtypes cannot declare billions of elements for free)."""
    return math.prod(shape) * max(1, 8 if dtype.hasobject else dtype.itemsize)


def array_refusal(dtype: np.dtype, shape: tuple[int, ...]) -> str | None:
    """Why an array of this dtype and shape is refused (``limits.max_array_mb``), or None."""
    nbytes, limit = array_bytes(dtype, shape), _limits.current().max_array_bytes
    if nbytes <= limit:
        return None
    return f"declares {human_bytes(nbytes)} ({dtype} {tuple(shape)}; limit {human_bytes(limit)}: limits.max_array_mb)"


def check_shape(shape: Any, what: str) -> tuple[int, ...]:
    """``shape`` as a tuple of non-negative ints, or Refused."""
    if not isinstance(shape, tuple) or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape):
        raise Refused(f"malformed {what} shape")
    return shape


def check_array(dtype: np.dtype, shape: tuple[int, ...]) -> None:
    """Refused when the declared array is over ``limits.max_array_mb``."""
    why = array_refusal(dtype, shape)
    if why is not None:
        raise Refused(f"array {why}")


def invalid_text(array: np.ndarray) -> bool:
    """Whether a unicode array holds a code point beyond U+10FFFF (numpy reads those into broken strs:
    SystemError once the text is used), wherever the array was read from (npy, pickle)."""
    if array.dtype.kind != "U" or not array.size:
        return False
    return int(np.frombuffer(array.tobytes(), array.dtype.str[0] + "u4").max()) > sys.maxunicode


class Budget:
    """What one pickle may build: objects (every opcode run, every item a container is built from)
    and bytes of data (arrays, bytes and strings made by calls), against the limits in force."""

    def __init__(self) -> None:
        lim = _limits.current()
        self.max_items, self.max_data, self.max_array = lim.max_pickle_items, lim.max_file_bytes, lim.max_array_bytes
        self.items = self.data = 0

    def add_items(self, n: int, what: str) -> None:
        self.items += n
        if self.items > self.max_items:
            raise Refused(f"{what} would build {n:,} items (limit {self.max_items:,}: limits.max_pickle_items)"
                          if n > self.max_items else
                          f"pickle builds more than {self.max_items:,} objects (limits.max_pickle_items)")

    def add_data(self, nbytes: int) -> None:
        self.data += nbytes
        if self.data > self.max_data:
            raise Refused(f"pickle builds more than {human_bytes(self.max_data)} of arrays and strings "
                          f"(limit: limits.max_file_mb)")
