"""Issue 34's faster paths give what the plain ones gave: the .npz reader, calibrate's parallel reading and the
tolerance of large fits, align's chunks, ordered_map's ``meanwhile``. No timing is asserted here: speed is
``make bench``'s (benchmarks/bench_floors.py, bench_align.py)."""

from __future__ import annotations

import dataclasses
import zipfile

import numpy as np
import pytest

from _synthetic_pairs import synthetic_pairs
from rotavat_cli.alignment import align as A
from rotavat_cli.alignment.options import AlignOptions
from rotavat_cli.calibration import CalibrateOptions, fit_camera
from rotavat_cli.calibration import pairs as pairs_module
from rotavat_cli.calibration import refine
from rotavat_cli.calibration.pairs import gather_pairs
from rotavat_cli.errors import InputError
from rotavat_cli.parallel import ordered_map
from rotavat_cli.sequence import open_sequence
from rotavat_cli.unpickle import npy as npy_module
from rotavat_cli.unpickle.npz import load_npz


# ---- the .npz reader ---------------------------------------------------------------------------------------------
def test_each_member_header_is_read_once(tmp_path, monkeypatch):
    path = tmp_path / "f.npz"
    np.savez(path, a=np.arange(6.0).reshape(2, 3), b=np.array([1, 2], np.int64), c=np.zeros((0, 3), np.float32))
    reads = []
    original = npy_module.read_npy_header

    def counted(stream, source):
        reads.append(source)
        return original(stream, source)
    monkeypatch.setattr("rotavat_cli.unpickle.npz.read_npy_header", counted)
    data = load_npz(path)
    assert sorted(reads) == sorted(f"{path} ['{k}']" for k in "abc")  # once each (it was twice)
    with np.load(path) as npz:
        for key in "abc":
            assert data[key].dtype == npz[key].dtype and np.array_equal(data[key], npz[key])


def test_a_file_that_is_not_a_zip_is_named_so_and_a_broken_zip_otherwise(tmp_path):
    text = tmp_path / "text.npz"
    text.write_bytes(b"not a zip at all" * 8)
    with pytest.raises(InputError, match=r"text.npz: not a valid .npz file \(not a zip archive\)"):
        load_npz(text)
    good = tmp_path / "good.npz"
    np.savez(good, a=np.arange(3))
    raw = good.read_bytes()
    directory = raw.rfind(b"PK\x01\x02")  # the central directory's first entry, its signature spoiled
    broken = tmp_path / "broken.npz"
    broken.write_bytes(raw[:directory] + b"XX\x01\x02" + raw[directory + 4:])
    with pytest.raises(InputError, match=r"broken.npz: not a readable .npz file"):
        load_npz(broken)
    folder = tmp_path / "folder.npz"
    folder.mkdir()
    with pytest.raises(InputError, match="expected a .npz file"):
        load_npz(folder)
    with pytest.raises(InputError, match="file not found"):
        load_npz(tmp_path / "absent.npz")
    assert zipfile.is_zipfile(good)


def test_a_refused_member_leaves_no_member_read(tmp_path, monkeypatch):
    """Every member is checked before any is read: a truncated second member refuses the file before the first's data."""
    path = tmp_path / "f.npz"
    np.savez(path, a=np.arange(4.0), b=np.arange(5.0))
    with zipfile.ZipFile(path) as z:
        a, b = z.read("a.npy"), z.read("b.npy")
    bad = tmp_path / "bad.npz"
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("a.npy", a)
        z.writestr("b.npy", b[:-8])  # its header declares 40 bytes, 32 follow
    data_reads = []
    original = npy_module.read_npy_data
    monkeypatch.setattr("rotavat_cli.unpickle.npz.read_npy_data",
                        lambda *args: data_reads.append(args[3]) or original(*args))
    with pytest.raises(InputError, match="corrupt or truncated"):
        load_npz(bad)
    assert data_reads == []


# ---- calibrate: the frames read by workers -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def long_pairs(tmp_path_factory):
    """A 2D sequence long enough to be read by worker processes (900 frames x 3 walkers, 10% outliers)."""
    data = synthetic_pairs(np.random.default_rng(5), frames=900, people=3, outlier_fraction=0.1)
    folder = tmp_path_factory.mktemp("long_pairs")
    for t in range(900):
        sel = data.frame_index == t
        ids = data.track_id[sel] if t % 7 else np.arange(sel.sum()) + 100  # some frames with other ids
        np.savez(folder / f"{t:06d}.npz", feet_2d=data.feet_px[sel], heads_2d=data.heads_px[sel], person_ids=ids)
    width, height = data.camera.image_size
    (folder / "meta.yaml").write_text(f"image_size: [{width}, {height}]\n")
    return folder


