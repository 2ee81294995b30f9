"""``rotavat export SEQ --frame N --out scene.glb``: one frame as a glTF scene (people, ground, camera)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError, input_errors
from ..outputs import check_output_file
from ..render.style import RenderStyle
from ..render.export import export_frame
from ..words import count
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, config_for,
                      default_output, input_sequence, print_json, report)


def export(
    seq: Annotated[Path, typer.Argument(help="Sequence directory (with --from: the HPS tool's output).")],
    frame: Annotated[int, typer.Option(help="Frame index (negative counts from the end).")] = 0,
    out: Annotated[Path | None, typer.Option(help="Output .glb file; default <SEQ>_<frame>.glb beside SEQ (with --from: in the current folder).", dir_okay=False)] = None,
    camera: Annotated[Path | None, typer.Option(help="camera.yaml; default SEQ/camera.yaml.", dir_okay=False)] = None,
    force: ForceOpt = False,
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    opts = config_for(config, "render")
    with input_errors():
        palette = RenderStyle.from_config(opts).palette
    if out is not None and out.suffix.lower() != ".glb":
        raise InputError(f"--out must end in .glb, got {out}")
    target = out or default_output(seq, f"_{frame}.glb", from_)
    check_output_file(target, [seq, *([camera] if camera else [])], force)
    with input_sequence(seq, from_, image_size, smpl_model, quiet=quiet or as_json) as sequence:
        summary = export_frame(sequence, target, frame, camera, palette)
    if as_json:
        print_json(summary)
        return
    report(f"wrote {summary['out']}: frame {summary['frame']}, {count(summary['people'], 'person', 'people')}, ground, camera "
         f"({summary['image_size'][0]}x{summary['image_size'][1]}, vertical FOV {summary['yfov_deg']:.1f}°)", quiet)
