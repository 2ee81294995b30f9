"""The readers of every tool, by format name (trimesh's loader registry), and which format a file is.

Each per-tool module exports ``READERS = {"name": read_name}`` and a ``sniff(path) -> name | None``;
this module merges the tables (:data:`READERS`, :func:`available_formats`) and asks the sniffers
which format a file or directory looks like (:func:`detect_format`, :func:`other_format`). A new
tool's module is added to ``_MODULES`` here and its name to :data:`.tools.TOOL_NAMES`.
"""

from __future__ import annotations

import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import InputError
from . import (agora, bedlam, bev, cliff, comotion, fourdhumans, glamr, gvhmr, hybrik, multihmr, prompthmr, pymafx,
               slahmr, spec, tram, trace, wham)
from .imported import ImportedSequence, ImportOptions
from .tools import FORMATS

__all__ = ["READERS", "available_formats", "detect_format", "other_format"]

_MODULES = (cliff, bev, fourdhumans, multihmr, spec, agora, bedlam, wham, gvhmr, tram, hybrik, pymafx, slahmr, glamr, trace,
            comotion, prompthmr)
READERS: dict[str, Callable[[Path, ImportOptions], ImportedSequence]] = {}
for _module in _MODULES:
    READERS.update(_module.READERS)
if tuple(sorted(READERS)) != FORMATS:  # messages name each tool and list the formats from .tools
    raise RuntimeError(f"rotavat_cli.formats.tools.TOOL_NAMES must name every reader: {sorted(READERS)}")


def available_formats() -> list[str]:
    """Names accepted by ``--from``."""
    return sorted(READERS)


_MODULE_OF = {name: module for module in _MODULES for name in module.READERS}
# What a sniffer meets in a file of another format (or a damaged one): "not mine", never an error.
_SNIFF_ERRORS = (InputError, OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, EOFError,
                 zipfile.BadZipFile, RecursionError, OverflowError, MemoryError, SystemError, UnicodeError)


def _sniffed(module: Any, path: Path) -> str | None:
    try:
        return module.sniff(path) or None
    except _SNIFF_ERRORS:
        return None


def detect_format(path: str | Path) -> str | None:
    """Guess the format of a file or directory from its names and keys (None if unknown)."""
    path = Path(path)
    if not path.exists():
        return None
    for module in _MODULES:
        found = _sniffed(module, path)
        if found:
            return found
    return None


def other_format(path: str | Path, fmt: str) -> str | None:
    """The format ``path`` looks like when it is not ``fmt``'s (what ``--from fmt`` failed on): the one
    :func:`detect_format` finds, unless ``fmt``'s own sniffer recognises the file (then the failure is the
    file's, not the choice of reader); None when nothing recognises it."""
    path = Path(path)
    module = _MODULE_OF.get(fmt)
    if module is None or not path.exists() or _sniffed(module, path) == fmt:
        return None
    found = detect_format(path)
    return found if found != fmt else None
