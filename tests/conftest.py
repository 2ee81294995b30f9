"""Shared fixtures: a CLI runner (tests/_cli.py runs the CLI in-process), the session's synthetic body
models and format scenes (built once per test process), and small hand-made sequences."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

# pytest-xdist runs one worker per core (make test: -n auto): each worker's BLAS keeps to one thread, as
# rotavat's own pool workers do (rotavat_cli/batch/executors.py), instead of one per core in every worker,
# spinning against each other (a fifth of make test's CPU time). Before numpy is first imported.
if "PYTEST_XDIST_WORKER" in os.environ:
    for _key in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_key, "1")

import _body_models as B  # noqa: E402
import _format_fixtures as F  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from typer.testing import CliRunner  # noqa: E402


@pytest.fixture(scope="session")
def runner() -> CliRunner:
    """typer's test runner (it keeps no state between runs): ``_cli.invoke(runner, ARGS)``."""
    return CliRunner()


# ---- synthetic body models and the formats' scene (tests/_body_models.py, tests/_format_fixtures.py) ---
@pytest.fixture(scope="session")
def model_path(tmp_path_factory) -> Path:
    """The synthetic SMPL-layout model file. Stored, not deflated: each import and --from run loads it,
    in half the time (the deflated form is read by the SMPL-H and PyMAF-X models' tests)."""
    return B.write_synthetic_smpl(tmp_path_factory.mktemp("models") / "SMPL_SYNTH.npz", compress=False)


@pytest.fixture(scope="session")
def model(model_path):
    """The synthetic SMPL model, loaded."""
    return F.load_model(model_path)


@pytest.fixture(scope="session")
def smplx_on_smpl_path(model_path) -> Path:
    """The synthetic SMPL-X-layout model on the SMPL model's mesh (GVHMR's parameters need SMPL-X); stored."""
    return B.write_smplx_on_smpl(model_path.with_name("SMPLX_SYNTH.npz"), model_path, compress=False)


@pytest.fixture(scope="session")
def smplh_path(model_path) -> Path:
    """The synthetic SMPL-H-layout model on the SMPL model's body (SLAHMR's and GLAMR's parameters)."""
    return B.write_synthetic_smplh(model_path.with_name("SMPLH_SYNTH.npz"), model_path)


@pytest.fixture(scope="session")
def camera():
    """The formats' scene camera: 640x480, 500 px, 15 deg down, 3 m high."""
    return F.scene_camera((F.W, F.H), 500.0)


@pytest.fixture(scope="session")
def scene(model, camera):
    """:func:`_format_fixtures.default_scene`: tracks 3 and 5, then 3 alone, then nobody (read-only)."""
    return _read_only(F.default_scene(model, camera))


@pytest.fixture(scope="session")
def bev_scene(model):
    """:func:`_format_fixtures.bev_scene`: 6 frames of 5 people in front of BEV's camera, seed 3 (read-only)."""
    return _read_only(F.bev_scene(model, 6, 5))


def _read_only(frames: list) -> list:
    """A scene the session shares, its arrays made read-only (a test that changed them would change the
    other tests' scene)."""
    for person in (p for frame in frames for p in frame):
        for array in (person.pose, person.betas, person.transl, person.verts_cam, person.joints_cam):
            array.flags.writeable = False
    return frames


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
