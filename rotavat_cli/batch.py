"""Whole datasets: find every sequence under a root and run calibrate/align/eval/render on each, in parallel.

:func:`run_batch` is what ``rotavat batch`` runs. It finds the sequences (:func:`discover_sequences`),
skips those already complete (:func:`completed_marker`), cuts the rest into tasks and hands them to
an executor: the inline one (``jobs=1``), a process pool on this machine, or an existing Dask
distributed cluster. Tasks are top-level functions of this module called with plain arguments
(paths, dicts), so they pickle, and every task reads and writes the shared file system itself.

Per sequence ``<rel>`` (its path under ROOT) the outputs go to ``OUT/<rel>/``::

    camera.yaml          calibrate (the camera align used; when the sequence has none, align calibrates)
    aligned/             align: the RotAvat sequence, its camera.yaml and people.csv
    eval/metrics.*       eval: the input and the aligned prediction against GT/<rel>, side by side
    render/              render: the figure of the chosen frames (input, aligned, ground truth rows)
    input/               --from FORMAT only: the converted contract sequence the steps read
    .rotavat-complete    JSON marker written last: steps, input fingerprints, option digests, timings, row

Tasks of one sequence: ``prepare`` (import, then calibration on the pooled whole sequence), one
``align`` task per chunk of ``chunk_frames`` frames (each aligns its frames with
:func:`~rotavat_cli.align.align_sequence` into its own staging folder), ``merge`` (frames moved into
``aligned/``, the chunks' people.csv concatenated in order, so the result is byte-identical to one
``align_sequence`` call), one ``eval`` task per chunk, and ``finish`` (metrics merged, reports,
render, marker). Any error ends that sequence only, with a one-line reason.
"""

from __future__ import annotations

import concurrent.futures as cf
import csv
import hashlib
import heapq
import json
import math
import multiprocessing
import os
import shutil
import socket
import sys
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .atomic import atomic_open, atomic_write_text, staged_directory
from .config import default_config
from .errors import InputError, RotavatError
from .plain import to_plain
from .sequence import open_sequence, read_camera_yaml, write_camera_yaml

__all__ = ["STEPS", "MARKER", "REPORT_JSON", "REPORT_MD", "BatchOptions", "BatchReport", "TaskError", "parse_steps",
           "discover_sequences", "fingerprint", "completed_marker", "run_batch", "aggregate_rows",
           "markdown_batch_report", "write_batch_report"]

STEPS = ("calibrate", "align", "eval", "render")
MARKER = ".rotavat-complete"
MARKER_VERSION = 1
REPORT_JSON, REPORT_MD = "batch_report.json", "batch_report.md"
_ALIGN_STAGING = ".aligned.chunks"  # align chunks' staging (aligned/ and render/ are staged beside them by staged_directory)
_OUTPUTS = {"calibrate": "camera.yaml", "align": "aligned/people.csv", "eval": "eval/metrics.json", "render": "render"}


class TaskError(RotavatError):
    """A task of one sequence failed: the one-line reason (the sequence is reported failed, exit 1)."""

    exit_code = 1


@dataclass(frozen=True)
class BatchOptions:
    """What ``rotavat batch`` can vary; ``config`` is a merged configuration (calibrate/align/eval/render)."""

    steps: tuple[str, ...] = STEPS
    gt_root: Path | None = None
    fmt: str | None = None  # importer format of the sequences (--from)
    image_size: tuple[int, int] | None = None  # --from: original image size
    smpl_model: Path | None = None  # --from: body model for parameter-only formats
    executor: str = "local"  # local | dask
    jobs: int = 0  # 0: one per core
    scheduler: str | None = None  # dask: address of an existing scheduler; None = a LocalCluster
    chunk_frames: int = 100
    force: bool = False
    config: dict = field(default_factory=default_config)

    @classmethod
    def from_config(cls, config: dict, **fields: Any) -> "BatchOptions":
        """Options from a merged config's ``batch`` section, overridden by ``fields``."""
        section = config["batch"]
        base = {"steps": parse_steps(section["steps"]), "executor": section["executor"], "jobs": int(section["jobs"]),
                "scheduler": section["scheduler"], "chunk_frames": int(section["chunk_frames"]), "config": config}
        return cls(**{**base, **fields})


def parse_steps(text: str | Iterable[str]) -> tuple[str, ...]:
    """'align,calibrate' -> ('calibrate', 'align'): known steps, always run in pipeline order."""
    names = [s.strip().lower() for s in (text.split(",") if isinstance(text, str) else text) if s.strip()]
    unknown = [s for s in names if s not in STEPS]
    if unknown or not names:
        raise InputError(f"--steps: unknown step(s) {', '.join(unknown) or '(none)'}; choose from {','.join(STEPS)}")
    return tuple(s for s in STEPS if s in names)


