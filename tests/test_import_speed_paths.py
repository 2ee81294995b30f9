"""The fast paths of issue 34 give the same numbers as the slow ones: a long clip's people posed in batches
(:mod:`rotavat_cli.formats.row_blocks`) equal them posed frame by frame, in any order of building frames; the
matrix-product LBS equals smplx's einsum formulation; the GL read-back's un-premultiply and the normals' and mesh
reductions' topology caches give what the work done afresh gives."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import _fixtures_torch as T
import _fixtures_wham_hybrik as W
import _format_fixtures as F
from rotavat_cli.formats.read import read_format
from rotavat_cli.formats.row_blocks import RowBlocks, frame_offsets, posing_block_rows
from rotavat_cli.formats.smpl import _rigid_transforms, lbs, lbs_batch_rows, load_body_model, pose_to_matrices
from rotavat_cli.formats.imported import FrameNotes
from rotavat_cli.render.gl import unpremultiply
from rotavat_cli.render.style import vertex_normals
from rotavat_cli.settings import limits


# ---- RowBlocks ---------------------------------------------------------------------------------------------
def _squares(calls: list):
    def compute(start: int, stop: int) -> dict[str, np.ndarray]:
        calls.append((start, stop))
        rows = np.arange(start, stop, dtype=np.float64)
        return {"x": rows, "xx": np.stack([rows, rows ** 2], axis=1)}
    return compute


def test_row_blocks_in_order_compute_each_row_once():
    calls: list = []
    blocks = RowBlocks(10, _squares(calls), 4)
    offsets = frame_offsets([3, 0, 2, 3, 2])  # frames of several rows, one empty, straddling the blocks
    got = [blocks.rows(int(offsets[t]), int(offsets[t + 1]))["x"].tolist() for t in range(5)]
    assert got == [[0, 1, 2], [], [3, 4], [5, 6, 7], [8, 9]]
    assert sum(b - a for a, b in calls) <= 10 + 4  # at most one block's rows computed twice (a straddling frame)


def test_row_blocks_any_order_gives_the_same_rows():
    rng = np.random.default_rng(3)
    offsets = frame_offsets(rng.integers(0, 4, 30))
    blocks = RowBlocks(int(offsets[-1]), _squares([]), 5)
    for t in rng.permutation(30).tolist() + [0, 0, 29]:
        got = blocks.rows(int(offsets[t]), int(offsets[t + 1]))
        rows = np.arange(offsets[t], offsets[t + 1], dtype=np.float64)
        assert np.array_equal(got["x"], rows) and np.array_equal(got["xx"][:, 1], rows ** 2)


def test_row_blocks_a_frame_larger_than_a_block_is_whole():
    blocks = RowBlocks(10, _squares([]), 2)
    assert blocks.rows(1, 8)["x"].tolist() == [1, 2, 3, 4, 5, 6, 7]


def test_row_blocks_hand_out_read_only_views():
    blocks = RowBlocks(4, _squares([]), 4)
    with pytest.raises(ValueError):
        blocks.rows(0, 2)["x"][0] = 5.0


def test_posing_blocks_stay_within_one_frame_limit(model):
    assert posing_block_rows(model) == min(lbs_batch_rows(model), limits.current().max_frame_bytes // (model.n_verts * 24))
    with limits.applied(dataclasses.replace(limits.current(), max_frame_bytes=1 << 20)):
        assert posing_block_rows(model) == max(1, (1 << 20) // (model.n_verts * 24))


# ---- lbs ---------------------------------------------------------------------------------------------------
def _einsum_lbs(model, betas, pose, transl):
    """smplx's lbs.py formulation (einsum), as rotavat posed people before issue 34."""
    rot = pose_to_matrices(pose, model.n_joints)
    P = len(rot)
    n = min(betas.shape[1], model.shapedirs.shape[2])
    v_shaped = model.v_template[None] + np.einsum("vcs,ps->pvc", model.shapedirs[:, :, :n], betas[:, :n])
    rest = np.einsum("jv,pvc->pjc", model.J_regressor, v_shaped)
    v_posed = v_shaped + ((rot[:, 1:] - np.eye(3)).reshape(P, -1) @ model.posedirs).reshape(P, -1, 3)
    joints, rel = _rigid_transforms(rot, rest, model.parents)
    Tr = np.einsum("vj,pjab->pvab", model.weights, rel)
    verts = np.einsum("pvab,pvb->pva", Tr[..., :3, :3], v_posed) + Tr[..., :3, 3]
    return verts + transl[:, None], joints + transl[:, None]


def _random_people(rng, n, n_joints):
    return rng.standard_normal((n, 10)), 0.3 * rng.standard_normal((n, n_joints, 3)), rng.standard_normal((n, 3))


def test_lbs_matrix_products_equal_the_einsum_formulation(model):
    betas, pose, transl = _random_people(np.random.default_rng(0), 5, model.n_joints)
    verts, joints = lbs(model, betas, pose, transl)
    ref_verts, ref_joints = _einsum_lbs(model, betas, pose, transl)
    np.testing.assert_allclose(verts, ref_verts, rtol=0, atol=1e-12)
    np.testing.assert_allclose(joints, ref_joints, rtol=0, atol=1e-12)


def test_lbs_in_one_batch_equals_person_by_person(model):
    """Joints exactly; vertices to the last bits (the pose blend shapes are one matrix product for the batch,
    whose sums BLAS may order otherwise than for one row): far below float32, which frames store."""
    betas, pose, transl = _random_people(np.random.default_rng(1), 7, model.n_joints)
    verts, joints = lbs(model, betas, pose, transl)
    for p in range(7):
        v, j = lbs(model, betas[p:p + 1], pose[p:p + 1], transl[p:p + 1])
        assert np.array_equal(j[0], joints[p])
        np.testing.assert_allclose(v[0], verts[p], rtol=0, atol=1e-14)


