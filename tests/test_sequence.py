"""Sequence I/O: round trips in both forms, validation errors, CLI `info`."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from _cli import invoke
from conftest import tetra_frame, tree_hash

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.errors import InputError
from rotavat_cli.sequence import (DirectorySource, Frame, FrameSource, Sequence, open_sequence, read_camera_yaml,
                                  read_frame_npz, write_camera_yaml, write_frame)


def test_open_sequence_lists_frames_and_meta(npz_seq: Path):
    seq = open_sequence(npz_seq)
    assert seq.form == "npz"
    assert seq.frame_names == ("000000", "000001", "000002")
    assert seq.image_size == (640, 480)
    assert seq.intrinsics.focal_px == 500.0
    assert [f.n_people for f in seq.frames()] == [3, 0, 2]


def test_npz_round_trip_keeps_values_and_dtypes(npz_seq: Path, tmp_path: Path):
    seq = open_sequence(npz_seq)
    frame = seq.read_frame("000000")
    frame = frame.replace(extra_key=np.arange(5, dtype=np.int16))
    write_frame(tmp_path / "out", frame, "npz")
    back = read_frame_npz(tmp_path / "out" / "000000.npz")
    assert set(back.data) == set(frame.data)
    for key, value in frame.data.items():
        assert back.data[key].dtype == value.dtype, key
        np.testing.assert_array_equal(back.data[key], value)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_obj_round_trip(tmp_path: Path, dtype):
    rng = np.random.default_rng(3)
    data = tetra_frame(rng, 3, dtype)
    frame = Frame("000007", {k: data[k] for k in ("vertices", "faces", "person_ids")})
    write_frame(tmp_path / "objseq", frame, "obj")
    assert sorted(p.name for p in (tmp_path / "objseq" / "000007").iterdir()) == ["10.obj", "11.obj", "12.obj"]
    seq = open_sequence(tmp_path / "objseq")
    assert seq.form == "obj"
    back = seq.read_frame("000007")
    np.testing.assert_array_equal(back.data["person_ids"], [10, 11, 12])
    np.testing.assert_array_equal(back.data["faces"], data["faces"])
    # float32 sources are written with 9 significant digits: exact after casting back
    np.testing.assert_array_equal(back.data["vertices"].astype(dtype), data["vertices"])


def test_obj_empty_frame_folder_is_a_valid_empty_frame(tmp_path: Path):
    (tmp_path / "s" / "000000").mkdir(parents=True)
    seq = open_sequence(tmp_path / "s")
    assert seq.form == "obj" and seq.read_frame("000000").n_people == 0


def test_camera_yaml_round_trip(tmp_path: Path):
    cam = Camera((800, 600), 700.0, None, 0.3, -0.02, 4.5)
    write_camera_yaml(tmp_path / "camera.yaml", cam, {"method": "grid", "pairs": 5})
    cam2, fit = read_camera_yaml(tmp_path / "camera.yaml")
    assert fit == {"method": "grid", "pairs": 5}
    assert cam2.pitch_rad == pytest.approx(0.3) and cam2.roll_rad == pytest.approx(-0.02)


def _write(seq: Path, name: str, **arrays):
    np.savez(seq / name, **arrays)


BAD_FRAMES = {
    "shape": ({"vertices": np.zeros((2, 4, 2))}, "vertices"),
    "nan": ({"vertices": np.full((1, 4, 3), np.nan)}, "non-finite"),
    "count": ({"vertices": np.zeros((2, 4, 3)), "person_ids": np.arange(3)}, "inconsistent people counts"),
    "dup_ids": ({"feet_2d": np.zeros((2, 2)), "person_ids": np.array([1, 1])}, "duplicate"),
    "faces": ({"vertices": np.zeros((1, 4, 3)), "faces": np.array([[0, 1, 9]])}, "faces"),
    "dtype": ({"feet_2d": np.array([["a", "b"]])}, "numeric"),
    "image_size": ({"image_size": np.array([640, -1])}, "image_size"),
}


@pytest.mark.parametrize("case", sorted(BAD_FRAMES))
def test_bad_frames_exit_2_with_one_line(tmp_path: Path, runner, case):
    seq = tmp_path / "bad"
    seq.mkdir()
    (seq / "meta.yaml").write_text("image_size: [640, 480]\n")
    arrays, message = BAD_FRAMES[case]
    _write(seq, "000003.npz", **arrays)
    result = invoke(runner, "info", seq)
    assert result.exit_code == 2
    err = result.stderr.strip()
    assert "000003.npz" in err and message in err
    assert len(err.splitlines()) == 1
    assert "Traceback" not in result.output
    with pytest.raises(InputError, match="000003.npz"):
        list(open_sequence(seq).frames())


def test_object_array_is_refused_without_pickle(tmp_path: Path, runner):
    seq = tmp_path / "pk"
    seq.mkdir()
    np.save(seq / "x.npy", np.zeros(1))
    np.savez(seq / "000000.npz", vertices=np.array([{"a": 1}], dtype=object))
    result = invoke(runner, "info", seq)
    assert result.exit_code == 2 and "pickle" in result.stderr


def test_corrupt_npz(tmp_path: Path, runner):
    seq = tmp_path / "c"
    seq.mkdir()
    (seq / "000000.npz").write_bytes(b"not a zip")
    result = invoke(runner, "info", seq)
    assert result.exit_code == 2 and "000000.npz" in result.stderr


@pytest.mark.parametrize("setup,message", [
    (lambda p: None, "no such directory"),
    (lambda p: p.mkdir(), "no frames found"),
    (lambda p: (p.mkdir(), (p / "000000.npz").write_bytes(b""), (p / "meta.yaml").write_text("image_size: [1, 2, 3]\n")), "image_size"),
    (lambda p: (p.mkdir(), (p / "000000.npz").write_bytes(b""), (p / "meta.yaml").write_text("a: [\n")), "invalid YAML"),
])
def test_bad_sequences(tmp_path: Path, runner, setup, message):
    seq = tmp_path / "s"
    setup(seq)
    result = invoke(runner, "info", seq)
    assert result.exit_code == 2 and message in result.stderr, result.stderr


def test_unknown_image_size_is_reported(tmp_path: Path):
    seq = tmp_path / "s"
    seq.mkdir()
    np.savez(seq / "000000.npz", feet_2d=np.zeros((1, 2)), heads_2d=np.zeros((1, 2)))
    with pytest.raises(InputError, match="unknown image size"):
        open_sequence(seq).require_image_size()


def test_info_json_and_input_untouched(npz_seq: Path, runner):
    before = tree_hash(npz_seq)
    result = invoke(runner, "info", npz_seq, "--json")
    assert result.exit_code == 0
    summary = json.loads(result.stdout)
    assert summary["frames"] == 3 and summary["people_total"] == 5 and summary["empty_frames"] == 1
    assert summary["image_size"] == [640, 480] and summary["vertex_counts"] == [4]
    assert summary["tracks"] == 3
    assert tree_hash(npz_seq) == before


def test_info_table(npz_seq: Path, runner):
    result = invoke(runner, "info", npz_seq)
    assert result.exit_code == 0 and "640x480" in result.stdout


def test_version_and_help(runner):
    from rotavat_cli import __version__

    assert invoke(runner, "--version").stdout.strip() == f"rotavat {__version__}"
    for command in ("info", "synth"):
        assert invoke(runner, command, "--help").exit_code == 0


def test_progress_bars_stay_off_in_ci(monkeypatch):
    from rotavat_cli.cli import _common

    monkeypatch.setenv("FORCE_COLOR", "1")
    monkeypatch.delenv("CI", raising=False)
    assert _common.progress_enabled(False, False) is False  # stderr is not a tty under pytest
    monkeypatch.setenv("CI", "true")
    monkeypatch.setattr(_common.console.file, "isatty", lambda: True, raising=False)
    assert _common.progress_enabled(False, False) is False
    assert _common.progress_enabled(True, False) is False


# ---- frame sources ---------------------------------------------------------------------------------
def test_a_directory_is_the_default_frame_source(npz_seq: Path):
    seq = open_sequence(npz_seq)
    source = seq.frame_source
    assert isinstance(source, DirectorySource) and isinstance(source, FrameSource)
    assert (source.path, source.form, source.frame_names) == (npz_seq, "npz", seq.frame_names)
    assert seq.frame_path("000001") == npz_seq / "000001.npz"
    assert seq.warnings == () and seq.frame_notes(seq.frame_names) is None
    seq.add_frame_notes(None)  # nothing to take in
    bare = Sequence(npz_seq, "npz", seq.frame_names, seq.meta)  # no source given: the directory itself
    assert bare.frame_source == source
    assert [f.n_people for f in bare.frames()] == [f.n_people for f in seq.frames()] == [3, 0, 2]
    part = replace(seq, frame_names=seq.frame_names[1:])  # what batch's align chunks do
    assert [f.name for f in part.frames()] == ["000001", "000002"] and len(part) == 2


class _MemorySource:
    """Frames held in memory, one warning collected while reading them (a FrameSource)."""

    def __init__(self, frames: list[Frame]):
        self._frames = {f.name: f for f in frames}
        self.warnings: list[str] = []

    @property
    def frame_names(self) -> tuple[str, ...]:
        return tuple(self._frames)

    def read_frame(self, name: str) -> Frame:
        if name == "b" and "b was odd" not in self.warnings:
            self.warnings.append("b was odd")
        return self._frames[name]


def test_a_sequence_over_any_frame_source(tmp_path: Path):
    rng = np.random.default_rng(4)
    frames = [Frame(name, {**tetra_frame(rng, p), "image_size": np.array([320, 240])}, f"mem [{name}]")
              for name, p in (("a", 2), ("b", 1))]
    source = _MemorySource(frames)
    assert isinstance(source, FrameSource)
    seq = Sequence(tmp_path / "nowhere", "npz", source.frame_names, {"focal_length": 300.0}, source=source,
                   origin="the tool's output")
    assert seq.label == "the tool's output" and len(seq) == 2
    assert seq.image_size == (320, 240)  # from the first frame: no meta.yaml says it
    assert [f.n_people for f in seq.frames()] == [2, 1] and seq.read_frame("b").source == "mem [b]"
    assert seq.warnings == ("b was odd",)
    assert seq.frame_intrinsics(seq.read_frame("a")).focal_px == 300.0
    with pytest.raises(ValueError, match="not files"):
        seq.frame_path("a")
    assert not (tmp_path / "nowhere").exists()


def _photo_of_another_size(scene: Path) -> Path:
    """A synthetic scene in ``scene`` whose frame 000002 of pred/ says its photo is 1666x2500 (the others
    1280x720, as BEV's image mode writes each photo's own size); its pred/ folder."""
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(scene, SynthOptions(seed=3, frames=4, people=5))
    seq = open_sequence(scene / "pred")
    frame = seq.read_frame(seq.frame_names[2])
    write_frame(scene / "pred", frame.replace(image_size=np.array([1666, 2500])), "npz")
    return scene / "pred"


def test_frames_of_another_image_size_are_refused_by_calibrate_and_align(tmp_path, runner):
    """Photos of different sizes imported as one sequence are not one static camera: calibrate and align
    refuse them with one line naming the frame, and the step to calibrate that frame alone."""
    pred = _photo_of_another_size(tmp_path / "s")
    cal = invoke(runner, "calibrate", pred, "--out", tmp_path / "cam.yaml")
    assert cal.exit_code == 2 and "image size 1666x2500 differs from 1280x720" in cal.stderr
    assert cal.stderr.count("\n") == 1 and "000002" in cal.stderr
    step = cal.stderr.strip().split(", e.g. ", 1)[1]  # run as written by the slow test below
    assert step.startswith("mkdir ") and step.endswith("rotavat calibrate pred_000002")
    aligned = invoke(runner, "align", "--in", pred, "--camera", tmp_path / "s" / "gt" / "camera.yaml",
                     "--out", tmp_path / "a")
    assert aligned.exit_code == 2 and "not one static camera's" in aligned.stderr


@pytest.mark.slow
def test_the_step_named_for_a_frame_of_another_size_runs_as_written(tmp_path, runner):
    """The step calibrate's refusal names (mkdir, cp, rotavat calibrate) runs in a shell as written, with
    this environment's console script, and calibrates the frame at its own size."""
    pred = _photo_of_another_size(tmp_path / "s")
    cal = invoke(runner, "calibrate", pred, "--out", tmp_path / "cam.yaml")
    step = cal.stderr.strip().split(", e.g. ", 1)[1]
    rotavat = Path(sys.executable).parent / "rotavat"  # the console script of this environment
    ran = subprocess.run(step.replace("rotavat calibrate", f"{rotavat} calibrate"), shell=True,
                         cwd=tmp_path / "s", capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    assert yaml.safe_load((tmp_path / "s" / "pred_000002" / "camera.yaml").read_text())["image_size"] == [1666, 2500]
    aligned = invoke(runner, "align", "--in", pred, "--camera", tmp_path / "s" / "gt" / "camera.yaml",
                     "--out", tmp_path / "a")
    assert aligned.exit_code == 2 and "not one static camera's" in aligned.stderr  # the copy left pred/ as it was


def test_info_warns_of_root_centred_and_behind_camera_people_and_of_several_image_sizes(tmp_path, runner):
    """AGORA's sample predictions are root-centred: info says why calibrate will find no usable pairs."""
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=3, frames=3, people=4))
    pred = tmp_path / "s" / "pred"
    seq = open_sequence(pred)
    frame = seq.read_frame("000000")
    verts, joints = frame.data["vertices"], frame.data["joints"]
    roots = joints[:, :1]
    centred = frame.replace(vertices=verts - roots, joints=joints - roots)  # translation zero: 4 people at the camera
    write_frame(pred, centred, "npz")
    behind = seq.read_frame("000001")
    flipped = behind.data["vertices"].copy()
    flipped[0, :, 2] *= -1.0  # one person behind the camera
    write_frame(pred, behind.replace(vertices=flipped), "npz")
    write_frame(pred, seq.read_frame("000002").replace(image_size=np.array([640, 480])), "npz")
    result = invoke(runner, "info", pred)
    text = " ".join(result.stderr.split())  # the warnings are diagnostics (stderr); the console wraps lines
    assert result.exit_code == 0
    assert "4 people are centred on the camera" in text and "1 person is partly at or behind" in text
    assert "frames of 2 image sizes (640x480, 1280x720)" in text
    summary = json.loads(invoke(runner, "info", pred, "--json").stdout)
    assert (summary["people_root_centred"], summary["people_behind_camera"]) == (4, 1)


