"""Calibration as estimation: priors instead of cliffs, honest uncertainty, known values, plausibility,
what the bodies know (who stands, which way is up), at the level of pairs and of sequences."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from _synthetic_pairs import synthetic_pairs
from _cli import invoke

from rotavat_cli.calibration import CalibrateOptions, calibrate_sequence, fit_camera
from rotavat_cli.calibration.objective import BodyAxes
from rotavat_cli.calibration.plausibility import implausible_findings
from rotavat_cli.calibration.priors import LENS_FOCAL_OVER_DIAGONAL, default_priors, lens_range_px
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.errors import DegenerateSceneError, InputError
from rotavat_cli.sequence import open_sequence, write_camera_yaml, write_meta

SIZE = (1920, 1080)
DIAGONAL = math.hypot(*SIZE)


def walker(camera: Camera, frames: int = 40, distance_m: float = 8.0, noise_px: float = 1.5, seed: int = 0,
           ar: float = 0.0, stature_m: float = 1.72, still: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """One person walking across the view at one ground distance (or standing still): feet, heads (N, 2) px.

    ``ar``: lag-1 autocorrelation of the pixel noise (drifting detections)."""
    rng = np.random.default_rng(seed)
    forward = camera.world_from_cam(np.array([[0.0, 0.0, 1.0]]))[0] - camera.center_world
    forward[1] = 0.0
    forward /= np.linalg.norm(forward)
    side = np.cross(forward, [0.0, 1.0, 0.0])
    base = camera.center_world * [1.0, 0.0, 1.0] + distance_m * forward
    x = np.zeros(frames) if still else np.linspace(-0.35, 0.35, frames) * distance_m
    ground = base + x[:, None] * side
    feet = camera.project(camera.cam_from_world(ground))
    heads = camera.project(camera.cam_from_world(ground + [0.0, stature_m, 0.0]))
    noise = np.zeros((frames, 4))
    step = rng.normal(0.0, noise_px, (frames, 4))
    for t in range(frames):
        noise[t] = (ar * noise[t - 1] if t else 0.0) + math.sqrt(1.0 - ar * ar) * step[t]
    return feet + noise[:, :2], heads + noise[:, 2:]


HANDHELD = Camera(SIZE, 0.72 * DIAGONAL, None, math.radians(6.0), math.radians(0.5), 1.55)
CCTV = Camera(SIZE, 0.9 * DIAGONAL, None, math.radians(25.0), 0.0, 5.0)


# ---- one depth: the priors answer, and say so ------------------------------------------------------------
@pytest.mark.parametrize("camera", [HANDHELD, CCTV], ids=["handheld", "cctv"])
def test_a_walker_at_one_depth_gets_an_answer_from_the_lens_prior(camera):
    feet, heads = walker(camera)
    ids, frames = np.zeros(len(feet), int), np.arange(len(feet))
    with pytest.raises(DegenerateSceneError, match=r"one depth.*--focal-prior lens"):
        fit_camera(feet, heads, SIZE, focal_prior="none", frame_index=frames, track_id=ids)
    res = fit_camera(feet, heads, SIZE, frame_index=frames, track_id=ids)  # the step the refusal names
    assert "prior" in res.determined_by["focal_px"].split("+") and res.focal_prior == "lens"
    if res.determined_by["focal_px"] == "prior":
        assert any("focal length from the prior" in w and "--focal PX or --focal-mm MM" in w for w in res.warnings)
    assert abs(res.camera.focal_px - camera.focal_px) < 2 * res.std["focal_px"]
    assert 0.15 < res.std["focal_px"] / res.camera.focal_px < 0.4  # no wider than the lens prior
    assert abs(math.degrees(res.camera.pitch_rad - camera.pitch_rad)) < 2 * res.std["pitch_deg"]
    assert abs(res.camera.height_m - camera.height_m) < 2 * res.std["height_m"]
    assert not res.implausible


def test_the_known_focal_and_camera_height_determine_a_walker_at_one_depth():
    feet, heads = walker(CCTV, stature_m=1.80)
    res = fit_camera(feet, heads, SIZE, focal_px=CCTV.focal_px, camera_height_m=5.0, frame_index=np.arange(40),
                     track_id=np.zeros(40, int))
    assert res.fixed == {"focal_px": "given", "height_m": "given"} and res.camera.height_m == 5.0
    assert res.person_height_estimated and abs(res.person_height_m - 1.80) < 2 * res.person_height_std_m
    assert abs(math.degrees(res.camera.pitch_rad - CCTV.pitch_rad)) < 1.0
    assert not any("camera height" in w for w in res.warnings)  # a given height is never "poorly determined"


def test_a_known_pitch_is_kept_and_reported_as_given():
    data = synthetic_pairs(np.random.default_rng(3), frames=4, people=8)
    true_pitch = math.degrees(data.camera.pitch_rad)
    res = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, pitch_deg=true_pitch)
    assert math.degrees(res.camera.pitch_rad) == pytest.approx(true_pitch, abs=1e-9)
    assert res.fixed["pitch_deg"] == "given" and math.isnan(res.std["pitch_deg"])
    assert abs(res.camera.height_m / data.camera.height_m - 1) < 0.05


def test_multi_depth_scenes_are_unchanged_by_the_lens_prior():
    for seed in (4, 5):
        data = synthetic_pairs(np.random.default_rng(seed), frames=20, people=10)
        kw = dict(frame_index=data.frame_index, track_id=data.track_id)
        with_prior = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, **kw)
        alone = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, focal_prior="none", **kw)
        assert with_prior.determined_by["focal_px"] == "people"
        assert abs(with_prior.camera.focal_px / alone.camera.focal_px - 1) < 0.01
        assert abs(with_prior.camera.focal_px / data.camera.focal_px - 1) < 3 * with_prior.std["focal_px"] / \
            with_prior.camera.focal_px


# ---- honest uncertainty ---------------------------------------------------------------------------------
def test_drifting_detections_of_one_walker_count_for_less():
    feet, heads = walker(CCTV, frames=60, ar=0.9, seed=1)
    kw = dict(focal_px=CCTV.focal_px, frame_index=np.arange(60), track_id=np.zeros(60, int))
    drifting = fit_camera(feet, heads, SIZE, **kw)
    feet, heads = walker(CCTV, frames=60, ar=0.0, seed=1)
    independent = fit_camera(feet, heads, SIZE, **kw)
    assert drifting.design_effect > 4 and independent.design_effect < 2
    assert drifting.std_statistical["pitch_deg"] > 1.5 * independent.std_statistical["pitch_deg"]


# ---- plausibility --------------------------------------------------------------------------------------
def test_implausible_findings_name_each_rule():
    lo, hi = lens_range_px(SIZE)
    assert lo == pytest.approx(LENS_FOCAL_OVER_DIAGONAL * DIAGONAL * math.exp(-0.9))
    ok = {"focal_px": 100.0, "pitch_deg": 1.0, "roll_deg": 1.0, "height_m": 0.2}
    assert implausible_findings(CCTV, ok, focal_estimated=True) == ()
    low = Camera(SIZE, 5000.0 / 256 * 1920, None, 0.1, 0.0, 0.11)  # 4D-Humans' focal rule taken for a lens
    found = implausible_findings(low, ok, focal_estimated=True)
    assert found[0].startswith("focal length 37500 px is outside") and found[1] == "camera height 0.11 m is under 0.3 m"
    assert implausible_findings(low, ok, focal_estimated=False, height_estimated=False) == ()  # the user's values
    assert implausible_findings(CCTV, ok, focal_estimated=True, height_estimated=False, mean_stature_m=3.57) == (
        "the people's mean stature 3.57 m (from the given camera height) is outside 1.4-2.1 m",)
    wide = {**ok, "pitch_deg": 18.0, "roll_deg": math.inf, "height_m": 4.0}
    assert implausible_findings(CCTV, wide, focal_estimated=True) == (
        "pitch undetermined (+-18 deg)", "roll undetermined", "camera height undetermined (5.00 +- 4.00 m)")


def test_a_person_standing_still_counts_once_and_leaves_the_pitch_open(tmp_path):
    seq = open_sequence(_walker_sequence(tmp_path / "s", CCTV, frames=30, still=True, distance_m=12.0))
    calib = calibrate_sequence(seq, CalibrateOptions(body_axes=False))
    res = calib.result
    assert res.pairs == 1 and any("1 person stands still: its 30 pairs count as 1" in n for n in res.notes)
    assert any(f.startswith("pitch undetermined") for f in res.implausible)  # never a value with exit 0 unflagged
    assert abs(math.degrees(res.camera.pitch_rad - CCTV.pitch_rad)) < 2 * res.std["pitch_deg"]
    assert res.fit_dict()["implausible"] == list(res.implausible)


# ---- what the bodies know -------------------------------------------------------------------------------
def test_standing_bodies_give_the_pitch_the_pairs_leave_open():
    feet, heads = walker(CCTV, frames=1, still=True, distance_m=12.0)
    body = BodyAxes(CCTV.up_cam.copy(), math.radians(10.0), 1)  # an HPS body that does not lean
    res = fit_camera(feet, heads, SIZE, body=body)
    assert res.body_axes == 1 and "bodies" in res.determined_by["pitch_deg"].split("+")
    assert abs(math.degrees(res.camera.pitch_rad - CCTV.pitch_rad)) < 2 * res.std["pitch_deg"] < 20
    assert not any(f.startswith("pitch") for f in res.implausible)
    walking = fit_camera(*walker(CCTV, distance_m=12.0), SIZE, frame_index=np.arange(40),
                         track_id=np.zeros(40, int), body=body)
    assert walking.body_axes == 0  # the pairs (and priors) leave the pitch within 10 deg: the bodies stay out


def test_priors_follow_the_options():
    p = default_priors(SIZE, camera_height_m=6.0)
    assert p.height_kind == "stature" and math.exp(p.mean[3]) == pytest.approx(6.0)
    assert default_priors(SIZE, focal_prior="none").focal_kind == "none"
    fov = default_priors(SIZE, fov_prior_deg=(40.0, 5.0))
    assert fov.focal_kind == "fov" and math.exp(fov.mean[0]) == pytest.approx(540.0 / math.tan(math.radians(20.0)))


# ---- sequences: who stands, declared principal point, tracks, the CLI ------------------------------------
def _walker_sequence(folder, camera, pp=None, joints=None, frames=20, ids=None, **walk):
    """A contract sequence of the walker's 2D points (+ optional joints per frame and declared principal point)."""
    feet, heads = walker(camera, frames=frames, **walk)
    folder.mkdir(parents=True)
    for t in range(frames):
        data = {"feet_2d": feet[t:t + 1], "heads_2d": heads[t:t + 1],
                "person_ids": np.array([7 if ids is None else ids[t]], np.int64)}
        if joints is not None:
            data["joints"] = joints[t:t + 1]
        np.savez(folder / f"{t:06d}.npz", **data)
    write_meta(folder, {"image_size": list(camera.image_size), **({"principal_point": list(pp)} if pp else {})})
    return folder