# ---- discovery and fingerprints -------------------------------------------------------------------
def discover_sequences(root: str | Path, fmt: str | None = None, exclude: Iterable[str | Path] = ()) -> list[tuple[str, Path]]:
    """Every sequence under ``root`` as (rel, path), sorted by rel ('.' when ``root`` is one).

    Contract sequences: a folder holding ``*.npz`` frames, or sub-folders of ``*.obj`` files. With
    ``fmt`` (an importer format): a folder the importer recognises as a whole, else each file it
    recognises (rel then drops the file's suffix). Sequences are not searched inside; folders whose
    name starts with '.' or '_', and the ``exclude`` paths (the output and ground-truth roots), are skipped.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: no such directory")
    skip = {Path(p).resolve() for p in exclude}
    matches = _format_matcher(fmt) if fmt else None
    found: list[tuple[str, Path]] = []
    seen: set[Path] = set()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        here = Path(dirpath)
        real = here.resolve()
        if real in seen or real in skip:  # symlink loops; output or GT root inside ROOT
            dirnames[:] = []
            continue
        seen.add(real)
        dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "_")))
        if matches is None:
            if any(f.endswith(".npz") and not f.startswith(".") for f in filenames) or any(_obj_frame_dir(here / d) for d in dirnames):
                found.append((_rel(here, root), here))
                dirnames[:] = []
        elif matches(here):
            found.append((_rel(here, root), here))
            dirnames[:] = []
        else:
            found += [(_rel(here / f, root, strip=True), here / f) for f in sorted(filenames)
                      if not f.startswith(".") and matches(here / f)]
    found.sort(key=lambda item: item[0])
    rels = [rel for rel, _ in found]
    clash = sorted({rel for rel in rels if rels.count(rel) > 1})
    if clash:
        raise InputError(f"{root}: two sequences would share the output folder {clash[0]} (a file and a folder of the same name?)")
    return found


def _rel(path: Path, root: Path, strip: bool = False) -> str:
    """POSIX path of ``path`` under ``root`` ('.' for root), the suffix dropped for file sequences."""
    rel = path.relative_to(root)
    return (rel.with_suffix("") if strip else rel).as_posix()


def _obj_frame_dir(folder: Path) -> bool:
    """An OBJ frame folder: at least one .obj and nothing else (hidden entries aside)."""
    try:
        entries = [p for p in folder.iterdir() if not p.name.startswith(".")]
    except OSError:
        return False
    return bool(entries) and all(p.suffix.lower() == ".obj" and p.is_file() for p in entries)


def _format_matcher(fmt: str) -> Callable[[Path], bool]:
    """path -> True when the importers detect ``fmt`` (or a sibling format of the same reader module)."""
    try:
        from . import formats
    except ImportError:
        raise InputError("--from needs rotavat's importers (rotavat_cli.formats), missing from this installation") from None
    if fmt not in formats.available_formats():
        raise InputError(f"unknown format '{fmt}' for --from (known: {', '.join(formats.available_formats())})")
    readers = getattr(formats, "READERS", {})
    family = getattr(readers.get(fmt), "__module__", fmt)

    def matches(path: Path) -> bool:
        found = formats.detect_format(path)
        return found is not None and (found == fmt or getattr(readers.get(found), "__module__", found) == family)
    return matches


def fingerprint(path: str | Path, exclude: Iterable[str | Path] = ()) -> dict:
    """Files, bytes, newest mtime (ns) and a digest of every (name, size, mtime) under ``path`` (hidden skipped)."""
    path = Path(path)
    skip = {Path(p).resolve() for p in exclude}
    entries = []
    if path.is_file():
        st = path.stat()
        entries.append((path.name, st.st_size, st.st_mtime_ns))
    for dirpath, dirnames, filenames in os.walk(path, followlinks=True):
        here = Path(dirpath)
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".") and (here / d).resolve() not in skip)
        for name in sorted(filenames):
            if not name.startswith("."):
                st = (here / name).stat()
                entries.append(((here / name).relative_to(path).as_posix(), st.st_size, st.st_mtime_ns))
    digest = hashlib.sha256("".join(f"{n}\0{s}\0{m}\n" for n, s, m in entries).encode()).hexdigest()
    return {"files": len(entries), "bytes": sum(e[1] for e in entries),
            "newest_mtime_ns": max((e[2] for e in entries), default=0), "digest": digest}


def _frames_hint(path: Path) -> int | None:
    """Frames of a contract sequence from its listing (None for imported sources: known after import)."""
    if not path.is_dir():
        return None
    npz = sum(1 for p in path.glob("*.npz") if not p.name.startswith("."))
    return npz or sum(1 for p in path.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))


# ---- markers --------------------------------------------------------------------------------------
def _digest(value: Any) -> str:
    """Stable digest of plain data."""
    return hashlib.sha256(json.dumps(to_plain(value), sort_keys=True).encode()).hexdigest()[:16]


def _step_digests(plan: dict) -> dict[str, str]:
    """Per step, a digest of every option its outputs depend on (a changed option redoes the sequence)."""
    cfg, imp = plan["config"], plan["import"]
    align = {k: v for k, v in cfg["align"].items() if k != "jobs"}  # how many processes does not change the result
    return {"calibrate": _digest([cfg["calibrate"], imp]), "align": _digest([cfg["calibrate"], align, imp]),
            "eval": _digest([cfg["eval"], imp, plan["gt_root"]]), "render": _digest([cfg["render"], imp])}


def completed_marker(job: dict, plan: dict) -> dict | None:
    """The marker of ``job`` when its outputs are complete for ``plan``, else None (run it).

    Complete: the marker exists (it is written last), lists every requested step with the same
    options, was written after the newest input file, the inputs' fingerprints are unchanged, and
    each step's main output exists.
    """
    out = Path(job["out"])
    try:
        marker = json.loads((out / MARKER).read_text())
        written_ns = (out / MARKER).stat().st_mtime_ns
    except (OSError, ValueError):
        return None
    if not isinstance(marker, dict) or marker.get("version") != MARKER_VERSION:
        return None
    options = marker.get("options") or {}
    if any(step not in marker.get("steps", []) or options.get(step) != plan["digests"][step] for step in plan["steps"]):
        return None
    inputs = marker.get("inputs") or {}
    if any(inputs.get(key) != value for key, value in job["inputs"].items()):
        return None
    if written_ns < max(v["newest_mtime_ns"] for v in job["inputs"].values()):
        return None
    if not all((out / _OUTPUTS[step]).exists() for step in plan["steps"]):
        return None
    return marker


# ---- tasks (run in workers: plain arguments in, plain results out) --------------------------------
def _call(fn: Callable, *args: Any) -> dict:
    """Run one task; its value, seconds and the worker's identity and peak RSS. Errors become a one-line TaskError."""
    start = time.perf_counter()
    try:
        value = fn(*args)
    except RotavatError as exc:
        raise TaskError(_one_line(str(exc))) from None
    except Exception as exc:  # anything else in a worker: report it on one line, with where it happened
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" (at {Path(tb[-1].filename).name}:{tb[-1].lineno})" if tb else ""
        raise TaskError(_one_line(f"{type(exc).__name__}: {exc}{where}")) from None
    return {"value": value, "seconds": time.perf_counter() - start, "worker": _worker()}


def _one_line(text: str) -> str:
    """Collapse whitespace so a reason fits one line."""
    return " ".join(text.split()) or "failed"


