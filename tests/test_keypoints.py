"""Mid-sole and crown pixels from each tool's 2D keypoint layout (rotavat_cli.formats.keypoints), and what the
importers write with them (feet_2d/heads_2d without meshes; people not placed in the camera; BEV photos of
different sizes; Multi-HMR's demo file names; a BEV file read as ROMP)."""

from __future__ import annotations

import _format_fixtures as F
import numpy as np
import pytest

from rotavat_cli.geometry.camera import ROOT_CENTRED_M, project_cam_to_px
from rotavat_cli.errors import InputError
from rotavat_cli.formats import import_sequence
from rotavat_cli.formats.frames import people_frame
from rotavat_cli.formats.imported import placement_warnings
from rotavat_cli.formats.meta import feet_heads_from
from rotavat_cli.sequence import Frame, people_not_placed


def unplaced_people(vertices, joints) -> np.ndarray:
    """(P,) bool: the people a frame of these vertices and joints does not place in the camera."""
    data = {k: v for k, v in (("vertices", vertices), ("joints", joints)) if v is not None}
    return np.logical_or(*people_not_placed(Frame("f", data, "f")))
from rotavat_cli.formats.keypoints import LAYOUTS, PointRule, extrapolated, feet_heads_px, mean_of, recipe_for
from rotavat_cli.bodies.joint_layouts import LAYOUT_NAMES, layout_by_count
from rotavat_cli.bodies.landmarks import foot_head_points, sole_crown_points
from rotavat_cli.sequence import open_sequence
from rotavat_cli.synth.bodies import load_bodies

W, H = 640, 480


def _kp(n: int, points: dict[int, tuple[float, float]], people: int = 1) -> np.ndarray:
    """(people, n, 2) keypoints, zero except ``points`` (index -> pixel), the same for every person."""
    kp = np.zeros((people, n, 2))
    for index, uv in points.items():
        kp[:, index] = uv
    return kp


# ---- hand-computed cases, indices written from each tool's own joint list -------------------------------
# A person in pixels: feet points at v = 100 (heels 102), ankles at v = 95, hips at v = 50, shoulders at
# v = 20, ears at v = 10, centred on u = 50.
FEET_POINTS = {"lbig": (40, 100), "lsmall": (36, 100), "lheel": (44, 102), "rbig": (60, 100), "rsmall": (64, 100),
               "rheel": (56, 102)}
FEET_MEAN = (50.0, 100 + 2 / 3)
EARS_CROWN_V = 10 + 0.632 * (10 - 20)  # mid-ears + 0.632 (mid-ears - mid-shoulders)


def _feet(order: tuple[int, int, int, int, int, int]) -> dict[int, tuple[float, float]]:
    """OpenPose's foot points at indices (LBigToe, LSmallToe, LHeel, RBigToe, RSmallToe, RHeel)."""
    return dict(zip(order, FEET_POINTS.values()))


@pytest.mark.parametrize("layout, n, feet, ears, shoulders", [
    ("openpose25", 25, (19, 20, 21, 22, 23, 24), (17, 18), (2, 5)),  # openpose doc/02_output.md BODY_25
    ("smpl45", 45, (29, 30, 31, 32, 33, 34), (27, 28), (16, 17)),  # smplx SMPL + vertex joints (SPIN JOINT_MAP)
    ("smplx127", 127, (60, 61, 62, 63, 64, 65), (58, 59), (16, 17)),  # smplx joint_names.py
    ("smplx144", 144, (60, 61, 62, 63, 64, 65), (58, 59), (16, 17)),
])
def test_feet_mean_and_ears_crown(layout, n, feet, ears, shoulders):
    kp = _kp(n, {**_feet(feet), ears[0]: (45, 10), ears[1]: (55, 10), shoulders[0]: (35, 20), shoulders[1]: (65, 20)})
    sole, crown, used = feet_heads_px(kp, layout)
    np.testing.assert_allclose(sole, [FEET_MEAN])
    np.testing.assert_allclose(crown, [[50.0, EARS_CROWN_V]])
    assert used.startswith(f"{layout}: mid-sole = mean of OpenPose") and "crown estimated" in used


