"""Synthetic static-camera scenes: ground truth and an HPS-like prediction (:mod:`.scene`), made of the
packaged library of realistic bodies (:mod:`.bodies`)."""

from .bodies import BODIES_PATH, BodyLibrary, load_bodies
from .scene import (HPS_FOCAL_CHOICES, SynthOptions, hps_focal_px, random_camera, sample_walks, synth_frames,
                    write_synth_scene)

__all__ = ["BODIES_PATH", "BodyLibrary", "load_bodies", "HPS_FOCAL_CHOICES", "SynthOptions", "hps_focal_px",
           "random_camera", "sample_walks", "synth_frames", "write_synth_scene"]
