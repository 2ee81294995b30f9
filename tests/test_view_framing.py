"""rotavat view (issue 33, point 5): the 3D view starts framed on the aligned rows, the truth and the camera (a raw
prediction a focal guess puts hundreds of metres off stays drawn, outside), ``--frame-all`` frames everything; each
row tints its people's colours its own way; recordings stay small by default (reduced meshes, scaled-down video
frames) and ``--full-detail`` gives every vertex and the files back. Read back with Rerun's own reader (the
optional extra rotavat[view]: skipped cleanly without it)."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke

from rotavat_cli.alignment import AlignOptions, align_sequence
from rotavat_cli.render.style import RenderStyle, person_colors, rgb8
from rotavat_cli.sequence import open_sequence
from rotavat_cli.synth import SynthOptions, write_synth_scene
from rotavat_cli.view.detail import reduce_mesh, thin_points, video_frame
from rotavat_cli.view.roles import framed_rows, row_role, row_tint, row_tones
from rotavat_cli.view.scene import EYE_FOV_Y_DEG, eye_world

PALETTE = np.array(RenderStyle().palette)


# ---- the rules (no Rerun) ----------------------------------------------------------------------------------
def test_a_rows_role_comes_from_its_meta_and_the_truth_flag():
    assert row_role({"aligned_from": {"focal_kind": "assumed"}, "focal_kind": "camera"}) == "aligned"
    assert row_role({"focal_kind": "camera"}) == "aligned"  # a tool run with the real camera
    assert row_role({"focal_kind": "assumed", "focal_rule": "4dhumans"}) == "raw"
    assert row_role(None) == "raw" and row_role({"focal_kind": "assumed"}, truth=True) == "truth"


def test_the_view_frames_the_aligned_rows_and_the_truth_else_everything():
    assert framed_rows(["raw", "aligned", "truth"]) == [False, True, True]
    assert framed_rows(["raw", "truth"]) == [False, True]
    assert framed_rows(["raw", "raw"]) == [True, True]  # nothing aligned: every row
    assert framed_rows(["raw", "aligned"], frame_all=True) == [True, True]


def test_no_two_rows_share_a_colour_for_any_person():
    roles = ["raw", "aligned", "truth", "raw", "aligned"]
    tinted = [row_tint(PALETTE, tone) for tone in row_tones(roles)]
    assert np.array_equal(tinted[1], PALETTE)  # the first aligned row: the palette as it is
    for i in range(len(roles)):
        for j in range(i + 1, len(roles)):  # every palette colour, the grey #7f7f7f too, differs between rows
            assert np.linalg.norm(tinted[i] - tinted[j], axis=1).min() > 0.08, (roles[i], i, roles[j], j)
    assert np.all((tinted[0] >= 0) & (tinted[0] <= 1))


def test_detail_options_are_whole_numbers():
    from rotavat_cli.view import ViewOptions

    assert ViewOptions(mesh_vertices=1500.0).mesh_vertices == 1500 and ViewOptions().mesh_vertices == 1000
    for bad in (2.5, -1, True):
        with pytest.raises(ValueError, match="mesh_vertices"):
            ViewOptions(mesh_vertices=bad)
    with pytest.raises(ValueError, match="image_max_px must be a whole number, got 640.5"):
        ViewOptions(image_max_px=640.5)


def test_the_documented_tints_are_the_rules():
    """docs/render.md's table of row tints, example column, is what row_tint makes of the palette's red."""
    import re

    from rotavat_cli.render.style import parse_color

    page = (Path(__file__).resolve().parents[1] / "docs" / "render.md").read_text(encoding="utf-8")
    documented = dict(re.findall(r"^\| (aligned|truth|raw) \| [^|]+ \| `(#[0-9a-f]{6})` \|$", page, re.M))
    red = np.array([parse_color("#d62728")])
    made = {role: "#%02x%02x%02x" % tuple(np.round(255 * row_tint(red, tone)[0]).astype(int))
            for role, tone in zip(("aligned", "truth", "raw"), row_tones(["aligned", "truth", "raw"]))}
    assert documented == made


def test_the_eye_sees_the_whole_box_from_the_right_and_above():
    lo, hi = np.array([-3.0, 0.0, -12.0]), np.array([2.0, 5.0, 0.0])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    position, target = eye_world(np.vstack([corners, [[np.nan, 0.0, 0.0]]]))  # a NaN point is left out
    assert _inside_view(position, target, corners).all()
    seen = _on_view(position, target, corners)  # (8, 2) at unit depth: centred on the target
    np.testing.assert_allclose(seen.min(axis=0) + seen.max(axis=0), 0.0, atol=0.02)
    assert position[0] > hi[0] and position[1] > hi[1]  # from the right (the camera's x), above
    assert not _inside_view(position, target, corners * 3.0).all()  # no farther than it has to be


def test_a_mesh_is_reduced_to_at_most_the_asked_vertices_and_keeps_its_soles():
    seq = _sample_gt()
    frame = seq.read_frame(seq.frame_names[0])
    verts = seq.camera.world_from_cam(frame.data["vertices"])  # (P, 6591, 3), Y up
    reduction = reduce_mesh(verts[0], frame.data["faces"], 1000)
    assert 900 <= reduction.vertices <= 1000
    small = reduction.apply(verts)  # one grouping for every body with these faces
    assert small.shape == (len(verts), reduction.vertices, 3) and small.dtype == np.float32
    assert 1.8 * reduction.vertices < len(reduction.faces) < 2.0 * reduction.vertices  # still (nearly) closed
    assert reduction.faces.max() < reduction.vertices
    lift = small[..., 1].min(axis=1) - verts[..., 1].min(axis=1)  # the lowest sole point rises less than 1 cm
    assert np.all((lift >= -1e-6) & (lift < 0.01))
    heights = small[..., 1].max(axis=1) - small[..., 1].min(axis=1)
    np.testing.assert_allclose(heights, verts[..., 1].max(axis=1) - verts[..., 1].min(axis=1), atol=0.02)
    assert reduce_mesh(verts[0], frame.data["faces"], 10_000).vertices == verts.shape[1]  # small enough: as it is


def test_point_clouds_are_thinned_and_video_frames_scaled_down(tmp_path):
    assert thin_points(np.zeros((1, 6591, 3)), 1000).shape == (1, 942, 3) and thin_points(np.zeros((1, 50, 3)), 0).shape[1] == 50
    from PIL import Image

    path = tmp_path / "000000.png"
    Image.new("RGB", (1920, 1080), (200, 30, 30)).save(path)
    data, media_type, size = video_frame(path.read_bytes(), path, 960)
    assert media_type == "image/jpeg" and size == (960, 540) and Image.open(io.BytesIO(data)).size == (960, 540)
    assert video_frame(path.read_bytes(), path, 0) == (path.read_bytes(), "image/png", (1920, 1080))  # 0: the file


# ---- a recording of a 4D-Humans-like prediction (its focal guess puts it ~40x too deep) ---------------------------
@pytest.fixture(scope="module")
def far_scene(tmp_path_factory):
    """pred: an HPS prediction made with 4D-Humans' focal rule (12,500 px for a 297 px camera: ~400 m deep); pred_aligned:
    align's output in the true camera; gt; 1280 x 720 video frames for a 640 x 360 camera; each recorded with the
    defaults and with --full-detail --frame-all."""
    pytest.importorskip("rerun")
    root = tmp_path_factory.mktemp("far")
    write_synth_scene(root, SynthOptions(seed=7, frames=4, people=2, image_size=(640, 360), hps_focal="4dhumans"))
    gt = open_sequence(root / "gt")
    align_sequence(open_sequence(root / "pred"), gt.camera, root / "pred_aligned", AlignOptions(jobs=1))
    from PIL import Image

    (root / "images").mkdir()
    rng = np.random.default_rng(3)
    for name in gt.frame_names:  # noisy frames: a JPEG of camera noise does not shrink to nothing
        pixels = np.clip(rng.normal(120, 40, (720, 1280, 3)), 0, 255).astype(np.uint8)
        Image.fromarray(pixels).save(root / "images" / f"{name}.jpg", quality=90)
    out = {}
    for key, extra in (("default", []), ("full", ["--full-detail", "--frame-all"])):
        result = invoke_view(root, root / f"{key}.rrd", *extra)
        out[key] = json.loads(result.stdout), _read_all(root / f"{key}.rrd")
    return root, out


def invoke_view(root: Path, out: Path, *extra: str):
    from typer.testing import CliRunner

    result = invoke(CliRunner(), "view", root / "pred", root / "pred_aligned", "--gt", root / "gt", "--camera",
                    root / "gt" / "camera.yaml", "--image", root / "images", "--out", out, "--json", *extra)
    assert result.exit_code == 0, result.output
    return result


def test_the_view_starts_framed_on_the_aligned_rows_and_the_truth_with_the_raw_row_outside(far_scene):
    root, out = far_scene
    summary, (data, eye) = out["default"]
    assert summary["framed"] == ["pred_aligned", "gt"]
    assert any(note.startswith("pred (raw): drawn up to ") and "--frame-all frames every row" in note for note in summary["notes"])
    position, target = eye
    camera = open_sequence(root / "gt").camera
    framed = np.vstack([_points(data, "pred_aligned"), _points(data, "gt"), camera.center_world[None]])
    raw = _points(data, "pred")
    assert _inside_view(position, target, framed).all()
    assert not _inside_view(position, target, raw).any()  # still drawn: 400 m off, outside the first view
    assert np.linalg.norm(position - target) < 40.0
    assert np.linalg.norm(raw - camera.center_world, axis=1).min() > 300.0  # where 4D-Humans' focal guess puts it
    lines = np.concatenate([np.asarray(s) for s in _first(data["/world/ground"], "LineStrips3D:strips")])
    assert lines[:, 2].min() > -30.0  # the grid under the framed rows (1 m lines), not over 400 m


def test_frame_all_frames_every_row(far_scene):
    root, out = far_scene
    summary, (data, (position, target)) = out["full"]
    assert summary["framed"] == ["pred", "pred_aligned", "gt"] and not [n for n in summary["notes"] if "(raw)" in n]
    everything = np.vstack([_points(data, row) for row in ("pred", "pred_aligned", "gt")])
    assert _inside_view(position, target, everything).all()
    lines = np.concatenate([np.asarray(s) for s in _first(data["/world/ground"], "LineStrips3D:strips")])
    assert lines[:, 2].min() < everything[:, 2].min()  # the grid reaches the raw row


def test_raw_aligned_and_true_people_differ_in_colour_in_the_scene_and_the_plots(far_scene):
    _, out = far_scene
    _, (data, _) = out["default"]
    for pid in (0, 1):
        albedo = {row: _rgb(_first(data[f"/world/{row}/people/{pid}/mesh"], "Mesh3D:albedo_factor")[0])
                  for row in ("pred", "pred_aligned", "gt")}
        lines = {row: _rgb(_first(data[f"/plots/foot_height_m/{row}/{pid}"], "SeriesLines:colors")[0])
                 for row in ("pred", "pred_aligned", "gt")}
        palette = list(rgb8(tuple(person_colors(np.array([pid]), RenderStyle().palette)[0])))
        for colours in (albedo, lines):
            assert colours["pred_aligned"] == palette  # the aligned row keeps the palette's colour
            assert len({tuple(c) for c in colours.values()}) == 3  # raw, aligned, truth: three colours
        names = {row: _first(data[f"/plots/foot_height_m/{row}/{pid}"], "SeriesLines:names")[0] for row in albedo}
        assert names == {row: f"{row} {pid}" for row in albedo}  # and named by row


def test_default_recordings_stay_small_and_full_detail_gives_everything_back(far_scene):
    root, out = far_scene
    (default, (data, _)), (full, (full_data, _)) = out["default"], out["full"]
    mesh = _first(data["/world/pred_aligned/people/0/mesh"], "Mesh3D:vertex_positions")
    full_mesh = _first(full_data["/world/pred_aligned/people/0/mesh"], "Mesh3D:vertex_positions")
    normals = _first(data["/world/pred_aligned/people/0/mesh"], "Mesh3D:vertex_normals")
    assert len(full_mesh) == 6591 and 900 <= len(mesh) <= 1000 and len(normals) == len(mesh)
    video = [row for _, row in data["/world/camera/image/video"] if row.get("EncodedImage:blob")]
    from PIL import Image

    assert Image.open(io.BytesIO(bytes(video[0]["EncodedImage:blob"][0]))).size == (960, 540)
    np.testing.assert_allclose(video[0]["Transform3D:scale"], [[640 / 960, 360 / 540, 1.0]])  # fills the 640 x 360 pinhole
    full_video = [row for _, row in full_data["/world/camera/image/video"] if row.get("EncodedImage:blob")]
    name = open_sequence(root / "gt").frame_names[0]
    assert bytes(full_video[0]["EncodedImage:blob"][0]) == (root / "images" / f"{name}.jpg").read_bytes()
    # 4 frames x 3 rows x 2 people and 4 noisy 1280 x 720 video frames: 1.66-1.68 MB measured by default (Rerun's
    # chunking moves it by ~1 %), 7.28 MB with --full-detail
    assert default["bytes"] < 2.0e6
    assert full["bytes"] > 3.5 * default["bytes"]


# ---- helpers ---------------------------------------------------------------------------------------------------
def _on_view(position: np.ndarray, target: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, 2) where points show to an eye at ``position`` looking at ``target``: (right, up) at unit depth (NaN
    behind the eye)."""
    forward = (target - position) / np.linalg.norm(target - position)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = np.asarray(points, dtype=np.float64) - position
    depth = rel @ forward
    return np.where(depth[:, None] > 0, np.stack([rel @ right, rel @ up], axis=1) / np.maximum(depth, 1e-12)[:, None], np.nan)


