"""Issue 34 for the multi-person importers: 4D-Humans, CoMotion, PromptHMR, BEDLAM and CLIFF pose a clip's people a
block of rows at a time (:mod:`rotavat_cli.formats.row_blocks`: one ``lbs`` call per block, not one per frame), and
the frames are bit for bit those posed frame by frame, in any order of building them and whatever the block size.

Blocks of one row are the frame-by-frame posing these readers did before: a frame larger than a block is posed
whole (:class:`~rotavat_cli.formats.row_blocks.RowBlocks`), so each frame's people are posed together and alone."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

import _fixtures_comotion_prompthmr as CP
import _format_fixtures as F
from rotavat_cli.formats import import_sequence
from rotavat_cli.formats.imported import FrameNotes
from rotavat_cli.formats.read import read_format
from rotavat_cli.sequence import open_sequence

N_FRAMES = 20
IMAGE_SIZE = (F.W, F.H)


def _scene(model, camera, seed: int) -> list[list[F.Person]]:
    """N_FRAMES frames of up to 3 tracks coming and going (frames 0 and 7 empty), each person with a random body
    pose and shape (the pose and shape blend shapes at work)."""
    rng = np.random.default_rng(seed)

    def bent(person: F.Person) -> F.Person:
        return dataclasses.replace(person, pose=np.concatenate([person.pose[:1], 0.3 * rng.standard_normal((23, 3))]),
                                   betas=rng.standard_normal(10))

    return [[bent(F.standing_person(model, camera, k + np.sin(i / 4), -7.0 - k, k)) for k in range(3)
             if 3 * k <= i < N_FRAMES - 2 * k] if i not in (0, 7) else [] for i in range(N_FRAMES)]


def _write(fmt: str, tmp_path, model, camera, seed: int):
    """(source, reader module, read_format keywords, SMPL-X model wanted) of a clip of ``fmt``."""
    scene = _scene(model, camera, seed)
    rng = np.random.default_rng(seed + 1)
    if fmt == "4dhumans":  # frame 2 holds a track PHALP only carried on (tracked_time > 0: not posed)
        return F.write_phalp(tmp_path / "phalp.pkl", scene, IMAGE_SIZE), "fourdhumans", {}, False
    if fmt == "comotion":
        return (CP.write_comotion(tmp_path / "co" / "clip.pt", scene), "comotion", {"image_size": IMAGE_SIZE}, False)
    if fmt == "prompthmr":
        src = CP.write_prompthmr(tmp_path / "ph", scene, camera, IMAGE_SIZE,
                                 body_pose=0.3 * rng.standard_normal((N_FRAMES, 21, 3)))
        return src, "prompthmr", {}, True
    if fmt == "bedlam":
        return F.write_bedlam(tmp_path / "scene.npz", scene), "bedlam", {}, False
    pose_format = fmt.split("-")[1]  # cliff-aa, cliff-rotmat
    return (F.write_cliff(tmp_path / "cliff.npz", scene, IMAGE_SIZE, pose_format=pose_format), "cliff",
            {"image_size": IMAGE_SIZE}, False)


def _frames(imported, order) -> dict[int, dict[str, np.ndarray]]:
    out = {}
    for index in order:
        frame = imported.build(int(index), FrameNotes())
        out[int(index)] = {key: np.array(value) for key, value in frame.data.items()}
    return out


def _assert_same_frames(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for index in a:
        assert a[index].keys() == b[index].keys(), index
        for key in a[index]:
            assert a[index][key].dtype == b[index][key].dtype, (index, key)
            assert np.array_equal(a[index][key], b[index][key], equal_nan=True), (index, key)


@pytest.mark.parametrize("fmt", ["4dhumans", "comotion", "prompthmr", "bedlam", "cliff-aa", "cliff-rotmat"])
def test_frames_posed_in_blocks_equal_frames_posed_one_by_one(fmt, tmp_path, monkeypatch, model, model_path, camera,
                                                              smplx_on_smpl_path):
    src, module_name, kw, smplx = _write(fmt, tmp_path, model, camera, seed=40)
    module = importlib.import_module(f"rotavat_cli.formats.{module_name}")
    name, body_model = fmt.split("-")[0], smplx_on_smpl_path if smplx else model_path

    def read(block: int | None = None):
        with monkeypatch.context() as patch:
            if block is not None:
                patch.setattr(module, "posing_block_rows", lambda _model: block)
            return read_format(src, name, smpl_model=body_model, **kw)

    n_frames = read().n_frames
    one_by_one = _frames(read(1), range(n_frames))  # each frame's people posed together and alone
    counts = [len(f.get("vertices", ())) for f in one_by_one.values()]
    assert sum(counts) > n_frames and max(counts) == 3  # several people a frame
    assert fmt == "bedlam" or counts[0] == 0  # frames without anyone, the first one too (BEDLAM: rows make frames)
    shuffled = np.random.default_rng(41).permutation(n_frames)
    _assert_same_frames(one_by_one, _frames(read(), range(n_frames)))
    _assert_same_frames(one_by_one, _frames(read(), shuffled))
    _assert_same_frames(one_by_one, _frames(read(3), range(n_frames)))  # blocks straddling frames
    _assert_same_frames(one_by_one, _frames(read(3), shuffled.tolist() + [0, 0, n_frames - 1]))
    # what the import writes: the same arrays
    import_sequence(src, tmp_path / "out", name, smpl_model=body_model, **kw)
    written = {i: dict(frame.data) for i, frame in enumerate(open_sequence(tmp_path / "out").frames())}
    _assert_same_frames({i: {k: f[k] for k in written[i]} for i, f in one_by_one.items()}, written)


@pytest.mark.parametrize("fmt", ["4dhumans", "comotion", "prompthmr", "bedlam", "cliff-aa"])
def test_a_clip_is_posed_one_lbs_call_per_block(fmt, tmp_path, monkeypatch, model, model_path, camera,
                                                smplx_on_smpl_path):
    src, module_name, kw, smplx = _write(fmt, tmp_path, model, camera, seed=42)
    module = importlib.import_module(f"rotavat_cli.formats.{module_name}")
    calls: list[int] = []
    real_lbs = module.lbs

    def counted(body_model, betas, *args, **kwargs):
        calls.append(len(betas))
        return real_lbs(body_model, betas, *args, **kwargs)

    monkeypatch.setattr(module, "lbs", counted)
    monkeypatch.setattr(module, "posing_block_rows", lambda _model: 8)
    imported = read_format(src, fmt.split("-")[0], smpl_model=smplx_on_smpl_path if smplx else model_path, **kw)
    people = sum(len(frame.get("vertices", ())) for frame in _frames(imported, range(imported.n_frames)).values())
    # built in order, each block starts at a frame: a frame straddling a block's end (at most 3 people: 2 rows of it
    # in the block) is posed again as the next block's first, so each block adds at least 6 new rows
    blocks = [n for n in calls if n]  # an empty frame's zero rows cost nothing (lbs returns at once)
    assert people <= sum(blocks) <= people + 2 * len(blocks)
    assert len(blocks) <= -(-people // 6) and len(blocks) < imported.n_frames / 2
