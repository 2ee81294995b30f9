"""A file given to the wrong reader says what it is (issue 24): another tool's output read with the wrong
``--from`` names the format it looks like and the ``--from`` that reads it, on every command that takes
``--from``; a file that is no tool's output at all (JSON, an image, a video, a zip archive, ...) is named
as such with the list of formats rotavat reads. One line, exit 2. Real files when present
(../shared/realfiles, skipped when absent)."""

from __future__ import annotations

import io
import json
import pickle
import zipfile
from pathlib import Path

import _fixtures_torch as T
import _fixtures_wham_hybrik as WH
import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle
from rotavat_cli.formats import available_formats, other_format
from rotavat_cli.formats.file_kinds import file_kind

W, H = 640, 480
REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"
READS = f"(rotavat reads: {', '.join(available_formats())})"


def _one_line_error(result) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.stderr.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), result.stderr
    return lines[0]


def _write(fmt: str, folder: Path, scene) -> Path:
    if fmt == "hybrik":
        return WH.write_hybrik(folder / "res.pk", scene, (W, H))
    if fmt == "4dhumans":
        return F.write_phalp(folder / "demo_video.pkl", scene, (W, H))
    if fmt == "wham":
        return WH.write_wham(folder / "wham_output.pkl", scene)
    if fmt == "bev":
        return F.write_bev(folder / "bev", scene, (W, H))
    raise AssertionError(fmt)


# ---- another tool's output, read with the wrong --from ---------------------------------------------
@pytest.mark.parametrize("written, read_as, tool, chosen", [
    ("hybrik", "4dhumans", "a HybrIK", "a 4D-Humans"),   # was: "frame 'pred_uvd' is not a dict"
    ("4dhumans", "wham", "a 4D-Humans", "a WHAM"),        # was: "track key '...jpg' is not an integer track id"
    ("wham", "hybrik", "a WHAM", "a HybrIK"),             # was: "missing key 'pred_xyz_29'"
    ("bev", "multihmr", "a BEV", "a Multi-HMR"),          # was: "...npz: no 'verts_smplx' key"
])
def test_wrong_from_names_the_format_the_file_looks_like(written, read_as, tool, chosen, tmp_path, scene, runner):
    src = _write(written, tmp_path, scene)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", read_as, "--image-size", W, H))
    assert text.startswith(f"error: {src}: this looks like {tool} output (--from {written}), not {chosen} one "
                           f"(read as {read_as}: ")
    assert other_format(src, read_as) == written and other_format(src, written) is None
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["import", "calibrate", "align", "eval", "eval --gt-from", "export", "measure",
                                     "render"])
def test_every_command_with_from_says_it(command, tmp_path, scene, runner):
    """The hint is made where every --from reader runs (formats.reading_errors), so each command gives it."""
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    gt = tmp_path / "gt"
    assert invoke(runner, "import", src, gt, "--quiet").exit_code == 0
    wrong = ["--from", "4dhumans"]
    args = {"import": ["import", src, tmp_path / "out", *wrong],
            "calibrate": ["calibrate", src, *wrong, "--out", tmp_path / "cam.yaml"],
            "align": ["align", src, *wrong, "--out", tmp_path / "al"],
            "eval": ["eval", src, *wrong, "--gt", gt, "--out", tmp_path / "ev"],
            "eval --gt-from": ["eval", gt, "--gt", src, "--gt-from", "4dhumans", "--out", tmp_path / "ev"],
            "export": ["export", src, *wrong, "--out", tmp_path / "x.glb"],
            "measure": ["measure", src, *wrong, "--out", tmp_path / "m.csv"],
            "render": ["render", src, *wrong, "--out", tmp_path / "r"]}[command]
    text = _one_line_error(invoke(runner, *args))
    assert f"{src}: this looks like a HybrIK output (--from hybrik), not a 4D-Humans one" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gt", "res.pk"]  # nothing written


