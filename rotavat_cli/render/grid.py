"""Panels and grids: one row per :class:`RowFrame`, one column per view, with titles and row labels.

A panel is the view's background (:attr:`View.under`), the row's shaded people rasterised through
the view's ``clip_from_cam`` and composited by coverage, then the view's annotations
(:attr:`View.over`). Person colours come from ``person_id`` modulo the palette.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .geometry import OrthoExtent, PanelView
from .style import RenderStyle, font, person_colors, rgb8, shade_vertices, vertex_normals
from .views import REGISTRY, RowFrame, scene_extents, view_specs

__all__ = ["render_panel", "render_grid", "LABEL_PX"]

LABEL_PX = 26  # header row / label column thickness in grids


@dataclass(frozen=True)
class _Mesh:
    """A row's people flattened for the rasterisers: computed once, shaded per view."""

    points_cam: np.ndarray  # (N, 3) float64, N = P * V
    faces: np.ndarray  # (P * F, 3) int64, offset per person
    colors: np.ndarray  # (N, 3) unlit colours
    normals_cam: np.ndarray  # (N, 3) unit


def _row_mesh(row: RowFrame, style: RenderStyle) -> _Mesh:
    """Flatten a row's finite people into one mesh with per-vertex colours and normals."""
    verts = np.asarray(row.verts_cam, dtype=np.float64)
    faces = np.asarray(row.faces, dtype=np.int64).reshape(-1, 3)
    if verts.ndim != 3 or verts.shape[0] == 0 or verts.shape[1] == 0 or faces.shape[0] == 0:
        return _Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
    finite = np.isfinite(verts).all(axis=(1, 2))
    verts, ids = verts[finite], np.asarray(row.person_ids)[finite]
    P, V = verts.shape[:2]
    colors = np.broadcast_to(person_colors(ids, style.palette)[:, None, :], (P, V, 3))
    flat_faces = (faces[None] + V * np.arange(P)[:, None, None]).reshape(-1, 3)
    return _Mesh(verts.reshape(-1, 3), flat_faces, colors.reshape(-1, 3), vertex_normals(verts, faces).reshape(-1, 3))


def _mesh_layer(mesh: _Mesh, view: PanelView, rasterize: Any) -> np.ndarray:
    """Rasterise a row's shaded people in one view -> (H, W, 4) float RGBA."""
    if mesh.faces.shape[0] == 0:
        return np.zeros((view.size[1], view.size[0], 4), dtype=np.float32)
    lit = shade_vertices(mesh.colors, mesh.normals_cam, view.light_cam)
    return rasterize(mesh.points_cam, mesh.faces, lit, view.clip_from_cam, view.size)


def render_panel(row: RowFrame, view: PanelView, rasterize: Any, style: RenderStyle, mesh: _Mesh | None = None) -> np.ndarray:
    """One panel: the view's background, the shaded meshes, then its annotations -> (H, W, 3) uint8."""
    from PIL import Image

    spec = REGISTRY[view.kind]
    W, H = view.size
    img = Image.new("RGB", (W, H), rgb8(style.background))
    spec.under(img, view, row, style)
    layer = _mesh_layer(mesh if mesh is not None else _row_mesh(row, style), view, rasterize)
    base = np.asarray(img, dtype=np.float32) / 255.0
    alpha = layer[..., 3:4]
    img = Image.fromarray(np.round(255.0 * (base * (1.0 - alpha) + layer[..., :3] * alpha)).astype(np.uint8))
    spec.over(img, view, row, style)
    return np.asarray(img)


def render_grid(rows: list[RowFrame], views: tuple[str, ...], size: tuple[int, int], rasterize: Any,
                style: RenderStyle, extents: dict[str, OrthoExtent] | None = None, title: str = "") -> np.ndarray:
    """Figure: one row per RowFrame, one column per view, labelled -> (H_total, W_total, 3) uint8.

    extents: shared orthographic extents (default: fitted to these rows).
    """
    from PIL import Image, ImageDraw

    specs = view_specs(views)
    extents = extents if extents is not None else scene_extents(rows, views, size, style.margin)
    W, H = size
    fig = Image.new("RGB", (LABEL_PX + W * len(specs), LABEL_PX + H * len(rows)), (255, 255, 255))
    draw = ImageDraw.Draw(fig)
    face = font(LABEL_PX * 6 // 10)
    ink = rgb8(style.text)
    for j, spec in enumerate(specs):
        draw.text((LABEL_PX + W * j + W / 2, LABEL_PX / 2), spec.title, fill=ink, font=face, anchor="mm")
    if title:
        draw.text((4, LABEL_PX / 2), title, fill=ink, font=font(LABEL_PX * 4 // 10), anchor="lm")
    for i, row in enumerate(rows):
        label = Image.new("RGB", (H, LABEL_PX), (255, 255, 255))
        ImageDraw.Draw(label).text((H / 2, LABEL_PX / 2), row.label, fill=ink, font=face, anchor="mm")
        fig.paste(label.rotate(90, expand=True), (0, LABEL_PX + H * i))
        mesh = _row_mesh(row, style)
        for j, spec in enumerate(specs):
            panel = render_panel(row, spec.panel(row, size, extents), rasterize, style, mesh)
            fig.paste(Image.fromarray(panel), (LABEL_PX + W * j, LABEL_PX + H * i))
    return np.asarray(fig)
