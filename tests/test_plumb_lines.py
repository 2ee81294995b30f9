"""The lens from the scene's straight lines (rotavat_cli.calibration.plumb_lines)."""

from __future__ import annotations

import numpy as np
import pytest

from rotavat_cli.calibration.plumb_lines import fit_plumb_lines, read_lines_file, straightness_px2
from rotavat_cli.errors import InputError
from rotavat_cli.geometry.lens import distort_px, lens_radius_px

SIZE = (1280, 720)
PP = (652.0, 351.0)  # off the image centre, as a real principal point


def _scene_lines(rng: np.random.Generator, n_lines: int, points: int) -> list[np.ndarray]:
    """Straight pinhole segments across the image (random ends), ``points`` samples each."""
    lines = []
    for _ in range(n_lines):
        a, b = rng.uniform([40, 30], [1240, 690], size=(2, 2))
        t = np.linspace(0.0, 1.0, points)[:, None]
        lines.append(a + t * (b - a))
    return lines


def _clicked(lines: list[np.ndarray], lam: float, noise_px: float, rng: np.random.Generator) -> list[np.ndarray]:
    radius = lens_radius_px(SIZE)
    return [distort_px(line, lam, PP, radius) + rng.normal(0.0, noise_px, line.shape) for line in lines]


@pytest.mark.parametrize("lam", [-0.3, -0.12, 0.0, 0.15])
def test_exact_lines_give_the_lens_back(lam):
    rng = np.random.default_rng(1)
    fit = fit_plumb_lines(_clicked(_scene_lines(rng, 5, 10), lam, 0.0, rng), SIZE, PP)
    assert fit.distortion == pytest.approx(lam, abs=1e-6)
    assert fit.rms_px < 1e-3
    assert (fit.lines, fit.points) == (5, 50)


def test_noisy_clicks_recover_the_lens_within_two_std_in_nine_of_ten_scenes():
    inside, errors = 0, []
    for seed in range(40):
        rng = np.random.default_rng(seed)
        fit = fit_plumb_lines(_clicked(_scene_lines(rng, 6, 8), -0.25, 1.0, rng), SIZE, PP)
        errors.append(fit.distortion + 0.25)
        inside += abs(fit.distortion + 0.25) <= 2 * fit.std
        assert 0.5 < fit.rms_px < 1.5  # the click noise, 1 px
    assert inside >= 36, (inside, np.round(errors, 4))
    assert abs(np.mean(errors)) < 0.01


def test_the_straightness_is_smallest_at_the_true_lens():
    rng = np.random.default_rng(3)
    bent = _clicked(_scene_lines(rng, 4, 12), -0.2, 0.0, rng)
    cost = straightness_px2(bent, np.array([-0.3, -0.2, -0.1, 0.0]), PP, lens_radius_px(SIZE))
    assert np.argmin(cost) == 1 and cost[1] < 1e-6 < cost[2] < cost[3]


def test_too_few_lines_or_points_are_refused():
    rng = np.random.default_rng(0)
    lines = _scene_lines(rng, 3, 10)
    with pytest.raises(ValueError, match="at least 2 lines"):
        fit_plumb_lines(lines[:1], SIZE)
    with pytest.raises(ValueError, match="at least 2 lines"):
        fit_plumb_lines([line[:2] for line in lines], SIZE)


def test_lines_through_the_centre_cannot_tell_the_lens():
    centre = np.array(PP)
    lines = [centre + np.linspace(-300, 300, 9)[:, None] * np.array(d) for d in ((1.0, 0.0), (0.0, 1.0), (0.6, 0.8))]
    with pytest.raises(ValueError, match="do not determine the lens"):
        fit_plumb_lines(lines, SIZE, PP)


def test_the_lines_file_is_read_and_bad_ones_named(tmp_path):
    good = tmp_path / "lines.yaml"
    good.write_text("lines:\n  - [[10, 20], [30, 40], [50, 61]]\n  - [[0, 0], [5, 5], [9, 11], [20, 19]]\n")
    lines = read_lines_file(good)
    assert [line.shape for line in lines] == [(3, 2), (4, 2)]
    bad = tmp_path / "bad.yaml"
    bad.write_text("lines:\n  - [[10, 20, 3], [30, 40, 3]]\n")
    with pytest.raises(InputError, match=r"bad.yaml: lines\[0\] must be a list of \[u, v\] pixel pairs"):
        read_lines_file(bad)
    bad.write_text("lines:\n  - [[10, 20], [30, .nan], [1, 2]]\n  - [[0, 0], [5, 5], [9, 11]]\n")
    with pytest.raises(InputError, match=r"bad.yaml: lines\[0\] must be a list of finite \[u, v\] pixel pairs"):
        read_lines_file(bad)
    (tmp_path / "none.yaml").write_text("points: []\n")
    with pytest.raises(InputError, match="none.yaml: expected a mapping with 'lines'"):
        read_lines_file(tmp_path / "none.yaml")


def test_a_small_file_of_yaml_aliases_is_refused_before_it_is_expanded(tmp_path):
    """Nine levels of nine aliases are 387 million values once expanded: refused from the shape of the first point."""
    levels = ["a0: &a0 [1.0, 2.0]"] + [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, 9)]
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(levels) + "\nlines: [*a8, *a8]\n")
    assert bomb.stat().st_size < 1000
    with pytest.raises(InputError, match=r"lines\[0\] must be a list of \[u, v\] pixel pairs"):
        read_lines_file(bomb)