@pytest.mark.parametrize("layout, n, feet, head_top", [
    ("spin49", 49, (19, 20, 21, 22, 23, 24), 38),  # SPIN JOINT_NAMES: 'Top of Head (LSP)' = 25 + 13
    ("phalp44", 44, (19, 20, 21, 22, 23, 24), 38),
    ("phalp45", 45, (19, 20, 21, 22, 23, 24), 38),
    ("romp54", 54, (29, 30, 31, 32, 33, 34), 48),  # simple_romp: SMPL-24 + 21 vertex joints + 9 (J_regressor_extra)
    ("romp71", 71, (29, 30, 31, 32, 33, 34), 48),
])
def test_feet_mean_and_head_top(layout, n, feet, head_top):
    sole, crown, used = feet_heads_px(_kp(n, {**_feet(feet), head_top: (51, 3)}), layout)
    np.testing.assert_allclose(sole, [FEET_MEAN])
    np.testing.assert_allclose(crown, [[51.0, 3.0]])
    assert "estimated" not in used


def test_coco17_estimates_both_points():
    """COCO: sole = mid-ankles + 0.07 (mid-ankles - mid-hips) + 0.556 (nose - mid-ears); crown from ears, shoulders."""
    kp = _kp(17, {0: (58, 12), 3: (45, 10), 4: (55, 10), 5: (35, 20), 6: (65, 20), 11: (44, 50), 12: (56, 50),
                  15: (46, 95), 16: (54, 95)})
    sole, crown, used = feet_heads_px(kp, "coco17")
    np.testing.assert_allclose(sole, [[50 + 0.556 * 8, 95 + 0.07 * 45 + 0.556 * 2]])
    np.testing.assert_allclose(crown, [[50.0, EARS_CROWN_V]])
    assert "estimate" in used and "face looks where the feet point" in used


def test_h36m17_estimates_both_points():
    """H36M order (VideoPose3D): ankles 3, 6; hips 1, 4; thorax 8; head 10."""
    kp = _kp(17, {1: (45, 50), 4: (55, 50), 3: (46, 95), 6: (54, 95), 8: (50, 22), 10: (50, 8)})
    sole, crown, _ = feet_heads_px(kp, "h36m17")
    np.testing.assert_allclose(sole, [[50.0, 95 + 0.116 * 45]])
    np.testing.assert_allclose(crown, [[50.0, 8 - 0.462 * 14]])


@pytest.mark.parametrize("layout, n, head_top", [("smpl24", 24, None), ("hybrik29", 29, 24)])
def test_smpl_joints_estimate_the_sole_and_hybrik_has_a_head_top(layout, n, head_top):
    """SMPL order: hips 1, 2; ankles 7, 8; feet 10, 11; head 15; HybrIK's leaf 24 = head top (vertex 411)."""
    points = {1: (45, 50), 2: (55, 50), 7: (46, 94), 8: (54, 94), 10: (46, 98), 11: (54, 98), 15: (50, 18)}
    if head_top is not None:
        points[head_top] = (50, 2)
    sole, crown, _ = feet_heads_px(_kp(n, points), layout)
    np.testing.assert_allclose(sole, [[50.0, 96 + 0.047 * 46]])
    np.testing.assert_allclose(crown, [[50.0, 2.0 if head_top is not None else 18 - 0.314 * 32]])


def test_missing_or_unconfident_points_give_nan_for_that_person_only():
    kp = np.concatenate([_kp(25, {**_feet((19, 20, 21, 22, 23, 24)), 17: (45, 10), 18: (55, 10), 2: (35, 20),
                                  5: (65, 20)}, people=3), np.ones((3, 25, 1))], axis=2)
    kp[1, 21, :2] = np.nan  # a heel not found
    kp[2, 18, 2] = 0.0  # an ear with zero confidence
    sole, crown, _ = feet_heads_px(kp, "openpose25")
    assert np.isfinite(sole[[0, 2]]).all() and np.isnan(sole[1]).all()
    assert np.isfinite(crown[[0, 1]]).all() and np.isnan(crown[2]).all()


