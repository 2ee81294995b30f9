"""Body-model parameters through import and align: posing the model with the aligned frame's world (or
camera) parameters reproduces its vertices (docs/conventions.md, "Body-model parameters")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rotavat_cli.alignment.align import align_sequence
from rotavat_cli.alignment.options import AlignOptions
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.errors import InputError
from rotavat_cli.formats.convert import import_sequence
from rotavat_cli.formats.smpl import lbs, load_body_model, pose_from_body, smpl_param_arrays
from rotavat_cli.geometry.rotations import matrix_to_axis_angle
from rotavat_cli.sequence import SMPL_PARAM_KEYS, WORLD_PARAM_KEYS, open_sequence, validate_frame, write_meta

CAMERA = Camera((1280, 720), 1000.0, None, np.deg2rad(12.0), np.deg2rad(2.0), 3.5)
HPS_FOCAL_PX = 1600.0  # the focal the "method" made its meshes with: people come out 1.6x too far


def posed_from(model, frame, orient_key: str, transl_key: str) -> np.ndarray:
    """The rule of the contract: pose with (betas, body_pose, orient, transl), scale about the pelvis."""
    pose = pose_from_body(frame[orient_key], frame["smpl_body_pose"], model.n_joints)
    verts, joints = lbs(model, frame["smpl_betas"], pose, frame[transl_key])
    pelvis = joints[:, :1]
    return pelvis + frame["smpl_scale"][:, None, None] * (verts - pelvis)


def people_in_view(model, rng, n_people: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Betas (P, 10), axis-angle pose (P, J, 3) and transl (P, 3) of people standing 8-14 m in front of
    :data:`CAMERA`, drawn as a method with :data:`HPS_FOCAL_PX` would: bodies upright in the world, a
    little bent at every joint, then carried to the method's depth."""
    P, J = n_people, model.n_joints
    betas = rng.normal(0.0, 1.0, (P, 10))
    pose = rng.normal(0.0, 0.15, (P, J, 3))
    # SMPL's rest body is Y up like the world: turned about the vertical, then seen by the camera
    yaw = rng.uniform(-np.pi, np.pi, P)
    c, s = np.cos(yaw), np.sin(yaw)
    R_yaw = np.stack([np.stack([c, 0 * c, s], -1), np.tile([0.0, 1.0, 0.0], (P, 1)), np.stack([-s, 0 * c, c], -1)], 1)
    pose[:, 0] = matrix_to_axis_angle(CAMERA.R_cam_from_world @ R_yaw)
    _, joints = lbs(model, betas, pose, None)
    ground_world = np.stack([rng.uniform(-1.5, 1.5, P), np.full(P, 0.95), -rng.uniform(8, 14, P)], axis=1)
    pelvis_cam = (ground_world @ CAMERA.R_cam_from_world.T + CAMERA.t_cam_from_world) * (HPS_FOCAL_PX / CAMERA.focal_px)
    transl = pelvis_cam - joints[:, 0]
    return betas, pose, transl


def write_param_sequence(folder: Path, model, n_frames: int = 3, n_people: int = 3, seed: int = 0) -> Path:
    """A sequence whose frames hold the people's vertices and body-model parameters (method's focal)."""
    rng = np.random.default_rng(seed)
    folder.mkdir()
    write_meta(folder, {"image_size": [1280, 720], "focal_length": HPS_FOCAL_PX})
    for index in range(n_frames):
        betas, pose, transl = people_in_view(model, rng, n_people)
        verts, joints = lbs(model, betas, pose, transl)
        np.savez(folder / f"{index:06d}.npz", vertices=verts.astype(np.float32), faces=model.faces,
                 person_ids=np.arange(n_people), **smpl_param_arrays(model, betas, pose, transl, joints))
    return folder


@pytest.mark.parametrize("kind", ["smpl", "smplx"])
def test_world_parameters_reproduce_the_aligned_vertices(tmp_path, model_path, smplx_on_smpl_path, kind):
    model = load_body_model(model_path if kind == "smpl" else smplx_on_smpl_path)
    seq_dir = write_param_sequence(tmp_path / "pred", model)
    align_sequence(open_sequence(seq_dir), CAMERA, tmp_path / "aligned", AlignOptions(jobs=1))
    aligned = open_sequence(tmp_path / "aligned")
    moved = 0
    for frame in aligned.frames():
        data = {k: np.asarray(v, dtype=np.float64) for k, v in frame.data.items()}
        assert set(SMPL_PARAM_KEYS + WORLD_PARAM_KEYS) <= set(data)
        verts_world = CAMERA.world_from_cam(data["vertices"])
        err_world = np.abs(posed_from(model, data, "world_global_orient", "world_transl") - verts_world).max()
        err_cam = np.abs(posed_from(model, data, "smpl_global_orient", "smpl_transl") - data["vertices"]).max()
        assert err_world < 1e-3 and err_cam < 1e-3  # within 1 mm (float32 vertices: ~1e-6 m)
        moved += int(np.sum(np.abs(data["smpl_scale"] - 1.0) > 0.01))
        # the world pelvis is where the contract's rule puts it: world_transl + (smpl_pelvis - smpl_transl)
        pelvis_world = data["world_transl"] + data["smpl_pelvis"] - data["smpl_transl"]
        assert np.allclose(pelvis_world, CAMERA.world_from_cam(data["smpl_pelvis"]), atol=1e-9)
    assert moved >= 6  # moved 1.6x nearer (the method's focal), turned upright and scaled back onto the crown ray


