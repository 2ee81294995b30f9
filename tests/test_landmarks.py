"""Tests for rotavat_cli.bodies.landmarks: mid-sole and crown from meshes (known topology and geometry)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from rotavat_cli.bodies import landmarks
from rotavat_cli.bodies.landmarks import (SMPL, SMPLX, Topology, foot_head_points, ground_contact, register_topology,
                                  sole_crown_points, topology_for)

TOL_M = 0.01  # the brief's accuracy target for geometry mode: 1 cm
STATURE_M = 1.70


# --------------------------------------------------------------------------- synthetic humanoid
def _humanoid_body(stride_m: float = 0.0, lift_left_m: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Procedural body in its own frame (x left-right, y up, z forward, ground y=0).

    Returns verts_body (V, 3), mid-sole truth (3,), crown truth (3,). The left leg (x > 0) is moved
    forward by ``stride_m`` and lifted by ``lift_left_m``; the right leg goes back by ``stride_m``.
    """
    parts = []
    sole_points = []
    for side, dz, dy in ((+1.0, stride_m, lift_left_m), (-1.0, -stride_m, 0.0)):
        x = 0.10 * side
        foot = trimesh.creation.box(extents=(0.10, 0.06, 0.26))
        foot.apply_translation((x, 0.03 + dy, 0.05 + dz))  # feet stick out forward
        leg = trimesh.creation.cylinder(radius=0.065, segment=[(x, 0.06 + dy, dz), (x, 0.86, dz)], sections=24)
        arm = trimesh.creation.cylinder(radius=0.04, segment=[(0.23 * side, 0.80, 0.0), (0.23 * side, 1.44, 0.0)])
        parts += [foot, leg, arm]
        sole_points.append((x, dy, 0.05 + dz))
    torso = trimesh.creation.box(extents=(0.36, 0.60, 0.22))
    torso.apply_translation((0.0, 1.16, 0.0))
    neck = trimesh.creation.cylinder(radius=0.05, segment=[(0.0, 1.46, 0.0), (0.0, 1.50, 0.0)])
    head = trimesh.creation.icosphere(subdivisions=3, radius=0.11)
    head.apply_translation((0.0, STATURE_M - 0.11, 0.0))
    body = trimesh.util.concatenate(parts + [torso, neck, head]).subdivide_to_size(max_edge=0.03)
    mid_sole = np.mean(sole_points, axis=0)
    crown = np.array([0.0, STATURE_M, 0.0])
    return np.asarray(body.vertices, dtype=np.float64), mid_sole, crown


