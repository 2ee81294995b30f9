"""The README's numbers that are cheap to recompute, recomputed: the sample scene of `make run`.

A number quoted in the README must be what the code gives today; this test fails when they drift
(`make docs-check` also re-measures the slower ones)."""

from __future__ import annotations

import re
from pathlib import Path

from rotavat_cli import AlignOptions, CalibrateOptions, align_sequence, calibrate_sequence, evaluate, open_sequence

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
SCENE = ROOT / "sample_data" / "scene"


def test_the_sample_scene_numbers_the_readme_quotes(tmp_path):
    pred, gt = open_sequence(SCENE / "pred", read_camera=False), open_sequence(SCENE / "gt")
    calib = calibrate_sequence(pred, CalibrateOptions())
    summary = align_sequence(pred, calib.result.camera, tmp_path / "aligned", AlignOptions(),
                             camera_fit=calib.fit_dict())
    before, after = (evaluate(s, gt).metrics for s in (pred, open_sequence(tmp_path / "aligned")))
    quoted = (f"W-MPJPE\n{before['w_mpjpe']:,.0f} → {after['w_mpjpe']:,.0f} mm, PA-MPJPE "
              f"{before['pa_mpjpe']:.1f} → {after['pa_mpjpe']:.1f} mm, group PA-MPJPE (one similarity for all the "
              f"people of a frame) {before['group_pa_mpjpe']:,.0f} → {after['group_pa_mpjpe']:,.0f} mm, depth order "
              f"of the people (PCRD) {before['pcrd']:.2f} → {after['pcrd']:.2f}")
    assert quoted.replace("\n", " ") in " ".join(README.split()), quoted
    drift = f"{summary.median_drift_px:.0f} px for the median person, {summary.max_drift_px:.0f} px for the farthest-moved"
    assert drift in " ".join(README.split()), drift


def test_the_readme_quotes_no_number_twice_differently():
    """The sample's W-MPJPE appears in one form only (a re-measure that updates one copy and not the other fails)."""
    found = set(re.findall(r"16,381 → ([\d,]+) mm", README))
    assert len(found) == 1, found
