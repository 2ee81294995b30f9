"""Shared fixtures: small hand-made sequences and a CLI runner (tests/_cli.py runs the CLI in-process)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner


@pytest.fixture(scope="session")
def runner() -> CliRunner:
    """typer's test runner (it keeps no state between runs): ``_cli.invoke(runner, ARGS)``."""
    return CliRunner()


def tree_hash(path: Path) -> str:
    """Hash of every file's path and bytes under ``path`` (to prove inputs are untouched)."""
    h = hashlib.sha256()
    for p in sorted(path.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(path)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def tetra_frame(rng: np.random.Generator, P: int, dtype=np.float32) -> dict:
    """A frame of P tetrahedra with joints, 2D points and ids."""
    base = np.array([[0, 0, 0], [0.3, 0, 0], [0, -1.7, 0], [0, 0, 0.3]], dtype=np.float64)
    offsets = np.stack([rng.uniform(-2, 2, P), rng.uniform(0, 1, P), rng.uniform(5, 12, P)], axis=-1)
    verts = (base[None] + offsets[:, None]).astype(dtype)
    return {
        "vertices": verts,
        "faces": np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]], dtype=np.int32),
        "joints": verts[:, :3].copy(),
        "feet_2d": rng.uniform(0, 640, (P, 2)),
        "heads_2d": rng.uniform(0, 480, (P, 2)),
        "person_ids": np.arange(P, dtype=np.int64) + 10,
    }


@pytest.fixture
def npz_seq(tmp_path: Path) -> Path:
    """A 3-frame npz sequence (one frame empty) with meta.yaml."""
    rng = np.random.default_rng(0)
    seq = tmp_path / "seq"
    seq.mkdir()
    for i, P in enumerate([3, 0, 2]):
        data = tetra_frame(rng, P)
        if P == 0:
            data["vertices"] = np.zeros((0, 4, 3), np.float32)
        np.savez(seq / f"{i:06d}.npz", **data)
    (seq / "meta.yaml").write_text("image_size: [640, 480]\nfocal_length: 500.0\nsource: test\n")
    return seq
