"""Configuration: ``configs/default.yaml`` < ``--config FILE`` < command-line flags.

The defaults file is the single source of every option's default. A user file may set any
subset of its keys; an unknown key or a value of the wrong type is an :class:`InputError`
naming the key and the file. This module only loads and merges: what a value may be (its bounds,
its names) each options class says in its ``RULES`` (:mod:`rotavat_cli.settings.option_rules`), and the
command line checks a file's values against them. The merged result is a fresh plain dict (never a shared preset
mutated in place), safe to dump next to outputs with ``yaml.safe_dump``.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from pathlib import Path
from collections.abc import Callable
from typing import Any

from ..errors import InputError
from .option_rules import is_number, short_repr
from ..files.yaml_io import read_yaml

__all__ = ["DEFAULT_CONFIG_PATH", "default_config", "load_config", "merge_config", "packaged_default"]

DEFAULT_CONFIG_PATH = Path(__file__).resolve().parents[1] / "data" / "default.yaml"


def default_config() -> dict:
    """A fresh copy of the packaged defaults."""
    return copy.deepcopy(_read_defaults())


def packaged_default(packaged: Callable[[], Any], name: str) -> Any:
    """A dataclass field defaulting to attribute ``name`` of ``packaged()``: the options instance built
    from the packaged configs/default.yaml, so the YAML stays the one source of the default."""
    return dataclasses.field(default_factory=lambda: getattr(packaged(), name))


_DEFAULTS_CACHE: dict | None = None


def _read_defaults() -> dict:
    """Packaged defaults, read once."""
    global _DEFAULTS_CACHE
    if _DEFAULTS_CACHE is None:
        _DEFAULTS_CACHE = read_yaml(DEFAULT_CONFIG_PATH)
    return _DEFAULTS_CACHE


def merge_config(base: dict, override: dict, source: str, prefix: str = "") -> dict:
    """Return ``base`` updated by ``override``; keys must exist in ``base`` with compatible types."""
    merged = copy.deepcopy(base)
    for key, value in override.items():
        dotted = f"{prefix}{key}"
        if key not in base:
            known = ", ".join(sorted(base)) if isinstance(base, dict) else ""
            raise InputError(f"{source}: unknown key '{dotted}' (known: {known})")
        default = base[key]
        if isinstance(default, dict):
            if not isinstance(value, dict):
                raise InputError(f"{source}: key '{dotted}' must be a mapping")
            merged[key] = merge_config(default, value, source, f"{dotted}.")
        else:
            merged[key] = _check_type(default, value, dotted, source)
    return merged


# Keys whose value is a name or a number (the default is a name): their kind, not a bound.
_NAME_OR_NUMBER = {"synth.hps_focal"}
_MAX_LIST = 64  # longest list a config key takes (lists are [W, H], ranges, grid steps, colours ...)


def _check_type(default: Any, value: Any, key: str, source: str) -> Any:
    """Accept ``value`` if it fits the default's type (null defaults accept any plain scalar or flat
    list) and its numbers are finite. What a value may be (bounds, names) each options class says."""
    if value is None:
        if default is not None:
            raise InputError(f"{source}: key '{key}' must be like {short_repr(default)}, got null")
        return value
    if default is None:
        ok = _is_scalar(value) or (isinstance(value, list) and len(value) <= _MAX_LIST and all(map(_is_scalar, value)))
    elif key in _NAME_OR_NUMBER and is_number(value):
        ok = True
    elif isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, (int, float)):
        ok = is_number(value)
    elif isinstance(default, list):  # same length, each item of its default item's kind
        ok = isinstance(value, list) and len(value) == len(default) and all(map(_same_kind, default, value))
    else:
        ok = isinstance(value, type(default))
    if not ok:
        raise InputError(f"{source}: key '{key}' must be like {short_repr(default)}, got {short_repr(value)}")
    for number in (value if isinstance(value, list) else [value]):
        if is_number(number) and not math.isfinite(number):
            raise InputError(f"{source}: key '{key}' must be finite, got {number}")
    return value


def _same_kind(default: Any, value: Any) -> bool:
    """A list item fits its default item: a number for a number, a name for a name, a flag for a flag."""
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if is_number(default):
        return is_number(value)
    return _is_scalar(value) and not is_number(value) if isinstance(default, str) else _is_scalar(value)


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, bool, int, float))


def load_config(path: str | Path | None = None, overrides: dict | None = None) -> dict:
    """Defaults, then the optional YAML file, then explicit overrides (e.g. CLI flags, None = unset)."""
    config = default_config()
    if path is not None:
        config = merge_config(config, read_yaml(path), str(path))
    if overrides:
        config = merge_config(config, _drop_none(overrides), "command line")
    return config


def _drop_none(tree: dict) -> dict:
    """Remove None leaves (flags the user did not give)."""
    out = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            sub = _drop_none(value)
            if sub:
                out[key] = sub
        elif value is not None:
            out[key] = value
    return out

