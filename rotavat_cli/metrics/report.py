"""Evaluation reports (metrics.json, metrics.md) and ``--fail-if`` quality gates, with ground truth
(:class:`~.evaluate.EvalResult`) and without (:class:`~.ground_free_eval.GroundFreeResult`)."""

from __future__ import annotations

import json
import math
import operator
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..files.atomic import atomic_write_text
from ..errors import InputError
from ..bodies.measure import source_words
from ..plain import to_plain
from ..version import WRITTEN_BY
from .evaluate import EvalResult
from .ground_free_eval import CAMERA_STD_METRICS, GROUND_FREE, GROUND_FREE_METRICS, GroundFreeResult
from .person_metrics import PERSON_METRICS
from .protocols import PROTOCOLS
from .tool_world import tool_world_markdown

__all__ = ["REPORT_GROUPS", "REPORT_COLUMNS", "GROUND_FREE_GROUPS", "HIGHER_IS_BETTER", "GATE_METRICS", "Gate",
           "parse_gate", "check_gate_rows", "check_gate_metrics", "check_gates", "report_sections", "report_rows",
           "format_value", "change_text", "column_labels", "metric_label", "metric_value", "markdown_report",
           "write_reports", "ground_free_sections", "ground_free_rows", "markdown_ground_free",
           "write_ground_free_reports"]

# The report's tables (metrics.md, the terminal): the headline numbers first, then the rest by theme; a
# metric no row has is left out, the camera errors come last (metrics.json keeps every metric).
REPORT_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Headline", ("w_mpjpe", "w_pve", "mpjpe", "pa_mpjpe", "group_pa_mpjpe", "pve", "pa_pve", "f1")),
    ("World and ground", ("wa_mpjpe", "rte", "root_err", "pcrd", "w_mpjpe_spec", "w_pve_spec", "foot_height",
                          "lean_deg", "stature_err")),
    ("Detection", ("precision", "recall", "nmje", "nmve")),
    ("Temporal", ("accel_err", "jitter", "foot_sliding")),
)
REPORT_COLUMNS = tuple(name for _, names in REPORT_GROUPS for name in names)  # every metric a protocol reports
_CAMERA_GROUP = "Camera"
_COUNT_METRICS = ("matched", "missed", "false_positives")
_CAMERA_METRICS = ("cam_focal_pct", "cam_pitch_deg", "cam_roll_deg", "cam_height_pct")
# The same without ground truth (every measure of ground_free_eval.GROUND_FREE_METRICS, then the camera's std).
GROUND_FREE_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Headline", ("feet_height", "penetration_pct", "lean", "sliding", "stature_spread")),
    ("Ground and posture", ("floating_pct", "feet_height_median", "penetration_depth", "lean_p90")),
    ("Motion and stature", ("accel", "stature", "stature_sd")),
    ("Camera uncertainty", CAMERA_STD_METRICS),
)
# Shares of 1 where more is better (every other metric and measure is better lower, but stature).
HIGHER_IS_BETTER = frozenset(("precision", "recall", "f1", "pcrd"))
_GROUND_FREE_GATES = frozenset((*GROUND_FREE_METRICS, *CAMERA_STD_METRICS))  # what eval without --gt reports
# A measure without ground truth -> the metric of the same idea against it (named in a refused gate's message).
_COUNTERPARTS = {"feet_height": "foot_height", "lean": "lean_deg", "sliding": "foot_sliding", "accel": "accel_err"}
GATE_METRICS = frozenset((*REPORT_COLUMNS, *PERSON_METRICS, *_COUNT_METRICS, *_CAMERA_METRICS,
                          *_GROUND_FREE_GATES))  # what --fail-if may name
_OPS = {"<=": operator.le, ">=": operator.ge, "==": operator.eq, "!=": operator.ne, "<": operator.lt, ">": operator.gt}
_GATE = re.compile(r"^\s*(?:(?P<row>[^:]+):)?\s*(?P<metric>[A-Za-z_0-9]+)\s*(?P<op><=|>=|==|!=|<|>)\s*(?P<value>[-+0-9.eE]+)\s*$")