def test_layouts_lookup_and_rules():
    assert feet_heads_px(np.zeros((1, 24, 2)), "spin49") is None  # shorter than the layout
    assert feet_heads_px(np.zeros((1, 49, 2)), "nope") is None and recipe_for(None) is None
    assert recipe_for("phalp44 (OpenPose-25 + 19 extra)") is LAYOUTS["phalp44"]
    assert [layout_by_count(n) for n in (24, 29, 45, 49, 54, 71, 127, 144, 17)] == [
        "smpl24", "hybrik29", "smpl45", "spin49", "romp54", "romp71", "smplx127", "smplx144", None]
    for name, recipe in LAYOUTS.items():  # every rule reads points the layout has
        assert recipe.n_keypoints == len(LAYOUT_NAMES[name])
        assert max(recipe.sole.indices + recipe.crown.indices) < recipe.n_keypoints
    assert extrapolated((0,), (1,), 0.5).terms == ((1.5, (0,)), (-0.5, (1,))) and not mean_of(3).estimated
    with pytest.raises(ValueError, match="sum to 1"):
        PointRule(((0.5, (0,)),))


# ---- measured errors on the packaged bodies (the module docstring's anny column) ---------------------------
def _ears(verts: np.ndarray, joints: np.ndarray, crown: np.ndarray) -> np.ndarray:
    """(2, 3) left/right ear of a packaged body: the outermost 1.2 cm of each side of the head, at ear height."""
    shoulder_y, head_y = joints[16, 1], joints[15, 1]
    head = verts[(verts[:, 1] > shoulder_y + 0.08) & (np.abs(verts[:, 0]) < 0.12)]
    band = head[(head[:, 1] < crown[1] - 0.06) & (head[:, 1] > head_y - 0.02)]
    return np.stack([band[s * band[:, 0] > (s * band[:, 0]).max() - 0.012].mean(axis=0) for s in (1, -1)])


def test_documented_errors_on_the_packaged_bodies():
    """SMPL-24 sole rule (anny 0.8 / 1.4 % of stature) and ears crown rule (0.6 / 1.1 %), 96 views x 8 bodies."""
    bodies = load_bodies()
    left, right, heads_cam = sole_crown_points(bodies.vertices)
    feet_cam = 0.5 * (left + right)  # the rules estimate the mid-sole (the foot point moves from it on its own)
    ears = np.stack([_ears(v, j, h) for v, j, h in zip(bodies.vertices, bodies.joints, heads_cam)])
    names = ("left_hip", "right_hip", "left_ankle", "right_ankle", "left_foot", "right_foot", "left_shoulder",
             "right_shoulder")
    idx24 = [LAYOUT_NAMES["smpl24"].index(n) for n in names]
    idx45 = [LAYOUT_NAMES["smpl45"].index(n) for n in names + ("left_ear", "right_ear")]
    sole_err, crown_err = [], []
    for R, t in F.measurement_views():
        joints_px, sole_px, crown_px, ears_px = (project_cam_to_px(points @ R.T + t, 1000.0, (0.0, 0.0))
                                                 for points in (bodies.joints, feet_cam, heads_cam, ears))
        stature = np.linalg.norm(sole_px - crown_px, axis=-1)
        kp24 = np.full((len(bodies), 24, 2), np.nan)
        kp24[:, idx24] = joints_px[:, idx24]
        sole_err.append(np.linalg.norm(feet_heads_px(kp24, "smpl24")[0] - sole_px, axis=-1) / stature)
        kp45 = np.full((len(bodies), 45, 2), np.nan)
        kp45[:, idx45] = np.concatenate([joints_px[:, idx24], ears_px], axis=1)
        crown_err.append(np.linalg.norm(feet_heads_px(kp45, "smpl45")[1] - crown_px, axis=-1) / stature)
    sole_err, crown_err = 100 * np.array(sole_err), 100 * np.array(crown_err)
    assert sole_err.mean() == pytest.approx(0.75, abs=0.05) and sole_err.max() < 1.45
    assert crown_err.mean() == pytest.approx(0.62, abs=0.05) and crown_err.max() < 1.1


