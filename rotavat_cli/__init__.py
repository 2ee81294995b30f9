"""rotavat: auto-calibrate a static camera from its people, re-seat HPS meshes on the ground, score them.

The command line (``rotavat``) is a thin layer over this API:

>>> from rotavat_cli import Camera, rotavat_transforms
>>> cam = Camera((640, 480), 500.0, None, 0.3, 0.0, 4.0)
>>> round(cam.height_m, 1)
4.0
"""

from __future__ import annotations

__version__ = "0.1.0"

from .alignment import (AlignOptions, AlignSummary, AlignTransform, align_frame, align_sequence, apply_transforms,
                        rotavat_transforms, track_statures)
from .batch import BatchOptions, run_batch
from .calibration import CalibrateOptions, CalibrationResult, calibrate_sequence, fit_camera
from .calibration.pairs import gather_pairs
from .camera import Camera, camera_from_yaml_dict, camera_to_yaml_dict
from .config import default_config, load_config
from .errors import DegenerateSceneError, GateError, InputError, RotavatError
from .formats import available_formats, detect_format, import_sequence, imported_sequence
from .landmarks import foot_head_points
from .metrics import mpjpe, procrustes_align, pve
from .metrics.evaluate import EvalOptions, EvalResult, evaluate
from .render import FigureOptions, export_frame, render_sequences
from .sequence import Frame, Intrinsics, Sequence, open_sequence, read_camera_yaml, write_camera_yaml, write_frame
from .synth import SynthOptions, write_synth_scene

__all__ = [
    "__version__",
    "AlignOptions",
    "AlignSummary",
    "AlignTransform",
    "BatchOptions",
    "CalibrateOptions",
    "CalibrationResult",
    "Camera",
    "DegenerateSceneError",
    "EvalOptions",
    "EvalResult",
    "FigureOptions",
    "Frame",
    "GateError",
    "InputError",
    "Intrinsics",
    "RotavatError",
    "Sequence",
    "SynthOptions",
    "align_frame",
    "align_sequence",
    "available_formats",
    "calibrate_sequence",
    "detect_format",
    "import_sequence",
    "imported_sequence",
    "apply_transforms",
    "camera_from_yaml_dict",
    "camera_to_yaml_dict",
    "default_config",
    "evaluate",
    "export_frame",
    "fit_camera",
    "foot_head_points",
    "gather_pairs",
    "load_config",
    "mpjpe",
    "open_sequence",
    "procrustes_align",
    "pve",
    "read_camera_yaml",
    "render_sequences",
    "rotavat_transforms",
    "run_batch",
    "track_statures",
    "write_camera_yaml",
    "write_frame",
    "write_synth_scene",
]
