"""rotavat: auto-calibrate a static camera from its people, re-seat HPS meshes on the ground, score them."""

from __future__ import annotations

__version__ = "0.1.0"

from .camera import Camera, camera_from_yaml_dict, camera_to_yaml_dict
from .config import load_config
from .errors import DegenerateSceneError, GateError, InputError, RotavatError
from .sequence import Frame, Intrinsics, Sequence, open_sequence, read_camera_yaml, write_camera_yaml, write_frame

__all__ = [
    "__version__",
    "Camera",
    "camera_from_yaml_dict",
    "camera_to_yaml_dict",
    "load_config",
    "RotavatError",
    "InputError",
    "DegenerateSceneError",
    "GateError",
    "Frame",
    "Intrinsics",
    "Sequence",
    "open_sequence",
    "read_camera_yaml",
    "write_camera_yaml",
    "write_frame",
]
