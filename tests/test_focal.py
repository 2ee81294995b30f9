"""The focal an HPS method guessed is not the camera's: contract, calibrate, align, eval under each rule."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from _cli import invoke

from rotavat_cli.alignment import AlignOptions, align_frame, align_sequence
from rotavat_cli.alignment.transform import apply_transforms, method_rays_cam, rotavat_transforms
from rotavat_cli.geometry.camera import Camera, reexpress_cam
from rotavat_cli.errors import InputError
from rotavat_cli.geometry.focal import focal_from_rule, hybrik_focal_px
from rotavat_cli.bodies.landmarks import foot_head_points
from rotavat_cli.sequence import Frame, open_sequence, write_frame, write_meta
from rotavat_cli.synth import SynthOptions, synth_frames, write_synth_scene

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"


def _scene(root: Path, rule: str, seed: int = 6, frames: int = 10, people: int = 8) -> Path:
    write_synth_scene(root, SynthOptions(seed=seed, frames=frames, people=people, image_size=(1920, 1080),
                                         hps_focal=rule))
    return root


def _w_mpjpe_mm(pred: Path, gt: Path) -> float:
    from rotavat_cli.metrics.evaluate import evaluate

    return float(evaluate(open_sequence(pred), open_sequence(gt)).metrics["w_mpjpe"])


# ---- the contract --------------------------------------------------------------------------------
def test_rules_match_the_tools_documented_focals():
    assert focal_from_rule("cliff", (1920, 1080)) == pytest.approx(2202.9071, abs=1e-3)
    assert focal_from_rule("bev", (1920, 1080)) == pytest.approx(443.4 / 512 * 1920)
    assert 2 * math.degrees(math.atan(960 / focal_from_rule("romp", (1920, 1080)))) == pytest.approx(60.0)
    assert focal_from_rule("4dhumans", (1920, 1080)) == pytest.approx(37500.0)
    np.testing.assert_allclose(hybrik_focal_px([256.0, 128.0]), [1000.0, 500.0])
    with pytest.raises(ValueError, match="unknown focal rule"):
        focal_from_rule("nosuch", (10, 10))


def test_a_frame_states_one_focal_per_person(tmp_path):
    verts = np.zeros((3, 4, 3), np.float32) + [0, 0, 5]
    frame = Frame("000000", {"vertices": verts, "focal_length": np.array([900.0, 1000.0, 1100.0])})
    np.testing.assert_array_equal(frame.intrinsics.focals_px(3), [900.0, 1000.0, 1100.0])
    one = Frame("000000", {"vertices": verts, "focal_length": np.float64(800.0)})
    np.testing.assert_array_equal(one.intrinsics.focals_px(3), [800.0] * 3)
    seq = tmp_path / "s"
    seq.mkdir()
    np.savez(seq / "000000.npz", vertices=verts, focal_length=np.array([900.0, 1000.0]))  # 2 focals, 3 people
    (seq / "meta.yaml").write_text("image_size: [640, 480]\n")
    with pytest.raises(InputError, match=r"000000.npz: key 'focal_length' must be one number or one per person \(3,\)"):
        open_sequence(seq).read_frame("000000")


def test_focal_kind_is_assumed_unless_said_and_validated(tmp_path, npz_seq, runner):
    assert open_sequence(npz_seq).focal_kind == "assumed"  # no focal_kind: never taken for the camera's
    meta = npz_seq / "meta.yaml"
    meta.write_text(meta.read_text() + "focal_kind: camera\n")
    assert open_sequence(npz_seq).focal_kind == "camera"
    meta.write_text(meta.read_text().replace("focal_kind: camera", "focal_kind: guessed"))
    result = invoke(runner, "info", npz_seq)
    assert result.exit_code == 2 and "focal_kind" in result.stderr and "camera, assumed" in result.stderr


# ---- RotAvat on the method's rays ---------------------------------------------------------------
def test_the_re_expression_does_not_change_the_result():
    """Any rigid shift of a person before RotAvat-on-rays gives the same output (module docstring)."""
    rng = np.random.default_rng(0)
    cam = Camera((1920, 1080), 1100.0, None, math.radians(25), math.radians(1.0), 6.0)
    ground = cam.backproject_px_to_ground(rng.uniform([300, 700], [1600, 1000], (5, 2)))
    body = ground[:, None] + rng.normal(0, 0.1, (5, 40, 3)) + np.linspace(0, 1.7, 40)[None, :, None] * cam.up_cam
    feet, heads = foot_head_points(body)
    rays = [method_rays_cam(p, 2200.0, cam.principal_point, cam.focal_px, cam.principal_point) for p in (feet, heads)]
    shift = rng.normal(0, 0.5, (5, 1, 3))
    a = apply_transforms(body, rotavat_transforms(feet, heads, cam.up_cam, cam.height_m, "paper", None, *rays))
    b = apply_transforms(body + shift, rotavat_transforms(feet + shift[:, 0], heads + shift[:, 0], cam.up_cam,
                                                          cam.height_m, "paper", None, *rays))
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_per_person_focals_keep_the_pixels_the_method_drew():
    """HybrIK-style: each person's mesh made with its own focal; aligned into the real camera."""
    opts = SynthOptions(seed=3, frames=1, people=6, hps_focal="true", lean=0.0, depth_sd=0.0, noise_3d_m=0.0)
    camera, _, frames = synth_frames(opts)
    gt, _ = next(frames)
    verts = gt.data["vertices"].astype(np.float64)
    joints = gt.data["joints"].astype(np.float64)
    focals = camera.focal_px * np.array([0.8, 0.9, 1.1, 1.25, 1.0, 0.85])  # one focal per person (HybrIK's box rule)
    roots = joints[:, 0]
    pp = camera.principal_point
    pred = Frame("000000", {"vertices": reexpress_cam(verts, roots, camera.focal_px, pp, focals, pp).astype(np.float32),
                            "joints": reexpress_cam(joints, roots, camera.focal_px, pp, focals, pp).astype(np.float32),
                            "focal_length": focals})
    new, cols = align_frame(pred, camera)
    feet0, heads0 = foot_head_points(pred.data["vertices"].astype(np.float64))
    feet1, heads1 = foot_head_points(new.data["vertices"].astype(np.float64))
    drawn = lambda p: np.stack([Camera(camera.image_size, f, pp).project(x) for f, x in zip(focals, p)])  # noqa: E731
    np.testing.assert_allclose(camera.project(feet1), drawn(feet0), atol=0.02)
    np.testing.assert_allclose(camera.project(heads1), drawn(heads0), atol=0.02)
    np.testing.assert_allclose(camera.height_above_ground(feet1), 0.0, atol=1e-4)
    np.testing.assert_array_equal(cols["mesh_focal_px"], focals)
    # the true bodies come back, up to what the rigid re-expression itself changed in the pixels drawn
    # (a body at 0.8-1.25 times the depth is seen in another perspective: a few px at its foot and crown)
    err_mm = 1000 * np.linalg.norm(new.data["joints"] - joints, axis=-1).mean(axis=1)
    assert np.all(err_mm < 100.0), err_mm
    before_mm = 1000 * np.linalg.norm(pred.data["joints"] - joints, axis=-1).mean(axis=1)
    moved = focals != camera.focal_px
    assert np.all(before_mm[moved] > 10 * err_mm[moved])
    assert float(new.data["focal_length"]) == camera.focal_px  # the output is in the camera


