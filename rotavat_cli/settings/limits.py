"""Size limits on what a file may make rotavat allocate (the ``limits:`` section of the config).

Small hostile files can declare huge things: a 3 MB zip member that inflates to 4 GB, an ``.npy``
header announcing a 48 GB array, a 78-byte pickle calling ``list(range(400_000_000))``, a pickle
whose shared references expand a thousandfold when converted. Every reader checks the *declared*
size against these limits before allocating, and refuses with an
:class:`~rotavat_cli.errors.InputError` naming the file, the number and the config key.

The defaults (``configs/default.yaml``) are proportionate to real data, with a wide margin:

- ``max_file_mb`` (2048): the largest file, decompressed stream (joblib pickle, npz member) or sum
  of the npz members read. A frame of 20 SMPL-X people is ~3 MB; the largest real HPS output
  seen (a long 4D-Humans/PHALP tracking pickle) is a few hundred MB.
- ``max_array_mb`` (1024): the largest single array a file may declare (npz/npy header, pickled
  array, joblib array). A whole CLIFF/BEDLAM scene file's largest array is tens of MB.
- ``max_frame_mb`` (256): all the arrays of one contract frame (``.npz``) together, and the
  float64 meshes of one frame posed from a tool's parameters (``formats.smpl.lbs``: a CLIFF file of
  0.1 MB can name 5,000 people in one image). A frame of 100 SMPL-X people in float64 is 25 MB.
- ``max_pickle_items`` (20,000,000): the most objects one pickle may build (opcodes run, items
  a container is built from, object-array elements) and the most items its shared references may
  add when expanded (a list referenced 1,000 times is converted 1,000 times). A PHALP-like pickle
  of 2,000 frames of 5 people builds 1.4 million; every object costs roughly 50-250 bytes.
- ``max_grid_cells`` (2,000,000): calibration grid cells (``calibrate.grid.steps``); the paper's
  50^3 is 125,000 and takes well under a second.

Raise them for a rare real giant (``--config`` with ``limits: {max_array_mb: 4096}``). The value
is process-wide: commands set it from their merged config (``cli._common.config_for``), batch
tasks from their plan's config; worker processes are forked and inherit it, and a
:class:`Limits` is a frozen dataclass of ints, so it pickles to any other worker.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from .config import default_config
from ..errors import InputError, input_errors
from .option_rules import Rule, check_rules

__all__ = ["Limits", "current", "configure", "applied", "human_bytes"]

_MB = 1 << 20
# config key -> (field, scale): sizes are given in MB (MiB) and kept in bytes
_KEYS = {
    "max_file_mb": ("max_file_bytes", _MB),
    "max_array_mb": ("max_array_bytes", _MB),
    "max_frame_mb": ("max_frame_bytes", _MB),
    "max_pickle_items": ("max_pickle_items", 1),
    "max_grid_cells": ("max_grid_cells", 1),
}
RULES = {key: Rule(low=0, open_low=True) for key in _KEYS}  # every limit is a positive number: option_rules.py


@dataclass(frozen=True)
class Limits:
    """Largest file/stream (bytes), array (bytes), contract frame (bytes), pickle (items) and
    calibration grid (cells)."""

    max_file_bytes: int
    max_array_bytes: int
    max_frame_bytes: int
    max_pickle_items: int
    max_grid_cells: int

    @classmethod
    def from_config(cls, section: Mapping[str, Any] | None) -> "Limits":
        """From a config's ``limits`` section (MB -> bytes); missing keys take the packaged defaults."""
        section = dict(section or {})
        unknown = sorted(set(section) - set(_KEYS))
        if unknown:
            raise InputError(f"unknown key 'limits.{unknown[0]}' (known: {', '.join(sorted(_KEYS))})")
        values = {}
        for key, (name, scale) in _KEYS.items():
            value = section[key] if key in section else _packaged_section()[key]
            with input_errors():
                check_rules({key: value}, RULES, prefix="limits.")
            values[name] = max(1, int(value * scale))
        return cls(**values)


def _packaged_section() -> dict:
    """The ``limits`` section of the packaged defaults."""
    return default_config().get("limits", {})


_current: Limits | None = None


def current() -> Limits:
    """The limits in force: the last :func:`configure`, else the packaged defaults."""
    global _current
    if _current is None:
        _current = Limits.from_config(_packaged_section())
    return _current


def configure(limits: Limits | None) -> None:
    """Set the process-wide limits (None: back to the packaged defaults)."""
    global _current
    _current = limits


@contextmanager
def applied(limits: Limits) -> Iterator[Limits]:
    """Use ``limits`` inside a ``with`` block, then restore the previous value (tests)."""
    global _current
    previous = _current
    _current = limits
    try:
        yield limits
    finally:
        _current = previous


def human_bytes(n: int | float) -> str:
    """'3.5 GiB', '12.0 MiB', '640 bytes'.

    >>> human_bytes(3758096384), human_bytes(1 << 30), human_bytes(640)
    ('3.5 GiB', '1.0 GiB', '640 bytes')
    """
    for unit, shift in (("TiB", 40), ("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if n >= 1 << shift:
            return f"{n / (1 << shift):.1f} {unit}"
    return f"{int(n)} bytes"
