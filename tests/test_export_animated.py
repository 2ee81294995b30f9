"""rotavat export of whole sequences: the animated glTF scene (per-frame meshes and skinned bodies), BVH and
AMASS, read back with real readers (pygltflib, trimesh, Blender when installed) and evaluated by hand."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib
import pytest
import trimesh
from _cli import invoke
from conftest import tree_hash
from scipy.spatial.transform import Rotation

from rotavat_cli.settings import limits
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.exchange import (R_AMASS_FROM_WORLD, BinLayout, GlbWriter, bvh_joint_positions, joint_names, json_chunk,
                                  read_bvh, rest_shape, skin_weights)
from rotavat_cli.exchange.animated import export_animated
from rotavat_cli.formats.smpl import BodyModel, lbs, load_body_model, pose_from_body
from rotavat_cli.files.outputs import written_by_rotavat
from rotavat_cli.render.export import world_from_gl_camera
from rotavat_cli.geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from rotavat_cli.sequence import open_sequence, write_camera_yaml, write_meta
from rotavat_cli.synth import SynthOptions, write_synth_scene

FPS = 10.0
SKIN_TOL_M = 1e-5  # float32 keyframes and rest mesh: the skin evaluates lbs to 0.2 um here; 10 um leaves room
POSITION_TOL_M = 1e-5  # float32 world vertices
# who is where in the parameter scene: track 1 comes at frame 2, track 2 leaves after frame 2
PRESENCE = np.array([[1, 0, 1], [1, 0, 1], [1, 1, 1], [1, 1, 0], [1, 1, 0]], dtype=bool)


# ---- scenes ------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def synth_scene(tmp_path_factory) -> Path:
    """rotavat synth's meshes: 4 frames x 3 people (gt/ with camera.yaml, 5 fps), no body-model parameters."""
    out = tmp_path_factory.mktemp("anim") / "scene"
    write_synth_scene(out, SynthOptions(seed=2, frames=4, people=3, image_size=(640, 360)))
    return out


@pytest.fixture(scope="module")
def leaving_scene(synth_scene, tmp_path_factory) -> Path:
    """The synth ground truth with person 1 gone from frames 2 and 3."""
    out = tmp_path_factory.mktemp("leave") / "gt"
    shutil.copytree(synth_scene / "gt", out)
    for name in ("000002", "000003"):
        with np.load(out / f"{name}.npz") as frame:
            data = dict(frame)
        keep = data["person_ids"] != 1
        np.savez(out / f"{name}.npz", **{k: v[keep] if k in ("vertices", "joints", "feet_2d", "heads_2d", "keypoints_2d",
                                                                    "person_ids") else v for k, v in data.items()})
    return out


def write_param_scene(out: Path, model_path: Path, presence: np.ndarray, seed: int = 0, fps: float | None = FPS) -> Camera:
    """An aligned-like sequence with body-model parameters (the posing rule of docs/conventions.md): each
    track (constant betas and scale) upright on the ground, turning and walking, posed by lbs in the camera
    frame and scaled about its pelvis; world keys computed from the same world root."""
    model = load_body_model(model_path)
    n_joints, n_pose = model.n_joints, 3 * (model.n_joints - 1)
    rng = np.random.default_rng(seed)
    cam = Camera((640, 360), 500.0, None, np.deg2rad(20.0), np.deg2rad(2.0), 4.0)
    n_tracks = presence.shape[1]
    betas = 0.5 * rng.standard_normal((n_tracks, 10))
    scale = 1.0 + 0.04 * np.arange(n_tracks)
    rest_root = lbs(model, betas, np.zeros((n_tracks, n_joints, 3)))[1][:, 0]  # J0(betas)
    out.mkdir(parents=True)
    for t, row in enumerate(presence):
        ids = np.flatnonzero(row)
        yaw = 0.3 * t + ids
        root_world = np.stack([axis_angle_to_matrix(np.array([0.0, 1.0, 0.0]), y) for y in yaw])
        body_pose = 0.3 * np.sin(t + np.arange(n_pose)[None] + ids[:, None]) * rng.uniform(0.5, 1.0, (len(ids), n_pose))
        ground = np.stack([-1.5 + 1.5 * ids + 0.1 * t, np.zeros(len(ids)), -8.0 + 0.05 * t * ids], axis=1)
        pelvis_world = ground + np.outer(scale[ids] * rest_root[ids, 1], [0.0, 1.0, 0.0])
        root_cam = cam.R_cam_from_world @ root_world
        pelvis_cam = cam.cam_from_world(pelvis_world)
        transl_cam = pelvis_cam - rest_root[ids]
        verts, joints = lbs(model, betas[ids], pose_from_body(matrix_to_axis_angle(root_cam), body_pose, n_joints), transl_cam)
        s = scale[ids][:, None, None]
        data = {"vertices": (pelvis_cam[:, None] + s * (verts - pelvis_cam[:, None])).astype(np.float32),
                "joints": (pelvis_cam[:, None] + s * (joints - pelvis_cam[:, None])).astype(np.float32),
                "faces": model.faces.astype(np.int32), "person_ids": ids.astype(np.int64),
                "smpl_global_orient": matrix_to_axis_angle(root_cam), "smpl_body_pose": body_pose,
                "smpl_betas": betas[ids], "smpl_transl": transl_cam, "smpl_pelvis": pelvis_cam, "smpl_scale": scale[ids],
                "world_global_orient": matrix_to_axis_angle(root_world), "world_transl": pelvis_world - rest_root[ids]}
        np.savez(out / f"{t:06d}.npz", **data)
    write_camera_yaml(out / "camera.yaml", cam)
    meta = {"image_size": [640, 360], "focal_length": 500.0, "focal_kind": "camera",
            "body_model": {"kind": model.kind, "file": model_path.name, "joints": n_joints}}
    write_meta(out, meta if fps is None else {**meta, "fps": fps})
    return cam


