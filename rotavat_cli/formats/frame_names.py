"""Contract frame names from a tool's image names, and the natural sort order of file names."""

from __future__ import annotations

import re

__all__ = ["frame_names", "natural_key"]


def frame_names(sources: list[str], warnings: list[str]) -> list[str]:
    """Contract frame names from the tool's image stems (no extension), in the tool's (time) order.

    The image stem is kept (characters outside ``[A-Za-z0-9._-]`` become ``_``) so sequences
    imported from two tools run on the same images line up frame by frame in ``eval``. When stems
    repeat, or sorting them by name would not give the tool's order (``img_2`` after ``img_10``),
    names become ``<zero-padded index>_<stem>`` instead (order kept, cross-tool matching lost).
    """
    stems = [re.sub(r"[^A-Za-z0-9._-]", "_", str(s)) or "frame" for s in sources]
    if len(set(stems)) == len(stems) and stems == sorted(stems) and not any(s.startswith(".") for s in stems):
        return stems
    width = max(6, len(str(len(stems))))
    warnings.append("frame names are the image names prefixed by their index (the image names repeat or do not "
                    "sort in time order)")
    return [f"{i:0{width}d}_{stem.lstrip('.')}" for i, stem in enumerate(stems)]


def natural_key(name: str) -> tuple:
    """Sort key that orders 'img_2' before 'img_10'."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name))
