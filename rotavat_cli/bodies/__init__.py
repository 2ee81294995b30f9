"""People's bodies: where a mesh stands (foot point, crown), each joint layout's names, who stands, sits or lies,
statures through a camera, and a frame's foot points and crowns.

Modules (docs/architecture.md):

- :mod:`.landmarks`: foot point (the ground contact) and crown of a mesh; the one rule (`ground_contact`);
- :mod:`.joint_layouts`: the joint names of each 2D/3D layout;
- :mod:`.posture`: who stands, sits, kneels or bends, from the joints;
- :mod:`.measure`: statures from a camera, and where their scale comes from;
- :mod:`.frame_points`: each person's foot point and crown in a frame (meshes, joints or 2D points).
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".landmarks": (
        "SMPL_JOINT_NAMES", "Topology", "SMPL", "SMPLX", "register_topology", "topology_for", "topology_from_npz",
        "foot_head_points", "FULL_RAISE", "SHARED_RAISE", "contact_weights", "ground_contact", "sole_crown_points",
        "DEFAULT_UP_HINT_CAM"
    ),
    ".joint_layouts": ("LAYOUT_NAMES", "layout_by_count", "layout_key"),
    ".posture": (
        "KNEE_DOWN_MAX", "PELVIS_LOW_MAX", "PELVIS_SEATED_MAX", "POSTURES", "POSTURE_JOINTS", "PostureMeasures",
        "THIGH_SEATED_MIN_RAD", "TRUNK_BEND_MAX_RAD", "classify_postures", "posture_measures", "posture_reasons",
        "postures", "standing_mask", "summarize_postures"
    ),
    ".measure": (
        "statures_from_camera_m", "TrackStatures", "statures_by_track", "SCALE_SOURCES", "REFERENCE_SD_MAX_M",
        "scale_source", "source_words", "stature_provenance"
    ),
    ".frame_points": (
        "EDGE_MARGIN_FRACTION", "EDGE_MARGIN_MIN_PX", "MeshIntrinsics", "beyond_border_px", "edge_margin_px",
        "in_view", "joints_foot_head_cam", "frame_foot_head_cam"
    ),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
