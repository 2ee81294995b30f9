"""Configuration: ``configs/default.yaml`` < ``--config FILE`` < command-line flags.

The defaults file is the single source of every option's default. A user file may set any
subset of its keys; an unknown key or a value of the wrong type is an :class:`InputError`
naming the key and the file. The merged result is a fresh plain dict (never a shared preset
mutated in place), safe to dump next to outputs with ``yaml.safe_dump``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import reprlib
from pathlib import Path
from collections.abc import Callable
from typing import Any

from .defaults import read_defaults
from .errors import InputError
from .yaml_io import read_yaml

__all__ = ["default_config", "load_config", "merge_config", "packaged_default", "config_choices"]


def default_config() -> dict:
    """A fresh copy of the packaged defaults."""
    return copy.deepcopy(read_defaults())


def packaged_default(packaged: Callable[[], Any], name: str) -> Any:
    """A dataclass field defaulting to attribute ``name`` of ``packaged()``: the options instance built
    from the packaged configs/default.yaml, so the YAML stays the one source of the default."""
    return dataclasses.field(default_factory=lambda: getattr(packaged(), name))


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
# Inclusive bounds of numeric keys (None: open); every number must also be finite.
_RANGES: dict[str, tuple[float | None, float | None]] = {
    "align.jobs": (0, None), "batch.jobs": (0, None), "batch.chunk_frames": (1, None),
    "synth.frames": (1, None), "synth.people": (0, None), "synth.noise_px": (0, None), "synth.outliers": (0, 1),
    "synth.depth_sd": (0, None), "synth.lean": (0, 1), "synth.camera_height_range_m": (1e-3, 1e5),
    "synth.pitch_range_deg": (-89, 89),
    "calibrate.person_height_m": (0.5, 3.0), "calibrate.person_height_sd_m": (0, 1.0),
    "calibrate.camera_height_m": (0.01, 1e5), "calibrate.box_depth_m": (-1.0, 2.0), "calibrate.focal_px": (1e-3, 1e7),
    "calibrate.fov_prior_deg": (0.1, 179.9), "calibrate.pitch_deg": (-89.9, 89.9),
    "eval.threshold_px": (1e-9, None), "eval.iou_threshold": (0, 1),
    "render.fps": (0.01, 1000), "render.margin": (0, 10), "render.every": (1, None),
    "limits.max_file_mb": (1, None), "limits.max_array_mb": (1, None), "limits.max_pickle_items": (1, None),
    "limits.max_grid_cells": (1, None),
    # lists: every item
    "calibrate.grid.steps": (1, 100_000), "calibrate.grid.focal_range_h": (1e-3, 1e3),
    "calibrate.grid.pitch_range_deg": (-90, 90), "calibrate.grid.height_range_m": (1e-2, 1e5),
    "calibrate.principal_point": (-1e6, 1e6), "synth.image_size": (32, 100_000), "render.size": (16, 8192),
    "align.stature_range_m": (0, 10),
}
_ORDERED = {"align.stature_range_m": "<", "calibrate.grid.focal_range_h": "<=",  # [low, high] pairs
            "calibrate.grid.pitch_range_deg": "<=", "calibrate.grid.height_range_m": "<=",
            "synth.camera_height_range_m": "<=", "synth.pitch_range_deg": "<="}
_MAX_LIST = 64  # longest list a config key takes (lists are [W, H], ranges, grid steps, colours ...)
_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxstring, _SHORT.maxother = 2, 4, 40, 40


@functools.lru_cache(maxsize=1)
def _choices() -> dict[str, tuple[str, ...]]:
    """Keys whose value is one of a few names: each list lives beside the code that uses it."""
    from .alignment.options import HEIGHT_FROM
    from .alignment.transform import UPRIGHT
    from .batch.plan import EXECUTORS
    from .calibration.options import FOCAL_PRIORS, METHODS, POINTS
    from .calibration.residuals import RESIDUALS
    from .metrics.fused import ENGINES
    from .metrics.evaluate import MATCHES, PROTOCOL_NAMES
    from .render.raster import RENDERERS
    from .render.sequences import GHOSTS, SCALES
    from .render.views import FITS
    from .synth.layouts import LAYOUTS

    return {"calibrate.method": METHODS, "calibrate.residual": RESIDUALS, "calibrate.points": POINTS,
            "calibrate.focal_prior": FOCAL_PRIORS,
            "align.upright": UPRIGHT, "align.height_from": HEIGHT_FROM, "eval.match": MATCHES, "eval.engine": ENGINES,
            "eval.protocol": PROTOCOL_NAMES,
            "render.renderer": RENDERERS, "render.fit": FITS, "render.scale": SCALES, "render.ghost": GHOSTS,
            "batch.executor": EXECUTORS, "synth.layout": LAYOUTS}


def _check_type(default: Any, value: Any, key: str, source: str) -> Any:
    """Accept ``value`` if it fits the default's type (null defaults accept any plain scalar or flat
    list), numbers finite and within the key's range, names among the key's choices."""
    if value is None:
        if default is not None:
            raise InputError(f"{source}: key '{key}' must be like {_SHORT.repr(default)}, got null")
        return value
    if default is None:
        ok = _is_scalar(value) or (isinstance(value, list) and len(value) <= _MAX_LIST and all(map(_is_scalar, value)))
    elif key in _NAME_OR_NUMBER and _is_number(value):
        ok = True
    elif isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, (int, float)):
        ok = _is_number(value)
    elif isinstance(default, list):  # same length, each item of its default item's kind
        ok = isinstance(value, list) and len(value) == len(default) and all(map(_same_kind, default, value))
    else:
        ok = isinstance(value, type(default))
    if not ok:
        raise InputError(f"{source}: key '{key}' must be like {_SHORT.repr(default)}, got {_SHORT.repr(value)}")
    for number in (value if isinstance(value, list) else [value]):
        if _is_number(number) and not math.isfinite(number):
            raise InputError(f"{source}: key '{key}' must be finite, got {number}")
    if key in _ORDERED and not (value[0] < value[1] if _ORDERED[key] == "<" else value[0] <= value[1]):
        raise InputError(f"{source}: key '{key}' must be [low, high] with low {_ORDERED[key]} high, got {value}")
    choices = _choices().get(key)
    if choices is not None and value not in choices:
        raise InputError(f"{source}: key '{key}' must be one of {', '.join(choices)}, got {_SHORT.repr(value)}")
    lo, hi = _RANGES.get(key, (None, None))
    for number in (value if isinstance(value, list) else [value]):
        if _is_number(number) and ((lo is not None and number < lo) or (hi is not None and number > hi)):
            span = f"{'' if lo is None else lo}..{'' if hi is None else hi}"
            raise InputError(f"{source}: key '{key}' must be within {span}, got {_SHORT.repr(number)}")
    return value


def _same_kind(default: Any, value: Any) -> bool:
    """A list item fits its default item: a number for a number, a name for a name, a flag for a flag."""
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if _is_number(default):
        return _is_number(value)
    return _is_scalar(value) and not _is_number(value) if isinstance(default, str) else _is_scalar(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


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


def config_choices(section: str) -> dict[str, tuple[str, ...]]:
    """The keys of a config section whose value is one of a few names, with those names (--help shows them)."""
    prefix = f"{section}."
    return {key[len(prefix):]: names for key, names in _choices().items() if key.startswith(prefix)}
