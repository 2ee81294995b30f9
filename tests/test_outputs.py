"""Users' data is sacred: no output over or into an input, nothing replaced that rotavat did not write."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.files.outputs import MARKER, STAGING_OWNER, written_by_rotavat


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    out = tmp_path_factory.mktemp("outs") / "s"
    write_synth_scene(out, SynthOptions(seed=2, frames=3, people=4))
    return out


def _one_line(result) -> str:
    assert result.exit_code == 2, (result.exit_code, result.output)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), result.stderr
    return lines[0]


def _copy(scene: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(scene, dst)
    return dst


def test_align_never_writes_over_its_input_or_the_folder_holding_it(scene, tmp_path, runner):
    s = _copy(scene, tmp_path / "s")
    before = tree_hash(s)
    gt_cam = s / "gt" / "camera.yaml"
    assert "hold the input" in _one_line(invoke(runner, "align", "--in", s / "pred", "--camera", gt_cam, "--out", s))
    assert "is the input" in _one_line(invoke(runner, "align", "--in", s / "pred", "--camera", gt_cam, "--out", s / "pred"))
    assert "inside the input" in _one_line(invoke(runner, "align", "--in", s / "pred", "--camera", gt_cam,
                                                  "--out", s / "pred" / "x"))
    assert "hold the input" in _one_line(invoke(runner, "align", "--in", s / "pred", "--camera", gt_cam,
                                                "--out", s, "--force"))  # --force never touches an input
    assert tree_hash(s) == before


def test_a_foreign_folder_or_file_is_not_replaced_without_force(scene, tmp_path, runner):
    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "thesis.tex").write_text("years of work")
    args = ("align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml")
    assert "did not write" in _one_line(invoke(runner, *args, "--out", keep, "-q"))
    assert (keep / "thesis.tex").read_text() == "years of work"
    (tmp_path / "afile").write_text("data")
    assert "is a file" in _one_line(invoke(runner, *args, "--out", tmp_path / "afile", "-q"))
    assert (tmp_path / "afile").read_text() == "data"
    # rotavat's own output is replaced without --force; a foreign one with it
    assert invoke(runner, *args, "--out", tmp_path / "mine", "-q").exit_code == 0
    assert (tmp_path / "mine" / MARKER).is_file()
    assert invoke(runner, *args, "--out", tmp_path / "mine", "-q").exit_code == 0
    assert invoke(runner, *args, "--out", keep, "-q", "--force").exit_code == 0
    assert not (keep / "thesis.tex").exists() and (keep / "people.csv").exists()


def test_default_output_beside_an_input_that_is_a_regular_file(scene, tmp_path, runner):
    s = _copy(scene, tmp_path / "s")
    (s / "pred_aligned").write_text("not rotavat's")
    result = invoke(runner, "align", "--in", s / "pred", "--camera", s / "gt" / "camera.yaml", "-q")
    assert "not a folder" in _one_line(result) and (s / "pred_aligned").read_text() == "not rotavat's"


def test_calibrate_writes_camera_yaml_only_where_it_may(scene, tmp_path, runner):
    s = _copy(scene, tmp_path / "s")
    frame = s / "pred" / "000000.npz"
    frame_bytes = frame.read_bytes()
    assert "inside the input" in _one_line(invoke(runner, "calibrate", s / "pred", "--out", frame))
    assert frame.read_bytes() == frame_bytes
    known = "image_size: [1280, 720]\nfocal_px: 900.0\npitch_deg: 20.0\nheight_m: 5.0\n"
    (s / "pred" / "camera.yaml").write_text(known)  # a user's own known camera
    assert "did not write" in _one_line(invoke(runner, "calibrate", s / "pred", "-q"))
    assert (s / "pred" / "camera.yaml").read_text() == known
    assert "never replaces it" in _one_line(invoke(runner, "calibrate", s / "pred", "-q", "--force"))  # not even so
    assert (s / "pred" / "camera.yaml").read_text() == known
    (s / "pred" / "camera.yaml").unlink()
    assert invoke(runner, "calibrate", s / "pred", "-q").exit_code == 0
    assert written_by_rotavat(s / "pred" / "camera.yaml")
    assert invoke(runner, "calibrate", s / "pred", "-q").exit_code == 0  # its own file: replaced


def test_batch_never_writes_inside_its_input(scene, tmp_path, runner):
    root = tmp_path / "root"
    _copy(scene / "pred", root / "seq")
    before = tree_hash(root)
    assert "inside the input" in _one_line(invoke(runner, "batch", root, "--out", root / "seq", "-q"))
    assert "hold the input" in _one_line(invoke(runner, "batch", root, "--out", tmp_path, "-q"))
    assert tree_hash(root) == before


def test_eval_and_export_files(scene, tmp_path, runner):
    (tmp_path / "ev").mkdir()
    (tmp_path / "ev" / "metrics.md").write_text("my notes")
    args = ("eval", scene / "pred", "--gt", scene / "gt", "--out", tmp_path / "ev", "-q")
    assert "did not write" in _one_line(invoke(runner, *args))
    assert (tmp_path / "ev" / "metrics.md").read_text() == "my notes"
    assert invoke(runner, *args, "--force").exit_code == 0
    assert invoke(runner, *args, "--per-person", tmp_path / "pp.csv").exit_code == 0
    assert invoke(runner, *args, "--per-person", tmp_path / "pp.csv").exit_code == 0  # its own CSV again
    glb = tmp_path / "scene.glb"
    glb.write_bytes(b"glTF\x02\x00\x00\x00" + bytes(40))  # someone else's model
    exp = ("export", scene / "gt", "--out", glb, "-q")
    assert "did not write" in _one_line(invoke(runner, *exp))
    assert invoke(runner, *exp, "--force").exit_code == 0 and written_by_rotavat(glb)
    assert invoke(runner, *exp).exit_code == 0


def test_synth_into_a_used_folder_needs_force_and_replaces_it_whole(tmp_path, runner):
    out = tmp_path / "scene"
    out.mkdir()
    (out / "old.txt").write_text("x")
    assert "did not write" in _one_line(invoke(runner, "synth", out, "--frames", "2", "--people", "2"))
    assert invoke(runner, "synth", out, "--frames", "2", "--people", "2", "-q", "--force").exit_code == 0
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "gt", "pred", "synth.yaml"]
    assert invoke(runner, "synth", out, "--frames", "3", "--people", "2", "-q").exit_code == 0
    assert len(list((out / "gt").glob("*.npz"))) == 3  # never old and new frames mixed


def test_stale_staging_of_a_killed_run_is_removed(scene, tmp_path, runner):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)  # a process that has ended
    stale = tmp_path / ".al.partial-abc123"
    stale.mkdir()
    (stale / "000000.npz").write_bytes(bytes(1000))
    import socket

    (stale / STAGING_OWNER).write_text(f"{socket.gethostname()} {pid} 0\n")
    foreign = tmp_path / ".al.partial-notours"
    foreign.mkdir()  # no owner file: not provably rotavat's, left alone
    result = invoke(runner, "align", "--in", scene / "pred", "--camera", scene / "gt" / "camera.yaml",
                    "--out", tmp_path / "al", "-q")
    assert result.exit_code == 0, result.stderr
    assert not stale.exists() and foreign.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".al.")) == [".al.partial-notours"]


@pytest.mark.slow
def test_thousands_of_jobs_start_no_more_workers_than_cores(scene, tmp_path):
    """--jobs 10000 in a subprocess limited to 64 processes: it must finish and say how many it used."""
    import resource

    code = ("import resource, sys; resource.setrlimit(resource.RLIMIT_NPROC, (64, 64)); "
            "from rotavat_cli.cli import main; sys.argv = sys.argv[1:]; main()")
    args = [sys.executable, "-c", code, "rotavat", "align", "--in", str(scene / "pred"), "--camera",
            str(scene / "gt" / "camera.yaml"), "--out", str(tmp_path / "al"), "--jobs", "10000"]
    if os.geteuid() == 0:  # root ignores RLIMIT_NPROC: the message and the finish still tell
        args[2] = "from rotavat_cli.cli import main; import sys; sys.argv = sys.argv[1:]; main()"
    result = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "using at most" in result.stderr and (tmp_path / "al" / "people.csv").exists()
    assert resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss < 1_500_000  # kB: no fork bomb


def test_integer_vertices_are_aligned_as_floats(scene, tmp_path):
    from rotavat_cli.alignment.align import align_frame
    from rotavat_cli.sequence import Frame, open_sequence

    cam = open_sequence(scene / "gt").camera
    frame = open_sequence(scene / "gt").read_frame("000000")
    mm = np.round(frame.data["vertices"].astype(np.float64) * 1000).astype(np.int32)  # millimetres as int32
    as_int = Frame("000000", {"vertices": mm, "focal_length": frame.data["focal_length"]})
    as_float = Frame("000000", {"vertices": mm.astype(np.float64), "focal_length": frame.data["focal_length"]})
    new_int, _ = align_frame(as_int, cam.replace(height_m=cam.height_m * 1000))
    new_float, _ = align_frame(as_float, cam.replace(height_m=cam.height_m * 1000))
    assert new_int.data["vertices"].dtype == np.float64
    np.testing.assert_array_equal(new_int.data["vertices"], new_float.data["vertices"])
    assert np.abs(new_int.data["vertices"] - np.round(new_int.data["vertices"])).max() > 0.01  # not rounded


def test_security_page_states_the_promises():
    text = (Path(__file__).resolve().parents[1] / "SECURITY.md").read_text()
    for promise in ("never", "--force", "allow_pickle", "limits", "exit status 2"):
        assert promise in text