@pytest.fixture(scope="module")
def neutral_model(tmp_path_factory, model_path) -> Path:
    """The synthetic SMPL model under an official-looking name (AMASS's gender comes from it)."""
    path = tmp_path_factory.mktemp("neutral") / "SMPL_NEUTRAL.npz"
    shutil.copy(model_path, path)
    return path


@pytest.fixture(scope="module")
def param_scene(tmp_path_factory, neutral_model) -> Path:
    out = tmp_path_factory.mktemp("params") / "aligned"
    write_param_scene(out, neutral_model, PRESENCE)
    return out


# ---- reading a glTF back by hand ---------------------------------------------------------------------------
def load_gltf(path: Path) -> tuple[pygltflib.GLTF2, bytes]:
    gltf = pygltflib.GLTF2().load(str(path))
    return gltf, gltf.binary_blob()


def accessor_array(gltf: pygltflib.GLTF2, blob: bytes, index: int) -> np.ndarray:
    """An accessor's elements (count, width), or (count,) for scalars."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    dtype = {5126: np.float32, 5121: np.uint8, 5123: np.uint16, 5125: np.uint32}[acc.componentType]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    stride = view.byteStride or width * np.dtype(dtype).itemsize
    rows = np.lib.stride_tricks.as_strided(np.frombuffer(blob, dtype, offset=start, count=(acc.count - 1) * stride // np.dtype(dtype).itemsize + width),
                                           (acc.count, width), (stride, np.dtype(dtype).itemsize))
    return rows[:, 0].copy() if width == 1 else rows.copy()


def node_index(gltf: pygltflib.GLTF2) -> dict[str, int]:
    return {node.name: i for i, node in enumerate(gltf.nodes)}


def animated_trs(gltf: pygltflib.GLTF2, blob: bytes, time_s: float) -> dict[int, list[np.ndarray]]:
    """Every node's (translation, rotation xyzw, scale) at ``time_s``, a keyframe time: STEP and LINEAR
    channels both give the keyframe's value there (the last key at or before it; the first before any)."""
    trs = {i: [np.array(n.translation or [0.0, 0, 0]), np.array(n.rotation or [0.0, 0, 0, 1]), np.array(n.scale or [1.0, 1, 1])]
           for i, n in enumerate(gltf.nodes)}
    animation = gltf.animations[0]
    for channel in animation.channels:
        sampler = animation.samplers[channel.sampler]
        times = accessor_array(gltf, blob, sampler.input)
        values = accessor_array(gltf, blob, sampler.output)
        key = max(int(np.searchsorted(times, time_s + 1e-6)) - 1, 0)
        trs[channel.target.node][{"translation": 0, "rotation": 1, "scale": 2}[channel.target.path]] = values[key]
    return trs


def world_matrices(gltf: pygltflib.GLTF2, trs: dict[int, list[np.ndarray]]) -> dict[int, np.ndarray]:
    """Every node's world matrix from its (animated) TRS or matrix."""
    parent = {child: i for i, node in enumerate(gltf.nodes) for child in node.children or []}
    local = {}
    for i, node in enumerate(gltf.nodes):
        if node.matrix:
            local[i] = np.array(node.matrix).reshape(4, 4).T
            continue
        t, r, s = trs[i]
        m = np.eye(4)
        m[:3, :3] = Rotation.from_quat(r).as_matrix() * s
        m[:3, 3] = t
        local[i] = m
    out: dict[int, np.ndarray] = {}

    def world(i: int) -> np.ndarray:
        if i not in out:
            out[i] = world(parent[i]) @ local[i] if i in parent else local[i]
        return out[i]

    for i in range(len(gltf.nodes)):
        world(i)
    return out