# ---- people_frame: feet/heads from keypoints, placement -----------------------------------------------------
def _openpose_person(u: float) -> np.ndarray:
    kp = _kp(25, {**_feet((19, 20, 21, 22, 23, 24)), 17: (45, 10), 18: (55, 10), 2: (35, 20), 5: (65, 20)})[0]
    return kp + [u - 50, 0]


def test_people_frame_writes_feet_and_heads_without_meshes_only():
    kp = np.stack([_openpose_person(50), _openpose_person(150)])
    joints = np.zeros((2, 24, 3)) + [0, 0, 5]
    frame = people_frame("f", "src", [], joints=joints, keypoints_2d=kp, keypoints_layout="openpose25")
    np.testing.assert_allclose(frame.data["feet_2d"], [FEET_MEAN, (150, FEET_MEAN[1])], rtol=1e-6)
    np.testing.assert_allclose(frame.data["heads_2d"], [[50, EARS_CROWN_V], [150, EARS_CROWN_V]], rtol=1e-6)
    meshes = people_frame("f", "src", [], vertices=np.ones((2, 10, 3)), keypoints_2d=kp, keypoints_layout="openpose25")
    assert "feet_2d" not in meshes.data  # meshes give their own landmarks
    assert feet_heads_from("openpose25", True) == "mesh landmarks (sole vertices' ground contact, crown vertex)"
    assert feet_heads_from("openpose25 (x)", False).startswith("keypoints_2d, openpose25: mid-sole = mean")
    assert feet_heads_from("nope", False) is None


def test_people_frame_keeps_a_person_missing_a_point_as_a_nan_row():
    kp = np.stack([_openpose_person(50), _openpose_person(150)])
    kp[1, 21] = np.nan
    frame = people_frame("f", "src", [], joints=np.zeros((2, 24, 3)) + [0, 0, 5], keypoints_2d=kp,
                         keypoints_layout="openpose25")
    assert np.isnan(frame.data["feet_2d"][1]).all() and np.isfinite(frame.data["heads_2d"]).all()


def test_unplaced_people_and_their_warning():
    """Root within ROOT_CENTRED_M of the camera centre, or any point at or behind the camera plane: not placed."""
    body = np.array([[0.0, 0.0, 0.0], [0.0, -0.9, 0.05], [0.0, 0.9, -0.05]])  # root first, metres
    joints = np.stack([body + [0, 0, 6.0],  # in front of the camera
                       body,  # root-centred: root at the camera centre (and half behind it)
                       body + [0, 0, ROOT_CENTRED_M - 0.1],  # root 0.4 m ahead: at the centre, all z > 0
                       body + [0, 0, ROOT_CENTRED_M + 0.1]])  # root 0.6 m ahead, all z > 0: placed
    assert unplaced_people(None, joints).tolist() == [False, True, True, False]
    verts = joints.copy()
    verts[3, 2, 2] = -0.01  # one vertex behind the camera plane
    assert unplaced_people(verts, joints).tolist() == [False, True, True, True]
    assert unplaced_people(verts, None).tolist() == [False, True, True, True]  # root = the vertices' mean
    assert placement_warnings(0, 5, "x") == []
    assert placement_warnings(3, 3, "x")[0].startswith("x: every person at the camera centre or (partly) behind")
    assert placement_warnings(1, 3, "x")[0].startswith("x: 1 of 3 people at the camera centre")


# ---- importers ------------------------------------------------------------------------------------------
def test_agora_root_centred_people_are_reported(tmp_path, scene):
    src = F.write_agora(tmp_path / "agora", scene, root_centred=True)
    summary = import_sequence(src, tmp_path / "out", "agora")
    text = " ".join(summary["warnings"])
    assert "every person at the camera centre or (partly) behind the camera" in text
    frame = next(open_sequence(tmp_path / "out").frames())
    np.testing.assert_allclose(frame.data["joints"][:, 0], 0.0, atol=1e-6)  # imported as they are, not moved
    placed = import_sequence(F.write_agora(tmp_path / "ok", scene), tmp_path / "out_ok", "agora")
    assert not any("camera centre" in w for w in placed["warnings"])


