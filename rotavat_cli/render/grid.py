"""Panels and grids: one row per :class:`RowFrame`, one column per view, with titles and row captions.

A panel is the view's background (:attr:`View.under`), the row's shaded people rasterised through
the view's ``clip_from_cam`` and composited by coverage, the row's ghost (the ground truth, faint
with an outline), then the view's annotations (:attr:`View.over`) and the person ids. People are
meshes, point clouds or skeletons (:mod:`.skeleton`), all triangles for the rasterisers; person
colours come from ``person_id`` modulo the palette.

Layout: a header strip with the column titles, then per row a caption strip (the row's label and
its numbers: camera, metrics against the ground truth) above its panels.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from .geometry import PanelView, panel_px_per_m, project_view_px
from .skeleton import BONE_RADIUS_M, POINT_RADIUS_M, Shapes, layout_bones, point_shapes, skeleton_shapes
from .style import RenderStyle, font, mix, person_colors, rgb8, shade_vertices, vertex_normals
from .views import REGISTRY, RowFrame, edge_marker, front_points_cam, scene_extents, view_specs

__all__ = ["render_panel", "render_grid", "LABEL_PX", "row_shapes", "GHOST_ALPHA", "person_label"]

LABEL_PX = 26  # header strip and row caption strip height in grids
GHOST_ALPHA = 0.35  # the ghost's fill opacity (its outline is opaque)
_MIN_RADIUS_PX = {"skeleton": 1.3, "points": 0.8}  # bones / points stay at least this many px thick
_LABEL_POINTS = 400  # person id labels: at most this many of a person's points are projected


@dataclass(frozen=True)
class _Mesh:
    """A row's people flattened for the rasterisers: computed once, shaded per view."""

    points_cam: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (F, 3) int64
    colors: np.ndarray  # (N, 3) unlit colours
    normals_cam: np.ndarray  # (N, 3) unit


_EMPTY = _Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros((0, 3)))


def _mesh_of_triangles(row: RowFrame, style: RenderStyle) -> _Mesh:
    """A mesh row's finite people as one mesh with per-vertex colours and normals (view-independent)."""
    verts = np.asarray(row.verts_cam, dtype=np.float64)
    faces = np.asarray(row.faces, dtype=np.int64).reshape(-1, 3)
    finite = np.isfinite(verts).all(axis=(1, 2))
    verts, ids = verts[finite], np.asarray(row.person_ids)[finite]
    if not len(verts):
        return _EMPTY
    P, V = verts.shape[:2]
    colors = np.broadcast_to(person_colors(ids, style.palette)[:, None, :], (P, V, 3))
    flat_faces = (faces[None] + V * np.arange(P)[:, None, None]).reshape(-1, 3)
    return _Mesh(verts.reshape(-1, 3), flat_faces, colors.reshape(-1, 3), vertex_normals(verts, faces).reshape(-1, 3))


def row_shapes(row: RowFrame, scale: np.ndarray | float = 1.0) -> Shapes:
    """A point-cloud or skeleton row's people as triangles (:mod:`.skeleton`); ``scale`` (P,) multiplies
    the default radii."""
    scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), (len(row.person_ids),))
    if row.kind == "points":
        return point_shapes(row.verts_cam, scale)
    if row.kind == "skeleton":
        return skeleton_shapes(row.joints_cam, layout_bones(row.joints_layout), scale)
    return Shapes.empty()


def _panel_scale(row: RowFrame, view: PanelView) -> np.ndarray:
    """(P,) radius multipliers keeping each person's bones/points at least a pixel or so thick in ``view``."""
    points = row.points_cam
    base = BONE_RADIUS_M if row.kind == "skeleton" else POINT_RADIUS_M
    with np.errstate(invalid="ignore"):
        depth = np.nanmedian(np.where(np.isfinite(points[..., 2]), points[..., 2], np.nan), axis=1) if points.shape[1] \
            else np.ones(len(points))
    px_per_m = panel_px_per_m(view, depth)
    scale = _MIN_RADIUS_PX.get(row.kind, 1.0) / (base * px_per_m)
    return np.maximum(1.0, np.nan_to_num(scale, nan=1.0, posinf=1.0))


def _row_mesh(row: RowFrame, style: RenderStyle, view: PanelView | None = None) -> _Mesh:
    """What the rasterisers draw for a row: its mesh (any view), or its skeleton/points sized for ``view``."""
    if row.kind == "mesh":
        return _mesh_of_triangles(row, style)
    if row.kind == "none" or view is None:
        return _EMPTY
    shapes = row_shapes(row, _panel_scale(row, view))
    if not len(shapes.points):
        return _EMPTY
    colors = person_colors(np.asarray(row.person_ids)[shapes.person], style.palette)
    return _Mesh(shapes.points, shapes.faces, colors, shapes.normals)