def _worker() -> dict:
    """Host, pid and peak resident memory (MB) of this process."""
    try:
        import resource

        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        rss_mb = rss / (1 << 20) if sys.platform == "darwin" else rss / 1024.0
    except ImportError:  # Windows
        rss_mb = float("nan")
    return {"host": socket.gethostname(), "pid": os.getpid(), "peak_rss_mb": rss_mb}


def _chunks(n: int, size: int) -> list[tuple[int, int]]:
    """[start, stop) ranges of at most ``size`` covering 0..n."""
    return [(a, min(a + size, n)) for a in range(0, n, max(1, size))]


def _camera_summary(camera_file: Path, image_size: tuple[int, int] | None, origin: str) -> dict:
    """Camera parameters in report units, with a few fit figures when estimated."""
    camera, fit = read_camera_yaml(camera_file, image_size)
    summary = {"origin": origin, "file": str(camera_file), "focal_px": camera.focal_px,
               "pitch_deg": math.degrees(camera.pitch_rad), "roll_deg": math.degrees(camera.roll_rad),
               "height_m": camera.height_m}
    summary.update({k: fit[k] for k in ("method", "focal_policy", "pairs", "inliers", "rmse_px") if k in fit})
    return summary


def task_prepare(job: dict, plan: dict) -> dict:
    """Clear the previous run's marker and staging, import (--from), calibrate on the whole sequence, plan chunks."""
    out, steps = Path(job["out"]), plan["steps"]
    out.mkdir(parents=True, exist_ok=True)
    (out / MARKER).unlink(missing_ok=True)  # from here on the outputs are not complete
    for stale in [out / _ALIGN_STAGING, *out.glob(".aligned.*-*"), *out.glob(".render.*-*")]:  # an interrupted run's staging
        shutil.rmtree(stale, ignore_errors=True)
    result: dict[str, Any] = {"seconds": {}, "warnings": [], "frame_passes": 0, "camera": None, "camera_file": None}
    imp = plan["import"]
    if imp["format"]:
        from .formats import import_sequence

        start = time.perf_counter()
        summary = import_sequence(job["source"], job["seq"], imp["format"], image_size=imp["image_size"],
                                  smpl_model=imp["smpl_model"], overwrite=True)
        result["warnings"] += [str(w) for w in summary.get("warnings", [])]
        result["seconds"]["import"] = time.perf_counter() - start
    seq_dir = Path(job["seq"])
    seq = open_sequence(seq_dir, read_camera=False)
    result["frames"] = len(seq)
    camera_file, origin = None, None
    if "calibrate" in steps or ("align" in steps and not (seq_dir / "camera.yaml").exists()):
        from .autocalib import calibrate_sequence

        start = time.perf_counter()
        calib = calibrate_sequence(seq, plan["config"]["calibrate"])
        camera_file, origin = out / "camera.yaml", "calibrated"
        write_camera_yaml(camera_file, calib.result.camera, {**calib.result.fit_dict(), "focal_policy": calib.focal_policy})
        result["warnings"] += list(calib.result.warnings)
        result["seconds"]["calibrate"] = time.perf_counter() - start
        result["frame_passes"] = len(seq)
    elif (seq_dir / "camera.yaml").exists():
        camera_file, origin = seq_dir / "camera.yaml", "given"
    if camera_file is not None:
        result["camera_file"] = str(camera_file)
        result["camera"] = _camera_summary(camera_file, seq.intrinsics.image_size, origin)
    size = int(plan["chunk_frames"])
    if "align" in steps:  # track statures need the whole sequence: one chunk
        result["align_chunks"] = [(0, len(seq))] if plan["config"]["align"]["height_from"] == "track" else _chunks(len(seq), size)
    if "eval" in steps:
        gt = open_sequence(job["gt"], read_camera=False)
        result["eval_chunks"] = _chunks(len(set(seq.frame_names) | set(gt.frame_names)), size)
    return result


def _chunk_dir(job: dict, index: int) -> Path:
    """Staging folder of one align chunk."""
    return Path(job["out"]) / _ALIGN_STAGING / f"chunk-{index:06d}"


def task_align_chunk(job: dict, plan: dict, camera_file: str, index: int, start: int, stop: int) -> dict:
    """Align frames [start, stop) into the chunk's staging folder (frames, people.csv, camera.yaml, meta.yaml)."""
    from .align import align_sequence

    seq = open_sequence(job["seq"], read_camera=False)
    camera, fit = read_camera_yaml(camera_file, seq.intrinsics.image_size)
    part = replace(seq, frame_names=seq.frame_names[start:stop])
    opts = plan["config"]["align"]  # workers=1: the batch's own workers are the parallelism (no nested pools)
    align_sequence(part, camera, _chunk_dir(job, index), opts["upright"], opts["height_from"], fit or None, workers=1)
    return {"frames": stop - start}


_CHUNK_FILES = ("people.csv", "camera.yaml", "meta.yaml")


def task_align_merge(job: dict, plan: dict, n_chunks: int) -> dict:
    """Move the chunks' frames into ``aligned/``, concatenate their people.csv in order; summarise people.csv."""
    out = Path(job["out"])
    parts = [_chunk_dir(job, i) for i in range(n_chunks)]
    with staged_directory(out / "aligned") as merged:  # swapped in whole once complete
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
    shutil.rmtree(out / _ALIGN_STAGING, ignore_errors=True)
    return _people_summary(out / "aligned" / "people.csv")


def _people_summary(people_csv: Path) -> dict:
    """What align did, from its people.csv (the same numbers whatever the chunking)."""
    people = aligned = 0
    flagged: dict[str, int] = {}
    depth, rotation, stature, drift = [], [], [], []
    with open(people_csv, encoding="utf-8", newline="") as handle:
        for row in csv.DictReader(handle):
            people += 1
            if row["flag"]:
                flagged[row["flag"]] = flagged.get(row["flag"], 0) + 1
                continue
            aligned += 1
            depth.append(float(row["depth_scale"]))
            rotation.append(abs(float(row["rotation_deg"])))
            stature.append(float(row["stature_m"]))
            drift.append(float(row["head_drift_px"] or 0.0))
    med = (lambda v: float(np.median(v)) if v else float("nan"))
    return {"people": people, "aligned": aligned, "flagged": flagged, "median_depth_scale": med(depth),
            "median_abs_depth_change_pct": med([abs(d - 1.0) * 100.0 for d in depth]),
            "median_rotation_deg": med(rotation), "median_stature_m": med(stature),
            "max_head_drift_px": max(drift, default=0.0)}


