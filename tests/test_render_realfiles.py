"""rotavat render on a real group photo (/work/shared/realfiles, README there): BEV's output of the BUDDI flickr
photo, imported, calibrated, aligned and drawn over the photo itself. Skipped when the files are absent.

Issue 24: the photo under the front view ended in a traceback (``box offset can't be negative``) whenever the
image's rectangle started at a fractional panel pixel that rounded down (a 500x493 photo at the default 640x360,
this 500x332 one at 136x90, 320x180 or 400x400), with ``--fit people`` and ``--fit camera`` alike.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from _cli import invoke
from PIL import Image

REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"
FLICKR = REALFILES / "buddi" / "flickr_bev"
BEV_FILE = FLICKR / "college_232334_0.08.npz"
PHOTO = FLICKR / "college_232334.png"

pytestmark = pytest.mark.skipif(not (BEV_FILE.is_file() and PHOTO.is_file()),
                                reason="real BEV group photo absent (../shared/realfiles)")


@pytest.fixture(scope="module")
def aligned_photo(tmp_path_factory, runner) -> tuple[Path, Path, Path]:
    """(imported sequence, its aligned output, a folder holding the photo named like the frame)."""
    root = tmp_path_factory.mktemp("flickr")
    seq = root / "college"
    for args in (["import", "--from", "bev", BEV_FILE, seq, "--image-size", "500", "332"], ["calibrate", seq],
                 ["align", seq, "--accept-camera"]):
        result = invoke(runner, *args, "-q")
        assert result.exit_code == 0, (args, result.stderr)
    images = root / "images"
    images.mkdir()
    (images / "college_232334.png").symlink_to(PHOTO)  # matched to the frame by name; not copied
    return seq, root / "college_aligned", images


def test_the_photo_under_the_front_view_at_a_panel_size_that_crashed(runner, aligned_photo, tmp_path):
    """In a 136x90 panel the whole photo (the people are all over it) starts at x = 0.23 px, which rounded down
    asked Pillow for the photo from a negative offset. Now it is drawn, its corner where the image starts; and
    the aligned row's caption counts its flagged people (people.csv), the imported row has none."""
    seq, aligned, images = aligned_photo
    W, H = 136, 90
    result = invoke(runner, "render", seq, aligned, "--image", images, "--renderer", "fallback", "--views", "front",
                    "--size", str(W), str(H), "--out", tmp_path / "fig", "--json", "--accept-camera")
    assert result.exit_code == 0 and "Traceback" not in result.stderr, result.output
    summary = json.loads(result.stdout)
    with Image.open(summary["files"][0]) as img:
        front = np.asarray(img.convert("RGB"))[26 + 26:26 + 26 + H, :W].astype(int)  # header, caption, first row's panel
    with Image.open(PHOTO) as photo:
        corner = np.asarray(photo.convert("RGB"))[:12, :12].reshape(-1, 3).mean(axis=0)  # the photo's top-left corner
    s = min(W / 500, H / 332)  # the whole photo, letterboxed: its top-left corner is drawn where the image starts
    x0, y0 = int(np.ceil(0.5 * (W - s * 500))), int(np.ceil(0.5 * (H - s * 332)))
    assert np.abs(front[y0:y0 + 3, x0 + 1:x0 + 4].reshape(-1, 3).mean(axis=0) - corner).max() < 30
    with open(aligned / "people.csv", encoding="utf-8", newline="") as handle:
        flagged = sum(1 for r in csv.DictReader(handle) if r["flag"])
    assert "flagged" not in summary["captions"]["college"]
    assert (f"{flagged} flagged in people.csv" in summary["captions"]["college_aligned"]) == bool(flagged)
