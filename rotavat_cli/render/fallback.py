"""NumPy z-buffer rasteriser: the renderer that always works (no OpenGL, no EGL).

Same contract as :mod:`rotavat_cli.render.gl`: points ``(N, 3)``, triangles ``(F, 3)`` and
per-vertex colours go through one ``clip_from_points`` 4x4 matrix (OpenGL clip space: NDC ``x``
right, ``y`` up, ``z`` in [-1, 1], nearer = smaller); the result is an ``(H, W, 4)`` float image,
row 0 at the top, alpha = coverage.

How it stays vectorised: triangles are grouped by the size of their pixel bounding box (rounded
up to a power of two ``k``); each group tests its triangles' ``k x k`` candidate pixel centres at
once with edge functions, and a per-pixel depth minimum (``np.minimum.at`` on the flat pixel
index) keeps the nearest candidate. Batches are sized so no temporary exceeds ``_MAX_CANDIDATES``.
Colours and depth are interpolated linearly in screen space (exact for depth, which is affine in
screen space; the colour error of not being perspective-correct is invisible on body-sized
triangles). Triangles with a vertex behind the eye (``w <= 0``) or outside the depth range are
dropped rather than clipped. Pixels are binary (no anti-aliasing).
"""

from __future__ import annotations

import numpy as np

from .geometry import ndc_to_px

__all__ = ["rasterize_numpy"]

_MAX_CANDIDATES = 1 << 22  # candidate pixels per batch (~4M: ~200 MB of float64 temporaries at peak)
_MIN_AREA_PX2 = 1e-12  # twice-area below this: a degenerate (zero-area) triangle