def skinned_vertices(gltf: pygltflib.GLTF2, blob: bytes, track: int, time_s: float) -> np.ndarray:
    """(V, 3) the skinned mesh of ``person_<track>`` at ``time_s``: sum_j w_j (G_j IBM_j) v (glTF's skinning)."""
    nodes = node_index(gltf)
    worlds = world_matrices(gltf, animated_trs(gltf, blob, time_s))
    mesh_node = gltf.nodes[nodes[f"person_{track}/mesh"]]
    skin = gltf.skins[mesh_node.skin]
    primitive = gltf.meshes[mesh_node.mesh].primitives[0]
    rest = accessor_array(gltf, blob, primitive.attributes.POSITION).astype(np.float64)
    joints = accessor_array(gltf, blob, primitive.attributes.JOINTS_0).astype(np.int64)
    weights = accessor_array(gltf, blob, primitive.attributes.WEIGHTS_0).astype(np.float64)
    ibm = accessor_array(gltf, blob, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    joint_mats = np.stack([worlds[node] @ ibm[k] for k, node in enumerate(skin.joints)])
    blend = np.einsum("vk,vkab->vab", weights, joint_mats[joints])
    return np.einsum("vab,vb->va", blend[:, :3, :3], rest) + blend[:, :3, 3]


def world_body(model: BodyModel, data: dict, p: int, scale: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Person ``p`` of an aligned frame posed in the world without pose correctives (vertices (V, 3), joints
    (J, 3)), scaled about the pelvis by ``smpl_scale`` (or not)."""
    plain = dataclasses.replace(model, posedirs=np.zeros_like(model.posedirs))
    pose = pose_from_body(data["world_global_orient"][p:p + 1], data["smpl_body_pose"][p:p + 1], model.n_joints)
    verts, joints = lbs(plain, data["smpl_betas"][p:p + 1], pose, data["world_transl"][p:p + 1])
    pelvis = joints[:, :1]
    s = float(data["smpl_scale"][p]) if scale else 1.0
    return (pelvis + s * (verts - pelvis))[0], (pelvis + s * (joints - pelvis))[0]


def camera_body(model: BodyModel, data: dict, p: int) -> np.ndarray:
    """(V, 3) person ``p`` posed from its camera-frame parameters without pose correctives, scaled about the
    pelvis: the frame's meshes less the correctives, in the camera frame."""
    plain = dataclasses.replace(model, posedirs=np.zeros_like(model.posedirs))
    pose = pose_from_body(data["smpl_global_orient"][p:p + 1], data["smpl_body_pose"][p:p + 1], model.n_joints)
    verts, joints = lbs(plain, data["smpl_betas"][p:p + 1], pose, data["smpl_transl"][p:p + 1])
    pelvis = joints[:, :1]
    return (pelvis + float(data["smpl_scale"][p]) * (verts - pelvis))[0]


# ---- the GLB writer ------------------------------------------------------------------------------------------
def test_glb_writer_pads_and_refuses_overruns(tmp_path):
    layout = BinLayout()
    view = layout.view(10, name="ten")  # padded to 12 in the BIN
    assert layout.size == 12 and layout.view(4) == 1 and layout.view_offset(1) == 12
    with pytest.raises(ValueError, match="does not fit"):
        layout.accessor(view, 0, 5126, 3, "VEC3")  # 36 bytes in a 10-byte view
    chunk = json_chunk({"asset": {"version": "2.0"}})  # 27 bytes of JSON, one space of padding
    assert len(chunk) == 28 and chunk.endswith(b"} ")
    with pytest.raises(ValueError, match="does not fit its reserved"):
        json_chunk({"asset": {"version": "2.0"}}, length=8)
    with open(tmp_path / "x.glb", "wb") as handle:
        writer = GlbWriter(handle, 60, layout)
        with pytest.raises(ValueError, match="overrun"):
            writer.write_at(12, np.zeros(2, np.float32))
        writer.write_at(12, np.array([1.5], np.float32))
        writer.finish({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 16}]})
    data = (tmp_path / "x.glb").read_bytes()
    assert data[:4] == b"glTF" and int.from_bytes(data[8:12], "little") == len(data) == 12 + 8 + 60 + 8 + 16
    assert np.frombuffer(data[-4:], np.float32)[0] == 1.5


def test_skin_weights_keep_the_four_largest_renormalised():
    weights = np.array([[0.5, 0.2, 0.1, 0.1, 0.1, 0.0], [1.0, 0, 0, 0, 0, 0]])
    joints, top, dropped = skin_weights(weights)
    assert joints[0].tolist()[:2] == [0, 1] and joints[1].tolist() == [0, 0, 0, 0]
    np.testing.assert_allclose(top.sum(axis=1), 1.0, rtol=1e-6)
    np.testing.assert_allclose(top[0, :2], [0.5 / 0.9, 0.2 / 0.9], rtol=1e-6)
    assert dropped == pytest.approx(0.1)


