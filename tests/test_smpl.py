"""numpy SMPL linear blend skinning against hand-computed results on small synthetic model files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rotavat_cli.settings import limits
from rotavat_cli.errors import InputError
from rotavat_cli.formats import smpl
from rotavat_cli.formats.smpl import SMPLX_TO_SMPL24, joints_to_smpl24, lbs, load_body_model, pose_to_matrices
from rotavat_cli.geometry.rotations import axis_angle_to_matrix

# A 3-joint chain along +y (joints at y = 0, 1, 2), written in the official npz layout:
# vertex 0/1/2 sit on the joints, vertex 3 is the tip (y = 3), vertex 4 is half skinned to joints 0 and 1.
TEMPLATE = np.array([[0.0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0], [1, 0.5, 0]])
WEIGHTS = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1], [0.5, 0.5, 0]])


def _write_chain(path: Path, shapedirs=None, posedirs=None, dtype=np.float64, parents0=4294967295) -> Path:
    n = len(TEMPLATE)
    regressor = np.zeros((3, n))
    regressor[[0, 1, 2], [0, 1, 2]] = 1.0
    np.savez(path, v_template=TEMPLATE.astype(dtype),
             shapedirs=(np.zeros((n, 3, 2)) if shapedirs is None else shapedirs).astype(dtype),
             posedirs=(np.zeros((n, 3, 18)) if posedirs is None else posedirs).astype(dtype),
             J_regressor=regressor.astype(dtype), weights=WEIGHTS.astype(dtype),
             kintree_table=np.array([[parents0, 0, 1], [0, 1, 2]], dtype=np.uint32),
             f=np.array([[0, 1, 4], [1, 2, 3]]))
    return path


def _rot(axis, deg):
    return axis_angle_to_matrix(np.asarray(axis, float), np.deg2rad(deg))


@pytest.fixture
def chain(tmp_path):
    return load_body_model(_write_chain(tmp_path / "chain.npz"))


def test_identity_pose_gives_the_template(chain):
    verts, joints = lbs(chain, np.zeros((1, 2)), np.zeros((1, 3, 3)))
    np.testing.assert_allclose(verts[0], TEMPLATE, atol=1e-12)
    np.testing.assert_allclose(joints[0], TEMPLATE[:3], atol=1e-12)


def test_root_rotation_turns_about_the_root_joint(chain):
    """90 deg about +x maps +y to +z: joints (0,0,0), (0,0,1), (0,0,2); then transl is added."""
    pose = np.zeros((1, 3, 3))
    pose[0, 0] = [np.pi / 2, 0, 0]
    verts, joints = lbs(chain, np.zeros((1, 2)), pose, transl=np.array([[1.0, 2.0, 3.0]]))
    np.testing.assert_allclose(joints[0], [[1, 2, 3], [1, 2, 4], [1, 2, 5]], atol=1e-12)
    np.testing.assert_allclose(verts[0, 3], [1, 2, 6], atol=1e-12)


def test_child_rotation_moves_only_its_subtree(chain):
    """Joint 1 turned 90 deg about +z: joint 2 and the tip swing to -x around (0, 1, 0)."""
    pose = np.zeros((1, 3, 3))
    pose[0, 1] = [0, 0, np.pi / 2]
    verts, joints = lbs(chain, np.zeros((1, 2)), pose)
    np.testing.assert_allclose(joints[0], [[0, 0, 0], [0, 1, 0], [-1, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(verts[0, 3], [-2, 1, 0], atol=1e-12)
    # half joint 0 (unmoved), half joint 1 (rotated about (0,1,0)): (1, .5, 0) -> mean of itself and (.5, 2, 0)
    np.testing.assert_allclose(verts[0, 4], [0.75, 1.25, 0], atol=1e-12)


def test_chained_rotations_compose(chain):
    """Root 90 deg about z (+y -> -x), joint 1 another 90 deg about z (-x -> -y below joint 1)."""
    pose = np.zeros((1, 3, 3))
    pose[0, 0] = [0, 0, np.pi / 2]
    pose[0, 1] = [0, 0, np.pi / 2]
    _, joints = lbs(chain, np.zeros((1, 2)), pose)
    np.testing.assert_allclose(joints[0], [[0, 0, 0], [-1, 0, 0], [-1, -1, 0]], atol=1e-12)


def test_shape_and_pose_blend_shapes(tmp_path):
    shapedirs = np.zeros((5, 3, 2))
    shapedirs[:, 1, 0] = TEMPLATE[:, 1]  # beta 0 stretches y by (1 + beta0)
    shapedirs[3, 0, 1] = 1.0  # beta 1 moves the tip along x
    posedirs = np.zeros((5, 3, 18))
    posedirs[0, 2, 9 + 4] = 1.0  # vertex 0's z follows element [1, 1] of (R - I) of joint 2 (second 9-block)
    model = load_body_model(_write_chain(tmp_path / "c.npz", shapedirs, posedirs))
    verts, joints = lbs(model, np.array([[0.5, 0.2]]), np.zeros((1, 3, 3)))
    np.testing.assert_allclose(joints[0], [[0, 0, 0], [0, 1.5, 0], [0, 3.0, 0]], atol=1e-12)
    np.testing.assert_allclose(verts[0, 3], [0.2, 4.5, 0], atol=1e-12)
    # Pose corrective: joint 2 turned 90 deg about x gives R[1,1] - 1 = -1 -> vertex 0 (on the root) moves -1 in z.
    pose = np.zeros((1, 3, 3))
    pose[0, 2] = [np.pi / 2, 0, 0]
    verts, _ = lbs(model, np.zeros((1, 2)), pose)
    np.testing.assert_allclose(verts[0, 0], [0, 0, -1], atol=1e-12)


def test_axis_angle_and_rotation_matrices_agree(chain):
    rng = np.random.default_rng(0)
    pose = rng.normal(0, 0.5, (3, 3, 3))
    mats = np.stack([np.stack([_rot(p, np.rad2deg(np.linalg.norm(p))) for p in person]) for person in pose])
    v1, j1 = lbs(chain, np.zeros((3, 2)), pose)
    v2, j2 = lbs(chain, np.zeros((3, 2)), mats)
    v3, _ = lbs(chain, np.zeros((3, 2)), pose.reshape(3, 9))
    np.testing.assert_allclose(v1, v2, atol=1e-12)
    np.testing.assert_allclose(v1, v3, atol=1e-12)
    np.testing.assert_allclose(j1, j2, atol=1e-12)


@pytest.mark.parametrize("n_people", [0, 1, 3])
def test_cardinality(chain, n_people):
    verts, joints = lbs(chain, np.zeros((n_people, 5)), np.zeros((n_people, 3, 3)), np.zeros((n_people, 3)))
    assert verts.shape == (n_people, 5, 3) and joints.shape == (n_people, 3, 3)


def test_many_people_are_posed_in_chunks_equal_to_all_at_once(chain, monkeypatch):
    """Past the chunk size lbs poses a few people at a time (bounded memory): same numbers."""
    rng = np.random.default_rng(3)
    betas, pose, transl = rng.normal(0, 1, (7, 2)), rng.normal(0, 0.5, (7, 9)), rng.normal(0, 2, (7, 3))
    whole = lbs(chain, betas, pose, transl)
    monkeypatch.setattr(smpl, "_LBS_CHUNK_BYTES", 2 * chain.n_verts * smpl._LBS_BYTES_PER_VERTEX)  # 2 people
    chunked = lbs(chain, betas, pose, transl)
    for a, b in zip(whole, chunked):
        assert a.shape == b.shape
        np.testing.assert_array_equal(a, b)


def test_posing_more_than_a_frame_may_hold_is_refused(chain):
    with limits.applied(limits.Limits(1 << 30, 1 << 30, 10 * 5 * 3 * 8, 1000, 1000)):  # 10 people of 5 vertices
        assert lbs(chain, np.zeros((10, 2)), np.zeros((10, 3, 3)))[0].shape == (10, 5, 3)
        with pytest.raises(InputError, match=r"posing 11 people on chain.npz \(5 vertices\) needs 1.3 KiB of meshes, "
                                             r"over limits.max_frame_mb \(1.2 KiB\)"):
            lbs(chain, np.zeros((11, 2)), np.zeros((11, 3, 3)))


def test_float32_file_and_smpl_layout(model_path):
    """The synthetic SMPL-layout model (24 joints, uint32 kintree) loads; identity pose = template."""
    model = load_body_model(model_path)
    assert model.kind == "smpl" and model.n_joints == 24 and model.parents[0] == -1
    verts, joints = lbs(model, np.zeros((1, 10)), np.zeros((1, 24, 3)))
    np.testing.assert_allclose(verts[0], model.v_template, atol=1e-12)
    np.testing.assert_allclose(joints[0], model.J_regressor @ model.v_template, atol=1e-12)
    # A rigid 180-degree turn about x (SMPL's canonical frame -> OpenCV's camera frame): y and z flip around the root.
    pose = np.zeros((1, 24, 3))
    pose[0, 0] = [np.pi, 0, 0]
    verts, _ = lbs(model, np.zeros((1, 10)), pose)
    root = joints[0, 0]
    np.testing.assert_allclose(verts[0], (model.v_template - root) * [1, -1, -1] + root, atol=1e-9)


def test_pose_to_matrices_rejects_wrong_shapes():
    with pytest.raises(ValueError, match="neither axis-angle nor rotation"):
        pose_to_matrices(np.zeros((2, 7)), 3)


def test_joint_mappings():
    smplx = np.arange(127 * 3, dtype=float).reshape(1, 127, 3)
    mapped, note = joints_to_smpl24(smplx)
    assert mapped.shape == (1, 24, 3) and "SMPL-X" in note
    assert mapped[0, 22].tolist() == smplx[0, SMPLX_TO_SMPL24[22]].tolist() == smplx[0, 28].tolist()
    smpl45 = np.zeros((2, 45, 3))
    assert joints_to_smpl24(smpl45)[1] == "smpl24"
    with pytest.raises(ValueError):
        joints_to_smpl24(np.zeros((1, 49, 3)))


# ---- model files: wrong ones are InputErrors naming the file and key --------------------------
def test_model_file_errors(tmp_path):
    good = _write_chain(tmp_path / "good.npz")
    data = dict(np.load(good, allow_pickle=False))
    cases = {
        "missing.npz": ({k: v for k, v in data.items() if k != "weights"}, "missing weights"),
        "shape.npz": ({**data, "weights": data["weights"][:, :2]}, "'weights' must be"),
        "posedirs.npz": ({**data, "posedirs": np.zeros((5, 3, 7))}, "'posedirs' must be"),
        "tree.npz": ({**data, "kintree_table": np.array([[0, 2, 0], [0, 1, 2]])}, "after its parent"),
        "nan.npz": ({**data, "v_template": data["v_template"] * np.nan}, "non-finite"),
    }
    for name, (arrays, needle) in cases.items():
        np.savez(tmp_path / name, **arrays)
        with pytest.raises(InputError, match=needle):
            load_body_model(tmp_path / name)
    sparse_like = np.empty((), dtype=object)
    sparse_like[()] = {"data": [1.0]}
    np.savez(tmp_path / "sparse.npz", **{**data, "J_regressor": sparse_like})
    with pytest.raises(InputError, match="pickled object"):
        load_body_model(tmp_path / "sparse.npz")
    (tmp_path / "SMPL_NEUTRAL.pkl").write_bytes(b"whatever")  # .pkl models: tests/test_smpl_pkl.py
    with pytest.raises(InputError, match=r"SMPL_NEUTRAL\.pkl: not a readable pickle"):
        load_body_model(tmp_path / "SMPL_NEUTRAL.pkl")
    with pytest.raises(InputError, match="file not found"):
        load_body_model(tmp_path / "nope.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(InputError, match="junk.npz: not a valid .npz file"):
        load_body_model(tmp_path / "junk.npz")


def test_a_model_file_is_read_once_per_version_and_its_arrays_cannot_be_changed(tmp_path):
    path = _write_chain(tmp_path / "m.npz")
    first = load_body_model(path)
    assert load_body_model(path) is first  # the same file: the same model, not read again
    with pytest.raises(ValueError):
        first.v_template[0, 0] = 9.0  # read-only: no caller can change what the next one gets
    import os

    shapedirs = np.zeros((len(TEMPLATE), 3, 2))
    shapedirs[3, 1, 0] = 1.0
    _write_chain(path, shapedirs)
    os.utime(path, ns=(first_ns := os.stat(path).st_mtime_ns + 10**9, first_ns))  # a newer version of the file
    second = load_body_model(path)
    assert second is not first and second.shapedirs[3, 1, 0] == 1.0
    with limits.applied(limits.Limits.from_config({"max_array_mb": 1})):  # other limits: checked again
        assert load_body_model(path) is not second
