"""``rotavat align SEQ``: RotAvat on every mesh of a sequence (``--in SEQ`` is the same)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..alignment.camera_choice import CALIBRATED, GIVEN, AlignCamera, camera_for_align
from ..alignment.options import AlignOptions
from ..alignment.camera_gate import align_remedies, check_align_camera, implausible_findings, reader_flags, what_to_give
from ..alignment.align import align_sequence
from ..calibration.plausibility import MEAN_STATURE_RANGE_M
from ..errors import InputError, input_errors
from ..bodies.measure import stature_provenance
from ..files.outputs import check_output_dir
from ..parallel import cpu_count
from ..sequence import Sequence, read_camera_yaml
from ..words import count
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, config_for,
                      default_output, info, input_sequence, print_json, progress_bar, progress_enabled, report, warn)
from .calibrate import run_calibration


def align(
    seq: Annotated[Path | None, typer.Argument(help="Input sequence directory (never modified); with --from the HPS tool's output.", show_default=False)] = None,
    in_: Annotated[Path | None, typer.Option("--in", help="The same as SEQ (kept for scripts written for earlier versions).")] = None,
    camera: Annotated[Path | None, typer.Option(help="camera.yaml to use; default SEQ/camera.yaml, else calibrate first.", dir_okay=False)] = None,
    out: Annotated[Path | None, typer.Option(help="Output directory; default SEQ_aligned beside the input (with --from: in the current folder).", file_okay=False)] = None,
    upright: Annotated[str | None, typer.Option(help="paper: rotate in the camera-foot-head plane (pixels unchanged); full: true vertical.")] = None,
    height_from: Annotated[str | None, typer.Option(help="frame: each mesh keeps its stature; track: median stature per person_id.")] = None,
    jobs: Annotated[int | None, typer.Option(help="Worker processes for the frames (0 = one per core; never more than the cores).", min=0)] = None,
    accept_camera: Annotated[bool, typer.Option("--accept-camera", help="Use the camera even if its calibration found it implausible (its camera.yaml fit lists implausible findings): a warning names them, and the output's camera.yaml records that you accepted it.")] = False,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    if seq is None and in_ is None:
        raise InputError("rotavat align: missing the input sequence SEQ (see rotavat align --help)")
    if seq is not None and in_ is not None and seq != in_:
        raise InputError(f"rotavat align: two inputs given ({seq} and --in {in_}): give one")
    seq = seq if seq is not None else in_
    out_given = out
    with input_errors("align"):
        options = AlignOptions.from_config(config_for(config, "align", upright=upright, height_from=height_from, jobs=jobs))
    out = out or default_output(seq, "_aligned", from_)
    check_output_dir(out, [seq, *([camera] if camera else [])], force)
    if options.jobs > cpu_count():
        info(f"jobs {options.jobs}: using at most {cpu_count()} workers (one per core)", quiet or as_json)
    with input_sequence(seq, from_, image_size, smpl_model, quiet=quiet or as_json) as sequence:
        given = None if camera is None else AlignCamera(*read_camera_yaml(camera, sequence.image_size), GIVEN, str(camera))

        def calibrate(s: Sequence) -> AlignCamera:
            calib = run_calibration(s, config, quiet or as_json)
            return AlignCamera(calib.result.camera, calib.fit_dict(), CALIBRATED, "calibrated from the people")

        chosen = camera_for_align(sequence, given, calibrate)
        remedies = align_remedies(seq, out_given, reader_flags(from_, image_size, smpl_model), config)
        chosen, camera_warning = check_align_camera(chosen, str(seq), accept_camera, remedies)  # refused: exit 2
        if camera_warning and not (quiet or as_json):  # one line, never wrapped: logs keep the findings together
            warn(camera_warning)
        with progress_bar("aligning", len(sequence), progress_enabled(quiet, as_json)) as advance:
            summary = align_sequence(sequence, chosen.camera, out, options, camera_fit=chosen.fit or None, progress=advance,
                                     force=force)
    origin = chosen.source
    group_lo, group_hi = MEAN_STATURE_RANGE_M  # the same rule as calibrate's for a given camera height
    plausible = not summary.in_medians or group_lo <= summary.median_stature_m <= group_hi
    result = {"out": str(out), "camera": origin, "camera_implausible": list(implausible_findings(chosen.fit)),
              **{k: v for k, v in vars(summary).items() if k != "out" and not k.startswith("_")},
              "in_medians": summary.in_medians,
              "median_stature_plausible": plausible}
    if as_json:
        print_json(result)
        return
    flagged = sum(summary.flagged.values())
    report(f"aligned {summary.aligned} of {count(summary.people, 'person', 'people')} in "
           f"{count(summary.frames, 'frame')} ({flagged} flagged"
         + (": " + ", ".join(f"{k} {v}" for k, v in summary.flagged.items()) if flagged else "") + ")", quiet)
    if summary.implausible:
        lo, hi = options.stature_range_m
        warn(f"{count(summary.implausible, 'aligned person has', 'aligned people have')} a stature outside {lo:g}-{hi:g} m "
             "(implausible_stature in people.csv): check the camera, or those people's detections")
    if not plausible:
        warn(f"the aligned people's median stature {summary.median_stature_m:.2f} m is outside {group_lo:g}-{group_hi:g} m: "
             f"the camera is wrong ({what_to_give(chosen.fit, remedies.calibrate)}), or these are not adults standing")
    if summary.not_standing:
        info(f"note: {summary.not_standing} aligned people do not stand, by their joints (sitting, kneeling or bending "
             "in people.csv's flag): their feet are on the ground, but their implied stature means nothing and the "
             "medians leave them out", quiet)
    if summary.cut:
        info(f"note: {count(summary.cut, 'person-frame is', 'person-frames are')} cut by the image border (cut_by_border "
             "in people.csv's flag: foot or crown outside the image or at its edge): left where their tool put them, "
             "since no seen foot re-seats them", quiet)
    if summary.flight:
        info(f"note: {count(summary.flight, 'person-frame is', 'person-frames are')} in the air (flight in "
             "people.csv's flag: a run of a track's frames whose foot is above the ground for its stature): aligned at "
             "their height above the ground (foot_height_m), left out of the medians", quiet)
    if summary.in_medians:
        report(f"median depth correction x{summary.median_depth_scale:.3f} ({summary.median_abs_depth_change_pct:.1f}%), "
               f"median tilt removed {summary.median_rotation_deg:.2f}°, median stature {summary.median_stature_m:.2f} m "
               f"({stature_provenance(chosen.fit)}); "
               f"foot and crown keep their pixels, the other points move {summary.median_drift_px:.0f} px (median), "
               f"{summary.max_drift_px:.0f} px at most (people.csv: drift_mean_px, drift_max_px)", quiet)
    report(f"camera: {origin}; wrote {out} (frames, camera.yaml, people.csv)", quiet)