def _screen_triangles(points: np.ndarray, faces: np.ndarray, clip_from_points: np.ndarray,
                      size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Visible triangles in screen space: corners_px (T, 3, 2), depth (T, 3), kept face indices (T,)."""
    p = np.asarray(points, dtype=np.float64)
    clip = p @ clip_from_points[:3, :3].T + clip_from_points[:3, 3]
    w = p @ clip_from_points[3, :3] + clip_from_points[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = clip / w[:, None]
    ok_vertex = (w > 0) & np.isfinite(ndc).all(axis=1) & (np.abs(ndc[:, 2]) <= 1.0)
    keep = np.flatnonzero(ok_vertex[faces].all(axis=1))
    tri = faces[keep]
    return ndc_to_px(ndc[:, :2], size)[tri], ndc[:, 2][tri], keep


def _pixel_boxes(corners_px: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integer pixel ranges (T,) x0, y0, x1, y1 (inclusive) whose centres may fall in each triangle."""
    W, H = size
    lo = np.ceil(corners_px.min(axis=1) - 0.5).astype(np.int64)
    hi = np.floor(corners_px.max(axis=1) - 0.5).astype(np.int64)
    x0, y0 = np.maximum(lo[:, 0], 0), np.maximum(lo[:, 1], 0)
    x1, y1 = np.minimum(hi[:, 0], W - 1), np.minimum(hi[:, 1], H - 1)
    return x0, y0, x1, y1


def _bucket_of(extent: np.ndarray) -> np.ndarray:
    """Smallest power of two >= extent (T,) int (extent >= 1)."""
    return (1 << np.ceil(np.log2(np.maximum(extent, 1))).astype(np.int64)).astype(np.int64)


def _rasterize_batch(corners_px: np.ndarray, depth: np.ndarray, tri_index: np.ndarray, x0: np.ndarray,
                     y0: np.ndarray, k: int, size: tuple[int, int], zbuf: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Covered pixels of one batch whose depth passes the test -> (pixel, tri, w1, w2) of the winners.

    corners_px: (T, 3, 2); depth: (T, 3); tri_index: (T,) ids into the caller's arrays;
    x0, y0: (T,) box origins; k: box side; size: (W, H); zbuf: (H*W,) float64, updated in place.
    """
    width, height = size
    offs = np.arange(k * k)
    px = x0[:, None] + offs % k + 0.5  # (T, k*k) pixel centres
    py = y0[:, None] + offs // k + 0.5
    a, b, c = corners_px[:, 0], corners_px[:, 1], corners_px[:, 2]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    inv = 1.0 / area
    # barycentric weights of b and c (edge functions), then a's
    w1 = ((px - a[:, 0:1]) * (c[:, 1:2] - a[:, 1:2]) - (py - a[:, 1:2]) * (c[:, 0:1] - a[:, 0:1])) * inv[:, None]
    w2 = ((b[:, 0:1] - a[:, 0:1]) * (py - a[:, 1:2]) - (b[:, 1:2] - a[:, 1:2]) * (px - a[:, 0:1])) * inv[:, None]
    w0 = 1.0 - w1 - w2
    inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (px < width) & (py < height)  # boxes reach past clipped edges
    t_idx, o_idx = np.nonzero(inside)
    w1, w2 = w1[t_idx, o_idx], w2[t_idx, o_idx]
    z = depth[t_idx, 0] + w1 * (depth[t_idx, 1] - depth[t_idx, 0]) + w2 * (depth[t_idx, 2] - depth[t_idx, 0])
    pixel = (py[t_idx, o_idx].astype(np.int64)) * width + px[t_idx, o_idx].astype(np.int64)
    np.minimum.at(zbuf, pixel, z)
    win = z <= zbuf[pixel]
    return pixel[win], tri_index[t_idx[win]], w1[win], w2[win]


def rasterize_numpy(points: np.ndarray, faces: np.ndarray, colors: np.ndarray, clip_from_points: np.ndarray,
                    size: tuple[int, int]) -> np.ndarray:
    """Rasterise coloured triangles with a z-buffer -> (H, W, 4) float32 RGBA in [0, 1], alpha = coverage.

    points: (N, 3) float; faces: (F, 3) int; colors: (N, 3) float in [0, 1];
    clip_from_points: (4, 4) OpenGL clip-space matrix; size: (W, H) px.
    """
    W, H = int(size[0]), int(size[1])
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    colors = np.asarray(colors, dtype=np.float64)
    zbuf = np.full(W * H, np.inf)
    rgb = np.zeros((W * H, 3))
    covered = np.zeros(W * H, dtype=bool)
    if faces.shape[0] == 0 or len(points) == 0:
        return np.zeros((H, W, 4), dtype=np.float32)
    corners, depth, face_index = _screen_triangles(points, faces, np.asarray(clip_from_points, dtype=np.float64), (W, H))
    x0, y0, x1, y1 = _pixel_boxes(corners, (W, H))
    area = np.abs((corners[:, 1, 0] - corners[:, 0, 0]) * (corners[:, 2, 1] - corners[:, 0, 1])
                  - (corners[:, 1, 1] - corners[:, 0, 1]) * (corners[:, 2, 0] - corners[:, 0, 0]))
    live = np.flatnonzero((x1 >= x0) & (y1 >= y0) & (area > _MIN_AREA_PX2))
    bucket = _bucket_of(np.maximum(x1 - x0, y1 - y0)[live] + 1)
    for k in np.unique(bucket):
        members = live[bucket == k]
        step = max(1, _MAX_CANDIDATES // int(k * k))
        for start in range(0, members.size, step):
            sel = members[start:start + step]
            pixel, tri, w1, w2 = _rasterize_batch(corners[sel], depth[sel], sel, x0[sel], y0[sel], int(k), (W, H), zbuf)
            f = faces[face_index[tri]]
            rgb[pixel] = (colors[f[:, 0]] * (1.0 - w1 - w2)[:, None] + colors[f[:, 1]] * w1[:, None]
                          + colors[f[:, 2]] * w2[:, None])
            covered[pixel] = True
    out = np.concatenate([rgb, covered[:, None].astype(np.float64)], axis=1)
    return np.clip(out, 0.0, 1.0).reshape(H, W, 4).astype(np.float32)
