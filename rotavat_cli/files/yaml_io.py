"""YAML files in and out: the safe loader only, one-line errors naming the file, atomic writes under
rotavat's header line (which says rotavat wrote the file and may replace it:
:func:`rotavat_cli.files.outputs.written_by_rotavat`)."""

from __future__ import annotations

from pathlib import Path

import yaml

from .atomic import atomic_write_text
from ..errors import file_error
from .outputs import TEXT_HEADER
from ..version import __version__


def read_yaml(path: str | Path) -> dict:
    """Load a YAML mapping with ``yaml.safe_load`` (an empty file is ``{}``); errors name the file."""
    path = Path(path)
    if path.exists() and not path.is_file():
        raise file_error(path, "not a regular file")
    try:
        with open(path, encoding="utf-8") as handle:
            data = yaml.safe_load(handle)
    except FileNotFoundError:
        raise file_error(path, "file not found") from None
    except yaml.YAMLError as exc:
        raise file_error(path, f"invalid YAML ({str(exc).splitlines()[0]})") from None
    except RecursionError:
        raise file_error(path, "YAML nested too deeply to read") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise file_error(path, f"cannot read ({exc})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise file_error(path, "must hold a YAML mapping (key: value)")
    return data


def write_yaml(path: str | Path, data: dict) -> None:
    """Dump plain-typed ``data`` with ``yaml.safe_dump`` atomically, under rotavat's header line."""
    header = f"{TEXT_HEADER} {__version__}\n"
    atomic_write_text(path, header + yaml.safe_dump(data, sort_keys=False, default_flow_style=None))
