"""The calibration's world checks on real files (../shared/realfiles, ../shared/realdata; README there): people
cut by the border, a group photo no one stature fits, a real camera whose edge walker used to pull the focal
away. Each test is skipped when its file is absent."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from _cli import invoke

from rotavat_cli.calibration import CalibrateOptions, calibrate_sequence
from rotavat_cli.sequence import open_sequence

SHARED = Path(__file__).resolve().parents[2] / "shared"
BEV_LIVE = SHARED / "realfiles" / "buddi" / "bev_live"
FLICKR = SHARED / "realfiles" / "buddi" / "flickr_bev" / "college_232334_0.08.npz"
PETS = SHARED / "realdata" / "pets2009_s2l1"


def _needs(path: Path) -> None:
    if not path.exists():
        pytest.skip(f"{path} absent (../shared)")


@pytest.mark.parametrize("image, beyond_px", [("image_1", 578), ("image_5", 981)])
def test_upper_body_photos_are_refused_naming_the_cut(image, beyond_px, tmp_path, runner):
    """BEV draws the legs these photos cut off: the feet land 578 and 981 px below the picture. calibrate used to
    answer (head rmse 2,136 px), and align with a given focal and height wrote people of 8-35 m; now one line
    names the cut and what still applies."""
    src = BEV_LIVE / f"{image}_0.08.npz"
    _needs(src)
    seq = tmp_path / image
    assert invoke(runner, "import", "--from", "bev", src, seq, "-q").exit_code == 0
    result = invoke(runner, "calibrate", seq)
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1
    assert (f"everyone is cut by the image border (2 people, their feet or crowns up to {beyond_px} px beyond"
            in result.stderr) and f"rotavat eval {seq} --gt GT" in result.stderr
    assert not (seq / "camera.yaml").exists()


def test_a_group_photo_no_one_stature_fits_is_implausible(tmp_path, runner):
    """The BUDDI photo: a boy, a kneeling woman, the photographer and a man seated behind him (his joints read as
    standing) measure 1.49-2.21 m under the camera they imply: the camera says so and align refuses it."""
    _needs(FLICKR)
    seq = tmp_path / "college"
    assert invoke(runner, "import", "--from", "bev", FLICKR, seq, "--image-size", "500", "332", "-q").exit_code == 0
    calib = calibrate_sequence(open_sequence(seq), CalibrateOptions())
    (spread,) = [f for f in calib.result.implausible if f.startswith("the people's implied statures spread by")]
    assert 20 < float(spread.split("spread by ")[1].split("%")[0]) < 40
    assert any("cut by the image border" in n for n in calib.result.notes)  # the bench sitter at the right edge
    refused = invoke(runner, "align", seq)
    assert refused.exit_code == 2 and "implied statures spread" in refused.stderr


def test_pets_walker_at_the_edge_no_longer_pulls_the_focal(tmp_path, runner):
    """PETS 2009 (true focal 1190 px): one person entering at the image's bottom edge (42 of 4,650 box pairs) moved
    the box model's focal to 576 px, 11 of its own std away. Left out as cut, the focal is within its std."""
    _needs(PETS)
    out = tmp_path / "c.yaml"
    result = invoke(runner, "calibrate", PETS, "--out", out)
    assert result.exit_code == 0, result.stderr
    assert "left out 1 person cut by the image border (42 of 4650 pairs" in " ".join(result.stderr.split())
    fit = yaml.safe_load(out.read_text())
    truth = yaml.safe_load((PETS / "camera_gt.yaml").read_text())
    z = abs(fit["focal_px"] - truth["focal_px"]) / fit["fit"]["std"]["focal_px"]
    assert z < 1.0 and math.isfinite(z) and fit["fit"]["scale_from"] == "prior"
