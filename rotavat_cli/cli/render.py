"""``rotavat render SEQ [SEQ2 ...]``: front / side / top pictures of the people, one grid row per sequence."""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from ..alignment.camera_gate import reader_flags
from ..files.atomic import staged_directory
from ..errors import input_errors
from ..files.outputs import check_output_dir
from ..render.views import FITS, VIEWS
from ..render.sequences import GHOSTS, SCALES, FigureOptions, figure_steps, render_sequences
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, config_for, console,
                      default_output, input_sequence, print_json, progress_bar, progress_enabled, report, warn)


def render(
    seqs: Annotated[list[Path], typer.Argument(help="Sequence directories: one grid row each (e.g. pred/ pred_aligned/); with --from the first is the HPS tool's output.")],
    camera: Annotated[Path | None, typer.Option(help="camera.yaml for the rows without one of their own (each SEQ/camera.yaml wins: the ground truth in its true camera, an aligned output in its own).", dir_okay=False)] = None,
    frames: Annotated[str | None, typer.Option(help="Frame indices, comma-separated (e.g. 0,10,-1); default the first.")] = None,
    every: Annotated[int | None, typer.Option(help="Render every N-th frame instead.")] = None,
    views: Annotated[str | None, typer.Option(help=f"Columns, comma-separated: {', '.join(VIEWS)}.")] = None,
    image: Annotated[Path | None, typer.Option(help="Folder of video frames (matched by frame name) under the front view.", file_okay=False, exists=True)] = None,
    out: Annotated[Path | None, typer.Option(help="Output folder; default <first SEQ>_render beside it (with --from: in the current folder).", file_okay=False)] = None,
    size: Annotated[tuple[int, int] | None, typer.Option(help="One panel's width and height (px).")] = None,
    renderer: Annotated[str | None, typer.Option(help="auto (OpenGL via EGL, else fallback) | gl | fallback (numpy).")] = None,
    fit: Annotated[str | None, typer.Option(help=f"Frame the views on: {' | '.join(FITS)} (camera: the whole image, and the camera inside the side and top views).")] = None,
    scale: Annotated[str | None, typer.Option(help=f"Side/top windows: {' | '.join(SCALES)} (row: each row its own; shared: one for every row).")] = None,
    gt: Annotated[str | None, typer.Option(help="The ground-truth row: its label or 1-based number, auto (the row named gt) or none; the other rows' captions give their errors against it.")] = None,
    ghost: Annotated[str | None, typer.Option(help=f"{' | '.join(GHOSTS)}: with gt, draw the ground truth faintly over every other row.")] = None,
    labels: Annotated[bool | None, typer.Option("--labels/--no-labels", help="Person ids over the people.")] = None,
    gif: Annotated[bool | None, typer.Option("--gif/--no-gif", help="Also write render.gif of the rendered frames.")] = None,
    mp4: Annotated[bool | None, typer.Option("--mp4/--no-mp4", help="Also write render.mp4 (needs: pip install 'rotavat[video]').")] = None,
    glb: Annotated[bool | None, typer.Option("--glb/--no-glb", help="Also write a glTF scene (.glb) per frame.")] = None,
    plots: Annotated[bool | None, typer.Option("--plots/--no-plots", help="Also write tracks_<row>.png: foot height, lean and stature of each track over all frames.")] = None,
    accept_camera: Annotated[bool, typer.Option("--accept-camera", help="Use a row's camera even if its calibration found it implausible (its camera.yaml fit lists implausible findings); a warning names them.")] = False,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    opts = config_for(config, "render", views=views, frames=frames, every=every, size=list(size) if size else None,
                      renderer=renderer, fit=fit, scale=scale, gt=gt, ghost=ghost, labels=labels, gif=gif, mp4=mp4,
                      glb=glb, plots=plots)
    with input_errors():
        options = FigureOptions.from_config(opts, camera, image)
    options = dataclasses.replace(options, accept_camera=accept_camera,
                                  reader_flags=reader_flags(from_, image_size, smpl_model))
    out = out or default_output(seqs[0], "_render", from_)
    check_output_dir(out, [*seqs, *([camera] if camera else []), *([image] if image else [])], force)
    with contextlib.ExitStack() as inputs:
        sequences = [inputs.enter_context(input_sequence(path, from_ if i == 0 else None, image_size, smpl_model,
                                                         quiet=quiet or as_json)) for i, path in enumerate(seqs)]
        with progress_bar("rendering", figure_steps(sequences, options), progress_enabled(quiet, as_json)) as advance, \
                staged_directory(out, "render") as stage:  # the folder is replaced whole: no stale pictures
            summary = render_sequences(sequences, stage, options, advance)
    summary = summary.moved_to(out)
    for warning in summary.warnings:  # one line each, never wrapped; on stderr even under --quiet
        warn(warning)
    for note in summary.notes if not (quiet or as_json) else ():  # e.g. a row's own camera used, not --camera's
        console.print(f"note: {escape(note)}", highlight=False, soft_wrap=True)
    if as_json:
        print_json(vars(summary))
        return
    fallback = f" (fallback: {summary.renderer_note})" if summary.renderer == "fallback" and summary.renderer_note else ""
    report(f"rendered {len(summary.frames)} frame(s) x {len(summary.rows)} row(s) x {len(summary.views)} view(s) with "
         f"{summary.renderer} ({summary.renderer_detail}){fallback} in {summary.seconds:.2f} s", quiet)
    for path in summary.files:
        report(f"wrote {path}", quiet)
