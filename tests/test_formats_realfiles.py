"""Real files written by the tools themselves (/work/shared/realfiles, README there): each one an importer
exists for imports, reprojects onto its own image, and gives people of plausible size. Skipped when absent.

- buddi/bev_live: BEV image mode on three photos of different sizes (muelea/buddi demo data);
- gait/demo_walk_1.pkl: 4D-Humans track.py on a 1920x1080 walking video (one track, no body model here).
"""

from __future__ import annotations

import json

from pathlib import Path

import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle
from rotavat_cli.geometry.camera import project_cam_to_px
from rotavat_cli.errors import InputError
from rotavat_cli.formats import import_sequence
from rotavat_cli.formats.image_size import image_size_from_header
from rotavat_cli.formats.keypoints import feet_heads_px
from rotavat_cli.bodies.joint_layouts import LAYOUT_NAMES
from rotavat_cli.bodies.landmarks import foot_head_points, sole_crown_points
from rotavat_cli.sequence import open_sequence

REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"
BEV_LIVE = REALFILES / "buddi" / "bev_live"
IMAGES = REALFILES / "buddi" / "images"
GAIT = REALFILES / "gait" / "demo_walk_1.pkl"

needs_bev = pytest.mark.skipif(not BEV_LIVE.is_dir(), reason="real BEV files absent (../shared/realfiles)")
needs_gait = pytest.mark.skipif(not GAIT.is_file(), reason="real 4D-Humans file absent (../shared/realfiles)")


def _bev_results() -> list[dict]:
    return [unpickle.load_npz(p, keys=("results",))["results"].item() for p in sorted(BEV_LIVE.glob("*.npz"))]


