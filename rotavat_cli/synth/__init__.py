"""Synthetic static-camera scenes: ground truth and an HPS-like prediction (:mod:`.scene`), made of the
packaged library of realistic bodies (:mod:`.bodies`), the people placed by a layout (:mod:`.layouts`)."""

from .bodies import BODIES_PATH, BodyLibrary, load_bodies
from .layouts import LAYOUTS
from .scene import (HPS_FOCAL_CHOICES, SynthOptions, hps_focal_px, random_camera, sample_walks, synth_frames,
                    write_synth_scene)

__all__ = ["BODIES_PATH", "BodyLibrary", "load_bodies", "HPS_FOCAL_CHOICES", "LAYOUTS", "SynthOptions", "hps_focal_px",
           "random_camera", "sample_walks", "synth_frames", "write_synth_scene"]
