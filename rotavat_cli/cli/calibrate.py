"""``rotavat calibrate SEQ``: estimate the static camera from the people (2D foot/head points)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..calibration.plumb_lines import fit_plumb_lines, read_lines_file
from ..calibration.residuals import RESIDUAL_KINDS
from ..calibration.options import CalibrateOptions
from ..alignment.camera_gate import what_to_give
from ..calibration.sequence import SequenceCalibration, calibrate_sequence
from ..geometry.camera import camera_parameters
from ..errors import InputError
from ..geometry.focal import CAMERA
from ..formats.model_fit import model_fit_finding
from ..files.outputs import check_output_file
from ..sequence import Sequence, write_camera_yaml
from ..files.yaml_io import read_yaml
from ..words import count
from ._common import (ConfigOpt, FocalMmOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt,
                      check_focal_flags, check_sequence_path, config_for, focal_flag_wins, info, input_sequence, print_json, report, warn)


def run_calibration(seq: Sequence, config: Path | None, quiet: bool, focal_source: str | None = None,
                    lens_options: dict | None = None, **flags) -> SequenceCalibration:
    """Calibrate with defaults < config file < flags (named by their ``calibrate`` config key), printing
    notes and warnings unless quiet (warnings always), and whether the meshes fit their own pixels.

    A focal flag (``focal_px``, ``focal_mm``) replaces the config file's other focal key; ``focal_source``
    says where a given focal came from (default: the flag, ``--focal`` or ``--focal-mm``, else the config key);
    ``lens_options``: a lens from the scene's lines (:func:`_lens_from_lines`: its coefficient, sd and source)."""
    section = focal_flag_wins(config_for(config, "calibrate", **flags), flags.get("focal_px"), flags.get("focal_mm"))
    options = CalibrateOptions.from_config(section)
    if lens_options:
        options = options.replace(**lens_options)
    if focal_source is None and (flags.get("focal_px") is not None or flags.get("focal_mm") is not None):
        focal_source = options.given_focal_source("--focal", "--focal-mm")
    calib = calibrate_sequence(seq, options.replace(focal_source=focal_source) if focal_source else options)
    finding = model_fit_finding(seq)  # meshes that do not fit their own pixels: a wrong model or image size
    if finding is not None:
        warn(finding)
    for note in calib.result.notes:
        info(f"note: {escape(note)}", quiet)
    for warning in calib.result.warnings:
        warn(warning)
    if calib.result.implausible:
        warn(f"implausible camera: {'; '.join(calib.result.implausible)} (fit.implausible; align, render and batch "
             f"refuse it without --accept-camera): {what_to_give(calib.fit_dict())}")
    return calib


_RESIDUAL_HELP = " or ".join(f"{kind.name} ({kind.summary})" for kind in RESIDUAL_KINDS.values()) + "."


