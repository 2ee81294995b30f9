"""rotavat_cli.bodies.posture (who stands) and rotavat_cli.bodies.joint_layouts (the layouts' joint names).

Hand-built bodies in three layouts, turned every way in the camera frame; the real HPS outputs of
../shared/realfiles (skipped when absent) classified as the photos show them.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from rotavat_cli.bodies import joint_layouts, posture
from rotavat_cli.formats import imported_sequence, keypoints
from rotavat_cli.formats.smpl import joints_to_smpl24, load_body_model, pose_from_body, posed_joints
from rotavat_cli.bodies.joint_layouts import LAYOUT_NAMES
from rotavat_cli.unpickle.torch_files import load_torch
from rotavat_cli.bodies.posture import (KNEE_DOWN_MAX, PELVIS_LOW_MAX, PELVIS_SEATED_MAX, POSTURE_JOINTS, THIGH_SEATED_MIN_RAD,
                                 TRUNK_BEND_MAX_RAD, posture_measures, posture_reasons, postures, standing_mask,
                                 summarize_postures)

REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"
FLICKR = REALFILES / "buddi" / "flickr_bev" / "college_232334_0.08.npz"
BEV_LIVE = REALFILES / "buddi" / "bev_live"
GAIT = REALFILES / "gait" / "demo_walk_1.pkl"
HYBRIK = REALFILES / "hybrik" / "res.pk"
TENNIS = REALFILES / "gvhmr" / "tennis" / "hmr4d_results.pt"

LAYOUTS = ("smpl24", "phalp44 (OpenPose-25 + 19 extra)", "coco17")

# Body frame of the hand-built bodies: x left, y up, z forward; metres.
_MID_HIPS = np.array([0.0, 0.9, 0.0])
_HALF_HIPS, _HALF_SHOULDERS = np.array([0.1, 0.0, 0.0]), np.array([0.18, 0.0, 0.0])
_TRUNK_M, _THIGH_M, _SHANK_M = 0.5, 0.42, 0.42


def _sagittal(angle_deg: float) -> np.ndarray:
    """(3,) unit direction in the sagittal plane, ``angle_deg`` from straight down towards forward."""
    a = np.deg2rad(angle_deg)
    return np.array([0.0, -np.cos(a), np.sin(a)])


def body(hip_deg=(0.0, 0.0), knee_deg=(0.0, 0.0), lean_deg=0.0) -> dict[str, np.ndarray]:
    """Named joints (body frame) of a body whose trunk leans ``lean_deg`` forward, each thigh flexed
    ``hip_deg`` (left, right) forward of the trunk's line and each shank folded ``knee_deg`` back."""
    trunk_down = _sagittal(-lean_deg)
    mid_shoulders = _MID_HIPS - _TRUNK_M * trunk_down
    joints = {"left_shoulder": mid_shoulders + _HALF_SHOULDERS, "right_shoulder": mid_shoulders - _HALF_SHOULDERS}
    for side, sign, hip, knee in zip(("left", "right"), (1, -1), hip_deg, knee_deg):
        joints[f"{side}_hip"] = _MID_HIPS + sign * _HALF_HIPS
        joints[f"{side}_knee"] = joints[f"{side}_hip"] + _THIGH_M * _sagittal(hip - lean_deg)
        joints[f"{side}_ankle"] = joints[f"{side}_knee"] + _SHANK_M * _sagittal(hip - lean_deg - knee)
    return joints