# ---- per-frame meshes ----------------------------------------------------------------------------------------
def test_animated_glb_round_trips_through_pygltflib(synth_scene, tmp_path):
    before = tree_hash(synth_scene)
    seq = open_sequence(synth_scene / "gt")
    out = tmp_path / "anim.glb"
    summary = export_animated(seq, out)
    assert summary["drawn_as"] == "mesh" and summary["frames"] == 4 and summary["people"] == 3
    assert summary["fps"] == 5.0 and summary["fps_from"] == "meta.yaml" and summary["bytes"] == out.stat().st_size
    gltf, blob = load_gltf(out)
    nodes = node_index(gltf)
    assert {f"person_{i}" for i in range(3)} <= set(nodes) and {"ground", "camera_frustum", "camera"} <= set(nodes)
    # the camera: W / H, the vertical field of view, the one-frame export's pose
    (camera,) = gltf.cameras
    cam = seq.camera
    assert camera.perspective.aspectRatio == pytest.approx(640 / 360) and camera.perspective.yfov == pytest.approx(cam.vertical_fov_rad)
    np.testing.assert_allclose(np.array(gltf.nodes[nodes["camera"]].matrix).reshape(4, 4).T, world_from_gl_camera(cam), atol=1e-12)
    # one STEP scale channel per person-frame; their keyframes are the 4 frames' times at 5 fps
    (animation,) = gltf.animations
    assert len(animation.channels) == 12 and {s.interpolation for s in animation.samplers} == {"STEP"}
    key_times = np.unique(np.concatenate([accessor_array(gltf, blob, s.input) for s in animation.samplers]))
    np.testing.assert_allclose(key_times, np.arange(4) / 5.0, atol=1e-7)
    # every person-frame's mesh: V vertices at the frame's world vertices, the shared triangle list
    first = seq.read_frame("000002")
    mesh = gltf.meshes[gltf.nodes[nodes["person_1/000002"]].mesh]
    primitive = mesh.primitives[0]
    positions = accessor_array(gltf, blob, primitive.attributes.POSITION)
    assert gltf.accessors[primitive.attributes.POSITION].count == first.data["vertices"].shape[1]
    assert gltf.accessors[primitive.indices].count == first.data["faces"].size
    np.testing.assert_allclose(positions, cam.world_from_cam(first.data["vertices"][1]), atol=POSITION_TOL_M)
    acc = gltf.accessors[primitive.attributes.POSITION]
    np.testing.assert_array_equal(acc.min, positions.min(axis=0)) and np.testing.assert_array_equal(acc.max, positions.max(axis=0))
    assert len({m.primitives[0].indices for m in gltf.meshes if m.name.startswith("person_")}) == 1  # one index buffer
    loaded = trimesh.load(out, force="scene")
    assert sum(isinstance(g, trimesh.Trimesh) for g in loaded.geometry.values()) == 12 + 1  # person-frames + ground
    assert tree_hash(synth_scene) == before


def visible_children(gltf, blob, time_s: float) -> dict[str, list[str]]:
    """person node -> the names of its children shown (scale 1) at ``time_s``."""
    trs = animated_trs(gltf, blob, time_s)
    out = {}
    for i, node in enumerate(gltf.nodes):
        if node.name.startswith("person_") and "/" not in node.name:
            out[node.name] = [gltf.nodes[c].name for c in node.children if np.all(trs[c][2] == 1.0)]
    return out


def test_a_person_who_leaves_is_hidden_on_the_frames_without_them(leaving_scene, tmp_path):
    out = tmp_path / "leave.glb"
    summary = export_animated(open_sequence(leaving_scene), out)
    assert summary["person_frames"] == 10
    gltf, blob = load_gltf(out)
    for t, name in enumerate(["000000", "000001", "000002", "000003"]):
        shown = visible_children(gltf, blob, t / 5.0)
        assert shown["person_0"] == [f"person_0/{name}"] and shown["person_2"] == [f"person_2/{name}"]
        assert shown["person_1"] == ([f"person_1/{name}"] if t < 2 else [])
    # a still viewer (no animation) sees the first frame only
    still = {gltf.nodes[c].name for n in gltf.nodes if n.name.startswith("person_") and "/" not in n.name
             for c in n.children if (gltf.nodes[c].scale or [1, 1, 1]) != [0.0, 0.0, 0.0]}
    assert still == {"person_0/000000", "person_1/000000", "person_2/000000"}


