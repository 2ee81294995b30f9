"""Statures from a known camera (rotavat_cli.bodies.measure) and `rotavat measure`."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.bodies.measure import statures_from_camera_m, statures_by_track
from rotavat_cli.sequence import Frame, write_camera_yaml, write_frame, write_meta

# A street camera: tilted, rolled, principal point off the image centre (every term of the model matters).
CAM = Camera((1280, 720), 1100.0, (610.0, 380.0), np.deg2rad(22.0), np.deg2rad(4.0), 6.5)


def _people(rng: np.random.Generator, n: int, camera: Camera = CAM) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot and head pixels (n, 2) of n upright people of random statures (n,) m on the ground."""
    W, H = camera.image_size
    feet_px = np.stack([rng.uniform(50, W - 50, n), rng.uniform(0.45 * H, H - 20, n)], axis=-1)
    statures_m = rng.uniform(1.0, 2.1, n)
    feet_cam = camera.backproject_px_to_ground(feet_px)
    return feet_px, camera.project(feet_cam + statures_m[:, None] * camera.up_cam), statures_m


def _vertical_px(foot_px: np.ndarray, s_m: np.ndarray, camera: Camera = CAM) -> np.ndarray:
    """Pixels (S, 2) of the points s_m (S,) metres above the ground point under foot_px (2,)."""
    return camera.project(camera.backproject_px_to_ground(foot_px) + s_m[:, None] * camera.up_cam)


# ---- statures_from_camera_m ------------------------------------------------------------------------
@pytest.mark.parametrize("n", [0, 1, 3, 200])
def test_known_statures_are_recovered_exactly(n):
    feet, heads, statures = _people(np.random.default_rng(n), n)
    got = statures_from_camera_m(feet, heads, CAM)
    assert got.shape == (n,) and got.dtype == np.float64
    np.testing.assert_allclose(got, statures, rtol=0, atol=1e-9)


def test_leading_dimensions_broadcast():
    feet, heads, statures = _people(np.random.default_rng(1), 6)
    got = statures_from_camera_m(feet.reshape(2, 3, 2).astype(np.float32), heads.reshape(2, 3, 2), CAM)
    assert got.shape == (2, 3)
    np.testing.assert_allclose(got.ravel(), statures, atol=1e-3)  # float32 feet: ~1e-4 px of rounding
    one = statures_from_camera_m(feet[0], heads[:3], CAM)  # one foot against three heads
    assert one.shape == (3,)


def test_a_foot_above_the_horizon_gives_nan():
    u = np.array([100.0, 640.0, 1200.0])
    horizon_v = CAM.horizon_v_px(u)
    feet = np.stack([u, horizon_v - 5.0], axis=-1)  # the foot ray never meets the ground
    heads = feet - [0.0, 100.0]
    assert np.isnan(statures_from_camera_m(feet, heads, CAM)).all()
    assert np.isnan(statures_from_camera_m([[np.nan, 500.0]], [[600.0, 300.0]], CAM)).all()


def test_a_head_pixel_off_the_vertical_counts_by_its_orthogonal_projection():
    foot = np.array([300.0, 600.0])
    on_line = _vertical_px(foot, np.array([0.0, 1.75]))
    direction = (on_line[1] - on_line[0]) / np.linalg.norm(on_line[1] - on_line[0])
    normal = np.array([-direction[1], direction[0]])
    heads = on_line[1] + np.array([-30.0, -4.0, 7.0, 25.0])[:, None] * normal  # off the line, across it
    np.testing.assert_allclose(statures_from_camera_m(foot, heads, CAM), 1.75, atol=1e-9)
    # and the answer is the point of the vertical nearest the head pixel (brute force over heights)
    head = on_line[1] + 12.0 * normal + 9.0 * direction
    s = float(statures_from_camera_m(foot, head, CAM))
    grid = np.linspace(s - 0.05, s + 0.05, 2001)
    nearest = grid[np.argmin(np.linalg.norm(_vertical_px(foot, grid) - head, axis=-1))]
    assert abs(nearest - s) < 1e-4 and s > 1.75


def test_a_head_beyond_the_vertical_vanishing_point_is_behind_the_camera():
    foot = np.array([640.0, 500.0])
    b = CAM.K @ CAM.up_cam
    vanishing = b[:2] / b[2]  # a camera looking down: the image of "up" meets below the image (the nadir)
    heads = foot + np.array([[0.5], [1.5]]) * (vanishing - foot)
    below, behind = statures_from_camera_m(foot, heads, CAM)
    assert below < 0.0 and np.isnan(behind)  # toward the nadir: below the ground, then behind the camera


def test_shapes_that_are_not_pixels_are_refused():
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        statures_from_camera_m(np.zeros((3, 3)), np.zeros((3, 2)), CAM)


