"""``rotavat`` run in this process, its click command built from the Typer app once per process.

typer's ``CliRunner.invoke(app, ...)`` builds the whole click command (every command, option and help
text) on each call: about 0.3 s, most of a small in-process run. Here it is built on first use and
reused by every ``CliRunner().invoke(app, ...)`` of the process (a pytest session, or one pytest-xdist
worker; the fuzz campaign of ``make fuzz``). The command keeps no state between runs: each run gets its
own click context, as a new process would.
"""

from __future__ import annotations

import functools

import typer.main
import typer.testing
from typer.testing import CliRunner

from rotavat_cli.cli import app


@functools.cache
def command():
    """The click command of ``rotavat`` (built once, on first use)."""
    return typer.main.get_command(app)


def _get_command(typer_app):
    return command() if typer_app is app else typer.main.get_command(typer_app)


# typer.testing.CliRunner.invoke builds the command through this module-level name (typer 0.12 to 0.29).
assert callable(getattr(typer.testing, "_get_command", None)), "typer.testing changed: update tests/_cli.py"
typer.testing._get_command = _get_command


def invoke(runner: CliRunner, *args, **kwargs):
    """``rotavat ARGS`` in-process (exceptions propagate unless ``catch_exceptions=True``); the click Result."""
    kwargs.setdefault("catch_exceptions", False)
    return runner.invoke(app, [str(a) for a in args], **kwargs)


def error_text(result) -> str:
    """A refused run's message (exit 2, no traceback, its first line an ``error:``): its lines joined by spaces
    (a long one-line message may be folded by the terminal's width)."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert lines[0].startswith("error:")
    return " ".join(lines)