@dataclass(frozen=True)
class Gate:
    """``[row:]metric OP value``: trips when the comparison is true (e.g. ``w_mpjpe>300``)."""

    metric: str
    op: str
    value: float
    row: str | None = None  # restrict to the prediction whose path or folder name matches

    def __str__(self) -> str:
        return f"{self.row + ':' if self.row else ''}{self.metric}{self.op}{self.value:g}"


def parse_gate(text: str) -> Gate:
    """Parse a ``--fail-if`` condition; InputError if malformed or the metric is unknown."""
    m = _GATE.match(text)
    if not m:
        raise InputError(f"--fail-if '{text}': expected [ROW:]METRIC OP NUMBER, e.g. 'w_mpjpe>300'")
    if m["metric"] not in GATE_METRICS:
        hint = f"; names are lower case: '{m['metric'].lower()}'" if m["metric"].lower() in GATE_METRICS else ""
        raise InputError(f"--fail-if '{text}': unknown metric '{m['metric']}'{hint} "
                         f"(known: {', '.join(sorted(GATE_METRICS))})")
    try:
        value = float(m["value"])
    except ValueError:
        raise InputError(f"--fail-if '{text}': '{m['value']}' is not a number") from None
    return Gate(m["metric"], m["op"], value, m["row"])


def check_gate_rows(gates: Sequence[Gate], preds: Sequence[str | Path]) -> None:
    """InputError for a gate whose ROW names none of the predictions (a usage error, checked before any work)."""
    names = {str(p) for p in preds} | {Path(p).name for p in preds}
    for gate in gates:
        if gate.row is not None and gate.row not in names:
            raise InputError(f"--fail-if '{gate}': no prediction named '{gate.row}' "
                             f"(the predictions: {', '.join(str(p) for p in preds)})")


def check_gate_metrics(gates: Sequence[Gate], protocol: str) -> None:
    """InputError for a gate on a metric the protocol never reports (it would always trip on NaN);
    ``protocol`` :data:`~.ground_free_eval.GROUND_FREE`: eval without ground truth."""
    if protocol == GROUND_FREE:
        for gate in gates:
            if gate.metric not in _GROUND_FREE_GATES:
                near = {v: k for k, v in _COUNTERPARTS.items()}.get(gate.metric)
                hint = f"; without it: {near}" if near else ""
                raise InputError(f"--fail-if '{gate}': {gate.metric} needs --gt{hint} (without ground truth eval "
                                 f"reports {', '.join(sorted(_GROUND_FREE_GATES))})")
        return
    for gate in gates:
        if gate.metric in _GROUND_FREE_GATES:
            near = _COUNTERPARTS.get(gate.metric)
            hint = f"; against the ground truth: {near}" if near else ""
            raise InputError(f"--fail-if '{gate}': {gate.metric} is measured without --gt (docs/metrics.md, "
                             f"\"Without ground truth\"){hint}")
    proto = PROTOCOLS[protocol]
    reported = set(proto.pair_metrics) | set(proto.track_metrics) | set(_COUNT_METRICS) | set(_CAMERA_METRICS)
    reported |= {"precision", "recall", "f1", "nmje", "nmve"} if proto.detection else set()
    reported -= set(proto.skipped)
    for gate in gates:
        if gate.metric not in reported:
            why = f" ({proto.skipped[gate.metric]})" if gate.metric in proto.skipped else ""
            raise InputError(f"--fail-if '{gate}': --protocol {protocol} does not report {gate.metric}{why}")


def metric_label(result: EvalResult, metric: str) -> str:
    """How a table names a metric: ``name (protocol, unit)``; camera errors keep their own names; a measure
    without ground truth ``name (unit)`` (one set of definitions: the table's title says which)."""
    if metric not in result.metrics:
        return metric
    unit = result.units.get(metric, "")
    if result.protocol == GROUND_FREE:
        return f"{metric} ({unit})" if unit else metric
    return f"{metric} ({result.protocol}{', ' + unit if unit else ''})"


def metric_value(result: EvalResult, metric: str) -> float:
    """A metric of a result by report name."""
    if metric in result.metrics:
        return result.metrics[metric]
    if metric in result.camera:
        return result.camera[metric]
    return float(getattr(result, metric, math.nan))


