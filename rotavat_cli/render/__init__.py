"""Pictures and 3D scenes of people in a static camera: ``rotavat render`` and ``rotavat export``.

Modules (docs/render.md):

- :mod:`.views`: the view registry (front, side, top: one :class:`View` entry each) and how a
  view projects a :class:`RowFrame`; :mod:`.geometry`: the clip-space maths they share;
- :mod:`.style`: colours, palette, shading (:class:`RenderStyle`);
- :mod:`.raster`: the renderer choice (:func:`open_rasterizer`) between :mod:`.gl` (OpenGL via
  EGL) and :mod:`.fallback` (NumPy z-buffer);
- :mod:`.grid`: panels and the rows x views grid; :mod:`.rows`: rows read from sequences;
- :mod:`.skeleton`: people without triangles (skeletons from the joint layout, point clouds) as small meshes;
- :mod:`.sequences`: :func:`render_sequences` (what ``rotavat render`` runs) and its options;
- :mod:`.video` (GIF, MP4 with the ``rotavat[video]`` extra), :mod:`.tracks` (per-track plots over time);
- :mod:`.export`: glTF scenes, :func:`export_frame` (what ``rotavat export`` runs).
"""

from __future__ import annotations

from .export import (R_CV_FROM_GL, build_scene, export_frame, frustum_segments_world, glb_bytes, gltf_camera,
                     ground_quad_world, read_glb_json, world_from_gl_camera, write_glb)
from .fallback import rasterize_numpy
from .geometry import (FrontCrop, OrthoExtent, PanelView, clip_from_cam_perspective, clip_from_world_ortho,
                       fit_front_crop, fit_ortho_extent, horizontal_forward_world, ndc_to_px, nice_length_m,
                       panel_px_per_m, paste_boxes_px, project_view_px)
from .gl import GL_SYSTEM_PACKAGES
from .grid import LABEL_PX, person_label, render_grid, render_panel, row_shapes
from .raster import RENDERERS, Rasterizer, open_rasterizer
from .rows import IMAGE_SUFFIXES, people_flags, read_row, row_labels, select_frames, sequence_camera, sequence_layout
from .sequences import (GHOSTS, SCALES, FigureOptions, FigureSummary, figure_steps, flagged_caption, ground_truth_row,
                        metrics_caption, render_sequences)
from .skeleton import BONE_FAMILIES, Shapes, layout_bones, layout_name, point_shapes, skeleton_shapes
from .tracks import Tracks, plot_tracks, sequence_tracks
from .video import MP4_INSTALL, require_mp4, write_gif, write_mp4
from .style import RenderStyle, parse_color, person_colors, shade_vertices, vertex_normals
from .views import (FITS, REGISTRY, VIEWS, Ortho, RowFrame, View, camera_numbers, front_view, ortho_basis_world,
                    ortho_bounds, ortho_view, parse_views, scene_extents, view_specs)

__all__ = [
    # views
    "REGISTRY",
    "VIEWS",
    "FITS",
    "camera_numbers",
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
    "FrontCrop",
    "PanelView",
    "fit_front_crop",
    "panel_px_per_m",
    "paste_boxes_px",
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
    "row_shapes",
    "person_label",
    "LABEL_PX",
    "IMAGE_SUFFIXES",
    "select_frames",
    "row_labels",
    "sequence_camera",
    "sequence_layout",
    "read_row",
    "people_flags",
    "FigureOptions",
    "FigureSummary",
    "SCALES",
    "GHOSTS",
    "render_sequences",
    "figure_steps",
    "ground_truth_row",
    "metrics_caption",
    "flagged_caption",
    # people without triangles
    "BONE_FAMILIES",
    "Shapes",
    "layout_name",
    "layout_bones",
    "skeleton_shapes",
    "point_shapes",
    # animations and plots
    "MP4_INSTALL",
    "require_mp4",
    "write_gif",
    "write_mp4",
    "Tracks",
    "sequence_tracks",
    "plot_tracks",
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