POSES = {  # name: (body, expected posture)
    "standing": (body(), "standing"),
    "walking": (body(hip_deg=(25.0, 10.0), knee_deg=(60.0, 5.0)), "standing"),  # left swings, right stands
    "contrapposto": (body(hip_deg=(15.0, 3.0), knee_deg=(30.0, 3.0)), "standing"),
    "sitting": (body(hip_deg=(90.0, 90.0), knee_deg=(90.0, 90.0)), "sitting"),
    "squatting": (body(hip_deg=(120.0, 120.0), knee_deg=(130.0, 130.0), lean_deg=40.0), "sitting"),
    "kneeling": (body(knee_deg=(90.0, 90.0)), "kneeling"),
    "kneeling on one knee": (body(hip_deg=(90.0, 0.0), knee_deg=(90.0, 90.0)), "kneeling"),
    "bending at the hips": (body(hip_deg=(90.0, 90.0), lean_deg=90.0), "bending"),
    "bowing 60 deg": (body(hip_deg=(60.0, 60.0), lean_deg=60.0), "bending"),
    "picking up": (body(hip_deg=(100.0, 100.0), knee_deg=(30.0, 30.0), lean_deg=80.0), "bending"),
    # standing on bent knees, on one leg, running: read as standing (issue 31: they read as sitting before)
    "plie (knees 60)": (body(hip_deg=(30.0, 30.0), knee_deg=(60.0, 60.0)), "standing"),
    "deep plie (knees 90, thighs 45 off the trunk)": (body(hip_deg=(45.0, 45.0), knee_deg=(90.0, 90.0)), "standing"),
    "tennis ready stance": (body(hip_deg=(45.0, 45.0), knee_deg=(40.0, 40.0), lean_deg=25.0), "standing"),
    "crouch (knees 75, leaning 20)": (body(hip_deg=(30.0, 30.0), knee_deg=(75.0, 75.0), lean_deg=20.0), "standing"),
    "one leg, the other in passe": (body(hip_deg=(0.0, 80.0), knee_deg=(10.0, 130.0)), "standing"),
    "one leg bent, the other in passe": (body(hip_deg=(20.0, 80.0), knee_deg=(40.0, 130.0)), "standing"),
    "runner, stance": (body(hip_deg=(20.0, -10.0), knee_deg=(40.0, 100.0), lean_deg=10.0), "standing"),
    "runner, flight": (body(hip_deg=(40.0, -20.0), knee_deg=(20.0, 90.0), lean_deg=10.0), "standing"),
    "sitting on a high stool (thighs 80 off the trunk)": (body(hip_deg=(80.0, 80.0), knee_deg=(80.0, 80.0)), "sitting"),
}


def in_layout(people: list[dict[str, np.ndarray]], layout: str, rng: np.random.Generator) -> np.ndarray:
    """(P, J, 3) joints of ``layout``: the named joints set, every other joint random (they must not matter)."""
    names = LAYOUT_NAMES[joint_layouts.layout_key(layout)]
    joints = rng.normal(0.0, 1.0, (len(people), len(names), 3))
    for p, person in enumerate(people):
        for name, point in person.items():
            joints[p, names.index(name)] = point
    return joints


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """(3, 3) a uniformly random rotation (QR of a Gaussian matrix, signs fixed, det +1)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def into_camera(joints_body: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(P, J, 3) each person turned by its own random rotation, scaled and put 3-15 m in front of the camera."""
    rotations = np.stack([random_rotation(rng) for _ in joints_body])
    scale = rng.uniform(0.6, 1.2, (len(joints_body), 1, 1))  # children to tall adults: angles ignore size
    shift = np.stack([rng.uniform(-3, 3, len(joints_body)), rng.uniform(-1, 2, len(joints_body)),
                      rng.uniform(3, 15, len(joints_body))], axis=-1)
    return scale * np.einsum("pij,pkj->pki", rotations, joints_body) + shift[:, None, :]


# ---- joint_layouts: the leaf module, and the layouts of formats.keypoints' recipes ------------------------

def _rotavat_imports(module_path: Path) -> set[str]:
    tree = ast.parse(module_path.read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level > 0 or (node.module or "").startswith("rotavat_cli")):
            found.add(("." * node.level) + (node.module or ""))
        elif isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.startswith("rotavat_cli")}
    return found


def test_the_new_modules_import_only_the_bottom_floor():
    assert _rotavat_imports(Path(joint_layouts.__file__)) == {".landmarks"}
    assert _rotavat_imports(Path(posture.__file__)) == {".joint_layouts", "..geometry.rotations"}


def test_formats_keypoints_recipes_are_of_the_leafs_layouts():
    assert set(keypoints.LAYOUTS) <= set(LAYOUT_NAMES)


def test_every_layout_has_the_posture_joints():
    assert len(LAYOUT_NAMES) == 15
    for name, names in LAYOUT_NAMES.items():
        assert set(POSTURE_JOINTS) <= set(names), name


# ---- hand-built bodies ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("layout", LAYOUTS)
def test_hand_built_postures_whatever_the_camera(layout):
    rng = np.random.default_rng(0)
    expected = [want for _, want in POSES.values()]
    bodies = in_layout([b for b, _ in POSES.values()], layout, rng)
    for _ in range(5):
        joints_cam = into_camera(bodies, rng)
        assert postures(joints_cam, layout).tolist() == expected
        assert standing_mask(joints_cam, layout).tolist() == [want == "standing" for want in expected]