def _seated_joints(frames: int, sitting: np.ndarray) -> np.ndarray:
    """(frames, 24, 3) SMPL-order joints: a standing body, or a seated one where ``sitting``."""
    j = np.zeros((frames, 24, 3))
    hips, knees_up, ankles = -0.9, -0.5, 0.0  # y down in the camera frame: the feet at 0, the head at -1.7
    for side, x in ((1, 0.1), (2, -0.1)):
        j[:, side] = (x, hips, 8.0)
    j[:, 16], j[:, 17] = (0.18, -1.4, 8.0), (-0.18, -1.4, 8.0)
    j[:, 12], j[:, 15] = (0.0, -1.5, 8.0), (0.0, -1.6, 8.0)
    for knee, ankle, x in ((4, 7, 0.1), (5, 8, -0.1)):
        j[:, knee] = np.where(sitting[:, None], (x, hips, 7.55), (x, knees_up, 8.0))
        j[:, ankle] = np.where(sitting[:, None], (x, ankles, 7.55), (x, ankles, 8.0))
    return j


def test_people_who_do_not_stand_are_left_out_and_counted(tmp_path):
    sitting = np.arange(20) % 2 == 1
    ids = np.where(sitting, 8, 7)
    seq = open_sequence(_walker_sequence(tmp_path / "s", CCTV, joints=_seated_joints(20, sitting), ids=ids))
    calib = calibrate_sequence(seq, CalibrateOptions(focal_px=CCTV.focal_px))
    assert calib.result.pairs == 10 and any("left out 1 person who does not stand (1 sitting; 10 of 20 pairs" in n
                                            for n in calib.result.notes)
    everyone = calibrate_sequence(seq, CalibrateOptions(focal_px=CCTV.focal_px, standing_only=False))
    assert everyone.result.pairs == 20