def test_align_output_declares_the_cameras_focal_and_recalibrates_as_declared(tmp_path, runner):
    scene = _scene(tmp_path / "s", "cliff", frames=6, people=6)
    gt_cam = scene / "gt" / "camera.yaml"
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", gt_cam, "--out", tmp_path / "al", "-q")
    assert result.exit_code == 0, result.stderr
    out = open_sequence(tmp_path / "al")
    assert out.focal_kind == "camera" and out.intrinsics.focal_px == out.camera.focal_px
    assert out.meta["aligned_from"]["focal_rule"] == "cliff"
    assert all(float(f.data["focal_length"]) == out.camera.focal_px for f in out.frames())
    rows = list(csv.DictReader(open(tmp_path / "al" / "people.csv")))
    np.testing.assert_allclose([float(r["mesh_focal_px"]) for r in rows], focal_from_rule("cliff", (1920, 1080)), rtol=2e-6)  # 6 digits
    est = json.loads(invoke(runner, "calibrate", tmp_path / "al", "--out", tmp_path / "c.yaml", "--json").stdout)
    assert est["fit"]["focal_policy"] == "declared" and est["focal_px"] == out.camera.focal_px


# ---- the chain under each tool's rule ------------------------------------------------------------
@pytest.mark.parametrize("rule", ["cliff", "bev", "romp", "4dhumans"])
def test_chain_is_right_under_each_rule(rule, tmp_path, runner):
    """calibrate -> align -> eval on a prediction made with the method's focal, with and without the true focal."""
    scene = _scene(tmp_path / "s", rule, frames=20)
    gt = open_sequence(scene / "gt")
    true_f = gt.camera.focal_px
    before = _w_mpjpe_mm(scene / "pred", scene / "gt")
    after = {}
    for name, extra in (("self", []), ("given", ["--focal", str(true_f)])):
        cam = tmp_path / f"{name}.yaml"
        result = invoke(runner, "calibrate", scene / "pred", "--out", cam, "--json", *extra)
        assert result.exit_code == 0, result.stderr
        fit = json.loads(result.stdout)
        if name == "self":
            assert fit["fit"]["focal_policy"] == "estimated"
            assert abs(fit["focal_px"] / true_f - 1) < 0.15  # not the method's guess
        out = tmp_path / f"al_{name}"
        assert invoke(runner, "align", "--in", scene / "pred", "--camera", cam, "--out", out, "-q").exit_code == 0
        after[name] = _w_mpjpe_mm(out, scene / "gt")
        statures = [float(r["stature_m"]) for r in csv.DictReader(open(out / "people.csv")) if r["stature_m"]]
        assert abs(np.median(statures) / 1.70 - 1) < 0.08
    assert after["self"] < 0.2 * before and after["given"] < 0.2 * before, (before, after)