def test_measures_are_the_built_ones_and_do_not_depend_on_the_camera():
    rng = np.random.default_rng(1)
    people = [POSES[name][0] for name in ("standing", "walking", "sitting", "kneeling", "bending at the hips",
                                          "one leg, the other in passe")]
    bodies = in_layout(people, "smpl24", rng)
    m = posture_measures(bodies, "smpl24")
    np.testing.assert_allclose(np.rad2deg(m.knee_rad), [[0, 0], [60, 5], [90, 90], [90, 90], [0, 0], [10, 130]],
                               atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(m.hip_flexion_rad), [[0, 0], [25, 10], [90, 90], [0, 0], [90, 90],
                                                               [0, 80]], atol=1e-9)
    # trunk to the ankles->shoulders axis: 0 upright; seated = atan(thigh / (shank + trunk)), kneeling (the ankles
    # behind) = atan(shank / (thigh + trunk)); bent: the axis from the ankles (0.06 m up) to the shoulders (0.5 m
    # forward, 0.9 m up) is 31 deg from vertical, the trunk 90
    seated = np.rad2deg(np.arctan2(_THIGH_M, _SHANK_M + _TRUNK_M))
    kneeling = np.rad2deg(np.arctan2(_SHANK_M, _THIGH_M + _TRUNK_M))
    bent = 90.0 - np.rad2deg(np.arctan2(_TRUNK_M, _THIGH_M + _SHANK_M))
    walker = people[1]
    mid = {part: 0.5 * (walker[f"left_{part}"] + walker[f"right_{part}"]) for part in ("hip", "ankle", "shoulder")}
    trunk, axis = mid["shoulder"] - mid["hip"], mid["shoulder"] - mid["ankle"]
    stride = np.rad2deg(np.arccos(trunk @ axis / np.linalg.norm(trunk) / np.linalg.norm(axis)))
    np.testing.assert_allclose(np.rad2deg(m.trunk_bend_rad)[:5], [0, stride, seated, kneeling, bent], atol=1e-6)
    assert 0 < stride < 10  # a stride moves the mid-ankles only a little
    # the support leg: the lower ankle along the body axis (the walker's right, the stance leg; the dancer's left)
    assert m.support_leg[[1, 5]].tolist() == [1, 0]
    # pelvis above the support ankle along that ankle -> mid-shoulders axis, in leg lengths: a straight leg under
    # the pelvis 1 (its hip is 0.1 m to the side of the mid-hips: a hair over 1); seated: the pelvis one shank up,
    # the axis leaning back by the thigh: (thigh^2 + shank (shank + trunk)) / |axis| / leg
    seated_pelvis = (_THIGH_M ** 2 + _SHANK_M * (_SHANK_M + _TRUNK_M)) / np.hypot(_THIGH_M, _SHANK_M + _TRUNK_M)
    np.testing.assert_allclose(m.pelvis_height[[0, 2]], [1.0, seated_pelvis / (_THIGH_M + _SHANK_M)], atol=0.02)
    assert m.pelvis_height[2] == pytest.approx(0.67, abs=0.01)
    # the lower knee above the support ankle along the trunk, in shanks: 0 kneeling, 1 standing straight
    np.testing.assert_allclose(m.knee_height[[0, 3]], [1.0, 0.0], atol=1e-9)
    for _ in range(10):
        turned = posture_measures(into_camera(bodies, rng), "smpl24")
        for field in ("knee_rad", "hip_flexion_rad", "trunk_bend_rad", "pelvis_height", "knee_height"):
            np.testing.assert_allclose(getattr(turned, field), getattr(m, field), atol=1e-9)
        assert np.array_equal(turned.support_leg[[1, 5]], m.support_leg[[1, 5]])  # the others: feet level