def test_no_one_standing_is_refused_with_a_step_that_works(tmp_path, runner):
    seq = _walker_sequence(tmp_path / "s", CCTV, joints=_seated_joints(20, np.ones(20, bool)))
    result = invoke(runner, "calibrate", seq, "--focal", CCTV.focal_px)
    assert result.exit_code == 2 and "no one stands (1 sitting" in result.stderr and "--all-people" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    again = invoke(runner, "calibrate", seq, "--focal", CCTV.focal_px, "--all-people", "--json")
    assert again.exit_code == 0 and json_fit(again)["pairs"] == 20


def json_fit(result) -> dict:
    import json

    return json.loads(result.stdout)["fit"]


def test_a_declared_principal_point_is_used_with_a_note(tmp_path):
    camera = Camera(SIZE, CCTV.focal_px, (900.0, 580.0), CCTV.pitch_rad, 0.0, 5.0)
    seq = open_sequence(_walker_sequence(tmp_path / "s", camera, pp=(900.0, 580.0)))
    calib = calibrate_sequence(seq, CalibrateOptions(focal_px=camera.focal_px))
    assert calib.result.camera.principal_point == (900.0, 580.0)
    assert any("principal point (900, 580) from the sequence" in n for n in calib.result.notes)
    given = calibrate_sequence(seq, CalibrateOptions(focal_px=camera.focal_px, principal_point=(960.0, 540.0)))
    assert given.result.camera.principal_point == (960.0, 540.0)
    assert not any("principal point" in n for n in given.result.notes)  # (one walker's 20 pairs: the roll's note)


