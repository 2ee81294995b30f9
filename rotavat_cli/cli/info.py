"""``rotavat info SEQ``: validate a sequence and summarise it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..sequence import open_sequence, summarize_sequence
from ..words import count
from ._common import ConfigOpt, JsonOpt, QuietOpt, print_json, report, use_config, warn, warn_ignored


def info(
    seq: Annotated[Path, typer.Argument(help="Sequence directory (npz frames or folders of per-person OBJ).")],
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    use_config(config)  # its limits
    sequence = open_sequence(seq)
    warn_ignored(sequence)
    summary = summarize_sequence(sequence)
    if as_json:
        print_json(summary)
        return
    table = Table(title=f"sequence {summary['path']}", show_header=False)
    ppf = summary["people_per_frame"]
    rows = [
        ("form", summary["form"]),
        ("frames", f"{summary['frames']} ({summary['empty_frames']} empty)"),
        ("people", f"{summary['people_total']} total; per frame min {ppf['min']}, median {ppf['median']:g}, max {ppf['max']}"),
        ("tracks", str(summary["tracks"]) if summary["tracks"] is not None else "no person_ids"),
        ("keys", ", ".join(summary["keys"])),
        ("vertices / joints / 2D keypoints", " / ".join(",".join(map(str, summary[k])) or "-" for k in ("vertex_counts", "joint_counts", "keypoint_counts"))),
        ("image size", _size_cell(summary)),
        ("mesh focal (px)", _focal_cell(summary)),
        ("principal point", _principal_point_cell(summary)),
        ("source", summary["source"] or "-"),
    ]
    cam = summary["camera"]
    rows.append(("camera.yaml", "none" if cam is None else
                 f"f {cam['focal_px']:.1f} px, pitch {cam['pitch_deg']:.2f}°, roll {cam['roll_deg']:.2f}°, height {cam['height_m']:.2f} m"))
    for key, value in rows:
        table.add_row(key, value)
    report(table, False)  # the command's result: --quiet silences its warnings only
    for warning in sequence_warnings(summary):
        warn(warning)


def sequence_warnings(summary: dict) -> list[str]:
    """What in a summarised sequence stops calibrate or align from giving a right answer, and why."""
    warnings = []
    if len(summary["image_sizes"]) > 1:
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
