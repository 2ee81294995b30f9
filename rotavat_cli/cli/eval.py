"""``rotavat eval PRED... [--gt GT]``: before/after metrics side by side, with CI gates.

With ``--gt`` each prediction is scored against the ground truth (:func:`_with_truth`); without it each
sequence is measured against its own scene's ground, upright and in time (:func:`_without_truth`). Both
write metrics.json and metrics.md of the same shape, print one table, and share ``--fail-if``.
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import GateError, InputError
from ..metrics.evaluate import PER_PERSON_SIGNATURE, EvalOptions, evaluate, parse_joints, write_per_person_csv
from ..metrics.ground_free_eval import GROUND_FREE, OWN, measure_sequence, scene_cameras
from ..metrics.tool_world import tool_world_line, tool_world_reports
from ..metrics.report import (change_text, check_gate_metrics, check_gate_rows, check_gates, column_labels,
                              format_value, ground_free_sections, metric_label, metric_value, parse_gate, report_paths,
                              report_sections, write_ground_free_reports, write_reports)
from ..files.outputs import check_output_file
from ._common import (ConfigOpt, ForceOpt, FromOpt, ImageSizeOpt, JsonOpt, QuietOpt, SmplModelOpt, config_for,
                      default_output, info, input_sequence, print_json, progress_bar, progress_enabled, report)


def eval_(
    pred: Annotated[list[Path] | None, typer.Argument(help="Prediction sequence directories; without --gt the sequences to measure, e.g. the input and its aligned output (default: the current directory).")] = None,
    gt: Annotated[Path | None, typer.Option("--gt", help="Ground-truth sequence directory (its camera.yaml enables ground-aware metrics). Without it: each sequence's ground-free measures.")] = None,
    camera: Annotated[Path | None, typer.Option("--camera", help="Without --gt: the scene camera's camera.yaml, for the sequences that have none of their own (default: the camera of a sequence given alongside, e.g. the aligned output's).", dir_okay=False)] = None,
    out: Annotated[Path | None, typer.Option(help="Folder for metrics.json and metrics.md; default <first PRED>_eval beside it (with --from: in the current folder; never inside a prediction).", file_okay=False)] = None,
    per_person: Annotated[Path | None, typer.Option("--per-person", help="Also write one CSV row per matched person (with --gt).", dir_okay=False)] = None,
    fail_if: Annotated[list[str] | None, typer.Option("--fail-if", help="Gate, e.g. 'w_mpjpe>300', 'pred_aligned:f1<0.9' or, without --gt, 'penetration_pct>5'; exit 1 if true.")] = None,
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
    """With --gt: one row per PRED against the ground truth (docs/metrics.md). Without --gt: one row per
    SEQ measured against its scene's ground, in the world of its camera.yaml (else --camera, else the
    camera of a sequence given alongside): feet height and penetration, foot sliding on contact, lean,
    stature per track and its spread, acceleration, and the camera's own uncertainty (docs/metrics.md,
    "Without ground truth"); e.g. `rotavat eval walk walk_aligned` puts before and after side by side.
    Exit status: 0 ok, 1 a --fail-if gate tripped, 2 bad input or usage.
    """
    opts = config_for(config, "eval", match=match, threshold_px=threshold_px, iou_threshold=iou_threshold,
                      engine=engine, protocol=protocol)
    gates = [parse_gate(text) for text in fail_if or []]
    preds = pred or [Path(".")]
    check_gate_rows(gates, preds)
    reading = (from_, image_size, smpl_model)
    if gt is None:
        truth_only = {"--per-person": per_person, "--match": match, "--threshold-px": threshold_px,
                      "--iou-threshold": iou_threshold, "--joints": joints, "--engine": engine, "--protocol": protocol,
                      "--gt-from": gt_from}
        given = [flag for flag, value in truth_only.items() if value is not None]
        if given:
            raise InputError(f"{given[0]} is for eval against ground truth (--gt GT); without it eval measures each "
                             "sequence against its scene's ground")
        results, json_path, md_path = _without_truth(preds, camera, out, gates, force, reading, quiet or as_json)
    else:
        if camera is not None:
            raise InputError("--camera is for eval without --gt (with --gt the world metrics use the ground "
                             "truth's camera.yaml)")
        results, json_path, md_path = _with_truth(preds, gt, gt_from, out, per_person, gates, force, reading, opts,
                                                  joints, quiet or as_json)
    reasons = check_gates(results, gates)
    if as_json:
        print_json({"metrics_json": str(json_path), "metrics_md": str(md_path), "gates_failed": reasons,
                    "predictions": [r.as_dict() for r in results]})
    elif not quiet:
        report(_table(results), quiet)
        for note, rows in _notes_once(results).items():  # a note every row shares is said once, naming them
            info(f"{', '.join(rows)}: {note}", quiet)
        for result in results:
            if result.tool_world is not None:
                info(tool_world_line(Path(result.pred).name or result.pred, result.tool_world), quiet)
        report(f"wrote {json_path} and {md_path}", quiet)
    if reasons:
        raise GateError("quality gate failed: " + "; ".join(reasons))


def _with_truth(preds: list[Path], gt: Path, gt_from: str | None, out: Path | None, per_person: Path | None, gates,
                force: bool, reading: tuple, opts: dict, joints: str | None, silent: bool):
    """Score every prediction against the ground truth: (results, metrics.json, metrics.md)."""
    options = EvalOptions.from_config(opts, parse_joints(joints))
    check_gate_metrics(gates, options.protocol)
    from_, image_size, smpl_model = reading
    inputs = [*preds, gt]
    out = out or default_output(preds[0], "_eval", from_)
    for target in report_paths(out):
        check_output_file(target, inputs, force)
    if per_person:
        check_output_file(per_person, inputs, force, signature=PER_PERSON_SIGNATURE.encode())
    with ExitStack() as stack:
        gt_seq = stack.enter_context(input_sequence(gt, gt_from, image_size, smpl_model, quiet=silent))
        pred_seqs = [stack.enter_context(input_sequence(p, from_, image_size, smpl_model, quiet=silent)) for p in preds]
        with progress_bar("evaluating", sum(len(s) for s in pred_seqs), progress_enabled(silent, silent)) as advance:
            results = [evaluate(s, gt_seq, options, advance) for s in pred_seqs]
        for result, world in zip(results, tool_world_reports(pred_seqs, gt_seq.camera, "truth")):
            result.tool_world = world
    json_path, md_path = write_reports(out, results, str(gt), {**opts, "joints": joints})
    if per_person:
        write_per_person_csv(per_person, results)
    return results, json_path, md_path


def _without_truth(seqs_in: list[Path], camera: Path | None, out: Path | None, gates, force: bool, reading: tuple,
                   silent: bool):
    """Measure every sequence against its scene's ground: (results, metrics.json, metrics.md)."""
    check_gate_metrics(gates, GROUND_FREE)
    from_, image_size, smpl_model = reading
    if camera is not None and not camera.is_file():
        raise InputError(f"{camera}: no such file (--camera)")
    out = out or default_output(seqs_in[0], "_eval", from_)
    for target in report_paths(out):
        check_output_file(target, [*seqs_in, *([camera] if camera else [])], force)
    with ExitStack() as stack:
        seqs = [stack.enter_context(input_sequence(p, from_, image_size, smpl_model, quiet=silent)) for p in seqs_in]
        scenes = scene_cameras(seqs, camera)
        for seq, scene in zip(seqs, scenes):
            if scene is None:
                from ..alignment.camera_gate import reader_flags
                from ..render.rows import no_camera

                raise no_camera(seq, "ground-free measures (eval without --gt)", reader_flags(*reading),
                                tuple(str(p) for p in seqs_in), command="eval")
            if camera is not None and scene.whence == OWN:
                info(f"{seq.label}: measured in its own camera ({scene.file}), not --camera {camera} (--camera is for "
                     "the sequences without one)", silent)
        with progress_bar("measuring", sum(len(s) for s in seqs), progress_enabled(silent, silent)) as advance:
            results = [measure_sequence(s, scene, advance) for s, scene in zip(seqs, scenes)]
        for result, world in zip(results, tool_world_reports(seqs)):
            result.tool_world = world
    json_path, md_path = write_ground_free_reports(out, results, {"camera": str(camera) if camera else None})
    return results, json_path, md_path


