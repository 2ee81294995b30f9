"""rotavat render: view geometry, both rasterisers on a small scene (real content), grids and the CLI."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash
from PIL import Image

from rotavat_cli.geometry.camera import Camera, project_cam_to_px
from rotavat_cli.settings.config import default_config
from rotavat_cli.errors import RotavatError
from rotavat_cli.bodies.landmarks import foot_head_points
from rotavat_cli.render import (LABEL_PX, REGISTRY, RENDERERS, VIEWS, FigureOptions, FrontCrop, PanelView, RenderStyle,
                                RowFrame, clip_from_cam_perspective, figure_steps, fit_ortho_extent, front_view,
                                ground_truth_row, horizontal_forward_world, layout_bones, layout_name, metrics_caption,
                                open_rasterizer, ortho_basis_world, ortho_bounds, ortho_view, parse_views, paste_boxes_px,
                                people_flags, person_colors, plot_tracks, project_view_px, rasterize_numpy, read_row,
                                render_grid, render_panel, render_sequences, scene_extents, select_frames,
                                sequence_camera, sequence_tracks)
from rotavat_cli.render.skeleton import JOINT_RADIUS_M
from rotavat_cli.render.views import front_points_cam
from rotavat_cli.render.views import side_fov_px, tick_marks
from rotavat_cli.sequence import open_sequence, read_camera_yaml
from rotavat_cli.synth import SynthOptions, write_synth_scene
from rotavat_cli.synth.bodies import load_bodies

SIZE = (320, 180)  # test panels: small and fast
PX_TOL = 2.0  # silhouette vs projected bounds: one pixel of rasterisation rule + one of anti-aliasing
RGB = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))  # ids 0, 1, 2: classify pixels by channel
STYLE = RenderStyle(palette=RGB, margin=0.05, camera=(1.0, 0.0, 1.0))  # magenta camera: not a person class


def _gl_available() -> bool:
    try:
        open_rasterizer("gl").release()
        return True
    except RotavatError:
        return False


GL = _gl_available()


@pytest.fixture(params=["gl", "fallback"])
def rasterizer(request):
    """Both renderers; the fallback always runs, OpenGL only where an EGL context can be made."""
    if request.param == "gl" and not GL:
        pytest.skip("no EGL/OpenGL context on this machine")
    with open_rasterizer(request.param) as r:
        assert r.name == request.param
        yield r


def _camera() -> Camera:
    return Camera((320, 180), 200.0, None, np.deg2rad(20.0), np.deg2rad(2.0), 4.0)


def _people_row(camera: Camera, ground_xz: np.ndarray, ids: list[int], lift_m: list[float] | None = None,
                label: str = "row") -> RowFrame:
    """Bodies standing at world ground points (X, Z), optionally lifted, in the camera frame."""
    lib = load_bodies()
    P = len(ids)
    lift = np.zeros(P) if lift_m is None else np.asarray(lift_m, dtype=float)
    pos = np.stack([ground_xz[:, 0], lift, ground_xz[:, 1]], axis=1)
    verts_world = lib.vertices[np.arange(P) % len(lib)] + pos[:, None, :]
    verts_cam = camera.cam_from_world(verts_world)
    return RowFrame(label, verts_cam, lib.faces, np.asarray(ids), camera.image_size, camera.focal_px,
                    camera.principal_point, camera)


def _panel_top(i: int, height: int = SIZE[1]) -> int:
    """First pixel row of grid row ``i``'s panels (header strip, then per row a caption strip and panels)."""
    return LABEL_PX + i * (LABEL_PX + height) + LABEL_PX


