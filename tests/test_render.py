"""rotavat render: view geometry, both rasterisers on a small scene (real content), grids and the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import invoke, tree_hash
from PIL import Image

from rotavat_cli.camera import Camera
from rotavat_cli.config import default_config
from rotavat_cli.errors import RotavatError
from rotavat_cli.render import (REGISTRY, RENDERERS, VIEWS, FigureOptions, RenderStyle, RowFrame,
                                clip_from_cam_perspective, fit_ortho_extent, front_view, horizontal_forward_world,
                                open_rasterizer, ortho_basis_world, ortho_view, parse_views, person_colors,
                                project_view_px, rasterize_numpy, read_row, render_grid, render_panel, scene_extents,
                                select_frames)
from rotavat_cli.sequence import open_sequence
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
    panel = render_panel(row, view, rasterizer.rasterize, STYLE)
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
    panel = render_panel(row, view, rasterizer.rasterize, STYLE)
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
    ext = scene_extents([row], ("top",), SIZE, STYLE.margin)["top"]
    view = ortho_view("top", cam, ext, SIZE)
    panel = render_panel(row, view, rasterizer.rasterize, STYLE)
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
    a = render_panel(row, front_view(row, SIZE), rasterizer.rasterize, STYLE).astype(int)
    b = render_panel(flipped, front_view(flipped, SIZE), rasterizer.rasterize, STYLE).astype(int)
    assert np.mean(np.abs(a - b).max(axis=-1) > 8) < 0.002
    masks = _masks(a)
    assert all(m.sum() > 50 for m in masks)


def test_empty_frame_draws_the_scene_without_people(rasterizer):
    cam = _camera()
    lib = load_bodies()
    row = RowFrame("empty", np.zeros((0, lib.vertices.shape[1], 3)), lib.faces, np.zeros(0, int), cam.image_size,
                   cam.focal_px, cam.principal_point, cam)
    fig = render_grid([row], ("front", "side", "top"), SIZE, rasterizer.rasterize, STYLE)
    assert fig.shape == (26 + SIZE[1], 26 + 3 * SIZE[0], 3)
    assert not _masks(fig).any()


@pytest.mark.skipif(not GL, reason="no EGL/OpenGL context on this machine")
def test_renderers_agree():
    cam = _camera()
    row = _people_row(cam, np.array([[-1.5, -5.0], [0.3, -5.5], [1.8, -6.0]]), [0, 1, 2])
    view = front_view(row, SIZE)
    with open_rasterizer("gl") as gl:
        a = render_panel(row, view, gl.rasterize, STYLE)
    b = render_panel(row, view, rasterize_numpy, STYLE)
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
    fig = render_grid([near, far], ("front", "side"), SIZE, rasterize_numpy, STYLE)
    assert fig.shape == (26 + 2 * SIZE[1], 26 + 2 * SIZE[0], 3)
    side = [fig[26 + i * SIZE[1]:26 + (i + 1) * SIZE[1], 26 + SIZE[0]:] for i in range(2)]
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
        rows.append(int(_box(_masks(render_panel(alone, view, rasterize, STYLE))[0])[3]))
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
        assert img.size == (26 + 3 * 200, 26 + 2 * 120)
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
        pixel = np.asarray(img)[26 + 5, 26 + 5].astype(int)  # image corner: no person there
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
        assert img.size == (26 + 64, 26 + 36)


def test_cli_refuses_an_unknown_view_listing_the_registry(runner, scene, tmp_path):
    result = invoke(runner, "render", scene / "gt", "--views", "back", "--out", tmp_path / "fig")
    assert result.exit_code == 2 and f"choose from {', '.join(VIEWS)}" in " ".join(result.stderr.split())


def test_render_and_export_read_a_tool_output_with_from(runner, tmp_path):
    """--from on render (the first SEQ) and export: the same pictures and glTF as after `rotavat import`."""
    import _format_fixtures as F

    camera = F.scene_camera()
    model_path = F.write_synthetic_smpl(tmp_path / "smpl.npz")  # BEV's meshes take their faces from the model
    src = F.write_bev(tmp_path / "bev", F.default_scene(F.load_model(model_path), camera), camera.image_size)
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
