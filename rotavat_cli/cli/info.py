"""``rotavat info SEQ``: validate a sequence and summarise it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..sequence import summarize_sequence
from ..words import count
from ._common import (ConfigOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, input_sequence, print_json,
                      report, use_config, warn)


def info(
    seq: Annotated[Path, typer.Argument(help="Sequence directory (npz frames or folders of per-person OBJ); with --from the HPS tool's output.")],
    from_: FromOpt = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    use_config(config)  # its limits
    with input_sequence(seq, from_, image_size, smpl_model, quiet=quiet or as_json) as sequence:
        summary = summarize_sequence(sequence)
        videos = sequence.several_videos()  # one tool's file of several videos: how to import each
        block = sequence.meta.get("import") if isinstance(sequence.meta.get("import"), dict) else {}
        empty_why = block.get("empty_frames_why")  # what the importer knew of the empty frames
    summary = {**summary, "empty_frames_why": empty_why}
    if as_json:
        print_json(summary)
        return
    table = Table(title=f"sequence {summary['path']}", show_header=False)
    ppf = summary["people_per_frame"]
    rows = [
        ("form", summary["form"]),
        ("frames", f"{summary['frames']} ({summary['empty_frames']} empty"
                   + (f": {empty_why})" if summary["empty_frames"] and empty_why else ")")),
        ("people", f"{summary['people_total']} total; per frame min {ppf['min']}, median {ppf['median']:g}, max {ppf['max']}"),
        ("tracks", str(summary["tracks"]) if summary["tracks"] is not None else "no person_ids"),
        ("keys", ", ".join(summary["keys"])),
        ("vertices / joints / 2D keypoints", " / ".join(",".join(map(str, summary[k])) or "-" for k in ("vertex_counts", "joint_counts", "keypoint_counts"))),
        ("image size", _size_cell(summary)),
        ("mesh focal (px)", _focal_cell(summary)),
        ("principal point", _principal_point_cell(summary)),
        ("source", summary["source"] or "-"),
    ]
    rows.append(("camera.yaml", _camera_cell(summary["camera"])))
    for key, value in rows:
        table.add_row(key, value)
    report(table, False)  # the command's result: --quiet silences its warnings only
    for warning in sequence_warnings(summary, videos):
        warn(warning)


_CAMERA_CELLS = (("focal_px", "f", "{:.1f}", " px"), ("pitch_deg", "pitch", "{:.2f}", "°"), ("roll_deg", "roll", "{:.2f}", "°"),
                 ("height_m", "height", "{:.2f}", " m"))


def _camera_cell(cam: dict | None) -> str:
    """camera.yaml's parameters, each with its std (or why it has none: given, ...) from the fit block, and a
    mark when its calibration found it implausible (``fit.implausible``: align, render and batch refuse it)."""
    if cam is None:
        return "none"
    fit = cam.get("fit") if isinstance(cam.get("fit"), dict) else {}
    std = fit.get("std") if isinstance(fit.get("std"), dict) else {}
    fixed = fit.get("fixed") if isinstance(fit.get("fixed"), dict) else {}
    parts = []
    for key, name, form, unit in _CAMERA_CELLS:
        sd, value = std.get(key), form.format(cam[key])
        if key in fixed:
            parts.append(f"{name} {value}{unit} ({fixed[key]})")
        elif isinstance(sd, (int, float)) and math.isfinite(sd):
            parts.append(f"{name} {value} ± {form.format(sd)}{unit}")
        elif isinstance(sd, (int, float)) and math.isinf(sd):
            parts.append(f"{name} {value}{unit} (undetermined)")
        else:
            parts.append(f"{name} {value}{unit}")
    lens = cam.get("distortion")
    if isinstance(lens, (int, float)) and not isinstance(lens, bool) and lens:  # the camera's lens (division model)
        given = fit.get("lens") if isinstance(fit.get("lens"), dict) else {}
        sd = std.get("distortion", given.get("sd"))
        parts.append(f"lens {lens:+.4f}" + (f" ± {sd:.4f}" if isinstance(sd, (int, float)) and math.isfinite(sd) else "")
                     + (f" ({str(given['from']).split(' (')[0]})" if given.get("from") else ""))
    implausible = fit.get("implausible") or []
    mark = f"; [red]implausible[/] ({len(implausible)} findings: fit.implausible)" if implausible else ""
    return ", ".join(parts) + mark


def sequence_warnings(summary: dict, videos: str | None = None) -> list[str]:
    """What in a summarised sequence stops calibrate or align from giving a right answer, and why (``videos``:
    :meth:`rotavat_cli.sequence.Sequence.several_videos`, for a tool's file of several videos)."""
    warnings = []
    cam = summary["camera"]
    implausible = ((cam or {}).get("fit") or {}).get("implausible") or []
    if implausible:
        warnings.append(f"{summary['path']}: its camera.yaml was found implausible by its calibration: "
                        f"{'; '.join(map(str, implausible))} (fit.implausible): align, render and batch refuse it "
                        "without --accept-camera")
    if videos is not None:
        warnings.append(f"{summary['path']}: {videos}")
    elif len(summary["image_sizes"]) > 1:
        sizes = ", ".join("x".join(map(str, size)) for size in summary["image_sizes"])
        warnings.append(f"{summary['path']}: frames of {len(summary['image_sizes'])} image sizes ({sizes}) are not one "
                        "static camera's: calibrate and align refuse them; split them into one sequence per camera")
    if summary["people_root_centred"]:
        warnings.append(f"{summary['path']}: {count(summary['people_root_centred'], 'person is', 'people are')} centred on the camera (their "
                        "translation is zero: a root-centred output, not placed in the camera frame); they cannot be "
                        "calibrated or aligned: import the tool's camera-frame output (its translation) instead")
    if summary["frames_not_alignable"]:
        names = summary["frames_not_alignable"]
        warnings.append(f"{summary['path']}: {len(names)} frames with people have neither meshes ('vertices') nor "
                        f"joints with 'feet_2d'/'heads_2d' (first: {names[0]}): align refuses them")
    if summary["frames_with_another_focal"]:
        names = summary["frames_with_another_focal"]
        warnings.append(f"{summary['path']}: {len(names)} frames state a focal length other than meta.yaml's "
                        f"{summary['focal_px']:g} px (first: {names[0]}): each frame's own is used; check which is right")
    cam, declared = summary["camera"], summary["focal_px"]
    if cam is not None and declared and summary["focal_kind"] == "camera" and \
            not math.isclose(cam["focal_px"], declared, rel_tol=1e-3):
        warnings.append(f"{summary['path']}: camera.yaml's focal {cam['focal_px']:.1f} px differs from the declared "
                        f"camera focal {declared:.1f} px (meta.yaml, focal_kind: camera): one of them is wrong")
    if summary["people_behind_camera"]:
        warnings.append(f"{summary['path']}: {count(summary['people_behind_camera'], 'person is', 'people are')} partly at or behind the camera "
                        "(z <= 0): not what the camera saw; check the file's camera frame and translation")
    return warnings


def _sizes(summary: dict) -> list[list[int]]:
    """The frames' image sizes when they differ (photos of several sizes), else []."""
    return summary["image_sizes"] if len(summary["image_sizes"]) > 1 else []


def _size_cell(summary: dict) -> str:
    """The image size, or "per frame (N sizes: ...)" when the frames differ."""
    if _sizes(summary):
        return f"per frame ({len(_sizes(summary))} sizes: {', '.join('x'.join(map(str, s)) for s in _sizes(summary))})"
    return "x".join(map(str, summary["image_size"])) if summary["image_size"] else "[red]unknown[/]"


def _principal_point_cell(summary: dict) -> str:
    """The declared principal point, "image centre", or per frame when the image sizes differ."""
    if summary["principal_point"]:
        return ", ".join(f"{v:.1f}" for v in summary["principal_point"])
    if _sizes(summary):
        return "per frame" if "principal_point" in summary["keys"] else "each image's centre"
    return "image centre"


def _focal_cell(summary: dict) -> str:
    """The focal the meshes were made with, and whether it is the camera's own or a method's guess."""
    if not summary["focal_px"]:
        return "per frame" if "focal_length" in summary["keys"] or "K" in summary["keys"] else "not stated"
    if summary["focal_kind"] == "camera":
        return f"{summary['focal_px']:.1f} (the camera's own)"
    rule = f", rule {summary['focal_rule']}" if summary.get("focal_rule") else ""
    return f"{summary['focal_px']:.1f} (assumed by the method{rule}: not the camera's; calibrate estimates it)"