def test_thresholds_sit_between_the_hand_built_limits():
    """A bow of 45 deg over straight legs still stands (trunk ~28 deg off the body axis); 50 deg does not."""
    rng = np.random.default_rng(2)
    bows = in_layout([body(hip_deg=(a, a), lean_deg=a) for a in (45.0, 50.0)], "smpl24", rng)
    assert standing_mask(into_camera(bows, rng), "smpl24").tolist() == [True, False]
    assert np.rad2deg(TRUNK_BEND_MAX_RAD) == pytest.approx(30.0)
    # an upright trunk, thighs 40 deg off it, knees 100 vs 110 deg: the pelvis 0.65 vs 0.58 leg above the feet
    low = in_layout([body(hip_deg=(40.0, 40.0), knee_deg=(k, k)) for k in (100.0, 110.0)], "coco17", rng)
    m = posture_measures(low, "coco17")
    np.testing.assert_allclose(m.pelvis_height, [0.649, 0.578], atol=0.001)
    assert (m.knee_height > KNEE_DOWN_MAX).all() and PELVIS_LOW_MAX == 0.6
    assert postures(into_camera(low, rng), "coco17").tolist() == ["standing", "sitting"]
    # the same pelvis (0.65 leg: knees 100 deg), thighs 45 vs 55 deg off an upright trunk: standing, then sitting
    seats = in_layout([body(hip_deg=(h, h), knee_deg=(100.0, 100.0)) for h in (45.0, 55.0)], "smpl24", rng)
    m = posture_measures(seats, "smpl24")
    np.testing.assert_allclose(m.pelvis_height, [0.651, 0.651], atol=0.001)
    assert PELVIS_LOW_MAX < m.pelvis_height.min() and m.pelvis_height.max() < PELVIS_SEATED_MAX
    np.testing.assert_allclose(np.rad2deg(m.support_hip_flexion_rad), [45.0, 55.0], atol=1e-9)
    assert postures(into_camera(seats, rng), "smpl24").tolist() == ["standing", "sitting"]
    # thighs in line with the trunk, shanks folded back 75 vs 80 deg: the knees 0.26 vs 0.17 shank above the feet
    kneel = in_layout([body(knee_deg=(k, k)) for k in (75.0, 80.0)], "smpl24", rng)
    np.testing.assert_allclose(posture_measures(kneel, "smpl24").knee_height, np.cos(np.deg2rad([75.0, 80.0])),
                               atol=1e-9)
    assert postures(into_camera(kneel, rng), "smpl24").tolist() == ["standing", "kneeling"] and KNEE_DOWN_MAX == 0.2
    assert np.rad2deg(THIGH_SEATED_MIN_RAD) == pytest.approx(50.0)


def test_reasons_and_summary():
    rng = np.random.default_rng(3)
    names = ("standing", "sitting", "kneeling", "bending at the hips")
    joints = into_camera(in_layout([POSES[n][0] for n in names], "smpl24", rng), rng)
    reasons = posture_reasons(joints, "smpl24")
    assert reasons[0].startswith("standing: pelvis 1.01 leg above the left foot (sitting under 0.6, or under 0.8 "
                                 "with the thigh 50 deg off the trunk: 0); knee 1.00 shank above it (kneeling under "
                                 "0.2); trunk 0 deg off the body axis (bending from 30)")
    assert reasons[1].startswith("sitting: pelvis 0.67 leg above the")
    assert "with the thigh 50 deg off the trunk: 90)" in reasons[1]
    assert reasons[2].startswith("kneeling: pelvis 0.67") and "knee 0.00 shank above it" in reasons[2]
    assert reasons[3].startswith("bending: ") and reasons[3].endswith("trunk 59 deg off the body axis (bending from 30)")
    assert summarize_postures(postures(joints, "smpl24")) == "1 sitting, 1 kneeling, 1 bending"
    assert summarize_postures(["standing", "standing"]) == ""
    assert summarize_postures(["unknown", "sitting", "sitting"]) == "2 sitting, 1 unknown"


# ---- layouts and bad joints ----------------------------------------------------------------------------------

def test_layout_by_name_by_count_or_none(monkeypatch):
    rng = np.random.default_rng(4)
    people = [POSES["standing"][0], POSES["sitting"][0]]
    for layout in ("smpl24", "smpl45", "romp71", "smplx144", "hybrik29"):
        joints = in_layout(people, layout, rng)
        assert standing_mask(joints, layout).tolist() == [True, False]
        assert standing_mask(joints, None).tolist() == [True, False], layout  # SMPL family: by the count
    coco = in_layout(people, "coco17", rng)
    assert standing_mask(coco, None) is None  # 17 joints name no SMPL-family layout
    assert standing_mask(coco, "hands21") is None and posture_reasons(coco, "hands21") is None
    assert standing_mask(coco[:, :16], "coco17") is None  # fewer joints than the layout has
    monkeypatch.setitem(LAYOUT_NAMES, "upper_body5", ("nose", "left_shoulder", "right_shoulder", "left_hip",
                                                      "right_hip"))
    assert posture_measures(coco[:, :5], "upper_body5") is None and postures(coco[:, :5], "upper_body5") is None