def test_joint_only_sequence_is_drawn_as_bone_lines(synth_scene, tmp_path):
    seq_dir = tmp_path / "joints"
    seq_dir.mkdir()
    shutil.copy(synth_scene / "gt" / "camera.yaml", seq_dir)
    seq = open_sequence(synth_scene / "gt")
    for name in seq.frame_names[:2]:
        data = dict(seq.read_frame(name).data)
        np.savez(seq_dir / f"{name}.npz", joints=data["joints"], person_ids=data["person_ids"])
    out = tmp_path / "bones.glb"
    summary = export_animated(open_sequence(seq_dir), out)
    assert summary["drawn_as"] == "skeleton" and summary["fps_from"] == "assumed" and summary["fps"] == 30.0
    assert any("30 frames per second assumed" in note for note in summary["notes"])
    gltf, blob = load_gltf(out)
    primitive = gltf.meshes[gltf.nodes[node_index(gltf)["person_2/000001"]].mesh].primitives[0]
    assert primitive.mode == 1 and gltf.accessors[primitive.attributes.POSITION].count == 24  # LINES over the 24 joints
    assert gltf.accessors[primitive.indices].count == 2 * 23  # SMPL's 23 bones
    np.testing.assert_allclose(accessor_array(gltf, blob, primitive.attributes.POSITION),
                               seq.camera.world_from_cam(seq.read_frame("000001").data["joints"][2]), atol=POSITION_TOL_M)


# ---- skinned bodies ------------------------------------------------------------------------------------------
def test_skinned_glb_reproduces_the_model_at_every_frame(param_scene, neutral_model, tmp_path):
    model = load_body_model(neutral_model)
    out = tmp_path / "skinned.glb"
    summary = export_animated(open_sequence(param_scene), out, model=model, model_path=neutral_model)
    assert summary["drawn_as"] == "skinned" and summary["people"] == 3 and summary["fps"] == FPS
    assert any("pose-corrective" in note for note in summary["notes"])
    gltf, blob = load_gltf(out)
    nodes = node_index(gltf)
    assert len(gltf.skins) == 3 and {f"person_{i}" for i in range(3)} <= set(nodes)
    # keyframes: a track's root translation has one key per frame it is in
    counts = {}
    for channel in gltf.animations[0].channels:
        name = gltf.nodes[channel.target.node].name
        if name.endswith("/pelvis") and channel.target.path == "translation":
            counts[name] = gltf.accessors[gltf.animations[0].samplers[channel.sampler].input].count
    assert counts == {"person_0/pelvis": 5, "person_1/pelvis": 3, "person_2/pelvis": 3}
    seq = open_sequence(param_scene)
    for t, name in enumerate(seq.frame_names):
        frame = seq.read_frame(name)
        trs = animated_trs(gltf, blob, t / FPS)
        for track in range(3):
            shown = np.all(trs[nodes[f"person_{track}"]][2] == 1.0)
            assert shown == PRESENCE[t, track], (t, track)
        for p, track in enumerate(frame.person_ids):
            verts = skinned_vertices(gltf, blob, int(track), t / FPS)
            expected, _ = world_body(model, frame.data, p)
            assert np.abs(verts - expected).max() < SKIN_TOL_M
            # against the frame's own meshes (with pose correctives): the blend shapes' millimetres only
            assert np.abs(verts - seq.camera.world_from_cam(frame.data["vertices"][p])).max() < 0.02


def test_skinned_glb_in_another_camera_places_the_bodies_by_it(param_scene, neutral_model, tmp_path):
    """--camera another camera: the roots come from the camera-frame parameters through it (the frames' world
    keys belong to their own camera.yaml's world)."""
    seq = open_sequence(param_scene)
    other = seq.camera.replace(pitch_rad=np.deg2rad(35.0), height_m=6.0)
    write_camera_yaml(tmp_path / "other.yaml", other)
    model = load_body_model(neutral_model)
    out = tmp_path / "other.glb"
    export_animated(seq, out, camera_path=tmp_path / "other.yaml", model=model, model_path=neutral_model)
    gltf, blob = load_gltf(out)
    frame = seq.read_frame("000003")
    for p, track in enumerate(frame.person_ids):
        verts = skinned_vertices(gltf, blob, int(track), 3 / FPS)
        assert np.abs(verts - other.world_from_cam(camera_body(model, frame.data, p))).max() < SKIN_TOL_M


