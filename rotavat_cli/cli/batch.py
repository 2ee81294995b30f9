"""``rotavat batch ROOT``: every sequence of a dataset through calibrate, align, eval and render, in parallel."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from ..batch.report import REPORT_JSON, REPORT_MD
from ..batch.plan import BatchOptions
from ..batch.driver import run_batch
from ..errors import BatchFailedError, InputError
from ..files.outputs import beside
from ..parallel import cpu_count
from ._common import (ConfigOpt, FocalMmOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, check_focal_flags,
                      check_sequence_path, console, focal_flag_wins, print_json, progress_enabled, report, use_config)


def batch(
    root: Annotated[Path, typer.Argument(help="Dataset root: every folder of frames below it (or, with --from, every output of that tool) is a sequence.")],
    out: Annotated[Path | None, typer.Option(help="Output root mirroring ROOT's tree; default ROOT_batch beside ROOT.", file_okay=False)] = None,
    steps: Annotated[str | None, typer.Option(help="Comma-separated steps: calibrate,align,eval,render,view (eval needs --gt-root; view: pip install 'rotavat[view]').")] = None,
    view: Annotated[bool, typer.Option("--view", help="Also write OUT/<sequence>/view.rrd beside its figures: a Rerun recording of the input, the aligned output and the ground truth over time (the view step).")] = False,
    gt_root: Annotated[Path | None, typer.Option("--gt-root", help="Ground truth mirroring ROOT's tree: GT/<rel> scores ROOT/<rel>.", file_okay=False)] = None,
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", help="Worker processes (0 = one per core, the default; 1 = in this process).", min=0)] = None,
    executor: Annotated[str | None, typer.Option(help="local (a process pool here) or dask (a Dask cluster; pip install 'rotavat[dask]').")] = None,
    scheduler: Annotated[str | None, typer.Option(help="dask: address of an existing scheduler, e.g. tcp://10.0.0.5:8786 (default: a LocalCluster here).")] = None,
    chunk_frames: Annotated[int | None, typer.Option(help="Align/eval longer sequences as tasks of this many frames.", min=1)] = None,
    focal: Annotated[float | None, typer.Option("--focal", help="The cameras' known focal length (px), for every sequence's calibration (calibrate.focal_px).")] = None,
    focal_mm: FocalMmOpt = None,
    camera_height: Annotated[float | None, typer.Option(help="The cameras' known height above the ground (m), for every sequence's calibration (calibrate.camera_height_m).")] = None,
    pitch: Annotated[float | None, typer.Option("--pitch", help="The cameras' known pitch (deg, + = looking down), for every sequence's calibration (calibrate.pitch_deg).")] = None,
    camera: Annotated[Path | None, typer.Option(help="A camera.yaml to use for every sequence instead of calibrating (the calibrate step copies it).", dir_okay=False)] = None,
    accept_camera: Annotated[bool, typer.Option("--accept-camera", help="Use cameras even if their calibration found them implausible (camera.yaml fit lists implausible findings); otherwise such a sequence fails with the findings and what to give.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Redo sequences whose outputs are already complete; write into an OUT that rotavat did not write (never into ROOT or GT).")] = False,
    from_: FromOpt = None,
    gt_from: Annotated[str | None, typer.Option("--gt-from", help="Ground truth under --gt-root in a dataset's own format (agora, bedlam, ...): GT/<rel> is found by that importer and imported into OUT/<rel>/gt.")] = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """A sequence whose outputs are complete and newer than its inputs is skipped (--force redoes it); a
    failing sequence is reported with its reason and the others go on. Exit status: 0 all ok, 1 a
    sequence failed, 2 bad input or usage.
    """
    if root.is_file():  # a tool's file or a sequence's frame as ROOT: what it is and the command that reads it
        check_sequence_path(root)
    known = {"focal_px": focal, "focal_mm": focal_mm, "camera_height_m": camera_height, "pitch_deg": pitch}  # what the user knows of the cameras
    if camera is not None and any(v is not None for v in known.values()):
        raise InputError("--camera replaces the calibration: give it, or --focal/--focal-mm/--camera-height/--pitch, not both")
    check_focal_flags(focal, focal_mm)
    cfg = use_config(config, {"batch": {"steps": steps, "executor": executor, "jobs": jobs, "scheduler": scheduler,
                                         "chunk_frames": chunk_frames}, "calibrate": known})
    cfg = {**cfg, "calibrate": focal_flag_wins(cfg["calibrate"], focal, focal_mm)}
    if gt_from is not None and gt_root is None:
        raise InputError("--gt-from needs --gt-root (the ground truth in that format, mirroring ROOT's tree)")
    options = BatchOptions.from_config(cfg, gt_root=gt_root, fmt=from_, gt_fmt=gt_from, image_size=image_size,
                                       smpl_model=smpl_model, force=force, camera=camera, accept_camera=accept_camera)
    if options.scheduler and options.executor != "dask":
        if executor is not None:
            raise InputError("--scheduler is for --executor dask")
        options = replace(options, executor="dask")
    if view:
        options = replace(options, steps=(*options.steps, "view"))
    if gt_root is None and steps is None and "eval" in options.steps:  # default steps: no ground truth, no eval
        options = replace(options, steps=tuple(s for s in options.steps if s != "eval"))
        _say("eval skipped: no --gt-root", quiet or as_json)
    out = out or beside(root, "_batch")
    if options.jobs > cpu_count() and options.executor == "local":
        _say(f"jobs {options.jobs}: using at most {cpu_count()} workers (one per core)", quiet or as_json)
    display = _Display(progress_enabled(quiet, as_json), quiet or as_json)
    with display.progress:
        batch_report = run_batch(root, out, options, display)
    counts = batch_report.aggregate["counts"]
    if as_json:
        print_json({"report_json": str(out / REPORT_JSON), "report_md": str(out / REPORT_MD), "counts": counts,
                    "failed": [{"sequence": r["sequence"], "reason": r["reason"]} for r in batch_report.failed],
                    "aggregate": batch_report.aggregate, "workers": batch_report.worker_stats})
    else:
        report(f"{counts['done']} done, {counts['skipped']} skipped (complete), {counts['failed']} failed of "
               f"{counts['sequences']} sequences in {batch_report.seconds:.1f} s ({batch_report.executor}, "
               f"{batch_report.workers} worker(s))" + _headline(batch_report.aggregate), quiet)
        report(f"wrote {out / REPORT_JSON} and {out / REPORT_MD}", quiet)
    if batch_report.failed:
        raise BatchFailedError(f"{len(batch_report.failed)} of {counts['sequences']} sequences failed (reasons above and "
                               f"in {out / REPORT_MD})")


def _headline(aggregate: dict) -> str:
    """'; W-MPJPE 2888 -> 249 mm' from the dataset aggregate, when evaluated."""
    ev = aggregate.get("eval", {})
    values = [ev[s]["metrics"].get("w_mpjpe", math.nan) for s in ("before", "after") if s in ev]
    if not values or not all(math.isfinite(v) for v in values):
        return ""
    return "; dataset W-MPJPE " + " → ".join(f"{v:.0f}" for v in values) + " mm"


class _Display:
    """Progress callback: a live display (sequences and frames, ETA) on a terminal, one line per sequence otherwise."""

    def __init__(self, live: bool, quiet: bool) -> None:
        self.quiet, self.finished, self.total = quiet, 0, 0
        self.progress = Progress(TextColumn("{task.description:>9}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                                 TextColumn("ETA"), TimeRemainingColumn(), console=console, disable=not live, transient=True)
        self.seq_task = self.frame_task = None

    def __call__(self, kind: str, data: dict[str, Any]) -> None:
        if kind == "start":
            self.total = data["sequences"]
            self.seq_task = self.progress.add_task("sequences", total=data["sequences"])
            self.frame_task = self.progress.add_task("frames", total=data["frames_total"] or None)
            runs = f"{data['to_run']} to run ({data['executor']}, {data['workers']} worker(s))" if data["to_run"] else "nothing to run"
            _say(f"{data['sequences']} sequences: {data['skipped']} already complete (skipped), {runs}", self.quiet)
        elif kind == "frames_total":
            task = self.progress.tasks[self.frame_task]
            self.progress.update(self.frame_task, total=(task.total or 0) + data["add"])
        elif kind == "frames":
            self.progress.advance(self.frame_task, data["done"])
        elif kind == "sequence":
            self.finished += 1
            self.progress.advance(self.seq_task)
            self._line(data)

    def _line(self, row: dict) -> None:
        """One line per finished sequence; failures are printed even with --quiet (they set the exit status)."""
        head = f"[{self.finished}/{self.total}] {row['sequence']}"
        if row["status"] == "failed":
            console.print(f"{escape(head)} [bold red]failed:[/] {escape(row['reason'])}", highlight=False, markup=True,
                          soft_wrap=True)
            return
        if row["status"] == "skipped":
            return
        cam = row.get("camera") or {}
        parts = [f"{(row.get('seconds') or {}).get('total', 0.0):.1f} s"]
        if cam:
            parts.append(f"f {cam['focal_px']:.0f} px, pitch {cam['pitch_deg']:.1f}°, height {cam['height_m']:.2f} m"
                         + ((" (implausible camera" + (", accepted" if cam.get("accepted") else "") + ")")
                            if cam.get("implausible") else ""))
        ev = row.get("eval") or {}
        w = [(ev.get(s) or {}).get("metrics", {}).get("w_mpjpe") for s in ("before", "after") if ev.get(s)]
        if w and all(v is not None and math.isfinite(v) for v in w):
            parts.append("W-MPJPE " + " → ".join(f"{v:.0f}" for v in w) + " mm")
        _say(f"{head} done ({'; '.join(parts)})", self.quiet)


def _say(message: str, quiet: bool) -> None:
    """A message on stderr unless quiet, never wrapped (CI logs keep one line per sequence)."""
    if not quiet:
        console.print(message, highlight=False, soft_wrap=True)
