"""What one run of ``rotavat`` keeps in its click context's ``meta`` (a dict the group's context shares with
the command's), for the group's error handler and the commands' messages; and that context itself.

A leaf of the CLI (typer only): the group writes the command line and whether ``--json`` was given, a
command's :func:`~rotavat_cli.cli._common.print_json` that it printed its result, and messages that name a
command to run repeat the user's own line (:func:`~rotavat_cli.cli._common.not_a_sequence`).
"""

from __future__ import annotations

import importlib
from typing import Any

import typer

__all__ = ["ARGV_KEY", "COMMAND_KEY", "JSON_KEY", "JSON_PRINTED_KEY", "current_context"]

ARGV_KEY = "rotavat.argv"  # the arguments after ``rotavat`` as given: messages repeat the user's command line
COMMAND_KEY = "rotavat.command"  # the running command's path ("rotavat info")
JSON_KEY = "rotavat.json"  # the running command was given --json: an error is also one JSON object on stdout
JSON_PRINTED_KEY = "rotavat.json_printed"  # the command printed its JSON result (print_json): stdout holds one

# click's Context as typer ships it (typer may vendor its own click), and the module keeping the current one
_CLICK_CONTEXT = next(c for c in typer.Context.__mro__ if c.__name__ == "Context" and c.__module__.endswith(".core"))


def current_context() -> Any:
    """The click context of the running command (None outside a run: the Python API)."""
    globals_ = importlib.import_module(_CLICK_CONTEXT.__module__.rsplit(".", 1)[0] + ".globals")
    return globals_.get_current_context(silent=True)
