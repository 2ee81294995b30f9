"""Synthetic body-model files in the layouts of SMPL (24 joints), SMPL-X (55) and SMPL-H (52), so no
licensed model is needed. All are built on the packaged body mesh 0 (``rotavat_cli/data/bodies.npz``).

The session's shared model files and scenes are pytest fixtures in ``conftest.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rotavat_cli.formats.smpl import SMPL_PARENTS
from rotavat_cli.synth.bodies import BODIES_PATH

# SMPL-X's kinematic tree (vchoutas/smplx, the official model files): body 0-21 as SMPL, jaw 22 and
# eyes 23-24 on the head (15), 15 joints per hand on the wrists (20, 21): index, middle, pinky, ring,
# thumb, three deep.
SMPLX_PARENTS = SMPL_PARENTS[:22] + (15, 15, 15) + tuple(
    p for wrist in (20, 21) for f in range(5) for p in (wrist, 25 + 15 * (wrist - 20) + 3 * f, 26 + 15 * (wrist - 20) + 3 * f))


def _hand_parents(wrist: int, first: int) -> list[int]:
    """SMPL-H's 15 joints of one hand: five fingers (index, middle, pinky, ring, thumb) of three joints
    each, every finger's first joint a child of the wrist (smplx joint_names.py SMPLH_JOINT_NAMES)."""
    parents = []
    for finger in range(5):
        base = first + 3 * finger
        parents += [wrist, base, base + 1]
    return parents


SMPLH_PARENTS = tuple(SMPL_PARENTS[:22]) + tuple(_hand_parents(20, 22)) + tuple(_hand_parents(21, 37))


def _body_mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The packaged body 0: vertices (V, 3) and SMPL joints (24, 3) in metres (float64), faces (F, 3)."""
    with np.load(BODIES_PATH, allow_pickle=False) as bodies:
        return (bodies["vertices"][0].astype(np.float64), bodies["joints"][0].astype(np.float64),
                bodies["faces"].astype(np.int64))


def _nearest_skinning(verts: np.ndarray, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J_regressor (J, V): the mean of the 6 vertices nearest each joint; weights (V, J): each vertex
    on its nearest joint, one-hot."""
    dist = np.linalg.norm(verts[:, None] - joints[None], axis=-1)  # (V, J)
    regressor = np.zeros((len(joints), len(verts)))
    for j in range(len(joints)):
        regressor[j, np.argsort(dist[:, j])[:6]] = 1.0 / 6.0
    weights = np.zeros((len(verts), len(joints)))
    weights[np.arange(len(verts)), dist.argmin(axis=1)] = 1.0
    return regressor, weights


def _kintree(parents: tuple[int, ...]) -> np.ndarray:
    """The model files' (2, J) uint32 kintree_table: parents (the root's 2**32 - 1), then the joint indices."""
    return np.array([[4294967295, *parents[1:]], list(range(len(parents)))], dtype=np.uint32)


def _savez(compress: bool):
    """``np.savez_compressed`` (members deflated) or ``np.savez`` (stored)."""
    return np.savez_compressed if compress else np.savez


def write_synthetic_smpl(path: Path, n_betas: int = 10, seed: int = 0, dtype=np.float32,
                         compress: bool = True) -> Path:
    """An SMPL-layout .npz (24 joints, SMPL kinematic tree) built on the packaged body mesh 0, its
    members deflated (``np.savez_compressed``: 1 MB) or, ``compress=False``, stored (``np.savez``: 17 MB,
    read in half the time).

    J_regressor: mean of the 6 vertices nearest each body joint; weights: nearest joint, one-hot;
    shapedirs: smooth random fields; posedirs: random in the first 9 columns only.
    """
    rng = np.random.default_rng(seed)
    verts, joints, faces = _body_mesh()
    regressor, weights = _nearest_skinning(verts, joints)
    n_verts = len(verts)
    shapedirs = 0.01 * np.sin(verts[:, :, None] * rng.uniform(1, 4, (1, 3, n_betas)) + rng.uniform(0, 6, (1, 3, n_betas)))
    posedirs = np.zeros((n_verts, 3, 207))
    posedirs[:, :, :9] = 0.002 * rng.standard_normal((n_verts, 3, 9))
    _savez(compress)(path, v_template=verts.astype(dtype), shapedirs=shapedirs.astype(dtype),
                     posedirs=posedirs.astype(dtype), J_regressor=regressor.astype(dtype),
                     weights=weights.astype(dtype), kintree_table=_kintree(SMPL_PARENTS), f=faces.astype(np.uint32))
    return path


