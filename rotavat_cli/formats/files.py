"""Finding a tool's result file: an npz's keys read from its zip index, and the one file of a directory
that a tool's sniffer recognises."""

from __future__ import annotations

import zipfile
from collections.abc import Callable
from pathlib import Path

from ..errors import file_error

__all__ = ["npz_has_keys", "single_file"]


def npz_has_keys(path: Path, keys: set[str]) -> bool:
    """True for an .npz file holding at least ``keys`` (read from the zip index, no arrays loaded)."""
    if not (path.is_file() and path.suffix == ".npz"):
        return False
    with zipfile.ZipFile(path) as archive:
        return keys <= {n[:-4] for n in archive.namelist()}


def single_file(src: Path, sniff: Callable[[Path], str | None], what: str, hint: str = "") -> Path:
    """``src`` itself, or the one file in directory ``src`` that ``sniff`` recognises."""
    if src.is_file():
        return src
    candidates = [p for p in sorted(src.glob("*.npz")) if sniff(p)]
    if len(candidates) != 1:
        raise file_error(src, f"expected one {what} in the directory, found {len(candidates)}{hint}")
    return candidates[0]
