"""The camera and its geometry: the pinhole with pitch, roll and height over a flat ground (camera.yaml), batched
rotations, and the focal lengths HPS methods assume.

Modules (docs/architecture.md):

- :mod:`.camera`: the camera model, its world frame and camera.yaml's dict (docs/conventions.md);
- :mod:`.rotations`: batched rotations: axis-angle, matrices, the rotation between two directions;
- :mod:`.focal`: each HPS method's focal rule and the kinds `camera`/`assumed`; 35 mm-equivalent focals.
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".camera": (
        "Camera", "up_vector_cam", "pitch_roll_from_up", "intrinsics_matrix", "project_cam_to_px", "pixel_rays_cam",
        "backproject_px_to_plane", "height_above_ground", "R_cam_from_world_from_up", "horizon_v_px",
        "reexpress_cam", "camera_parameters", "people_not_in_front", "world_to_cam", "ROOT_CENTRED_M",
        "check_camera_bounds", "MAX_IMAGE_SIDE_PX", "MAX_FOCAL_PX", "MAX_HEIGHT_M"
    ),
    ".rotations": ("axis_angle_to_matrix", "cross3", "matrix_to_axis_angle", "rotation_between"),
    ".focal": (
        "FOCAL_KINDS", "CAMERA", "ASSUMED", "BEV_FOCAL_ON_512", "FocalRule", "FOCAL_RULES", "focal_from_rule",
        "hybrik_focal_px", "focal_kind_or_default", "FULL_FRAME_DIAGONAL_MM", "ASPECT_TOLERANCE",
        "focal_px_from_35mm", "focal_px_at_size"
    ),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