def write_synthetic_smplx(path: Path, n_betas: int = 10, seed: int = 1) -> Path:
    """An SMPL-X-layout .npz (55 joints, SMPL-X kinematic tree) on the packaged body mesh 0, with joints
    of its own (PyMAF-X's tests).

    Joints 0-21 sit where the SMPL synthetic model has them; face joints 1-3 cm off the head joint,
    hand joints 2-6 cm along each forearm past the wrist. J_regressor: mean of the 6 vertices nearest
    each joint; weights: nearest joint, one-hot; no pose correctives (rigid poses are exact).
    """
    rng = np.random.default_rng(seed)
    verts, body, faces = _body_mesh()
    joints = np.zeros((55, 3))
    joints[:22] = body[:22]
    joints[22:25] = body[15] + np.array([[0, -0.02, 0.03], [0.02, 0.01, 0.03], [-0.02, 0.01, 0.03]])
    for wrist, elbow, first in ((20, 18, 25), (21, 19, 40)):
        along = (body[wrist] - body[elbow]) / np.linalg.norm(body[wrist] - body[elbow])
        for k in range(15):
            joints[first + k] = body[wrist] + along * (0.02 + 0.02 * (k % 3)) + 0.005 * (k // 3) * np.array([0, 0, 1.0])
    regressor, weights = _nearest_skinning(verts, joints)
    phases = rng.uniform(1, 4, (1, 3, n_betas)), rng.uniform(0, 6, (1, 3, n_betas))
    shapedirs = 0.01 * np.sin(verts[:, :, None] * phases[0] + phases[1])
    np.savez_compressed(path, v_template=verts.astype(np.float32), shapedirs=shapedirs.astype(np.float32),
                        posedirs=np.zeros((len(verts), 3, 9 * 54), np.float32), J_regressor=regressor.astype(np.float32),
                        weights=weights.astype(np.float32), kintree_table=_kintree(SMPLX_PARENTS),
                        f=faces.astype(np.uint32))
    return path


def write_smplx_on_smpl(path: Path, smpl_path: Path, compress: bool = True) -> Path:
    """An SMPL-X-layout .npz (55 joints) on the synthetic SMPL model of ``smpl_path``: the same mesh,
    shape space and body joints 0-21; SMPL's hand joints become SMPL-X 28 / 43 (the middle fingers'
    first joints, which rotavat maps back to SMPL's hands), the other new joints copy the head or
    wrists. Posing with a zero body pose gives the SMPL model's mesh and joints exactly. Deflated, or
    stored (``compress=False``: 40 MB, read in a third of the time)."""
    with np.load(smpl_path, allow_pickle=False) as smpl:
        arrays = dict(smpl)
    reg24, w24 = arrays["J_regressor"], arrays["weights"]
    source = [15] * 3 + [20] * 15 + [21] * 15  # joints 22..54 copy these SMPL rows
    source[28 - 22], source[43 - 22] = 22, 23
    regressor = np.concatenate([reg24[:22], reg24[source]])
    weights = np.zeros((len(w24), 55), w24.dtype)
    weights[:, :22] = w24[:, :22]
    weights[:, 28] += w24[:, 22]  # SMPL's hand columns move to the middle fingers' first joints
    weights[:, 43] += w24[:, 23]
    posedirs = np.zeros((len(w24), 3, 9 * 54), np.float32)
    _savez(compress)(path, v_template=arrays["v_template"], shapedirs=arrays["shapedirs"], posedirs=posedirs,
                     J_regressor=regressor.astype(np.float32), weights=weights, kintree_table=_kintree(SMPLX_PARENTS),
                     f=arrays["f"])
    return path


def write_synthetic_smplh(path: Path, smpl_path: Path) -> Path:
    """An SMPL-H-layout .npz (52 joints, 16 betas) with the synthetic SMPL body of ``smpl_path``.

    Body joints 0-21 are SMPL's; every finger joint rests at SMPL's hand joint of its side (22 / 23),
    and the vertices SMPL skins to its hand joints follow the middle finger's first joint (25 / 40),
    so a body at rest is the same mesh as with the SMPL file.
    """
    with np.load(smpl_path, allow_pickle=False) as smpl:
        d = {k: smpl[k] for k in smpl.files}
    n_verts = d["v_template"].shape[0]
    regressor = np.concatenate([d["J_regressor"][:22], np.repeat(d["J_regressor"][22:23], 15, axis=0),
                                np.repeat(d["J_regressor"][23:24], 15, axis=0)])
    weights = np.zeros((n_verts, 52), d["weights"].dtype)
    weights[:, :22] = d["weights"][:, :22]
    weights[:, 25], weights[:, 40] = d["weights"][:, 22], d["weights"][:, 23]
    shapedirs = np.concatenate([d["shapedirs"], np.zeros((n_verts, 3, 6), d["shapedirs"].dtype)], axis=2)
    posedirs = np.zeros((n_verts, 3, 9 * 51), d["posedirs"].dtype)
    posedirs[:, :, :9 * 21] = d["posedirs"][:, :, :9 * 21]
    np.savez_compressed(path, v_template=d["v_template"], shapedirs=shapedirs, posedirs=posedirs,
                        J_regressor=regressor, weights=weights, kintree_table=_kintree(SMPLH_PARENTS), f=d["f"])
    return path


def write_moved_model(path: Path, model_path: Path, shift_m) -> Path:
    """The model file of ``model_path`` with its template (so its joints too) moved by ``shift_m`` (3,) m in
    the model's own frame (Y up): a body posed with it lands ``shift_m`` away from where the model file of
    ``model_path`` puts it, whatever the pose (``global_orient`` turns about the moved pelvis, ``transl``
    adds to it). A deliberately mismatched model: rotavat's synthetic bodies stand on their soles at the
    origin (pelvis 0.94 m above it), SMPL-X's pelvis rests 0.35 m below its origin, so the synthetic SMPL-X
    stand-in is a real SMPL-X moved by about ``(0, 1.3, 0)``: its meshes land 1.3 m low (issue 31)."""
    with np.load(model_path, allow_pickle=False) as model:
        arrays = dict(model)
    arrays["v_template"] = (arrays["v_template"] + np.asarray(shift_m, np.float64)).astype(arrays["v_template"].dtype)
    np.savez(path, **arrays)
    return path
