"""Synthetic static-camera scenes: ground truth and an HPS-like prediction (:mod:`.scene`), made of the
packaged library of realistic bodies (:mod:`.bodies`), the people placed by a layout (:mod:`.layouts`)."""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".bodies": ("BODIES_PATH", "BodyLibrary", "load_bodies"),
    ".layouts": ("LAYOUTS",),
    ".scene": (
        "HPS_FOCAL_CHOICES", "SynthOptions", "hps_focal_px", "random_camera", "sample_walks", "synth_frames",
        "write_synth_scene"
    ),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