def _inside_view(position: np.ndarray, target: np.ndarray, points: np.ndarray, aspect: float = 1.4) -> np.ndarray:
    """(N,) whether each point lies in the view of an eye at ``position`` looking at ``target`` (the viewer's
    vertical field of view, a panel ``aspect`` wide)."""
    tan_v = math.tan(math.radians(EYE_FOV_Y_DEG) / 2)
    seen = _on_view(position, target, points)
    return (np.abs(seen[:, 0]) <= aspect * tan_v + 1e-6) & (np.abs(seen[:, 1]) <= tan_v + 1e-6)


def _read_all(path: Path) -> tuple[dict[str, list[tuple[int | None, dict]]], tuple[np.ndarray, np.ndarray]]:
    """The recording's data ``{entity: [(frame or None, {component: value})]}`` and its blueprint's eye (position,
    look target), through rerun.chunk.RrdReader."""
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    data: dict[str, list] = {}
    for chunk in reader.stream():
        columns = chunk.to_record_batch().to_pydict()
        frames = columns.get("frame", [None] * chunk.num_rows)
        for r in range(chunk.num_rows):
            data.setdefault(chunk.entity_path, []).append((frames[r], {k: v[r] for k, v in columns.items() if ":" in k}))
    eye = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for key in ("position", "look_target"):
            if f"EyeControls3D:{key}" in batch.schema.names:
                eye[key] = np.array(batch.column(f"EyeControls3D:{key}").to_pylist()[0][0])
    return data, (eye["position"], eye["look_target"])


def _first(rows: list[tuple[int | None, dict]], component: str):
    """The first value of ``component`` among an entity's rows."""
    return next(row[component] for _, row in rows if row.get(component) is not None)


def _points(data: dict, row: str) -> np.ndarray:
    """(N, 3) every mesh vertex a row drew, over every frame."""
    out = [np.asarray(values["Mesh3D:vertex_positions"]) for path, rows in data.items()
           if path.startswith(f"/world/{row}/people/") for _, values in rows if values.get("Mesh3D:vertex_positions")]
    return np.vstack(out)


def _rgb(packed: int) -> list[int]:
    """A Rerun colour (0xRRGGBBAA) -> [r, g, b]."""
    return [(packed >> s) & 255 for s in (24, 16, 8)]


def _sample_gt():
    return open_sequence(Path(__file__).resolve().parents[1] / "sample_data" / "scene" / "gt")
