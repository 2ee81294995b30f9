"""The focal as people know it: ``--focal-mm`` (35 mm equivalent) and a photo's EXIF (``calibrate --image``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from conftest import tree_hash
from PIL import Image
from PIL.ExifTags import IFD, Base

from rotavat_cli.calibration import CalibrateOptions
from rotavat_cli.geometry.camera import Camera
from rotavat_cli.errors import InputError
from rotavat_cli.geometry.focal import FULL_FRAME_DIAGONAL_MM, focal_px_at_size, focal_px_from_35mm
from rotavat_cli.formats.exif import focal_from_exif, read_photo_focal

SIZE = (1920, 1080)
# 26 mm (35 mm equivalent) on a 1920x1080 image: 26 / 43.2666 mm * 2202.907 px (the diagonal)
F26_PX = 26.0 * math.hypot(1920, 1080) / math.hypot(36, 24)


# ---- the conversion ------------------------------------------------------------------------------
def test_35mm_equivalent_by_hand():
    assert FULL_FRAME_DIAGONAL_MM == pytest.approx(43.2666153, abs=1e-7)  # sqrt(36^2 + 24^2) = sqrt(1872)
    # 26 mm on a 4032x3024 phone photo: its diagonal is 5040 px, so 26 * 5040 / 43.2666153 = 3028.663 px
    assert focal_px_from_35mm(26.0, (4032, 3024)) == pytest.approx(3028.663071, abs=1e-5)
    assert focal_px_from_35mm(26.0, SIZE) == pytest.approx(1323.782459, abs=1e-5)
    # the 35 mm frame itself at 1 px per mm: the focal in px is the focal in mm
    assert focal_px_from_35mm(50.0, (36, 24)) == pytest.approx(50.0)


@pytest.mark.parametrize("bad", [0.0, -26.0, math.nan, math.inf, True, "26"])
def test_35mm_equivalent_refuses_what_is_no_focal(bad):
    with pytest.raises(ValueError, match="35 mm-equivalent focal must be a positive number"):
        focal_px_from_35mm(bad, SIZE)


def test_a_focal_carried_to_another_image_size():
    assert focal_px_at_size(3000.0, (4000, 2250), SIZE) == pytest.approx(1440.0)  # 16:9 resized: width ratio 0.48
    assert focal_px_at_size(3000.0, (2250, 4000), SIZE) == pytest.approx(1440.0)  # the same photo held upright
    with pytest.raises(ValueError, match=r"a 4032x3024 image \(aspect 1.333\) is not a resize of a 1920x1080 one"):
        focal_px_at_size(3000.0, (4032, 3024), SIZE)


def test_options_fix_one_focal_and_name_where_it_came_from():
    opts = CalibrateOptions(focal_mm=26.0)
    assert opts.given_focal_px(SIZE) == pytest.approx(F26_PX) and CalibrateOptions().given_focal_px(SIZE) is None
    assert opts.given_focal_source("--focal", "--focal-mm") == "--focal-mm 26 (35 mm equivalent)"
    assert CalibrateOptions(focal_px=900.0, focal_source="EXIF x").given_focal_source() == "EXIF x"
    with pytest.raises(ValueError, match="focal_px and focal_mm both fix the focal length"):
        CalibrateOptions(focal_px=900.0, focal_mm=26.0)
    with pytest.raises(ValueError, match="focal_source names where a given focal came from"):
        CalibrateOptions(focal_source="--focal")  # no focal given


# ---- EXIF -----------------------------------------------------------------------------------------
def write_photo(path: Path, size: tuple[int, int], exif_tags: dict[int, object] | None = None,
                orientation: int | None = None) -> Path:
    """A small JPEG of ``size`` with these Exif-IFD tags (none: no EXIF at all)."""
    exif = Image.Exif()
    for tag, value in (exif_tags or {}).items():
        exif.get_ifd(IFD.Exif)[tag] = value
    if orientation is not None:
        exif[Base.Orientation] = orientation
    Image.new("RGB", size, (90, 120, 150)).save(path, **({"exif": exif} if exif_tags or orientation else {}))
    return path


def test_exif_tags_give_the_focal():
    assert focal_from_exif({Base.FocalLengthIn35mmFilm: 26}, (4032, 3024))[0] == pytest.approx(3028.663071, abs=1e-5)
    # FocalLength 4.25 mm; 1000 px per cm of sensor (unit 3) -> 4.25 mm * 100 px/mm = 425 px
    focal, words = focal_from_exif({Base.FocalLength: 4.25, Base.FocalPlaneXResolution: 1000.0,
                                    Base.FocalPlaneResolutionUnit: 3}, (640, 360))
    assert focal == pytest.approx(425.0) and words == "FocalLength 4.25 mm and FocalPlaneXResolution 1000 px/cm"
    # no unit: EXIF's default is the inch (25.4 mm)
    assert focal_from_exif({Base.FocalLength: 5.08, Base.FocalPlaneXResolution: 2540.0}, (640, 360))[0] == pytest.approx(508.0)
    assert focal_from_exif({Base.FocalLengthIn35mmFilm: 0}, SIZE)[0] is None  # 0 means unknown
    assert focal_from_exif({Base.FocalLength: 4.25, Base.FocalPlaneXResolution: 100.0,
                            Base.FocalPlaneResolutionUnit: 1}, SIZE) == (
        None, "FocalLength 4.25 mm but FocalPlaneResolutionUnit 1 is no length unit")


def test_read_photo_focal(tmp_path):
    photo = read_photo_focal(write_photo(tmp_path / "p.jpg", (384, 216), {Base.FocalLengthIn35mmFilm: 26}))
    assert photo.image_size == (384, 216) and photo.focal_px == pytest.approx(F26_PX / 5)
    assert photo.at_size(SIZE) == pytest.approx(F26_PX)
    assert photo.source(SIZE) == f"EXIF FocalLengthIn35mmFilm 26 mm of {tmp_path / 'p.jpg'}, a 384x216 photo carried to 1920x1080"
    upright = read_photo_focal(write_photo(tmp_path / "u.jpg", (384, 216), {Base.FocalLengthIn35mmFilm: 26}, orientation=6))
    assert upright.image_size == (216, 384) and upright.at_size(SIZE) == pytest.approx(F26_PX)  # shown turned
    png = tmp_path / "none.png"
    Image.new("RGB", (64, 36)).save(png)
    assert read_photo_focal(png).focal_px is None
    for name, data in (("text.jpg", b"not an image"), ("cut.jpg", b"\xff\xd8\xff\xe0\x00\x10JFIF")):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError, match=f"{name}: not a readable image"):
            read_photo_focal(tmp_path / name)
    with pytest.raises(InputError, match="missing.jpg: file not found"):
        read_photo_focal(tmp_path / "missing.jpg")


# ---- through the CLI ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def seq(tmp_path_factory) -> Path:
    """Foot/head pairs of 1.7 m people seen by a 1920x1080 camera of 26 mm (35 mm equivalent)."""
    cam = Camera(SIZE, F26_PX, None, np.deg2rad(20.0), np.deg2rad(1.0), 4.0)
    rng = np.random.default_rng(7)
    path = tmp_path_factory.mktemp("focal_mm") / "seq"
    path.mkdir()
    for t in range(3):
        feet_px = np.column_stack([rng.uniform(200, 1720, 8), rng.uniform(650, 1050, 8)])
        heads_px = cam.project(cam.backproject_px_to_ground(feet_px) + 1.7 * cam.up_cam)
        np.savez(path / f"{t:06d}.npz", feet_2d=feet_px, heads_2d=heads_px)
    (path / "meta.yaml").write_text("image_size: [1920, 1080]\n")
    return path


def calibrate_json(runner, seq: Path, out: Path, *args) -> dict:
    result = invoke(runner, "calibrate", seq, "--out", out / "cam.yaml", "--json", *args)
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


def refusal(runner, *args) -> str:
    """The one stderr line of a refused command (exit 2)."""
    result = invoke(runner, *[str(a) for a in args])
    assert result.exit_code == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]


def test_focal_mm_fixes_the_focal(runner, seq, tmp_path):
    before = tree_hash(seq)
    est = calibrate_json(runner, seq, tmp_path, "--focal-mm", "26")
    assert est["focal_px"] == pytest.approx(F26_PX, rel=1e-12)
    fit = est["fit"]
    assert fit["focal_policy"] == "given" and fit["fixed"]["focal_px"] == "given"
    assert fit["focal_source"] == "--focal-mm 26 (35 mm equivalent)"
    assert est["pitch_deg"] == pytest.approx(20.0, abs=0.01) and est["height_m"] == pytest.approx(4.0, rel=1e-3)
    assert tree_hash(seq) == before
    text = invoke(runner, "calibrate", seq, "--out", tmp_path / "c2.yaml", "--focal-mm", "26")
    assert "focal from --focal-mm 26 (35 mm equivalent)" in text.stdout  # the report line


def test_a_focal_flag_wins_over_the_config_files_other_key(runner, seq, tmp_path):
    config = tmp_path / "cfg.yaml"
    config.write_text("calibrate:\n  focal_px: 1000.0\n")
    est = calibrate_json(runner, seq, tmp_path, "--config", config, "--focal-mm", "26")
    assert est["focal_px"] == pytest.approx(F26_PX) and est["fit"]["focal_source"].startswith("--focal-mm")
    est = calibrate_json(runner, seq, tmp_path, "--config", config)
    assert est["focal_px"] == 1000.0 and est["fit"]["focal_source"] == "calibrate.focal_px"
    config.write_text("calibrate:\n  focal_px: 1000.0\n  focal_mm: 26.0\n")
    assert "focal_px and focal_mm both fix the focal length" in refusal(runner, "calibrate", seq, "--config", config,
                                                                         "--out", tmp_path / "c.yaml")


def test_focal_and_focal_mm_together_are_refused(runner, seq, tmp_path):
    line = refusal(runner, "calibrate", seq, "--focal", "1300", "--focal-mm", "26", "--out", tmp_path / "c.yaml")
    assert line == "error: --focal and --focal-mm both fix the focal length: give one, not both"
    assert not (tmp_path / "c.yaml").exists()
    line = refusal(runner, "batch", seq.parent, "--focal", "1300", "--focal-mm", "26", "--out", tmp_path / "b")
    assert "--focal and --focal-mm" in line


@pytest.mark.parametrize("bad", ["0", "-26", "nan", "inf"])
def test_a_focal_mm_that_is_no_focal_is_refused(runner, seq, tmp_path, bad):
    assert refusal(runner, "calibrate", seq, "--focal-mm", bad, "--out", tmp_path / "c.yaml").startswith("error: --focal-mm: must be")


def test_exif_35mm_equivalent_is_the_given_focal(runner, seq, tmp_path):
    photo = write_photo(tmp_path / "IMG_0001.jpg", (3840, 2160), {Base.FocalLengthIn35mmFilm: 26})
    est = calibrate_json(runner, seq, tmp_path, "--image", photo)
    assert est["focal_px"] == pytest.approx(F26_PX)  # the photo's 4K focal carried to the sequence's 1080p
    assert est["fit"]["focal_policy"] == "given"
    assert est["fit"]["focal_source"] == f"EXIF FocalLengthIn35mmFilm 26 mm of {photo}, a 3840x2160 photo carried to 1920x1080"
    # --focal and --focal-mm win over the photo
    est = calibrate_json(runner, seq, tmp_path, "--image", photo, "--focal", "1500")
    assert est["focal_px"] == 1500.0 and est["fit"]["focal_source"] == "--focal"


def test_exif_focal_length_with_the_sensors_pixel_pitch(runner, seq, tmp_path):
    # 1920 px over a 6.4 mm wide sensor: 300 px/mm; FocalLength 4.4127 mm -> 1323.8 px
    focal_mm = F26_PX / 300.0
    photo = write_photo(tmp_path / "fl.jpg", SIZE, {Base.FocalLength: focal_mm, Base.FocalPlaneXResolution: 300.0,
                                                    Base.FocalPlaneResolutionUnit: 4})
    est = calibrate_json(runner, seq, tmp_path, "--image", photo)
    assert est["focal_px"] == pytest.approx(F26_PX, rel=1e-6)  # EXIF rationals keep ~7 digits
    assert est["fit"]["focal_source"].startswith("EXIF FocalLength 4.41") and "FocalPlaneXResolution 300 px/mm" in est["fit"]["focal_source"]


def test_a_photo_without_a_focal_leaves_it_estimated(runner, seq, tmp_path):
    photo = write_photo(tmp_path / "plain.jpg", SIZE)
    result = invoke(runner, "calibrate", seq, "--out", tmp_path / "cam.yaml", "--image", photo)
    assert result.exit_code == 0, result.stderr
    assert "no focal length from its EXIF" in " ".join(result.stderr.split())
    est = calibrate_json(runner, seq, tmp_path, "--image", photo)
    assert est["fit"]["focal_policy"] == "estimated" and "focal_source" not in est["fit"]


def test_a_photo_that_cannot_give_the_focal_is_refused(runner, seq, tmp_path):
    photo = write_photo(tmp_path / "four_three.jpg", (400, 300), {Base.FocalLengthIn35mmFilm: 26})
    line = refusal(runner, "calibrate", seq, "--image", photo, "--out", tmp_path / "c.yaml")
    assert f"{photo}: a 400x300 image (aspect 1.333) is not a resize of a 1920x1080 one" in line
    (tmp_path / "notes.jpg").write_text("not a photo")
    assert refusal(runner, "calibrate", seq, "--image", tmp_path / "notes.jpg", "--out", tmp_path / "c.yaml").startswith(
        f"error: {tmp_path / 'notes.jpg'}: not a readable image")
    assert not (tmp_path / "c.yaml").exists()


def test_a_folder_of_frames_gives_its_first_frames_exif(runner, seq, tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    write_photo(frames / "000000.jpg", (960, 540), {Base.FocalLengthIn35mmFilm: 26})
    est = calibrate_json(runner, seq, tmp_path, "--image", frames)
    assert est["focal_px"] == pytest.approx(F26_PX) and str(frames / "000000.jpg") in est["fit"]["focal_source"]