def _masks(panel: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 -> (3, H, W) bool: pixels clearly of the red, green, blue person."""
    p = panel.astype(int)
    return np.stack([(p[..., k] > 60) & (np.delete(p, k, axis=-1).max(axis=-1) < 0.45 * p[..., k]) for k in range(3)])


def _box(mask: np.ndarray) -> np.ndarray:
    """Pixel extent [x0, y0, x1, y1] (x1, y1 exclusive) of a mask."""
    ys, xs = np.nonzero(mask)
    return np.array([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], dtype=float)


# ---- geometry ------------------------------------------------------------------------------------
def test_perspective_clip_matrix_reproduces_projection():
    rng = np.random.default_rng(0)
    cam = _camera()
    pts = rng.uniform([-2, -1, 3], [2, 1, 20], (50, 3))
    clip = clip_from_cam_perspective(cam.focal_px, cam.principal_point, cam.image_size, 0.05, 100.0)
    np.testing.assert_allclose(project_view_px(clip, pts, cam.image_size), cam.project(pts), atol=1e-9)


def test_ortho_bases_are_orthonormal_and_side_is_perpendicular_to_the_view():
    cam = _camera()
    fwd = horizontal_forward_world(cam)
    axis_world = cam.R_cam_from_world.T @ [0.0, 0.0, 1.0]
    assert abs(fwd[1]) < 1e-12 and np.dot(fwd, axis_world) > 0.9
    for kind in ("side", "top"):
        B = ortho_basis_world(kind, cam)
        np.testing.assert_allclose(B @ B.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(B[2], np.cross(B[1], B[0]), atol=1e-12)  # right, up, into the panel
    side = ortho_basis_world("side", cam)
    assert abs(np.dot(side[2], fwd)) < 1e-12 and abs(side[2][1]) < 1e-12  # looks along the ground, across the view
    np.testing.assert_allclose(side[1], [0, 1, 0])


def test_fit_extent_is_isotropic_and_covers_bounds():
    bounds = np.array([[2.0, 0.0, -1.0], [12.0, 1.8, 1.0]])
    ext = fit_ortho_extent(bounds, (400, 200), 0.05, floor_room=0.2)
    half_w, half_h = 200 / ext.px_per_m, 100 / ext.px_per_m
    assert ext.center_m[0] - half_w <= 2.0 and ext.center_m[0] + half_w >= 12.0
    assert ext.center_m[1] - half_h < 0.0 and ext.center_m[1] + half_h >= 1.8
    assert ext.center_m[1] - half_h >= -0.2 * 2 * half_h - 0.5  # ground kept low, not centred


def test_person_colors_by_id_modulo_palette():
    np.testing.assert_allclose(person_colors(np.array([0, 4, -1, 2]), RGB), [RGB[0], RGB[1], RGB[2], RGB[2]])


def test_options_defaults_are_the_packaged_config():
    render = default_config()["render"]
    assert FigureOptions() == FigureOptions.from_config(render)  # configs/default.yaml is the one source
    assert RenderStyle() == RenderStyle.from_config(render)
    assert FigureOptions().style == RenderStyle()


def test_registry_views_are_the_valid_views():
    assert VIEWS == tuple(REGISTRY) and all(REGISTRY[name].name == name and REGISTRY[name].title for name in VIEWS)
    assert parse_views(",".join(VIEWS)) == VIEWS
    assert set(parse_views(default_config()["render"]["views"])) <= set(VIEWS)
    with pytest.raises(ValueError, match=f"unknown view\\(s\\) back; choose from {', '.join(VIEWS)}$"):
        parse_views("front,back")
    cam = _camera()
    for view in REGISTRY.values():  # every orthographic entry: orthonormal, right-handed axes
        if view.ortho is not None:
            B = ortho_basis_world(view.name, cam)
            np.testing.assert_allclose(B @ B.T, np.eye(3), atol=1e-12)
            np.testing.assert_allclose(B[2], np.cross(B[1], B[0]), atol=1e-12)
            assert view.needs_camera


def test_open_rasterizer_refuses_unknown_renderers():
    with pytest.raises(ValueError, match=", ".join(RENDERERS)):
        open_rasterizer("vulkan")
    with open_rasterizer("fallback") as r:
        assert (r.name, r.note, r.rasterize) == ("fallback", "requested", rasterize_numpy)


def test_select_frames_and_views():
    assert select_frames(10, None, None) == [0]
    assert select_frames(10, "0,3,-1", None) == [0, 3, 9]
    assert select_frames(10, None, 4) == [0, 4, 8]
    with pytest.raises(ValueError, match="out of range"):
        select_frames(3, "5", None)
    with pytest.raises(ValueError, match="not both"):
        select_frames(3, "0", 2)
    assert parse_views("front, top") == ("front", "top")
    with pytest.raises(ValueError, match="unknown view"):
        parse_views("front,back")


# ---- pictures, both renderers --------------------------------------------------------------------
def test_front_silhouettes_match_projected_bounds(rasterizer):
    cam = _camera()
    row = _people_row(cam, np.array([[-2.5, -9.0], [0.0, -7.0], [2.5, -11.0]]), [0, 1, 2])
    view = front_view(row, cam.image_size)  # panel = image size: pixels map one to one
    panel = render_panel(row, view, rasterizer.rasterize, STYLE, labels=False)
    masks = _masks(panel)
    for p in range(3):
        uv = cam.project(row.verts_cam[p])
        expected = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
        np.testing.assert_allclose(_box(masks[p]), expected, atol=PX_TOL, err_msg=f"person {p}")
        assert masks[p].sum() > 0.25 * np.prod(expected[2:] - expected[:2])  # a body, not a thin outline


def test_side_view_feet_on_ground_line_and_floating_shows(rasterizer):
    cam = _camera()
    row = _people_row(cam, np.array([[0.0, -6.0], [0.5, -9.0], [-0.5, -12.0]]), [0, 1, 2], lift_m=[0.0, 0.0, 0.5])
    ext = scene_extents([row], ("side",), SIZE, STYLE.margin)["side"]
    view = ortho_view("side", cam, ext, SIZE)
    panel = render_panel(row, view, rasterizer.rasterize, STYLE, labels=False)
    ground = np.array([round(255 * c) for c in STYLE.ground])
    line_hits = (np.abs(panel.astype(int) - ground).max(axis=-1) <= 3).sum(axis=1)
    v_line = int(np.argmax(line_hits))  # the ground line: the row with most ground-coloured pixels
    assert line_hits[v_line] > 0.5 * SIZE[0]
    assert abs(v_line + 0.5 - project_view_px(view.clip_from_world, np.zeros(3), SIZE)[1]) <= 1.5
    masks = _masks(panel)
    lib = load_bodies()
    for p, lift in enumerate([0.0, 0.0, 0.5]):
        x0, y0, x1, y1 = _box(masks[p])
        assert abs(y1 - (v_line + 1 + -lift * ext.px_per_m)) <= PX_TOL + 1, f"person {p}: feet at row {y1}, line {v_line}"
        assert abs((y1 - y0) - lib.stature_m[p] * ext.px_per_m) <= PX_TOL + 1  # upright, full height
    assert (v_line + 1) - _box(masks[2])[3] > 0.5 * ext.px_per_m - PX_TOL - 1  # the lifted one floats


def test_top_view_places_people_and_camera(rasterizer):
    cam = _camera()
    ground_xz = np.array([[-3.0, -8.0], [0.0, -5.0], [3.0, -10.0]])
    row = _people_row(cam, ground_xz, [0, 1, 2])
    ext = scene_extents([row], ("top",), SIZE, STYLE.margin, fit="camera")["top"]  # the camera in the window
    view = ortho_view("top", cam, ext, SIZE)
    panel = render_panel(row, view, rasterizer.rasterize, STYLE, labels=False)
    masks = _masks(panel)
    expected = project_view_px(view.clip_from_world, np.stack([ground_xz[:, 0], 0 * ground_xz[:, 0], ground_xz[:, 1]], 1), SIZE)
    for p in range(3):
        ys, xs = np.nonzero(masks[p])
        assert np.hypot(xs.mean() + 0.5 - expected[p, 0], ys.mean() + 0.5 - expected[p, 1]) < 0.5 * ext.px_per_m
    cu, cv = project_view_px(view.clip_from_world, cam.center_world * [1, 0, 1], SIZE).astype(int)
    assert np.abs(panel[cv, cu].astype(int) - [round(255 * c) for c in STYLE.camera]).max() <= 3
    assert expected[:, 1].max() < cv  # people are ahead of the camera: above it on the map


def test_colors_follow_ids_not_order(rasterizer):
    cam = _camera()
    row = _people_row(cam, np.array([[-2.5, -9.0], [0.0, -7.0], [2.5, -11.0]]), [0, 1, 2])
    flipped = RowFrame(row.label, row.verts_cam[::-1], row.faces, row.person_ids[::-1], row.image_size,
                       row.focal_px, row.principal_point, cam)
    a = render_panel(row, front_view(row, SIZE), rasterizer.rasterize, STYLE, labels=False).astype(int)
    b = render_panel(flipped, front_view(flipped, SIZE), rasterizer.rasterize, STYLE, labels=False).astype(int)
    assert np.mean(np.abs(a - b).max(axis=-1) > 8) < 0.002
    masks = _masks(a)
    assert all(m.sum() > 50 for m in masks)


def test_empty_frame_draws_the_scene_without_people(rasterizer):
    cam = _camera()
    lib = load_bodies()
    row = RowFrame("empty", np.zeros((0, lib.vertices.shape[1], 3)), lib.faces, np.zeros(0, int), cam.image_size,
                   cam.focal_px, cam.principal_point, cam)
    fig = render_grid([row], ("front", "side", "top"), SIZE, rasterizer.rasterize, STYLE)
    assert fig.shape == (LABEL_PX + LABEL_PX + SIZE[1], 3 * SIZE[0], 3)
    assert not _masks(fig).any()


@pytest.mark.skipif(not GL, reason="no EGL/OpenGL context on this machine")
def test_renderers_agree():
    cam = _camera()
    row = _people_row(cam, np.array([[-1.5, -5.0], [0.3, -5.5], [1.8, -6.0]]), [0, 1, 2])
    view = front_view(row, SIZE)
    with open_rasterizer("gl") as gl:
        a = render_panel(row, view, gl.rasterize, STYLE, labels=False)
    b = render_panel(row, view, rasterize_numpy, STYLE, labels=False)
    ma, mb = _masks(a), _masks(b)
    for p in range(3):
        assert (ma[p] & mb[p]).sum() / (ma[p] | mb[p]).sum() > 0.9  # differences: anti-aliased edges only


def test_grid_shares_one_scale_across_rows():
    cam = _camera()
    near = _people_row(cam, np.array([[0.0, -5.0]]), [0], label="near")
    far = _people_row(cam, np.array([[0.0, -25.0]]), [1], label="far")
    ext = scene_extents([near, far], ("side",), SIZE, STYLE.margin)["side"]
    alone = scene_extents([near], ("side",), SIZE, STYLE.margin)["side"]
    assert ext.px_per_m < alone.px_per_m  # the far row's person widens everyone's window
    fig = render_grid([near, far], ("front", "side"), SIZE, rasterize_numpy, STYLE, labels=False)
    assert fig.shape == (LABEL_PX + 2 * (LABEL_PX + SIZE[1]), 2 * SIZE[0], 3)
    side = [fig[_panel_top(i):_panel_top(i) + SIZE[1], SIZE[0]:] for i in range(2)]
    h0 = np.ptp(np.nonzero(_masks(side[0])[0])[0])
    h1 = np.ptp(np.nonzero(_masks(side[1])[1])[0])
    assert abs(h0 - h1) <= 3  # same body height in px: one metric scale


# ---- CLI -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("render") / "scene"
    write_synth_scene(out, SynthOptions(seed=1, frames=3, people=4, image_size=(320, 180)))
    return out


def _json(result) -> dict:
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def _lowest_rows(row: RowFrame, view, rasterize) -> list[int]:
    """Bottom pixel row of each person's silhouette, each drawn alone in the view."""
    rows = []
    for p in range(len(row.person_ids)):
        alone = RowFrame(row.label, row.verts_cam[p:p + 1], row.faces, np.array([0]), row.image_size, row.focal_px,
                         row.principal_point, row.camera)
        rows.append(int(_box(_masks(render_panel(alone, view, rasterize, STYLE, labels=False))[0])[3]))
    return rows


def test_aligned_people_stand_on_the_side_view_ground_line(runner, scene, tmp_path, rasterizer):
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml",
                    "--out", tmp_path / "aligned", "-q")
    assert result.exit_code == 0, result.output
    cam = open_sequence(scene / "gt").camera
    rows = {name: read_row(open_sequence(path), "000001", name, cam)
            for name, path in (("pred", scene / "pred"), ("aligned", tmp_path / "aligned"))}
    size = (480, 270)
    ext = scene_extents(list(rows.values()), ("side",), size, STYLE.margin)["side"]
    view = ortho_view("side", cam, ext, size)
    v_line = project_view_px(view.clip_from_world, np.zeros(3), size)[1]
    aligned = np.array(_lowest_rows(rows["aligned"], view, rasterizer.rasterize))
    pred = np.array(_lowest_rows(rows["pred"], view, rasterizer.rasterize))
    assert np.all(np.abs(aligned - v_line) <= PX_TOL), (aligned, v_line)
    assert np.max(np.abs(pred - v_line)) > 5 * PX_TOL  # the prediction floats or sinks visibly