def test_flagged_people_keep_their_parameters_with_scale_one(tmp_path, model_path):
    """A person align leaves unchanged (here: cut by the image border) keeps the input's parameters, scale 1."""
    model = load_body_model(model_path)
    seq_dir = write_param_sequence(tmp_path / "pred", model, n_frames=1, n_people=2, seed=4)
    with np.load(seq_dir / "000000.npz") as npz:
        frame = dict(npz)
    frame["vertices"][1] += [40.0, 0.0, 0.0]  # person 1 far right, out of the image: cut by the border
    np.savez(seq_dir / "000000.npz", **frame)
    align_sequence(open_sequence(seq_dir), CAMERA, tmp_path / "aligned", AlignOptions(jobs=1))
    out = next(open_sequence(tmp_path / "aligned").frames()).data
    assert out["smpl_scale"][1] == 1.0 and out["smpl_scale"][0] != 1.0
    assert np.allclose(out["smpl_global_orient"][1], frame["smpl_global_orient"][1])
    assert np.allclose(out["smpl_transl"][1], frame["smpl_transl"][1])


def test_aligning_twice_composes_the_scale(tmp_path, model_path):
    model = load_body_model(model_path)
    seq_dir = write_param_sequence(tmp_path / "pred", model, n_frames=1)
    align_sequence(open_sequence(seq_dir), CAMERA, tmp_path / "once", AlignOptions(jobs=1))
    other = Camera((1280, 720), 1000.0, None, np.deg2rad(14.0), 0.0, 3.2)
    align_sequence(open_sequence(tmp_path / "once"), other, tmp_path / "twice", AlignOptions(jobs=1))
    data = {k: np.asarray(v, np.float64) for k, v in next(open_sequence(tmp_path / "twice").frames()).data.items()}
    assert np.abs(posed_from(model, data, "world_global_orient", "world_transl")
                  - other.world_from_cam(data["vertices"])).max() < 1e-3


def test_parameters_come_whole():
    params = {"smpl_global_orient": np.zeros((1, 3)), "smpl_betas": np.zeros((1, 10))}
    with pytest.raises(InputError, match="body-model parameters come together: .* but not smpl_body_pose"):
        validate_frame({"vertices": np.zeros((1, 4, 3)), **params}, "f.npz")
    whole = {k: np.zeros((1, 3)) for k in SMPL_PARAM_KEYS}
    with pytest.raises(InputError, match="come together"):
        validate_frame({**whole, "world_transl": np.zeros((1, 3))}, "f.npz")
    validate_frame({**whole, "smpl_scale": np.ones(1), "world_transl": np.zeros((1, 3)),
                    "world_global_orient": np.zeros((1, 3))}, "f.npz")


@pytest.mark.parametrize("fmt", ["cliff", "4dhumans", "tram", "hybrik", "bedlam"])
def test_imported_parameters_pose_the_imported_vertices(tmp_path, fmt, scene, model, camera, model_path):
    """The importers that pose the model keep its parameters: posing them gives the frame's meshes."""
    from test_formats import _as_the_tool_places_it, _import

    _, out, _ = _import(fmt, tmp_path, _as_the_tool_places_it(fmt, scene, camera), model, camera, model_path)
    seq = open_sequence(out)
    assert seq.meta["body_model"] == {"kind": "smpl", "file": model_path.name, "joints": 24}
    checked = 0
    for frame in seq.frames():
        if not frame.n_people:
            continue
        data = {k: np.asarray(v, np.float64) for k, v in frame.data.items()}
        pose = pose_from_body(data["smpl_global_orient"], data["smpl_body_pose"], model.n_joints)
        verts, joints = lbs(model, data["smpl_betas"], pose, data["smpl_transl"])
        assert np.abs(verts - data["vertices"]).max() < 1e-4  # float32 vertices up to 260 m away (4D-Humans)
        assert np.allclose(joints[:, 0], data["smpl_pelvis"], atol=1e-9)
        checked += frame.n_people
    assert checked == 3
