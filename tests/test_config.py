"""Config precedence: defaults < --config FILE < flags; unknown keys are errors."""

from pathlib import Path

import pytest

from rotavat_cli.settings.config import DEFAULT_CONFIG_PATH, default_config, load_config
from rotavat_cli.errors import InputError


def test_the_repo_defaults_are_the_packaged_file_itself():
    """One source: configs/default.yaml is a link to the packaged file (installed with the package),
    not a copy kept equal."""
    repo_file = Path(__file__).resolve().parents[1] / "configs" / "default.yaml"
    assert repo_file.is_symlink() and repo_file.resolve() == DEFAULT_CONFIG_PATH


def test_paper_grid_defaults():
    grid = default_config()["calibrate"]["grid"]
    assert grid == {"focal_range_h": [0.1, 6.0], "pitch_range_deg": [-45.0, 90.0], "height_range_m": [0.5, 40.0], "steps": [50, 50, 50]}


def test_precedence(tmp_path: Path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("calibrate:\n  person_height_m: 1.8\n  method: grid\n")
    merged = load_config(cfg, {"calibrate": {"method": "refine", "residual": None}})
    assert merged["calibrate"]["person_height_m"] == 1.8  # from the file
    assert merged["calibrate"]["method"] == "refine"  # flag wins
    assert merged["calibrate"]["residual"] == "full"  # unset flag keeps the default


def test_defaults_are_not_mutated(tmp_path: Path):
    load_config(None, {"synth": {"frames": 3}})
    assert default_config()["synth"]["frames"] == 20


@pytest.mark.parametrize("text,message", [
    ("calibrate:\n  metod: grid\n", "unknown key 'calibrate.metod'"),
    ("calibrate:\n  person_height_m: tall\n", "person_height_m"),
    ("calibrate: 3\n", "must be a mapping"),
    ("- a\n", "mapping"),
])
def test_bad_config_names_key_and_file(tmp_path: Path, text, message):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        load_config(cfg)
    assert "bad.yaml" in str(info.value)


def test_cli_config_error_exits_2(tmp_path: Path, runner):
    from _cli import invoke

    cfg = tmp_path / "bad.yaml"
    cfg.write_text("synth:\n  peeple: 3\n")
    result = invoke(runner, "synth", tmp_path / "out", "--config", cfg)
    assert result.exit_code == 2 and "peeple" in result.stderr and "bad.yaml" in result.stderr
    assert not (tmp_path / "out").exists()


def test_every_options_class_defaults_to_the_packaged_config():
    """The packaged YAML is the one source of defaults: each options class built from it equals its own defaults."""
    from rotavat_cli.alignment import AlignOptions
    from rotavat_cli.batch import BatchOptions
    from rotavat_cli.calibration import CalibrateOptions
    from rotavat_cli.metrics.evaluate import EvalOptions
    from rotavat_cli.render import FigureOptions, RenderStyle
    from rotavat_cli.synth import SynthOptions

    config = default_config()
    assert AlignOptions() == AlignOptions.from_config(config["align"])
    assert CalibrateOptions() == CalibrateOptions.from_config(config["calibrate"])
    assert EvalOptions() == EvalOptions.from_config(config["eval"])
    assert SynthOptions() == SynthOptions.from_config(config["synth"])
    assert FigureOptions() == FigureOptions.from_config(config["render"])
    assert RenderStyle() == RenderStyle.from_config(config["render"])
    assert BatchOptions() == BatchOptions.from_config(config)