def _eval_options(plan: dict) -> Any:
    """EvalOptions from the eval config section."""
    from .evaluate import EvalOptions

    opts = plan["config"]["eval"]
    return EvalOptions(opts["match"], float(opts["threshold_px"]), float(opts["iou_threshold"]), None)


def _eval_pred_dir(job: dict, side: str) -> str:
    """The prediction scored by an eval side: the input ('before') or the aligned sequence ('after')."""
    return job["seq"] if side == "before" else str(Path(job["out"]) / "aligned")


def task_eval_chunk(job: dict, plan: dict, side: str, start: int, stop: int) -> dict:
    """Score frames [start, stop) of the sorted union of prediction and GT frame names, for one side."""
    from .evaluate import PERSON_METRICS, EvalResult, _score_frame  # evaluate()'s per-frame scorer; see docs/batch.md

    opts, gt, pred_dir = _eval_options(plan), open_sequence(job["gt"]), _eval_pred_dir(job, side)
    pred = open_sequence(pred_dir)
    pred_names, gt_names = set(pred.frame_names), set(gt.frame_names)
    result = EvalResult(pred_dir, job["gt"])
    columns: dict[str, list] = {k: [] for k in ("frame", "pred_index", "gt_index", "person_id", *PERSON_METRICS)}
    for name in sorted(pred_names | gt_names)[start:stop]:
        _score_frame(name, pred, gt, pred_names, gt_names, pred.camera, gt.camera, opts, result, columns)
    result.per_person = columns
    return {"part": result, "frames": stop - start}


_COUNTS = ("frames", "frames_pred_only", "frames_gt_only", "people_gt", "people_pred", "matched", "missed", "false_positives")


def _merge_eval(parts: list, pred_dir: str, gt_dir: str) -> Any:
    """One EvalResult from chunk results in frame order: counts summed, per-person columns concatenated."""
    from .evaluate import EvalResult, _aggregate, _camera_errors

    result = EvalResult(pred_dir, gt_dir)
    for name in _COUNTS:
        setattr(result, name, sum(getattr(p, name) for p in parts))
    result.per_person = {k: [v for p in parts for v in p.per_person[k]] for k in parts[0].per_person}
    pred_cam, gt_cam = open_sequence(pred_dir).camera, open_sequence(gt_dir).camera
    if pred_cam is not None and gt_cam is not None:
        result.camera = _camera_errors(pred_cam, gt_cam)
    result.metrics = _aggregate(result, result.per_person)
    return result


def _figure_options(render: dict, camera_path: Path | None) -> Any:
    """FigureOptions from the render config section (ValueError on a bad option)."""
    from .figure import FigureOptions, parse_views
    from .render import RenderStyle
    from .render_gl import RENDERERS

    if render["renderer"] not in RENDERERS:
        raise ValueError(f"render.renderer must be one of {', '.join(RENDERERS)}, got {render['renderer']!r}")
    if min(render["size"]) < 16 or max(render["size"]) > 8192 or render["fps"] <= 0:
        raise ValueError(f"render.size must be within 16..8192 px and render.fps > 0, got {render['size']}, {render['fps']}")
    return FigureOptions(parse_views(render["views"]), tuple(render["size"]),
                         None if render["frames"] is None else str(render["frames"]), render["every"], render["renderer"],
                         camera_path, None, render["gif"], float(render["fps"]), render["glb"], RenderStyle.from_config(render))


def task_finish(job: dict, plan: dict, state: dict) -> dict:
    """Merge and write the metrics, render, and write the marker last; returns the sequence's report row."""
    out, steps = Path(job["out"]), plan["steps"]
    seconds = dict(state["seconds"])
    row = {"sequence": job["rel"], "status": "done", "reason": None, "source": job["source"], "out": job["out"],
           "gt": job["gt"], "frames": state["frames"], "people": None, "camera": state["camera"],
           "warnings": state["warnings"]}
    if "align" in steps:
        row["align"] = state["align"]
        row["people"] = state["align"]["people"]
    if "eval" in steps:
        from .report import write_reports

        start = time.perf_counter()
        results = [_merge_eval(state["eval_parts"][side], _eval_pred_dir(job, side), job["gt"])
                   for side in ("before", "after") if side in state["eval_parts"]]
        write_reports(out / "eval", results, job["gt"], {**plan["config"]["eval"], "joints": None})
        row["eval"] = dict(zip(("before", "after"), (r.as_dict() for r in results)))
        row["people"] = row["people"] if row["people"] is not None else results[0].people_pred
        seconds["eval"] = seconds.get("eval", 0.0) + time.perf_counter() - start
    if row["people"] is None and state["camera"] and state["camera"].get("pairs") is not None:
        row["people"] = state["camera"]["pairs"]  # calibrate only: the foot/head pairs offered
    if "render" in steps:
        from .figure import render_sequences

        start = time.perf_counter()
        paths = [Path(job["seq"])] + ([out / "aligned"] if "align" in steps else []) + ([Path(job["gt"])] if job["gt"] else [])
        camera = out / "aligned" / "camera.yaml" if "align" in steps else state["camera_file"]
        try:
            figure = _figure_options(plan["config"]["render"], Path(camera) if camera else None)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        with staged_directory(out / "render") as staging:
            summary = render_sequences(paths, staging, figure)
        row["render"] = {"renderer": summary.renderer, "files": [Path(f).name for f in summary.files]}
        seconds["render"] = time.perf_counter() - start
    row["seconds"] = {**seconds, "total": sum(seconds.values())}
    marker = {"version": MARKER_VERSION, "rotavat": __version__, "steps": list(steps),
              "options": {s: plan["digests"][s] for s in steps}, "inputs": job["inputs"],
              "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"), "row": row}
    atomic_write_text(out / MARKER, json.dumps(to_plain(marker), indent=2) + "\n")
    return row


