"""The tasks of one sequence, run in workers: plain arguments in, plain results out, errors as one line.

``prepare`` (import, then calibration on the pooled whole sequence), one ``align`` task per chunk of
frames (each into its own staging folder), ``merge`` (the chunks' frames moved into ``aligned/``,
their people.csv concatenated in order: byte-identical to one ``align_sequence`` call), one ``eval``
task per chunk and side, and ``finish`` (metrics merged, or without ground truth the input's and the aligned
output's measures against their ground, reports, render, the marker written last).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

try:
    import resource
except ImportError:  # not a POSIX system: no peak memory in the report
    resource = None

from ..version import __version__
from ..files.atomic import atomic_open, atomic_write_text, staged_directory
from ..alignment.align import align_sequence, flight_plan, summarize_people_csv
from ..alignment.camera_choice import CALIBRATED, GIVEN, AlignCamera, camera_for_align
from ..alignment.camera_gate import (ImplausibleCameraError, batch_remedies, check_align_camera, implausible_findings,
                                     is_accepted)
from ..alignment.options import AlignOptions
from ..calibration.options import CalibrateOptions
from ..calibration.sequence import calibrate_sequence
from ..geometry.camera import camera_from_yaml_dict, camera_parameters, camera_to_yaml_dict
from ..errors import InputError, RotavatError, TaskError, input_errors
from ..formats.convert import import_sequence
from ..settings.limits import Limits
from ..settings.limits import configure as configure_limits
from ..metrics.evaluate import EvalOptions, evaluate, merge_results
from ..metrics.ground_free_eval import measure_sequence, scene_cameras
from ..metrics.report import write_reports
from ..plain import to_plain
from ..render.sequences import FigureOptions, render_sequences
from ..sequence import Sequence, open_sequence, write_camera_yaml
from ..view.recording import ViewOptions, record_sequences
from .plan import ALIGN_STAGING, MARKER, MARKER_VERSION, OUTPUTS

__all__ = ["TaskError", "run_task", "one_line", "task_prepare", "task_align_chunk", "task_align_merge", "task_eval_chunk",
           "task_finish"]



def run_task(fn: Callable, *args: Any) -> dict:
    """Run one task; its value, seconds and the worker's identity and peak RSS. Errors become a one-line TaskError."""
    start = time.perf_counter()
    try:
        value = fn(*args)
    except RotavatError as exc:
        raise TaskError(one_line(str(exc))) from None
    except Exception as exc:  # anything else in a worker: report it on one line, with where it happened
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {Path(tb[-1].filename).name}:{tb[-1].lineno})" if tb else ""
        raise TaskError(one_line(f"{type(exc).__name__}: {exc}{where}")) from None
    return {"value": value, "seconds": time.perf_counter() - start, "worker": _worker()}


def one_line(text: str) -> str:
    """Collapse whitespace so a reason fits one line."""
    return " ".join(text.split()) or "failed"


def _worker() -> dict:
    """Host, pid and peak resident memory (MB) of this process."""
    rss_mb = float("nan")
    if resource is not None:
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        rss_mb = rss / (1 << 20) if sys.platform == "darwin" else rss / 1024.0
    return {"host": socket.gethostname(), "pid": os.getpid(), "peak_rss_mb": rss_mb}


def _apply_limits(plan: dict) -> None:
    """Put the batch config's size ``limits`` in force in this worker before it reads any file."""
    configure_limits(Limits.from_config(plan["config"].get("limits")))


def _chunks(n: int, size: int) -> list[tuple[int, int]]:
    """[start, stop) ranges of at most ``size`` covering 0..n."""
    return [(a, min(a + size, n)) for a in range(0, n, max(1, size))]


def _camera_summary(chosen: AlignCamera) -> dict:
    """Camera parameters in report units, with a few fit figures when estimated, and the gate's view of it:
    ``implausible`` (its calibration's findings; [] = plausible) and ``accepted`` (used under --accept-camera)."""
    summary = {"origin": chosen.origin, "file": chosen.source, **camera_parameters(chosen.camera)}
    summary.update({k: chosen.fit[k] for k in ("method", "focal_policy", "pairs", "inliers", "rmse_px") if k in chosen.fit})
    summary.update(implausible=list(implausible_findings(chosen.fit)), accepted=is_accepted(chosen.fit))
    return summary


def _given_camera(plan: dict, seq: Sequence) -> AlignCamera | None:
    """The camera.yaml given for every sequence (``batch --camera FILE``), read for this sequence's image size."""
    given = plan.get("camera")
    if not given:
        return None
    data = given["yaml"]
    with input_errors(given["path"]):
        camera = camera_from_yaml_dict(data, seq.image_size)
    fit = data.get("fit") if isinstance(data.get("fit"), dict) else {}
    return AlignCamera(camera, dict(fit), GIVEN, given["path"])