# ---- calibrate: known height, box points, honest table, the unmoved refinement -------------------------
def test_known_camera_height_estimates_the_mean_stature():
    from _synthetic_pairs import synthetic_pairs

    from rotavat_cli.calibration import fit_camera

    data = synthetic_pairs(np.random.default_rng(21), frames=40, people=15, stature_mean_m=1.80, roll_deg=None)
    true = data.camera
    assumed = fit_camera(data.feet_px, data.heads_px, true.image_size, frame_index=data.frame_index,
                         track_id=data.track_id)
    known = fit_camera(data.feet_px, data.heads_px, true.image_size, frame_index=data.frame_index,
                       track_id=data.track_id, camera_height_m=true.height_m)
    assert assumed.camera.height_m == pytest.approx(true.height_m * 1.70 / 1.80, rel=0.03)  # 1.70 m assumed: too low
    assert known.camera.height_m == true.height_m and known.fixed["height_m"] == "given"
    assert known.person_height_estimated and known.person_height_m == pytest.approx(1.80, abs=0.03)
    assert 0 < known.person_height_std_m < 0.1 and abs(known.person_height_m - 1.80) < 3 * known.person_height_std_m
    # the same fit at another scale (the priors differ: camera height vs mean stature, 1e-5 rad)
    assert known.camera.pitch_rad == pytest.approx(assumed.camera.pitch_rad, abs=1e-4)
    fit = known.fit_dict()
    assert fit["person_height"] == "estimated" and fit["std"]["person_height_m"] == known.person_height_std_m
    assert math.isnan(known.std["height_m"])


def test_camera_height_from_the_command_line(tmp_path, runner):
    scene = _scene(tmp_path / "s", "cliff", frames=8)
    true = open_sequence(scene / "gt").camera
    result = invoke(runner, "calibrate", scene / "pred", "--camera-height", str(true.height_m), "--out",
                    tmp_path / "c.yaml")
    assert result.exit_code == 0, result.stderr
    assert "person_height_m" in result.stdout and "fixed: given" in result.stdout
    written = yaml.safe_load((tmp_path / "c.yaml").read_text())
    assert written["height_m"] == true.height_m and written["fit"]["person_height"] == "estimated"
    assert abs(written["fit"]["person_height_m"] - 1.70) < 0.15
    bad = invoke(runner, "calibrate", scene / "pred", "--camera-height", "-3", "--out", tmp_path / "d.yaml")
    assert bad.exit_code == 2 and "--camera-height" in bad.stderr and not (tmp_path / "d.yaml").exists()