def test_pairs_read_by_workers_equal_pairs_read_here(long_pairs, monkeypatch):
    seq = open_sequence(long_pairs)
    called = []
    parallel = gather_pairs(seq, meanwhile=lambda: called.append("meanwhile"))
    monkeypatch.setattr(pairs_module, "_PARALLEL_MIN_FRAMES", 10**9)  # every frame read in this process
    inline = gather_pairs(seq, meanwhile=lambda: called.append("meanwhile"))
    assert called == ["meanwhile", "meanwhile"]  # once each way
    for field in dataclasses.fields(parallel):
        a, b = getattr(parallel, field.name), getattr(inline, field.name)
        assert (np.array_equal(a, b, equal_nan=a.dtype.kind == "f") if isinstance(a, np.ndarray) else a == b), field.name
    assert len(parallel.feet_px) > 2000 and parallel.n_frames == 900


def test_a_bad_frame_read_by_a_worker_is_named(long_pairs, tmp_path):
    import shutil

    copy = tmp_path / "seq"
    shutil.copytree(long_pairs, copy)
    (copy / "000601.npz").write_bytes(b"junk")
    with pytest.raises(InputError, match="000601.npz: not a valid .npz file"):
        gather_pairs(open_sequence(copy))


def test_ordered_map_runs_meanwhile_once_before_the_results():
    order = []
    results = ordered_map(lambda x: x * 2, range(9), workers=2, meanwhile=lambda: order.append("meanwhile"))
    for value in results:
        order.append(value)
    assert order == ["meanwhile", *range(0, 18, 2)]
    order.clear()
    for value in ordered_map(lambda x: x + 1, [1, 2], workers=1, meanwhile=lambda: order.append("meanwhile")):
        order.append(value)
    assert order == ["meanwhile", 2, 3]


def test_a_large_fit_stops_within_a_hundredth_of_its_std_of_the_tight_one(monkeypatch):
    """Over MANY_PAIRS pairs the fit's tolerance is 1e-6 (relative): the camera it gives is the 1e-10 fit's to far
    below its std."""
    data = synthetic_pairs(np.random.default_rng(8), frames=700, people=8, outlier_fraction=0.1)
    assert len(data.feet_px) > refine.MANY_PAIRS
    kwargs = dict(frame_index=data.frame_index, track_id=data.track_id)
    loose = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, CalibrateOptions(), **kwargs)
    monkeypatch.setattr(refine, "_TOL_MANY", refine._TOL)
    tight = fit_camera(data.feet_px, data.heads_px, data.camera.image_size, CalibrateOptions(), **kwargs)
    for key, value in (("focal_px", "focal_px"), ("pitch_rad", "pitch_deg"), ("height_m", "height_m")):
        shift = getattr(loose.camera, key) - getattr(tight.camera, key)
        if key == "pitch_rad":
            shift = np.degrees(shift)
        assert abs(shift) < 1e-2 * tight.std[value], (key, shift, tight.std[value])


# ---- align: a chunk's people at once -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    out = tmp_path_factory.mktemp("scene")
    write_synth_scene(out, SynthOptions(seed=3, frames=6, people=5))
    return out


def test_a_chunk_aligned_at_once_equals_each_frame_alone(scene):
    seq = open_sequence(scene / "pred")
    camera = open_sequence(scene / "gt").camera
    frames = [seq.read_frame(name) for name in seq.frame_names]
    frames[2] = frames[2].replace(**{k: v[:0] for k, v in frames[2].data.items()
                                     if k in ("vertices", "joints", "person_ids", "feet_2d", "heads_2d")})  # nobody
    frames[4] = frames[4].replace(**{k: v[:2] for k, v in frames[4].data.items()
                                     if k in ("vertices", "joints", "person_ids", "feet_2d", "heads_2d")})  # two people
    frames[5] = frames[5].replace(**{k: v[:1] for k, v in frames[5].data.items()
                                     if k in ("vertices", "joints", "person_ids", "feet_2d", "heads_2d")})  # one person
    elevations = [None] * len(frames)
    elevations[3] = np.where(np.arange(frames[3].n_people) == 1, 0.4, np.nan)  # one person in the air
    statures = {int(i): 1.6 + 0.05 * k for k, i in enumerate(frames[0].person_ids)}
    options = AlignOptions()
    intrinsics = [seq.frame_intrinsics(frame) for frame in frames]
    together = A._align_frames(frames, camera, options, statures, intrinsics, seq.joints_layout, elevations, "prior")
    for k, frame in enumerate(frames):
        alone = A.align_frame(frame, camera, options, statures, intrinsics[k], seq.joints_layout, elevations[k], "prior")
        assert set(alone[0].data) == set(together[k][0].data)
        for key, value in alone[0].data.items():
            assert np.array_equal(value, together[k][0].data[key], equal_nan=value.dtype.kind == "f"), (k, key)
        for key, value in alone[1].items():
            other = together[k][1][key]
            assert value.dtype == other.dtype and (np.array_equal(value, other, equal_nan=value.dtype.kind == "f")
                                                   if value.dtype.kind != "O" else list(value) == list(other)), (k, key)
    assert together[2][1]["flag"].size == 0 and together[3][1]["flag"][1] == "flight"