def test_calibrate_leaves_out_root_centred_people_and_says_so(tmp_path, runner):
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=3, frames=2, people=3))
    pred = tmp_path / "s" / "pred"
    seq = open_sequence(pred)
    for name in seq.frame_names:
        frame = seq.read_frame(name)
        roots = frame.data["joints"][:, :1]
        data = {k: v for k, v in frame.data.items() if k not in ("feet_2d", "heads_2d")}  # pairs from the meshes
        data.update(vertices=frame.data["vertices"] - roots, joints=frame.data["joints"] - roots)
        write_frame(pred, Frame(name, data, frame.source), "npz")
    result = invoke(runner, "calibrate", pred, "--out", tmp_path / "cam.yaml")
    assert result.exit_code == 2 and "its 6 people are not placed in the camera frame (root-centred" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and f"rotavat eval {pred} --gt GT" in result.stderr


@pytest.mark.slow
def test_results_go_to_stdout_and_diagnostics_to_stderr(tmp_path):
    """`rotavat info SEQ > f.txt` keeps the table; warnings, progress and errors stay on stderr (real processes)."""
    import subprocess
    import sys

    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=2, frames=2, people=3))
    pred = tmp_path / "s" / "pred"
    frame = open_sequence(pred).read_frame("000001")
    write_frame(pred, frame.replace(image_size=np.array([640, 480])), "npz")  # a warning to print

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([str(Path(sys.executable).parent / "rotavat"), *args], capture_output=True, text=True,
                              env={**os.environ, "COLUMNS": "200"})

    info = run("info", str(pred))
    assert info.returncode == 0 and "sequence" in info.stdout and "1280x720" in info.stdout
    assert "warning:" in info.stderr and "warning:" not in info.stdout
    synth = run("synth", str(tmp_path / "t"), "--frames", "2", "--people", "2")
    assert synth.stdout.startswith("wrote 2 frames x 2 people") and synth.stderr == ""
    cal = run("calibrate", str(tmp_path / "s" / "gt"), "--out", str(tmp_path / "cam.yaml"))
    assert cal.returncode == 0 and "focal_px" in cal.stdout and "wrote" in cal.stdout
    bad = run("info", str(tmp_path / "nowhere"))
    assert bad.returncode == 2 and bad.stdout == "" and bad.stderr.startswith("error:")


