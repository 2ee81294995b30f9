"""Pictures and 3D scenes of people in a static camera: ``rotavat render`` and ``rotavat export``.

Modules (docs/render.md):

- :mod:`.views`: the view registry (front, side, top: one :class:`View` entry each) and how a
  view projects a :class:`RowFrame`; :mod:`.geometry`: the clip-space maths they share;
- :mod:`.style`: colours, palette, shading (:class:`RenderStyle`);
- :mod:`.raster`: the renderer choice (:func:`open_rasterizer`) between :mod:`.gl` (OpenGL via
  EGL) and :mod:`.fallback` (NumPy z-buffer);
- :mod:`.grid`: panels and the rows x views grid; :mod:`.rows`: rows read from sequences;
- :mod:`.sequences`: :func:`render_sequences` (what ``rotavat render`` runs) and its options;
- :mod:`.export`: glTF scenes, :func:`export_frame` (what ``rotavat export`` runs).
"""

from __future__ import annotations

from .export import (R_CV_FROM_GL, build_scene, export_frame, frustum_segments_world, glb_bytes, gltf_camera,
                     ground_quad_world, read_glb_json, world_from_gl_camera, write_glb)
from .fallback import rasterize_numpy
from .geometry import (OrthoExtent, PanelView, clip_from_cam_perspective, clip_from_world_ortho, fit_ortho_extent,
                       horizontal_forward_world, ndc_to_px, nice_length_m, project_view_px)
from .gl import GL_SYSTEM_PACKAGES
from .grid import render_grid, render_panel
from .raster import RENDERERS, Rasterizer, open_rasterizer
from .rows import IMAGE_SUFFIXES, read_row, row_labels, select_frames, sequence_camera
from .sequences import FigureOptions, FigureSummary, render_sequences
from .style import RenderStyle, parse_color, person_colors, shade_vertices, vertex_normals
from .views import (REGISTRY, VIEWS, Ortho, RowFrame, View, front_view, ortho_basis_world, ortho_bounds, ortho_view,
                    parse_views, scene_extents, view_specs)

__all__ = [
    # views
    "REGISTRY",
    "VIEWS",
    "View",
    "Ortho",
    "RowFrame",
    "view_specs",
    "parse_views",
    "front_view",
    "ortho_view",
    "ortho_basis_world",
    "ortho_bounds",
    "scene_extents",
    # geometry
    "OrthoExtent",
    "PanelView",
    "clip_from_cam_perspective",
    "clip_from_world_ortho",
    "fit_ortho_extent",
    "horizontal_forward_world",
    "ndc_to_px",
    "nice_length_m",
    "project_view_px",
    # style
    "RenderStyle",
    "parse_color",
    "person_colors",
    "shade_vertices",
    "vertex_normals",
    # rasterisers
    "RENDERERS",
    "GL_SYSTEM_PACKAGES",
    "Rasterizer",
    "open_rasterizer",
    "rasterize_numpy",
    # grids and figures
    "render_panel",
    "render_grid",
    "IMAGE_SUFFIXES",
    "select_frames",
    "row_labels",
    "sequence_camera",
    "read_row",
    "FigureOptions",
    "FigureSummary",
    "render_sequences",
    # glTF
    "R_CV_FROM_GL",
    "build_scene",
    "export_frame",
    "frustum_segments_world",
    "glb_bytes",
    "gltf_camera",
    "ground_quad_world",
    "read_glb_json",
    "world_from_gl_camera",
    "write_glb",
]
