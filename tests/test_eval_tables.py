"""The eval tables (issue 33, point 6): the headline numbers first with their change, the rest below by theme,
in metrics.md and on the terminal, with and without ground truth; metrics.json keeps every key, and every
metric a table shows can be gated."""

from __future__ import annotations

import json
import math
import re

import pytest
from _cli import invoke

from rotavat_cli.metrics.evaluate import EvalResult
from rotavat_cli.metrics.ground_free_eval import CAMERA_STD_METRICS, GROUND_FREE_METRICS, GroundFreeResult
from rotavat_cli.metrics.person_metrics import PERSON_METRICS
from rotavat_cli.metrics.protocols import PROTOCOLS
from rotavat_cli.metrics.report import (GATE_METRICS, GROUND_FREE_GROUPS, HIGHER_IS_BETTER, REPORT_COLUMNS,
                                        REPORT_GROUPS, check_gate_metrics, markdown_ground_free, markdown_report,
                                        parse_gate, write_reports)


def result(pred: str, **metrics: float) -> EvalResult:
    """A paper-protocol result with the given metrics (mm, '' for the shares), 10 of 12 people matched."""
    units = {m: PROTOCOLS["paper"].unit(m) for m in metrics}
    return EvalResult(pred, "gt", frames=3, people_gt=12, people_pred=11, matched=10, missed=2, false_positives=1,
                      metrics=dict(metrics), units=units, camera={"cam_focal_pct": 2.0, "cam_focal_pct_signed": -2.0})


def tables(md: str) -> dict[str, list[list[str]]]:
    """metrics.md's '## Title' tables: title -> rows of cells (header row first)."""
    out = {}
    for title, body in re.findall(r"^## (.+?)\n\n((?:\|.*\n)+)", md, re.M):
        rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in body.splitlines()]
        out[title] = [rows[0], *rows[2:]]
    return out


BEFORE = dict(w_mpjpe=1000.0, w_pve=1100.0, mpjpe=200.0, pa_mpjpe=50.0, group_pa_mpjpe=400.0, pve=220.0, pa_pve=55.0,
              f1=0.8, pcrd=0.5, precision=0.9, recall=0.75, root_err=900.0, accel_err=30.0, jitter=math.nan)
AFTER = {**BEFORE, "w_mpjpe": 250.0, "group_pa_mpjpe": 100.0, "pcrd": 0.75}


def test_headline_first_with_the_change_then_the_rest_by_theme():
    md = markdown_report([result("runs/pred", **BEFORE), result("runs/pred_aligned", **AFTER)], "gt")
    got = tables(md)
    assert list(got) == ["Headline", "World and ground", "Detection", "Temporal", "Camera"]
    head = got["Headline"]
    assert head[0] == ["metric", "`pred`", "`pred_aligned`", "change"]
    assert head[1] == ["matched / gt", "10/12", "10/12", ""]
    assert [row[0].split(" ")[0] for row in head[2:]] == ["w_mpjpe", "w_pve", "mpjpe", "pa_mpjpe", "group_pa_mpjpe",
                                                           "pve", "pa_pve", "f1"]
    assert head[2] == ["w_mpjpe (paper, mm)", "1000.0", "250.0", "-75.0%"]
    assert head[6] == ["group_pa_mpjpe (paper, mm)", "400.0", "100.0", "-75.0%"]
    assert ["pcrd (paper)", "0.500", "0.750", "+50.0%"] in got["World and ground"]
    assert got["Temporal"][1:] == [["accel_err (paper, mm/frame^2)", "30.00", "30.00", "+0.0%"]]  # jitter NaN: left out
    assert got["Camera"][1:] == [["cam_focal_pct", "2.0", "2.0", "+0.0%"]]  # not its *_signed twin
    # the predictions' own table keeps their paths and counts; the reading guide names the higher-better shares
    assert "| `runs/pred_aligned` | 3 | 10 | 2 | 1 |" in md
    assert "but for `f1`, `pcrd`, `precision`, `recall` (shares of 1: higher is better)" in md


def test_every_metric_shown_once_and_every_one_gateable():
    md = markdown_report([result("a", **BEFORE), result("b", **AFTER)], "gt")
    shown = [row[0].split(" ")[0] for rows in tables(md).values() for row in rows[1:] if row[0] != "matched / gt"]
    assert sorted(shown) == sorted({m for m in BEFORE if math.isfinite(BEFORE[m])} | {"cam_focal_pct"})
    assert len(REPORT_COLUMNS) == len(set(REPORT_COLUMNS))  # one group each
    assert set(PERSON_METRICS) <= set(REPORT_COLUMNS) <= GATE_METRICS
    for metric in (*REPORT_COLUMNS, *GROUND_FREE_METRICS, *CAMERA_STD_METRICS, "cam_pitch_deg", "matched"):
        assert parse_gate(f"{metric}>1").metric == metric
    check_gate_metrics([parse_gate("pcrd<0.9"), parse_gate("group_pa_mpjpe>100")], "paper")
    assert HIGHER_IS_BETTER == {"precision", "recall", "f1", "pcrd"}
    assert REPORT_GROUPS[0][0] == "Headline" and "group_pa_mpjpe" in REPORT_GROUPS[0][1]