# ---- calibrate: the paper grid's pruning, the threads ----------------------------------------------------------------
@pytest.fixture(scope="module")
def many_pairs():
    return synthetic_pairs(np.random.default_rng(12), frames=300, people=10, outlier_fraction=0.1)


def test_the_pruned_paper_grid_finds_the_unpruned_best_cell(many_pairs, monkeypatch):
    from rotavat_cli.calibration import grid as G

    data, spec = many_pairs, G.GridSpec()
    width, height = data.camera.image_size
    args = (data.feet_px, data.heads_px, (width / 2, height / 2), spec.focal_values_px(height),
            spec.pitch_values_rad(), spec.height_values_m(), 1.7)
    assert len(data.feet_px) >= G._PRUNE_MIN_PAIRS
    pruned = G.paper_grid_search(*args)
    monkeypatch.setattr(G, "_PRUNE_MIN_PAIRS", 10**9)
    full = G.paper_grid_search(*args)
    assert (pruned.index, pruned.cost, pruned.focal_px, pruned.height_m) == (full.index, full.cost, full.focal_px,
                                                                             full.height_m)
    scored = np.isfinite(pruned.costs)
    assert scored.sum() < 0.2 * np.isfinite(full.costs).sum()  # most valid cells were never scored in full
    assert np.array_equal(pruned.costs[scored], full.costs[scored])  # the scored ones as the full scan scores them


def test_threads_give_the_same_seeding_grid_and_jacobian(many_pairs, monkeypatch):
    from rotavat_cli.calibration import grid as G
    from rotavat_cli.calibration import objective as O
    from rotavat_cli.calibration.params import to_internal
    from rotavat_cli.calibration.residuals import residual_kind

    data = many_pairs
    width, height = data.camera.image_size
    spec = G.GridSpec()
    robust = (data.feet_px[:700], data.heads_px[:700], (width / 2, height / 2), np.geomspace(200, 6000, 40),
              spec.pitch_values_rad(), np.geomspace(0.5, 40, 30), 1.7)
    threaded = G.robust_grid_costs(*robust)
    prob = O.make_problem(data.feet_px, data.heads_px, np.array([width / 2, height / 2]), 1.7, 0.07, 2.0,
                          residual_kind("full"), (width, height), None, data.track_id)
    params = np.array([1400.0, 0.35, 0.01, 6.0, 0.0, 0.0])
    free = np.array([True, True, True, True, False, False])
    x = to_internal(params)[free]
    r0 = O.residual_at(prob, x, params, free, 1.2, "cauchy", 2.0)
    monkeypatch.setattr(O, "_THREAD_ROWS", 0)  # the parameter sets on two threads whatever the size
    jac_threads = O.jacobian_at(prob, x, r0, params, free, 1.2, "cauchy", 2.0)
    monkeypatch.setattr(G, "_workers", lambda *args: 1)
    monkeypatch.setattr(O, "_THREAD_ROWS", 10**12)
    assert np.array_equal(threaded, G.robust_grid_costs(*robust))
    assert np.array_equal(jac_threads, O.jacobian_at(prob, x, r0, params, free, 1.2, "cauchy", 2.0))


def test_a_persons_transform_does_not_depend_on_who_else_is_computed():
    """numpy's matrix-vector product rounds a lone row by another kernel: one person alone, or among 63 others (a
    chunk of frames), gets the same transform to the last bit."""
    from rotavat_cli.alignment.transform import rotavat_transforms

    rng = np.random.default_rng(3)
    feet = np.column_stack([rng.uniform(-3, 3, 64), rng.uniform(1.0, 2.0, 64), rng.uniform(4, 15, 64)])
    heads = feet + np.column_stack([rng.normal(0, 0.1, 64), rng.uniform(-1.8, -1.5, 64), rng.normal(0, 0.1, 64)])
    up = np.array([0.0, -0.95, -0.3]) / np.linalg.norm([0.0, -0.95, -0.3])
    together = rotavat_transforms(feet, heads, up, 4.0, foot_rays_cam=feet * 1.01, head_rays_cam=heads * 0.99)
    for i in range(64):
        alone = rotavat_transforms(feet[i:i + 1], heads[i:i + 1], up, 4.0, foot_rays_cam=feet[i:i + 1] * 1.01,
                                   head_rays_cam=heads[i:i + 1] * 0.99)
        for field in dataclasses.fields(alone):
            assert np.array_equal(getattr(alone, field.name), getattr(together, field.name)[i:i + 1]), (i, field.name)