def test_cli_render_before_after_grid(runner, scene, tmp_path):
    before = tree_hash(scene)
    result = invoke(runner, "render", scene / "pred", scene / "gt", "--camera", scene / "gt" / "camera.yaml",
                    "--out", tmp_path / "fig", "--frames", "0,-1", "--size", "200", "120", "--json")
    summary = _json(result)
    assert summary["renderer"] in ("gl", "fallback") and summary["rows"] == ["pred", "gt"]
    assert summary["frames"] == ["000000", "000002"]
    with Image.open(tmp_path / "fig" / "000002.png") as img:
        assert img.size == (3 * 200, LABEL_PX + 2 * (LABEL_PX + 120))
    assert tree_hash(scene) == before


def test_cli_render_fallback_gif_glb(runner, scene, tmp_path):
    summary = _json(invoke(runner, "render", scene / "gt", "--out", tmp_path / "fig", "--every", "1", "--renderer", "fallback",
                           "--views", "side,top", "--size", "160", "90", "--gif", "--glb", "--json"))
    assert summary["renderer"] == "fallback" and summary["renderer_note"] == "requested"
    with Image.open(tmp_path / "fig" / "render.gif") as gif:
        assert gif.n_frames == 3
    assert (tmp_path / "fig" / "000001.glb").stat().st_size > 1000


def test_cli_render_auto_falls_back_and_says_so(runner, scene, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "moderngl", None)  # as on a machine without moderngl: import fails
    summary = _json(invoke(runner, "render", scene / "gt", "--out", tmp_path / "a", "--size", "160", "90", "--json"))
    assert summary["renderer"] == "fallback" and "moderngl is not installed" in summary["renderer_note"]
    assert (tmp_path / "a" / "000000.png").exists()
    result = invoke(runner, "render", scene / "gt", "--out", tmp_path / "b", "--renderer", "gl")
    assert result.exit_code == 2 and "--renderer fallback" in result.stderr


def test_missing_egl_library_falls_back(runner, scene, tmp_path, monkeypatch):
    monkeypatch.setenv("GLCONTEXT_LINUX_LIBEGL", str(tmp_path / "no" / "libEGL.so.1"))  # as without libegl1
    summary = _json(invoke(runner, "render", scene / "gt", "--out", tmp_path / "a", "--size", "160", "90", "--json"))
    assert summary["renderer"] == "fallback" and "OpenGL renderer unavailable" in summary["renderer_note"]


def test_cli_render_front_over_video_frame(runner, scene, tmp_path):
    frames = tmp_path / "video"
    frames.mkdir()
    Image.new("RGB", (320, 180), (255, 0, 255)).save(frames / "000000.jpg", quality=100)
    invoke(runner, "render", scene / "pred", "--views", "front", "--image", frames, "--out", tmp_path / "fig",
           "--size", "320", "180", "--renderer", "fallback", "-q")
    with Image.open(tmp_path / "fig" / "000000.png") as img:
        pixel = np.asarray(img)[_panel_top(0) + 5, 5].astype(int)  # image corner: no person there
    assert np.abs(pixel - [255, 0, 255]).max() <= 8


@pytest.mark.parametrize("args, message", [
    (["pred"], "rotavat calibrate"),
    (["gt", "--views", "front,back"], "unknown view"),
    (["gt", "--frames", "7"], "out of range"),
    (["gt", "--frames", "0", "--every", "2"], "not both"),
    (["gt", "--renderer", "vulkan"], "--renderer"),
    (["gt", "--image", "."], "no image named 000000"),
])
def test_cli_render_bad_input_exit_2(runner, scene, tmp_path, monkeypatch, args, message):
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")  # "." (an empty image folder) is not where the output goes
    result = invoke(runner, "render", scene / args[0], *args[1:], "--out", tmp_path / "fig")
    assert result.exit_code == 2, result.output
    assert message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) <= 3  # one message (rich may wrap it)


def test_cli_render_front_only_needs_no_camera(runner, scene, tmp_path):
    summary = _json(invoke(runner, "render", scene / "pred", "--views", "front", "--out", tmp_path / "fig",
                           "--size", "160", "90", "--json"))
    assert Path(summary["files"][0]).exists()


@pytest.mark.parametrize("name", VIEWS)
def test_cli_renders_every_registry_view(runner, scene, tmp_path, name):
    summary = _json(invoke(runner, "render", scene / "gt", "--views", name, "--renderer", "fallback", "--out",
                           tmp_path / "fig", "--size", "64", "36", "--json"))
    assert summary["views"] == [name]
    with Image.open(summary["files"][0]) as img:
        assert img.size == (64, LABEL_PX + LABEL_PX + 36)


def test_cli_refuses_an_unknown_view_listing_the_registry(runner, scene, tmp_path):
    result = invoke(runner, "render", scene / "gt", "--views", "back", "--out", tmp_path / "fig")
    assert result.exit_code == 2 and f"choose from {', '.join(VIEWS)}" in " ".join(result.stderr.split())


def test_render_and_export_read_a_tool_output_with_from(runner, tmp_path, model, model_path, camera):
    """--from on render (the first SEQ) and export: the same pictures and glTF as after `rotavat import`."""
    import _format_fixtures as F

    # BEV's meshes take their faces from the model (model_path)
    src = F.write_bev(tmp_path / "bev", F.default_scene(model, camera), camera.image_size)
    imported = tmp_path / "x" / "bev"  # named like the source: the row labels are the same
    assert invoke(runner, "import", "--from", "bev", src, imported, "--smpl-model", model_path, "-q").exit_code == 0
    cam = tmp_path / "cam.yaml"
    assert invoke(runner, "calibrate", imported, "--out", cam, "--focal", camera.focal_px, "-q").exit_code == 0
    common = ["--camera", cam, "--size", *map(str, SIZE), "--renderer", "fallback", "-q"]
    a = invoke(runner, "render", "--from", "bev", src, "--smpl-model", model_path, "--out", tmp_path / "a", *common)
    b = invoke(runner, "render", imported, "--out", tmp_path / "b", *common)
    assert a.exit_code == 0 and b.exit_code == 0, a.stderr + b.stderr
    png = sorted((tmp_path / "b").glob("*.png"))[0].name
    assert np.array_equal(np.asarray(Image.open(tmp_path / "a" / png)), np.asarray(Image.open(tmp_path / "b" / png)))
    e1 = invoke(runner, "export", "--from", "bev", src, "--smpl-model", model_path, "--camera", cam, "--out", tmp_path / "a.glb",
                "-q")
    e2 = invoke(runner, "export", imported, "--camera", cam, "--out", tmp_path / "b.glb", "-q")
    assert e1.exit_code == 0 and e2.exit_code == 0, e1.stderr + e2.stderr
    assert (tmp_path / "a.glb").read_bytes() == (tmp_path / "b.glb").read_bytes()


# ---- issue 19: every sequence renderable, error visible ------------------------------------------
def _joints_row(camera: Camera, ground_xz: np.ndarray, ids: list[int], label: str = "joints") -> RowFrame:
    """SMPL-24 joints of the synthetic bodies standing at world ground points, no vertices."""
    lib = load_bodies()
    P = len(ids)
    pos = np.stack([ground_xz[:, 0], np.zeros(P), ground_xz[:, 1]], axis=1)
    joints_cam = camera.cam_from_world(lib.joints[np.arange(P) % len(lib)] + pos[:, None, :])
    return RowFrame(label, np.zeros((P, 0, 3)), np.zeros((0, 3), np.int64), np.asarray(ids), camera.image_size,
                    camera.focal_px, camera.principal_point, camera, joints_cam=joints_cam, joints_layout="smpl24")


