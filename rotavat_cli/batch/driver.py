"""The driver: skip complete sequences, submit each sequence's tasks as their inputs are ready, collect rows."""

from __future__ import annotations

import heapq
import time
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ..errors import TaskError
from ..files.outputs import check_output_dir, mark_output_dir
from .executors import InlineExecutor, make_executor
from .plan import BatchOptions, completed_marker, make_plan
from .report import BatchReport, aggregate_rows, write_batch_report
from .tasks import one_line, run_task, task_align_chunk, task_align_merge, task_eval_chunk, task_finish, task_prepare

__all__ = ["Progress", "run_batch"]

Progress = Callable[[str, dict], None]  # progress(kind, data), called in the driving process

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
                    self.inflight[self.executor.submit(run_task, fn, *args)] = (rel, stage, chunk)
            if self.inflight:
                for future in self.executor.wait(list(self.inflight)):
                    self.complete(future, *self.inflight.pop(future))

    def complete(self, future: Any, rel: str, stage: str, chunk: int) -> None:
        if rel in self.rows:  # the sequence already failed: ignore its stragglers
            return
        try:
            payload = future.result()
        except Exception as exc:  # TaskError from the task; BrokenProcessPool, KilledWorker, ... from the executor
            reason = str(exc) if isinstance(exc, TaskError) else f"worker lost: {one_line(f'{type(exc).__name__}: {exc}')}"
            return self.fail(rel, f"{stage}: {reason}")
        self.note_worker(payload)
        st, value = self.state[rel], payload["value"]
        if stage in ("align", "merge", "eval"):
            step = "eval" if stage == "eval" else "align"
            st["seconds"][step] = st["seconds"].get(step, 0.0) + payload["seconds"]
        frames = value.get("frame_passes" if stage == "prepare" else "frames", 0) if isinstance(value, dict) else 0
        if frames and stage != "finish":
            self.emit("frames", {"done": frames})
        if stage == "prepare" and value.get("refused"):  # the camera gate refused its camera: nothing else runs
            return self.fail(rel, f"{stage}: {value['refused']}", camera=value.get("camera"), warnings=value["warnings"],
                             frames=value.get("frames"))
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
                self.push(rel, "align", task_align_chunk, job, self.plan, value["camera_yaml"], i, a, b, chunk=i)
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

    def fail(self, rel: str, reason: str, **known: Any) -> None:
        """Report ``rel`` failed; ``known``: what its tasks had found (frames, camera, warnings) for the report."""
        job = self.jobs[rel]
        self.rows[rel] = {"sequence": rel, "status": "failed", "reason": reason, "source": job["source"], "out": job["out"],
                          "gt": job["gt"], "frames": self.state[rel].get("frames"), "people": None,
                          **{k: v for k, v in known.items() if v is not None}}
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
    check_output_dir(out, [root, *([options.gt_root] if options.gt_root else [])], options.force)
    emit = progress or (lambda kind, data: None)
    started, t0 = datetime.now(timezone.utc).isoformat(timespec="seconds"), time.perf_counter()
    plan, jobs = make_plan(root, out, options)
    out.mkdir(parents=True, exist_ok=True)
    mark_output_dir(out, "batch")
    rows: dict[str, dict] = {}
    todo = []
    for job in jobs:
        marker = None if options.force else completed_marker(job, plan)
        if marker is not None:
            rows[job["rel"]] = {**marker["row"], "status": "skipped", "reason": "complete (inputs and options unchanged)"}
        else:
            todo.append(job)
    n_tasks = sum(max(1, -(-(j["frames_hint"] or 1) // options.chunk_frames)) for j in todo)  # align/eval chunks
    executor = make_executor(options, n_tasks) if todo else InlineExecutor()
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