def _chain_stature_m(joints: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """(P,) stature whatever the pose: ankle-knee-hip and pelvis-spine-neck-head bone lengths, plus the head
    joint to the crown and the ankles to the mid-sole (seated people are not sole-to-crown tall)."""
    def seg(a, b):
        return np.linalg.norm(joints[:, a] - joints[:, b], axis=-1)
    feet, crowns = foot_head_points(verts)
    legs = 0.5 * (seg(1, 4) + seg(4, 7) + seg(2, 5) + seg(5, 8))
    trunk = seg(0, 3) + seg(3, 6) + seg(6, 9) + seg(9, 12) + seg(12, 15)
    ends = np.linalg.norm(crowns - joints[:, 15], axis=-1) + np.linalg.norm(joints[:, [7, 8]].mean(axis=1) - feet, axis=-1)
    return legs + trunk + ends


@needs_bev
def test_bev_photos_import_with_their_own_sizes_and_reproject(tmp_path):
    summary = import_sequence(BEV_LIVE, tmp_path / "out", "bev")  # no --image-size: each photo's own, inferred
    seq = open_sequence(tmp_path / "out")
    assert seq.frame_names == ("image_1", "image_5", "image_8")  # '<image>_<center_thresh>' -> the image's name
    assert summary["people"] == 6 and "image_size" not in seq.meta
    for frame in seq.frames():
        size = tuple(frame.data["image_size"].tolist())
        if IMAGES.is_dir():
            assert size == image_size_from_header(IMAGES / f"{frame.name}.jpg")  # 1457x971, 1666x2500, 3000x2000
        focal, principal_point = float(frame.data["focal_length"]), tuple(frame.data["principal_point"])
        assert focal == pytest.approx(443.4 / 512 * max(size))
        reproj = project_cam_to_px(frame.data["joints"], focal, principal_point)
        assert np.abs(frame.data["keypoints_2d"][:, :24] - reproj).max() < 1.0  # px, its own focal
        _, crowns = foot_head_points(frame.data["vertices"])  # the heads are in the photo (some feet are not)
        uv = project_cam_to_px(crowns, focal, principal_point)
        assert np.all((uv > 0) & (uv < np.array(size)))


@needs_bev
def test_bev_people_are_people_sized():
    """Five of the six are 1.6-1.8 m; BEV made the sixth a child (SMPL+A age weight 0.54): 1.15 m."""
    statures, ages = [], []
    for results in _bev_results():
        statures += _chain_stature_m(results["joints"], results["verts"]).tolist()
        ages += results["smpl_betas"][:, 10].tolist()
    statures, ages = np.array(statures), np.array(ages)
    adults = ages < 0.2
    assert adults.sum() == 5 and np.all((statures[adults] > 1.5) & (statures[adults] < 2.0))
    assert statures[~adults] == pytest.approx([1.15], abs=0.05)


@needs_bev
def test_bev_read_as_romp_says_it_is_bev(tmp_path, runner):
    with pytest.raises(InputError, match="this is a BEV result .*71 joints.*read it with --from bev"):
        import_sequence(BEV_LIVE, tmp_path / "out", "romp")
    result = invoke(runner, "import", BEV_LIVE, tmp_path / "out", "--from", "romp")
    assert result.exit_code == 2 and "could not be inferred" not in result.output


@needs_bev
def test_keypoint_rules_on_real_smpl_people():
    """The 'smpl' column of formats/keypoints.py: BEV's four people whose sole-to-crown length exceeds 1.4 m (the
    seated man and the child-shaped woman of image_8 are left out), each turned to the 96 measurement views."""
    errors: dict[str, list] = {"feet mean": [], "smpl24 sole": [], "smpl24 crown": [], "ears crown": [], "lsp": []}
    for results in _bev_results():
        joints, verts = results["joints"].astype(np.float64), results["verts"].astype(np.float64)
        left, right, crowns = sole_crown_points(verts)
        feet = 0.5 * (left + right)  # the rules estimate the mid-sole (the foot point moves from it on its own)
        kept = np.linalg.norm(crowns - feet, axis=-1) > 1.4
        joints, feet, crowns = joints[kept], feet[kept], crowns[kept]
        for p in range(len(joints)):  # body frame: sole at the origin, +Y from sole to crown
            up = (crowns[p] - feet[p]) / np.linalg.norm(crowns[p] - feet[p])
            x = np.cross(up, [0.0, 0.0, 1.0])
            x /= np.linalg.norm(x)
            body_from_cam = np.stack([x, up, np.cross(x, up)])
            points = (np.concatenate([joints[p], feet[p:p + 1], crowns[p:p + 1]]) - feet[p]) @ body_from_cam.T
            for R, t in F.measurement_views():
                uv = project_cam_to_px(points @ R.T + t, 1000.0, (0.0, 0.0))
                kp, sole, crown = uv[None, :71], uv[71], uv[72]
                stature = np.linalg.norm(sole - crown)
                smpl24 = feet_heads_px(kp[:, :24], "smpl24")
                smpl45 = feet_heads_px(kp[:, :45], "smpl45")
                romp71 = feet_heads_px(kp, "romp71")
                for key, got, want in (("feet mean", smpl45[0], sole), ("smpl24 sole", smpl24[0], sole),
                                       ("smpl24 crown", smpl24[1], crown), ("ears crown", smpl45[1], crown),
                                       ("lsp", romp71[1], crown)):
                    errors[key].append(100 * np.linalg.norm(got[0] - want) / stature)
    documented = {"feet mean": (1.70, 2.79), "smpl24 sole": (0.74, 1.26), "smpl24 crown": (1.13, 2.87),
                  "ears crown": (1.28, 3.45), "lsp": (1.81, 3.32)}  # % of stature, mean / max
    assert LAYOUT_NAMES["romp71"][48] == "head_top_lsp"
    for key, (mean, peak) in documented.items():
        assert np.mean(errors[key]) == pytest.approx(mean, abs=0.02), key
        assert np.max(errors[key]) == pytest.approx(peak, abs=0.02), key


@needs_gait
def test_fourdhumans_walker_without_a_model(tmp_path, runner):
    """Joints only: every frame gets feet_2d/heads_2d from OpenPose toes/heels and LSP's top of head; the
    2D keypoints are the 3D joints seen through PHALP's focal; calibrate gets past the missing points and,
    the walker standing at one depth, answers the focal from the lens prior (never PHALP's 37,500 px) and
    says so; align then seats the walker at a plausible stature."""
    summary = import_sequence(GAIT, tmp_path / "out", "4dhumans")
    seq = open_sequence(tmp_path / "out")
    assert summary["frames"] == summary["people"] == 67 and seq.intrinsics.image_size == (1920, 1080)
    assert seq.meta["import"]["feet_heads_from"].startswith("keypoints_2d, phalp44: mid-sole = mean of OpenPose")
    focal, principal_point = seq.intrinsics.focal_px, seq.intrinsics.principal_point
    assert focal == pytest.approx(5000 / 256 * 1920)
    statures = []
    for frame in seq.frames():
        assert np.isfinite(frame.data["feet_2d"]).all() and np.isfinite(frame.data["heads_2d"]).all()
        assert np.all(frame.data["heads_2d"][:, 1] < frame.data["feet_2d"][:, 1] - 300)  # px: upright, head above
        reproj = project_cam_to_px(frame.data["joints"], focal, principal_point)
        assert np.abs(frame.data["keypoints_2d"] - reproj).max() < 1.0
        joints = frame.data["joints"]
        statures.append(np.linalg.norm(joints[:, 38] - joints[:, 19:25].mean(axis=1), axis=-1))
    assert 1.5 < np.mean(statures) < 2.0  # m, LSP top of head to the OpenPose feet (1.55 m)
    result = invoke(runner, "calibrate", tmp_path / "out", "--json")
    assert result.exit_code == 0, result.stderr
    fit = json.loads(result.stdout)["fit"]
    assert fit["determined_by"]["focal_px"] == "prior" and fit["implausible"] == []
    assert 0.4 * 1920 < json.loads(result.stdout)["focal_px"] < 1.3 * 2203  # a lens, not PHALP's 37,500 px
    assert any("one depth" in w for w in fit["warnings"])
    result = invoke(runner, "align", tmp_path / "out", "--out", tmp_path / "aligned", "--json")
    assert result.exit_code == 0, result.stderr
    assert 1.5 < json.loads(result.stdout)["median_stature_m"] < 1.9


AGORA_SAMPLE = REALFILES / "agora_sample" / "smpl_verts_personId_0.pkl"


@pytest.mark.skipif(not AGORA_SAMPLE.is_file(), reason="AGORA's sample predictions absent (../shared/realfiles)")
def test_agora_sample_prediction_imports_and_calibrate_names_what_still_works(tmp_path, runner):
    """AGORA's own sample (a batch axis of one on 'joints', root-centred): imported; calibrate refuses in one
    line naming the step that works (root-aligned eval), and that step runs."""
    summary = import_sequence(AGORA_SAMPLE, tmp_path / "ag", "agora")
    frame = next(open_sequence(tmp_path / "ag").frames())
    assert summary["people"] == 1 and frame.data["keypoints_2d"].shape[:2] == (1, 45)
    result = invoke(runner, "calibrate", tmp_path / "ag")
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1
    step = result.stderr.strip().rsplit("root-aligned metrics still apply: ", 1)[1]
    assert step == f"rotavat eval {tmp_path / 'ag'} --gt GT"
    ran = invoke(runner, *step.split()[1:-1], tmp_path / "ag", "--out", tmp_path / "ev")  # GT: itself, here
    assert ran.exit_code == 0, ran.stderr
