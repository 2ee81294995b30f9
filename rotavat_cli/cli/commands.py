"""The commands of ``rotavat``: the one list the group reads, in the order ``rotavat --help`` shows them.

A command lives in its own module of this package, as a plain function whose parameters are its
options (typer builds the click command from them). ``rotavat --help`` and ``rotavat --version``
read only this table; a command's module, and the API it runs, is imported when that command is
used (:class:`rotavat_cli.cli.group.RotavatGroup`). Each summary is the command's first line of
help, written here once. Adding a command: one module, one line below.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CommandEntry", "COMMANDS", "command_entry"]


@dataclass(frozen=True)
class CommandEntry:
    """One command: its name, the module and function that run it, the config section whose keys are
    its options (their defaults and ranges shown in --help; "" for none) and its one-line summary."""

    name: str
    module: str  # in rotavat_cli.cli
    function: str
    section: str
    summary: str


COMMANDS: tuple[CommandEntry, ...] = (
    CommandEntry("info", "info", "info", "",
                 "Validate a sequence and print a summary: form, frames, people, keys, sizes, intrinsics, camera."),
    CommandEntry("synth", "synth", "synth", "synth",
                 "Synthesise a static-camera scene: true people on the ground (gt/) and an HPS-like prediction (pred/)."),
    CommandEntry("calibrate", "calibrate", "calibrate", "calibrate",
                 "Estimate focal, pitch, roll and height of the static camera from the people in a sequence."),
    CommandEntry("measure", "measure", "measure", "",
                 "Measure each person's stature (sole to crown) from the camera: median and spread per track."),
    CommandEntry("align", "align", "align", "align",
                 "Re-seat every mesh on the ground plane, upright, keeping its foot and crown pixels (RotAvat)."),
    CommandEntry("eval", "eval", "eval_", "eval",
                 "Score predictions against ground truth (MPJPE, PA-MPJPE, PVE, W-MPJPE, W-PVE, detection, camera, "
                 "temporal), or without it measure feet height, penetration, sliding, lean, stature and jitter."),
    CommandEntry("render", "render", "render", "render",
                 "Draw the meshes from the camera (front) and orthographically from the side and top, where floating, "
                 "sunk and leaning bodies show."),
    CommandEntry("view", "view", "view", "view",
                 "Write a Rerun recording (.rrd) of sequences over time: before, after and truth in one 3D world, the "
                 "camera and its uncertainty, tracks and their series."),
    CommandEntry("export", "export", "export", "export",
                 "Write the sequence as an animated .glb (glTF 2.0, Y up, metres: people, ground, camera), one frame "
                 "(--frame), or each person's motion as BVH or AMASS (--format)."),
    CommandEntry("import", "import_", "import_", "",
                 "Convert HPS results (CLIFF, BEV/ROMP, 4D-Humans, Multi-HMR, SPEC, AGORA, BEDLAM, WHAM, GVHMR, TRAM, "
                 "HybrIK, PyMAF-X, TRACE, SLAHMR, GLAMR, CoMotion, PromptHMR) into the contract (OpenCV camera "
                 "frame, metres)."),
    CommandEntry("batch", "batch", "batch", "batch",
                 "Run calibrate/align/eval/render on every sequence under ROOT; outputs mirror ROOT's tree, plus "
                 "batch_report.json/.md."),
)


def command_entry(name: str) -> CommandEntry | None:
    """The entry of command ``name``, or None when there is no such command."""
    return next((entry for entry in COMMANDS if entry.name == name), None)
