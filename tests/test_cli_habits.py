"""Real habits (issue 24): where outputs go, what --quiet silences, what info says of photos of several sizes,
and counts in words."""

from __future__ import annotations

import json
import re

import _format_fixtures as F
import numpy as np
from _cli import invoke

from rotavat_cli.sequence import Frame, open_sequence, write_frame
from rotavat_cli.synth import SynthOptions, write_synth_scene
from rotavat_cli.words import count

W, H = F.W, F.H


def _bev_photo(folder, model):
    """A BEV image-mode output of 5 standing people (the tool's own file)."""
    return F.write_bev(folder, F.bev_scene(model, 2, 5), (W, H))


def test_outputs_of_a_from_source_go_to_the_current_folder_not_the_data_folder(tmp_path, model, model_path,
                                                                                 runner, monkeypatch):
    data, work = tmp_path / "data", tmp_path / "work"
    src = _bev_photo(data / "bev", model)
    work.mkdir()
    monkeypatch.chdir(work)
    common = ["--from", "bev", "--smpl-model", model_path, "--image-size", str(W), str(H)]
    assert invoke(runner, "calibrate", src, *common, "--out", work / "cam.yaml", "-q").exit_code == 0
    before = sorted(p.name for p in data.iterdir())
    result = invoke(runner, "align", src, *common, "--camera", work / "cam.yaml", "--json")
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["out"] == "bev_aligned" and (work / "bev_aligned").is_dir()  # as typed
    assert sorted(p.name for p in data.iterdir()) == before  # nothing written beside the tool's output
    result = invoke(runner, "eval", src, *common, "--gt", work / "bev_aligned", "--json")
    assert result.exit_code == 0 and (work / "bev_eval" / "metrics.json").is_file()


def test_quiet_silences_notes_and_results_but_keeps_warnings(tmp_path, runner):
    write_synth_scene(tmp_path / "s", SynthOptions(seed=4, frames=2, people=4))
    pred = tmp_path / "s" / "pred"
    seq = open_sequence(pred)
    frame = seq.read_frame(seq.frame_names[1])
    write_frame(pred, Frame(frame.name, {**frame.data, "image_size": np.array([1666, 2500])}, frame.source), "npz")
    result = invoke(runner, "info", pred, "-q")
    assert result.exit_code == 0 and "frames of 2 image sizes" in result.stderr  # the warning stays ...
    assert "per frame (2 sizes: 1280x720, 1666x2500)" in result.stdout  # ... and the table says what sizes are
    wide = invoke(runner, "calibrate", "--help", env={"COLUMNS": "240"})  # the help, unwrapped
    assert "No progress bar, no notes and no summary or table on stdout; warnings and errors still go to stderr" in \
        wide.stdout


def test_counts_read_in_words():
    assert [count(n, "person", "people") for n in (0, 1, 2)] == ["0 people", "1 person", "2 people"]
    assert count(1, "frame") == "1 frame" and count(5, "frame") == "5 frames"


def test_the_head_column_warning_keeps_quiet_on_a_clean_synthetic_scene(tmp_path):
    """It fired on nearly every run (the walkthrough's own scene: centred principal point, no distortion);
    this scene gave 30 on 3 dof, over the 99% quantile (11) the test used."""
    from rotavat_cli.calibration import CalibrateOptions, calibrate_sequence

    write_synth_scene(tmp_path / "s", SynthOptions(seed=8, frames=20, people=8, image_size=(1280, 720)))
    result = calibrate_sequence(open_sequence(tmp_path / "s" / "pred", read_camera=False), CalibrateOptions()).result
    assert not any("head columns" in w for w in result.warnings) and result.determined_by["focal_px"] == "people"


def test_help_at_80_columns_gives_each_option_a_readable_line(runner):
    """At 80 columns rich's panel gave option help ~17 characters and cut it ('(bottom-/top-ce…'): a narrow
    terminal now gets click's plain layout; a wide one keeps the panels."""
    narrow = invoke(runner, "calibrate", "--help", env={"COLUMNS": "80"}).stdout
    assert max(len(line) for line in narrow.splitlines()) <= 80 and "…" not in narrow
    assert "The camera's known focal length (px)." in narrow  # one line, not 17-character shreds
    assert "(bottom-/top-centre of person boxes; refine," in " ".join(narrow.split())
    wide = invoke(runner, "calibrate", "--help", env={"COLUMNS": "200"}).stdout
    assert "╭─ Options" in wide and "[default: 1.7]" in wide and "[default: 1.7]" in narrow


def test_calibrate_prints_its_summary_on_one_line_below_the_table(tmp_path, runner):
    """The summary was the table's caption, wrapped to the table's width (five short lines)."""
    from pathlib import Path

    scene = Path(__file__).resolve().parents[1] / "sample_data" / "scene"
    out = invoke(runner, "calibrate", scene / "pred", "--out", tmp_path / "c.yaml").stdout
    (line,) = [line for line in out.splitlines() if "inliers over" in line]
    assert "head rmse" in line and "meshes made with f" in line and re.match(r"\d+/20 pairs inliers over 4 frames, ", line) is not None
