"""``rotavat measure SEQ``: each person's stature (m) from the sequence's calibrated camera."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from ..files.atomic import atomic_open
from ..calibration.pairs import gather_pairs
from ..geometry.camera import Camera
from ..errors import InputError
from ..bodies.measure import TrackStatures, scale_source, stature_provenance, statures_by_track, statures_from_camera_m
from ..bodies.stature_error import StatureErrors, stature_errors
from ..files.outputs import check_output_file
from ..plain import csv_cell
from ..sequence import Sequence, read_camera_yaml
from ._common import (ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, console, default_output,
                      input_sequence, print_json, report)

CSV_COLUMNS = ("track_id", "pairs", "median_stature_m", "spread_m", "stature_from", "std_m", "std_camera_m",
               "std_pixels_m", "extrapolated")
# How every CSV this command writes starts (the overwrite check): the columns of its first version, which later
# columns follow, so that an earlier version's file is still recognised as rotavat's.
CSV_SIGNATURE = ",".join(CSV_COLUMNS[:4])
UNTRACKED = -1  # the track of pairs without a person id (every pair, when some frame has no person_ids)


def measure(
    seq: Annotated[Path, typer.Argument(help="Sequence directory (2D feet_2d/heads_2d with person_ids, or meshes with their focal); with --from the HPS tool's output.")],
    camera: Annotated[Path | None, typer.Option(help="camera.yaml to measure with; default SEQ/camera.yaml (made by `rotavat calibrate SEQ`).", dir_okay=False)] = None,
    out: Annotated[Path | None, typer.Option(help="Per-track CSV; default SEQ_measure.csv beside the input (with --from: in the current folder).", dir_okay=False)] = None,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    out = out or default_output(seq, "_measure.csv", from_)
    check_output_file(out, [seq, *([camera] if camera else [])], force, signature=CSV_SIGNATURE.encode())
    quiet_notes = quiet or as_json
    with input_sequence(seq, from_, image_size, smpl_model, read_camera=camera is None, quiet=quiet_notes) as sequence:
        cam, fit, origin = _camera(sequence, camera, from_)
        pairs = gather_pairs(sequence)
    statures_m = statures_from_camera_m(pairs.feet_px, pairs.heads_px, cam)
    cut = np.zeros(len(statures_m), bool) if pairs.cut is None else pairs.cut
    statures_m[cut] = np.nan  # a person cut by the border has no seen foot or crown: nothing to measure
    ids = pairs.person_ids if pairs.tracked else np.full(len(statures_m), UNTRACKED, np.int64)
    ids = np.where(ids < 0, UNTRACKED, ids)
    tracks = statures_by_track(statures_m, ids)
    try:
        errors = stature_errors(pairs.feet_px, pairs.heads_px, statures_m, ids, cam, fit, pairs.frame_index)
    except ValueError as exc:
        raise InputError(f"{origin}: {exc}") from None
    source = scale_source(fit)
    _write_csv(out, tracks, source, errors)
    _warn(fit, origin, pairs.tracked, statures_m, quiet_notes, int(cut.sum()))
    _note_unknowns(errors, origin, quiet_notes)
    finite = statures_m[np.isfinite(statures_m)]
    people = tracks.median_m[(tracks.ids != UNTRACKED) & (tracks.pairs > 0)]
    summary = {"camera": origin, "csv": str(out), "pairs": len(statures_m), "measured": len(finite),
               "tracked": pairs.tracked, "median_stature_m": float(np.median(finite)) if len(finite) else None,
               "median_of_tracks_m": float(np.median(people)) if len(people) else None,
               "tracks": _track_rows(tracks, errors),
               "camera_uncertainty": "covariance" if errors.camera_known else "unknown",
               "footprint": "known" if errors.footprint_known else "unknown",
               "design_effect": errors.design_effect,
               "stature_from": source, "stature_provenance": stature_provenance(fit), "cut_pairs": int(cut.sum())}
    if as_json:
        print_json(summary)
        return
    report(_table(tracks, errors, summary), quiet)
    report(f"camera: {origin}; wrote {out}", quiet)


def _camera(seq: Sequence, given: Path | None, fmt: str | None) -> tuple[Camera, dict, str]:
    """The camera to measure with, its fit block and how messages name it: ``--camera``, else the
    sequence's own (its camera.yaml, or the camera its format carried), else an InputError naming
    the command that makes one."""
    if given is not None:
        cam, fit = read_camera_yaml(given, seq.image_size)
        origin = str(given)
    elif seq.camera is not None:
        cam, fit, origin = seq.camera, dict(seq.camera_fit or {}), seq.camera_label
    else:
        make = (f"`rotavat calibrate {seq.label}`" if fmt is None else
                f"`rotavat calibrate {seq.label} --from {fmt} --out camera.yaml` and pass --camera camera.yaml")
        raise InputError(f"{seq.label}: no camera to measure with: make one with {make} (or pass --camera FILE)")
    size = seq.image_size
    if size is not None and tuple(size) != tuple(cam.image_size):
        raise InputError(f"{origin}: its image size {cam.image_size[0]}x{cam.image_size[1]} differs from the "
                         f"sequence's {size[0]}x{size[1]} ({seq.label}): not this sequence's camera")
    return cam, fit, origin


def _note(message: str, quiet: bool) -> None:
    """One diagnostic line on stderr unless quiet (never wrapped: logs and tests see one line)."""
    if not quiet:
        console.print(message, highlight=False, soft_wrap=True)


def _warn(fit: dict, origin: str, tracked: bool, statures_m: np.ndarray, quiet: bool, cut: int = 0) -> None:
    """Diagnostics on stderr: a camera its calibration found implausible, pairs not grouped by person,
    pairs of people cut by the image border, pairs that could not be measured."""
    implausible = fit.get("implausible")
    if isinstance(implausible, list) and implausible:
        more = f"; and {len(implausible) - 3} more" if len(implausible) > 3 else ""
        shown = "; ".join(str(v) for v in implausible[:3]) + more
        _note(f"[yellow]warning:[/] {escape(origin)}: its calibration found the camera implausible (fit.implausible: "
              f"{escape(shown)}): statures measured with it may be wrong", quiet)
    if not tracked:
        _note("note: some frames have no person_ids: every pair is pooled into one row (track -1)", quiet)
    if cut:
        _note(f"note: {cut} of {len(statures_m)} pairs are of people cut by the image border (foot or crown outside "
              "it or at its edge): not measured", quiet)
    missing = int(np.isnan(statures_m).sum()) - cut
    if missing:
        _note(f"note: {missing} of {len(statures_m)} pairs could not be measured (foot on or above the horizon, or "
              "head behind the camera)", quiet)


def _note_unknowns(errors: StatureErrors, origin: str, quiet: bool) -> None:
    """One line when the camera carries no covariance or no footprint (a given camera, an older calibration)."""
    missing = [key for key, known in (("fit.covariance", errors.camera_known), ("fit.footprint_px",
                                                                               errors.footprint_known)) if not known]
    if not missing:
        return
    what = []
    if not errors.camera_known:
        what.append("each std is the pixel part only (the camera's own uncertainty is unknown)")
    if not errors.footprint_known:
        what.append("whether a person stands outside what the calibration saw is unknown (none marked extrapolated)")
    _note(f"note: {escape(origin)} has no {' nor '.join(missing)} (a given camera or an older calibration): "
          f"{'; '.join(what)}", quiet)


def _track_rows(tracks: TrackStatures, errors: StatureErrors) -> list[dict]:
    """One plain dict per track: :meth:`TrackStatures.rows` plus std_m, std_camera_m, std_pixels_m, extrapolated."""
    return [{**row, "std_m": float(total), "std_camera_m": float(cam), "std_pixels_m": float(pix),
             "extrapolated": bool(ex)}
            for row, total, cam, pix, ex in zip(tracks.rows(), errors.std_m, errors.std_camera_m, errors.std_pixels_m,
                                               errors.extrapolated)]


def _write_csv(path: Path, tracks: TrackStatures, source: str, errors: StatureErrors) -> None:
    """One row per track (atomic): track_id, pairs, median_stature_m, spread_m (half the IQR), stature_from (where
    the camera's scale comes from: rotavat_cli.bodies.measure.SCALE_SOURCES), std_m (the median's standard
    deviation) with its camera and pixel parts, extrapolated (true/false: rotavat_cli.bodies.stature_error)."""
    with atomic_open(path, "w") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        for row in _track_rows(tracks, errors):
            writer.writerow([row["id"], row["pairs"], csv_cell(row["median_m"]), csv_cell(row["spread_m"]), source,
                             csv_cell(row["std_m"]), csv_cell(row["std_camera_m"]), csv_cell(row["std_pixels_m"]),
                             "true" if row["extrapolated"] else "false"])


def _table(tracks: TrackStatures, errors: StatureErrors, summary: dict) -> Table:
    """Rich table: one row per track (``*``: extrapolated), the overall medians in the caption."""
    table = Table(title="statures (sole to crown)")
    for col in ("track", "pairs", "median m", "± std m", "spread m (½ IQR)"):
        table.add_column(col, justify="right")
    for row in _track_rows(tracks, errors):
        label = ("untracked" if row["id"] == UNTRACKED else str(row["id"])) + (" *" if row["extrapolated"] else "")
        table.add_row(label, str(row["pairs"]), _metres(row["median_m"]), _metres(row["std_m"]),
                      _metres(row["spread_m"]))
    extrapolated = " * extrapolated: standing outside what the calibration saw;" if errors.extrapolated.any() else ""
    table.caption = (f"overall median {_metres(summary['median_stature_m'])} m over {summary['measured']} of "
                     f"{summary['pairs']} pairs; median of the tracks' medians "
                     f"{_metres(summary['median_of_tracks_m'])} m;{extrapolated} statures {summary['stature_provenance']}")
    return table


def _metres(value: float | None) -> str:
    """A stature in metres with 3 decimals (millimetres), 'n/a' when unknown."""
    return "n/a" if value is None or not np.isfinite(value) else f"{value:.3f}"