def test_agora_45_joints_layout_says_what_it_is(tmp_path, scene):
    src = F.write_agora(tmp_path / "agora", scene, joints_2d=45)
    import_sequence(src, tmp_path / "out", "agora")
    meta = open_sequence(tmp_path / "out").meta["import"]
    assert meta["keypoints_2d_layout"].startswith("smpl45 ")
    assert meta["feet_heads_from"] == "mesh landmarks (sole vertices' ground contact, crown vertex)"
    import_sequence(F.write_agora(tmp_path / "a24", scene), tmp_path / "out24", "agora")
    assert open_sequence(tmp_path / "out24").meta["import"]["keypoints_2d_layout"].startswith("smpl24 ")


def test_bev_photos_of_different_sizes_carry_their_own_intrinsics(tmp_path, scene):
    """Image mode: <image>_<center_thresh>.npz, each photo its own size; frames state size, focal, principal point."""
    sizes = [(640, 480), (500, 750), None]  # the third frame is empty: no file
    src = F.write_bev(tmp_path / "bev", scene, (W, H), sizes=sizes, suffix="_0.08")
    summary = import_sequence(src, tmp_path / "out", "bev")
    seq = open_sequence(tmp_path / "out")
    assert seq.frame_names == ("frame_0000", "frame_0001")  # BEV's '_<center_thresh>' dropped
    assert "image_size" not in seq.meta and "focal_length" not in seq.meta
    assert any("differ in size (500x750, 640x480)" in w for w in summary["warnings"])
    for frame, size, people in zip(seq.frames(), sizes, scene):
        side = max(size)
        left, top = (side - size[0]) // 2, (side - size[1]) // 2
        assert frame.data["image_size"].tolist() == list(size)
        assert float(frame.data["focal_length"]) == pytest.approx(443.4 / 512 * side)
        np.testing.assert_allclose(frame.data["principal_point"], [side / 2 - left, side / 2 - top])
        np.testing.assert_allclose(frame.data["vertices"], np.stack([p.verts_cam for p in people]), atol=1e-4)
        reproj = project_cam_to_px(frame.data["joints"], float(frame.data["focal_length"]),
                                   tuple(frame.data["principal_point"]))
        np.testing.assert_allclose(frame.data["keypoints_2d"][:, :24], reproj, atol=0.02)


def test_bev_one_size_stays_in_meta_and_other_names_are_kept(tmp_path, scene):
    src = F.write_bev(tmp_path / "bev", scene, (W, H), suffix="__1_0.12")  # video mode: '__<model id>_<thresh>'
    import_sequence(src, tmp_path / "out", "bev")
    seq = open_sequence(tmp_path / "out")
    assert seq.meta["image_size"] == [W, H] and seq.frame_names == ("frame_0000", "frame_0001")
    assert "image_size" not in next(seq.frames()).data


def test_a_bev_file_read_as_romp_says_so(tmp_path, scene):
    src = F.write_bev(tmp_path / "bev", scene, (W, H))
    with pytest.raises(InputError, match=r"this is a BEV result \(11 SMPL\+A shape parameters, 71 joints\), not "
                                         r"ROMP's: read it with --from bev"):
        import_sequence(src, tmp_path / "out", "romp")
    romp = F.write_bev(tmp_path / "romp", scene, (W, H), fmt="romp")
    with pytest.raises(InputError, match="this is a ROMP result"):
        import_sequence(romp, tmp_path / "out2", "bev", image_size=(W, H))


