"""The packaged defaults file (``rotavat_cli/data/default.yaml``; ``configs/default.yaml`` links to
it), read once.

A leaf below :mod:`rotavat_cli.config` (which merges user files over it) and
:mod:`rotavat_cli.limits` (which takes its ``limits`` section), so neither imports the other.

>>> read_defaults()["limits"]["max_pickle_items"]
20000000
"""

from __future__ import annotations

from pathlib import Path

from .yaml_io import read_yaml

__all__ = ["DEFAULT_CONFIG_PATH", "read_defaults"]

DEFAULT_CONFIG_PATH = Path(__file__).resolve().parent / "data" / "default.yaml"

_CACHE: dict | None = None


def read_defaults() -> dict:
    """The packaged defaults, read once: one shared dict (copy it before changing anything in it)."""
    global _CACHE
    if _CACHE is None:
        _CACHE = read_yaml(DEFAULT_CONFIG_PATH)
    return _CACHE