def test_joint_layouts_give_bones_by_name():
    assert layout_bones("smpl24")[:4] == ((0, 1), (0, 2), (0, 3), (1, 4))  # SMPL's kintree: pelvis -> hips, spine
    assert len(layout_bones("smpl24")) == 23 and len(layout_bones("smplx127")) == 21  # SMPL-X: no SMPL hand joints
    assert (8, 9) in layout_bones("phalp44 (OpenPose-25 + 19 extra)")  # OpenPose mid_hip -> right_hip
    assert layout_bones("cliff45x") is None and layout_bones(None) is None
    assert layout_name(None, 24) == "smpl24" and layout_name("phalp44 (...)", 44) == "phalp44"
    assert layout_name("phalp44", 10) is None  # a declared layout longer than the joints: not that layout


def test_joints_only_row_draws_its_skeleton_where_the_joints_project(rasterizer):
    cam = _camera()
    row = _joints_row(cam, np.array([[-1.5, -5.0], [0.0, -5.5], [1.5, -6.5]]), [0, 1, 2])
    assert row.kind == "skeleton"
    panel = render_panel(row, front_view(row, cam.image_size), rasterizer.rasterize, STYLE, labels=False)
    masks = _masks(panel)
    for p in range(3):
        uv = cam.project(row.joints_cam[p])
        inside = np.floor(uv).astype(int)
        hit = masks[p][inside[:, 1], inside[:, 0]]
        assert hit.mean() >= 0.9, f"person {p}: {hit.sum()} of 24 joints covered"
        r_px = 1.5 * JOINT_RADIUS_M * cam.focal_px / row.joints_cam[p, :, 2].min() + PX_TOL
        expected = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
        np.testing.assert_allclose(_box(masks[p]), expected + [-r_px, -r_px, r_px, r_px], atol=r_px)


def test_joints_only_skeleton_stands_on_the_side_view_ground(rasterizer):
    cam = _camera()
    row = _joints_row(cam, np.array([[0.0, -6.0], [0.5, -9.0]]), [0, 1])
    ext = scene_extents([row], ("side",), SIZE, STYLE.margin)["side"]
    view = ortho_view("side", cam, ext, SIZE)
    masks = _masks(render_panel(row, view, rasterizer.rasterize, STYLE, labels=False))
    lib = load_bodies()
    for p in range(2):
        lowest_joint_m = lib.joints[p, :, 1].min()  # the feet joints' height above the ground
        v_expected = project_view_px(view.clip_from_world, np.array([0.0, lowest_joint_m, 0.0]), SIZE)[1]
        r_px = JOINT_RADIUS_M * ext.px_per_m
        assert abs(_box(masks[p])[3] - v_expected) <= r_px + PX_TOL + 1


def test_point_cloud_row_covers_the_mesh_silhouette(rasterizer):
    cam = _camera()
    mesh = _people_row(cam, np.array([[-1.0, -6.0], [1.2, -8.0]]), [0, 1])
    cloud = RowFrame("cloud", mesh.verts_cam, np.zeros((0, 3), np.int64), mesh.person_ids, mesh.image_size,
                     mesh.focal_px, mesh.principal_point, cam)
    assert cloud.kind == "points"
    view = front_view(mesh, cam.image_size)
    a = _masks(render_panel(mesh, view, rasterizer.rasterize, STYLE, labels=False))
    b = _masks(render_panel(cloud, view, rasterizer.rasterize, STYLE, labels=False))
    for p in range(2):
        assert (a[p] & b[p]).sum() / a[p].sum() > 0.9  # the points close into the body's shape...
        assert (a[p] & b[p]).sum() / (a[p] | b[p]).sum() > 0.65  # ...a pixel thicker at most


def test_person_ids_are_labelled_above_each_person():
    cam = _camera()
    row = _people_row(cam, np.array([[-2.5, -9.0], [2.5, -9.0]]), [4, 17])
    view = front_view(row, cam.image_size)
    bare = render_panel(row, view, rasterize_numpy, STYLE, labels=False).astype(int)
    labelled = render_panel(row, view, rasterize_numpy, STYLE, labels=True).astype(int)
    changed = np.abs(bare - labelled).max(axis=-1) > 30
    for p in range(2):
        uv = cam.project(row.verts_cam[p])
        x0, x1, top = uv[:, 0].min(), uv[:, 0].max(), uv[:, 1].min()
        ys, xs = np.nonzero(changed[:, int(x0) - 10:int(x1) + 10])
        assert len(ys) > 10 and ys.max() <= top + 2 and ys.min() >= top - 25  # just above the head
    assert not changed[int(cam.project(row.verts_cam).reshape(-1, 2)[:, 1].max()) + 3:].any()  # nothing below


def test_default_palette_is_distinct_for_20_people():
    palette = RenderStyle().palette
    assert len(palette) >= 20 and len(set(palette)) == len(palette)

    def lab(rgb):  # sRGB -> CIELAB (D65)
        c = np.asarray(rgb, dtype=float)
        lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
        xyz = lin @ np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]).T
        f = np.cbrt(xyz / [0.95047, 1.0, 1.08883])
        return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])], axis=-1)

    L = lab(palette[:20])
    d = np.linalg.norm(L[:, None] - L[None], axis=-1) + 1e9 * np.eye(20)
    assert d.min() > 25  # clearly different colours (CIE76), the 12 of a crowd and more
    assert np.linalg.norm(L - lab(RenderStyle().background), axis=-1).min() > 35  # and all stand out
    assert len({tuple(c) for c in person_colors(np.arange(20), palette)}) == 20


def test_tick_marks_are_metres_from_the_camera():
    cam = _camera()
    row = _people_row(cam, np.array([[0.0, -6.0], [1.0, -14.0]]), [0, 1])
    for kind in ("side", "top"):
        ext = scene_extents([row], (kind,), SIZE, STYLE.margin, fit="camera")[kind]
        view = ortho_view(kind, cam, ext, SIZE)
        xs, ys = tick_marks(view)
        assert len(xs) >= 3 and len(ys) >= 2
        step = xs[1][0] - xs[0][0]
        assert step in (0.5, 1.0, 2.0, 5.0, 10.0)
        B = ortho_basis_world(kind, cam)
        foot = cam.center_world * [1, 0, 1]
        for u, x in xs:  # panel x of tick u = the world point u metres along the panel's right axis
            assert abs(project_view_px(view.clip_from_world, foot + u * B[0], SIZE)[0] - x) < 1e-6
        for v, y in ys:
            assert abs(project_view_px(view.clip_from_world, foot + v * B[1], SIZE)[1] - y) < 1e-6
    side_ys = tick_marks(ortho_view("side", cam, scene_extents([row], ("side",), SIZE, 0.05)["side"], SIZE))[1]
    ground_y = dict(side_ys)[0.0]  # the side view's height 0 is the ground line
    assert abs(ground_y - project_view_px(ortho_view("side", cam, scene_extents([row], ("side",), SIZE, 0.05)["side"],
                                                     SIZE).clip_from_world, np.zeros(3), SIZE)[1]) < 1e-6