def test_non_finite_or_coincident_joints_are_unknown_not_standing():
    rng = np.random.default_rng(5)
    joints = in_layout([POSES["standing"][0]] * 4, "phalp44", rng)
    names = LAYOUT_NAMES["phalp44"]
    joints[1, names.index("left_knee")] = np.nan
    joints[2, names.index("right_shoulder")] = np.inf
    joints[3, names.index("left_ankle")] = joints[3, names.index("left_knee")]  # a zero-length shank
    joints[0, names.index("nose")] = np.nan  # a joint the angles do not read
    with np.errstate(all="raise"):
        mask = standing_mask(joints, "phalp44 (OpenPose-25 + 19 extra)")
        reasons = posture_reasons(joints, "phalp44")
    assert mask.tolist() == [True, False, False, False]
    assert reasons[1:] == ("unknown: non-finite joints", "unknown: non-finite joints",
                           "unknown: coincident joints (a zero-length thigh, shank or trunk)")
    assert np.isnan(posture_measures(joints, "phalp44").knee_rad[1, 0])


def test_shapes_and_dtypes():
    rng = np.random.default_rng(6)
    assert standing_mask(np.zeros((0, 24, 3)), "smpl24").shape == (0,)
    assert posture_reasons(np.zeros((0, 24, 3)), "smpl24") == ()
    joints32 = in_layout([POSES["walking"][0]], "smpl24", rng).astype(np.float32)
    assert standing_mask(joints32, "smpl24").tolist() == [True]
    assert posture_measures(joints32, "smpl24").knee_rad.dtype == np.float64
    with pytest.raises(ValueError, match=r"shape \(P, J, 3\), got \(24, 3\)"):
        posture_measures(np.zeros((24, 3)), "smpl24")


# ---- real HPS outputs (../shared/realfiles) -------------------------------------------------------------------

def tennis_joints(smplx_model: Path) -> np.ndarray:
    """(312, 24, 3) GVHMR's tennis player: its SMPL-X parameters (camera frame) posed by ``smplx_model``, joints only."""
    params = {k: np.asarray(v, np.float64) for k, v in load_torch(TENNIS)["smpl_params_incam"].items()}
    model = load_body_model(smplx_model)
    pose = pose_from_body(params["global_orient"], params["body_pose"], model.n_joints)
    return joints_to_smpl24(posed_joints(model, params["betas"], pose, params["transl"]))[0]


def _imported(src: Path, fmt: str) -> tuple[np.ndarray, str]:
    """All frames' joints (sum of P, J, 3) of ``src`` converted in-process (nothing written) and their layout."""
    with imported_sequence(src, fmt) as seq:
        joints = np.concatenate([frame.data["joints"] for frame in seq.frames()])
        return joints, seq.meta["import"]["joints_layout"]


