"""How much of each frame a recording stores (docs/render.md, "rotavat view", "Size"): meshes reduced to about
``view.mesh_vertices`` vertices, point clouds thinned to as many, video frames scaled down to ``view.image_max_px``.

A mesh is reduced by vertex clustering that keeps its connectivity (:func:`reduce_mesh`): its vertices are
grouped by a grid of cubic cells, a group being the vertices of one cell joined by the mesh's own edges (a hand
resting on a hip stays two groups), and each group is drawn at its vertices' mean; the faces that keep three
distinct groups remain. The cell is the largest that leaves at most the asked number of groups. The grouping is
found once, on one body, and holds for every body with the same faces: a body's vertices move, its groups do not.

>>> verts = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
>>> reduced = reduce_mesh(verts, np.array([[0, 1, 2], [0, 2, 3], [1, 2, 3]]), 3)  # 4 vertices -> 3: the close two merge
>>> reduced.apply(verts[None])[0].astype(float).round(3).tolist(), reduced.faces.tolist()
([[0.005, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2]])
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import InputError
from ..render.rows import IMAGE_MEDIA_TYPES

__all__ = ["MeshReduction", "reduce_mesh", "thin_points", "video_frame"]

_CELL_STEPS = 40  # bisection steps on the cell's size (log scale): the count is within one group of the best
_JPEG_QUALITY = 85  # a scaled-down video frame is stored as JPEG at this quality


@dataclass(frozen=True)
class MeshReduction:
    """A mesh's V vertices grouped into C: a group is drawn at its vertices' mean, on the faces that keep three
    distinct groups."""

    order: np.ndarray  # (V,) vertex indices, group by group
    starts: np.ndarray  # (C,) where each group starts in ``order``
    counts: np.ndarray  # (C,) vertices per group
    faces: np.ndarray  # (F', 3) uint32, on the groups: each face once, in the mesh's own winding

    @property
    def vertices(self) -> int:
        """C, the vertices of the reduced mesh."""
        return len(self.starts)

    def apply(self, points: np.ndarray) -> np.ndarray:
        """(P, V, 3) the mesh's vertices (any body with its faces) -> (P, C, 3) float32, each group's mean (NaN
        where a group holds a NaN vertex)."""
        p = np.asarray(points, dtype=np.float32)
        sums = np.add.reduceat(p[:, self.order], self.starts, axis=1)
        return sums / self.counts[:, None].astype(np.float32)


def _groups(verts: np.ndarray, edges: np.ndarray, cell_m: float) -> tuple[int, np.ndarray]:
    """(count, (V,) group of each vertex): the vertices of one ``cell_m`` cube joined by ``edges`` (E, 2); a
    non-finite vertex is a group of its own."""
    finite = np.isfinite(verts).all(axis=1)
    cell = np.floor(np.where(finite[:, None], verts, 0.0) / cell_m).astype(np.int64)
    a, b = edges[:, 0], edges[:, 1]
    joined = (cell[a] == cell[b]).all(axis=1) & finite[a] & finite[b]
    V = len(verts)
    graph = coo_matrix((np.ones(int(joined.sum()), np.int8), (a[joined], b[joined])), shape=(V, V))
    return connected_components(graph, directed=False)


def reduce_mesh(verts: np.ndarray, faces: np.ndarray, target: int) -> MeshReduction:
    """The grouping of a mesh's (V, 3) ``verts`` (metres: one body, any pose) on its (F, 3) ``faces`` into at
    most ``target`` groups, as many as the cell sizes tried reach (:data:`_CELL_STEPS` halvings of the range
    0.1 mm .. the mesh's size); every vertex its own group when V <= ``target``."""
    v = np.asarray(verts, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    V = len(v)
    labels = np.arange(V)
    if V > target:
        edges = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        finite = v[np.isfinite(v).all(axis=1)]
        size = float(np.max(np.ptp(finite, axis=0))) if len(finite) else 1.0
        lo, hi = math.log(1e-4), math.log(max(size, 1e-3) * 2.0)
        best = None
        for _ in range(_CELL_STEPS):
            mid = 0.5 * (lo + hi)
            count, found = _groups(v, edges, math.exp(mid))
            if count > target:
                lo = mid
            else:
                hi = mid
                if best is None or count > best[0]:
                    best = (count, found)
        if best is not None:
            labels = best[1]
    order = np.argsort(labels, kind="stable")
    counts = np.bincount(labels)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    on_groups = labels[f]
    distinct = ((on_groups[:, 0] != on_groups[:, 1]) & (on_groups[:, 1] != on_groups[:, 2])
                & (on_groups[:, 0] != on_groups[:, 2]))
    on_groups = on_groups[distinct]
    _, first = np.unique(np.sort(on_groups, axis=1), axis=0, return_index=True)  # two faces on the same three groups: one
    return MeshReduction(order, starts, counts, on_groups[np.sort(first)].astype(np.uint32))


def thin_points(points: np.ndarray, target: int) -> np.ndarray:
    """(P, N, 3) point clouds -> every k-th point, k the smallest that leaves at most ``target`` (0: all).

    >>> thin_points(np.zeros((2, 10, 3)), 4).shape
    (2, 4, 3)
    """
    n = points.shape[1]
    return points if not target or n <= target else points[:, ::math.ceil(n / target)]


def video_frame(contents: bytes, path: Path, max_px: int) -> tuple[bytes, str, tuple[int, int]]:
    """A video frame as the recording stores it: (its bytes, their media type, their (W, H) px). A frame whose
    longer side exceeds ``max_px`` is scaled down to it and stored as JPEG; else, or with ``max_px`` 0, the
    file's own bytes (``path``: the file they were read from, its suffix one of
    :data:`~rotavat_cli.render.rows.IMAGE_MEDIA_TYPES`). InputError naming ``path`` when it is not an image Pillow
    reads."""
    media_type = IMAGE_MEDIA_TYPES[path.suffix.lower()]
    try:
        with Image.open(io.BytesIO(contents)) as img:
            size = img.size
            if not max_px or max(size) <= max_px:
                return contents, media_type, size
            scale = max_px / max(size)
            want = (max(1, round(size[0] * scale)), max(1, round(size[1] * scale)))
            img.draft("RGB", want)  # a JPEG is decoded at 1/2, 1/4 or 1/8 size straight away
            small = img.convert("RGB").resize(want, Image.Resampling.BILINEAR, reducing_gap=2.0)
    except UnidentifiedImageError:
        raise InputError(f"{path}: not a readable image (not a format Pillow reads)") from None
    except (OSError, Image.DecompressionBombError, ValueError) as exc:  # truncated, corrupt, or too many pixels
        raise InputError(f"{path}: not a readable image ({exc})") from None
    out = io.BytesIO()
    small.save(out, "JPEG", quality=_JPEG_QUALITY)
    return out.getvalue(), "image/jpeg", small.size