def test_side_view_draws_the_camera_at_its_height_and_its_field_of_view(rasterizer):
    cam = Camera((320, 180), 200.0, None, np.deg2rad(20.0), 0.0, 4.0)  # no roll: edges at pitch +- vfov/2
    row = _people_row(cam, np.array([[0.0, -8.0]]), [0])
    ext = scene_extents([row], ("side",), SIZE, STYLE.margin, fit="camera")["side"]
    view = ortho_view("side", cam, ext, SIZE)
    panel = render_panel(row, view, rasterizer.rasterize, STYLE, labels=False).astype(int)
    magenta = (np.abs(panel - [255, 0, 255]).max(axis=-1) <= 3)
    cu, cv = project_view_px(view.clip_from_world, cam.center_world, SIZE)
    assert magenta[int(cv), int(cu)]  # the camera dot at its position...
    v_ground = project_view_px(view.clip_from_world, np.zeros(3), SIZE)[1]
    assert abs((v_ground - cv) / ext.px_per_m - 4.0) < 0.02  # ...4 m above the ground line
    wedge = side_fov_px(view, cam)  # camera, lower edge's ground hit, ..., upper edge's end
    lower_deg = 20.0 + np.rad2deg(cam.vertical_fov_rad) / 2
    hit_m = 4.0 / np.tan(np.deg2rad(lower_deg))  # where the lower edge meets the ground, ahead of the camera
    np.testing.assert_allclose(wedge[1], project_view_px(view.clip_from_world, hit_m * ortho_basis_world("side", cam)[0],
                                                         SIZE), atol=1e-6)
    upper = wedge[-1] - wedge[0]
    assert np.isclose(np.rad2deg(np.arctan2(-upper[1], upper[0])), np.rad2deg(cam.vertical_fov_rad) / 2 - 20.0, atol=1e-6)  # rising
    # framed on the people, the camera is off the panel: a marker on the left edge at its height
    ext = scene_extents([row], ("side",), SIZE, STYLE.margin)["side"]
    view = ortho_view("side", cam, ext, SIZE)
    cu, cv = project_view_px(view.clip_from_world, cam.center_world, SIZE)
    assert cu < 0
    panel = render_panel(row, view, rasterizer.rasterize, STYLE, labels=False).astype(int)
    ys, xs = np.nonzero(np.abs(panel - [255, 0, 255]).max(axis=-1) <= 3)
    near = xs < 20
    assert near.sum() > 10 and abs(np.median(ys[near]) - np.clip(cv, 0, SIZE[1])) < 12


def test_ghost_is_drawn_faintly_over_the_row_in_its_camera(rasterizer):
    cam = _camera()
    aligned = _people_row(cam, np.array([[0.0, -8.0]]), [0], label="aligned")
    gt = _people_row(cam, np.array([[0.0, -9.0]]), [0], label="gt")  # the truth 1 m farther
    row = RowFrame(aligned.label, aligned.verts_cam, aligned.faces, aligned.person_ids, aligned.image_size,
                   aligned.focal_px, aligned.principal_point, cam, ghost=gt)
    ext = scene_extents([row], ("side",), SIZE, STYLE.margin)["side"]  # the window holds the ghost too
    view = ortho_view("side", cam, ext, SIZE)
    plain = render_panel(aligned, view, rasterizer.rasterize, STYLE, labels=False).astype(float)
    ghosted = render_panel(row, view, rasterizer.rasterize, STYLE, labels=False).astype(float)
    truth = _masks(render_panel(gt, view, rasterizer.rasterize, STYLE, labels=False))[0]
    body = _masks(plain.astype(np.uint8))[0]
    only_ghost = truth & ~body
    diff = np.abs(ghosted[only_ghost] - plain[only_ghost]).max(axis=-1)
    assert only_ghost.sum() > 100 and np.mean(diff > 20) > 0.9  # the ghost shows where the truth is...
    red = ghosted[only_ghost][:, 0] - ghosted[only_ghost][:, 1]
    assert np.median(red) < 0.6 * 255  # ...faintly (its fill is mostly background)
    assert np.abs(ghosted[body & ~truth] - plain[body & ~truth]).max() < 1.0  # the row's own body is untouched
    front = front_view(row, cam.image_size)  # the camera's view: no ghost (every body fits its own pixels there)
    assert np.array_equal(render_panel(row, front, rasterizer.rasterize, STYLE, labels=False),
                          render_panel(aligned, front, rasterizer.rasterize, STYLE, labels=False))


def test_front_view_frames_the_people_or_the_whole_image():
    cam = Camera((3840, 2160), 1800.0, None, np.deg2rad(10.0), 0.0, 8.0)
    row = _people_row(cam, np.array([[-3.0, -80.0], [3.0, -90.0]]), [0, 1])
    uv = cam.project(row.verts_cam).reshape(-1, 2)
    crop = scene_extents([row], ("front",), SIZE, STYLE.margin)["front"]
    x0, y0, x1, y1 = crop.box_px
    assert x0 <= uv[:, 0].min() and x1 >= uv[:, 0].max() and y0 <= uv[:, 1].min() and y1 >= uv[:, 1].max()
    assert (x1 - x0) < 0.4 * 3840 and np.isclose((x1 - x0) / (y1 - y0), SIZE[0] / SIZE[1])
    assert scene_extents([row], ("front",), SIZE, STYLE.margin, fit="camera")["front"] is None
    tall = [np.ptp(np.nonzero(_masks(render_panel(row, front_view(row, SIZE, c), rasterize_numpy, STYLE, labels=False))[0])[0])
            for c in (None, crop)]
    assert tall[1] > 2.5 * tall[0]  # framed on the people, they are bigger


def test_rows_are_placed_by_their_own_camera(runner, scene, tmp_path):
    """--camera is for the rows without a camera.yaml: the ground truth stays in its true camera."""
    from rotavat_cli.geometry.camera import camera_parameters
    from rotavat_cli.sequence import write_camera_yaml

    gt_cam = open_sequence(scene / "gt").camera
    wrong = gt_cam.replace(pitch_rad=gt_cam.pitch_rad + np.deg2rad(5.0), height_m=gt_cam.height_m + 0.4)
    write_camera_yaml(tmp_path / "wrong.yaml", wrong)
    seqs = [open_sequence(scene / "pred"), open_sequence(scene / "gt")]
    summary = render_sequences(seqs, tmp_path / "fig", FigureOptions(camera_path=tmp_path / "wrong.yaml",
                                                                     views=("side",), renderer="fallback", size=(160, 90)))
    p_wrong, p_gt = camera_parameters(wrong), camera_parameters(gt_cam)
    assert f"pitch {p_wrong['pitch_deg']:.1f}°" in summary.captions["pred"]  # no camera.yaml: --camera
    assert f"pitch {p_gt['pitch_deg']:.1f}°" in summary.captions["gt"] and f"height {p_gt['height_m']:.2f} m" in summary.captions["gt"]
    assert summary.gt == "gt" and summary.captions["gt"].startswith("ground truth")
    assert sequence_camera(seqs[1], tmp_path / "wrong.yaml", own_first=True) == gt_cam  # render's rule for rows
    assert sequence_camera(seqs[1], tmp_path / "wrong.yaml") == read_camera_yaml(tmp_path / "wrong.yaml")[0]  # export's


def test_captions_give_the_frame_metrics_against_the_ground_truth(scene, tmp_path):
    from rotavat_cli.metrics.evaluate import evaluate

    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    expected = evaluate(pred, gt, frames=(1, 2)).metrics  # frame 000001 alone
    caption = metrics_caption(pred, gt, "000001")
    assert f"W-MPJPE {expected['w_mpjpe']:.0f} mm" in caption and "(4/4 matched)" in caption
    assert f"lean {expected['lean_deg']:.1f}°" in caption and f"foot height {expected['foot_height']:.0f} mm" in caption
    assert expected["w_mpjpe"] > 100  # a raw prediction: the number says something
    assert ground_truth_row("auto", ["pred", "gt"]) == 1 and ground_truth_row("auto", ["a", "b"]) is None
    with pytest.raises(RotavatError, match="names no row"):
        ground_truth_row("truth", ["pred", "gt"])


def test_cli_ghost_needs_a_ground_truth_row(runner, scene, tmp_path):
    result = invoke(runner, "render", scene / "pred", "--camera", scene / "gt" / "camera.yaml", "--ghost", "gt",
                    "--out", tmp_path / "fig")
    assert result.exit_code == 2 and "--ghost gt needs a ground-truth row" in result.stderr
    assert len(result.stderr.strip().splitlines()) <= 3
    summary = _json(invoke(runner, "render", scene / "pred", scene / "gt", "--camera", scene / "gt" / "camera.yaml",
                           "--ghost", "gt", "--gt", "2", "--out", tmp_path / "fig2", "--size", "160", "90",
                           "--renderer", "fallback", "--json"))
    assert summary["gt"] == "gt" and "W-MPJPE" in summary["captions"]["pred"]