# ---- executors: one small interface over a process pool and a Dask client --------------------------
class _InlineExecutor:
    """Runs each task at submission, in this process (``jobs=1``)."""

    name, workers, limit = "local", 1, 1

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args))
        except Exception as exc:  # delivered through the future, like the other executors
            future.set_exception(exc)
        return future

    def wait(self, futures: list) -> set:
        return set(futures)

    def close(self, cancel: bool = False) -> None:
        pass


class _PoolExecutor:
    """A process pool on this machine (spawned workers: no state forked from the driver)."""

    name = "local"

    def __init__(self, jobs: int) -> None:
        self.workers, self.limit = jobs, jobs + 1  # one queued task so no worker waits for the driver
        self._pool = self._new()

    def _new(self) -> cf.ProcessPoolExecutor:
        return cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"))

    def submit(self, fn: Callable, *args: Any) -> cf.Future:
        try:
            return self._pool.submit(fn, *args)
        except cf.process.BrokenProcessPool:  # a worker died (killed, out of memory): its tasks failed; start afresh
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = self._new()
            return self._pool.submit(fn, *args)

    def wait(self, futures: list) -> set:
        return cf.wait(futures, return_when=cf.FIRST_COMPLETED).done

    def close(self, cancel: bool = False) -> None:
        self._pool.shutdown(wait=not cancel, cancel_futures=cancel)


