"""``rotavat export SEQ --out scene.glb``: the whole sequence as an animated glTF scene (people, ground, camera),
``--frame N`` one frame, ``--format bvh|amass`` each person's motion (docs/export.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape

from ..errors import InputError, input_errors
from ..files.outputs import check_output_dir, check_output_file
from ..words import count
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, console, default_output,
                      input_sequence, print_json, progress_bar, progress_enabled, report, use_config, warn)

if TYPE_CHECKING:
    from ..exchange.options import ExportOptions
    from ..render.style import RGB
    from ..sequence import Sequence

_SUFFIXES = {"glb": ".glb"}  # --format from --out's suffix; bvh and amass write a folder
_DEFAULT_OUT = {"glb": "_scene.glb", "bvh": "_bvh", "amass": "_amass"}


def export(
    seq: Annotated[Path, typer.Argument(help="Sequence directory (with --from: the HPS tool's output).")],
    frame: Annotated[int | None, typer.Option(help="Write this one frame (index; negative counts from the end) as a still .glb; default every frame, animated.")] = None,
    out: Annotated[Path | None, typer.Option(help="Output: a .glb file; with --format bvh or amass a folder (one file per person). Default beside SEQ: <SEQ>_scene.glb (<SEQ>_<frame>.glb with --frame), <SEQ>_bvh/, <SEQ>_amass/ (with --from: in the current folder).")] = None,
    format_: Annotated[str | None, typer.Option("--format", help="glb (an animated scene), bvh (a BVH file per person) or amass (an AMASS-style .npz per person); default from --out's suffix, else glb. bvh and amass need body-model parameters and --smpl-model.")] = None,
    camera: Annotated[Path | None, typer.Option(help="camera.yaml; default SEQ/camera.yaml.", dir_okay=False)] = None,
    smpl_model: Annotated[Path | None, typer.Option(help="The SMPL/SMPL-H/SMPL-X .npz the frames' body-model parameters were made with: skinned bodies in the .glb (a far smaller file), the skeleton for bvh and amass; with --from also the model that poses parameter-only formats.", dir_okay=False)] = None,
    fps: Annotated[float | None, typer.Option(help="Frames per second assumed when SEQ's meta.yaml states none.")] = None,
    euler: Annotated[str | None, typer.Option(help="BVH rotation channels, outermost first.")] = None,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    from ..exchange.options import FORMATS, ExportOptions
    from ..render.style import RenderStyle

    merged = use_config(config, {"export": {"fps": fps, "euler": euler}, "render": {}})  # checks flags and file
    with input_errors(config):  # a --config file's bad value
        options, palette = ExportOptions.from_config(merged["export"]), RenderStyle.from_config(merged["render"]).palette
    fmt = _format(format_, out, frame, FORMATS)
    if fmt == "glb" and out is not None and out.suffix.lower() != ".glb":
        raise InputError(f"--out must end in .glb, got {out} (--format bvh or amass write a folder)")
    target = out or default_output(seq, f"_{frame}.glb" if frame is not None else _DEFAULT_OUT[fmt], from_)
    inputs = [seq, *([camera] if camera else []), *([smpl_model] if smpl_model else [])]
    if fmt == "glb":
        check_output_file(target, inputs, force)
    else:
        check_output_dir(target, inputs, force)
    with input_sequence(seq, from_, image_size, smpl_model, quiet=quiet or as_json) as sequence:
        if camera is None and sequence.camera is None:  # the remedy repeats --from's flags, so it runs as written
            from ..alignment.camera_gate import reader_flags
            from ..render.rows import no_camera

            raise no_camera(sequence, "exported world", reader_flags(from_, image_size, smpl_model), (str(seq),),
                            command="export")
        summary = _run(sequence, target, fmt, frame, camera, smpl_model, options, palette, quiet or as_json)
    for warning in summary.get("warnings", []):
        warn(warning)
    for note in summary.get("notes", []) if not (quiet or as_json) else ():
        console.print(f"note: {escape(note)}", highlight=False, soft_wrap=True)
    if as_json:
        print_json(summary)
        return
    report(_summary_line(summary), quiet)


def _format(format_: str | None, out: Path | None, frame: int | None, formats: tuple[str, ...]) -> str:
    """The output format: --format, else from --out's suffix, else glb; InputError for a bad combination."""
    if format_ is not None and format_ not in formats:
        raise InputError(f"--format must be one of {', '.join(formats)}, got {format_!r}")
    fmt = format_ or next((f for f, suffix in _SUFFIXES.items() if out is not None and out.suffix.lower() == suffix), "glb")
    if frame is not None and fmt != "glb":
        raise InputError(f"--frame writes one frame as a .glb; --format {fmt} writes every frame (leave --frame out)")
    if fmt != "glb" and out is not None and out.suffix.lower() in (".bvh", ".npz", ".glb"):
        raise InputError(f"--format {fmt} writes one file per person into a folder: give --out a folder name "
                         f"(e.g. {out.with_suffix('')}), not {out}")
    return fmt


def _run(sequence: Sequence, target: Path, fmt: str, frame: int | None, camera: Path | None, smpl_model: Path | None,
         options: ExportOptions, palette: tuple[RGB, ...], silent: bool) -> dict:
    """Run the export the options ask for; its summary."""
    from ..exchange.animated import animated_steps, export_animated
    from ..exchange.motion import export_motion, motion_steps
    from ..formats.smpl import load_body_model
    from ..render.export import export_frame

    if frame is not None:
        return export_frame(sequence, target, frame, camera, palette)
    model = load_body_model(smpl_model) if smpl_model is not None else None
    steps = animated_steps(sequence) if fmt == "glb" else motion_steps(sequence)
    with progress_bar(f"exporting {fmt}", steps, progress_enabled(silent, silent)) as advance:
        if fmt == "glb":
            return export_animated(sequence, target, camera, palette, options, model, smpl_model, advance)
        return export_motion(sequence, target, fmt, camera, options, model, smpl_model, advance)


def _summary_line(summary: dict) -> str:
    """The one-line result for a human."""
    if "frame" in summary:  # --frame: one still frame
        return (f"wrote {summary['out']}: frame {summary['frame']}, {count(summary['people'], 'person', 'people')}, ground, "
                f"camera ({summary['image_size'][0]}x{summary['image_size'][1]}, vertical FOV {summary['yfov_deg']:.1f}°)")
    fps = f"{summary['fps']:g} fps{' (assumed)' if summary['fps_from'] != 'meta.yaml' else ''}"
    if summary["format"] == "glb":
        words = {"skinned": "skinned bodies", "mesh": "per-frame meshes", "points": "per-frame point clouds",
                 "skeleton": "per-frame skeletons"}
        drawn = " and ".join(words.get(kind, kind) for kind in summary["drawn_as"].split("+"))
        people = count(summary["people"], "person", "people") + (f" as {drawn}" if summary["people"] else "")
        return (f"wrote {summary['out']} ({summary['bytes'] / 1e6:.1f} MB): {count(summary['frames'], 'frame')} at {fps}, "
                f"{people}, ground, camera "
                f"({summary['image_size'][0]}x{summary['image_size'][1]}, vertical FOV {summary['yfov_deg']:.1f}°)")
    return (f"wrote {summary['out']}/: {count(len(summary['files']), summary['format'].upper() + ' file')} "
            f"(one per person) over {count(summary['frames'], 'frame')} at {fps}, body model {summary['model']}")
