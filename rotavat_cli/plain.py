"""Plain, JSON/YAML-safe values: numpy arrays and scalars to lists and floats, NaN to None."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .settings.limits import current

__all__ = ["to_plain", "csv_cell"]


def csv_cell(value: Any) -> str:
    """The text of a CSV cell rotavat writes: floats with 6 significant digits, NaN and inf empty.

    >>> [csv_cell(v) for v in (1 / 3, float("nan"), 7, "a")]
    ['0.333333', '', '7', 'a']
    """
    if isinstance(value, (float, np.floating)):
        return "" if not math.isfinite(value) else f"{value:.6g}"
    return str(value)


def to_plain(value: Any, max_items: int | None = None) -> Any:
    """Recursively convert to plain Python types (NaN and inf become None).

    The conversion visits at most ``max_items`` values (default ``limits.max_pickle_items``; an
    array counts its size): a structure that shares one list many times (as unpickled data can)
    would otherwise expand into a copy per reference. Past it: InputError.

    >>> to_plain({"a": np.float32(1.5), "b": np.array([1, 2]), "c": float("nan")})
    {'a': 1.5, 'b': [1, 2], 'c': None}
    """
    if max_items is None:
        max_items = current().max_pickle_items
    return _plain(value, [max_items], max_items)


def _plain(value: Any, left: list[int], limit: int) -> Any:
    """to_plain with ``left[0]`` values still allowed."""
    left[0] -= value.size if isinstance(value, np.ndarray) else 1
    if left[0] < 0:
        raise InputError(f"value to convert has more than {limit:,} items (limit: limits.max_pickle_items)")
    if isinstance(value, dict):
        return {str(k): _plain(v, left, limit) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v, left, limit) for v in value]
    if isinstance(value, np.ndarray):
        left[0] += value.size  # counted above; its elements are counted again one by one below
        return _plain(value.tolist(), left, limit)
    if isinstance(value, np.generic):
        return _plain(value.item(), left, limit)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value
