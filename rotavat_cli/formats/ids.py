"""Track / person ids and frame indices read from a tool's file: ids that fit a 64-bit integer (never
wrapped into other ids), frame indices that are those of one video."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import file_error

__all__ = ["MAX_FRAMES", "check_frame_range", "check_int64_ids", "int64_ids"]

_INT64 = np.iinfo(np.int64)
MAX_FRAMES = 100_000  # frames a tool's frame indices may imply beyond 100 per detection row (~1 h of video)


def int64_ids(ids: list[int], what: str, source: Any) -> np.ndarray:
    """Track / person ids (P,) as int64; InputError naming ``what`` when one does not fit 64 bits."""
    bad = [i for i in ids if not _INT64.min <= i <= _INT64.max]
    if bad:
        raise file_error(source, f"{what} {bad[0]} does not fit in a 64-bit integer")
    return np.asarray(ids, dtype=np.int64)


def check_int64_ids(ids: np.ndarray, source: Any) -> None:
    """InputError when track ids (P,) do not fit a 64-bit signed integer (uint64 beyond 2^63 - 1, inf,
    huge floats): ``astype(int64)`` would wrap them silently into other ids."""
    if ids.size and ids.dtype.kind in "uf":
        with np.errstate(invalid="ignore"):
            bad = ids > _INT64.max if ids.dtype.kind == "u" else ~np.isfinite(ids) | (np.abs(ids) >= 2.0 ** 63)
        if np.any(bad):
            raise file_error(source, f"person id {ids[np.argmax(bad)]} does not fit in a 64-bit integer")


def check_frame_range(n_frames: int, n_rows: int, source: Any, key: str) -> int:
    """``n_frames`` (1 + the largest frame index), unless it implies far more frames than the file has
    detection rows (a few KB naming frame 10^12 would make 10^12 frames)."""
    if n_frames > MAX_FRAMES + 100 * n_rows:
        raise file_error(source, f"'{key}' reaches frame {n_frames - 1:,} with {n_rows:,} detection rows: not the "
                                 "frame indices of one video")
    return n_frames
