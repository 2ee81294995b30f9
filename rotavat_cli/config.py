"""Configuration: ``configs/default.yaml`` < ``--config FILE`` < command-line flags.

The defaults file is the single source of every option's default. A user file may set any
subset of its keys; an unknown key or a value of the wrong type is an :class:`InputError`
naming the key and the file. The merged result is a fresh plain dict (never a shared preset
mutated in place), safe to dump next to outputs with ``yaml.safe_dump``.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

from .errors import InputError
from .sequence import read_yaml

__all__ = ["DEFAULT_CONFIG_PATH", "default_config", "load_config", "merge_config"]

DEFAULT_CONFIG_PATH = Path(__file__).resolve().parent / "data" / "default.yaml"


def default_config() -> dict:
    """A fresh copy of the packaged defaults."""
    return copy.deepcopy(_read_defaults())


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


# Keys whose value is a name or a number (the default is a name).
_NAME_OR_NUMBER = {"synth.hps_focal"}


def _check_type(default: Any, value: Any, key: str, source: str) -> Any:
    """Accept ``value`` if it fits the default's type (null defaults accept anything plain)."""
    if value is None or default is None:
        return value
    if key in _NAME_OR_NUMBER and isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, (int, float)):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif isinstance(default, list):
        ok = isinstance(value, list) and len(value) == len(default)
    else:
        ok = isinstance(value, type(default))
    if not ok:
        raise InputError(f"{source}: key '{key}' must be like {default!r}, got {value!r}")
    return value


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
