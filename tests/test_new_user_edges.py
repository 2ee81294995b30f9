"""Issue 33, a new user's first steps on their own data: every message that refuses names what the input
is and a command that runs as written, and these tests run that command.

- a tool's file given where a sequence directory is read (info, calibrate, align, ...): its format and the
  commands that read it (``--from FMT``, ``rotavat import``);
- a HybrIK ``res.pk`` of several videos: ``rotavat import ... --video NAME`` per video, never a mkdir/cp of one frame;
- a folder of AGORA predictions that mixes SMPL and SMPL-X: said in one line, imported with ``--model-kind``;
- ``--json`` on an error: one JSON object on stdout (``error``, ``exit``, ``command``, ``kind``);
- the small ones: info's implausible camera and stds, calibrate's "from" column, the stature moved from its prior,
  cameras compared with a tolerance, ranges shown once in --help, why 4D-Humans frames are empty, ``/scene/``
  git-ignored.

Real files (../shared/realfiles) are read by path and skipped when absent.
"""

from __future__ import annotations

import json
import math
import pickle
import re
import shlex
import shutil
from pathlib import Path

import _fixtures_wham_hybrik as WH
import _format_fixtures as F
import numpy as np
import pytest
import yaml
from _cli import invoke

from rotavat_cli.calibration.priors import Priors
from rotavat_cli.calibration.uncertainty import MOVED_PRIOR_SD, moved_by_data
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.cli.commands import COMMANDS
from rotavat_cli.formats.agora import model_kind_of
from rotavat_cli.sequence import open_sequence, write_camera_yaml
from rotavat_cli.unpickle.dispatch import load_file

REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"
GAIT = REALFILES / "gait" / "demo_walk_1.pkl"
AGORA_SAMPLE = REALFILES / "agora_sample"
SAMPLE_PRED = Path(__file__).resolve().parents[1] / "sample_data" / "scene" / "pred"
W, H = F.W, F.H

needs_gait = pytest.mark.skipif(not GAIT.is_file(), reason="real 4D-Humans file absent (../shared/realfiles)")
needs_agora = pytest.mark.skipif(not (AGORA_SAMPLE / "smpl_param_rm_personId_0.pkl").is_file(),
                                 reason="AGORA's sample predictions absent (../shared/realfiles)")