def _boxes(camera: Camera, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Box-derived pairs: bottom- and top-centre of people's boxes, sharing the box's (noisy) centre column."""
    W, H = camera.image_size
    ground = camera.backproject_px_to_ground(np.stack([rng.uniform(0.1 * W, 0.9 * W, n),
                                                       rng.uniform(0.55 * H, 0.95 * H, n)], axis=1))
    foot, head = camera.project(ground), camera.project(ground + 1.75 * camera.up_cam)
    column = 0.5 * (foot[:, 0] + head[:, 0]) + rng.normal(0, 1.0, n)
    return (np.stack([column, foot[:, 1] + rng.normal(0, 1.0, n)], axis=1),
            np.stack([column, head[:, 1] + rng.normal(0, 1.0, n)], axis=1))


def test_box_derived_points_are_recognised():
    from rotavat_cli.calibration import box_derived, fit_camera

    rng = np.random.default_rng(4)
    cam = Camera((1920, 1080), 1400.0, None, math.radians(20), math.radians(1.5), 7.0)
    feet, heads = _boxes(cam, 300, rng)
    assert box_derived(feet, heads)
    res = fit_camera(feet, heads, cam.image_size, focal_px=cam.focal_px)
    assert res.points == "boxes" and res.residual == "vertical" and "box-derived" in res.notes[0]
    forced = fit_camera(feet, heads, cam.image_size, focal_px=cam.focal_px, points="landmarks")
    assert forced.points == "landmarks" and not forced.notes
    heads[0, 0] += 3.0  # one head off its foot's column: these are not boxes
    assert not box_derived(feet, heads)
    assert fit_camera(feet, heads, cam.image_size, focal_px=cam.focal_px).points == "landmarks"
    grid = fit_camera(*_boxes(cam, 50, rng), cam.image_size, method="grid")
    assert grid.points == "landmarks" and "--method refine" in grid.notes[0]


def test_real_box_annotations_are_recognised(tmp_path, runner):
    """PETS 2009: one box per person (Town Centre's head and foot come from two boxes: not recognised)."""
    from rotavat_cli.calibration import box_derived
    from rotavat_cli.calibration.pairs import gather_pairs

    if not (REALDATA / "pets2009_s2l1").exists():
        pytest.skip("../shared/realdata not present")
    pairs = gather_pairs(open_sequence(REALDATA / "pets2009_s2l1"))
    assert box_derived(pairs.feet_px, pairs.heads_px)
    towncentre = gather_pairs(open_sequence(REALDATA / "towncentre"))
    assert not box_derived(towncentre.feet_px, towncentre.heads_px)
    # without the lens prior, PETS's box points leave the focal undetermined: refused, not a camera at the bound
    result = invoke(runner, "calibrate", REALDATA / "pets2009_s2l1", "--out", tmp_path / "c.yaml", "--focal-prior", "none")
    assert result.exit_code == 2 and "cannot determine the focal length" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "recognised as box-derived" in result.stderr
    assert not (tmp_path / "c.yaml").exists()


def test_the_table_never_calls_an_estimated_parameter_fixed(tmp_path, runner):
    from rotavat_cli.cli.calibrate import _std_cell

    root = _scene(tmp_path / "s", "cliff", seed=0, frames=5, people=4)
    result = invoke(runner, "calibrate", root / "pred", "--out", tmp_path / "c.yaml")
    assert result.exit_code == 0, result.stderr
    written = yaml.safe_load((tmp_path / "c.yaml").read_text())
    table = [line for line in result.stdout.splitlines() if line.startswith("│")]
    for key in ("focal_px", "pitch_deg", "roll_deg", "height_m"):
        row = next(line for line in table if key in line)
        assert "fixed" not in row and f"{written['fit']['std'][key]:.3f}" in row, row  # estimated: its std
    assert _std_cell(math.inf, None) == "undetermined" and _std_cell(None, "given") == "fixed: given"
    given = invoke(runner, "calibrate", root / "pred", "--focal", "1000", "--no-roll", "--out", tmp_path / "g.yaml")
    rows = {key: next(line for line in given.stdout.splitlines() if line.startswith("│") and key in line)
            for key in ("focal_px", "roll_deg")}
    assert "fixed: given" in rows["focal_px"] and "fixed: 0" in rows["roll_deg"]


def test_an_unmoved_refinement_falls_back_to_the_grid(monkeypatch):
    from _synthetic_pairs import synthetic_pairs

    from rotavat_cli.calibration import fit as calibrate_module

    data = synthetic_pairs(np.random.default_rng(2), frames=5, people=8)

    def stuck(prob, feet, heads, pp, size, focal_px, free, box, grid, max_rounds):
        seed = np.array([1000.0, math.radians(12.5), 0.0, 12.5, 0.0, box])
        return seed.copy(), np.ones(len(feet), bool), 1.0, seed

    monkeypatch.setattr(calibrate_module, "refine_fit", stuck)
    res = calibrate_module.fit_camera(data.feet_px, data.heads_px, data.camera.image_size, focal_prior="none")
    assert res.method == "grid" and "ended where it started" in res.warnings[0]
    assert math.degrees(res.camera.pitch_rad) != pytest.approx(12.5, abs=1e-3) and res.camera.height_m != 12.5


# ---- the plausibility flag ------------------------------------------------------------------------
def test_implausible_statures_are_flagged_and_counted(tmp_path, runner):
    cam = Camera((1280, 720), 900.0, None, math.radians(20), 0.0, 5.0)
    ground = cam.backproject_px_to_ground(np.array([[400.0, 600.0], [700.0, 620.0], [900.0, 580.0]]))
    column = np.linspace(0.0, 1.0, 30)[None, :, None]
    verts = ground[:, None] + column * (np.array([1.7, 3.0, 0.8])[:, None, None] * cam.up_cam)  # 1.7, 3.0, 0.8 m
    verts = verts + np.array([0.02, 0.0, 0.0]) * np.sin(np.arange(30))[None, :, None]  # not a line
    seq = tmp_path / "seq"
    write_frame(seq, Frame("000000", {"vertices": verts.astype(np.float32), "person_ids": np.arange(3)}), "npz")
    write_meta(seq, {"image_size": [1280, 720], "focal_length": 900.0, "focal_kind": "camera"})
    summary = align_sequence(open_sequence(seq), cam, tmp_path / "out", AlignOptions(jobs=1))
    flags = [r["flag"] for r in csv.DictReader(open(tmp_path / "out" / "people.csv"))]
    assert flags == ["", "implausible_stature", "implausible_stature"]
    assert summary.aligned == 3 and summary.implausible == 2 and summary.flagged == {"implausible_stature": 2}
    (tmp_path / "cfg.yaml").write_text("align:\n  stature_range_m: [0.5, 3.5]\n")
    result = invoke(runner, "align", "--in", seq, "--camera", _write_camera(tmp_path, cam), "--out", tmp_path / "out2",
                    "--config", tmp_path / "cfg.yaml", "--json")
    assert json.loads(result.stdout)["implausible"] == 0
    result = invoke(runner, "align", "--in", seq, "--camera", _write_camera(tmp_path, cam), "--out", tmp_path / "out3")
    assert "2 aligned people have a stature outside 1-2.3 m" in " ".join(result.stderr.split())


def _write_camera(tmp_path: Path, cam: Camera) -> Path:
    from rotavat_cli.sequence import write_camera_yaml

    write_camera_yaml(tmp_path / "cam.yaml", cam)
    return tmp_path / "cam.yaml"


def test_declared_focal_is_found_past_empty_frames(tmp_path):
    from rotavat_cli.calibration import declared_focal

    seq = tmp_path / "s"
    write_frame(seq, Frame("000000", {"vertices": np.zeros((0, 4, 3), np.float32)}), "npz")
    write_frame(seq, Frame("000001", {"vertices": np.ones((2, 4, 3), np.float32), "focal_length": np.float64(1234.0)}), "npz")
    write_meta(seq, {"image_size": [640, 480], "focal_kind": "camera"})
    assert declared_focal(open_sequence(seq)) == 1234.0
