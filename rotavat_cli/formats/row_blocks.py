"""A per-row computation over a long table, done a block of rows at a time: how a reader that builds one frame at a
time still poses its people in batches (one :func:`~.smpl.lbs` call per block, not one per frame).

A reader lays out its person rows frame by frame (a frame's people are consecutive rows) and asks a
:class:`RowBlocks` for a frame's rows; the first frame of a block computes the whole block (``compute(start, stop)``:
arrays of ``stop - start`` rows each) and keeps it until a frame outside it is asked for. Frames built in order
compute every row once; built in any other order (or again), each frame still gets exactly its rows, at worst for
the price of one block. One block is held at a time: memory is that of a block, whatever the clip's length.

>>> calls = []
>>> blocks = RowBlocks(5, lambda a, b: calls.append((a, b)) or {"x": np.arange(a, b) * 10}, 2)
>>> [blocks.rows(i, i + 1)["x"].tolist() for i in range(5)], calls
([[0], [10], [20], [30], [40]], [(0, 2), (2, 4), (4, 5)])
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..settings import limits
from .smpl import BodyModel, lbs_batch_rows

__all__ = ["RowBlocks", "frame_offsets", "posing_block_rows"]


class RowBlocks:
    """Rows ``[start, stop)`` of ``compute`` over ``n_rows`` rows, computed ``block`` rows at a time (the last block
    kept). ``compute(start, stop)`` returns a dict of arrays whose first axis is those rows; it must be row-wise
    (a row's values do not depend on the other rows computed with it). The arrays handed out are read-only views
    of the kept block."""

    def __init__(self, n_rows: int, compute: Callable[[int, int], dict[str, np.ndarray]], block: int) -> None:
        self.n_rows, self.compute, self.block = int(n_rows), compute, max(1, int(block))
        self._span = (0, -1)  # nothing kept: even rows [0, 0) (an empty first frame) compute the first block
        self._kept: dict[str, np.ndarray] = {}

    def rows(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """The values of rows ``[start, stop)`` (0 <= start <= stop <= n_rows), each array (stop - start, ...)."""
        lo, hi = self._span
        if not (lo <= start and stop <= hi):
            lo, hi = start, min(self.n_rows, start + max(self.block, stop - start))
            kept = self.compute(lo, hi)
            for value in kept.values():
                value.setflags(write=False)
            self._span, self._kept = (lo, hi), kept
        return {key: value[start - lo:stop - lo] for key, value in self._kept.items()}


def frame_offsets(people_per_frame: list[int] | np.ndarray) -> np.ndarray:
    """(T + 1,) where each frame's rows start in a frame-by-frame table (frame t: rows ``[o[t], o[t + 1])``).

    >>> frame_offsets([2, 0, 1]).tolist()
    [0, 2, 2, 3]
    """
    return np.concatenate([[0], np.cumsum(np.asarray(people_per_frame, dtype=np.int64))]).astype(np.int64)


def posing_block_rows(model: BodyModel) -> int:
    """Rows of a block of posed people on ``model``: one :func:`~.smpl.lbs` batch, and no more people than one
    contract frame may hold (``limits.max_frame_mb``: a frame over it is refused as it would be alone)."""
    per_person = model.n_verts * 3 * 8  # float64 vertices (V, 3), as smpl.check_posed_size counts them
    return max(1, min(lbs_batch_rows(model), limits.current().max_frame_bytes // per_person))
