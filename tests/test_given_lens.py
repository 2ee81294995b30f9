"""A calibration through a known lens (calibration/given_lens.py, calibrate --lens / --lens-lines)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from _cli import invoke
from typer.testing import CliRunner

from rotavat_cli.bodies.measure import statures_from_camera_m
from rotavat_cli.calibration import CalibrateOptions, fit_camera
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.geometry.lens import distort_px, lens_radius_px
from rotavat_cli.sequence import Frame, write_frame, write_meta

SIZE = (1280, 720)
LAM = -0.25  # barrel: the corner pulled in by a fifth


def _pairs(seed: int = 0, n: int = 300, noise_px: float = 1.0):
    """Feet and crowns (N, 2) px of people of known statures (N,) seen through a barrel lens, with click noise."""
    rng = np.random.default_rng(seed)
    cam = Camera(SIZE, 1000.0, None, np.deg2rad(20.0), np.deg2rad(1.0), 4.0, distortion=LAM)
    feet_cam = cam.backproject_px_to_ground(rng.uniform([50, 300], [1230, 700], (n, 2)))
    statures = rng.normal(1.70, 0.07, n)
    feet, heads = cam.project(feet_cam), cam.project(feet_cam + statures[:, None] * cam.up_cam)
    keep = np.all(np.isfinite(feet), 1) & np.all(np.isfinite(heads), 1) & (heads[:, 1] > 0)
    noisy = [p[keep] + rng.normal(0.0, noise_px, (keep.sum(), 2)) for p in (feet, heads)]
    return cam, *noisy, statures[keep]


def test_a_given_lens_is_removed_before_the_fit_and_carried_by_the_camera():
    truth, feet, heads, statures = _pairs()
    pinhole = fit_camera(feet, heads, SIZE)
    given = fit_camera(feet, heads, SIZE, lens_distortion=LAM)
    assert given.camera.distortion == LAM and pinhole.camera.distortion == 0.0
    err = {name: np.mean(np.abs(statures_from_camera_m(feet, heads, r.camera) - statures))
           for name, r in (("pinhole", pinhole), ("given", given))}
    assert err["given"] < 0.015 < 0.04 < err["pinhole"], err  # measured: 1.1 cm against 6.4 cm
    assert given.camera.focal_px == pytest.approx(truth.focal_px, rel=0.03)
    assert np.rad2deg(given.camera.pitch_rad) == pytest.approx(20.0, abs=0.3)
    fit = given.fit_dict()
    assert fit["lens"] == {"from": "given", "distortion": LAM, "sd": 0.01}
    assert fit["fixed"]["distortion"] == "given"
    assert any(note.startswith("lens given: division coefficient -0.2500") for note in fit["notes"])


def test_a_given_lens_is_not_fitted_again_to_few_pairs_of_a_measured_reference():
    """A reference of measured stature (few pairs: the defaults would try a lens) with the lens given: the pairs are
    undistorted once and fitted as a pinhole; no second lens is fitted to them (the camera's lens is the given one
    and the fit's only lens note is the given lens's). Before, the inner fit tried the lens on undistorted pairs."""
    _, feet, heads, _ = _pairs(seed=4, n=30)
    plain = fit_camera(feet, heads, SIZE, person_height_m=1.7, person_height_sd_m=0.01, lens_distortion=LAM)
    assert plain.camera.distortion == LAM and plain.fixed["distortion"] == "given"
    assert [n for n in plain.notes if n.startswith("lens")] == [
        "lens given: division coefficient -0.2500 (sd 0.0100); the pairs were undistorted before the fit and the "
        "camera carries the lens"]


def test_the_footprint_is_in_image_pixels():
    _, feet, heads, _ = _pairs(seed=1)
    result = fit_camera(feet, heads, SIZE, lens_distortion=LAM)
    hull = result.footprint_px
    assert len(hull) >= 3
    nearest = np.min(np.linalg.norm(hull[:, None] - feet[None], axis=-1), axis=1)
    assert np.max(nearest) < 1e-6  # each vertex is an inlier's own (distorted) foot pixel


def test_a_lens_is_given_or_fitted_not_both():
    with pytest.raises(ValueError, match="use one, not both"):
        CalibrateOptions(distortion=True, lens_distortion=-0.1)
    with pytest.raises(ValueError, match="lens_distortion"):
        CalibrateOptions(lens_distortion=0.7)


def _sequence(path, feet, heads):
    for t in range(0, len(feet), 20):
        ids = np.arange(len(feet[t:t + 20]))
        write_frame(path, Frame(f"{t:06d}", {"feet_2d": feet[t:t + 20], "heads_2d": heads[t:t + 20],
                                              "person_ids": ids + t}), "npz")
    write_meta(path, {"image_size": list(SIZE)})


def test_calibrate_takes_the_lens_from_the_scene_lines(tmp_path):
    _, feet, heads, _ = _pairs(seed=2, n=200)
    seq = tmp_path / "seq"
    _sequence(seq, feet, heads)
    rng = np.random.default_rng(5)
    straight = [np.stack([np.linspace(60, 1220, 9), np.full(9, v)], axis=1) for v in (50.0, 670.0)]
    straight += [np.stack([np.full(9, u), np.linspace(40, 680, 9)], axis=1) for u in (70.0, 1210.0)]
    bent = [distort_px(line, LAM, (640.0, 360.0), lens_radius_px(SIZE)) + rng.normal(0, 0.5, line.shape)
            for line in straight]
    (tmp_path / "lines.yaml").write_text(yaml.safe_dump({"lines": [line.tolist() for line in bent]}))
    runner = CliRunner()
    result = invoke(runner, "calibrate", seq, "--lens-lines", tmp_path / "lines.yaml", "--quiet")
    assert result.exit_code == 0, result.output
    written = yaml.safe_load((seq / "camera.yaml").read_text())
    assert written["distortion"] == pytest.approx(LAM, abs=0.01)
    assert written["fit"]["lens"]["from"].startswith("lines ")
    assert 0 < written["fit"]["lens"]["sd"] < 0.01


def test_calibrate_fits_the_lens_of_a_measured_reference_by_default(tmp_path):
    """One walker of tape-measured stature, 30 clicks through a barrel lens, one per frame: `calibrate
    --person-height 1.75 --height-sd 0.01` writes the lens it fitted; `--no-distortion` writes none."""
    rng = np.random.default_rng(8)
    cam = Camera(SIZE, 1000.0, None, np.deg2rad(20.0), 0.0, 4.0, distortion=LAM)
    uv = np.column_stack([np.linspace(150, 1130, 30), np.linspace(320, 700, 30)]) + rng.normal(0, 15, (30, 2))
    feet_cam = cam.backproject_px_to_ground(uv)
    feet, heads = (cam.project(p) + rng.normal(0, 1.0, (30, 2)) for p in (feet_cam, feet_cam + 1.75 * cam.up_cam))
    lens = {}
    for flags in ((), ("--no-distortion",)):
        seq = tmp_path / f"seq{len(flags)}"
        for t in range(30):
            write_frame(seq, Frame(f"{t:06d}", {"feet_2d": feet[t:t + 1], "heads_2d": heads[t:t + 1],
                                                "person_ids": np.array([7])}), "npz")
        write_meta(seq, {"image_size": list(SIZE)})
        result = invoke(CliRunner(), "calibrate", seq, "--person-height", "1.75", "--height-sd", "0.01", *flags,
                        "--quiet")
        assert result.exit_code == 0, result.output
        lens[flags] = yaml.safe_load((seq / "camera.yaml").read_text())
    assert lens[()]["distortion"] == pytest.approx(LAM, abs=0.03)
    assert any(n.startswith("lens fitted: the pairs tell") for n in lens[()]["fit"]["notes"])
    assert "distortion" not in lens[("--no-distortion",)]


@pytest.mark.parametrize("args, message", [
    (("--lens", "0.9"), "--lens: must be within -0.5..0.5"),
    (("--lens", "-0.1", "--distortion"), "--lens, --lens-lines and --distortion each set the lens"),
])
def test_bad_lens_flags_are_one_line_and_exit_2(tmp_path, args, message):
    _, feet, heads, _ = _pairs(seed=3, n=40)
    seq = tmp_path / "seq"
    _sequence(seq, feet, heads)
    result = invoke(CliRunner(), "calibrate", seq, *args, catch_exceptions=True)
    assert result.exit_code == 2 and message in result.output, result.output
    assert not (seq / "camera.yaml").exists()


def test_a_config_distortion_that_is_not_a_flag_is_one_line_and_exit_2(tmp_path):
    _, feet, heads, _ = _pairs(seed=3, n=40)
    seq = tmp_path / "seq"
    _sequence(seq, feet, heads)
    (tmp_path / "c.yaml").write_text("calibrate:\n  distortion: auto\n")
    result = invoke(CliRunner(), "calibrate", seq, "--config", tmp_path / "c.yaml", catch_exceptions=True)
    assert result.exit_code == 2 and "distortion must be true, false or null" in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1 and not (seq / "camera.yaml").exists()


def test_info_shows_the_cameras_lens():
    from rotavat_cli.cli.info import _camera_cell

    camera = {"focal_px": 1000.0, "pitch_deg": 20.0, "roll_deg": 1.0, "height_m": 4.0, "distortion": -0.25,
              "fit": {"std": {}, "fixed": {"distortion": "given"}, "lens": {"from": "given", "distortion": -0.25,
                                                                           "sd": 0.01}}}
    assert _camera_cell(camera).endswith("lens -0.2500 ± 0.0100 (given)")
    assert "lens" not in _camera_cell({**camera, "distortion": {"model": "opencv"}})  # an answer key's own lens block