def test_help_shows_defaults_choices_and_plain_text(runner):
    """--help: config defaults and choices shown, flags without a type, brackets kept, SEQ named as such."""
    def text(*args: str) -> str:  # the help's words, without the box drawing and line breaks
        return " ".join(invoke(runner, *args).stdout.replace("│", " ").split())

    align = text("align", "--help")
    assert "[default: paper]" in align and "paper|full" in align and "[default: frame]" in align
    assert "<bool>" not in align and "Usage: rotavat align [OPTIONS] [SEQ]" in align
    batch = text("batch", "--help")
    assert "pip install 'rotavat[dask]'" in batch and "local|dask" in batch and "[default: 100]" in batch
    calibrate = text("calibrate", "--help")
    assert "Usage: rotavat calibrate [OPTIONS] SEQ" in calibrate and "[default: --roll]" in calibrate
    assert "[default: 1.7]" in calibrate and "grid|refine" in calibrate


def test_align_takes_its_sequence_as_an_argument_or_with_in(tmp_path, runner):
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=2, frames=2, people=3))
    cam = tmp_path / "s" / "gt" / "camera.yaml"
    a = invoke(runner, "align", tmp_path / "s" / "pred", "--camera", cam, "--out", tmp_path / "a", "-q")
    b = invoke(runner, "align", "--in", tmp_path / "s" / "pred", "--camera", cam, "--out", tmp_path / "b", "-q")
    assert a.exit_code == 0 and b.exit_code == 0
    assert (tmp_path / "a" / "people.csv").read_text() == (tmp_path / "b" / "people.csv").read_text()
    both = invoke(runner, "align", tmp_path / "s" / "pred", "--in", tmp_path / "s" / "gt")
    none = invoke(runner, "align")
    assert both.exit_code == 2 and "two inputs given" in both.stderr
    assert none.exit_code == 2 and "missing the input sequence SEQ" in none.stderr


