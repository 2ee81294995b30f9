"""``rotavat synth OUT``: write a synthetic scene (ground truth + HPS-like prediction)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ..errors import input_errors
from ..synth.scene import SynthOptions, hps_focal_px, random_camera, write_synth_scene
from ..words import count
from ._common import ConfigOpt, JsonOpt, QuietOpt, config_for, print_json, progress_bar, progress_enabled, report


def synth(
    out: Annotated[Path, typer.Argument(help="Output directory (gets gt/, pred/ and synth.yaml).", file_okay=False)],
    seed: Annotated[int | None, typer.Option(help="Random seed (same seed, same scene).")] = None,
    frames: Annotated[int | None, typer.Option(help="Number of frames.", min=1)] = None,
    people: Annotated[int | None, typer.Option(help="People per frame.", min=0)] = None,
    layout: Annotated[str | None, typer.Option(help="Where people stand: crowd (walking all over the ground), walk (walking across the view at one depth: one passer-by), row (a group photo: side by side at one depth, still; use --frames 1), still (standing about at every depth, swaying and turning on the spot).")] = None,
    image_size: Annotated[tuple[int, int] | None, typer.Option(help="Image width and height (px).")] = None,
    roll: Annotated[float | None, typer.Option("--roll", help="Camera roll (deg); default random in [-3, 3].")] = None,
    camera_height_range: Annotated[tuple[float, float] | None, typer.Option(help="The random camera's height range LO HI (m); a handheld camera: 1.2 2.")] = None,
    pitch_range: Annotated[tuple[float, float] | None, typer.Option(help="The random camera's pitch range LO HI (deg, + = looking down); a handheld camera: -5 15.")] = None,
    noise_px: Annotated[float | None, typer.Option(help="Noise of the 2D detections (px).", min=0)] = None,
    outliers: Annotated[float | None, typer.Option(help="Fraction of gross 2D outliers.", min=0, max=1)] = None,
    hps_focal: Annotated[str | None, typer.Option(help="Focal the HPS prediction assumes: a method's rule (cliff: sqrt(W^2+H^2); bev, romp: 60 deg; 4dhumans: 5000/256 max(W,H)), true (the camera's), or a number of px. Default: cliff.")] = None,
    depth_sd: Annotated[float | None, typer.Option(help="Per-person log-normal depth error of the prediction.", min=0)] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace a non-empty OUT that rotavat did not write.")] = False,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    opts = config_for(config, "synth", seed=seed, frames=frames, people=people, layout=layout,
                      image_size=list(image_size) if image_size else None, roll_deg=roll,
                      camera_height_range_m=list(camera_height_range) if camera_height_range else None,
                      pitch_range_deg=list(pitch_range) if pitch_range else None, noise_px=noise_px,
                      outliers=outliers, hps_focal=hps_focal, depth_sd=depth_sd)
    with input_errors("synth"):
        options = SynthOptions.from_config(opts)
    with input_errors("--hps-focal"):
        hps_focal_px(options.hps_focal, random_camera(np.random.default_rng(0), options.image_size))
    with input_errors(str(out)), progress_bar("synthesising", options.frames, progress_enabled(quiet, as_json)) as advance:
        summary = write_synth_scene(out, options, advance, force)
    if as_json:
        print_json(summary)
    cam = summary["camera"]
    report(f"wrote {count(summary['frames'], 'frame')} x {count(summary['people'], 'person', 'people')} ({summary['layout']}) to {out}/gt and {out}/pred "
         f"(camera: f {cam['focal_px']:.0f} px, pitch {cam['pitch_deg']:.1f}°, roll {cam['roll_deg']:.1f}°, "
         f"height {cam['height_m']:.2f} m; HPS focal {summary['hps_focal_px']:.0f} px, rule "
         f"{summary['hps_focal_rule']})", quiet or as_json)
