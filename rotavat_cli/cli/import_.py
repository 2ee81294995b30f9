"""``rotavat import --from FORMAT SRC OUT``: convert an HPS method's own output into a contract sequence."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ..formats.convert import import_sequence
from ..formats.file_kinds import wrong_kind
from ..formats.registry import available_formats, detect_format
from ..words import count
from ._common import (ConfigOpt, JsonOpt, QuietOpt, print_json, progress_bar, progress_enabled, report,
                      use_config, warn)

_FORMATS = ", ".join(available_formats())


def import_(
    src: Annotated[Path, typer.Argument(help="The method's output: a file or a folder (see docs/formats.md).")],
    out: Annotated[Path, typer.Argument(help="New sequence directory (npz frames + meta.yaml [+ camera.yaml]).", file_okay=False)],
    from_: Annotated[str | None, typer.Option("--from", help=f"Source format: {_FORMATS}. Default: detected from SRC.")] = None,
    image_size: Annotated[tuple[int, int] | None, typer.Option(help="Original image width and height (px), for formats that do not store it.")] = None,
    smpl_model: Annotated[Path | None, typer.Option(help="SMPL/SMPL-X model (.npz, or the official .pkl) you downloaded, to pose parameter-only formats (CLIFF, 4D-Humans, BEDLAM, AGORA params).", dir_okay=False)] = None,
    fov: Annotated[float | None, typer.Option("--fov", help="Field of view (deg) the method ran with (multihmr: its --fov, default 60).")] = None,
    video: Annotated[str | None, typer.Option("--video", metavar="NAME", help="Import only this video of a file that holds several (hybrik: a res.pk of demo runs sharing one --out-dir; NAME is the image names' prefix, IMG_6412 for IMG_6412-000001.png).")] = None,
    model_kind: Annotated[str | None, typer.Option("--model-kind", metavar="smpl|smplx", help="Import only the predictions made with this body model of a folder that mixes them (agora: AGORA's sample_pred_format/ holds SMPL and SMPL-X ones; each file is opened once more to tell its model).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace a non-empty OUT that rotavat did not write (never SRC).")] = False,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    use_config(config)  # its limits
    fmt = from_ or detect_format(src)
    if fmt is None:
        raise wrong_kind(src, None) or InputError(f"{src}: cannot tell its format; pass --from ({_FORMATS})")
    if fmt not in available_formats():
        raise InputError(f"unknown format '{fmt}' (known: {_FORMATS})")
    with progress_bar(f"importing {fmt}", None, progress_enabled(quiet, as_json)) as advance:
        summary = import_sequence(src, out, fmt, image_size=image_size, smpl_model=smpl_model, fov_deg=fov,
                                  video=video, progress=advance, overwrite=force, model_kind=model_kind)
    if as_json:
        print_json(summary)
        return
    for warning in summary["warnings"]:
        warn(str(warning))
    size = summary["image_size"]
    focal = summary["focal_px"]
    why = f": {summary['empty_why']}" if summary["empty_frames"] and summary.get("empty_why") else ""
    report(f"imported {count(summary['frames'], 'frame')} ({count(summary['people'], 'person', 'people')}, "
           f"{summary['empty_frames']} empty{why}) "
         f"from {fmt} into {out}: {'meshes' if summary['has_vertices'] else 'no meshes'}, "
         f"joints {summary['joints_layout'] or 'none'}, image {f'{size[0]}x{size[1]}' if size else 'size unknown'}, "
         f"focal {f'{focal:.1f} px' if focal else 'per frame'}"
         + ("; camera.yaml written" if summary["camera_yaml"] else ""), quiet)