def _import_into(src: str, out: str, fmt: str, imp: dict, result: dict, what: str) -> None:
    """Convert a tool's output into a sequence folder of the batch's output (--from, --gt-from); its
    warnings (prefixed by ``what``) and time go into ``result``."""
    start = time.perf_counter()
    summary = import_sequence(src, out, fmt, image_size=imp["image_size"], smpl_model=imp["smpl_model"], overwrite=True)
    result["warnings"] += [f"{what}{w}" for w in summary.get("warnings", [])]
    result["seconds"]["import"] = result["seconds"].get("import", 0.0) + time.perf_counter() - start


def task_prepare(job: dict, plan: dict) -> dict:
    """Clear the previous run's marker and staging, import (--from), calibrate on the whole sequence, plan chunks."""
    _apply_limits(plan)
    out, steps = Path(job["out"]), plan["steps"]
    out.mkdir(parents=True, exist_ok=True)
    (out / MARKER).unlink(missing_ok=True)  # from here on the outputs are not complete
    for stale in [out / ALIGN_STAGING, *out.glob(".aligned.*-*"), *out.glob(".render.*-*")]:  # an interrupted run's staging
        shutil.rmtree(stale, ignore_errors=True)
    result: dict[str, Any] = {"seconds": {}, "warnings": [], "frame_passes": 0, "camera": None, "camera_file": None,
                              "camera_yaml": None}
    imp = plan["import"]
    if imp["format"]:
        _import_into(job["source"], job["seq"], imp["format"], imp, result, "")
    if imp.get("gt_format") and job["gt"]:  # --gt-from: the ground truth in its dataset's own format
        if not Path(job["gt_source"]).exists():
            raise InputError(f"{job['gt_source']}: no {imp['gt_format']} ground truth for this sequence (--gt-from)")
        _import_into(job["gt_source"], job["gt"], imp["gt_format"], imp, result, "ground truth: ")
    seq_dir = Path(job["seq"])
    seq = open_sequence(seq_dir)
    result["frames"] = len(seq)

    def calibrate(s: Sequence) -> AlignCamera:
        start = time.perf_counter()
        calib = calibrate_sequence(s, CalibrateOptions.from_config(plan["config"]["calibrate"]))
        write_camera_yaml(out / "camera.yaml", calib.result.camera, calib.fit_dict())
        result["warnings"] += list(calib.result.warnings)
        result["seconds"]["calibrate"] = time.perf_counter() - start
        result["frame_passes"] = len(s)
        return AlignCamera(calib.result.camera, calib.fit_dict(), CALIBRATED, str(out / "camera.yaml"))

    # The calibrate step's camera is the one given to align (as `calibrate` then `align --camera`);
    # align takes it, else the sequence's own, else calibrates. Without align, the sequence's own
    # camera (if any) is still reported and places the render rows. `batch --camera FILE` is that
    # camera for every sequence: the calibrate step copies it instead of fitting one.
    chosen = _given_camera(plan, seq)
    if chosen is not None and "calibrate" in steps:
        write_camera_yaml(out / "camera.yaml", chosen.camera, chosen.fit or None)
    elif "calibrate" in steps:
        chosen = calibrate(seq)
    if "align" in steps or (chosen is None and seq.camera is not None):
        chosen = camera_for_align(seq, chosen, calibrate)
    if chosen is not None and chosen.origin == GIVEN:  # a camera.yaml's own calibration warnings
        result["warnings"] += [f"{chosen.source}: {w}" for w in (chosen.fit.get("warnings") or [])]
    if chosen is not None and ("align" in steps or "render" in steps):  # the gate, before align and render use it
        try:  # accepted: the row's camera says so (implausible, accepted), as its aligned camera.yaml does
            chosen, _ = check_align_camera(chosen, job["source"], plan.get("accept_camera", False),
                                           batch_remedies(plan["root"], plan["out"]))
        except ImplausibleCameraError as exc:  # a failed sequence (the driver reports it), not a failed task
            result["refused"] = one_line(str(exc))
    if chosen is not None:  # handed to the align chunks as plain data: read or computed once
        result["camera_file"] = chosen.source
        result["camera_yaml"] = camera_to_yaml_dict(chosen.camera, chosen.fit or None)
        result["camera"] = _camera_summary(chosen)
    if result.get("refused"):
        return result
    size = int(plan["chunk_frames"])
    if "align" in steps:  # track statures need the whole sequence: one chunk
        result["align_chunks"] = [(0, len(seq))] if plan["config"]["align"]["height_from"] == "track" else _chunks(len(seq), size)
        if len(result["align_chunks"]) > 1:  # who is in flight needs whole tracks: found once, read by each chunk
            _write_flight_plan(job, flight_plan(seq, chosen.camera, AlignOptions.from_config(plan["config"]["align"])))
    if "eval" in steps:
        gt = open_sequence(job["gt"], read_camera=False)
        result["eval_chunks"] = _chunks(len(set(seq.frame_names) | set(gt.frame_names)), size)
    return result