def calibrate(
    seq: Annotated[Path, typer.Argument(help="Sequence directory (2D feet_2d/heads_2d, or meshes with their focal).")],
    out: Annotated[Path | None, typer.Option(help="Where to write camera.yaml; default SEQ/camera.yaml.", dir_okay=False)] = None,
    method: Annotated[str | None, typer.Option(help="grid: the paper's 50^3 search exactly; refine: grid + robust refinement.")] = None,
    focal: Annotated[float | None, typer.Option("--focal", help="The camera's known focal length (px). Otherwise it is estimated from the people, unless the sequence says its focal is the camera's own (focal_kind: camera).")] = None,
    focal_mm: FocalMmOpt = None,
    image: Annotated[Path | None, typer.Option("--image", help="A photo taken with the camera (same lens and zoom), or the folder of the sequence's frames (as for render and view: its first frame's image): its EXIF focal length (FocalLengthIn35mmFilm, else FocalLength with FocalPlaneXResolution), carried to the sequence's image size, is the given focal unless --focal or --focal-mm.")] = None,
    estimate_focal: Annotated[bool | None, typer.Option("--estimate-focal", help="Estimate f even when the sequence's focal is the camera's own.")] = None,
    camera_height: Annotated[float | None, typer.Option(help="The camera's known height above the ground (m): fixes the scale; the people's mean stature is estimated and reported.")] = None,
    pitch: Annotated[float | None, typer.Option("--pitch", help="The camera's known pitch (deg, + = looking down).")] = None,
    roll: Annotated[bool | None, typer.Option("--roll/--no-roll", help="Estimate roll (refine) or fix it at 0.")] = None,
    principal_point: Annotated[tuple[float, float] | None, typer.Option(help="Known principal point cx cy (px).")] = None,
    person_height: Annotated[float | None, typer.Option(help="Mean stature sole->crown (m).")] = None,
    height_sd: Annotated[float | None, typer.Option(help="Spread of the stature prior (m).")] = None,
    residual: Annotated[str | None, typer.Option(help=_RESIDUAL_HELP)] = None,
    points: Annotated[str | None, typer.Option(help="auto (boxes when every head is in its foot's column), landmarks (mid-sole, crown) or boxes (bottom-/top-centre of person boxes; refine, head row).")] = None,
    box_depth: Annotated[float | None, typer.Option(help="With --points boxes: box top's extra distance from the camera over the box bottom (m).")] = None,
    distortion: Annotated[bool | None, typer.Option("--distortion/--no-distortion", help="Fit radial lens distortion (refine; division model), kept when the pairs tell it from none. Default: only from fewer than 50 pairs of people of measured stature (--height-sd 0.02 or less).")] = None,
    lens: Annotated[float | None, typer.Option("--lens", help="The lens is known: its division-model coefficient (from a lens profile; negative for barrel). The pairs are undistorted before the fit and camera.yaml carries it.")] = None,
    lens_lines: Annotated[Path | None, typer.Option("--lens-lines", help="The lens from the scene's straight lines: a YAML file {lines: [[[u, v], ...], ...]} of edges clicked in the image (kerbs, door frames, poles), 3+ points each; as --lens with the coefficient that straightens them.", dir_okay=False)] = None,
    focal_prior: Annotated[str | None, typer.Option("--focal-prior", help="lens: the prior of real lenses' focal (docs/calibration.md); none: the people alone (refused when they cannot determine it).")] = None,
    fov_prior: Annotated[float | None, typer.Option("--fov-prior", help="Your own prior on the vertical field of view (deg), instead of the lens prior.")] = None,
    track: Annotated[list[int] | None, typer.Option("--track", help="Calibrate from this person_id only (repeat for several), e.g. a person of known stature with --person-height S --height-sd 0.01.")] = None,
    standing_only: Annotated[bool | None, typer.Option("--standing-only/--all-people", help="Leave out people whose joints say they sit, kneel or bend.")] = None,
    body_axes: Annotated[bool | None, typer.Option("--body-axes/--no-body-axes", help="Use standing bodies' own vertical where the pairs leave the pitch undetermined.")] = None,
    per_frame: Annotated[bool | None, typer.Option("--per-frame/--pooled", help="Also calibrate each frame alone and report the spread.")] = None,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    if from_ and out is None:
        raise InputError("with --from, pass --out FILE for the camera.yaml (the input is not a contract sequence)")
    check_focal_flags(focal, focal_mm)
    if from_ is None:
        check_sequence_path(seq)  # a tool's file given as SEQ: what it is and how to read it, before SEQ/camera.yaml
    target = out or seq / "camera.yaml"
    check_output_file(target, [seq], force, inside_input_ok=("camera.yaml",) if from_ is None else ())
    if sum(v is not None and v is not False for v in (lens, lens_lines, distortion or None)) > 1:
        raise InputError("--lens, --lens-lines and --distortion each set the lens: give one of them")
    with input_sequence(seq, from_, image_size, smpl_model, read_camera=False, quiet=quiet or as_json) as sequence:
        _never_replace_a_given_camera(target, seq, sequence)
        lens_options = {} if lens_lines is None else _lens_from_lines(lens_lines, sequence, principal_point)
        source = None
        if image is not None:
            photo = _photo_focal(image, sequence, given=focal is not None or focal_mm is not None, quiet=quiet or as_json)
            if photo is not None:
                focal, source = photo
        calib = run_calibration(
            sequence, config, quiet or as_json, focal_source=source, method=method, focal_px=focal, focal_mm=focal_mm,
            estimate_focal=estimate_focal,
            camera_height_m=camera_height, pitch_deg=pitch, focal_prior=focal_prior, tracks=list(track) if track else None,
            standing_only=standing_only, body_axes=body_axes,
            estimate_roll=roll, principal_point=list(principal_point) if principal_point else None,
            person_height_m=person_height, person_height_sd_m=height_sd, residual=residual, points=points,
            box_depth_m=box_depth, distortion=distortion, fov_prior_deg=fov_prior, per_frame=per_frame,
            lens_distortion=lens_options.get("lens_distortion", lens), lens_options=lens_options)
    fit = calib.fit_dict()
    write_camera_yaml(target, calib.result.camera, fit)
    cam = calib.result.camera
    summary = {"camera_yaml": str(target), **camera_parameters(cam), "person_height_m": calib.result.person_height_m,
               "fit": fit, "per_frame": calib.per_frame}
    if as_json:
        print_json(summary)
        return
    if not quiet:
        table, line = _table(summary)  # the summary line below the table, not wrapped to its width
        report(table, quiet)
        report(line, quiet)
    report(f"wrote {target}", quiet)


def _lens_from_lines(path: Path, seq: Sequence, principal_point: tuple[float, float] | None) -> dict:
    """The lens that straightens the lines of ``path`` (:func:`~rotavat_cli.calibration.plumb_lines.fit_plumb_lines`,
    about the principal point the fit will use: the given one, else the sequence's, else the image centre), as
    calibration options (the fit's note says it); InputError naming the file when the lines cannot tell it."""
    if seq.image_size is None:
        raise InputError(f"{seq.label}: --lens-lines needs the image size (meta.yaml image_size, or --image-size W H)")
    pp = principal_point if principal_point is not None else seq.intrinsics.principal_point
    try:
        fit = fit_plumb_lines(read_lines_file(path), seq.image_size, None if pp is None else tuple(map(float, pp)))
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None
    return {"lens_distortion": fit.distortion, "lens_distortion_sd": fit.std,
            "lens_source": f"lines {path} ({fit.lines} lines, {fit.rms_px:.2f} px rms)"}


def _photo_focal(image: Path, sequence: Sequence, given: bool, quiet: bool) -> tuple[float, str] | None:
    """The focal (px, on the sequence's images) the EXIF of ``image`` states and its ``focal_source``, or None
    with a note: when --focal/--focal-mm gave one (they win), or its EXIF states none. ``image`` is a photo,
    or a folder of frames (its first frame's image, matched by name as render and view do)."""
    from ..formats.exif import read_photo_focal

    if image.is_dir():
        from ..render.rows import frame_image_path

        if not sequence.frame_names:
            raise InputError(f"{image}: the sequence {sequence.path} has no frame to match an image to")
        image = frame_image_path(image, sequence.frame_names[0])
    photo = read_photo_focal(image)
    if given:
        if photo.focal_px is not None:
            info(f"note: the focal given on the command line wins over {escape(str(image))}'s EXIF ({escape(photo.tags)})",
                 quiet)
        return None
    if photo.focal_px is None:
        info(f"note: {escape(str(image))}: no focal length from its EXIF ({escape(photo.tags)})", quiet)
        return None
    size = sequence.require_image_size()
    return photo.at_size(size), photo.source(size)


def _never_replace_a_given_camera(target: Path, seq: Path, sequence: Sequence) -> None:
    """InputError (even with --force) when ``target`` holds a camera no fit produced: a camera.yaml without
    a ``fit:`` block (ground truth, written by hand), or the own camera.yaml of a sequence that declares
    its focal the camera's (``focal_kind: camera``). The estimate then goes beside it."""
    if not target.is_file():
        return
    try:
        given = read_yaml(target)
    except InputError:
        return  # not a camera at all: check_output_file has already judged it
    declared = target == seq / "camera.yaml" and sequence.focal_kind == CAMERA
    if isinstance(given, dict) and ("fit" not in given or declared):
        why = ("the camera of a sequence that declares it its own (focal_kind: camera)" if declared else
               "a camera no fit produced (no fit: block: ground truth, or written by hand)")
        raise InputError(f"{target}: {why}; calibrate never replaces it (not even with --force): write the estimate "
                         f"beside it: rotavat calibrate {seq} --out {seq.parent / (seq.name + '_camera.yaml')}")


def _table(summary: dict) -> tuple[Table, str]:
    """Rich table of the estimate: each parameter's std, "given"/"declared"/... when it was not
    estimated, "undetermined" when the people could not determine it."""
    fit = summary["fit"]
    std, fixed, by = fit.get("std", {}), fit.get("fixed", {}), fit.get("determined_by", {})
    table = Table(title=f"camera ({fit.get('method')}, focal {fit.get('focal_policy')})")
    spread = summary.get("per_frame") or {}
    for col in ("parameter", "value", "± std", "from") + (("alone: median (IQR)",) if spread else ()):
        table.add_column(col)
    rows = [("focal_px", "px"), ("pitch_deg", "°"), ("roll_deg", "°"), ("height_m", "m")]
    if fit.get("person_height") == "estimated":
        rows.append(("person_height_m", "m"))
    open_ = _undetermined_keys(fit)
    for key, unit in rows:
        alone = [_spread_cell(spread, key, unit)] if spread else []
        value = "undetermined" if key in open_ else f"{summary[key]:.3f} {unit}"
        table.add_row(key, value, _std_cell(std.get(key), fixed.get(key)), by.get(key, ""), *alone)
    if "distortion" in fit:
        table.add_row("distortion", f"{fit['distortion']:+.4f}", _std_cell(std.get("distortion"), None))
    elif fit.get("lens"):
        lens = fit["lens"]
        table.add_row("distortion", f"{lens['distortion']:+.4f}", f"± {lens['sd']:.4f}", str(lens["from"]).split(" (")[0])
    mesh = (f"; meshes made with f {fit['mesh_focal_px']:.0f} px ({fit['mesh_focal_kind']})"
            if fit.get("mesh_focal_px") is not None else "")
    given = f"; focal from {fit['focal_source']}" if fit.get("focal_source") else ""
    alone = (f"; {spread['frames_fitted']} frames calibrated alone ({spread['frames_skipped']} skipped)"
             if spread else "")
    return table, (f"{fit.get('inliers')}/{count(fit.get('pairs'), 'pair')} inliers over "
                   f"{count(fit.get('frames'), 'frame')}, head rmse {fit.get('rmse_px', float('nan')):.2f} px, points "
                   f"{fit.get('points', 'landmarks')}{given}{mesh}{alone}")


def _undetermined_keys(fit: dict) -> set[str]:
    """Parameters the plausibility checks call undetermined (fit.implausible): shown as such, never as a value."""
    words = {"focal length undetermined": "focal_px", "pitch undetermined": "pitch_deg",
             "roll undetermined": "roll_deg", "camera height undetermined": "height_m"}
    return {key for finding in fit.get("implausible", []) for text, key in words.items() if finding.startswith(text)}


def _spread_cell(spread: dict, key: str, unit: str) -> str:
    """A parameter's median over the frames calibrated alone and its interquartile range."""
    median, iqr = (spread.get(k, {}).get(key) for k in ("median", "iqr"))
    if median is None or iqr is None or not np.isfinite(median):
        return "n/a"
    return f"{median:.3f} ({iqr:.3f}) {unit}"


def _std_cell(sd: float | None, fixed: str | None) -> str:
    """The ± column: why a parameter was not estimated, or its std ("undetermined" when infinite)."""
    if fixed is not None:
        return f"fixed: {fixed}"
    if sd is None or np.isnan(sd):
        return "n/a"
    return "undetermined" if np.isinf(sd) else f"{sd:.3f}"