def test_skinned_smplx_and_its_amass_split(smplx_on_smpl_path, tmp_path, runner):
    seq_dir = tmp_path / "smplx"
    write_param_scene(seq_dir, smplx_on_smpl_path, PRESENCE[:2, :2], seed=4)
    model = load_body_model(smplx_on_smpl_path)
    out = tmp_path / "smplx.glb"
    summary = export_animated(open_sequence(seq_dir), out, model=model, model_path=smplx_on_smpl_path)
    assert summary["drawn_as"] == "skinned"
    gltf, blob = load_gltf(out)
    assert len(gltf.skins[0].joints) == 55 and "person_0/left_middle1" in node_index(gltf)
    frame = open_sequence(seq_dir).read_frame("000001")
    assert np.abs(skinned_vertices(gltf, blob, 0, 1 / FPS) - world_body(model, frame.data, 0)[0]).max() < SKIN_TOL_M
    result = invoke(runner, "export", seq_dir, "--format", "amass", "--smpl-model", smplx_on_smpl_path, "--out",
                    tmp_path / "amass", "--json")
    assert result.exit_code == 0, result.output
    assert any("does not name a gender" in note for note in json.loads(result.stdout)["notes"])  # SMPLX_SYNTH.npz
    with np.load(tmp_path / "amass" / "person_0.npz", allow_pickle=False) as npz:
        assert npz["poses"].shape == (2, 165) and str(npz["surface_model_type"]) == "smplx"
        assert {k: npz[k].shape[1] for k in ("pose_body", "pose_jaw", "pose_eye", "pose_hand")} == {
            "pose_body": 63, "pose_jaw": 3, "pose_eye": 6, "pose_hand": 90}
        np.testing.assert_array_equal(npz["pose_hand"], npz["poses"][:, 75:])


def test_skinned_glb_is_far_smaller_and_notes_what_to_pass(param_scene, neutral_model, tmp_path):
    meshes = export_animated(open_sequence(param_scene), tmp_path / "meshes.glb")
    assert meshes["drawn_as"] == "mesh" and any("--smpl-model" in note for note in meshes["notes"])
    skinned = export_animated(open_sequence(param_scene), tmp_path / "skinned.glb", model=load_body_model(neutral_model),
                              model_path=neutral_model)
    assert skinned["bytes"] < 0.6 * meshes["bytes"]
    assert {"person_0", "person_1", "person_2"} <= set(trimesh.load(tmp_path / "skinned.glb", force="scene").geometry)


def test_a_long_scene_is_still_known_as_rotavat_s(tmp_path):
    """A JSON chunk over 1 MB (a long animated scene) is not parsed whole: its opening asset block says who wrote it."""
    out = tmp_path / "long.glb"
    layout = BinLayout()
    layout.view(4)
    doc = {"asset": {"version": "2.0", "generator": "rotavat 9"}, "extras": {"pad": "x" * (2 << 20)},
           "buffers": [{"byteLength": 4}]}
    with open(out, "wb") as handle:
        GlbWriter(handle, len(json_chunk(doc)), layout).finish(doc)
    assert written_by_rotavat(out)
    doc["asset"]["generator"] = "someone else"
    with open(out, "wb") as handle:
        GlbWriter(handle, len(json_chunk(doc)), layout).finish(doc)
    assert not written_by_rotavat(out)


# ---- BVH and AMASS -------------------------------------------------------------------------------------------
def test_bvh_round_trip_gives_the_world_joints(runner, param_scene, neutral_model, tmp_path):
    before = tree_hash(param_scene)
    out = tmp_path / "bvh"
    result = invoke(runner, "export", param_scene, "--format", "bvh", "--smpl-model", neutral_model, "--out", out, "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert [(f["person_id"], f["first_frame"], f["frames"]) for f in summary["files"]] == [
        (0, "000000", 5), (1, "000002", 3), (2, "000000", 3)]
    model = load_body_model(neutral_model)
    seq = open_sequence(param_scene)
    data = read_bvh((out / "person_1.bvh").read_text())
    assert len(data.names) == 24 and data.names[0] == "pelvis" and data.frame_time == pytest.approx(1 / FPS)
    assert data.channels[0] == ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    assert all(len(c) == 3 for c in data.channels[1:]) and data.motion.shape == (3, 6 + 3 * 23)
    positions = bvh_joint_positions(data)
    names = list(data.names)
    for k, name in enumerate(seq.frame_names[2:]):
        frame = seq.read_frame(name)
        p = int(np.flatnonzero(frame.person_ids == 1)[0])
        _, joints = world_body(model, frame.data, p)
        order = [names.index(n) for n in joint_names(model)]
        np.testing.assert_allclose(positions[k][order], joints, atol=1e-5)  # 6 decimals in the file
        np.testing.assert_allclose(data.motion[k, :3], joints[0], atol=1e-6)  # the root path: the world pelvis
    assert tree_hash(param_scene) == before


def test_bvh_in_xyz_order_reads_back_alike(runner, param_scene, neutral_model, tmp_path):
    results = {}
    for order in ("ZXY", "XYZ"):
        out = tmp_path / order
        result = invoke(runner, "export", param_scene, "--format", "bvh", "--smpl-model", neutral_model, "--euler", order,
                        "--out", out, "--quiet")
        assert result.exit_code == 0, result.output
        data = read_bvh((out / "person_0.bvh").read_text())
        assert data.channels[1] == tuple(f"{axis}rotation" for axis in order)
        results[order] = bvh_joint_positions(data)
    np.testing.assert_allclose(results["ZXY"], results["XYZ"], atol=2e-5)


