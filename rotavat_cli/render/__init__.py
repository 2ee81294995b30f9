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

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".export": (
        "R_CV_FROM_GL", "build_scene", "export_frame", "frustum_segments_world", "glb_bytes", "gltf_camera",
        "ground_quad_world", "read_glb_json", "world_from_gl_camera", "write_glb"
    ),
    ".fallback": ("rasterize_numpy",),
    ".geometry": (
        "FrontCrop", "OrthoExtent", "PanelView", "clip_from_cam_perspective", "clip_from_world_ortho",
        "fit_front_crop", "fit_ortho_extent", "horizontal_forward_world", "ndc_to_px", "nice_length_m",
        "panel_px_per_m", "paste_boxes_px", "project_view_px"
    ),
    ".gl": ("GL_SYSTEM_PACKAGES",),
    ".grid": ("LABEL_PX", "person_label", "render_grid", "render_panel", "row_shapes"),
    ".raster": ("RENDERERS", "Rasterizer", "open_rasterizer"),
    ".rows": (
        "IMAGE_SUFFIXES", "people_flags", "read_row", "row_labels", "select_frames", "sequence_camera",
        "sequence_layout"
    ),
    ".sequences": (
        "GHOSTS", "SCALES", "FigureOptions", "FigureSummary", "figure_steps", "flagged_caption", "ground_truth_row",
        "metrics_caption", "render_sequences"
    ),
    ".skeleton": ("BONE_FAMILIES", "Shapes", "layout_bones", "layout_name", "point_shapes", "skeleton_shapes"),
    ".tracks": ("Tracks", "plot_tracks", "sequence_tracks"),
    ".video": ("MP4_INSTALL", "require_mp4", "write_gif", "write_mp4"),
    ".style": ("RenderStyle", "parse_color", "person_colors", "shade_vertices", "vertex_normals"),
    ".views": (
        "FITS", "REGISTRY", "VIEWS", "Ortho", "RowFrame", "View", "camera_numbers", "front_view", "ortho_basis_world",
        "ortho_bounds", "ortho_view", "parse_views", "scene_extents", "view_specs"
    ),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
