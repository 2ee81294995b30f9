"""``rotavat eval PRED... --gt GT``: before/after metrics side by side, with CI gates."""

from __future__ import annotations

import math
from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..errors import GateError
from ..metrics.evaluate import PER_PERSON_SIGNATURE, EvalOptions, evaluate, parse_joints, write_per_person_csv
from ..metrics.report import (check_gate_metrics, check_gate_rows, check_gates, format_value, metric_label,
                              metric_value, parse_gate, report_paths, report_rows, write_reports)
from ..outputs import check_output_file
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, config_for,
                      default_output, info, input_sequence, print_json, progress_bar, progress_enabled, report)


def eval_(
    pred: Annotated[list[Path] | None, typer.Argument(help="Prediction sequence directories (default: the current directory).")] = None,
    gt: Annotated[Path, typer.Option("--gt", help="Ground-truth sequence directory (its camera.yaml enables ground-aware metrics).")] = ...,
    out: Annotated[Path | None, typer.Option(help="Folder for metrics.json and metrics.md; default <first PRED>_eval beside it (with --from: in the current folder; never inside a prediction).", file_okay=False)] = None,
    per_person: Annotated[Path | None, typer.Option("--per-person", help="Also write one CSV row per matched person.", dir_okay=False)] = None,
    fail_if: Annotated[list[str] | None, typer.Option("--fail-if", help="Gate, e.g. 'w_mpjpe>300' or 'pred_aligned:f1<0.9'; exit 1 if true.")] = None,
    match: Annotated[str | None, typer.Option(help="auto (ids if both sides have them, else hungarian), ids, hungarian, agora.")] = None,
    threshold_px: Annotated[float | None, typer.Option(help="hungarian: max mean 2D joint distance of a match (px).")] = None,
    iou_threshold: Annotated[float | None, typer.Option(help="agora: min keypoint-box IoU of a match.")] = None,
    joints: Annotated[str | None, typer.Option(help="Joint subset used by both sides: '0-23', '0,1,2' or SMPL names.")] = None,
    engine: Annotated[str | None, typer.Option(help="Vertex metrics: auto (numba if installed), numpy, numba ('rotavat[fast]').")] = None,
    protocol: Annotated[str | None, typer.Option(help="Whose metric definitions: paper (default), spec, agora, bedlam, wham (docs/metrics.md).")] = None,
    force: ForceOpt = False,
    from_: FromOpt = None,
    gt_from: Annotated[str | None, typer.Option("--gt-from", help="Read GT in a dataset's own format (agora, bedlam, ...), converted on the fly.")] = None,
    image_size: ImageSizeOpt = None,
    smpl_model: SmplModelOpt = None,
    config: ConfigOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    opts = config_for(config, "eval", match=match, threshold_px=threshold_px, iou_threshold=iou_threshold,
                      engine=engine, protocol=protocol)
    gates = [parse_gate(text) for text in fail_if or []]
    options = EvalOptions.from_config(opts, parse_joints(joints))
    preds = pred or [Path(".")]
    check_gate_rows(gates, preds)
    check_gate_metrics(gates, options.protocol)
    inputs = [*preds, gt]
    out = out or default_output(preds[0], "_eval", from_)
    for target in report_paths(out):
        check_output_file(target, inputs, force)
    if per_person:
        check_output_file(per_person, inputs, force, signature=PER_PERSON_SIGNATURE.encode())
    with ExitStack() as stack:
        gt_seq = stack.enter_context(input_sequence(gt, gt_from, image_size, smpl_model, quiet=quiet or as_json))
        pred_seqs = [stack.enter_context(input_sequence(p, from_, image_size, smpl_model, quiet=quiet or as_json))
                     for p in preds]
        with progress_bar("evaluating", sum(len(s) for s in pred_seqs), progress_enabled(quiet, as_json)) as advance:
            results = [evaluate(s, gt_seq, options, advance) for s in pred_seqs]
    json_path, md_path = write_reports(out, results, str(gt), {**opts, "joints": joints})
    if per_person:
        write_per_person_csv(per_person, results)
    reasons = check_gates(results, gates)
    if as_json:
        print_json({"metrics_json": str(json_path), "metrics_md": str(md_path), "gates_failed": reasons,
                    "predictions": [r.as_dict() for r in results]})
    elif not quiet:
        report(_table(results), quiet)
        for note, rows in _notes_once(results).items():  # a note every row shares is said once, naming them
            info(f"{', '.join(rows)}: {note}", quiet)
        report(f"wrote {json_path} and {md_path}", quiet)
    if reasons:
        raise GateError("quality gate failed: " + "; ".join(reasons))


def _notes_once(results) -> dict[str, list[str]]:
    """Each distinct note of the rows, in order, with the rows that have it (``name (protocol)``)."""
    out: dict[str, list[str]] = {}
    for r in results:
        for note in r.notes:
            out.setdefault(note, []).append(f"{Path(r.pred).name or r.pred} ({r.protocol})")
    return out


def _table(results) -> Table:
    """Rich table: one row per metric, one column per prediction, plus the change of the last vs the first."""
    protocols = ", ".join(sorted({r.protocol for r in results}))
    table = Table(title=f"rotavat eval, protocol {protocols} (each metric: protocol, unit; camera: ° and %)")
    table.add_column("metric")
    for r in results:
        table.add_column(Path(r.pred).name or r.pred, justify="right")
    if len(results) > 1:
        table.add_column("change", justify="right")
    table.add_row("matched / gt", *(f"{r.matched}/{r.people_gt}" for r in results), *([""] if len(results) > 1 else []))
    for metric in report_rows(results):
        values = [metric_value(r, metric) for r in results]
        change = []
        if len(results) > 1:
            first, last = values[0], values[-1]
            change = [f"{100.0 * (last - first) / abs(first):+.0f}%" if math.isfinite(first) and math.isfinite(last) and first else ""]
        label = metric_label(next((r for r in results if metric in r.metrics), results[0]), metric)
        table.add_row(label, *(format_value(metric, v) for v in values), *change)
    return table