def _one_line_error(result, code: int = 2) -> str:
    """The one 'error:' line of a refused run (no traceback), without its prefix."""
    assert result.exit_code == code, result.output
    lines = [line for line in result.stderr.strip().splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    return lines[0].removeprefix("error: ")


def _run(runner, command: str):
    """Run a suggested ``rotavat ...`` command line exactly as written (shell words)."""
    words = shlex.split(command)
    assert words[0] == "rotavat", command
    return invoke(runner, *words[1:])


def _suggestions(text: str) -> tuple[str | None, str]:
    """(the '--from' command or None, the import command) of a refusal of a tool's file given as SEQ."""
    found = re.search(r"(?:read it as it is: (.+), or )?convert it once into a sequence: (.+)$", text)
    assert found, text
    return found[1], found[2]


# ---- 1. a tool's file where a sequence directory is read ----------------------------------------------------
@pytest.fixture()
def phalp(tmp_path, scene, monkeypatch) -> Path:
    """A 4D-Humans (PHALP) file of the formats' scene, in the current folder (the outputs of --from go there)."""
    monkeypatch.chdir(tmp_path)
    return F.write_phalp(tmp_path / "demo_video.pkl", scene, (W, H))


@pytest.mark.parametrize("command", ["info", "calibrate", "align", "measure", "render", "export"])
def test_a_tools_file_as_seq_names_its_format_and_both_commands(runner, phalp, command):
    """Was: 'not a directory (a sequence is a directory of frames)' (calibrate: '.../camera.yaml: ... is not a folder')."""
    text = _one_line_error(invoke(runner, command, phalp))
    assert text.startswith(f"{phalp}: a file, not a sequence directory") and "it is 4D-Humans output" in text
    read, convert = _suggestions(text)
    assert read.startswith(f"rotavat {command} {phalp} --from 4dhumans")
    assert convert == f"rotavat import --from 4dhumans {phalp} demo_video"
    if command == "calibrate":  # with --from, calibrate writes where it is told: the suggestion says where
        assert read.endswith("--out demo_video_camera.yaml")


def test_the_suggested_commands_run(runner, phalp, tmp_path):
    """info's and import's suggestions succeed as written; so does align's (it calibrates first)."""
    read, convert = _suggestions(_one_line_error(invoke(runner, "info", phalp)))
    result = _run(runner, read)
    assert result.exit_code == 0, result.output
    assert "4dhumans" in result.stdout and "3 (1 empty" in result.stdout
    result = _run(runner, convert)
    assert result.exit_code == 0, result.output
    assert len(open_sequence(tmp_path / "demo_video")) == 3
    result = invoke(runner, "info", tmp_path / "demo_video", "--json")  # the import is a sequence now
    assert result.exit_code == 0 and json.loads(result.stdout)["frames"] == 3


@needs_gait
def test_the_real_4dhumans_file_as_seq_info_calibrate_align(runner, tmp_path, monkeypatch):
    """The README's first command on one's own data, on the real file: each suggestion runs to a result (align's
    too, with the camera calibrate's suggestion wrote: align alone would calibrate again)."""
    monkeypatch.chdir(tmp_path)
    for command in ("info", "calibrate", "align"):
        text = _one_line_error(invoke(runner, command, GAIT))
        read, convert = _suggestions(text)
        assert read.startswith(f"rotavat {command} {GAIT} --from 4dhumans")
        assert convert == f"rotavat import --from 4dhumans {GAIT} demo_walk_1"
        result = _run(runner, read + (" --camera demo_walk_1_camera.yaml" if command == "align" else "") + " --quiet")
        assert result.exit_code == 0, (read, result.output)
    assert (tmp_path / "demo_walk_1_camera.yaml").is_file() and len(open_sequence(tmp_path / "demo_walk_1_aligned")) == 67


def test_a_frame_file_as_seq_names_its_sequence(runner, tmp_path):
    seq = shutil.copytree(SAMPLE_PRED, tmp_path / "pred")
    text = _one_line_error(invoke(runner, "info", seq / "000000.npz"))
    assert text.startswith(f"{seq / '000000.npz'}: a frame of a sequence, not a sequence directory")
    command = re.search(r"\((rotavat .+)\)$", text)[1]
    assert command == f"rotavat info {seq}"
    assert _run(runner, command).exit_code == 0


def test_a_file_of_no_tool_as_seq_says_what_it_is(runner, tmp_path):
    (tmp_path / "notes.json").write_text('{"a": 1}')
    text = _one_line_error(invoke(runner, "calibrate", tmp_path / "notes.json"))
    assert text.startswith(f"{tmp_path / 'notes.json'}: a JSON file, not a sequence directory")
    assert text.endswith("rotavat import --help)") and "4dhumans" in text
    assert invoke(runner, "import", "--help").exit_code == 0


def test_a_tools_file_as_a_later_render_row_is_told_to_import_it(runner, phalp, tmp_path):
    """render's --from reads its first row only: for a later row, the import is the way."""
    seq = shutil.copytree(SAMPLE_PRED, tmp_path / "pred")
    read, convert = _suggestions(_one_line_error(invoke(runner, "render", seq, phalp)))
    assert read is None and convert == f"rotavat import --from 4dhumans {phalp} demo_video"


def test_a_tools_folder_as_seq_is_named_too(runner, scene, tmp_path, monkeypatch):
    """A folder of AGORA's per-person files was 'no frames found (expected *.npz files or ...)'."""
    monkeypatch.chdir(tmp_path)
    src = F.write_agora(tmp_path / "agora_pred", scene[:2])
    text = _one_line_error(invoke(runner, "info", src))
    assert text.startswith(f"{src}: a folder of AGORA output, not a sequence directory")
    read, convert = _suggestions(text)
    assert (read, convert) == (f"rotavat info {src} --from agora", f"rotavat import --from agora {src} agora_pred_seq")
    for command in (read, convert):
        result = _run(runner, command)
        assert result.exit_code == 0, result.output
    assert len(open_sequence(tmp_path / "agora_pred_seq")) == 2


def test_batch_given_a_tools_file_is_told_to_import_it(runner, phalp):
    """batch reads folders (with --from, of a tool's outputs): for one file, the import is the way."""
    read, convert = _suggestions(_one_line_error(invoke(runner, "batch", phalp)))
    assert read is None and convert == f"rotavat import --from 4dhumans {phalp} demo_video"


# ---- 2. a HybrIK res.pk of several videos ----------------------------------------------------------------------
def _two_videos(model, camera, sizes=((384, 640), (1280, 720))) -> list:
    rng = np.random.default_rng(11)

    def scene(n_frames):
        return [[F.standing_person(model, camera, rng.uniform(-3, 3), -rng.uniform(6, 14), pid) for pid in range(5)]
                for _ in range(n_frames)]
    return [("IMG_6412", scene(4), sizes[0]), ("dance", scene(3), sizes[1])]


def _video_imports(text: str) -> list[str]:
    return re.findall(r"rotavat import --from hybrik \S+ \S+ --video [^\s;]+", text)


def test_several_videos_are_told_to_import_each_never_to_copy_a_frame(runner, model, camera, tmp_path, monkeypatch):
    """Was: 'mkdir seq_dance-000001 && cp seq/dance-000001.npz ...': a one-frame sequence out of a video."""
    monkeypatch.chdir(tmp_path)
    src = WH.write_hybrik_videos(tmp_path / "res.pk", _two_videos(model, camera))
    assert invoke(runner, "import", src, tmp_path / "seq", "--quiet").exit_code == 0
    for args in (("calibrate", tmp_path / "seq"), ("align", tmp_path / "seq"),
                 ("calibrate", src, "--from", "hybrik", "--out", tmp_path / "c.yaml")):
        text = _one_line_error(invoke(runner, *args))
        assert "mkdir" not in text and "cp " not in text
        assert "its frames come from 2 videos of one file (IMG_6412: 4 frames, 384x640; dance: 3 frames, 1280x720)" in text
        assert _video_imports(text) == [f"rotavat import --from hybrik {src} res_IMG_6412 --video IMG_6412",
                                        f"rotavat import --from hybrik {src} res_dance --video dance"]
    info = invoke(runner, "info", tmp_path / "seq")
    assert info.exit_code == 0 and len(_video_imports(info.stderr)) == 2
    for command, size in zip(_video_imports(text), ((384, 640), (1280, 720))):
        assert _run(runner, command + " --quiet").exit_code == 0
        out = tmp_path / shlex.split(command)[5]
        result = invoke(runner, "calibrate", out, "--quiet")
        assert result.exit_code == 0, result.output
        assert open_sequence(out).camera.image_size == size


def test_several_videos_of_one_size_are_refused_too(runner, model, camera, tmp_path):
    """Two videos of one image size are still two cameras: was calibrated as one, silently."""
    src = WH.write_hybrik_videos(tmp_path / "res.pk", _two_videos(model, camera, sizes=((W, H), (W, H))))
    assert invoke(runner, "import", src, tmp_path / "seq", "--quiet").exit_code == 0
    text = _one_line_error(invoke(runner, "calibrate", tmp_path / "seq"))
    assert "2 videos" in text and len(_video_imports(text)) == 2


# ---- 3. AGORA predictions mixing SMPL and SMPL-X -----------------------------------------------------------------
def _smplx_params_file(path: Path, person) -> Path:
    """An AGORA SMPL-X parameter prediction (sample_pred_format/smplx_param_rm_*: rotation matrices)."""
    rot = F.rotmats(person.pose)
    eye = lambda n: np.broadcast_to(np.eye(3), (1, n, 3, 3)).copy()  # noqa: E731
    params = {"global_orient": rot[None, :1], "body_pose": rot[None, 1:22], "jaw_pose": eye(1), "leye_pose": eye(1),
              "reye_pose": eye(1), "left_hand_pose": eye(15), "right_hand_pose": eye(15), "betas": person.betas[None],
              "transl": person.transl[None]}
    path.write_bytes(pickle.dumps({"params": params, "pose2rot": False, "joints": np.zeros((1, 127, 2))}, protocol=2))
    return path


@pytest.fixture()
def models_here(tmp_path, monkeypatch, model_path, smplx_on_smpl_path) -> Path:
    """The current folder holds SMPL_NEUTRAL.npz and SMPLX_NEUTRAL.npz (as the messages name them)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "SMPL_NEUTRAL.npz").symlink_to(model_path)
    (tmp_path / "SMPLX_NEUTRAL.npz").symlink_to(smplx_on_smpl_path)
    return tmp_path


def _mixed_commands(text: str, src: Path) -> list[str]:
    assert text.startswith(f"{src}: mixes SMPL predictions (") and "and SMPL-X ones (" in text
    return text.split("so import each on its own: ", 1)[1].split("; ")


def test_agora_folder_mixing_smpl_and_smplx_is_said_with_the_imports_that_read_it(runner, scene, models_here):
    """Was: 'pass --smpl-model (the model AGORA used)', then "'params' pose has 22 joints, the model 24" or
    "missing key 'jaw_pose'" whichever model was given."""
    F.write_agora(models_here / "sample", scene[:1], params=True)  # SMPL parameters, two people
    for k, person in enumerate(scene[0]):
        _smplx_params_file(models_here / "sample" / f"smplx_param_rm_personId_{k}.pkl", person)
    texts = {model: _one_line_error(invoke(runner, "import", "sample", "out", *(("--smpl-model", model) if model else ())))
             for model in (None, "SMPL_NEUTRAL.npz", "SMPLX_NEUTRAL.npz")}
    assert len(set(texts.values())) == 1  # the same whatever model was given
    commands = _mixed_commands(texts[None], Path("sample"))
    assert commands == ["rotavat import --from agora sample sample_smpl --model-kind smpl --smpl-model SMPL_NEUTRAL.npz",
                        "rotavat import --from agora sample sample_smplx --model-kind smplx --smpl-model SMPLX_NEUTRAL.npz"]
    for command, kind in zip(commands, ("smpl", "smplx")):
        result = _run(runner, command + " --json")
        assert result.exit_code == 0, result.output
        assert json.loads(result.stdout)["people"] == 2
        assert open_sequence(models_here / f"sample_{kind}").meta["import"]["model_kind"] == kind


def test_model_kind_picks_and_refuses_plainly(runner, scene, models_here):
    src = F.write_agora(models_here / "sample", scene[:1], params=True)
    text = _one_line_error(invoke(runner, "import", src, "out", "--model-kind", "smplx"))
    assert text == f"{src}: holds no SMPL-X predictions (--model-kind smplx); its files by body model: SMPL 2"
    text = _one_line_error(invoke(runner, "import", src, "out", "--model-kind", "smpl", "--smpl-model",
                                  "SMPLX_NEUTRAL.npz"))
    assert "holds SMPL parameters; --smpl-model SMPLX_NEUTRAL.npz is SMPL-X (55 joints): pass the SMPL model" in text
    assert "--model-kind must be one of smpl, smplx" in _one_line_error(invoke(runner, "import", src, "o", "--model-kind", "x"))
    phalp = F.write_phalp(models_here / "v.pkl", scene, (W, H))
    assert "--model-kind selects one body model's predictions" in _one_line_error(
        invoke(runner, "import", phalp, "o", "--model-kind", "smpl"))


def test_agora_meshes_of_both_models_import_with_the_same_advice(runner, scene, models_here):
    """Vertices only (no model needed): the import goes through, and a warning says the folder mixes models."""
    src = models_here / "verts"
    src.mkdir()
    for kind, n in (("smpl", 6890), ("smplx", 10475)):
        person = scene[0][0]
        verts = np.resize(person.verts_cam, (n, 3))  # the person's surface, vertices repeated to the model's count
        (src / f"{kind}_verts_personId_0.pkl").write_bytes(pickle.dumps(
            {"verts": verts, "allSmplJoints3d": person.joints_cam, "joints": np.zeros((24, 2))}, protocol=2))
    result = invoke(runner, "import", "verts", "out")
    assert result.exit_code == 0, result.output
    (warning,) = [line for line in result.stderr.splitlines() if "mixes SMPL" in line]
    assert warning.endswith("--model-kind smpl; rotavat import --from agora verts verts_smplx --model-kind smplx")


@needs_agora
def test_agora_real_sample_names_the_model_its_parameters_need(runner, models_here):
    assert [model_kind_of(load_file(AGORA_SAMPLE / f"smpl_{k}_personId_0.pkl")) for k in ("verts", "param_rm")] == \
        ["smpl", "smpl"]
    text = _one_line_error(invoke(runner, "import", AGORA_SAMPLE, "ag"))
    assert text == (f"{AGORA_SAMPLE / 'smpl_param_rm_personId_0.pkl'}: holds SMPL parameters only: pass --smpl-model "
                    "SMPL_NEUTRAL.npz (the SMPL model file) to pose them")
    result = invoke(runner, "import", AGORA_SAMPLE, "ag", "--smpl-model", "SMPL_NEUTRAL.npz", "--quiet")
    assert result.exit_code == 0, result.output


@needs_agora
def test_agora_real_sample_beside_smplx_files_is_said_and_imported_per_model(runner, scene, models_here):
    """AGORA's own sample_pred_format/ holds smpl_* and smplx_* files: the two real SMPL ones (linked, never
    copied) beside SMPL-X parameter files."""
    src = models_here / "sample_pred_format"
    src.mkdir()
    for name in ("smpl_verts_personId_0.pkl", "smpl_param_rm_personId_0.pkl"):
        (src / name).symlink_to(AGORA_SAMPLE / name)
    _smplx_params_file(src / "smplx_param_rm_personId_0.pkl", scene[0][0])
    commands = _mixed_commands(_one_line_error(invoke(runner, "import", src, "out")), src)
    assert commands[0].endswith("sample_pred_format_smpl --model-kind smpl --smpl-model SMPL_NEUTRAL.npz")
    for command, frames in zip(commands, (2, 1)):
        result = _run(runner, command + " --json")
        assert result.exit_code == 0, result.output
        assert json.loads(result.stdout)["frames"] == frames


# ---- 4. --json on an error ------------------------------------------------------------------------------------
@pytest.mark.parametrize("args", [("info", "missing"), ("calibrate", "missing"), ("align", "missing"),
                                  ("measure", "missing"), ("render", "missing"), ("eval", "missing"),
                                  ("import", "missing", "out"), ("batch", "missing")])
def test_json_error_object_on_stdout_for_bad_input(runner, tmp_path, monkeypatch, args):
    """Was: nothing on stdout (a CI step parsing it got an empty string)."""
    monkeypatch.chdir(tmp_path)
    result = invoke(runner, *args, "--json")
    text = _one_line_error(result)
    assert json.loads(result.stdout) == {"error": text, "exit": 2, "command": f"rotavat {args[0]}",
                                         "kind": "InputError"}


def test_json_error_of_a_degenerate_scene_and_a_usage_error(runner, tmp_path):
    seq = shutil.copytree(SAMPLE_PRED, tmp_path / "pred")
    result = invoke(runner, "calibrate", seq, "--json", "--track", "999")
    assert json.loads(result.stdout)["error"] == _one_line_error(result)
    result = invoke(runner, "info", seq, "--json", "--bogus")
    text = _one_line_error(result)
    assert json.loads(result.stdout) == {"error": text, "exit": 2, "command": "rotavat info", "kind": "UsageError"}
    result = invoke(runner, "align", seq, "--jobs", "-1", "--json")  # a bad value: click's usage error
    assert json.loads(result.stdout)["kind"] == "UsageError" and result.exit_code == 2
    result = invoke(runner, "info", seq, "--bogus")  # no --json: nothing on stdout
    assert result.exit_code == 2 and result.stdout == ""


def test_a_failed_gate_keeps_its_json_result_as_the_one_document(runner, tmp_path):
    """eval --fail-if --json prints its result (gates_failed) and exits 1: no second object is added."""
    seq = shutil.copytree(SAMPLE_PRED, tmp_path / "pred")
    gt = shutil.copytree(SAMPLE_PRED.parent / "gt", tmp_path / "gt")
    result = invoke(runner, "eval", seq, "--gt", gt, "--fail-if", "w_mpjpe>1", "--json", "--out", tmp_path / "ev")
    assert _one_line_error(result, 1).startswith("quality gate failed: pred: w_mpjpe")
    document = json.loads(result.stdout)
    assert document["gates_failed"] and "error" not in document


# ---- 5. the small ones --------------------------------------------------------------------------------------------
def test_info_marks_an_implausible_camera_and_gives_each_std(runner, tmp_path):
    seq = shutil.copytree(SAMPLE_PRED, tmp_path / "pred")
    camera = Camera((1280, 720), 900.0, None, math.radians(30.0), 0.0, 6.0)
    fit = {"method": "refine", "std": {"focal_px": 120.5, "pitch_deg": 2.25, "roll_deg": 0.5, "height_m": None},
           "fixed": {"height_m": "given"}, "implausible": ["focal length 900 px is outside ..."]}
    write_camera_yaml(seq / "camera.yaml", camera, fit)
    result = invoke(runner, "info", seq)
    assert result.exit_code == 0
    cell = " ".join(result.stdout.split("camera.yaml", 1)[1].replace("│", " ").split())
    assert cell.startswith("f 900.0 ± 120.5 px, pitch 30.00 ± 2.25°, roll 0.00 ± 0.50°, height 6.00 m (given); "
                           "implausible (1 findings: fit.implausible)")
    assert "camera.yaml was found implausible by its calibration: focal length 900 px" in result.stderr


def test_calibrate_from_column_says_given_and_a_moved_stature_is_the_peoples(runner, tmp_path):
    """A given camera height was an empty "from"; a stature 3 sd from the 1.70 m prior was labelled 'prior'."""
    assert invoke(runner, "synth", tmp_path / "s", "--seed", "1", "--frames", "6", "--people", "5", "-q").exit_code == 0
    result = invoke(runner, "calibrate", tmp_path / "s" / "pred", "--camera-height", "6", "--out", tmp_path / "c.yaml")
    row = next(line for line in result.stdout.splitlines() if line.split("│")[1:2] == [" height_m        "])
    assert row.split("│")[4].strip() == "given"
    fit = yaml.safe_load((tmp_path / "c.yaml").read_text())["fit"]
    assert abs(fit["person_height_m"] - 1.70) > MOVED_PRIOR_SD * 0.10  # 0.10 m: the mean stature's prior sd
    assert fit["determined_by"]["height_m"] == "given" and fit["determined_by"]["person_height_m"] == "people+prior"
    assert not any("stature from the prior" in w for w in fit["warnings"])
    pitched = invoke(runner, "calibrate", tmp_path / "s" / "pred", "--pitch", "20", "--out", tmp_path / "p.yaml", "--json")
    assert json.loads(pitched.stdout)["fit"]["determined_by"]["pitch_deg"] == "given"


def test_moved_by_data_adds_the_people_only_beyond_two_prior_sd():
    free = np.array([True, True, True, True, False, False])
    priors = Priors(np.array([math.log(1000.0), 0.3, 0.0, math.log(3.0), 0.0, 0.0]),
                    np.array([0.3, 0.2, 0.05, 0.1, math.inf, math.inf]))
    params = np.array([1000.0, 0.3 + 1.9 * 0.2, 0.0, 3.0 * math.exp(2.1 * 0.1), 0.0, 0.0])
    labels = {0: "prior", 1: "prior", 2: "people", 3: "bodies+prior"}
    assert moved_by_data(labels, params, priors, free) == {0: "prior", 1: "prior", 2: "people",
                                                           3: "people+bodies+prior"}
    assert moved_by_data(labels, params, None, free) == labels


def test_cameras_equal_but_for_float_noise_match():
    """view's note 'placed in the scene camera ...; its own camera gives its ground' came for two cameras equal
    to 1e-16: ``==`` is exact, Camera.matches is not."""
    a = Camera((1280, 720), 1000.0, (640.0, 360.0), 0.5, 0.01, 4.0)
    b = Camera((1280, 720), 1000.0 * (1 + 1e-16), (640.0, 360.0 + 1e-13), 0.5 + 1e-16, 0.01, 4.0 * (1 + 2e-16))
    assert a != b and a.matches(b) and b.matches(a)
    assert not a.matches(a.replace(pitch_rad=0.5 + 1e-6)) and not a.matches(a.replace(image_size=(1280, 721)))
    assert not a.matches(None)


@pytest.mark.parametrize("columns", ["80", "200"])
def test_help_shows_each_range_once(runner, columns, monkeypatch):
    """Was '[>= 0] [default: 0]  [x>=0]' for --jobs: the rule's range and click's."""
    monkeypatch.setenv("COLUMNS", columns)
    for entry in COMMANDS:
        text = invoke(runner, entry.name, "--help").stdout
        assert "x>=" not in text and "x<=" not in text and "<=x" not in text and "range>" not in text, entry.name
    text = " ".join(invoke(runner, "align", "--help").stdout.replace("│", " ").split())
    assert "never more than the cores). [>= 0] [default: 0]" in text
    text = " ".join(invoke(runner, "synth", "--help").stdout.replace("│", " ").split())
    assert "Fraction of gross 2D outliers. [0..1] [default: 0]" in text


def test_why_4dhumans_frames_are_empty(runner, phalp, tmp_path):
    """Frame 3 of the fixture holds a track PHALP carried on without detecting it: was '1 empty', no reason."""
    result = invoke(runner, "import", phalp, tmp_path / "seq")
    assert result.exit_code == 0, result.output
    assert ("(3 people, 1 empty: 1 with only tracks PHALP carried on, no detection (tracked_time > 0: their last "
            "state repeated, not imported; first 000003))") in result.stdout
    info = invoke(runner, "info", tmp_path / "seq", "--json")
    assert json.loads(info.stdout)["empty_frames_why"].startswith("1 with only tracks PHALP carried on")


def test_the_walkthrough_scene_is_git_ignored_but_not_the_sample():
    lines = (Path(__file__).resolve().parents[1] / ".gitignore").read_text().splitlines()
    assert "/scene/" in lines and "scene/" not in lines  # anchored: sample_data/scene/ stays tracked