def test_info_flags_what_align_would_refuse_and_focals_that_disagree(tmp_path, runner):
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=4, frames=3, people=3))
    gt = tmp_path / "s" / "gt"
    seq = open_sequence(gt)
    frame = seq.read_frame("000001")
    bare = {k: v for k, v in frame.data.items() if k not in ("vertices", "faces", "feet_2d", "heads_2d")}
    write_frame(gt, Frame("000001", bare, frame.source), "npz")  # joints only, no foot/crown pixels
    write_frame(gt, seq.read_frame("000002").replace(focal_length=np.float64(seq.intrinsics.focal_px * 1.5)), "npz")
    cam, fit = read_camera_yaml(gt / "camera.yaml")
    write_camera_yaml(gt / "camera.yaml", cam.replace(focal_px=cam.focal_px * 0.8), fit)
    text = " ".join(invoke(runner, "info", gt).stderr.split())
    assert "1 frames with people have neither meshes ('vertices') nor joints with 'feet_2d'/'heads_2d' (first: 000001)" in text
    assert "1 frames state a focal length other than meta.yaml's" in text and "(first: 000002)" in text
    assert "camera.yaml's focal" in text and "differs from the declared camera focal" in text
    clean = invoke(runner, "info", tmp_path / "s" / "pred")
    assert clean.exit_code == 0 and "warning" not in clean.stderr