def test_amass_npz_round_trip_in_z_up(runner, param_scene, neutral_model, tmp_path):
    out = tmp_path / "amass"
    result = invoke(runner, "export", param_scene, "--format", "amass", "--smpl-model", neutral_model, "--out", out, "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert any("AMASS has no scale" in note for note in summary["notes"])  # tracks 1 and 2 are scaled by 1.04, 1.08
    model = load_body_model(neutral_model)
    seq = open_sequence(param_scene)
    with np.load(out / "person_2.npz", allow_pickle=False) as npz:
        amass = dict(npz)
    assert amass["poses"].shape == (3, 72) and amass["trans"].shape == (3, 3) and amass["betas"].shape == (10,)
    assert str(amass["gender"]) == "neutral" and float(amass["mocap_framerate"]) == FPS
    assert amass["pose_body"].shape == (3, 63) and amass["rotavat_scale"].tolist() == pytest.approx([1.08] * 3)
    plain = dataclasses.replace(model, posedirs=np.zeros_like(model.posedirs))
    for k, name in enumerate(seq.frame_names[:3]):
        frame = seq.read_frame(name)
        p = int(np.flatnonzero(frame.person_ids == 2)[0])
        verts_amass, joints_amass = lbs(plain, amass["betas"][None], amass["poses"][k:k + 1], amass["trans"][k:k + 1])
        expected, joints = world_body(model, frame.data, p, scale=False)  # AMASS has no scale
        np.testing.assert_allclose(verts_amass[0] @ R_AMASS_FROM_WORLD, expected, atol=1e-9)
        assert joints_amass[0, 0, 2] == pytest.approx(joints[0, 1])  # Z up: the pelvis height is AMASS's z
    rest_verts, rest_joints = rest_shape(model, amass["betas"])
    lift = (1.08 - 1.0) * (rest_joints[0, 1] - rest_verts[:, 1].min())  # the pelvis's height over the rest soles
    assert 0.07 < lift < 0.08
    assert f"{100 * lift:+.1f} cm (person_2" in " ".join(summary["notes"])


# ---- the command line ----------------------------------------------------------------------------------------
def test_cli_animated_export_json(runner, synth_scene, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke(runner, "export", synth_scene / "gt", "--json")  # default output beside SEQ
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    out = Path(summary["out"])
    assert out.name == "gt_scene.glb" and out.exists() and summary["track_ids"] == "person_ids"
    again = invoke(runner, "export", synth_scene / "gt", "--quiet")  # its own output is replaced without --force
    assert again.exit_code == 0, again.output
    out.unlink()


def test_cli_frame_local_ids_are_noted(runner, synth_scene, tmp_path):
    seq_dir = tmp_path / "noids"
    seq_dir.mkdir()
    shutil.copy(synth_scene / "gt" / "camera.yaml", seq_dir)
    for name in ("000000", "000001"):
        with np.load(synth_scene / "gt" / f"{name}.npz") as frame:
            np.savez(seq_dir / f"{name}.npz", **{k: v for k, v in frame.items() if k != "person_ids"})
    result = invoke(runner, "export", seq_dir, "--out", tmp_path / "x.glb", "--fps", "24")
    assert result.exit_code == 0, result.output
    assert "not one body followed in time" in result.stderr and "24 fps (assumed)" in result.stdout


def test_cli_refuses_a_file_over_the_size_limit_before_writing(runner, synth_scene, tmp_path):
    config = tmp_path / "small.yaml"
    config.write_text("limits: {max_file_mb: 0.5}\n")
    with limits.applied(limits.current()):  # the command puts the file's limits in force for the process: undo it
        result = invoke(runner, "export", synth_scene / "gt", "--out", tmp_path / "big.glb", "--config", config)
    assert result.exit_code == 2
    assert "would take 1014.2 KiB (12 person-frames, 79,092 points), over limits.max_file_mb (512.0 KiB)" in result.stderr
    assert not (tmp_path / "big.glb").exists() and not list(tmp_path.glob(".big.glb*"))


@pytest.fixture(scope="module")
def joints_only(synth_scene, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("jo") / "joints"
    out.mkdir()
    shutil.copy(synth_scene / "gt" / "camera.yaml", out)
    with np.load(synth_scene / "gt" / "000000.npz") as frame:
        np.savez(out / "000000.npz", joints=frame["joints"], person_ids=frame["person_ids"])
    return out


@pytest.mark.parametrize("args, message", [
    (["params", "--format", "bvh"], "pass --smpl-model with its .npz file (SMPL_NEUTRAL.npz"),
    (["joints", "--format", "bvh", "--smpl-model", "MODEL"], "000000.npz: no body-model parameters"),
    (["joints", "--format", "amass", "--smpl-model", "MODEL"], "--format amass needs them"),
    (["params", "--format", "bvh", "--smpl-model", "SMPLX"], "has 55 joints, but"),
    (["params", "--format", "bvh", "--frame", "0"], "--frame writes one frame as a .glb"),
    (["params", "--format", "amass", "--out", "walk.npz"], "give --out a folder name (e.g. walk)"),
    (["params", "--format", "fbx"], "--format must be one of glb, bvh, amass"),
    (["params", "--out", "walk.bvh"], "--out must end in .glb"),
    (["params", "--fps", "0"], "--fps: must be > 0, got 0.0"),
    (["params", "--euler", "YXZ"], "--euler: must be one of ZXY, XYZ, got 'YXZ'"),
])
def test_cli_bad_input_is_one_line_exit_2(runner, param_scene, joints_only, neutral_model, smplx_on_smpl_path, tmp_path,
                                          monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    where = {"params": param_scene, "joints": joints_only, "MODEL": neutral_model, "SMPLX": smplx_on_smpl_path}
    result = invoke(runner, "export", *[where.get(a, a) for a in args])
    assert result.exit_code == 2, result.output
    assert message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


# ---- a real importer: Blender -----------------------------------------------------------------------------
_BLENDER_CHECK = """
import bpy, json, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
# Shading "SMOOTH": Debian 12's Blender 3.4 fails on its default ("NORMALS": numpy 1.24 has no np.bool)
bpy.ops.import_scene.gltf(filepath=sys.argv[-1], import_shading="SMOOTH")
scene = bpy.context.scene
print("ROTAVAT" + json.dumps({"objects": sorted(o.name for o in bpy.data.objects), "actions": len(bpy.data.actions),
      "frame_end": max((a.frame_range[1] for a in bpy.data.actions), default=0), "cameras": len(bpy.data.cameras),
      "armatures": len(bpy.data.armatures)}))
"""


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("blender") is None, reason="Blender is not installed (apt-get install blender)")
@pytest.mark.parametrize("kind", ["meshes", "skinned"])
def test_blender_imports_the_animated_scene(param_scene, neutral_model, tmp_path, kind):
    out = tmp_path / f"{kind}.glb"
    model = load_body_model(neutral_model) if kind == "skinned" else None
    export_animated(open_sequence(param_scene), out, model=model, model_path=neutral_model if model else None)
    proc = subprocess.run(["blender", "-b", "--factory-startup", "--python-expr", _BLENDER_CHECK, "--", str(out)],
                          capture_output=True, text=True, timeout=300)
    line = next((s for s in proc.stdout.splitlines() if s.startswith("ROTAVAT")), None)
    assert line is not None, proc.stdout[-2000:] + proc.stderr[-2000:]
    found = json.loads(line[len("ROTAVAT"):])
    assert found["cameras"] == 1 and {"ground", "camera_frustum"} <= set(found["objects"])
    assert {"person_0", "person_1", "person_2"} <= set(found["objects"]) or kind == "skinned"
    if kind == "skinned":
        assert found["armatures"] == 3
    # the last keyframe: frame 4 at 10 fps is 0.4 s, Blender frame 9.6 at its default 24 fps (from frame 0)
    assert found["frame_end"] == pytest.approx(4 / FPS * 24, abs=1e-3)


def test_a_tool_file_without_a_camera_names_commands_that_run(tmp_path, runner, scene, model_path, monkeypatch):
    """`export FILE --from cliff` with no camera: the message's calibrate and export commands repeat --from and
    its flags, and both run as written (they used to say `rotavat calibrate FILE`, which refuses a tool's file)."""
    import re
    import shlex

    import _format_fixtures as F

    src = F.write_cliff(tmp_path / "demo_cliff_hr48.npz", scene, (F.W, F.H))
    monkeypatch.chdir(tmp_path)
    flags = ["--from", "cliff", "--image-size", F.W, F.H, "--smpl-model", model_path]
    first = invoke(runner, "export", src, *flags, catch_exceptions=True)
    assert first.exit_code == 2 and "no camera for the exported world" in first.stderr
    commands = re.findall(r"`(rotavat [^`]+)`", first.stderr)
    assert [shlex.split(c)[1] for c in commands] == ["calibrate", "export"]
    for command in commands:
        result = invoke(runner, *shlex.split(command)[1:], "--quiet", catch_exceptions=True)
        assert result.exit_code == 0, (command, result.stderr)
    assert (tmp_path / "demo_cliff_hr48_scene.glb").is_file()