def test_three_predictions_get_a_change_column_each_and_clashing_names_their_paths():
    three = [result("x/pred", w_mpjpe=100.0), result("y/pred", w_mpjpe=50.0), result("z/other", w_mpjpe=0.0)]
    head = tables(markdown_report(three, "gt"))["Headline"]
    assert head[0] == ["metric", "`x/pred`", "`y/pred`", "`z/other`", "change `y/pred`", "change `z/other`"]
    assert head[2] == ["w_mpjpe (paper, mm)", "100.0", "50.0", "0.0", "-50.0%", "-100.0%"]
    one = tables(markdown_report([result("x/pred", w_mpjpe=100.0)], "gt"))["Headline"]
    assert one[0] == ["metric", "`pred`"] and one[2] == ["w_mpjpe (paper, mm)", "100.0"]


def test_metrics_json_keeps_its_keys(tmp_path):
    json_path, _ = write_reports(tmp_path, [result("a", **BEFORE)], "gt", {})
    data = json.loads(json_path.read_text())
    assert sorted(data) == ["gt", "metric_names", "options", "predictions", "protocol", "written_by"]
    assert data["metric_names"] == list(PERSON_METRICS) and data["metric_names"][-2:] == ["group_pa_mpjpe", "pcrd"]
    row = data["predictions"][0]
    assert {"pred", "gt", "frames", "matched", "missed", "false_positives", "protocol", "metrics", "units", "notes",
            "camera"} <= set(row)
    assert row["metrics"]["pcrd"] == 0.5 and row["units"]["group_pa_mpjpe"] == "mm"


def test_ground_free_headline_then_the_rest():
    assert sorted(m for _, names in GROUND_FREE_GROUPS for m in names) == sorted((*GROUND_FREE_METRICS,
                                                                                 *CAMERA_STD_METRICS))
    values = {m: 1.0 for m in GROUND_FREE_METRICS}
    rows = [GroundFreeResult(p, frames=2, people_pred=4, tracks=2, metrics={**values, "lean": lean},
                             units={"lean": "deg"}, camera={"cam_std_height_m": 0.5},
                             scene_camera={"file": "c.yaml", "from": "own"}) for p, lean in (("a/in", 40.0), ("b/al", 2.0))]
    got = tables(markdown_ground_free(rows))
    assert list(got) == ["Headline", "Ground and posture", "Motion and stature", "Camera uncertainty"]
    assert [row[0].split(" ")[0] for row in got["Headline"][1:]] == ["feet_height", "penetration_pct", "lean",
                                                                     "sliding", "stature_spread"]
    assert ["lean (deg)", "40.0", "2.0", "-95.0%"] in got["Headline"]
    assert got["Camera uncertainty"][1:] == [["cam_std_height_m", "0.50", "0.50", "+0.0%"]]


@pytest.fixture(scope="module")
def sample_eval(tmp_path_factory):
    """The synthetic scene's prediction and its aligned output, evaluated with and without ground truth."""
    from typer.testing import CliRunner

    runner, tmp = CliRunner(), tmp_path_factory.mktemp("tables")
    s = tmp / "s"
    assert invoke(runner, "synth", s, "--seed", "7", "--frames", "3", "--people", "4", "-q").exit_code == 0
    assert invoke(runner, "align", "--in", s / "pred", "--camera", s / "gt" / "camera.yaml", "--out", s / "al",
                  "-q").exit_code == 0
    with_gt = invoke(runner, "eval", s / "pred", s / "al", "--gt", s / "gt", "--out", tmp / "ev")
    without = invoke(runner, "eval", s / "pred", s / "al", "--out", tmp / "ev_free")
    return tmp, with_gt, without


def test_the_terminal_table_has_the_same_sections_in_order(sample_eval):
    tmp, with_gt, without = sample_eval
    assert with_gt.exit_code == 0 and without.exit_code == 0
    text = with_gt.stdout
    order = [text.index(title) for title in ("Headline", "World and ground", "Detection", "Camera")]
    assert order == sorted(order)
    assert text.index("w_mpjpe (paper, mm)") < text.index("World and ground") < text.index("pcrd (paper)")
    assert text.index("group_pa_mpjpe (paper, mm)") < text.index("World and ground")
    free = without.stdout
    assert free.index("feet_height (mm)") < free.index("stature_spread (mm)") < free.index("Ground and posture") \
        < free.index("floating_pct (%)")
    md = (tmp / "ev" / "metrics.md").read_text()
    assert list(tables(md))[:2] == ["Headline", "World and ground"]


def test_a_metric_of_no_group_is_still_shown():
    """A newly registered metric that no one put in a group yet lands in a last "More" table, not nowhere."""
    md = markdown_report([result("a", w_mpjpe=10.0, toy_mm=7.0)], "gt")
    assert list(tables(md)) == ["Headline", "More", "Camera"] and tables(md)["More"][1:] == [["toy_mm (paper)", "7.0"]]