def _mesh_layer(mesh: _Mesh, view: PanelView, rasterize: Any) -> np.ndarray:
    """Rasterise shaded people in one view -> (H, W, 4) float RGBA."""
    if mesh.faces.shape[0] == 0:
        return np.zeros((view.size[1], view.size[0], 4), dtype=np.float32)
    lit = shade_vertices(mesh.colors, mesh.normals_cam, view.light_cam)
    return rasterize(mesh.points_cam, mesh.faces, lit, view.clip_from_cam, view.size)


def _in_view(mesh: _Mesh, row: RowFrame, front: bool) -> _Mesh:
    """The mesh as ``row``'s panel draws it: in the front view through the row's lens (:func:`.views.front_points_cam`;
    its ghost too, placed in this row's camera), elsewhere as it is."""
    if not front or row.lens is None or not len(mesh.points_cam):
        return mesh
    return replace(mesh, points_cam=front_points_cam(mesh.points_cam, row))


def _outline(coverage: np.ndarray) -> np.ndarray:
    """(H, W) bool: covered pixels with an uncovered 4-neighbour (the silhouette's edge)."""
    inside = coverage > 0.5
    pad = np.pad(inside, 1, constant_values=False)
    interior = pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    return inside & ~interior


def _ghost_over(base: np.ndarray, layer: np.ndarray, style: RenderStyle) -> np.ndarray:
    """Composite a ghost layer faintly (fill at GHOST_ALPHA, opaque dark outline) over (H, W, 3) float."""
    alpha = GHOST_ALPHA * layer[..., 3:4]
    out = base * (1.0 - alpha) + layer[..., :3] * alpha
    edge = _outline(layer[..., 3])
    out[edge] = 0.45 * layer[..., :3][edge] + 0.55 * np.asarray(style.text)
    return out


def person_label(person_id: int, flag: str = "", ids: bool = True) -> str:
    """What is written above a person: its id, and for a person align flagged the flag too (the mark; drawn
    in an outlined box, even without ids).

    >>> person_label(3), person_label(3, "sitting"), person_label(3, "sitting", ids=False), person_label(3, ids=False)
    ('3', '3 sitting', 'sitting', '')
    """
    return " ".join(part for part in (str(int(person_id)) if ids else "", flag) if part)