def test_cli_joints_only_sequence_renders_every_view_and_exports(runner, tmp_path):
    """A joints-only import (no vertices, no faces) renders in every view and exports as a skeleton."""
    cam = _camera()
    row = _joints_row(cam, np.array([[-1.0, -7.0], [1.5, -9.0]]), [3, 5])
    seq = tmp_path / "joints"
    seq.mkdir()
    (seq / "meta.yaml").write_text("image_size: [320, 180]\nfocal_length: 200.0\nfocal_kind: camera\n"
                                   "import: {format: test, joints_layout: smpl24}\n")
    np.savez(seq / "000000.npz", joints=row.joints_cam.astype(np.float32), person_ids=np.array([3, 5]))
    from rotavat_cli.sequence import write_camera_yaml

    write_camera_yaml(seq / "camera.yaml", cam)
    summary = _json(invoke(runner, "render", seq, "--out", tmp_path / "fig", "--size", "160", "90", "--renderer",
                           "fallback", "--glb", "--json"))
    assert summary["views"] == list(VIEWS) and (tmp_path / "fig" / "000000.png").exists()
    result = invoke(runner, "export", seq, "--frame", "0", "--out", tmp_path / "s.glb", "--json")  # one still frame
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["drawn_as"] == "skeleton"
    import trimesh

    loaded = trimesh.load(tmp_path / "s.glb", force="scene")
    person = loaded.geometry["joints/person_5"]
    transform, _ = loaded.graph["joints/person_5"]
    pts = trimesh.transform_points(person.vertices, transform)
    joints_world = cam.world_from_cam(row.joints_cam[1])
    dist = np.linalg.norm(pts[:, None] - joints_world[None], axis=-1).min(axis=0)
    assert dist.max() < 0.05  # a ball at every joint, in the world frame
    assert abs(pts[:, 1].min() - (load_bodies().joints[1, :, 1].min() - JOINT_RADIUS_M)) < 0.01


def test_cli_progress_counts_the_frames_and_out_keeps_no_stale_pictures(runner, scene, tmp_path):
    seqs = [open_sequence(scene / "gt")]
    calls = []
    opts = FigureOptions(every=1, renderer="fallback", size=(64, 36), views=("side",))
    assert figure_steps(seqs, opts) == 3
    render_sequences(seqs, tmp_path / "a", opts, lambda: calls.append(1))
    assert len(calls) == 3
    opts = FigureOptions(every=1, renderer="fallback", size=(64, 36), views=("side",), plots=True)
    calls.clear()
    render_sequences(seqs, tmp_path / "b", opts, lambda: calls.append(1))
    assert figure_steps(seqs, opts) == 6 == len(calls)  # 3 rendered frames + 3 frames read for the plots
    out = tmp_path / "fig"
    for frames in ("0,1", "2"):
        result = invoke(runner, "render", scene / "gt", "--frames", frames, "--out", out, "--size", "64", "36",
                        "--renderer", "fallback", "-q")
        assert result.exit_code == 0, result.stderr
    assert sorted(p.name for p in out.glob("*.png")) == ["000002.png"]


def test_track_plots_measure_foot_height_lean_and_stature(scene, tmp_path):
    gt = open_sequence(scene / "gt")
    tracks = sequence_tracks(gt, gt.camera, "gt")
    assert tracks.ids == [0, 1, 2, 3] and tracks.source == "mesh landmarks"
    heights = np.array([v for series in tracks.values["foot_height_m"].values() for _, v in series])
    leans = np.array([v for series in tracks.values["lean_deg"].values() for _, v in series])
    assert len(heights) == 12 and np.abs(heights).max() < 0.02 and leans.max() < 3.0  # the truth stands upright on the ground
    frame = gt.read_frame("000000")
    feet, heads = foot_head_points(frame.data["vertices"])
    stature = dict(tracks.values["stature_m"][int(frame.person_ids[0])])[0]
    assert stature == pytest.approx(np.linalg.norm(heads[0] - feet[0]))
    png = plot_tracks(tmp_path / "t.png", tracks, RenderStyle().palette)
    with Image.open(png) as img:
        assert img.size == (900, 720)
        pixels = np.asarray(img.convert("RGB")).reshape(-1, 3)
    for rgb in person_colors(np.array(tracks.ids), RenderStyle().palette):  # one line per track, in its colour
        assert (np.abs(pixels.astype(int) - np.round(255 * np.asarray(rgb))).max(axis=1) <= 2).sum() > 50


def test_mp4_is_the_rendered_frames(runner, scene, tmp_path):
    av = pytest.importorskip("av")
    summary = _json(invoke(runner, "render", scene / "gt", "--every", "1", "--mp4", "--out", tmp_path / "fig",
                           "--size", "81", "45", "--views", "side", "--renderer", "fallback", "--json"))
    assert str(tmp_path / "fig" / "render.mp4") in summary["files"]
    with av.open(str(tmp_path / "fig" / "render.mp4")) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert len(frames) == 3 and frames[0].shape == (LABEL_PX + LABEL_PX + 46, 82, 3)  # padded to even sizes
    with Image.open(tmp_path / "fig" / "000000.png") as img:
        png = np.asarray(img).astype(int)
    assert np.abs(frames[0][:png.shape[0], :png.shape[1]].astype(int) - png).mean() < 12  # lossy, but the same picture


def test_mp4_without_the_extra_says_how_to_install(runner, scene, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "av", None)  # as without rotavat[video]: import fails
    result = invoke(runner, "render", scene / "gt", "--mp4", "--out", tmp_path / "fig")
    assert result.exit_code == 2 and "pip install 'rotavat[video]'" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "fig").exists()


def test_scale_row_gives_each_row_its_window(scene, tmp_path):
    seqs = [open_sequence(scene / "pred"), open_sequence(scene / "gt")]
    cam = seqs[1].camera
    rows = [read_row(s, "000000", s.path.name, cam) for s in seqs]
    own = [scene_extents([r], ("side",), SIZE, STYLE.margin)["side"] for r in rows]
    shared = scene_extents(rows, ("side",), SIZE, STYLE.margin)["side"]
    assert max(e.px_per_m for e in own) > 1.5 * shared.px_per_m  # the prediction's depth error widens a shared window
    figure = render_sequences(seqs, tmp_path / "fig", FigureOptions(views=("side",), renderer="fallback", size=SIZE,
                                                                    camera_path=scene / "gt" / "camera.yaml"))
    assert figure.rows == ["pred", "gt"]


# ---- the camera gate ------------------------------------------------------------------------------
def _gt_with_camera(scene: Path, dst: Path, **extra) -> Path:
    """A copy of the ground truth (frame 0) whose camera.yaml lists implausible findings (plus ``extra`` fit keys)."""
    from _camera_gate import implausible

    dst.mkdir(parents=True)
    (dst / "000000.npz").write_bytes((scene / "gt" / "000000.npz").read_bytes())
    (dst / "meta.yaml").write_text((scene / "gt" / "meta.yaml").read_text())
    implausible(scene / "gt" / "camera.yaml", dst / "camera.yaml", **extra)
    return dst


FAST_RENDER = ("--views", "side", "--renderer", "fallback", "--size", "160", "90")


def test_render_refuses_a_row_with_an_implausible_camera_unless_accepted(runner, scene, tmp_path):
    from _camera_gate import FINDINGS, assert_doc_link_exists, assert_named_flags_exist, error_line

    seq = _gt_with_camera(scene, tmp_path / "truth")
    result = invoke(runner, "render", seq, *FAST_RENDER, "--out", tmp_path / "fig")
    assert result.exit_code == 2
    message = error_line(result.stderr)
    assert message.startswith(f"{seq / 'camera.yaml'}: implausible camera ({FINDINGS[0]}; {FINDINGS[1]}); give what you know: "
                              f"rotavat calibrate {seq} --focal PX --camera-height M [--pitch DEG] (it rewrites")
    assert message.endswith("add --accept-camera to the render command to use it anyway")
    assert_named_flags_exist(message)
    assert_doc_link_exists(message)
    assert not (tmp_path / "fig").exists()
    summary = _json(invoke(runner, "render", seq, *FAST_RENDER, "--out", tmp_path / "fig", "--accept-camera", "--json"))
    assert summary["warnings"] == [f"{seq / 'camera.yaml'}: implausible camera ({FINDINGS[0]}; {FINDINGS[1]}), used anyway "
                                   "(--accept-camera)"]
    accepted = _gt_with_camera(scene, tmp_path / "accepted", accepted=True)  # as align writes it under --accept-camera
    result = invoke(runner, "render", accepted, *FAST_RENDER, "--out", tmp_path / "fig2")
    assert result.exit_code == 0 and "accepted earlier with --accept-camera" in result.stderr, result.stderr