class _DaskExecutor:
    """Tasks submitted to a Dask distributed cluster: an existing one (``scheduler``) or a LocalCluster here."""

    name = "dask"

    def __init__(self, scheduler: str | None, jobs: int) -> None:
        try:
            import distributed
        except ImportError:
            raise InputError("--executor dask needs Dask: pip install 'rotavat[dask]' (or dask[distributed])") from None
        import logging

        self._distributed, self._cluster = distributed, None
        try:
            if scheduler:
                self._client = distributed.Client(scheduler, timeout=20, set_as_default=False)
            else:
                self._cluster = distributed.LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                         host="127.0.0.1", dashboard_address=None, silence_logs=logging.ERROR)
                self._client = distributed.Client(self._cluster, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({_one_line(str(exc))})") from None
        if not self._client.nthreads():
            try:
                self._client.wait_for_workers(1, timeout=60)
            except (TimeoutError, OSError):
                self.close()
                raise InputError(f"the Dask cluster at {scheduler} has no workers") from None
        self.workers = sum(self._client.nthreads().values())
        self.limit = 2 * self.workers
        self.address = self._client.scheduler.address

    def submit(self, fn: Callable, *args: Any) -> Any:
        return self._client.submit(fn, *args, pure=False)

    def wait(self, futures: list) -> set:
        with self._client.as_current():  # distributed.wait uses the current client; ours is not the default
            return set(self._distributed.wait(futures, return_when="FIRST_COMPLETED").done)

    def close(self, cancel: bool = False) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()


def _make_executor(options: BatchOptions) -> Any:
    """The executor for ``options`` (a usage error if it cannot be had)."""
    jobs = options.jobs or _cores()
    if options.executor == "dask":
        return _DaskExecutor(options.scheduler, jobs)
    return _InlineExecutor() if jobs == 1 else _PoolExecutor(jobs)


def _cores() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


# ---- the driver -----------------------------------------------------------------------------------
@dataclass
class BatchReport:
    """What a batch run did: one row per sequence, the dataset aggregate, the workers."""

    root: str
    out: str
    gt_root: str | None
    steps: list[str]
    executor: str
    workers: int
    started: str
    seconds: float
    rows: list[dict]
    aggregate: dict
    worker_stats: list[dict]

    @property
    def failed(self) -> list[dict]:
        """Rows of the sequences that failed."""
        return [r for r in self.rows if r["status"] == "failed"]

    def as_dict(self) -> dict:
        """Plain dict for batch_report.json."""
        return to_plain(vars(self))


Progress = Callable[[str, dict], None]


def _plan(root: Path, out: Path, options: BatchOptions) -> tuple[dict, list[dict]]:
    """Validate the options, find the sequences, and build the plan and one job per sequence."""
    if options.executor not in ("local", "dask"):
        raise InputError(f"--executor must be local or dask, got {options.executor!r}")
    if options.jobs < 0 or options.chunk_frames < 1:
        raise InputError(f"--jobs must be >= 0 and --chunk-frames >= 1, got {options.jobs} and {options.chunk_frames}")
    if options.config["eval"]["match"] not in ("auto", "ids", "hungarian", "agora"):
        raise InputError(f"eval.match must be auto, ids, hungarian or agora, got {options.config['eval']['match']!r}")
    steps = parse_steps(options.steps)
    if "eval" in steps and options.gt_root is None:
        raise InputError("the eval step needs --gt-root (ground truth mirroring ROOT's tree)")
    gt_root = Path(options.gt_root).resolve() if options.gt_root is not None else None
    if gt_root is not None and not gt_root.is_dir():
        raise InputError(f"{options.gt_root}: no such directory (--gt-root)")
    if not root.is_dir():
        raise InputError(f"{root}: no such directory")
    if out.resolve() == root.resolve() or (gt_root is not None and out.resolve() == gt_root):
        raise InputError(f"{out}: the output folder must differ from ROOT and --gt-root")
    if "render" in steps:
        try:
            _figure_options(options.config["render"], None)
        except ValueError as exc:
            raise InputError(str(exc)) from None
    found = discover_sequences(root, options.fmt, exclude=[out] + ([gt_root] if gt_root else []))
    if not found:
        what = f"{options.fmt} outputs" if options.fmt else "sequences (folders of *.npz frames or of OBJ frame folders)"
        raise InputError(f"{root}: no {what} found")
    plan = {"steps": list(steps), "config": options.config, "chunk_frames": options.chunk_frames,
            "gt_root": str(gt_root) if gt_root else None,
            "import": {"format": options.fmt, "image_size": list(options.image_size) if options.image_size else None,
                       "smpl_model": str(Path(options.smpl_model).resolve()) if options.smpl_model else None}}
    plan["digests"] = _step_digests(plan)
    jobs = []
    out_abs = out.resolve()
    for index, (rel, path) in enumerate(found):
        target = out_abs / rel
        gt = gt_root / rel if gt_root is not None and "eval" in steps else None
        job = {"rel": rel, "index": index, "source": str(path.resolve()),
               "seq": str(target / "input") if options.fmt else str(path.resolve()), "out": str(target),
               "gt": str(gt) if gt is not None else None, "frames_hint": None if options.fmt else _frames_hint(path)}
        inputs = {"sequence": fingerprint(path, exclude=[out_abs] + ([gt_root] if gt_root else []))}
        if gt is not None:
            inputs["gt"] = fingerprint(gt) if gt.exists() else {"files": 0, "bytes": 0, "newest_mtime_ns": 0, "digest": "missing"}
        job["inputs"] = inputs
        jobs.append(job)
    return plan, jobs


_RANK = {"prepare": 0, "align": 1, "merge": 2, "eval": 3, "finish": 4}


class _Driver:
    """Submits each sequence's tasks as their inputs become ready, earliest sequence first.

    After ``prepare``: the align chunks and the input's eval chunks (they need no camera); after
    ``merge``: the aligned sequence's eval chunks; when nothing of the sequence is left: ``finish``.
    """

    def __init__(self, executor: Any, plan: dict, jobs: list[dict], emit: Progress, rows: dict, workers: dict) -> None:
        self.executor, self.plan, self.emit, self.rows, self.workers = executor, plan, emit, rows, workers
        self.jobs = {job["rel"]: job for job in jobs}
        self.state: dict[str, dict] = {job["rel"]: {"seconds": {}, "left": 0, "eval_parts": {}} for job in jobs}
        self.ready: list[tuple] = []
        self.inflight: dict[Any, tuple[str, str, int]] = {}
        self.serial = 0

    def push(self, rel: str, stage: str, fn: Callable, *args: Any, chunk: int = 0) -> None:
        self.serial += 1
        heapq.heappush(self.ready, (self.jobs[rel]["index"], _RANK[stage], chunk, self.serial, rel, stage, fn, args))

    def run(self) -> None:
        for rel, job in self.jobs.items():
            self.push(rel, "prepare", task_prepare, job, self.plan)
        while self.ready or self.inflight:
            while self.ready and len(self.inflight) < self.executor.limit:
                _, _, chunk, _, rel, stage, fn, args = heapq.heappop(self.ready)
                if rel not in self.rows:  # not failed meanwhile
                    self.inflight[self.executor.submit(_call, fn, *args)] = (rel, stage, chunk)
            if self.inflight:
                for future in self.executor.wait(list(self.inflight)):
                    self.complete(future, *self.inflight.pop(future))

    def complete(self, future: Any, rel: str, stage: str, chunk: int) -> None:
        if rel in self.rows:  # the sequence already failed: ignore its stragglers
            return
        try:
            payload = future.result()
        except Exception as exc:  # TaskError from the task; BrokenProcessPool, KilledWorker, ... from the executor
            reason = str(exc) if isinstance(exc, TaskError) else f"worker lost: {_one_line(f'{type(exc).__name__}: {exc}')}"
            return self.fail(rel, f"{stage}: {reason}")
        self.note_worker(payload)
        st, value = self.state[rel], payload["value"]
        if stage in ("align", "merge", "eval"):
            step = "eval" if stage == "eval" else "align"
            st["seconds"][step] = st["seconds"].get(step, 0.0) + payload["seconds"]
        frames = value.get("frame_passes" if stage == "prepare" else "frames", 0) if isinstance(value, dict) else 0
        if frames and stage != "finish":
            self.emit("frames", {"done": frames})
        if stage == "prepare":
            self.prepared(rel, value)
        elif stage == "finish":
            self.rows[rel] = value
            self.emit("sequence", value)
            return
        elif stage == "align":
            st["align_left"] -= 1
            if st["align_left"] == 0:
                self.push(rel, "merge", task_align_merge, self.jobs[rel], self.plan, len(st["align_chunks"]))
        elif stage == "merge":
            st["align"] = value
            self.push_eval(rel, "after")
        elif stage == "eval":
            side, index = divmod(chunk, 1 << 20)
            st["eval_parts"].setdefault(("before", "after")[side], {})[index] = value["part"]
        st["left"] -= stage != "prepare"
        if st["left"] == 0:
            self.push_finish(rel)

    def prepared(self, rel: str, value: dict) -> None:
        """Queue what the camera and the chunk plan allow; count every task left before ``finish``."""
        st, job, steps = self.state[rel], self.jobs[rel], self.plan["steps"]
        st.update({**value, "seconds": {**value["seconds"], **st["seconds"]}})
        align, evals = "align" in steps, "eval" in steps
        st["align_left"] = len(value.get("align_chunks", []))
        st["left"] = (len(value["align_chunks"]) + 1 if align else 0) + (len(value["eval_chunks"]) * (1 + align) if evals else 0)
        hint = job["frames_hint"] or 0
        per_frame = align + evals * (1 + align)  # frame passes after prepare
        self.emit("frames_total", {"add": value["frame_passes"] - (hint if "calibrate" in steps else 0)
                                   + per_frame * value["frames"] - per_frame * hint})
        if align:
            for i, (a, b) in enumerate(value["align_chunks"]):
                self.push(rel, "align", task_align_chunk, job, self.plan, value["camera_file"], i, a, b, chunk=i)
        if evals:
            self.push_eval(rel, "before")

    def push_eval(self, rel: str, side: str) -> None:
        if "eval" in self.plan["steps"]:
            base = (side == "after") << 20  # the chunk key carries the side: after-chunks queue after before-chunks
            for i, (a, b) in enumerate(self.state[rel]["eval_chunks"]):
                self.push(rel, "eval", task_eval_chunk, self.jobs[rel], self.plan, side, a, b, chunk=base + i)

    def push_finish(self, rel: str) -> None:
        st = self.state[rel]
        parts = {side: [chunks[i] for i in sorted(chunks)] for side, chunks in st["eval_parts"].items()}
        state = {k: st.get(k) for k in ("frames", "camera", "camera_file", "warnings", "align", "seconds")}
        self.push(rel, "finish", task_finish, self.jobs[rel], self.plan, {**state, "eval_parts": parts})

    def fail(self, rel: str, reason: str) -> None:
        job = self.jobs[rel]
        self.rows[rel] = {"sequence": rel, "status": "failed", "reason": reason, "source": job["source"], "out": job["out"],
                          "gt": job["gt"], "frames": self.state[rel].get("frames"), "people": None}
        self.emit("sequence", self.rows[rel])

    def note_worker(self, payload: dict) -> None:
        info = payload["worker"]
        key = f"{info['host']}:{info['pid']}"
        stats = self.workers.setdefault(key, {"host": info["host"], "pid": info["pid"], "tasks": 0, "busy_s": 0.0, "peak_rss_mb": 0.0})
        stats["tasks"] += 1
        stats["busy_s"] += payload["seconds"]
        stats["peak_rss_mb"] = max(stats["peak_rss_mb"], info["peak_rss_mb"])


def run_batch(root: str | Path, out: str | Path, options: BatchOptions, progress: Progress | None = None) -> BatchReport:
    """Run ``options.steps`` on every sequence under ``root`` into ``out``; write and return the batch report.

    ``progress(kind, data)`` is called in this process with kind ``start`` (sequences, to_run,
    skipped, frames_total, executor, workers), ``frames_total`` (add), ``frames`` (done: frame
    passes finished) and ``sequence`` (a report row, when a sequence is done, skipped or failed).
    """
    root, out = Path(root), Path(out)
    emit = progress or (lambda kind, data: None)
    started, t0 = datetime.now(timezone.utc).isoformat(timespec="seconds"), time.perf_counter()
    plan, jobs = _plan(root, out, options)
    rows: dict[str, dict] = {}
    todo = []
    for job in jobs:
        marker = None if options.force else completed_marker(job, plan)
        if marker is not None:
            rows[job["rel"]] = {**marker["row"], "status": "skipped", "reason": "complete (outputs newer than inputs)"}
        else:
            todo.append(job)
    executor = _make_executor(options) if todo else _InlineExecutor()
    steps = plan["steps"]
    passes = ("calibrate" in steps) + ("align" in steps) + ("eval" in steps) * (1 + ("align" in steps))  # frame passes
    emit("start", {"sequences": len(jobs), "to_run": len(todo), "skipped": len(rows), "executor": executor.name,
                   "workers": executor.workers, "frames_total": passes * sum(j["frames_hint"] or 0 for j in todo)})
    for row in rows.values():
        emit("sequence", row)
    workers: dict[str, dict] = {}
    cancel = True
    try:
        _Driver(executor, plan, todo, emit, rows, workers).run()
        cancel = False
    finally:
        executor.close(cancel=cancel)
    ordered = [rows[job["rel"]] for job in jobs]
    report = BatchReport(str(root), str(out), str(options.gt_root) if options.gt_root else None, plan["steps"], executor.name,
                         executor.workers, started, time.perf_counter() - t0, ordered, aggregate_rows(ordered),
                         sorted(workers.values(), key=lambda w: (w["host"], w["pid"])))
    write_batch_report(out, report)
    return report


# ---- the dataset aggregate and the report -----------------------------------------------------
def _num(value: Any) -> float:
    """A JSON number (None = NaN) as float."""
    return float("nan") if value is None else float(value)


def _weighted(values: list[float], weights: list[float]) -> float:
    """Weighted mean over finite values with positive weight (NaN when none)."""
    pairs = [(v, w) for v, w in zip(values, weights) if math.isfinite(v) and w > 0]
    total = sum(w for _, w in pairs)
    return sum(v * w for v, w in pairs) / total if total else float("nan")


def _stats(values: list[float], weights: list[float]) -> dict:
    """mean, people-weighted mean, median, min, max over finite values."""
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return {"n": 0}
    return {"n": len(finite), "mean": float(np.mean(finite)), "weighted_mean": _weighted(values, weights),
            "median": float(np.median(finite)), "min": min(finite), "max": max(finite)}


def aggregate_rows(rows: list[dict]) -> dict:
    """Dataset-level aggregate of report rows (done and skipped ones).

    Counts are summed. Each per-person error metric is the mean over sequences weighted by their
    matched people (= the mean over every matched person of the dataset when no value is missing);
    precision, recall, F1, NMJE and NMVE are recomputed from the summed match counts; camera errors
    and estimated camera parameters get mean, people-weighted mean, median, min and max.
    """
    from .evaluate import PERSON_METRICS
    from .metrics import detection_scores, normalize_by_f1

    ok = [r for r in rows if r["status"] in ("done", "skipped")]
    counts = {"sequences": len(rows), "done": sum(r["status"] == "done" for r in rows),
              "skipped": sum(r["status"] == "skipped" for r in rows), "failed": sum(r["status"] == "failed" for r in rows),
              "frames": sum(r.get("frames") or 0 for r in ok), "people": sum(r.get("people") or 0 for r in ok)}
    aligned = [r["align"] for r in ok if r.get("align")]
    if aligned:
        counts["aligned"] = sum(a["aligned"] for a in aligned)
        counts["flagged"] = {}
        for a in aligned:
            for flag, n in a["flagged"].items():
                counts["flagged"][flag] = counts["flagged"].get(flag, 0) + n
    out: dict[str, Any] = {"counts": counts, "eval": {}}
    for side in ("before", "after"):
        results = [r["eval"][side] for r in ok if r.get("eval") and r["eval"].get(side)]
        if not results:
            continue
        pooled = {k: sum(res[k] for res in results) for k in ("matched", "missed", "false_positives", "people_gt", "people_pred")}
        weights = [res["matched"] for res in results]
        metrics = {m: _weighted([_num(res["metrics"].get(m)) for res in results], weights) for m in PERSON_METRICS}
        metrics.update(detection_scores(pooled["matched"], pooled["missed"], pooled["false_positives"]))
        metrics["nmje"] = float(normalize_by_f1(metrics["mpjpe"], metrics["f1"]))
        metrics["nmve"] = float(normalize_by_f1(metrics["pve"], metrics["f1"]))
        cam_keys = sorted({k for res in results for k in res.get("camera", {})})
        people = [res["people_gt"] for res in results]
        cameras = {k: _stats([_num(res.get("camera", {}).get(k)) for res in results], people) for k in cam_keys}
        out["eval"][side] = {"sequences": len(results), **pooled, "metrics": metrics, "camera": cameras}
    cams = [(r["sequence"], r["camera"], r.get("people") or 0) for r in ok if r.get("camera")]
    out["cameras"] = {
        "per_sequence": [{"sequence": s, **{k: c.get(k) for k in ("origin", "focal_px", "pitch_deg", "roll_deg", "height_m", "rmse_px")}}
                         for s, c, _ in cams],
        **{k: _stats([_num(c.get(k)) for _, c, _ in cams], [p for _, _, p in cams]) for k in ("focal_px", "pitch_deg", "roll_deg", "height_m")},
    }
    return out


def _cell(value: Any, digits: int = 1) -> str:
    """A table cell: '–' for missing values."""
    v = _num(value) if not isinstance(value, str) else value
    if isinstance(v, str):
        return v
    return "–" if not math.isfinite(v) else f"{v:.{digits}f}"


def markdown_batch_report(report: BatchReport) -> str:
    """batch_report.md: counts, the dataset aggregate (input vs aligned), cameras, one row per sequence."""
    from .report import REPORT_COLUMNS, format_value

    agg, c = report.aggregate, report.aggregate["counts"]
    lines = [f"# rotavat batch of `{report.root}`", "",
             f"{c['sequences']} sequences: {c['done']} done, {c['skipped']} skipped (already complete), {c['failed']} failed; "
             f"{c['frames']} frames, {c['people']} people; steps {','.join(report.steps)}; {report.executor} executor, "
             f"{report.workers} worker(s); {report.seconds:.1f} s.", ""]
    evals = agg["eval"]
    if evals:
        sides = [s for s in ("before", "after") if s in evals]
        names = {"before": "input", "after": "aligned"}
        lines += [f"## Dataset aggregate (vs `{report.gt_root}`)", "",
                  "Errors in mm (lean in degrees), each the mean over sequences weighted by matched people; "
                  "precision/recall/F1 from the summed counts.", "",
                  "| metric | " + " | ".join(names[s] for s in sides) + (" | change |" if len(sides) == 2 else ""),
                  "|---" * (1 + len(sides) + (len(sides) == 2)) + "|"]
        for m in REPORT_COLUMNS:
            vals = [evals[s]["metrics"].get(m, float("nan")) for s in sides]
            if not any(math.isfinite(v) for v in vals):
                continue
            change = ""
            if len(vals) == 2:
                change = " | " + (f"{100.0 * (vals[1] - vals[0]) / abs(vals[0]):+.1f}%" if all(map(math.isfinite, vals)) and vals[0] else "–")
            lines.append(f"| {m} | " + " | ".join(format_value(m, v) for v in vals) + change + " |")
        for s in sides:
            e = evals[s]
            cams = ", ".join(f"{k} {v['median']:.2f}" for k, v in e["camera"].items() if v.get("n") and not k.endswith("_signed"))
            lines.append(f"\n{names[s]}: {e['sequences']} sequences, {e['matched']} matched of {e['people_gt']} true people, "
                         f"{e['false_positives']} false positives" + (f"; median camera errors: {cams}" if cams else ""))
        lines.append("")
    cams = agg["cameras"]
    if cams["per_sequence"]:
        lines += ["## Cameras", "", "| parameter | mean | people-weighted mean | median | min | max |", "|---|---|---|---|---|---|"]
        for k in ("focal_px", "pitch_deg", "roll_deg", "height_m"):
            s = cams[k]
            if s.get("n"):
                lines.append(f"| {k} | {s['mean']:.2f} | {s['weighted_mean']:.2f} | {s['median']:.2f} | {s['min']:.2f} | {s['max']:.2f} |")
        lines.append("")
    lines += ["## Sequences", "", "| sequence | status | frames | people | focal px | pitch ° | height m | W-MPJPE in → aligned | "
              "PA-MPJPE in → aligned | F1 | seconds |", "|---" * 11 + "|"]
    for r in report.rows:
        cam = r.get("camera") or {}
        ev = r.get("eval") or {}
        pair = (lambda m: " → ".join(_cell((ev[s] or {}).get("metrics", {}).get(m)) for s in ("before", "after") if ev.get(s)) or "–")
        f1 = (ev.get("after") or ev.get("before") or {}).get("metrics", {}).get("f1")
        secs = (r.get("seconds") or {}).get("total")
        lines.append(f"| `{r['sequence']}` | {r['status']} | {r.get('frames') or '–'} | {r.get('people') or '–'} | "
                     f"{_cell(cam.get('focal_px'), 0)} | {_cell(cam.get('pitch_deg'))} | {_cell(cam.get('height_m'), 2)} | "
                     f"{pair('w_mpjpe')} | {pair('pa_mpjpe')} | {_cell(f1, 3)} | {_cell(secs)} |")
    if report.failed:
        lines += ["", "## Failed", ""] + [f"- `{r['sequence']}`: {r['reason']}" for r in report.failed]
    return "\n".join(lines) + "\n"


def write_batch_report(out: str | Path, report: BatchReport) -> tuple[Path, Path]:
    """Write batch_report.json and batch_report.md into ``out`` atomically."""
    out = Path(out)
    json_path, md_path = out / REPORT_JSON, out / REPORT_MD
    atomic_write_text(json_path, json.dumps(report.as_dict(), indent=2) + "\n")
    atomic_write_text(md_path, markdown_batch_report(report))
    return json_path, md_path