def test_multihmr_demo_file_names_give_the_image_stems(tmp_path, scene):
    src = F.write_multihmr(tmp_path / "mh", scene, form="npy", model_name="multiHMR_896_L")
    assert min(p.name for p in src.iterdir()) == "img_000_multiHMR_896_L.png.npy"
    import_sequence(src, tmp_path / "out", "multihmr", image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    assert seq.frame_names == ("img_000", "img_001", "img_002")
    np.testing.assert_allclose(next(seq.frames()).data["vertices"], np.stack([p.verts_cam for p in scene[0]]), atol=1e-4)


def test_cliff_without_a_model_projects_its_joints_for_feet_and_heads(tmp_path, scene):
    src = F.write_cliff(tmp_path / "r.npz", scene, (W, H))
    import_sequence(src, tmp_path / "out", "cliff", image_size=(W, H))
    seq = open_sequence(tmp_path / "out")
    assert seq.meta["import"]["keypoints_2d_layout"].startswith("smpl45 ")
    frame = next(seq.frames())
    pred_joints = np.load(src)["pred_joints"][:2]
    np.testing.assert_allclose(frame.data["keypoints_2d"], F.project(pred_joints, np.hypot(W, H), (W / 2, H / 2)),
                               atol=0.02)
    assert frame.data["feet_2d"].shape == (2, 2) and np.isfinite(frame.data["heads_2d"]).all()


def test_bedlam_without_a_model_finds_feet_and_heads_near_the_meshes(tmp_path, scene, model):
    """gtkps (SMPL-24 here) give the mid-sole and crown within the SMPL-24 rules' error of the true landmarks."""
    src = F.write_bedlam(tmp_path / "scene.npz", scene)
    import_sequence(src, tmp_path / "out", "bedlam")
    seq = open_sequence(tmp_path / "out")
    assert seq.meta["import"]["feet_heads_from"].startswith("keypoints_2d, smpl24: mid-sole estimated")
    focal = 28.0 / 36.0 * 1280
    for frame, people in zip(seq.frames(), [f for f in scene if f]):
        feet_cam, heads_cam = foot_head_points(np.stack([p.verts_cam for p in people]))
        sole_px, crown_px = F.project(feet_cam, focal, (640, 360)), F.project(heads_cam, focal, (640, 360))
        stature = np.linalg.norm(sole_px - crown_px, axis=-1)
        assert np.all(np.linalg.norm(frame.data["feet_2d"] - sole_px, axis=-1) < 0.02 * stature)
        assert np.all(np.linalg.norm(frame.data["heads_2d"] - crown_px, axis=-1) < 0.05 * stature)


def test_every_reader_reports_people_not_placed_in_the_camera():
    """The check lives in ImportedSequence, not in the readers: any reader's root-centred people are reported."""
    from rotavat_cli.formats.imported import ImportedSequence

    body = np.array([[0.0, 0.0, 0.0], [0.0, -0.9, 0.05], [0.0, 0.9, -0.05]])

    def build(index, notes):  # a reader that knows nothing of the check: two people, one root-centred
        return people_frame(f"{index:06d}", "toy", notes.warnings, joints=np.stack([body + [0, 0, 6.0], body]))

    imported = ImportedSequence(("000000", "000001"), build, {"import": {"source_path": "/data/toy.pkl"}})
    assert len(list(imported.frames)) == 2
    assert imported.warnings == ["/data/toy.pkl: 2 of 4 people at the camera centre or (partly) behind the camera "
                                 "(z <= 0): root-centred output (no translation) or another frame, not people placed in "
                                 "the camera; calibrate and align cannot use them (root-aligned metrics such as MPJPE, "
                                 "PVE and PA-MPJPE still apply)"]


def test_track_ids_beyond_int64_are_refused_not_wrapped():
    joints = np.zeros((2, 3, 3)) + [0.0, 0.0, 5.0]
    for ids in (np.array([1, 2**63], dtype=np.uint64), np.array([1.0, np.inf])):
        with pytest.raises(InputError, match="does not fit in a 64-bit integer"):
            people_frame("f", "src.npz", [], joints=joints, person_ids=ids)
    assert people_frame("f", "src.npz", [], joints=joints, person_ids=np.array([3, 4], np.uint64)).person_ids.tolist() == [3, 4]
