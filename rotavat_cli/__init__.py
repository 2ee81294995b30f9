"""rotavat: auto-calibrate a static camera from its people, re-seat HPS meshes on the ground, score them.

The command line (``rotavat``) is a thin layer over this API:

>>> from rotavat_cli import Camera, rotavat_transforms
>>> cam = Camera((640, 480), 500.0, None, 0.3, 0.0, 4.0)
>>> round(cam.height_m, 1)
4.0

Each name below is imported from its module when first used (:mod:`rotavat_cli.lazy`), so
``import rotavat_cli`` costs nothing and ``rotavat --help`` loads no numpy. Where each rule lives:
docs/architecture.md.
"""

from .lazy import public_names
from .version import __version__

# Each public name and the module that defines it.
_PUBLIC = {
    ".alignment.align": ("AlignSummary", "align_frame", "align_sequence", "track_statures"),
    ".alignment.options": ("AlignOptions",),
    ".alignment.transform": ("AlignTransform", "apply_transforms", "rotavat_transforms"),
    ".batch.driver": ("run_batch",),
    ".batch.plan": ("BatchOptions",),
    ".calibration.fit": ("CalibrationResult", "fit_camera"),
    ".calibration.options": ("CalibrateOptions",),
    ".calibration.pairs": ("gather_pairs",),
    ".calibration.sequence": ("calibrate_sequence",),
    ".geometry.camera": ("Camera", "camera_from_yaml_dict", "camera_to_yaml_dict"),
    ".settings.config": ("default_config", "load_config"),
    ".errors": ("DegenerateSceneError", "GateError", "InputError", "RotavatError"),
    ".formats.convert": ("import_sequence", "imported_sequence"),
    ".formats.registry": ("available_formats", "detect_format"),
    ".bodies.landmarks": ("foot_head_points",),
    ".metrics.evaluate": ("EvalOptions", "EvalResult", "evaluate"),
    ".metrics.points": ("mpjpe", "procrustes_align", "pve"),
    ".render.export": ("export_frame",),
    ".render.sequences": ("FigureOptions", "render_sequences"),
    ".sequence": (
        "Frame", "Intrinsics", "Sequence", "open_sequence", "read_camera_yaml", "write_camera_yaml", "write_frame"
    ),
    ".synth.scene": ("SynthOptions", "write_synth_scene"),
}
__getattr__, __dir__, _names = public_names(__name__, _PUBLIC)
__all__ = ["__version__", *_names]