# ---- readers posing in blocks ------------------------------------------------------------------------------
def _frames(imported, order):
    out = {}
    for index in order:
        frame = imported.build(index, FrameNotes())
        out[index] = {k: np.array(v) for k, v in frame.data.items()}
    return out


def _assert_same_frames(a: dict, b: dict):
    assert a.keys() == b.keys()
    for index in a:
        assert a[index].keys() == b[index].keys()
        for key in a[index]:
            assert np.array_equal(a[index][key], b[index][key], equal_nan=True), (index, key)


def test_gvhmr_frames_posed_in_blocks_equal_frames_posed_alone(tmp_path, model, camera, smplx_on_smpl_path):
    rng = np.random.default_rng(4)
    n = 23
    people = [F.standing_person(model, camera, np.sin(i / 5), -6.0 - i / 10, 0) for i in range(n)]
    src = T.write_gvhmr(tmp_path / "g", people, (640, 480), body_pose=0.2 * rng.standard_normal((n, 63)))
    smplx = load_body_model(smplx_on_smpl_path)
    imported = read_format(src, "gvhmr", smpl_model=smplx)
    in_order = _frames(imported, range(n))
    backwards = _frames(read_format(src, "gvhmr", smpl_model=smplx), reversed(range(n)))
    _assert_same_frames(in_order, backwards)
    # each frame against the reader posing that one frame alone (a block of one row)
    with limits.applied(dataclasses.replace(limits.current(), max_frame_bytes=int(smplx.n_verts * 24 * 1.5))):
        alone = _frames(read_format(src, "gvhmr", smpl_model=smplx), range(n))
    _assert_same_frames(in_order, alone)


def test_wham_and_tram_frames_posed_in_blocks_equal_frames_posed_alone(tmp_path, model, camera):
    rng = np.random.default_rng(5)

    def bent(person):  # random body pose and shape: pose and shape blend shapes at work
        return dataclasses.replace(person, pose=np.concatenate([person.pose[:1], 0.3 * rng.standard_normal((23, 3))]),
                                   betas=rng.standard_normal(10))

    scene = [[bent(F.standing_person(model, camera, k + np.sin(i / 4), -7.0 - k, k)) for k in range(3) if 3 * k <= i < 20 - 2 * k]
             if i != 7 else [] for i in range(20)]
    wham = W.write_wham(tmp_path / "wham.pkl", [f for f in scene if f])
    tram = T.write_tram(tmp_path / "tram", scene, (640, 480))
    for src, fmt, size in ((wham, "wham", (640, 480)), (tram, "tram", None)):
        first = read_format(src, fmt, smpl_model=model, image_size=size)
        in_order = _frames(first, range(first.n_frames))
        shuffled = _frames(read_format(src, fmt, smpl_model=model, image_size=size), rng.permutation(first.n_frames))
        _assert_same_frames(in_order, shuffled)
        with limits.applied(dataclasses.replace(limits.current(), max_frame_bytes=int(model.n_verts * 24 * 3.5))):
            small = read_format(src, fmt, smpl_model=model, image_size=size)  # blocks of 3 rows
            _assert_same_frames(in_order, _frames(small, range(first.n_frames)))


# ---- render and view ---------------------------------------------------------------------------------------
def _old_unpremultiply(data: np.ndarray) -> np.ndarray:
    rgba = data.astype(np.float32) / 255.0
    alpha = rgba[..., 3:4]
    with np.errstate(divide="ignore", invalid="ignore"):
        rgba[..., :3] = np.where(alpha > 0, rgba[..., :3] / np.maximum(alpha, 1e-6), 0.0)
    return np.clip(rgba, 0.0, 1.0)


def test_unpremultiply_equals_dividing_every_pixel():
    rng = np.random.default_rng(6)
    data = rng.integers(0, 256, (40, 50, 4)).astype(np.uint8)
    data[:10, :, 3], data[10:20, :, 3] = 255, 0
    assert np.array_equal(unpremultiply(data[::-1]), _old_unpremultiply(data[::-1]))


def test_vertex_normals_of_another_topology_are_not_the_cached_ones():
    rng = np.random.default_rng(7)
    verts = rng.standard_normal((2, 30, 3))
    faces = rng.integers(0, 30, (40, 3))
    first = vertex_normals(verts, faces)
    again = vertex_normals(verts, faces.copy().astype(np.int32))  # the same topology read again: the same normals
    assert np.array_equal(first, again)
    other = np.roll(faces, 1, axis=0)[:, ::-1].copy()  # same shape, other faces
    fresh = vertex_normals(verts, other)
    assert not np.allclose(fresh, first)
    kept = faces.copy()
    faces[:] = 0  # the caller's array changing later does not change what was kept
    assert np.array_equal(vertex_normals(verts, kept), first)
    assert np.array_equal(vertex_normals(verts, other), fresh)


def test_row_blocks_give_an_empty_first_frame_its_empty_arrays():
    """A clip whose first frame has no one: rows [0, 0) are empty arrays of the block's shapes (it was a KeyError)."""
    from rotavat_cli.formats.row_blocks import RowBlocks

    blocks = RowBlocks(4, lambda a, b: {"x": np.arange(a, b, dtype=np.float32)[:, None] * np.ones((1, 3))}, 2)
    empty = blocks.rows(0, 0)
    assert empty["x"].shape == (0, 3) and empty["x"].dtype == np.float64
    assert blocks.rows(0, 2)["x"][:, 0].tolist() == [0.0, 1.0]
    assert RowBlocks(0, lambda a, b: {"x": np.zeros((b - a, 3))}, 8).rows(0, 0)["x"].shape == (0, 3)
