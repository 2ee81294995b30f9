"""Shared references: the items an unpickled object makes when fully converted, checked against
``limits.max_pickle_items`` (a list referenced 1,000 times is converted 1,000 times).

>>> row = list(range(10))
>>> expansion([row, row, row])
(34, 15)
"""

from __future__ import annotations

import itertools
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..settings import limits as _limits
from .checks import TEXT
from .refusal import Refused

__all__ = ["check_expansion", "expansion"]


def _leaf_weight(obj: Any) -> tuple[int, int] | None:
    """(expanded, held) items of an object that is not walked into; None for containers."""
    if isinstance(obj, np.ndarray):
        return None if obj.dtype.hasobject else (max(1, obj.size), max(1, obj.size))
    if isinstance(obj, (list, tuple, set, frozenset, dict)):
        return None
    if isinstance(obj, TEXT):
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


def expansion(root: Any) -> tuple[int, int]:
    """(expanded, held): items a full conversion of ``root`` makes (to_plain, np.asarray, str: a shared
    object once per reference) and items the unpickled objects hold (each object once).

    Iterative (no recursion limit), linear in what is held; Refused on a reference cycle.
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
                raise Refused("pickle contains a reference cycle")
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


def check_expansion(obj: Any) -> None:
    """Refused when shared references would add more than ``max_pickle_items`` items on conversion."""
    expanded, held = expansion(obj)
    limit = _limits.current().max_pickle_items
    if expanded - held > limit:
        raise Refused(f"shared references expand the pickle to {expanded:,} items, {expanded - held:,} more than it "
                      f"holds (limit {limit:,} more: limits.max_pickle_items)")
