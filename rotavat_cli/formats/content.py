"""What a tool's loaded file holds, checked: numeric arrays of the expected shape (:func:`as_array`)
and mapping keys (:func:`get`); each failure an InputError naming the file and the key."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import file_error

__all__ = ["as_array", "get"]


def as_array(obj: Any, name: str, source: Any, ndim: int | None = None, last: tuple[int, ...] | None = None,
             kinds: str = "fiu") -> np.ndarray:
    """Validate ``obj`` as a numeric ndarray (float64 copy for floats); InputError naming ``name``."""
    if isinstance(obj, (list, tuple)):
        try:
            obj = np.asarray(obj)
        except (ValueError, TypeError):
            raise file_error(source, f"'{name}' is not a numeric array") from None
    if not isinstance(obj, np.ndarray) or obj.dtype.kind not in kinds:
        got = obj.dtype if isinstance(obj, np.ndarray) else type(obj).__name__
        raise file_error(source, f"'{name}' must be a numeric array, got {got}")
    if ndim is not None and obj.ndim != ndim:
        raise file_error(source, f"'{name}' must have {ndim} dimensions, got shape {list(obj.shape)}")
    if last is not None and obj.shape[obj.ndim - len(last):] != last:
        raise file_error(source, f"'{name}' must end with shape {list(last)}, got {list(obj.shape)}")
    return obj.astype(np.float64) if obj.dtype.kind == "f" else obj


def get(mapping: Any, key: str, source: Any, required: bool = True) -> Any:
    """``mapping[key]`` with InputErrors for non-mappings and missing keys."""
    if not isinstance(mapping, Mapping):
        raise file_error(source, f"expected a dict of results, got {type(mapping).__name__}")
    if key not in mapping:
        if required:
            raise file_error(source, f"missing key '{key}'")
        return None
    return mapping[key]