def _measured(joints: np.ndarray, layout: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pelvis height (leg lengths), support thigh to trunk and trunk to body axis (degrees), per person."""
    m = posture_measures(joints, layout)
    return m.pelvis_height, np.rad2deg(m.support_hip_flexion_rad), np.rad2deg(m.trunk_bend_rad)


@pytest.mark.skipif(not FLICKR.is_file(), reason="real BEV group photo absent (../shared/realfiles)")
def test_flickr_group_photo_sitters_do_not_stand():
    """BEV's five people of college_232334.png: the boy, the woman kneeling behind him (her shins hidden: BEV
    bends her knees only 46-50 deg under straight hips, so she passes for standing), the photographer, the person
    sitting at the right edge and the one sitting on the bench behind the photographer, whom BEV draws as a
    crouching stander (knees 53-65 deg, thighs 32 deg off the trunk, pelvis 0.90 leg above the feet: a tennis
    player's crouch is lower), so joints read standing (posture.py's limits)."""
    joints, layout = _imported(FLICKR, "bev")
    assert layout == "smpl24"
    assert postures(joints, layout).tolist() == ["standing", "standing", "standing", "sitting", "standing"]
    pelvis, thigh, trunk = _measured(joints, layout)
    np.testing.assert_allclose(pelvis, [0.99, 0.92, 0.98, 0.68, 0.90], atol=0.005)  # module docstring table
    np.testing.assert_allclose(thigh, [6.8, 11.2, 10.0, 72.0, 31.8], atol=0.1)
    np.testing.assert_allclose(trunk, [6.5, 9.7, 4.5, 12.8, 1.7], atol=0.1)


@pytest.mark.skipif(not BEV_LIVE.is_dir(), reason="real BEV photos absent (../shared/realfiles)")
def test_bev_live_photos_couple_on_the_sofa_sits():
    """image_1 and image_5: two people standing each (image_5's legs cut by the picture's edge); image_8: two on a sofa."""
    joints, layout = _imported(BEV_LIVE, "bev")
    assert postures(joints, layout).tolist() == ["standing"] * 4 + ["sitting"] * 2
    pelvis, thigh, trunk = _measured(joints, layout)
    np.testing.assert_allclose(pelvis, [0.98, 0.97, 0.90, 0.98, 0.63, 0.40], atol=0.005)
    np.testing.assert_allclose(thigh[4:], [76.8, 108.5], atol=0.1)
    assert trunk.max() == pytest.approx(14.7, abs=0.1)


@pytest.mark.skipif(not GAIT.is_file(), reason="real 4D-Humans file absent (../shared/realfiles)")
def test_gait_walker_stands_in_every_frame():
    joints, layout = _imported(GAIT, "4dhumans")
    assert layout.startswith("phalp44") and joints.shape == (67, 44, 3)
    assert standing_mask(joints, layout).all()
    m = posture_measures(joints, layout)
    assert np.rad2deg(m.knee_rad).max() == pytest.approx(65.1, abs=0.1)  # the swing knee
    pelvis, thigh, trunk = _measured(joints, layout)
    assert pelvis.min() == pytest.approx(0.92, abs=0.005) and m.knee_height.min() == pytest.approx(0.76, abs=0.005)
    assert thigh.max() == pytest.approx(38.0, abs=0.1) and trunk.max() == pytest.approx(8.4, abs=0.1)


@pytest.mark.skipif(not HYBRIK.is_file(), reason="real HybrIK file absent (../shared/realfiles)")
def test_hybrik_dancer_stands_in_every_frame():
    """One dancer stepping: a knee lifts to 76 deg while the other leg stays straight."""
    joints, layout = _imported(HYBRIK, "hybrik")
    assert layout == "smpl24" and joints.shape == (135, 24, 3)
    assert standing_mask(joints, layout).all()
    m = posture_measures(joints, layout)
    assert np.rad2deg(m.knee_rad).max() == pytest.approx(75.7, abs=0.1)
    pelvis, thigh, trunk = _measured(joints, layout)
    assert pelvis.min() == pytest.approx(0.95, abs=0.005) and trunk.max() == pytest.approx(9.8, abs=0.1)


@pytest.mark.skipif(not TENNIS.is_file(), reason="real GVHMR file absent (../shared/realfiles)")
def test_gvhmr_tennis_player_stands_through_his_crouches(smplx_on_smpl_path):
    """GVHMR's tennis player (312 frames, the synthetic SMPL-X model's joints under GVHMR's poses): his ready stance
    (trunk up to 26 deg forward), his crouch before each serve (knees up to 80 deg, pelvis 0.74 leg above the feet)
    and his follow-through stand; the knee-and-hip rule before read 133 of 312 frames as bending, sitting or
    kneeling. What is left out: the deepest forward bends of the two follow-throughs (trunk 30-33 deg), and 4
    frames of their landing lunges (the landing leg folded, the other kicked up behind)."""
    joints = tennis_joints(smplx_on_smpl_path)
    names = postures(joints, "smpl24")
    assert joints.shape == (312, 24, 3) and (names == "standing").sum() == 296
    assert {name: int((names == name).sum()) for name in ("bending", "sitting", "kneeling")} == {
        "bending": 12, "sitting": 2, "kneeling": 2}
    pelvis, thigh, trunk = _measured(joints, "smpl24")
    crouch = slice(115, 129)  # the first serve's crouch
    assert (names[crouch] == "standing").all() and pelvis[crouch].min() == pytest.approx(0.75, abs=0.005)
    assert np.rad2deg(posture_measures(joints, "smpl24").knee_rad[crouch]).max() == pytest.approx(76.9, abs=0.1)
    assert trunk[names == "standing"].max() == pytest.approx(29.8, abs=0.1)
    assert trunk[names == "bending"].min() >= 30.0
