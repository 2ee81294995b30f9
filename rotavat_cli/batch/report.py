"""The batch report: one row per sequence, the dataset-level aggregate, batch_report.json and .md."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..files.atomic import atomic_write_text
from ..metrics.ground_free_eval import GROUND_FREE_METRICS, GROUND_FREE_UNITS
from ..metrics.protocols import detection, protocol
from ..metrics.report import REPORT_COLUMNS, format_value
from ..plain import to_plain

__all__ = ["REPORT_JSON", "REPORT_MD", "BatchReport", "aggregate_rows", "camera_checks", "markdown_batch_report",
           "write_batch_report"]

REPORT_JSON, REPORT_MD = "batch_report.json", "batch_report.md"


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

    Counts are summed. Each error metric of the sequences' protocol is the mean over sequences
    weighted by their matched people (= the mean over every matched person of the dataset when no
    value is missing; for a protocol's per-track metrics, the matched-weighted mean of the
    sequences' pooled values); the detection scores and errors over F1 are recomputed from the
    summed match counts by the protocol's own rule (AGORA's rounding included); camera errors and
    estimated camera parameters get mean, people-weighted mean, median, min and max. Without ground
    truth (rows with ``ground_free``: the input's and the aligned output's measures), each measure is the
    mean over sequences weighted by their people-frames (exactly the pooled value for the means and
    shares: feet height, floating, penetration, lean).
    """
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
        proto = protocol(results[0].get("protocol") or "paper")
        names = [*proto.pair_metrics, *proto.track_metrics]
        metrics = {m: _weighted([_num(res["metrics"].get(m)) for res in results], weights) for m in names}
        metrics.update(detection(proto, metrics, pooled))
        cam_keys = sorted({k for res in results for k in res.get("camera", {})})
        people = [res["people_gt"] for res in results]
        cameras = {k: _stats([_num(res.get("camera", {}).get(k)) for res in results], people) for k in cam_keys}
        out["eval"][side] = {"sequences": len(results), "protocol": proto.name, **pooled, "metrics": metrics,
                             "camera": cameras}
    out["ground_free"] = {}
    for side in ("before", "after"):
        results = [r["ground_free"][side] for r in ok if (r.get("ground_free") or {}).get(side)]
        if results:
            weights = [res["people_pred"] for res in results]
            out["ground_free"][side] = {
                "sequences": len(results), "people_frames": sum(weights),
                "metrics": {m: _weighted([_num(res["metrics"].get(m)) for res in results], weights) for m in GROUND_FREE_METRICS}}
    cams = [(r["sequence"], r["camera"], r.get("people") or 0) for r in ok if r.get("camera")]
    out["cameras"] = {
        "per_sequence": [{"sequence": s, **{k: c.get(k) for k in ("origin", "focal_px", "pitch_deg", "roll_deg", "height_m", "rmse_px",
                                                                   "implausible")}}
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
    agg, c = report.aggregate, report.aggregate["counts"]
    lines = [f"# rotavat batch of `{report.root}`", "",
             f"{c['sequences']} sequences: {c['done']} done, {c['skipped']} skipped (already complete), {c['failed']} failed; "
             f"{c['frames']} frames, {c['people']} people; steps {','.join(report.steps)}; {report.executor} executor, "
             f"{report.workers} worker(s); {report.seconds:.1f} s.", ""]
    evals = agg["eval"]
    if evals:
        sides = [s for s in ("before", "after") if s in evals]
        names = {"before": "input", "after": "aligned"}
        proto = protocol(evals[sides[0]].get("protocol") or "paper")
        lines += [f"## Dataset aggregate (vs `{report.gt_root}`), protocol `{proto.name}`", "",
                  f"Definitions of the `{proto.name}` protocol ({proto.source}); each error the mean over "
                  "sequences weighted by matched people; precision/recall/F1 from the summed counts by the "
                  "protocol's rule.", "",
                  "| metric | " + " | ".join(names[s] for s in sides) + (" | change |" if len(sides) == 2 else ""),
                  "|---" * (1 + len(sides) + (len(sides) == 2)) + "|"]
        for m in REPORT_COLUMNS:
            vals = [evals[s]["metrics"].get(m, float("nan")) for s in sides]
            if not any(math.isfinite(v) for v in vals):
                continue
            change = ""
            if len(vals) == 2:
                change = " | " + (f"{100.0 * (vals[1] - vals[0]) / abs(vals[0]):+.1f}%" if all(map(math.isfinite, vals)) and vals[0] else "–")
            unit = proto.unit(m)
            lines.append(f"| {m} ({proto.name}{', ' + unit if unit else ''}) | " + " | ".join(format_value(m, v) for v in vals)
                         + change + " |")
        for s in sides:
            e = evals[s]
            cams = ", ".join(f"{k} {v['median']:.2f}" for k, v in e["camera"].items() if v.get("n") and not k.endswith("_signed"))
            lines.append(f"\n{names[s]}: {e['sequences']} sequences, {e['matched']} matched of {e['people_gt']} true people, "
                         f"{e['false_positives']} false positives" + (f"; median camera errors: {cams}" if cams else ""))
        lines.append("")
    lines += _ground_free_lines(report)
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
    checks = camera_checks(report.rows)
    if checks:
        lines += ["", "## Camera checks and warnings", ""] + checks
    if report.failed:
        lines += ["", "## Failed", ""] + [f"- `{r['sequence']}`: {r['reason']}" for r in report.failed]
    return "\n".join(lines) + "\n"


# The per-sequence columns without ground truth: input -> aligned for each, then the aligned output's statures.
_GROUND_FREE_COLUMNS = ("feet_height", "penetration_pct", "floating_pct", "lean", "sliding", "accel")


def _ground_free_lines(report: BatchReport) -> list[str]:
    """batch_report.md's section without ground truth: the dataset aggregate (input vs aligned), then one row per
    sequence: each measure input -> aligned, the aligned output's statures and its people.csv flags."""
    agg = report.aggregate.get("ground_free") or {}
    if not agg:
        return []
    sides = [s for s in ("before", "after") if s in agg]
    names = {"before": "input", "after": "aligned"}
    lines = ["## Without ground truth: each sequence against its scene's ground", "",
             "Definitions: docs/metrics.md, \"Without ground truth\" (`rotavat eval INPUT ALIGNED`: the input measured "
             "in the aligned output's camera unless it has its own); each value the mean over sequences weighted by "
             "their people-frames.", "",
             "| measure | " + " | ".join(names[s] for s in sides) + (" | change |" if len(sides) == 2 else ""),
             "|---" * (1 + len(sides) + (len(sides) == 2)) + "|"]
    for m in GROUND_FREE_METRICS:
        vals = [agg[s]["metrics"].get(m, float("nan")) for s in sides]
        if not any(math.isfinite(v) for v in vals):
            continue
        change = ""
        if len(vals) == 2:
            change = " | " + (f"{100.0 * (vals[1] - vals[0]) / abs(vals[0]):+.1f}%" if all(map(math.isfinite, vals)) and vals[0] else "–")
        lines.append(f"| {m} ({GROUND_FREE_UNITS[m]}) | " + " | ".join(format_value(m, v) for v in vals) + change + " |")
    header = " | ".join(f"{m} ({GROUND_FREE_UNITS[m]}) in → aligned" for m in _GROUND_FREE_COLUMNS)
    lines += ["", f"| sequence | {header} | stature m (spread mm), aligned | people.csv flags |",
              "|---" * (3 + len(_GROUND_FREE_COLUMNS)) + "|"]
    for r in report.rows:
        gf = r.get("ground_free") or {}
        if not gf:
            continue
        cells = [" → ".join(format_value(m, _num((gf[s] or {}).get("metrics", {}).get(m))) for s in ("before", "after")
                            if gf.get(s)) for m in _GROUND_FREE_COLUMNS]
        after = (gf.get("after") or {}).get("metrics", {})
        stature = f"{format_value('stature', _num(after.get('stature')))} ({format_value('stature_spread', _num(after.get('stature_spread')))})"
        flagged = (r.get("align") or {}).get("flagged")
        flags = (gf.get("after") or {}).get("flags") if flagged is None else flagged
        flag_text = "–" if flags is None else (", ".join(f"{k} {n}" for k, n in sorted(flags.items()) if k) or "none")
        lines.append(f"| `{r['sequence']}` | " + " | ".join(cells) + f" | {stature} | {flag_text} |")
    return lines + [""]


def camera_checks(rows: list[dict]) -> list[str]:
    """Markdown bullets, one per sequence with an implausible camera or warnings: the findings, what became of
    the camera (used under --accept-camera, refused, or not used), then each warning (calibration, import, render).

    >>> camera_checks([{"sequence": "a", "status": "done", "camera": {"implausible": ["height 0.1 m"], "accepted": True},
    ...                 "warnings": ["few pairs"]}, {"sequence": "b", "status": "done", "camera": {}, "warnings": []}])
    ['- `a`: implausible camera (height 0.1 m), used (--accept-camera)', '  - few pairs']
    """
    lines = []
    for r in rows:
        cam, warnings = r.get("camera") or {}, r.get("warnings") or []
        found = cam.get("implausible") or []
        if not found and not warnings:
            continue
        if found:
            if cam.get("accepted"):
                fate = "used (--accept-camera)"
            elif r["status"] == "failed" and "implausible camera" in (r.get("reason") or ""):
                fate = "refused (see Failed)"
            else:
                fate = "not used by align or render"
            lines.append(f"- `{r['sequence']}`: implausible camera ({'; '.join(found)}), {fate}")
        else:
            lines.append(f"- `{r['sequence']}`: warnings")
        lines += [f"  - {w}" for w in warnings]
    return lines


def write_batch_report(out: str | Path, report: BatchReport) -> tuple[Path, Path]:
    """Write batch_report.json and batch_report.md into ``out`` atomically."""
    out = Path(out)
    json_path, md_path = out / REPORT_JSON, out / REPORT_MD
    atomic_write_text(json_path, json.dumps(report.as_dict(), indent=2) + "\n")
    atomic_write_text(md_path, markdown_batch_report(report))
    return json_path, md_path