def test_render_gates_the_camera_given_for_rows_without_one(runner, scene, tmp_path):
    from _camera_gate import FINDINGS, error_line, implausible, write_camera

    bad = implausible(scene / "gt" / "camera.yaml", tmp_path / "bad.yaml")
    result = invoke(runner, "render", scene / "pred", scene / "gt", "--camera", bad, *FAST_RENDER, "--out", tmp_path / "fig")
    assert result.exit_code == 2
    message = error_line(result.stderr)
    assert message.startswith(f"{bad} (--camera, for {scene / 'pred'}): implausible camera ({FINDINGS[0]};")
    assert "render --camera FILE (a camera.yaml you wrote: docs/conventions.md#camerayaml)" in message
    plain = write_camera(scene / "gt" / "camera.yaml", tmp_path / "plain.yaml", {"implausible": []})
    result = invoke(runner, "render", scene / "pred", scene / "gt", "--camera", plain, *FAST_RENDER, "--out", tmp_path / "fig")
    assert result.exit_code == 0 and "implausible" not in result.stderr, result.stderr


def test_an_aligned_output_with_an_implausible_camera_is_sent_back_to_align():
    from rotavat_cli.alignment import check_fit, render_remedies

    with pytest.raises(RotavatError, match=r"rotavat align INPUT --out out/pred_aligned, INPUT being the sequence"):
        check_fit("out/pred_aligned/camera.yaml", {"implausible": ["pitch undetermined"]}, False,
                  render_remedies("out/pred_aligned", own=True, aligned=True))