# ---- statures_by_track -----------------------------------------------------------------------------------
def test_track_medians_and_spreads_by_hand():
    statures = np.array([1.80, 1.60, np.nan, 1.70, 1.75, 1.65, 1.70, 1.50, np.nan])
    ids = np.array([2, 5, 2, 2, 5, 5, 5, 9, 11])
    res = statures_by_track(statures, ids)
    assert res.ids.tolist() == [2, 5, 9, 11] and res.pairs.tolist() == [2, 4, 1, 0]
    # track 2: {1.70, 1.80}: median 1.75, quartiles 1.725 and 1.775; track 5: {1.60, 1.65, 1.70, 1.75}:
    # median 1.675, quartiles 1.6375 and 1.7125; track 9: one value; track 11: nothing measured
    np.testing.assert_allclose(res.median_m[:3], [1.75, 1.675, 1.50])
    np.testing.assert_allclose(res.spread_m[:3], [0.025, 0.0375, 0.0])
    assert np.isnan(res.median_m[3]) and np.isnan(res.spread_m[3])
    assert res.rows()[1] == {"id": 5, "pairs": 4, "median_m": pytest.approx(1.675), "spread_m": pytest.approx(0.0375)}


def test_track_statures_match_numpy_quantiles_per_track():
    rng = np.random.default_rng(3)
    ids = rng.integers(0, 40, 3000)
    statures = rng.normal(1.7, 0.08, 3000)
    res = statures_by_track(statures, ids)
    for i, track in enumerate(res.ids):
        q25, q50, q75 = np.quantile(statures[ids == track], [0.25, 0.5, 0.75])
        assert res.median_m[i] == pytest.approx(q50, abs=1e-12)
        assert res.spread_m[i] == pytest.approx((q75 - q25) / 2, abs=1e-12)


