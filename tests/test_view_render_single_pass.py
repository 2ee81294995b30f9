"""view and render read each frame once and hold a bounded number of frames (issue 34): the W-MPJPE view logs and the
captions render draws are scored from the frames already read and equal evaluate()'s; render's side/top windows come
from per-frame bounds; GIF and MP4 are written as frames come, with the bytes of the writers before."""

from __future__ import annotations

import dataclasses
import io
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import rotavat_cli.render.sequences as render_seqs
from rotavat_cli.metrics.evaluate import EvalOptions, evaluate, evaluate_frame, frame_w_mpjpe, pairing_options
from rotavat_cli.render.sequences import FigureOptions, _window_row, metrics_caption, render_sequences
from rotavat_cli.render.video import gif_writer, mp4_writer, write_gif
from rotavat_cli.render.rows import read_row
from rotavat_cli.render.views import VIEWS, extents_from_bounds, scene_extents, window_bounds
from rotavat_cli.sequence import Sequence, open_sequence
from rotavat_cli.synth import SynthOptions, write_synth_scene

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "scene"


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    """A small synthetic scene: gt/ (with its camera.yaml) and pred/, 6 frames x 3 people."""
    out = tmp_path_factory.mktemp("single_pass") / "scene"
    write_synth_scene(out, SynthOptions(seed=4, frames=6, people=3, image_size=(320, 240)))
    return out


@pytest.fixture
def reads(monkeypatch) -> dict[tuple[str, str], int]:
    """Counts every ``read_frame(name)`` of every sequence class, by (sequence label, frame name)."""
    counts: dict[tuple[str, str], int] = {}
    original = Sequence.read_frame

    def counted(self, name):
        counts[(self.label, name)] = counts.get((self.label, name), 0) + 1
        return original(self, name)
    monkeypatch.setattr(Sequence, "read_frame", counted)
    return counts


def _per_frame_reads(counts: dict[tuple[str, str], int]) -> dict[str, int]:
    """The most reads of one frame, per sequence label."""
    out: dict[str, int] = {}
    for (label, _), n in counts.items():
        out[label] = max(out.get(label, 0), n)
    return out


# ---- metrics: one frame's scores are evaluate()'s -----------------------------------------------------------------
def test_frame_w_mpjpe_equals_evaluate(scene):
    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    opts = pairing_options(pred, gt, dataclasses.replace(EvalOptions(), engine="numpy"))
    cols = evaluate(pred, gt, dataclasses.replace(EvalOptions(), engine="numpy")).per_person
    want = {(f, int(p)): v for f, p, v in zip(cols["frame"], cols["person_id"], cols["w_mpjpe"])}
    got = {}
    for name in gt.frame_names:
        pf, gf = pred.read_frame(name), gt.read_frame(name)
        ids, values = frame_w_mpjpe(pf, gf, pred.frame_intrinsics(pf), gt.frame_intrinsics(gf), opts)
        got.update({(name, int(p)): float(v) for p, v in zip(ids, values)})
    assert got == want  # bit for bit


def test_evaluate_frame_is_evaluate_on_that_frame(scene):
    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    names = sorted(set(pred.frame_names) | set(gt.frame_names))
    for k in (0, 3):
        whole = evaluate(pred, gt, frames=(k, k + 1))
        given = evaluate_frame(pred, gt, names[k], pred.read_frame(names[k]), gt.read_frame(names[k]))
        assert repr(given.metrics) == repr(whole.metrics) and repr(given.per_person) == repr(whole.per_person)  # NaN too
        assert (given.matched, given.people_gt, given.frames) == (whole.matched, whole.people_gt, whole.frames)


def test_evaluate_frame_reads_nothing_when_given_frames(scene, reads):
    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    name = gt.frame_names[1]
    frames = pred.read_frame(name), gt.read_frame(name)
    reads.clear()
    evaluate_frame(pred, gt, name, *frames)
    assert reads == {}


# ---- view ---------------------------------------------------------------------------------------------------------
def _recorded_series(monkeypatch) -> dict[str, dict]:
    """Spy on the recording's series as _record_statics logs them: {row label: {series: {id: [(frame, value)]}}}."""
    import rotavat_cli.view.recording as recording

    captured: dict[str, dict] = {}
    original = recording._record_statics

    def spy(writer, states, *args, **kwargs):
        for state in states:
            captured[state.label] = {k: {pid: list(v) for pid, v in per.items()} for k, per in state.series.items()}
        return original(writer, states, *args, **kwargs)
    monkeypatch.setattr(recording, "_record_statics", spy)
    return captured


def test_view_reads_each_frame_once_and_logs_evaluates_w_mpjpe(scene, tmp_path, monkeypatch, reads):
    pytest.importorskip("rerun")
    from rotavat_cli.view import ViewOptions, record_sequences

    captured = _recorded_series(monkeypatch)
    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    summary = record_sequences([pred], tmp_path / "v.rrd", gt, ViewOptions(camera_path=scene / "gt" / "camera.yaml"))
    assert summary.warnings == []
    assert set(_per_frame_reads(reads).values()) == {1}  # every frame of every row read once
    assert len(reads) == 2 * len(gt.frame_names)
    cols = evaluate(open_sequence(scene / "pred"), open_sequence(scene / "gt")).per_person
    timeline = sorted(gt.frame_names)
    want: dict[int, list] = {}
    for f, p, v in zip(cols["frame"], cols["person_id"], cols["w_mpjpe"]):
        if v is not None and math.isfinite(v):
            want.setdefault(int(p), []).append((timeline.index(f), float(v)))
    assert captured["pred"]["w_mpjpe_mm"] == want