def test_calibrating_from_chosen_tracks(tmp_path):
    ids = np.where(np.arange(20) < 12, 3, 5)
    seq = open_sequence(_walker_sequence(tmp_path / "s", CCTV, ids=ids))
    calib = calibrate_sequence(seq, CalibrateOptions(focal_px=CCTV.focal_px, tracks=(3,)))
    assert calib.result.pairs == 12
    with pytest.raises(InputError, match=r"no person_id 4 with foot-head pairs \(ids: 3, 5\)"):
        calibrate_sequence(seq, CalibrateOptions(tracks=(4,)))


def test_the_cli_shows_what_determined_each_parameter_and_flags_an_open_one(tmp_path, runner):
    folder = _walker_sequence(tmp_path / "still", CCTV, frames=12, still=True, distance_m=12.0)
    result = invoke(runner, "calibrate", folder, "--out", tmp_path / "c.yaml")
    assert result.exit_code == 0
    pitch_row = next(line for line in result.stdout.splitlines() if "pitch_deg" in line)
    assert "undetermined" in pitch_row and "implausible camera: pitch undetermined" in result.stderr
    fit = yaml.safe_load((tmp_path / "c.yaml").read_text())["fit"]
    assert fit["determined_by"]["focal_px"] == "prior" and fit["implausible"]
    known = invoke(runner, "calibrate", folder, "--out", tmp_path / "k.yaml", "--pitch", "25", "--json")
    assert known.exit_code == 0 and json_fit(known)["fixed"]["pitch_deg"] == "given"
    assert not any(f.startswith("pitch") for f in json_fit(known)["implausible"])