def test_track_statures_of_nothing_and_bad_shapes():
    empty = statures_by_track(np.zeros(0), np.zeros(0, np.int64))
    assert len(empty) == 0 and empty.rows() == []
    with pytest.raises(ValueError, match="track_ids"):
        statures_by_track(np.ones(3), np.array([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match=r"\(N,\)"):
        statures_by_track(np.ones(3), np.ones(2, np.int64))


# ---- rotavat measure ------------------------------------------------------------------------------------
STATURES = {4: 1.58, 7: 1.71, 12: 1.93}


@pytest.fixture
def seq(tmp_path: Path) -> Path:
    """Three tracked people walking over 5 frames (track 12 leaves after 3), seen by CAM, with its camera.yaml."""
    out = tmp_path / "walk"
    out.mkdir()
    for t in range(5):
        ids = np.array([4, 7, 12]) if t < 3 else np.array([4, 7])
        feet = np.array([[150.0 + 60 * t, 420.0 + 20 * t], [900.0 - 40 * t, 650.0 - 15 * t], [620.0, 380.0 + 30 * t]])
        feet = feet[: len(ids)]
        heads = CAM.project(CAM.backproject_px_to_ground(feet)
                            + np.array([STATURES[i] for i in ids])[:, None] * CAM.up_cam)
        write_frame(out, Frame(f"{t:06d}", {"feet_2d": feet, "heads_2d": heads, "person_ids": ids}), "npz")
    write_meta(out, {"image_size": list(CAM.image_size)})
    write_camera_yaml(out / "camera.yaml", CAM, {"method": "refine", "implausible": []})
    return out


def test_measure_recovers_each_persons_stature(seq, runner):
    before = tree_hash(seq)
    result = invoke(runner, "measure", seq)
    assert result.exit_code == 0, result.stderr
    assert tree_hash(seq) == before  # the input is never written
    assert "warning" not in result.stderr
    with open(seq.parent / "walk_measure.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["track_id"] for r in rows] == ["4", "7", "12"] and [r["pairs"] for r in rows] == ["5", "5", "3"]
    for r in rows:
        assert float(r["median_stature_m"]) == pytest.approx(STATURES[int(r["track_id"])], abs=1e-6)
        assert float(r["spread_m"]) < 1e-6
    assert "1.930" in result.stdout and "walk_measure.csv" in result.stdout


def test_measure_json_and_an_explicit_camera_and_csv(seq, tmp_path, runner):
    other = tmp_path / "cam.yaml"
    write_camera_yaml(other, CAM, {"implausible": ["track 12: 2.31 m"]})
    out = tmp_path / "statures.csv"
    result = invoke(runner, "measure", seq, "--camera", other, "--out", out, "--json")
    assert result.exit_code == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["camera"] == str(other) and summary["csv"] == str(out) and summary["tracked"] is True
    assert summary["pairs"] == summary["measured"] == 13
    assert {t["id"]: t["median_m"] for t in summary["tracks"]} == pytest.approx(STATURES, abs=1e-6)
    assert summary["median_of_tracks_m"] == pytest.approx(1.71, abs=1e-6)
    assert out.read_text().splitlines()[0] == ("track_id,pairs,median_stature_m,spread_m,stature_from,std_m,std_camera_m,"
                                               "std_pixels_m,extrapolated")
    assert summary["stature_from"] == "prior" and "prior given back" in summary["stature_provenance"]
    assert result.stderr == ""  # --json: diagnostics quiet too
    warned = invoke(runner, "measure", seq, "--camera", other, "--out", out)  # its own CSV: replaced freely
    assert warned.exit_code == 0
    lines = [line for line in warned.stderr.splitlines() if "warning" in line]
    assert len(lines) == 1 and str(other) in lines[0] and "implausible" in lines[0] and "2.31 m" in lines[0]


def test_measure_without_a_camera_names_the_command_that_makes_one(seq, runner):
    (seq / "camera.yaml").unlink()
    result = invoke(runner, "measure", seq)
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert f"rotavat calibrate {seq}" in result.stderr and not (seq.parent / "walk_measure.csv").exists()


def test_measure_never_replaces_a_users_file_nor_writes_inside_the_input(seq, runner):
    mine = seq.parent / "walk_measure.csv"
    mine.write_text("my notes\n")
    result = invoke(runner, "measure", seq)
    assert result.exit_code == 2 and "--force" in result.stderr and mine.read_text() == "my notes\n"
    assert invoke(runner, "measure", seq, "--force").exit_code == 0 and mine.read_text().startswith("track_id")
    inside = invoke(runner, "measure", seq, "--out", seq / "s.csv")
    assert inside.exit_code == 2 and "inside the input" in inside.stderr


def test_measure_refuses_another_images_camera(seq, tmp_path, runner):
    write_camera_yaml(tmp_path / "wide.yaml", CAM.replace(image_size=(1920, 1080)))
    result = invoke(runner, "measure", seq, "--camera", tmp_path / "wide.yaml", "--out", tmp_path / "m.csv")
    assert result.exit_code == 2 and "1920x1080" in result.stderr and "1280x720" in result.stderr


def test_measure_pools_untracked_pairs_into_one_row(seq, tmp_path, runner):
    frame = np.load(seq / "000000.npz")
    write_frame(seq, Frame("000000", {k: frame[k] for k in ("feet_2d", "heads_2d")}), "npz")  # no person_ids
    result = invoke(runner, "measure", seq, "--out", tmp_path / "m.csv", "--json")
    summary = json.loads(result.stdout)
    assert summary["tracked"] is False and [t["id"] for t in summary["tracks"]] == [-1]
    assert summary["tracks"][0]["pairs"] == 13 and summary["median_of_tracks_m"] is None


def test_measure_names_a_broken_camera_file(seq, tmp_path, runner):
    bad = tmp_path / "bad.yaml"
    bad.write_text("image_size: [1280, 720]\nfocal_px: -3\npitch_deg: 20\nheight_m: 5\n")
    result = invoke(runner, "measure", seq, "--camera", bad, "--out", tmp_path / "m.csv")
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1
    assert str(bad) in result.stderr and "focal_px" in result.stderr and not (tmp_path / "m.csv").exists()


def test_measure_says_where_its_statures_come_from(seq, tmp_path, runner):
    """The camera's scale decides whether statures are measured: a camera height given to calibrate (fit.fixed),
    a reference person (fit.scale_from: reference), a camera without a fit block (ground truth) measure them; a
    camera whose height came from the people's stature prior gives that prior back."""
    cases = {"prior": ({"method": "refine"}, "1.70 m stature prior given back"),
             "camera_height": ({"fixed": {"height_m": "given"}}, "measured: the camera height was given"),
             "reference": ({"scale_from": "reference", "person_height_m": 1.93}, "reference person of 1.93 m"),
             "given_camera": (None, "measured with a given camera")}
    for source, (fit, words) in cases.items():
        cam = tmp_path / f"{source}.yaml"
        write_camera_yaml(cam, CAM, fit)
        out = tmp_path / f"{source}.csv"
        result = invoke(runner, "measure", seq, "--camera", cam, "--out", out)
        assert result.exit_code == 0, result.stderr
        assert words in " ".join(result.stdout.split())
        with open(out, newline="") as handle:
            assert {row["stature_from"] for row in csv.DictReader(handle)} == {source}


def test_measure_leaves_people_cut_by_the_border_unmeasured(seq, tmp_path, runner):
    """A pair whose foot lies below the image (a leg the photo cuts off) measures nothing: its track keeps its
    other pairs, and a note counts the cut ones."""
    frame = dict(np.load(seq / "000000.npz"))
    frame["feet_2d"] = frame["feet_2d"].copy()
    frame["feet_2d"][2, 1] = CAM.image_size[1] + 50.0
    write_frame(seq, Frame("000000", frame), "npz")
    out = tmp_path / "s.csv"
    result = invoke(runner, "measure", seq, "--out", out, "--json")
    summary = json.loads(result.stdout)
    assert summary["cut_pairs"] == 1 and summary["measured"] == 12
    assert {t["id"]: t["pairs"] for t in summary["tracks"]} == {4: 5, 7: 5, 12: 2}
    noted = invoke(runner, "measure", seq, "--out", out)
    assert "1 of 13 pairs are of people cut by the image border" in noted.stderr