def _upright_placement(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Random R_cam_from_body (3, 3), t_cam_from_body (3,): person upright in the image, 5-15 m away."""
    R_cam_from_body_upright = np.diag([1.0, -1.0, -1.0])  # body up -> image up, body faces the camera
    yaw = Rotation.from_rotvec([0.0, rng.uniform(-np.pi, np.pi), 0.0]).as_matrix()
    pitch = Rotation.from_rotvec([np.deg2rad(rng.uniform(-40.0, 40.0)), 0.0, 0.0]).as_matrix()
    roll = Rotation.from_rotvec([0.0, 0.0, np.deg2rad(rng.uniform(-15.0, 15.0))]).as_matrix()
    R = roll @ pitch @ R_cam_from_body_upright @ yaw
    t = np.array([rng.uniform(-3.0, 3.0), rng.uniform(-1.0, 3.0), rng.uniform(5.0, 15.0)])
    return R, t


def _to_cam(points_body: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Apply X_cam = R X_body + t to (..., 3)."""
    return points_body @ R.T + t


def _placed_people(rng: np.random.Generator, n_people: int, **body_kw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P, V, 3) upright humanoids in the camera frame with their truths feet (P, 3), heads (P, 3)."""
    verts_body, mid_sole_body, crown_body = _humanoid_body(**body_kw)
    placements = [_upright_placement(rng) for _ in range(n_people)]
    verts_cam = np.stack([_to_cam(verts_body, R, t) for R, t in placements])
    feet_cam = np.stack([_to_cam(mid_sole_body, R, t) for R, t in placements])
    heads_cam = np.stack([_to_cam(crown_body, R, t) for R, t in placements])
    return verts_cam, feet_cam, heads_cam


def _dist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Euclidean distance (P,)."""
    return np.linalg.norm(a - b, axis=-1)


def test_humanoid_fixture_is_not_a_known_topology():
    verts_body, _, _ = _humanoid_body()
    assert topology_for(len(verts_body)) is None
    assert np.isclose(verts_body[:, 1].min(), 0.0) and np.isclose(verts_body[:, 1].max(), STATURE_M)


# --------------------------------------------------------------------------- geometry mode
def test_geometry_mode_recovers_mid_sole_and_crown_within_1cm():
    rng = np.random.default_rng(0)
    verts_cam, feet_true, heads_true = _placed_people(rng, 6)
    feet_cam, heads_cam = foot_head_points(verts_cam)
    assert feet_cam.shape == heads_cam.shape == (6, 3)
    assert feet_cam.dtype == heads_cam.dtype == np.float64
    np.testing.assert_array_less(_dist(feet_cam, feet_true), TOL_M)
    np.testing.assert_array_less(_dist(heads_cam, heads_true), TOL_M)
    # stature (sole plane to crown) comes out right too
    np.testing.assert_allclose(_dist(feet_cam, heads_cam), STATURE_M, atol=TOL_M)


def _contact_truth(left: np.ndarray, right: np.ndarray, crown: np.ndarray) -> np.ndarray:
    """(3,) the ground contact written out: the mid-sole slid down the mid-sole -> crown axis to the lower sole's
    level, then moved toward the lower sole: not at all for a level difference under 10 % of the axis, all the
    way from 20 %, linearly between."""
    mid = 0.5 * (left + right)
    length = np.linalg.norm(crown - mid)
    up = (crown - mid) / length
    levels = [float((left - mid) @ up), float((right - mid) @ up)]
    on_axis = mid + min(levels) * up
    share = float(np.clip(((max(levels) - min(levels)) / length - 0.10) / 0.10, 0.0, 1.0))
    return on_axis + share * ((left if levels[0] <= levels[1] else right) - on_axis)


def test_geometry_mode_stride_and_lifted_foot():
    """Long stride (legs front/back) with the left foot 10 cm up: the foot point is on the right (standing)
    sole's level along the axis, under the mid-sole (the soles differ by 8.5 cm along it, 5 % of its length:
    a walker's), 4.2 cm from the mid-sole."""
    rng = np.random.default_rng(0)
    verts_body, mid_body, crown_body = _humanoid_body(stride_m=0.25, lift_left_m=0.10)
    soles = np.array([[0.10, 0.10, 0.30], [-0.10, 0.0, -0.20]])  # _humanoid_body's sole points (left lifted)
    contact_body = _contact_truth(*soles, crown_body)
    assert np.linalg.norm(contact_body - mid_body) == pytest.approx(0.0424, abs=1e-4)
    placements = [_upright_placement(rng) for _ in range(4)]
    verts_cam = np.stack([_to_cam(verts_body, R, t) for R, t in placements])
    feet_cam, heads_cam = foot_head_points(verts_cam)
    np.testing.assert_array_less(_dist(feet_cam, np.stack([_to_cam(contact_body, R, t) for R, t in placements])), TOL_M)
    np.testing.assert_array_less(_dist(heads_cam, np.stack([_to_cam(crown_body, R, t) for R, t in placements])), TOL_M)


def test_geometry_mode_any_orientation_with_rough_hint():
    """Arbitrary orientation; a hint 50 degrees off the true up is enough to orient the axis."""
    rng = np.random.default_rng(0)
    verts_body, mid_sole_body, crown_body = _humanoid_body()
    R = Rotation.random(4, random_state=rng).as_matrix()  # (4, 3, 3)
    t = rng.uniform(-5.0, 5.0, size=(4, 3)) + np.array([0.0, 0.0, 10.0])
    verts_cam = np.einsum("pij,vj->pvi", R, verts_body) + t[:, None, :]
    up_true_cam = R[:, :, 1]  # body y axis in the camera frame
    tilt_axis = np.cross(up_true_cam, rng.normal(size=(4, 3)))
    tilt = Rotation.from_rotvec(np.deg2rad(50.0) * tilt_axis / np.linalg.norm(tilt_axis, axis=1, keepdims=True))
    hint_cam = tilt.apply(up_true_cam) * 3.0  # any norm
    feet_cam, heads_cam = foot_head_points(verts_cam, up_hint_cam=hint_cam)
    np.testing.assert_array_less(_dist(feet_cam, R @ mid_sole_body + t), TOL_M)
    np.testing.assert_array_less(_dist(heads_cam, R @ crown_body + t), TOL_M)


def test_geometry_mode_t_pose_tie_break_by_hint():
    """Dense horizontal arms make the left-right variance slightly exceed the vertical one."""
    verts_body, mid_sole_body, crown_body = _humanoid_body()
    hanging_arms = (np.abs(verts_body[:, 0]) > 0.185) & (np.abs(verts_body[:, 0]) < 0.28)
    hanging_arms &= (verts_body[:, 1] > 0.79) & (verts_body[:, 1] < 1.45)
    reach = np.linspace(0.20, 0.85, 20000)
    arm = np.stack([reach, np.full_like(reach, 1.40), np.zeros_like(reach)], axis=1)
    t_pose_body = np.concatenate([verts_body[~hanging_arms], arm, arm * np.array([-1.0, 1.0, 1.0])])
    centered = t_pose_body - t_pose_body.mean(axis=0)
    evals, evecs = np.linalg.eigh(centered.T @ centered)
    assert abs(evecs[0, 2]) > 0.99 and evals[1] / evals[2] > 0.8  # largest axis is left-right
    rng = np.random.default_rng(0)
    R, t = _upright_placement(rng)
    feet_cam, heads_cam = foot_head_points(_to_cam(t_pose_body, R, t)[None])
    assert _dist(feet_cam[0], _to_cam(mid_sole_body, R, t)) < TOL_M
    assert _dist(heads_cam[0], _to_cam(crown_body, R, t)) < TOL_M


def test_up_hint_decides_which_end_is_the_head():
    rng = np.random.default_rng(0)
    verts_cam, feet_true, _ = _placed_people(rng, 2)
    _, heads_flipped = foot_head_points(verts_cam, up_hint_cam=np.array([0.0, 1.0, 0.0]))
    # upside down, the "crown" is the lowest patch: both soles, centred on the mid-sole
    np.testing.assert_array_less(_dist(heads_flipped, feet_true), TOL_M)


def test_geometry_mode_is_translation_equivariant():
    rng = np.random.default_rng(0)
    verts_cam, _, _ = _placed_people(rng, 2)
    shift = np.array([0.3, -0.2, 4.0])
    feet_a, heads_a = foot_head_points(verts_cam)
    feet_b, heads_b = foot_head_points(verts_cam + shift)
    np.testing.assert_allclose(feet_b, feet_a + shift, atol=1e-9)
    np.testing.assert_allclose(heads_b, heads_a + shift, atol=1e-9)


# --------------------------------------------------------------------------- known topologies
@pytest.mark.parametrize(
    ("topology", "toes", "heels"),
    [
        (SMPL, ((3216, 3226), (6617, 6624)), ((3387, 3458), (6787, 6858))),
        (SMPLX, ((5770, 5780), (8463, 8474)), ((8846, 8847), (8635, 8635))),
    ],
)
def test_known_topology_uses_planted_sole_and_crown_vertices(topology, toes, heels):
    rng = np.random.default_rng(0)
    verts_cam = rng.normal(scale=0.5, size=(2, topology.n_verts, 3)) + np.array([0.0, 0.0, 8.0])
    heel_l, toe_l = np.array([0.12, 1.5, 8.0]), np.array([0.10, 1.48, 7.76])
    heel_r, toe_r = np.array([-0.12, 1.5, 8.0]), np.array([-0.14, 1.49, 7.75])
    crown = np.array([0.0, -0.2, 8.05])
    verts_cam[:, list(toes[0])] = toe_l
    verts_cam[:, list(heels[0])] = heel_l
    verts_cam[:, list(toes[1])] = toe_r
    verts_cam[:, list(heels[1])] = heel_r
    verts_cam[:, topology.crown_index] = crown
    feet_cam, heads_cam = foot_head_points(verts_cam)
    sole_l, sole_r = 0.5 * (heel_l + toe_l), 0.5 * (heel_r + toe_r)  # half heel, half toes
    # the left sole is 5 mm higher (y down): the foot point is on the right sole's level along the axis
    np.testing.assert_allclose(feet_cam, np.tile(_contact_truth(sole_l, sole_r, crown), (2, 1)), atol=1e-12)
    np.testing.assert_allclose(heads_cam, np.tile(crown, (2, 1)), atol=1e-12)
    left, right, crowns = sole_crown_points(verts_cam)
    np.testing.assert_allclose(left, np.tile(sole_l, (2, 1)), atol=1e-12)
    np.testing.assert_allclose(right, np.tile(sole_r, (2, 1)), atol=1e-12)


def test_cited_indices_are_pinned():
    assert topology_for(6890) is SMPL and topology_for(10475) is SMPLX
    assert SMPL.crown_index == 412 and SMPLX.crown_index == 8976
    assert tuple(SMPL.left_sole_indices) == (3216, 3226, 3387, 3458)
    assert tuple(SMPL.right_sole_indices) == (6617, 6624, 6787, 6858)
    assert tuple(SMPLX.left_sole_indices) == (5770, 5780, 8846, 8847)
    assert tuple(SMPLX.right_sole_indices) == (8463, 8474, 8635, 8635)


def test_known_topology_ignores_up_hint():
    rng = np.random.default_rng(0)
    verts_cam = rng.normal(size=(2, SMPL.n_verts, 3))
    a = foot_head_points(verts_cam)
    b = foot_head_points(verts_cam, up_hint_cam=np.array([1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


# --------------------------------------------------------------------------- cardinality
@pytest.mark.parametrize("n_verts", [SMPL.n_verts, SMPLX.n_verts, 500])
def test_zero_people_gives_empty_float64(n_verts):
    feet_cam, heads_cam = foot_head_points(np.zeros((0, n_verts, 3), dtype=np.float32))
    assert feet_cam.shape == heads_cam.shape == (0, 3)
    assert feet_cam.dtype == heads_cam.dtype == np.float64


def test_batch_of_three_equals_one_by_one_geometry():
    rng = np.random.default_rng(0)
    verts_cam, _, _ = _placed_people(rng, 3, stride_m=0.1)
    feet_cam, heads_cam = foot_head_points(verts_cam)
    for p in range(3):
        feet_one, heads_one = foot_head_points(verts_cam[p : p + 1])
        np.testing.assert_allclose(feet_one[0], feet_cam[p], atol=1e-12)
        np.testing.assert_allclose(heads_one[0], heads_cam[p], atol=1e-12)


def test_batch_of_three_equals_one_by_one_topology():
    rng = np.random.default_rng(0)
    verts_cam = rng.normal(size=(3, SMPLX.n_verts, 3))
    feet_cam, heads_cam = foot_head_points(verts_cam)
    for p in range(3):
        feet_one, heads_one = foot_head_points(verts_cam[p : p + 1])
        np.testing.assert_array_equal(feet_one[0], feet_cam[p])
        np.testing.assert_array_equal(heads_one[0], heads_cam[p])


def test_float32_input_gives_float64_output():
    rng = np.random.default_rng(0)
    verts_cam, feet_true, _ = _placed_people(rng, 2)
    feet_cam, heads_cam = foot_head_points(verts_cam.astype(np.float32))
    assert feet_cam.dtype == heads_cam.dtype == np.float64
    np.testing.assert_array_less(_dist(feet_cam, feet_true), TOL_M)


# --------------------------------------------------------------------------- degenerate input
@pytest.mark.parametrize("n_verts", [SMPL.n_verts, None])
def test_non_finite_or_identical_vertices_give_nan_rows(n_verts):
    rng = np.random.default_rng(0)
    if n_verts is None:
        verts_cam, feet_true, heads_true = _placed_people(rng, 4)
    else:
        verts_cam = rng.normal(size=(4, n_verts, 3)) + np.array([0.0, 0.0, 8.0])
    verts_cam[1, 17, 2] = np.nan  # one NaN vertex, not at a landmark index
    verts_cam[2, 5, 0] = np.inf
    verts_cam[3] = np.array([0.5, 1.0, 7.0])  # all vertices identical
    with np.errstate(all="raise"):  # no floating-point warnings either
        feet_cam, heads_cam = foot_head_points(verts_cam)
    assert np.isnan(feet_cam[1:]).all() and np.isnan(heads_cam[1:]).all()
    assert np.isfinite(feet_cam[0]).all() and np.isfinite(heads_cam[0]).all()
    if n_verts is None:
        assert _dist(feet_cam[0], feet_true[0]) < TOL_M and _dist(heads_cam[0], heads_true[0]) < TOL_M


def test_collinear_or_vertexless_meshes_give_nan_rows():
    line = np.linspace(0.0, 1.7, 50)[:, None] * np.array([0.0, -1.0, 0.0]) + np.array([0.0, 0.0, 5.0])
    feet_cam, heads_cam = foot_head_points(line[None])
    assert np.isnan(feet_cam).all() and np.isnan(heads_cam).all()
    feet_cam, heads_cam = foot_head_points(np.zeros((2, 0, 3)))
    assert feet_cam.shape == (2, 3) and np.isnan(feet_cam).all() and np.isnan(heads_cam).all()


def test_bad_shapes_raise_value_error():
    with pytest.raises(ValueError, match=r"\(P, V, 3\)"):
        foot_head_points(np.zeros((10, 3)))
    with pytest.raises(ValueError, match="up_hint_cam must have shape"):
        foot_head_points(np.ones((2, 40, 3)), up_hint_cam=np.ones((3, 3)))
    with pytest.raises(ValueError, match="finite and non-zero"):
        foot_head_points(np.ones((2, 40, 3)), up_hint_cam=np.zeros(3))


# --------------------------------------------------------------------------- registry
def test_register_topology_switches_the_mesh_to_its_indices(monkeypatch):
    monkeypatch.setattr(landmarks, "_TOPOLOGIES", dict(landmarks._TOPOLOGIES))
    verts_body, mid_sole_body, crown_body = _humanoid_body()
    on_ground = np.flatnonzero(np.isclose(verts_body[:, 1], 0.0))
    left = on_ground[verts_body[on_ground, 0] > 0.0]
    right = on_ground[verts_body[on_ground, 0] < 0.0]
    crown_index = int(np.argmax(verts_body[:, 1]))
    topology = Topology("test_humanoid", len(verts_body), crown_index, left, right)
    assert topology_for(len(verts_body)) is None
    register_topology(topology)
    assert topology_for(len(verts_body)) is topology

    rng = np.random.default_rng(0)
    R, t = _upright_placement(rng)
    verts_cam = _to_cam(verts_body, R, t)[None]
    feet_cam, heads_cam = foot_head_points(verts_cam)
    expected_feet = 0.5 * (verts_cam[0, left].mean(axis=0) + verts_cam[0, right].mean(axis=0))
    np.testing.assert_allclose(feet_cam[0], expected_feet, atol=1e-12)
    np.testing.assert_allclose(heads_cam[0], verts_cam[0, crown_index], atol=1e-12)
    assert _dist(feet_cam[0], _to_cam(mid_sole_body, R, t)) < TOL_M
    assert _dist(heads_cam[0], _to_cam(crown_body, R, t)) < TOL_M


def test_packaged_synthetic_topology_is_built_in_and_loading_bodies_changes_nothing():
    """Every process finds the synthetic bodies' points by index, whether it has loaded them or not."""
    from rotavat_cli.synth.bodies import load_bodies

    registered = dict(landmarks._TOPOLOGIES)
    library = load_bodies()
    assert landmarks._TOPOLOGIES == registered  # no process-wide side effect
    n_verts = library.vertices.shape[1]
    assert n_verts not in (6890, 10475) and n_verts not in registered
    topology = topology_for(n_verts)
    assert topology.name == "rotavat-synth"
    np.testing.assert_array_equal(topology.left_sole_indices, library.topology.left_sole_indices)
    assert topology.crown_index == library.topology.crown_index


def test_topology_validates_indices():
    with pytest.raises(ValueError, match=r"must lie in \[0, 10\)"):
        Topology("bad", 10, 3, np.array([1, 2]), np.array([9, 10]))
    with pytest.raises(ValueError, match="left_sole_indices is empty"):
        Topology("bad", 10, 3, np.array([], dtype=int), np.array([4]))
    with pytest.raises(TypeError):
        register_topology("smpl")  # type: ignore[arg-type]
    assert not SMPL.left_sole_indices.flags.writeable