def _chunk_dir(job: dict, index: int) -> Path:
    """Staging folder of one align chunk."""
    return Path(job["out"]) / ALIGN_STAGING / f"chunk-{index:06d}"


_FLIGHT_PLAN = "flight.json"  # in the align staging folder: the frames in flight (alignment.align.flight_plan)


def _write_flight_plan(job: dict, found: dict) -> None:
    """The whole sequence's flight plan (frame name -> elevations, NaN as null), for the align chunks."""
    staging = Path(job["out"]) / ALIGN_STAGING
    staging.mkdir(parents=True, exist_ok=True)
    plain = {name: [None if not np.isfinite(e) else float(e) for e in values.tolist()] for name, values in found.items()}
    atomic_write_text(staging / _FLIGHT_PLAN, json.dumps(plain))


def _read_flight_plan(job: dict) -> dict | None:
    """The flight plan prepare wrote (None when the sequence is aligned in one chunk: align finds it itself)."""
    path = Path(job["out"]) / ALIGN_STAGING / _FLIGHT_PLAN
    if not path.is_file():
        return None
    plain = json.loads(path.read_text(encoding="utf-8"))
    return {name: np.array([np.nan if e is None else e for e in values], dtype=np.float64) for name, values in plain.items()}


def task_align_chunk(job: dict, plan: dict, camera_yaml: dict, index: int, start: int, stop: int) -> dict:
    """Align frames [start, stop) into the chunk's staging folder (frames, people.csv, camera.yaml, meta.yaml)."""
    _apply_limits(plan)
    seq = open_sequence(job["seq"], read_camera=False)
    camera, fit = camera_from_yaml_dict(camera_yaml), camera_yaml.get("fit") or {}
    part = replace(seq, frame_names=seq.frame_names[start:stop])
    # jobs=1: the batch's own workers are the parallelism (no nested pools)
    options = replace(AlignOptions.from_config(plan["config"]["align"]), jobs=1)
    align_sequence(part, camera, _chunk_dir(job, index), options, camera_fit=fit or None, flight=_read_flight_plan(job))
    return {"frames": stop - start}


_CHUNK_FILES = ("people.csv", "camera.yaml", "meta.yaml")


def task_align_merge(job: dict, plan: dict, n_chunks: int) -> dict:
    """Move the chunks' frames into ``aligned/``, concatenate their people.csv in order; summarise people.csv."""
    out = Path(job["out"])
    parts = [_chunk_dir(job, i) for i in range(n_chunks)]
    with staged_directory(out / "aligned", "align") as merged:  # swapped in whole once complete
        for k, part in enumerate(parts):
            for entry in sorted(part.iterdir()):
                if entry.name not in _CHUNK_FILES or (k == 0 and entry.name != "people.csv"):
                    os.replace(entry, merged / entry.name)
        with atomic_open(merged / "people.csv", "w") as handle:
            for k, part in enumerate(parts):
                with open(part / "people.csv", encoding="utf-8", newline="") as src:
                    header = src.readline()
                    if k == 0:
                        handle.write(header)
                    shutil.copyfileobj(src, handle)
    shutil.rmtree(out / ALIGN_STAGING, ignore_errors=True)
    return _people_summary(out / "aligned" / "people.csv")


def _people_summary(people_csv: Path) -> dict:
    """What align did, from its people.csv (the same numbers whatever the chunking)."""
    summary = summarize_people_csv(people_csv)
    return {k: v for k, v in vars(summary).items() if k not in ("out", "frames") and not k.startswith("_")}


def _eval_options(plan: dict) -> Any:
    """EvalOptions from the eval config section."""
    return EvalOptions.from_config(plan["config"]["eval"])


def _eval_pred_dir(job: dict, side: str) -> str:
    """The prediction scored by an eval side: the input ('before') or the aligned sequence ('after')."""
    return job["seq"] if side == "before" else str(Path(job["out"]) / "aligned")


def task_eval_chunk(job: dict, plan: dict, side: str, start: int, stop: int) -> dict:
    """Score frames [start, stop) of the sorted union of prediction and GT frame names, for one side."""
    _apply_limits(plan)
    part = evaluate(open_sequence(_eval_pred_dir(job, side)), open_sequence(job["gt"]), _eval_options(plan),
                    frames=(start, stop))
    return {"part": part, "frames": stop - start}


def _ground_free(job: dict) -> dict:
    """The input's ('before') and the aligned output's ('after') measures without ground truth, each in its scene
    camera (``rotavat eval INPUT ALIGNED``: the input in the aligned output's camera unless it has its own)."""
    seqs = [open_sequence(job["seq"]), open_sequence(Path(job["out"]) / "aligned")]
    return {side: measure_sequence(seq, scene).as_dict()
            for side, seq, scene in zip(("before", "after"), seqs, scene_cameras(seqs)) if scene is not None}


