"""``rotavat view SEQ [SEQ2 ...] [--gt GT] --out scene.rrd``: a Rerun recording of the sequences over time."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from ..alignment.camera_gate import reader_flags
from ..errors import InputError, input_errors
from ..files.outputs import check_output_file
from ..view.recording import ViewOptions, record_sequences, view_steps
from ..view.writer import RERUN_INSTALL, require_rerun
from ..words import count
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, config_for, console,
                      default_output, input_sequence, print_json, progress_bar, progress_enabled, report, warn)


def view(
    seqs: Annotated[list[Path], typer.Argument(help="Sequence directories, one entity tree each (e.g. pred/ pred_aligned/); with --from the first is the HPS tool's output.")],
    gt: Annotated[Path | None, typer.Option(help="Ground-truth sequence: its own entity tree, its true ground, and each other row's W-MPJPE per person over time.", file_okay=False, exists=True)] = None,
    out: Annotated[Path | None, typer.Option(help="Output .rrd file; default <first SEQ>_view.rrd beside it (with --from: in the current folder).", dir_okay=False)] = None,
    camera: Annotated[Path | None, typer.Option(help="The scene camera's camera.yaml; default the first SEQ's own, else the ground truth's.", dir_okay=False)] = None,
    image: Annotated[Path | None, typer.Option(help="Folder of video frames (matched by frame name), shown under the camera.", file_okay=False, exists=True)] = None,
    frames: Annotated[str | None, typer.Option(help="Frame indices, comma-separated (e.g. 0,10,-1); default every frame.")] = None,
    every: Annotated[int | None, typer.Option(help="Record every N-th frame instead.")] = None,
    frame_all: Annotated[bool, typer.Option("--frame-all", help="Start the 3D view framed on every row; default on the aligned rows, the truth and the camera (a raw prediction far off stays drawn, outside).")] = False,
    full_detail: Annotated[bool, typer.Option("--full-detail", help="Store every mesh vertex and the video frames as their files (view.mesh_vertices 0, view.image_max_px 0): about 6x the bytes of SMPL meshes.")] = False,
    spawn: Annotated[bool, typer.Option("--spawn", help="Open the recording in the Rerun viewer once written (needs a display).")] = False,
    accept_camera: Annotated[bool, typer.Option("--accept-camera", help="Use the scene camera even if its calibration found it implausible; a warning names the findings.")] = False,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    section = config_for(config, "view", frames=frames, every=every, frame_all=frame_all or None,
                         mesh_vertices=0 if full_detail else None, image_max_px=0 if full_detail else None)
    with input_errors():
        options = ViewOptions.from_config(section, config_for(config, "render"), camera, image)
    options = dataclasses.replace(options, accept_camera=accept_camera,
                                  reader_flags=reader_flags(from_, image_size, smpl_model))
    require_rerun()  # before any work: say how to install it
    if out is not None and out.suffix.lower() != ".rrd":
        raise InputError(f"--out must end in .rrd, got {out}")
    target = out or default_output(seqs[0], "_view.rrd", from_)
    check_output_file(target, [*seqs, *([gt] if gt else []), *([camera] if camera else []), *([image] if image else [])],
                      force)
    with contextlib.ExitStack() as inputs:
        sequences = [inputs.enter_context(input_sequence(path, from_ if i == 0 else None, image_size, smpl_model,
                                                         quiet=quiet or as_json)) for i, path in enumerate(seqs)]
        truth = inputs.enter_context(input_sequence(gt, None, quiet=quiet or as_json)) if gt is not None else None
        with progress_bar("recording", view_steps(sequences, truth, options), progress_enabled(quiet, as_json)) as advance:
            summary = record_sequences(sequences, target, truth, options, advance)
    for warning in summary.warnings:
        warn(warning)
    for note in summary.notes if not (quiet or as_json) else ():
        console.print(f"note: {escape(note)}", highlight=False, soft_wrap=True)
    if spawn:
        _spawn_viewer(Path(summary.out), quiet or as_json)
    if as_json:
        print_json(vars(summary))
        return
    report(f"recorded {count(summary.frames, 'frame')} x {count(len(summary.rows), 'row')} "
           f"({count(summary.people, 'person-frame')}) in {summary.seconds:.2f} s: {summary.camera}", quiet)
    viewer = _viewer()
    report(f"wrote {summary.out} ({summary.bytes / 1e6:.1f} MB); open it with: {shlex.quote(viewer or 'rerun')} "
           f"{shlex.quote(summary.out)}", quiet)


def _viewer() -> str | None:
    """How to start the Rerun viewer, as typed: ``rerun`` when that is on PATH and is the one beside this Python
    (the SDK's wheel installs it there), else that one's full path, else any ``rerun`` on PATH."""
    beside = Path(sys.executable).with_name("rerun")
    on_path = shutil.which("rerun")
    if beside.is_file() and os.access(beside, os.X_OK):
        return "rerun" if on_path and Path(on_path).resolve() == beside.resolve() else str(beside)
    return on_path


def _spawn_viewer(recording: Path, quiet: bool) -> None:
    """Open ``recording`` in the native viewer, detached; a warning (the recording stands) when it cannot be."""
    viewer = _viewer()
    if viewer is None:
        warn(f"--spawn: no Rerun viewer found ({RERUN_INSTALL} installs it); open the recording later with: rerun {recording}")
        return
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        warn(f"--spawn: no display to open the viewer on; open the recording where there is one: {viewer} {recording}")
        return
    subprocess.Popen([shutil.which(viewer) or viewer, str(recording)], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                     stderr=subprocess.DEVNULL, start_new_session=True)
    report(f"opened {recording} in the Rerun viewer", quiet)