def test_view_w_mpjpe_of_the_sample_scene_rows(tmp_path, monkeypatch):
    """Several rows (pred, pred twice under another name) against the truth: each its own series, evaluate()'s."""
    pytest.importorskip("rerun")
    from rotavat_cli.view import ViewOptions, record_sequences

    captured = _recorded_series(monkeypatch)
    seqs = [open_sequence(SAMPLE / "pred"), open_sequence(SAMPLE / "pred")]
    gt = open_sequence(SAMPLE / "gt")
    record_sequences(seqs, tmp_path / "v.rrd", gt, ViewOptions(camera_path=SAMPLE / "gt" / "camera.yaml"),
                     labels=["a", "b", "gt"])
    cols = evaluate(open_sequence(SAMPLE / "pred"), gt).per_person
    want = sorted((int(p), float(v)) for p, v in zip(cols["person_id"], cols["w_mpjpe"]))
    for label in ("a", "b"):
        got = sorted((pid, v) for pid, points in captured[label]["w_mpjpe_mm"].items() for _, v in points)
        assert got == want
    assert "w_mpjpe_mm" not in captured["gt"]


def test_view_row_not_comparable_warns_and_logs_no_w_mpjpe(scene, tmp_path, monkeypatch):
    """A row whose frames cannot be matched to the truth (mid-clip): one warning, no W-MPJPE series, as before."""
    pytest.importorskip("rerun")
    import rotavat_cli.view.recording as recording
    from rotavat_cli.errors import InputError
    from rotavat_cli.view import ViewOptions, record_sequences

    captured = _recorded_series(monkeypatch)
    original = recording.frame_w_mpjpe
    calls = {"n": 0}

    def failing(*args):
        calls["n"] += 1
        if calls["n"] == 3:
            raise InputError("cannot match people in 2D")
        return original(*args)
    monkeypatch.setattr(recording, "frame_w_mpjpe", failing)
    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    summary = record_sequences([pred], tmp_path / "v.rrd", gt, ViewOptions(camera_path=scene / "gt" / "camera.yaml"))
    assert [w for w in summary.warnings if "no W-MPJPE" in w] == [f"{pred.label}: no W-MPJPE against {gt.label} "
                                                                  "(cannot match people in 2D)"]
    assert "w_mpjpe_mm" not in captured["pred"]


# ---- render -------------------------------------------------------------------------------------------------------
def _render(scene: Path, out: Path, **changes) -> tuple:
    seqs = [open_sequence(scene / "pred"), open_sequence(scene / "gt")]
    opts = FigureOptions(size=(96, 64), renderer="fallback", ghost="gt", gt="2", camera_path=scene / "gt" / "camera.yaml",
                         **changes)
    return seqs, render_sequences(seqs, out, opts)


def test_render_reads_each_frame_once_when_the_clip_fits(scene, tmp_path, reads):
    seqs, summary = _render(scene, tmp_path / "fig", every=1)
    assert len(summary.frames) == 6
    assert set(_per_frame_reads(reads).values()) == {1}  # windows, drawing and captions from one read


def test_render_long_clip_keeps_bounds_not_frames(scene, tmp_path, reads, monkeypatch):
    """Beyond the frames kept, pass 2 reads a frame again (twice in all, never more: the captions reuse it), and
    what pass 1 keeps of a frame is its rows' window bounds (a few numbers), never its meshes."""
    monkeypatch.setattr(render_seqs, "_KEEP_FRAMES_BYTES", 0)
    kept = []
    original = render_seqs.window_bounds

    def spy(row, *args, **kwargs):
        bounds = original(row, *args, **kwargs)
        kept.append(bounds)
        return bounds
    monkeypatch.setattr(render_seqs, "window_bounds", spy)
    _, summary = _render(scene, tmp_path / "fig", every=1)
    assert set(_per_frame_reads(reads).values()) == {2}
    assert len(kept) == 2 * 6
    for bounds in kept:
        arrays = [bounds.front, *(b for pair in bounds.ortho.values() for b in pair)]
        assert sum(a.nbytes for a in arrays if a is not None) <= 4 * 8 + 2 * 2 * 2 * 3 * 8


def test_render_outputs_do_not_depend_on_frames_kept(scene, tmp_path, monkeypatch):
    _, once = _render(scene, tmp_path / "a", every=2, gif=True)
    monkeypatch.setattr(render_seqs, "_KEEP_FRAMES_BYTES", 0)
    _, twice = _render(scene, tmp_path / "b", every=2, gif=True)
    assert once.captions == twice.captions
    for a, b in zip(once.files, twice.files):
        assert Path(a).read_bytes() == Path(b).read_bytes()