def check_gates(results: Sequence[EvalResult], gates: Sequence[Gate]) -> list[str]:
    """Reasons of the gates that tripped (a NaN metric trips its gate: it cannot be vouched for)."""
    reasons = []
    for gate in gates:
        rows = [r for r in results if gate.row is None or gate.row in (r.pred, Path(r.pred).name)]
        if gate.row is not None and not rows:
            reasons.append(f"{gate}: no prediction named '{gate.row}'")
        for r in rows:
            value = metric_value(r, gate.metric)
            if math.isnan(value) or _OPS[gate.op](value, gate.value):
                reasons.append(f"{Path(r.pred).name}: {gate.metric} = {value:.4g} ({gate})")
    return reasons


def _sections(groups: Sequence[tuple[str, Sequence[str]]], has_value) -> list[tuple[str, list[str]]]:
    """The groups' metrics that ``has_value``, each group with one (empty groups left out)."""
    sections = [(title, [m for m in names if has_value(m)]) for title, names in groups]
    return [(title, names) for title, names in sections if names]


def report_sections(results: Sequence[EvalResult]) -> list[tuple[str, list[str]]]:
    """The report's tables, headline first: (title, metrics that have a value in at least one row); a metric
    NaN everywhere is left out (the notes say why), one of no group goes to "More", the camera errors (when
    present) come last."""
    more = tuple(dict.fromkeys(m for r in results for m in r.metrics if m not in REPORT_COLUMNS))
    sections = _sections([*REPORT_GROUPS, ("More", more)],
                         lambda m: any(math.isfinite(r.metrics.get(m, math.nan)) for r in results))
    cams = sorted({k for r in results for k in r.camera if not k.endswith("_signed")})
    return sections + ([(_CAMERA_GROUP, cams)] if cams else [])


def report_rows(results: Sequence[EvalResult]) -> list[str]:
    """Every metric of :func:`report_sections`, in order."""
    return [m for _, names in report_sections(results) for m in names]


def column_labels(results: Sequence) -> list[str]:
    """How the tables name each row's prediction: its folder name, or its path when two folder names clash."""
    names = [Path(r.pred).name or r.pred for r in results]
    return names if len(set(names)) == len(names) else [str(r.pred) for r in results]


def change_text(base: float, value: float, digits: int = 1) -> str:
    """The relative change of ``value`` against ``base`` ('+12.3%'), '' when either is missing or base is 0."""
    if not (math.isfinite(base) and math.isfinite(value)) or base == 0:
        return ""
    return f"{100.0 * (value - base) / abs(base):+.{digits}f}%"


_RATIOS = ("precision", "recall", "f1", "pcrd", "stature", "sliding")  # stature m, sliding m/s: to the mm
_RATES = ("accel_err", "jitter", "foot_sliding", "rte", "accel", "cam_std_pitch_deg", "cam_std_roll_deg",
          "cam_std_height_m")


def format_value(metric: str, value: float) -> str:
    """Table cell: 3 decimals for ratios (and metres, m/s), 2 for the temporal rates (and the camera's std in
    degrees and metres), 1 for mm, degrees, pixels and percentages; "inf" for a std the fit left undetermined."""
    if value is None or not math.isfinite(value):
        return "inf" if metric in CAMERA_STD_METRICS and value == math.inf else "–"
    if metric in _RATIOS:
        return f"{value:.3f}"
    return f"{value:.2f}" if metric in _RATES else f"{value:.1f}"


def _metric_tables(results: Sequence, sections: Sequence[tuple[str, Sequence[str]]],
                   lead: Sequence[tuple[str, list[str]]] = ()) -> list[str]:
    """metrics.md's tables, one per section: one row per metric, one column per prediction, then the relative
    change of each later prediction against the first; ``lead``: (label, cells) rows heading the first table."""
    heads = column_labels(results)
    changes = ["change"] if len(results) == 2 else [f"change `{h}`" for h in heads[1:]]
    lines = []
    for number, (title, metrics) in enumerate(sections):
        lines += ["", f"## {title}", "", "| metric | " + " | ".join(f"`{h}`" for h in heads) + "".join(
            f" | {c}" for c in changes) + " |", "|---" * (1 + len(heads) + len(changes)) + "|"]
        for label, cells in lead if number == 0 else ():
            lines.append(f"| {label} | " + " | ".join(cells) + " |" * (len(changes) + 1))
        for metric in metrics:
            values = [metric_value(r, metric) for r in results]
            label = metric_label(next((r for r in results if metric in r.metrics), results[0]), metric)
            cells = [format_value(metric, v) for v in values] + [change_text(values[0], v) or "–" for v in values[1:]]
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines


def _reading_guide(results: Sequence, what: str, better: str) -> str:
    """The sentence under a report's first table: which way is better, where the rest is, what 'change' is."""
    change = (f" `change`: the relative change of each later {what} against `{column_labels(results)[0]}`."
              if len(results) > 1 else "")
    return f"The headline numbers first, the rest below by theme (metrics.json has all of them); {better}.{change}"


def markdown_report(results: Sequence[EvalResult], gt: str) -> str:
    """metrics.md: the predictions and their match counts, then the metric tables (headline first: one row
    per metric, one column per prediction, the change against the first), unpaired frames, the tools'
    own worlds, the notes."""
    protocols = sorted({r.protocol for r in results})
    lines = [f"# rotavat eval against `{gt}`", ""]
    for name in protocols:
        lines.append(f"Protocol `{name}`: {PROTOCOLS[name].source}.")
    lines += ["", "| prediction | frames | matched | missed | FP |", "|---|---|---|---|---|"]
    lines += [f"| `{r.pred}` | {r.frames} | {r.matched} | {r.missed} | {r.false_positives} |" for r in results]
    higher = ", ".join(f"`{m}`" for m in sorted(HIGHER_IS_BETTER))
    lines += ["", _reading_guide(results, "prediction", f"lower is better, but for {higher} (shares of 1: "
                                 "higher is better)") + " Each metric names its protocol and unit "
              "(docs/metrics.md defines them: `w_mpjpe` is a different quantity under each protocol)."]
    lines += _metric_tables(results, report_sections(results),
                            [("matched / gt", [f"{r.matched}/{r.people_gt}" for r in results])])
    frames_note = [f"- `{r.pred}`: {r.frames_pred_only} frames only in the prediction, {r.frames_gt_only} only in the ground truth"
                   for r in results if r.frames_pred_only or r.frames_gt_only]
    if frames_note:
        lines += ["", "## Unpaired frames", "", "Counted as false positives / misses unless a note says otherwise:",
                  "", *frames_note]
    lines += _tool_world_section(results)
    notes = [f"- `{r.pred}` ({r.protocol}): {note}" for r in results for note in r.notes]
    notes += [f"- `{r.pred}`: statures (`stature_err`) {source_words(r.stature_from)}" for r in results
              if r.stature_from is not None and "stature_err" in r.metrics]
    if notes:
        lines += ["", "## Notes", "", *notes]
    return "\n".join(lines) + "\n"


def _tool_world_section(results: Sequence) -> list[str]:
    """The tools' own worlds (:func:`~.tool_world.tool_world_markdown`) under their heading; [] without one."""
    lines = tool_world_markdown([(r.pred, r.tool_world) for r in results])
    return ["", "## Their world and ours", *lines] if lines else []


def write_reports(out_dir: str | Path, results: Sequence[EvalResult], gt: str, options: dict) -> tuple[Path, Path]:
    """Write metrics.json and metrics.md atomically into ``out_dir``."""
    json_path, md_path = report_paths(out_dir)
    payload = {"written_by": WRITTEN_BY, "gt": gt, "options": options,
               "protocol": _protocol_field(results), "metric_names": list(PERSON_METRICS),
               "predictions": [r.as_dict() for r in results]}
    atomic_write_text(json_path, json.dumps(to_plain(payload), indent=2) + "\n")
    atomic_write_text(md_path, f"<!-- written by {WRITTEN_BY} -->\n" + markdown_report(results, gt))
    return json_path, md_path


def _protocol_field(results: Sequence[EvalResult]) -> str | list[str]:
    """metrics.json's top-level protocol: its name, or the sorted names when results mix protocols."""
    names = sorted({r.protocol for r in results})
    return names[0] if len(names) == 1 else names


def report_paths(out_dir: str | Path) -> tuple[Path, Path]:
    """The two files ``write_reports`` writes: metrics.json and metrics.md in ``out_dir``."""
    return Path(out_dir) / "metrics.json", Path(out_dir) / "metrics.md"