def _id_labels(img: Any, view: PanelView, row: RowFrame, style: RenderStyle, ids: bool = True,
               taken: list[tuple[float, float, float, float]] | None = None) -> None:
    """Each person's id above its silhouette (panel pixels of its points), in its colour; flagged people
    (:attr:`RowFrame.flagged`) get their flag in an outlined box, and in an orthographic view, when they
    lie off the panel (windows are fitted on the others), an edge marker pointing to them, clear of the
    labels in ``taken`` (the view's annotations) and of the ids."""
    points = front_points_cam(row.points_cam, row) if view.kind == "front" else row.points_cam
    flagged = row.flagged
    if not points.shape[1] or not (ids or flagged):
        return
    draw = ImageDraw.Draw(img, "RGBA")
    W, H = view.size
    f_px = max(9, min(W, H) // 32)
    face = font(f_px)
    step = max(1, points.shape[1] // _LABEL_POINTS)
    colors = person_colors(np.asarray(row.person_ids), style.palette)
    taken = list(taken or [])
    off_panel = []  # flagged people off an orthographic panel: their edge markers come after the labels
    for i, (pts, pid, color) in enumerate(zip(points[:, ::step], row.person_ids, colors)):
        text = person_label(pid, flagged.get(i, ""), ids)
        if not text:
            continue
        pts = pts[np.isfinite(pts).all(axis=1)]
        if view.kind == "front":
            pts = pts[pts[:, 2] > 0]
        if not len(pts):
            continue
        uv = project_view_px(view.clip_from_cam, pts, view.size)
        uv = uv[np.isfinite(uv).all(axis=1)]
        if not len(uv):
            continue
        ink = rgb8(mix(color, style.text, 0.35))
        outline = ink if i in flagged else None
        x, y = float(np.median(uv[:, 0])), float(uv[:, 1].min()) - 2
        if not (0 <= x < W and f_px <= y < H + f_px):
            if outline is not None and view.px_per_m and not _on_panel(uv, view.size):
                off_panel.append((np.median(uv, axis=0), rgb8(color), ink, text))
            continue
        box = draw.textbbox((x, y), text, font=face, anchor="md")
        x += max(0.0, 2 - box[0]) - max(0.0, box[2] + 2 - W)  # the whole label inside the panel
        box = draw.textbbox((x, y), text, font=face, anchor="md")
        draw.rectangle([box[0] - 2, box[1] - 1, box[2] + 2, box[3] + 1], fill=(255, 255, 255, 200), outline=outline,
                       width=1 if outline else 0)
        draw.text((x, y), text, fill=ink, font=face, anchor="md")
        taken.append((box[0] - 2, box[1] - 1, box[2] + 2, box[3] + 1))
    for target_px, fill, ink, text in off_panel:
        edge_marker(draw, view, target_px, fill, ink, text, max(4, min(W, H) // 60), f_px, ink, taken)


def _on_panel(uv: np.ndarray, size: tuple[int, int]) -> bool:
    """Whether any of the (N, 2) panel points is inside a W x H panel."""
    W, H = size
    return bool(np.any((uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)))


def render_panel(row: RowFrame, view: PanelView, rasterize: Any, style: RenderStyle, mesh: _Mesh | None = None,
                 labels: bool = True, ghost_mesh: _Mesh | None = None) -> np.ndarray:
    """One panel: the view's background, the shaded people, the ghost, the view's annotations and
    the person ids (``labels``; flagged people's marks are drawn either way) -> (H, W, 3) uint8. ``mesh`` / ``ghost_mesh``: the row's / its ghost's mesh when
    already flattened (mesh rows: the same in every view)."""
    spec = REGISTRY[view.kind]
    W, H = view.size
    img = Image.new("RGB", (W, H), rgb8(style.background))
    spec.under(img, view, row, style)
    front = view.kind == "front"
    layer = _mesh_layer(_in_view(mesh if mesh is not None and row.kind == "mesh" else _row_mesh(row, style, view), row,
                                 front), view, rasterize)
    base = np.asarray(img, dtype=np.float32) / 255.0
    alpha = layer[..., 3:4]
    out = base * (1.0 - alpha) + layer[..., :3] * alpha
    if row.ghost is not None and spec.shows_ghost:
        ghost = ghost_mesh if ghost_mesh is not None and row.ghost.kind == "mesh" else _row_mesh(row.ghost, style, view)
        out = _ghost_over(out, _mesh_layer(_in_view(ghost, row, front), view, rasterize), style)
    img = Image.fromarray(np.round(255.0 * np.clip(out, 0.0, 1.0)).astype(np.uint8))
    annotations = spec.over(img, view, row, style)
    _id_labels(img, view, row, style, labels, annotations)  # ids (``labels``), and the flagged people's marks always
    return np.asarray(img)


def render_grid(rows: list[RowFrame], views: tuple[str, ...], size: tuple[int, int], rasterize: Any,
                style: RenderStyle, extents: Any = None, title: str = "", labels: bool = True) -> np.ndarray:
    """Figure: one row per RowFrame, one column per view -> (H_total, W_total, 3) uint8,
    ``W_total = W * views``, ``H_total = LABEL_PX + rows * (LABEL_PX + H)``.

    extents: the views' windows, one mapping shared by every row or a list of one per row
    (default: one fitted to these rows).
    """
    specs = view_specs(views)
    extents = extents if extents is not None else scene_extents(rows, views, size, style.margin)
    per_row = list(extents) if isinstance(extents, (list, tuple)) else [extents] * len(rows)
    W, H = size
    fig = Image.new("RGB", (W * len(specs), LABEL_PX + (LABEL_PX + H) * len(rows)), (255, 255, 255))
    draw = ImageDraw.Draw(fig)
    face = font(LABEL_PX * 6 // 10)
    small = font(LABEL_PX * 5 // 10)
    ink = rgb8(style.text)
    flattened: dict[int, _Mesh] = {}  # mesh rows, flattened once (a ghost is drawn over every other row)

    def flat(row: RowFrame | None) -> _Mesh | None:
        if row is None or row.kind != "mesh":
            return None
        if id(row) not in flattened:
            flattened[id(row)] = _row_mesh(row, style)
        return flattened[id(row)]

    for j, spec in enumerate(specs):
        draw.text((W * j + W / 2, LABEL_PX / 2), spec.title, fill=ink, font=face, anchor="mm")
    if title:
        draw.text((4, LABEL_PX / 2), title, fill=ink, font=small, anchor="lm")
    for i, row in enumerate(rows):
        top = LABEL_PX + (LABEL_PX + H) * i
        draw.rectangle([0, top, fig.width, top + LABEL_PX - 1], fill=(236, 236, 232))
        draw.text((6, top + LABEL_PX / 2), row.label, fill=ink, font=face, anchor="lm")
        if row.caption:
            x = 6 + draw.textlength(row.label, font=face) + 14
            draw.text((x, top + LABEL_PX / 2), row.caption, fill=ink, font=small, anchor="lm")
        mesh, ghost = flat(row), flat(row.ghost)
        for j, spec in enumerate(specs):
            panel = render_panel(row, spec.panel(row, size, per_row[i]), rasterize, style, mesh, labels, ghost)
            fig.paste(Image.fromarray(panel), (W * j, top + LABEL_PX))
    return np.asarray(fig)