def test_a_damaged_file_read_with_its_own_from_gets_no_hint(tmp_path, scene, runner):
    """The reader's own complaint stands when the file is that format's (its sniffer recognises it)."""
    src = WH.write_hybrik(tmp_path / "res.pk", scene, (W, H))
    data = dict(unpickle.load_file(src))  # the restricted reader, as the importer reads it
    data["pred_uvd"][..., 0] += 0.05
    src.write_bytes(pickle.dumps(data))
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "hybrik"))
    assert "does not reproject onto pred_uvd" in text and "looks like" not in text


def test_bev_read_as_romp_keeps_its_own_message(tmp_path, scene, runner):
    src = _write("bev", tmp_path, scene)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "romp", "--image-size", W, H))
    assert "read it with --from bev" in text and "looks like" not in text


_REAL = [("gait/demo_walk_1.pkl", "wham", "a 4D-Humans output (--from 4dhumans), not a WHAM one"),
         ("hybrik/res.pk", "4dhumans", "a HybrIK output (--from hybrik), not a 4D-Humans one"),
         ("wham_lalasray/wham_output.pkl", "hybrik", "a WHAM output (--from wham), not a HybrIK one"),
         ("gvhmr/tennis/hmr4d_results.pt", "tram", "a GVHMR output (--from gvhmr), not a TRAM one"),
         ("agora_sample/smpl_verts_personId_0.pkl", "hybrik", "an AGORA output (--from agora), not a HybrIK one"),
         ("buddi/bev_live", "multihmr", "a BEV output (--from bev), not a Multi-HMR one")]


@pytest.mark.parametrize("name, read_as, says", _REAL, ids=[r[0] for r in _REAL])
def test_real_files_read_with_the_wrong_from(name, read_as, says, tmp_path, runner):
    src = REALFILES / name
    if not src.exists():
        pytest.skip(f"../shared/realfiles/{name} not present")
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", read_as, "--image-size", W, H))
    assert text.startswith(f"error: {src}: this looks like {says} (read as {read_as}: ")


# ---- files that are no tool's output ----------------------------------------------------------------
def _zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def _npz() -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, verts_smplx=np.zeros((1, 4, 3)))
    return buffer.getvalue()


def _npy() -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.zeros((1, 4, 3)))
    return buffer.getvalue()