def _figure_rows(job: dict, steps: list[str], state: dict) -> tuple[dict[str, Path], Path | None]:
    """The rows render and view show for a sequence, by name (``input``, ``aligned``, ``gt``: the ground truth
    last), and the camera.yaml for the rows without one: the one align used, else the calibrated (or given) one."""
    out = Path(job["out"])
    rows = {"input": Path(job["seq"]), **({"aligned": out / "aligned"} if "align" in steps else {}),
            **({"gt": Path(job["gt"])} if job["gt"] else {})}
    camera = out / "aligned" / "camera.yaml" if "align" in steps else state["camera_file"]
    return rows, Path(camera) if camera else None


def _new_warnings(warnings: list[str], camera: Path | None) -> list[str]:
    """A figure's warnings but the camera gate's on ``camera``: the camera align used passed the gate in
    prepare (the row's camera says implausible/accepted already)."""
    return [w for w in warnings if camera is None or str(camera) not in w]


def task_finish(job: dict, plan: dict, state: dict) -> dict:
    """Merge and write the metrics, render, record the view, and write the marker last; returns the sequence's report row."""
    _apply_limits(plan)
    out, steps = Path(job["out"]), plan["steps"]
    seconds = dict(state["seconds"])
    row = {"sequence": job["rel"], "status": "done", "reason": None, "source": job["source"], "out": job["out"],
           "gt": job["gt"], "frames": state["frames"], "people": None, "camera": state["camera"],
           "warnings": state["warnings"]}
    if "align" in steps:
        row["align"] = state["align"]
        row["people"] = state["align"]["people"]
    if "eval" in steps:
        start = time.perf_counter()
        results = [merge_results(state["eval_parts"][side]) for side in ("before", "after") if side in state["eval_parts"]]
        write_reports(out / "eval", results, job["gt"], {**plan["config"]["eval"], "joints": None})
        row["eval"] = dict(zip(("before", "after"), (r.as_dict() for r in results)))
        row["people"] = row["people"] if row["people"] is not None else results[0].people_pred
        seconds["eval"] = seconds.get("eval", 0.0) + time.perf_counter() - start
    if "align" in steps and not job["gt"]:  # no truth: the input and the aligned output against their scene's ground
        start = time.perf_counter()
        row["ground_free"] = _ground_free(job)
        seconds["ground_free"] = time.perf_counter() - start
    if row["people"] is None and state["camera"] and state["camera"].get("pairs") is not None:
        row["people"] = state["camera"]["pairs"]  # calibrate only: the foot/head pairs offered
    if "render" in steps:
        start = time.perf_counter()
        rows, camera = _figure_rows(job, steps, state)
        paths = list(rows.values())
        with input_errors():
            figure = FigureOptions.from_config(plan["config"]["render"], camera)
        # the last row is the ground truth (its folder is rarely named gt): each row in its own camera
        figure = replace(figure, gt=str(len(paths)) if job["gt"] else "none", accept_camera=plan.get("accept_camera", False))
        with staged_directory(out / "render", "render") as staging:
            summary = render_sequences([open_sequence(p) for p in paths], staging, figure)
        row["render"] = {"renderer": summary.renderer, "files": [Path(f).name for f in summary.files]}
        row["warnings"] = [*row["warnings"], *_new_warnings(summary.warnings, camera)]
        seconds["render"] = time.perf_counter() - start
    if "view" in steps:
        start = time.perf_counter()
        rows, camera = _figure_rows(job, steps, state)
        with input_errors():
            view = ViewOptions.from_config(plan["config"]["view"], plan["config"]["render"], camera)
        view = replace(view, accept_camera=plan.get("accept_camera", False))
        seqs = [open_sequence(p) for p in rows.values()]
        summary = record_sequences(seqs[:-1] if job["gt"] else seqs, out / OUTPUTS["view"],
                                   seqs[-1] if job["gt"] else None, view, labels=list(rows))
        row["view"] = {"file": OUTPUTS["view"], "frames": summary.frames, "bytes": summary.bytes}
        row["warnings"] = [*row["warnings"], *_new_warnings(summary.warnings, camera)]
        seconds["view"] = time.perf_counter() - start
    row["seconds"] = {**seconds, "total": sum(seconds.values())}
    marker = {"version": MARKER_VERSION, "rotavat": __version__, "steps": list(steps),
              "options": {s: plan["digests"][s] for s in steps}, "inputs": job["inputs"],
              "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"), "row": row}
    atomic_write_text(out / MARKER, json.dumps(to_plain(marker), indent=2) + "\n")
    return row