def test_window_bounds_give_scene_extents(scene):
    """The windows from per-row bounds are the windows fitted on the rows themselves, for both scales' inputs."""
    seqs = [open_sequence(scene / "pred"), open_sequence(scene / "gt")]
    rows = [_window_row(read_row(s, n, s.label, s.camera if s.camera is not None else seqs[1].camera))
            for n in seqs[1].frame_names for s in seqs]
    rows[0] = dataclasses.replace(rows[0], flags=("implausible_stature",) + ("",) * (len(rows[0].person_ids) - 1))
    for fit in ("people", "camera"):
        for chosen in (rows, rows[::2], rows[:1]):
            want = scene_extents(chosen, VIEWS, (96, 64), 0.1, fit)
            got = extents_from_bounds([window_bounds(r, VIEWS, fit) for r in chosen], VIEWS, (96, 64), 0.1, fit)
            assert got == want


def test_caption_from_frames_in_hand_equals_evaluates(scene):
    pred, gt = open_sequence(scene / "pred"), open_sequence(scene / "gt")
    name = gt.frame_names[2]
    read = metrics_caption(pred, gt, name)
    given = metrics_caption(pred, gt, name, pred.read_frame(name), gt.read_frame(name))
    names = sorted(set(pred.frame_names) | set(gt.frame_names))
    k = names.index(name)
    m = evaluate(pred, gt, dataclasses.replace(EvalOptions(), engine="numpy"), frames=(k, k + 1))
    assert read == given and f"W-MPJPE {m.metrics['w_mpjpe']:.0f} mm" in given
    assert f"({m.matched}/{m.people_gt} matched)" in given


# ---- animations ---------------------------------------------------------------------------------------------------
def _pillow_gif(images: list[np.ndarray], fps: float) -> bytes:
    """What write_gif wrote before issue 34: Pillow's save_all of every frame at once."""
    frames = [Image.fromarray(im).convert("P", palette=Image.ADAPTIVE, colors=255) for im in images]
    out = io.BytesIO()
    frames[0].save(out, format="GIF", save_all=True, append_images=frames[1:], duration=int(round(1000 / fps)), loop=0)
    return out.getvalue()


def _frames() -> dict[str, list[np.ndarray]]:
    rng = np.random.default_rng(0)
    base = (rng.random((30, 41, 3)) * 255).astype(np.uint8)
    a, b = base.copy(), base.copy()
    a[5:10, 5:20] = 0
    b[20:30, 30:40] = 255
    smooth = np.zeros_like(base)
    smooth[..., 1] = np.arange(41)[None] * 6
    return {"one": [base], "all the same": [base] * 3, "changes": [base, a, b], "repeats": [base, base, a, a, a, b, base],
            "palettes": [smooth, base, smooth]}


@pytest.mark.parametrize("case", list(_frames()))
def test_gif_writer_bytes_are_pillows_of_all_frames(case, tmp_path):
    """Frames added one at a time (spooled while the clip renders) give the GIF Pillow writes of the whole list."""
    images = _frames()[case]
    with gif_writer(tmp_path / "a.gif", 5.0) as gif:
        for image in images:
            gif.add(image)
        assert gif.stream.count == len(images)  # on disk, not in memory
    assert (tmp_path / "a.gif").read_bytes() == _pillow_gif(images, 5.0)


def test_write_gif_takes_frames_one_at_a_time(tmp_path):
    """A generator of frames is consumed as the GIF is written: the RGB frames are not kept (at most two alive)."""
    images = _frames()["repeats"] * 4
    alive = {"now": 0, "most": 0}

    class Tracked(np.ndarray):
        def __del__(self):
            alive["now"] -= 1

    def frames():
        for image in images:
            alive["now"] += 1
            alive["most"] = max(alive["most"], alive["now"])
            yield image.copy().view(Tracked)
    write_gif(tmp_path / "a.gif", frames(), 5.0)
    assert alive["most"] <= 2
    assert (tmp_path / "a.gif").read_bytes() == _pillow_gif(images, 5.0)


def test_animation_writers_leave_nothing_when_the_block_fails(tmp_path):
    image = _frames()["one"][0]
    with pytest.raises(RuntimeError):
        with gif_writer(tmp_path / "a.gif", 5.0) as gif:
            gif.add(image)
            raise RuntimeError("render failed")
    assert list(tmp_path.iterdir()) == []


def test_mp4_spool_holds_one_frame_and_encodes_the_same(tmp_path):
    pytest.importorskip("av")
    from rotavat_cli.render.video import write_mp4

    images = [np.full((32, 48, 3), 10 * i, np.uint8) for i in range(5)]
    with mp4_writer(tmp_path / "s.mp4", 5.0) as mp4:
        for image in images:
            mp4.add(image)
        spooled = list(mp4.stream.frames())
        assert mp4.stream.count == 5 and all(np.array_equal(a, b) for a, b in zip(spooled, images))
    write_mp4(tmp_path / "l.mp4", images, 5.0)
    assert (tmp_path / "s.mp4").read_bytes() == (tmp_path / "l.mp4").read_bytes()
