"""Contract of the packaged body library ``rotavat_cli/data/bodies.npz`` (made by tools/make_bodies.py).

Canonical body frame: metres, +Y up, the person faces +Z, +X is the person's left; lowest vertex
at y = 0; mid-sole (midpoint of the two sole-vertex means, on the ground) at x = z = 0.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

BODIES_NPZ = Path(__file__).resolve().parents[1] / "rotavat_cli" / "data" / "bodies.npz"

SMPL24 = [
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
]  # fmt: skip
J = {name: i for i, name in enumerate(SMPL24)}


@pytest.fixture(scope="module")
def npz():
    with np.load(BODIES_NPZ, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


def test_file_is_small():
    assert BODIES_NPZ.stat().st_size <= 1_100_000


def test_keys_shapes_dtypes(npz):
    assert set(npz) == {
        "vertices", "faces", "joints", "joint_names", "crown_index", "left_sole_indices",
        "right_sole_indices", "stature_m", "sex",
    }  # fmt: skip
    v, f, j = npz["vertices"], npz["faces"], npz["joints"]
    assert v.ndim == 3 and v.shape[0] == 8 and v.shape[2] == 3 and v.dtype == np.float32
    assert f.ndim == 2 and f.shape[1] == 3 and f.dtype == np.int32
    assert j.shape == (v.shape[0], 24, 3) and j.dtype == np.float32
    assert npz["joint_names"].dtype.kind == "U" and npz["joint_names"].tolist() == SMPL24
    assert npz["crown_index"].shape == () and npz["crown_index"].dtype == np.int64
    for key in ("left_sole_indices", "right_sole_indices"):
        idx = npz[key]
        assert idx.ndim == 1 and idx.dtype == np.int64 and len(idx) >= 10
        assert len(np.unique(idx)) == len(idx)
        assert idx.min() >= 0 and idx.max() < v.shape[1]
    assert not set(npz["left_sole_indices"].tolist()) & set(npz["right_sole_indices"].tolist())
    assert 0 <= int(npz["crown_index"]) < v.shape[1]
    assert npz["stature_m"].shape == (v.shape[0],) and npz["stature_m"].dtype == np.float64
    assert npz["sex"].shape == (v.shape[0],) and npz["sex"].dtype == np.dtype("<U6")
    assert set(npz["sex"].tolist()) == {"male", "female"}
    assert np.isfinite(v).all() and np.isfinite(j).all()


def test_faces_valid_and_outward(npz):
    f = npz["faces"]
    assert f.min() == 0 and f.max() == npz["vertices"].shape[1] - 1  # every vertex used
    assert np.all(f[:, 0] != f[:, 1]) and np.all(f[:, 1] != f[:, 2]) and np.all(f[:, 0] != f[:, 2])
    for v in npz["vertices"]:
        mesh = trimesh.Trimesh(v, f, process=False)
        assert mesh.is_winding_consistent
        assert mesh.is_watertight
        assert mesh.volume > 0.03  # outward normals; an adult is ~0.04-0.1 m^3


def test_ground_and_mid_sole(npz):
    v = npz["vertices"].astype(np.float64)
    assert np.all(v[:, :, 1].min(axis=1) == 0.0)
    left = v[:, npz["left_sole_indices"]]
    right = v[:, npz["right_sole_indices"]]
    mid = 0.5 * (left.mean(axis=1) + right.mean(axis=1))
    assert np.abs(mid[:, [0, 2]]).max() < 1e-3
    # soles are the bottom of the feet: within ~1 cm of the ground, left at +X, right at -X
    assert left[:, :, 1].max() < 0.012 and right[:, :, 1].max() < 0.012
    assert np.all(left[:, :, 0] > 0.03) and np.all(right[:, :, 0] < -0.03)
    # ... and they span the foot from heel to toe
    for soles in (left, right):
        length = soles[:, :, 2].max(axis=1) - soles[:, :, 2].min(axis=1)
        assert np.all(length > 0.15)


def test_crown_and_stature(npz):
    v = npz["vertices"]
    top = v[:, :, 1].max(axis=1)
    crown = v[:, int(npz["crown_index"])]
    assert np.all(top - crown[:, 1] <= 0.005)
    np.testing.assert_allclose(npz["stature_m"], top, atol=0.005)
    assert np.all((npz["stature_m"] >= 1.50) & (npz["stature_m"] <= 1.95))
    assert npz["stature_m"].max() - npz["stature_m"].min() > 0.2  # varied statures
    # the crown is above the body's mid line and over the feet
    assert np.all(np.abs(crown[:, 0]) < 0.03) and np.all(np.abs(crown[:, 2]) < 0.15)


def test_joints_plausible(npz):
    j = npz["joints"].astype(np.float64)
    s = npz["stature_m"][:, None]
    x, y = j[..., 0], j[..., 1]
    # pelvis between the hips, at about hip height, roughly half the stature up
    assert np.all(np.minimum(x[:, J["left_hip"]], x[:, J["right_hip"]]) < x[:, J["pelvis"]])
    assert np.all(x[:, J["pelvis"]] < np.maximum(x[:, J["left_hip"]], x[:, J["right_hip"]]))
    assert np.all(np.abs(y[:, J["pelvis"]] - y[:, J["left_hip"]]) < 0.1)
    assert np.all((y[:, J["pelvis"]] > 0.45 * s[:, 0]) & (y[:, J["pelvis"]] < 0.6 * s[:, 0]))
    # the spine goes up: pelvis < spine1 < spine2 < spine3 < neck < head < crown
    chain = ["pelvis", "spine1", "spine2", "spine3", "neck", "head"]
    for lo, hi in zip(chain, chain[1:]):
        assert np.all(y[:, J[lo]] < y[:, J[hi]]), (lo, hi)
    assert np.all(y[:, J["head"]] < s[:, 0])
    # legs go down: hip > knee > ankle > foot (> 0)
    for side in ("left", "right"):
        leg = [f"{side}_{n}" for n in ("hip", "knee", "ankle", "foot")]
        for hi, lo in zip(leg, leg[1:]):
            assert np.all(y[:, J[hi]] > y[:, J[lo]]), (hi, lo)
        assert np.all(y[:, J[f"{side}_foot"]] > 0)
        # arms hang down (standing pose, no T-pose): shoulder > elbow > wrist
        arm = [f"{side}_{n}" for n in ("shoulder", "elbow", "wrist")]
        for hi, lo in zip(arm, arm[1:]):
            assert np.all(y[:, J[hi]] > y[:, J[lo]] + 0.1), (hi, lo)
    # left joints at +X, right joints at -X; the mid-line joints near x = 0
    for name in SMPL24:
        if name.startswith("left_"):
            assert np.all(x[:, J[name]] > 0.02), name
            assert np.all(x[:, J["right_" + name[5:]]] < -0.02), name
        elif not name.startswith("right_"):
            assert np.all(np.abs(x[:, J[name]]) < 0.02), name
    # joints lie inside the body's bounding box
    v = npz["vertices"]
    assert np.all(j >= v.min(axis=1)[:, None] - 1e-3) and np.all(j <= v.max(axis=1)[:, None] + 1e-3)


def test_faces_plus_z(npz):
    j = npz["joints"].astype(np.float64)
    v = npz["vertices"].astype(np.float64)
    for side in ("left", "right"):
        # toes extend toward +Z from the ankles
        assert np.all(j[:, J[f"{side}_foot"], 2] > j[:, J[f"{side}_ankle"], 2] + 0.05)
    # the foot vertices reach further to +Z (toes) than to -Z (heel) from the ankle
    for b in range(len(v)):
        feet = v[b][v[b][:, 1] < 0.03]
        ankle_z = 0.5 * (j[b, J["left_ankle"], 2] + j[b, J["right_ankle"], 2])
        assert feet[:, 2].max() - ankle_z > 2.0 * (ankle_z - feet[:, 2].min())
    # right-handed frame: left (+X) x up (+Y) = +Z, which is forward for this body
    up = j[:, J["neck"]] - j[:, J["pelvis"]]
    left = j[:, J["left_hip"]] - j[:, J["right_hip"]]
    assert np.all(np.cross(left, up)[:, 2] > 0)  # left x up = forward for a +Z-facing person