def test_a_hand_written_camera_is_never_flagged(tmp_path):
    write_camera_yaml(tmp_path / "camera.yaml", HANDHELD)
    assert "fit" not in yaml.safe_load((tmp_path / "camera.yaml").read_text())


def test_align_flags_people_who_do_not_stand_and_leaves_them_out_of_the_medians():
    from rotavat_cli.alignment import AlignSummary, align_frame
    from rotavat_cli.sequence import Frame

    joints = _seated_joints(2, np.array([False, True]))  # (2 people, 24, 3): one stands, one sits
    joints[1, :, 0] += 1.0
    cam = Camera((1280, 720), 900.0, None, math.radians(10.0), 0.0, 1.6)
    feet = cam.project(joints[:, [7, 8]].mean(axis=1) + [0.0, 0.05, 0.0])
    heads = cam.project(joints[:, 15] - [0.0, 0.1, 0.0])
    frame = Frame("f", {"joints": joints, "feet_2d": feet, "heads_2d": heads, "person_ids": np.array([0, 1]),
                        "focal_length": np.float64(900.0), "image_size": np.array([1280, 720])})
    _, cols = align_frame(frame, cam)
    assert cols["flag"].tolist() == ["", "sitting"]
    summary = AlignSummary(Path("."))  # counts only: no folder is written
    summary.add(2, cols)
    summary.finish()
    assert summary.aligned == 2 and summary.not_standing == 1 and summary.flagged == {"sitting": 1}
    assert summary.median_stature_m == pytest.approx(float(cols["stature_m"][0]))


def test_align_flags_a_median_stature_no_adult_group_has(tmp_path, runner):
    """A camera of the wrong scale (a hand-written one: never implausible by itself) seats the people at
    3.4 m: align says so (stderr, and median_stature_plausible in its JSON), naming what to give."""
    scene = Path(__file__).resolve().parents[1] / "sample_data" / "scene"
    truth = yaml.safe_load((scene / "gt" / "camera.yaml").read_text())
    wrong = {k: truth[k] for k in ("image_size", "focal_px", "principal_point", "pitch_deg", "roll_deg")}
    (tmp_path / "wrong.yaml").write_text(yaml.safe_dump({**wrong, "height_m": 2.0 * truth["height_m"]}))
    result = invoke(runner, "align", scene / "pred", "--camera", tmp_path / "wrong.yaml", "--out", tmp_path / "a",
                    "--json")
    assert result.exit_code == 0 and json.loads(result.stdout)["median_stature_plausible"] is False
    assert json.loads(result.stdout)["median_stature_m"] > 3.0
    noisy = invoke(runner, "align", scene / "pred", "--camera", tmp_path / "wrong.yaml", "--out", tmp_path / "b")
    said = " ".join(noisy.stderr.split())  # the terminal wraps warnings
    assert "median stature 3." in said and "is outside 1.4-2.1 m" in said and "--camera-height M" in said
    fine = invoke(runner, "align", scene / "pred", "--camera", scene / "gt" / "camera.yaml", "--out", tmp_path / "c",
                  "--json")
    assert json.loads(fine.stdout)["median_stature_plausible"] is True
