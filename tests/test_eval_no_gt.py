"""``rotavat eval SEQ...`` without ground truth: each measure against a hand-computed case, a sequence measured
in its scene camera, the CLI before/after on a synthetic scene, its gates, its JSON, and batch's report."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.batch.report import aggregate_rows
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.bodies.landmarks import SMPL
from rotavat_cli.metrics.ground_free import (acceleration_m, consecutive_windows, contact_sliding_m,
                                             feet_height_summary, lean_summary, stature_summary)
from rotavat_cli.metrics.ground_free_eval import (ALONGSIDE, GIVEN, GROUND_FREE_METRICS, OWN, measure_sequence,
                                                  scene_cameras)
from rotavat_cli.metrics.scene import lean_deg
from rotavat_cli.sequence import open_sequence, write_camera_yaml

FPS = 30.0


# ---- the measures, by hand ----------------------------------------------------------------------------


def test_feet_height_floating_sunk_and_on_the_ground():
    assert feet_height_summary(np.array([0.10])) == pytest.approx(
        {"feet_height": 100.0, "feet_height_median": 100.0, "floating_pct": 100.0, "penetration_pct": 0.0,
         "penetration_depth": 0.0})
    assert feet_height_summary(np.array([-0.03])) == pytest.approx(
        {"feet_height": 30.0, "feet_height_median": 30.0, "floating_pct": 0.0, "penetration_pct": 100.0,
         "penetration_depth": 30.0})
    # 4 mm above and 5 mm under: neither floating (> 5 cm) nor sunk (> 1 cm under); NaN (no foot point) left out
    mixed = feet_height_summary(np.array([0.004, -0.005, 0.10, -0.03, np.nan]))
    assert mixed == pytest.approx({"feet_height": 1000.0 * (0.004 + 0.005 + 0.10 + 0.03) / 4,
                                   "feet_height_median": 1000.0 * (0.005 + 0.03) / 2, "floating_pct": 25.0,
                                   "penetration_pct": 25.0, "penetration_depth": 1000.0 * (0.005 + 0.03) / 4})
    assert all(math.isnan(v) for v in feet_height_summary(np.zeros(0)).values())


def soles_track(n_frames: int, step_m: float, height_m: float = 0.0) -> np.ndarray:
    """(T, 2, 3) the two soles of one person, 30 cm apart, sliding ``step_m`` along X per frame at ``height_m``."""
    t = np.arange(n_frames, dtype=np.float64)[:, None]
    left = np.hstack([step_m * t, np.full_like(t, height_m), np.zeros_like(t)])
    return np.stack([left, left + [0.0, 0.0, 0.3]], axis=1)


def test_sliding_one_centimetre_per_frame_on_contact_is_0_3_m_per_s_at_30_fps():
    soles = soles_track(4, 0.01)
    ids, frames = np.full(4, 5), np.arange(4)
    per_step = contact_sliding_m(soles, ids, frames)
    assert per_step == pytest.approx(np.full(6, 0.01))  # 3 frame pairs x 2 soles, m/frame
    assert per_step.mean() * FPS == pytest.approx(0.3)
    rng = np.random.default_rng(0)  # rows in any order: the same contacts
    shuffled = rng.permutation(4)
    assert np.sort(contact_sliding_m(soles[shuffled], ids[shuffled], frames[shuffled])) == pytest.approx(np.sort(per_step))


def test_sliding_counts_only_horizontal_steps_of_soles_at_the_ground_over_consecutive_frames():
    assert contact_sliding_m(soles_track(4, 0.01, height_m=0.10), np.zeros(4, int), np.arange(4)).size == 0  # lifted
    assert contact_sliding_m(soles_track(4, 0.01, height_m=-0.20), np.zeros(4, int), np.arange(4)).size == 0  # sunk deep
    assert contact_sliding_m(soles_track(3, 0.01, height_m=-0.03), np.zeros(3, int), np.arange(3)) == pytest.approx(
        np.full(4, 0.01))  # 3 cm under: in contact
    rising = soles_track(3, 0.0)
    rising[:, :, 1] = [[0.0], [0.02], [0.04]]  # straight up 2 cm/frame, still under 5 cm: no sliding
    assert contact_sliding_m(rising, np.zeros(3, int), np.arange(3)) == pytest.approx(np.zeros(4))
    # frame 2 missing: only the pair (0, 1) is consecutive; a second track interleaved is its own
    soles = np.concatenate([soles_track(3, 0.01), soles_track(2, 0.02)])
    ids, frames = np.array([1, 1, 1, 2, 2]), np.array([0, 1, 3, 0, 1])
    assert np.sort(contact_sliding_m(soles, ids, frames)) == pytest.approx([0.01, 0.01, 0.02, 0.02])
    swapped = soles_track(2, 0.01)
    swapped[1] = swapped[1, ::-1]  # the next frame lists its soles the other way round (geometry-mode meshes)
    assert contact_sliding_m(swapped, np.zeros(2, int), np.arange(2)) == pytest.approx([0.01, 0.01])


def test_consecutive_windows():
    order, starts = consecutive_windows(np.array([2, 1, 1, 1, 2]), np.array([5, 0, 1, 2, 6]), 3)
    assert order.tolist() == [1, 2, 3, 0, 4] and starts.tolist() == [0]
    with pytest.raises(ValueError, match="length"):
        consecutive_windows(np.zeros(2, int), np.arange(2), 0)


def test_a_ten_degree_lean():
    tilt = np.deg2rad(10.0)
    foot = np.array([[1.0, 0.0, -4.0]])
    crown = foot + 1.7 * np.array([[np.sin(tilt), np.cos(tilt), 0.0]])
    lean = lean_deg(foot, crown, np.array([0.0, 1.0, 0.0]))
    assert lean == pytest.approx([10.0])
    assert lean_summary(np.array([0.0, 10.0, 10.0, 20.0, np.nan])) == pytest.approx({"lean": 10.0, "lean_p90": 17.0})


def test_stature_constant_versus_varying_and_across_people():
    statures = np.array([1.70, 1.70, 1.70, 1.70, 1.60, 1.70, 1.80, 1.70])
    ids = np.array([1, 1, 1, 1, 2, 2, 2, 2])
    values, tracks = stature_summary(statures, ids)
    assert tracks.spread_m == pytest.approx([0.0, 0.025])  # track 2 sorted 1.6 1.7 1.7 1.8: q25 1.675, q75 1.725
    assert values == pytest.approx({"stature": 1.70, "stature_spread": 12.5, "stature_sd": 0.0})
    other, _ = stature_summary(np.array([1.60, 1.60, 1.80, 1.80]), np.array([1, 1, 2, 2]))
    assert other == pytest.approx({"stature": 1.70, "stature_spread": 0.0, "stature_sd": 100.0})
    no_ids, table = stature_summary(np.array([1.60, 1.80]), None)
    assert table is None and no_ids["stature"] == pytest.approx(1.70) and math.isnan(no_ids["stature_spread"])


def test_constant_acceleration_is_recovered_in_m_per_s2():
    t = np.arange(6) / FPS
    a = 2.0  # m/s^2 along X, and a still second joint
    joints = np.zeros((6, 2, 3))
    joints[:, 0, 0] = 0.5 * a * t**2 + 0.3 * t
    joints[:, 1] = [0.0, 1.0, 4.0]
    per_window = acceleration_m(joints, np.full(6, 3), np.arange(6))
    assert per_window * FPS**2 == pytest.approx(np.full(4, a / 2))  # mean over the 2 joints
    one_joint = acceleration_m(joints[:, :1], np.full(6, 3), np.array([0, 1, 2, 4, 5, 6]))  # a gap after frame 2
    assert one_joint * FPS**2 == pytest.approx([a, a])  # the windows (0, 1, 2) and (4, 5, 6): none across the gap
    assert acceleration_m(joints[:2], np.zeros(2, int), np.arange(2)).size == 0


# ---- a sequence in its scene camera --------------------------------------------------------------------

CAMERA = Camera((640, 480), 500.0, None, np.deg2rad(20.0), 0.0, 3.0)


def smpl_people(cam: Camera, feet_world: np.ndarray, crowns_world: np.ndarray) -> np.ndarray:
    """(P, 6890, 3) SMPL-topology meshes in the camera frame whose two soles straddle ``feet_world`` (P, 3) by
    +-15 cm along X and whose crown is ``crowns_world`` (P, 3); the other vertices halfway."""
    verts = np.repeat((0.5 * (feet_world + crowns_world))[:, None], SMPL.n_verts, axis=1)
    verts[:, SMPL.left_sole_indices] = (feet_world + [0.15, 0.0, 0.0])[:, None]
    verts[:, SMPL.right_sole_indices] = (feet_world - [0.15, 0.0, 0.0])[:, None]
    verts[:, SMPL.crown_index] = crowns_world
    return cam.cam_from_world(verts).astype(np.float32)


def write_walk(path: Path, feet_by_frame: list[np.ndarray], ids: list[int] | None, fps: float | None = 10.0,
               camera: Camera | None = CAMERA, stature_m: float = 1.7) -> Path:
    """A sequence of upright people (crown ``stature_m`` over each foot) with ``feet_by_frame`` (P, 3) world feet."""
    path.mkdir(parents=True)
    for k, feet in enumerate(feet_by_frame):
        feet = np.asarray(feet, dtype=np.float64).reshape(-1, 3)
        data = {"vertices": smpl_people(CAMERA, feet, feet + [0.0, stature_m, 0.0])}
        if ids is not None:
            data["person_ids"] = np.asarray(ids[:len(feet)])
        np.savez(path / f"{k:06d}.npz", **data)
    (path / "meta.yaml").write_text("image_size: [640, 480]\nfocal_length: 500.0\nfocal_kind: camera\n"
                                    + (f"fps: {fps}\n" if fps else ""))
    if camera is not None:
        write_camera_yaml(path / "camera.yaml", camera, {"method": "refine", "std": {"focal_px": 20.0, "pitch_deg": 0.5,
                                                                                     "roll_deg": 0.25, "height_m": 0.1}})
    return path


def test_a_floating_walker_measured_in_its_own_camera(tmp_path):
    """One person 10 cm in the air walking 5 cm/frame at 10 fps, another on the ground standing still."""
    frames = [np.array([[0.05 * k, 0.10, -5.0], [1.0, 0.0, -6.0]]) for k in range(4)]
    seq = open_sequence(write_walk(tmp_path / "walk", frames, [7, 8]))
    (scene,) = scene_cameras([seq])
    assert scene.whence == OWN
    r = measure_sequence(seq, scene)
    m = r.metrics
    assert set(m) == set(GROUND_FREE_METRICS) and r.people_pred == 8 and r.tracks == 2 and r.frames == 4
    assert m["feet_height"] == pytest.approx(50.0, abs=1e-3) and m["floating_pct"] == 50.0 and m["penetration_pct"] == 0.0
    assert m["lean"] == pytest.approx(0.0, abs=1e-4) and m["stature"] == pytest.approx(1.7, abs=1e-6)
    assert m["stature_spread"] == pytest.approx(0.0, abs=1e-3)
    assert m["sliding"] == pytest.approx(0.0, abs=1e-4)  # only the still person is in contact
    assert m["accel"] == pytest.approx(0.0, abs=1e-3)  # constant velocity (foot point and crown: no joints)
    assert r.camera == {"cam_std_focal_px": 20.0, "cam_std_pitch_deg": 0.5, "cam_std_roll_deg": 0.25, "cam_std_height_m": 0.1}
    assert (r.fps, r.fps_assumed, r.flags, r.stature_from) == (10.0, False, None, None)
    assert [t["id"] for t in r.statures] == [7, 8] and r.notes == []


def test_a_sliding_walker_without_fps_and_a_sequence_without_ids(tmp_path):
    frames = [np.array([[0.01 * k, 0.0, -5.0]]) for k in range(3)]
    r = measure_sequence(*_own(write_walk(tmp_path / "slide", frames, [1], fps=None)))
    assert r.fps == 30.0 and r.fps_assumed and any("30 assumed" in n for n in r.notes)
    assert r.metrics["sliding"] == pytest.approx(0.3, rel=1e-4)  # 1 cm/frame at the assumed 30 fps
    no_ids = measure_sequence(*_own(write_walk(tmp_path / "noids", frames, None)))
    assert math.isnan(no_ids.metrics["sliding"]) and no_ids.tracks == 0 and any("person_ids" in n for n in no_ids.notes)
    assert no_ids.metrics["feet_height"] == pytest.approx(0.0, abs=1e-3)


def _own(path: Path):
    seq = open_sequence(path)
    return seq, scene_cameras([seq])[0]


def test_the_scene_camera_rule(tmp_path):
    """Own camera.yaml first; a sequence without one: --camera, else the camera of one given alongside; else None."""
    frames = [np.zeros((1, 3))]
    bare = open_sequence(write_walk(tmp_path / "bare", frames, [1], camera=None))
    owned = open_sequence(write_walk(tmp_path / "owned", frames, [1]))
    other = Camera((640, 480), 600.0, None, np.deg2rad(25.0), 0.0, 4.0)
    write_camera_yaml(tmp_path / "given.yaml", other)
    assert [s.whence for s in scene_cameras([bare, owned])] == [ALONGSIDE, OWN]
    given = scene_cameras([bare, owned], tmp_path / "given.yaml")
    assert [s.whence for s in given] == [GIVEN, OWN] and given[0].camera.focal_px == 600.0 and given[0].fit == {}
    assert scene_cameras([bare]) == [None]


# ---- the command ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synth_scene(tmp_path_factory, runner) -> Path:
    """`rotavat synth` (3 frames x 4 people) and its prediction aligned in the true camera (read-only for the tests)."""
    s = tmp_path_factory.mktemp("synth") / "s"
    assert invoke(runner, "synth", s, "--seed", "12", "--frames", "3", "--people", "4", "-q").exit_code == 0
    assert invoke(runner, "align", "--in", s / "pred", "--camera", s / "gt" / "camera.yaml", "--out", s / "al",
                  "-q").exit_code == 0
    return s


def test_before_and_after_on_a_synthetic_scene(synth_scene, tmp_path, runner):
    s = synth_scene
    before_hash = tree_hash(s)
    result = invoke(runner, "eval", s / "pred", s / "al", "--out", tmp_path / "ev", "--json")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert sorted(data) == ["gates_failed", "metrics_json", "metrics_md", "predictions"] and data["gates_failed"] == []
    before, after = data["predictions"]
    for row in (before, after):
        assert row["gt"] is None and row["protocol"] == "ground_free" and row["frames"] == 3 and row["people_pred"] == 12
        assert sorted(row["metrics"]) == sorted(GROUND_FREE_METRICS) and row["units"]["sliding"] == "m/s"
        assert row["tracks"] == 4 and len(row["statures"]) == 4
    assert before["scene_camera"]["from"] == ALONGSIDE and after["scene_camera"]["from"] == OWN
    assert before["scene_camera"]["file"] == after["scene_camera"]["file"] == str(s / "al" / "camera.yaml")
    assert after["metrics"]["feet_height"] < 1.0 < 100.0 < before["metrics"]["feet_height"]  # aligned: on the ground
    assert after["metrics"]["lean"] < 0.5 * before["metrics"]["lean"]
    assert after["metrics"]["penetration_pct"] == 0.0 and after["flags"] == {}
    on_disk = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert on_disk["gt"] is None and on_disk["protocol"] == "ground_free" and "feet_height" in on_disk["metric_names"]
    assert on_disk["predictions"][1]["metrics"]["feet_height"] == pytest.approx(after["metrics"]["feet_height"])
    md = (tmp_path / "ev" / "metrics.md").read_text()
    assert "without ground truth" in md and "| metric | `pred` | `al` | change |" in md and "Statures per track" in md
    assert tree_hash(s) == before_hash  # inputs untouched
    table = invoke(runner, "eval", s / "pred", s / "al", "--out", tmp_path / "ev2")
    assert table.exit_code == 0 and "feet_height (mm)" in table.stdout and "alongside" in table.stdout


def test_gates_without_ground_truth(synth_scene, tmp_path, runner):
    s, out = synth_scene, tmp_path / "ev"
    ok = invoke(runner, "eval", s / "pred", s / "al", "--out", out, "--fail-if", "al:feet_height>1", "-q")
    assert ok.exit_code == 0 and ok.stderr == ""
    bad = invoke(runner, "eval", s / "pred", s / "al", "--out", out, "--fail-if", "feet_height>1", "-q")
    assert bad.exit_code == 1 and len(bad.stderr.strip().splitlines()) == 1 and "pred: feet_height" in bad.stderr
    tripped = invoke(runner, "eval", s / "al", "--out", out, "--fail-if", "cam_std_height_m<1", "-q")
    assert tripped.exit_code == 1  # the true camera has no fit block: no std, NaN trips (cannot be vouched for)
    truth_metric = invoke(runner, "eval", s / "pred", s / "al", "--out", out, "--fail-if", "lean_deg>3")
    assert truth_metric.exit_code == 2 and "needs --gt; without it: lean" in truth_metric.stderr
    free_with_truth = invoke(runner, "eval", s / "al", "--gt", s / "gt", "--out", out, "--fail-if", "lean>3")
    assert free_with_truth.exit_code == 2 and "measured without --gt" in free_with_truth.stderr


def test_usage_errors_exit_2_on_one_line(synth_scene, tmp_path, runner):
    s = synth_scene
    cases = [(("eval", s / "pred", "--out", tmp_path / "a"), f"{s / 'pred'}: no camera.yaml for the ground-free "
              f"measures (eval without --gt): run `rotavat calibrate {s / 'pred'}`"),
             (("eval", s / "pred", s / "al", "--out", tmp_path / "b", "--protocol", "wham"), "--protocol is for eval against"),
             (("eval", s / "pred", "--gt", s / "gt", "--camera", s / "gt" / "camera.yaml", "--out", tmp_path / "c"),
              "--camera is for eval without --gt")]
    bad_fps = write_walk(tmp_path / "bad_fps", [np.zeros((1, 3))], [1], fps=-5.0)
    cases += [(("eval", bad_fps, "--out", tmp_path / "d"), f"{bad_fps / 'meta.yaml'}: key 'fps' must be a positive number"),
              (("eval", s / "pred", "--camera", tmp_path / "none.yaml", "--out", tmp_path / "e"),
               f"{tmp_path / 'none.yaml'}: no such file (--camera)")]
    for args, message in cases:
        result = invoke(runner, *args)
        assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr
        assert message in result.stderr


def test_a_camera_given_for_a_sequence_without_one(synth_scene, tmp_path, runner):
    s = synth_scene
    result = invoke(runner, "eval", s / "pred", "--camera", s / "gt" / "camera.yaml", "--out", tmp_path / "ev", "--json")
    assert result.exit_code == 0, result.stderr
    (row,) = json.loads(result.stdout)["predictions"]
    assert row["scene_camera"]["from"] == GIVEN and row["camera"] == {}
    assert any("no uncertainty recorded" in note for note in row["notes"])


# ---- batch ----------------------------------------------------------------------------------------------


def test_batch_without_ground_truth_reports_the_measures(synth_scene, tmp_path, runner):
    root = tmp_path / "root"
    shutil.copytree(synth_scene / "pred", root / "cam1")
    result = invoke(runner, "batch", root, "--out", tmp_path / "out", "--steps", "calibrate,align", "--jobs", "1", "-q")
    assert result.exit_code == 0, result.stderr
    report = json.loads((tmp_path / "out" / "batch_report.json").read_text())
    (row,) = report["rows"]
    assert row["ground_free"]["after"]["metrics"]["feet_height"] < 1.0 < row["ground_free"]["before"]["metrics"]["feet_height"]
    assert report["aggregate"]["ground_free"]["after"]["people_frames"] == 12
    md = (tmp_path / "out" / "batch_report.md").read_text()
    assert "## Without ground truth" in md and "| `cam1` |" in md


def test_batch_aggregate_weights_the_sequences_by_their_people_frames():
    def row(name, people, before, after):
        return {"sequence": name, "status": "done", "frames": 1, "people": people,
                "ground_free": {"before": {"people_pred": people, "metrics": {"feet_height": before}},
                                "after": {"people_pred": people, "metrics": {"feet_height": after}}}}

    agg = aggregate_rows([row("a", 10, 100.0, 1.0), row("b", 30, 200.0, None)])["ground_free"]
    assert agg["before"]["metrics"]["feet_height"] == pytest.approx(175.0)
    assert agg["after"]["metrics"]["feet_height"] == pytest.approx(1.0) and agg["before"]["people_frames"] == 40
