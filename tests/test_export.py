"""rotavat export: GLB scenes (people, ground, frustum, camera) read back with trimesh and by hand."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.render import (R_CV_FROM_GL, RenderStyle, build_scene, export_frame, frustum_segments_world,
                                ground_quad_world, read_glb_json, read_row, world_from_gl_camera, write_glb)
from rotavat_cli.sequence import open_sequence, read_camera_yaml, write_camera_yaml
from rotavat_cli.synth import SynthOptions, write_synth_scene

FEET_TOL_M = 0.02  # synthetic soles sit on y = 0 up to the mesh's own sole thickness


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("export") / "scene"
    write_synth_scene(out, SynthOptions(seed=2, frames=2, people=3, image_size=(640, 360)))
    return out


def test_R_cv_from_gl_is_the_axis_flip_of_camera_conventions():
    np.testing.assert_allclose(R_CV_FROM_GL @ [0, 0, -1], [0, 0, 1])  # glTF looks along -z, OpenCV along +z
    np.testing.assert_allclose(R_CV_FROM_GL @ [0, 1, 0], [0, -1, 0])  # glTF y up, OpenCV y down
    np.testing.assert_allclose(R_CV_FROM_GL @ [1, 0, 0], [1, 0, 0])
    assert np.isclose(np.linalg.det(R_CV_FROM_GL), 1.0)  # a rotation, not a mirror


def test_gl_camera_pose_sees_what_the_opencv_camera_sees():
    cam = Camera((640, 360), 500.0, None, np.deg2rad(25.0), np.deg2rad(3.0), 6.0)
    pose = world_from_gl_camera(cam)
    np.testing.assert_allclose(pose[:3, 3], cam.center_world)
    forward_world = -pose[:3, 2]
    np.testing.assert_allclose(forward_world, cam.R_cam_from_world.T @ [0, 0, 1], atol=1e-12)
    point_cam = np.array([0.7, -0.3, 9.0])  # right, up in the image, in front
    p_gl = np.linalg.inv(pose) @ np.append(cam.world_from_cam(point_cam), 1.0)
    np.testing.assert_allclose(p_gl[:3], [0.7, 0.3, -9.0], atol=1e-9)


def test_frustum_and_ground_geometry():
    cam = Camera((640, 360), 500.0, None, np.deg2rad(25.0), 0.0, 6.0)
    seg = frustum_segments_world(cam, 2.0)
    assert seg.shape == (8, 2, 3)
    np.testing.assert_allclose(seg[:4, 0], np.broadcast_to(cam.center_world, (4, 3)))
    far_cam = cam.cam_from_world(seg[:4, 1])
    np.testing.assert_allclose(far_cam[:, 2], 2.0, atol=1e-9)
    np.testing.assert_allclose(cam.project(far_cam), [[0, 0], [640, 0], [640, 360], [0, 360]], atol=1e-6)
    verts, faces = ground_quad_world(np.array([[1.0, 0.0, -3.0], [-2.0, 1.7, -8.0]]))
    np.testing.assert_allclose(verts[:, 1], 0.0)
    normal = np.cross(verts[faces[0, 1]] - verts[faces[0, 0]], verts[faces[0, 2]] - verts[faces[0, 0]])
    assert normal[1] > 0  # faces up


def test_glb_round_trip(scene, tmp_path):
    before = tree_hash(scene)
    out = tmp_path / "frame.glb"
    seq = open_sequence(scene / "gt")
    summary = export_frame(seq, out, frame=1)
    assert summary["frame"] == "000001" and summary["people"] == 3 and summary["drawn_as"] == "mesh"
    cam = seq.camera
    W, H = cam.image_size

    loaded = trimesh.load(out, force="scene")
    meshes = {k: g for k, g in loaded.geometry.items() if isinstance(g, trimesh.Trimesh)}
    assert sorted(meshes) == ["ground", "gt/person_0", "gt/person_1", "gt/person_2"]
    assert any(isinstance(g, trimesh.path.Path3D) for g in loaded.geometry.values())  # the frustum
    assert loaded.camera.fov[0] / loaded.camera.fov[1] == pytest.approx(W / H)  # trimesh reads fov_x = aspect * fov_y
    np.testing.assert_allclose(loaded.camera_transform, world_from_gl_camera(cam), atol=1e-9)

    frame = seq.read_frame("000001")
    verts_world, _ = loaded.graph["gt/person_1"]
    person = meshes["gt/person_1"].copy().apply_transform(verts_world)
    np.testing.assert_allclose(person.vertices, cam.world_from_cam(frame.data["vertices"][1]), atol=1e-5)
    assert abs(person.vertices[:, 1].min()) < FEET_TOL_M  # ground truth stands on Y = 0
    np.testing.assert_allclose(meshes["ground"].vertices[:, 1], 0.0)

    gltf = read_glb_json(out)
    (camera,) = gltf["cameras"]
    assert camera["type"] == "perspective"
    assert camera["perspective"]["aspectRatio"] == pytest.approx(W / H, rel=1e-12)
    assert camera["perspective"]["yfov"] == pytest.approx(cam.vertical_fov_rad, rel=1e-12)
    node = next(n for n in gltf["nodes"] if n.get("camera") == 0)
    np.testing.assert_allclose(np.array(node["matrix"]).reshape(4, 4).T, world_from_gl_camera(cam), atol=1e-12)
    palette = RenderStyle().palette
    colors = {tuple(np.round(m["pbrMetallicRoughness"]["baseColorFactor"][:3], 3)) for m in gltf["materials"]}
    assert tuple(np.round(np.round(255 * np.array(palette[2])) / 255, 3)) in colors  # person 2 in its palette colour
    assert tree_hash(scene) == before


def test_scene_of_several_rows_names_nodes_by_row(scene, tmp_path):
    gt = open_sequence(scene / "gt")
    pred = open_sequence(scene / "pred")
    rows = [read_row(gt, "000000", "gt", gt.camera), read_row(pred, "000000", "pred", gt.camera)]
    path = write_glb(tmp_path / "both.glb", build_scene(rows, gt.camera, RenderStyle().palette), gt.camera)
    names = set(trimesh.load(path, force="scene").geometry)
    assert {"gt/person_0", "pred/person_0", "ground", "camera_frustum"} <= names


def test_cli_export(runner, scene, tmp_path):
    result = invoke(runner, "export", scene / "gt", "--frame", "-1", "--out", tmp_path / "s.glb", "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["frame"] == "000001" and summary["aspect_ratio"] == pytest.approx(640 / 360)
    assert read_glb_json(tmp_path / "s.glb")["cameras"][0]["perspective"]["aspectRatio"] == pytest.approx(640 / 360)


@pytest.mark.parametrize("args, message", [
    (["pred"], "rotavat calibrate"),
    (["gt", "--frame", "9"], "out of range"),
    (["gt", "--out", "scene.obj"], "must end in .glb"),
])
def test_cli_export_bad_input_exit_2(runner, scene, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    result = invoke(runner, "export", scene / args[0], *args[1:])
    assert result.exit_code == 2, result.output
    assert message in result.stderr and "Traceback" not in result.stderr


def test_cli_export_camera_overrides_the_sequence_own(runner, scene, tmp_path):
    """--camera is the camera the GLB is placed by, even when SEQ has its own camera.yaml."""
    cam, fit = read_camera_yaml(scene / "gt" / "camera.yaml")
    write_camera_yaml(tmp_path / "wide.yaml", cam.replace(focal_px=cam.focal_px / 2), fit)
    own = json.loads(invoke(runner, "export", scene / "gt", "--out", tmp_path / "a.glb", "--json").stdout)
    given = json.loads(invoke(runner, "export", scene / "gt", "--camera", tmp_path / "wide.yaml", "--out",
                              tmp_path / "b.glb", "--json").stdout)
    assert given["yfov_deg"] > own["yfov_deg"] + 10  # half the focal: a much wider view
    assert given["yfov_deg"] == pytest.approx(np.rad2deg(cam.replace(focal_px=cam.focal_px / 2).vertical_fov_rad))