# ---- issue 24: odd image sizes, flagged people, messages that run ---------------------------------
def _photo_row(image_size: tuple[int, int], photo_size: tuple[int, int] | None = None) -> RowFrame:
    """A row without people over a solid magenta photo (``photo_size``, default the image size)."""
    w, h = photo_size or image_size
    photo = np.zeros((h, w, 3), np.uint8)
    photo[..., 0] = photo[..., 2] = 255
    return RowFrame("photo", np.zeros((0, 0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64), image_size,
                    float(max(image_size)), (image_size[0] / 2, image_size[1] / 2), image=photo)


def _front_background(row: RowFrame, size: tuple[int, int], crop: FrontCrop | None) -> tuple[np.ndarray, PanelView]:
    """The front view's background (letterbox + photo) of a row in a panel, and the view."""
    view = front_view(row, size, crop)
    img = Image.new("RGB", size, (0, 0, 0))
    REGISTRY["front"].under(img, view, row, STYLE)
    return np.asarray(img).astype(int), view


def test_front_view_pastes_a_500x493_photo_letterboxed():
    """Issue 24: a 500x493 photo letterboxed in a 640x360 panel starts at x = 137.45 px, which rounded to 137
    asked Pillow for the photo from x = -0.6 ("box offset can't be negative")."""
    row = _photo_row((500, 493))
    panel, view = _front_background(row, (640, 360), None)
    x0, _, x1, _ = view.image_rect
    assert x0 == pytest.approx(137.45, abs=0.01)
    magenta = (panel[..., 0] > 240) & (panel[..., 1] < 15) & (panel[..., 2] > 240)
    cols = np.nonzero(magenta.all(axis=0))[0]
    assert cols.min() <= x0 + 1 and cols.max() >= x1 - 2  # the photo fills its rectangle...
    assert not magenta[:, : int(x0) - 1].any() and not magenta[:, int(x1) + 2:].any()  # ...and no more


def test_front_view_pastes_every_image_size_and_crop():
    """Random image, photo and panel sizes, whole or cropped (crops overhanging the image included): the photo
    always lands, never asking Pillow for a negative offset or for more than the photo."""
    rng = np.random.default_rng(0)
    for _ in range(150):
        image_size = tuple(int(v) for v in rng.integers(16, 1200, 2))
        photo_size = tuple(int(v) + int(d) for v, d in zip(image_size, rng.integers(-1, 2, 2)))  # inferred sizes: +-1 px
        size = tuple(int(v) for v in rng.integers(16, 400, 2))
        crop = None
        if rng.random() < 0.6:  # a crop: may be wider or taller than the image, offsets fractional
            w = rng.uniform(0.05, 1.5) * image_size[0]
            h = w * size[1] / size[0]
            cx, cy = rng.uniform(0, image_size[0]), rng.uniform(0, image_size[1])
            crop = FrontCrop((cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2))
        row = _photo_row(image_size, photo_size)
        panel, view = _front_background(row, size, crop)
        boxes = paste_boxes_px(view.image_rect, size, photo_size)
        if boxes is None:
            continue
        (b0, b1, b2, b3), (s0, s1, s2, s3) = boxes
        assert 0 <= b0 < b2 <= size[0] and 0 <= b1 < b3 <= size[1]
        assert 0 <= s0 < s2 <= photo_size[0] and 0 <= s1 < s3 <= photo_size[1]
        inner = panel[b1 + 1:b3 - 1, b0 + 1:b2 - 1]
        assert inner.size == 0 or (np.abs(inner - [255, 0, 255]).max() <= 2)


def _move_and_flag(aligned: Path, frame: str, person_id: int, ahead_m: float, flag: str) -> None:
    """Move one person of an aligned frame ``ahead_m`` further along the ground, away from the camera, and
    give it ``flag`` in people.csv (as align does for a half-visible bystander sent far away)."""
    import csv

    cam = open_sequence(aligned).camera
    with np.load(aligned / f"{frame}.npz") as npz:
        data = dict(npz)
    p = int(np.nonzero(data["person_ids"] == person_id)[0][0])
    shift_world = ahead_m * horizontal_forward_world(cam)
    for key in ("vertices", "joints"):
        moved = cam.cam_from_world(cam.world_from_cam(data[key][p].astype(np.float64)) + shift_world)
        data[key][p] = moved.astype(data[key].dtype)
    np.savez(aligned / f"{frame}.npz", **data)
    with open(aligned / "people.csv", encoding="utf-8", newline="") as handle:
        records = list(csv.DictReader(handle))
    for r in records:
        if r["frame"] == frame and int(r["person_id"]) == person_id:
            r["flag"] = flag
    with open(aligned / "people.csv", "w", encoding="utf-8", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(records[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(records)


def _window_box_m(extent, size: tuple[int, int]) -> np.ndarray:
    """(2, 2) min/max of an orthographic window in its view plane, metres."""
    half = np.array(size, dtype=float) / 2 / extent.px_per_m
    return np.stack([np.asarray(extent.center_m) - half, np.asarray(extent.center_m) + half])


def test_side_and_top_windows_frame_the_plausible_people_and_mark_the_flagged(runner, scene, tmp_path, monkeypatch):
    """Issue 24: a person align flagged, 30 m behind the group, no longer shrinks the group to specks: the
    side/top windows hold the others and not it; it is drawn with its flag, an edge marker points to it and the
    caption says what the mark means."""
    import rotavat_cli.render.sequences as figure_module

    aligned = tmp_path / "aligned"
    assert invoke(runner, "align", scene / "pred", "--camera", scene / "gt" / "camera.yaml", "--out", aligned,
                  "-q").exit_code == 0
    _move_and_flag(aligned, "000000", 1, 30.0, "implausible_stature")
    seen = {}
    draw_grid = figure_module.render_grid

    def spy(rows, views, size, rasterize, style, extents=None, **kwargs):
        seen.update(rows=rows, extents=extents)
        seen["image"] = draw_grid(rows, views, size, rasterize, style, extents, **kwargs)
        return seen["image"]

    monkeypatch.setattr(figure_module, "render_grid", spy)
    size = (320, 180)
    summary = render_sequences([open_sequence(aligned)], tmp_path / "fig",
                               FigureOptions(views=("side", "top"), renderer="fallback", size=size, style=STYLE))
    row, extents = seen["rows"][0], seen["extents"][0]
    assert row.flags == ("", "implausible_stature", "", "")  # read from people.csv, by frame and person_id
    for kind in ("side", "top"):
        window = _window_box_m(extents[kind], size)
        for p in range(4):
            lo, hi = ortho_bounds(kind, row.camera, row.points_cam[p])[:, :2]
            if p == 1:  # the flagged one: outside the window
                assert np.any(lo > window[1]) or np.any(hi < window[0]), (kind, lo, hi, window)
            else:  # the others: inside it
                assert np.all(lo >= window[0]) and np.all(hi <= window[1]), (kind, p, lo, hi, window)
    assert "1 flagged in people.csv (outlined label: id and flag; not framed in side/top)" in summary.captions["aligned"]
    side = seen["image"][_panel_top(0):_panel_top(0) + size[1], :size[0]]
    top = seen["image"][_panel_top(0):_panel_top(0) + size[1], size[0]:]
    green = 1  # person 1's colour in STYLE's palette: only its edge markers are green
    assert _masks(side)[green][:, -16:].sum() > 10  # ahead of the camera: off the side panel's right edge
    assert _masks(top)[green][:16].sum() > 10  # ahead of the camera: off the top panel's top edge
    # without people.csv's flags the same person widens the windows to hold it; with nobody plausible, everyone is framed
    plain = dataclasses.replace(row, flags=None)
    assert scene_extents([plain], ("side",), size, STYLE.margin)["side"].px_per_m < 0.5 * extents["side"].px_per_m
    everyone_flagged = dataclasses.replace(row, flags=("sitting",) * 4)
    assert scene_extents([everyone_flagged], ("side",), size, STYLE.margin) == scene_extents([plain], ("side",), size,
                                                                                            STYLE.margin)
    assert people_flags(open_sequence(scene / "pred")) is None  # rows without a people.csv have no flags
    (tmp_path / "odd").mkdir()
    (tmp_path / "odd" / "people.csv").write_text("frame,person\n000000,1\n")
    warnings = []
    assert people_flags(dataclasses.replace(open_sequence(aligned), path=tmp_path / "odd"), warnings) is None
    assert warnings == [f"{tmp_path / 'odd' / 'people.csv'}: no person_id, flag column: no person is marked as flagged"]


def test_render_without_a_camera_names_commands_that_run(runner, tmp_path, model, model_path, camera, monkeypatch):
    """Issue 24: `render --from bev FILE` without a camera named `rotavat calibrate FILE`, which fails (not a
    folder); the commands it names now run as written, with the user's paths and --from/--image-size/--smpl-model.
    Issue 26: the camera file they name goes to the current folder, never into the tool's data folder."""
    import shlex

    import _format_fixtures as F

    src = F.write_bev(tmp_path / "data" / "bev", F.default_scene(model, camera), camera.image_size)
    data_before = sorted(p.name for p in (tmp_path / "data").rglob("*"))
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    reader = ["--from", "bev", "--image-size", *map(str, camera.image_size), "--smpl-model", str(model_path)]
    result = invoke(runner, "render", src, *reader, "--size", "160", "90")
    assert result.exit_code == 2 and "Traceback" not in result.stderr, result.output
    message = " ".join(result.stderr.split())
    commands = message.split("`")[1::2]  # the commands, between backquotes
    assert [c.split()[:2] for c in commands] == [["rotavat", "calibrate"], ["rotavat", "render"]], message
    for command in commands:
        assert " ".join(reader) in command, command  # the reading flags, as given
        run = invoke(runner, *shlex.split(command)[1:], "-q")
        assert run.exit_code == 0, (command, run.stderr)
    assert "--camera bev_camera.yaml" in message and (tmp_path / "work" / "bev_camera.yaml").is_file()
    assert sorted((tmp_path / "work" / "bev_render").glob("*.png"))  # the named render's pictures (its default output)
    assert sorted(p.name for p in (tmp_path / "data").rglob("*")) == data_before  # nothing written into the data


def test_render_notes_a_row_whose_own_camera_wins_over_camera(runner, scene, tmp_path):
    """Issue 24: with --camera, a row drawn in its own camera.yaml says so (one note line on stderr)."""
    from rotavat_cli.sequence import write_camera_yaml

    write_camera_yaml(tmp_path / "other.yaml", open_sequence(scene / "gt").camera.replace(height_m=9.0))
    args = ["--views", "side", "--renderer", "fallback", "--size", "160", "90"]
    result = invoke(runner, "render", scene / "pred", scene / "gt", "--camera", tmp_path / "other.yaml", *args,
                    "--out", tmp_path / "a")
    assert result.exit_code == 0, result.stderr
    notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
    assert notes == [f"note: {scene / 'gt'}: drawn in its own camera ({scene / 'gt' / 'camera.yaml'}), not --camera "
                     f"{tmp_path / 'other.yaml'} (--camera is for the rows without one)"]  # pred has none: --camera's
    same = invoke(runner, "render", scene / "pred", scene / "gt", "--camera", scene / "gt" / "camera.yaml", *args,
                  "--out", tmp_path / "b")
    assert same.exit_code == 0 and "note:" not in same.stderr  # its own camera is the one given: nothing to say


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_vertex_normals_are_zero_where_undefined_even_next_to_a_nan_vertex(dtype):
    """Issue 26 made vertex_normals float32-aware; a NaN vertex then left NaN normals on its neighbours, where
    the docstring (and the code before) promised 0."""
    from rotavat_cli.render.style import vertex_normals

    verts = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [5, 5, 5], [np.nan, 0, 0]]], dtype=dtype)
    faces = np.array([[0, 1, 2], [0, 3, 1], [3, 5, 1]])  # vertex 4 in no face; vertex 5 NaN
    n = vertex_normals(verts, faces)
    assert n.dtype == dtype and np.isfinite(n).all()
    np.testing.assert_allclose(n[0, 4], 0.0)  # no face: no normal
    np.testing.assert_allclose(n[0, [3, 5]], 0.0)  # only NaN faces: no normal
    np.testing.assert_allclose(n[0, 2], [0, 0, 1], atol=1e-6)


def test_the_front_view_draws_people_through_the_rows_lens(rasterizer):
    """A row whose people are in a camera with a lens (an aligned output, a ground truth: Sequence.image_lens) is
    drawn where the lens shows them in the image, not where its pinhole would; the side view keeps the true points."""
    lens = _camera().replace(distortion=-0.3)
    row = dataclasses.replace(_people_row(lens, np.array([[-4.5, -7.0], [0.0, -7.0], [4.5, -7.5]]), [0, 1, 2]),
                              lens=lens)
    warped = front_points_cam(row.verts_cam, row)
    pinhole_px = project_cam_to_px(warped, lens.focal_px, lens.principal_point)
    np.testing.assert_allclose(pinhole_px, lens.project(row.verts_cam), atol=1e-9)  # the lens's pixels, exactly
    np.testing.assert_array_equal(warped[..., 2], row.verts_cam[..., 2])  # the depths kept: the same z-buffer
    masks = _masks(render_panel(row, front_view(row, lens.image_size), rasterizer.rasterize, STYLE, labels=False))
    for p in (0, 2):  # the people near the borders: barrel pulls them toward the centre
        uv = lens.project(row.verts_cam[p])
        expected = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
        np.testing.assert_allclose(_box(masks[p]), expected, atol=PX_TOL, err_msg=f"person {p}")
        pinhole = lens.pinhole.project(row.verts_cam[p])
        assert abs(np.median(pinhole[:, 0]) - np.median(uv[:, 0])) > 3 * PX_TOL  # not where the pinhole draws them
    assert front_points_cam(row.verts_cam, dataclasses.replace(row, lens=None)) is row.verts_cam  # no lens: untouched