# ---- without ground truth ------------------------------------------------------------------------


def ground_free_sections(results: Sequence[GroundFreeResult]) -> list[tuple[str, list[str]]]:
    """The tables without ground truth, headline first: (title, measures with a value in at least one row);
    the camera's recorded std where a row has it; a measure of no group goes to "More"."""
    grouped = {m for _, names in GROUND_FREE_GROUPS for m in names}
    groups = [*GROUND_FREE_GROUPS, ("More", tuple(m for m in GROUND_FREE_METRICS if m not in grouped))]
    return _sections(groups, lambda m: any(math.isfinite(r.metrics.get(m, math.nan)) for r in results)
                     if m not in CAMERA_STD_METRICS else any(m in r.camera for r in results))


def ground_free_rows(results: Sequence[GroundFreeResult]) -> list[str]:
    """Every measure of :func:`ground_free_sections`, in order."""
    return [m for _, names in ground_free_sections(results) for m in names]


def _flags_text(flags: dict[str, int] | None) -> str:
    """people.csv's flag counts in a cell: 'flight 2, sitting 1', 'none', or '–' without a people.csv."""
    if flags is None:
        return "–"
    return ", ".join(f"{flag} {n}" for flag, n in sorted(flags.items())) or "none"


def markdown_ground_free(results: Sequence[GroundFreeResult]) -> str:
    """metrics.md without ground truth: the sequences and their scene cameras, the measure tables (headline
    first: one row per measure, one column per sequence, the change against the first), the statures per
    track, the tools' own worlds, the notes."""
    lines = ["# rotavat eval without ground truth", "",
             "Each sequence measured in the world of its scene camera (docs/metrics.md, \"Without ground truth\", "
             "defines every measure); `cam_std_*` are the camera's own uncertainty as its calibration recorded it.", "",
             "| sequence | frames | people-frames | tracks | scene camera | people.csv flags |", "|---" * 6 + "|"]
    for r in results:
        camera = f"`{r.scene_camera.get('file', '')}` ({r.scene_camera.get('from', '')})"
        lines.append(f"| `{r.pred}` | {r.frames} | {r.people_pred} | {r.tracks} | {camera} | {_flags_text(r.flags)} |")
    lines += ["", _reading_guide(results, "sequence", "lower is better, but for `stature` (the people's own)")]
    lines += _metric_tables(results, ground_free_sections(results))
    tracks = [(r, t) for r in results for t in r.statures]
    if tracks:
        lines += ["", "## Statures per track", "", "Foot point to crown; spread: half the interquartile range over "
                  "its frames.", "", "| sequence | track | frames | median m | spread mm |", "|---|---|---|---|---|"]
        lines += [f"| `{r.pred}` | {t['id']} | {t['pairs']} | {format_value('stature', t['median_m'])} | "
                  f"{format_value('feet_height', 1000.0 * t['spread_m'])} |" for r, t in tracks]
    lines += _tool_world_section(results)
    notes = [f"- `{r.pred}`: {note}" for r in results for note in r.notes]
    notes += [f"- `{r.pred}`: statures scaled by its camera: {source_words(r.stature_from)}" for r in results
              if r.stature_from is not None]
    if notes:
        lines += ["", "## Notes", "", *notes]
    return "\n".join(lines) + "\n"


def write_ground_free_reports(out_dir: str | Path, results: Sequence[GroundFreeResult], options: dict) -> tuple[Path, Path]:
    """Write metrics.json and metrics.md of eval without ground truth atomically into ``out_dir`` (metrics.json as
    :func:`write_reports` writes it, ``gt`` null and ``metric_names`` the ground-free measures)."""
    json_path, md_path = report_paths(out_dir)
    payload = {"written_by": WRITTEN_BY, "gt": None, "options": options, "protocol": GROUND_FREE,
               "metric_names": [*GROUND_FREE_METRICS, *CAMERA_STD_METRICS], "predictions": [r.as_dict() for r in results]}
    atomic_write_text(json_path, json.dumps(to_plain(payload), indent=2) + "\n")
    atomic_write_text(md_path, f"<!-- written by {WRITTEN_BY} -->\n" + markdown_ground_free(results))
    return json_path, md_path