@pytest.mark.parametrize("name, content, kind", [
    ("results.json", json.dumps({"humans": [{"verts": [[0, 0, 1]]}]}).encode(), "a JSON file"),
    ("results.pkl", b"\n  [1, 2, 3]\n", "a JSON file"),
    ("bom.json", b"\xef\xbb\xbf{\"a\": 1}", "a JSON file"),
    ("frame.png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x01\x00\x00\x00\x00\xf0", "a PNG image"),
    ("frame.jpg", b"\xff\xd8\xff\xe0\x00\x10JFIF\x00", "a JPEG image"),
    ("clip.mp4", b"\x00\x00\x00\x20ftypisom\x00\x00\x02\x00isomiso2", "an MP4/MOV video"),
    ("clip.mov", b"\x00\x00\x00\x14ftypqt  \x00\x00\x00\x00", "an MP4/MOV video"),
    ("photo.heic", b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00", "a HEIC/AVIF image"),
    ("clip.avi", b"RIFF\x00\x10\x00\x00AVI LIST", "an AVI video"),
    ("clip.webm", b"\x1aE\xdf\xa3\x9fB\x86\x81\x01", "a Matroska/WebM video"),
    ("camera.yaml", b"image_size: [640, 480]\nfocal_length: 500\n", "a YAML file"),
    ("doc.pdf", b"%PDF-1.7\n", "a PDF document"),
    ("results.zip", _zip({"a/readme.txt": b"hello"}), "a zip archive"),
    ("res.pk", b"", "an empty file"),
])
def test_file_kind_names_what_no_reader_reads(name, content, kind, tmp_path):
    path = tmp_path / name
    path.write_bytes(content)
    assert file_kind(path) == kind


@pytest.mark.parametrize("name, content", [
    ("a.npz", _npz()),
    ("a.npy", _npy()),
    ("a.pkl", pickle.dumps({"verts": np.zeros(3)}, protocol=2)),
    ("a.pkl", pickle.dumps([1, 2], protocol=0)),
    ("a.pkl", F.joblib_bytes({"a": np.zeros(3)})),
    ("a.pt", T.torch_zip_bytes({"a": 1}, name="hmr4d_results")),
    ("a.pkl", b"{\x00\x81 binary that starts like JSON"),
    ("a.npz", b"PK\x03\x04 truncated"),  # a damaged npz: its reader says what is wrong
])
def test_file_kind_leaves_what_the_readers_read_to_them(name, content, tmp_path):
    path = tmp_path / name
    path.write_bytes(content)
    assert file_kind(path) is None
    assert file_kind(tmp_path) is None  # a folder


def test_a_json_file_read_as_multihmr_says_it_is_json(tmp_path, runner):
    """Was: 'not a readable pickle (invalid opcode)' (with --image-size) or a request for --image-size."""
    src = tmp_path / "humans.json"
    src.write_text(json.dumps([{"verts_smplx": [[0.0, 0.0, 2.0]]}]))
    for extra in ([], ["--image-size", W, H]):
        text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "multihmr", *extra))
        assert text == f"error: {src}: a JSON file, not a Multi-HMR output {READS}"
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out"))  # nothing detected
    assert text == f"error: {src}: a JSON file, not an HPS tool's output {READS}"
    text = _one_line_error(invoke(runner, "calibrate", src, "--from", "multihmr", "--image-size", W, H, "--out",
                                  tmp_path / "cam.yaml"))
    assert text == f"error: {src}: a JSON file, not a Multi-HMR output {READS}"
    assert not (tmp_path / "out").exists()


def test_a_json_file_inside_a_multihmr_folder_says_it_is_json(tmp_path, runner):
    folder = tmp_path / "mh"
    folder.mkdir()
    (folder / "img_000.pkl").write_text('{"humans": []}')
    text = _one_line_error(invoke(runner, "import", folder, tmp_path / "out", "--from", "multihmr", "--image-size", W, H))
    assert text == f"error: {folder / 'img_000.pkl'}: a JSON file, not a Multi-HMR output {READS}"
    (folder / "img_000.pkl").rename(folder / "img_000.json")
    text = _one_line_error(invoke(runner, "import", folder, tmp_path / "out", "--from", "multihmr", "--image-size", W, H))
    assert text == f"error: {folder}: no Multi-HMR result files (.npy, .npz or .pkl) found (it holds 1 .json)"


@pytest.mark.parametrize("name, content, fmt, says", [
    ("frame.png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "hybrik", "a PNG image, not a HybrIK output"),
    ("clip.mp4", b"\x00\x00\x00\x20ftypisom\x00\x00\x02\x00", "4dhumans", "an MP4/MOV video, not a 4D-Humans output"),
    ("results.zip", _zip({"notes.txt": b"x"}), "cliff", "a zip archive, not a CLIFF output"),
    ("camera.yaml", b"focal_length: 500\n", "agora", "a YAML file, not an AGORA output"),
])
def test_other_files_read_with_from_say_what_they_are(name, content, fmt, says, tmp_path, runner):
    src = tmp_path / name
    src.write_bytes(content)
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", fmt, "--image-size", W, H))
    assert text == f"error: {src}: {says} {READS}"


def test_a_real_photo_read_as_bev_says_it_is_a_jpeg(tmp_path, runner):
    src = REALFILES / "buddi" / "images" / "image_1.jpg"
    if not src.is_file():
        pytest.skip("../shared/realfiles/buddi/images not present")
    text = _one_line_error(invoke(runner, "import", src, tmp_path / "out", "--from", "bev"))
    assert text == f"error: {src}: a JPEG image, not a BEV output {READS}"
