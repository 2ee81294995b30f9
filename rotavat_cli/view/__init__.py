"""Interactive 3D recordings of sequences over time: ``rotavat view`` writes a Rerun recording (.rrd).

Modules (docs/render.md, "rotavat view"):

- :mod:`.scene`: what the recording shows besides the people, in world metres (ground grid and ticks,
  other grounds as planes, the camera's label, track paths); pure numpy;
- :mod:`.recording`: :func:`record_sequences` (what ``rotavat view`` runs) and its options: the scene camera,
  the frames streamed one at a time, what is kept for the end (tracks' paths and series);
- :mod:`.writer`: the Rerun calls (:class:`RecordingWriter`), the viewer's layout, and the one import of Rerun
  (the optional extra ``rotavat[view]``: :func:`require_rerun`);
- :mod:`.roles`: each row's role (aligned, truth, raw), which rows the 3D view starts framed on, each row's tint;
- :mod:`.detail`: how much of a frame is stored (meshes reduced, point clouds thinned, video frames scaled down).
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".scene": (
        "EYE_FOV_Y_DEG", "GRID_MARGIN_M", "MAX_GRID_LINES", "camera_label", "eye_world", "grid_lines_world", "grid_step_m",
        "grid_ticks_world", "ground_extent_m", "label_anchors_world", "plane_quad_world", "tilted_square_world",
        "track_strips", "uncertainty_cameras", "world_points_f32"
    ),
    ".recording": ("ViewOptions", "ViewSummary", "record_sequences", "view_steps"),
    ".writer": ("RERUN_INSTALL", "SERIES", "WORLD", "RecordingWriter", "blueprint", "require_rerun"),
    ".roles": ("ROLES", "RowTone", "framed_rows", "row_role", "row_tint", "row_tones"),
    ".detail": ("MeshReduction", "reduce_mesh", "thin_points", "video_frame"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