def _notes_once(results) -> dict[str, list[str]]:
    """Each distinct note of the rows, in order, with the rows that have it (``name (protocol)``)."""
    out: dict[str, list[str]] = {}
    for r in results:
        for note in r.notes:
            out.setdefault(note, []).append(f"{Path(r.pred).name or r.pred} ({r.protocol})")
    return out


def _table(results) -> Table:
    """Rich table: one row per metric, headline first and the rest by theme (a section each, as metrics.md's
    tables), one column per prediction, plus the change of each later one against the first."""
    protocols = ", ".join(sorted({r.protocol for r in results}))
    truth = results[0].protocol != GROUND_FREE
    title = (f"rotavat eval, protocol {protocols} (each metric: protocol, unit; camera: ° and %)" if truth else
             "rotavat eval without ground truth: each sequence in its scene camera's world (docs/metrics.md)")
    table = Table(title=title)
    table.add_column("metric")
    heads = column_labels(results)
    for head in heads:
        table.add_column(escape(head), justify="right")
    changes = ["change"] if len(results) == 2 else [f"change {escape(h)}" for h in heads[1:]]
    for change in changes:
        table.add_column(change, justify="right")
    pad = [""] * len(changes)
    if truth:
        lead = [("matched / gt", [f"{r.matched}/{r.people_gt}" for r in results])]
    else:
        lead = [("people-frames / tracks", [f"{r.people_pred}/{r.tracks}" for r in results]),
                ("scene camera", [r.scene_camera.get("from", "") for r in results])]
    sections = report_sections(results) if truth else ground_free_sections(results)
    for number, (name, metrics) in enumerate(sections):
        table.add_row(f"[bold]{name}[/]", *[""] * len(heads), *pad)
        for label, cells in lead if number == 0 else ():
            table.add_row(label, *cells, *pad)
        for i, metric in enumerate(metrics):
            values = [metric_value(r, metric) for r in results]
            label = metric_label(next((r for r in results if metric in r.metrics), results[0]), metric)
            table.add_row(escape(label), *(format_value(metric, v) for v in values),
                          *(change_text(values[0], v, 0) for v in values[1:]), end_section=i == len(metrics) - 1)
    if not truth and any(r.flags is not None for r in results):
        table.add_row("people.csv flags", *(", ".join(f"{k} {n}" for k, n in sorted(r.flags.items())) or "none"
                                            if r.flags is not None else "–" for r in results), *pad)
    return table
