"""The ``rotavat`` group: builds a command only when it is used, and answers every failure in one line
(and, for a command given ``--json``, in one JSON object on stdout).

Start-up is the price of every call, ``rotavat --help`` included, so the group imports nothing of the
API: it lists the commands from :data:`rotavat_cli.cli.commands.COMMANDS` and imports a command's
module (and through it the API that command runs) when that command is resolved. While the group's
own help is written, each command is a stub carrying its one-line summary.
"""

from __future__ import annotations

import importlib
import inspect
import json
import sys
import warnings
from typing import Any

import typer
from typer.core import TyperCommand, TyperGroup

from ..errors import RotavatError
from ._run import ARGV_KEY, COMMAND_KEY, JSON_KEY, JSON_PRINTED_KEY
from .commands import COMMANDS, CommandEntry, command_entry

__all__ = ["RotavatGroup", "error_line"]

# click's exception classes as typer ships them (typer may vendor its own click)
_USAGE_ERROR = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")
_CLICK_EXCEPTION = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")
_NO_ARGS_IS_HELP = getattr(sys.modules[_USAGE_ERROR.__module__], "NoArgsIsHelpError", ())  # click >= 8.2


class RotavatGroup(TyperGroup):
    """Click group that builds each command on first use and answers every bad input or usage with
    one line on stderr and exit status 2.

    A RotavatError prints its message and exits with its code (2, or 1 for a quality gate). The
    environment's refusals that no check can rule out beforehand (a file system error, memory
    exhausted, a structure nested too deep) are input problems too: one line, exit 2. Usage errors
    (a missing option, a bad value) are one line naming the command, not click's help box.

    With ``--json``, every one of these failures is also one JSON object on stdout (:func:`_json_error`),
    unless the command already printed its JSON result there (``eval --fail-if``, ``batch``: the result
    carries the failure), so stdout always parses as one JSON document.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._built: dict[str, Any] = {}  # name -> click command, built once per group
        self._listing = False  # True while the group's own --help is written: commands are stubs

    def list_commands(self, ctx: Any) -> list[str]:
        return [entry.name for entry in COMMANDS]

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        entry = command_entry(cmd_name)
        if entry is None:
            return None
        if self._listing:
            return TyperCommand(name=entry.name, help=entry.summary, short_help=entry.summary)
        if cmd_name not in self._built:
            self._built[cmd_name] = _build(entry, ctx)
        return self._built[cmd_name]

    def format_help(self, ctx: Any, formatter: Any) -> None:
        self._listing = True
        try:
            super().format_help(ctx, formatter)
        finally:
            self._listing = False

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        ctx.meta[ARGV_KEY] = list(args)
        return super().parse_args(ctx, args)

    def invoke(self, ctx: Any) -> Any:
        try:
            with warnings.catch_warnings():  # numpy's overflow/invalid-value notes on hostile data: the
                warnings.simplefilter("ignore", RuntimeWarning)  # checks after them say what is wrong, once
                return super().invoke(ctx)
        except RotavatError as exc:
            message, code, kind = str(exc), exc.exit_code, type(exc).__name__
        except OSError as exc:
            where = f"{exc.filename}: " if exc.filename else ""
            message, code, kind = f"{where}{exc.strerror or exc}", 2, "OSError"
        except MemoryError:
            message, code, kind = ("out of memory: the input is larger than this machine can hold (see the limits "
                                   "section of configs/default.yaml)", 2, "MemoryError")
        except RecursionError:
            message, code, kind = "the input is nested too deeply to read", 2, "RecursionError"
        error_line(message)
        if ctx.meta.get(JSON_KEY) and not ctx.meta.get(JSON_PRINTED_KEY):
            _json_error(message, code, ctx.meta.get(COMMAND_KEY, "rotavat"), kind)
        raise typer.Exit(code) from None

    def main(self, args: Any = None, prog_name: str | None = None, complete_var: str | None = None,
             standalone_mode: bool = True, **extra: Any) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        try:
            code = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except _NO_ARGS_IS_HELP as exc:  # `rotavat` alone: its help is the answer
            typer.echo(exc.ctx.get_help())
            sys.exit(0)
        except _USAGE_ERROR as exc:
            name = exc.ctx.command_path if exc.ctx is not None else "rotavat"
            message = f"{name}: {exc.format_message()} (see {name} --help)"
            error_line(message)
            if _asked_for_json(exc.ctx, sys.argv[1:] if args is None else args):
                _json_error(message, 2, name, "UsageError")
            sys.exit(2)
        except _CLICK_EXCEPTION as exc:
            error_line(exc.format_message())
            if _asked_for_json(getattr(exc, "ctx", None), sys.argv[1:] if args is None else args):
                _json_error(exc.format_message(), exc.exit_code, "rotavat", type(exc).__name__)
            sys.exit(exc.exit_code)
        except typer.Abort:
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


class _Command(TyperCommand):
    """A rotavat command: notes in its context whether it was given --json (the group's error handler reads it)."""

    def invoke(self, ctx: Any) -> Any:
        ctx.meta[JSON_KEY] = bool(ctx.params.get("as_json"))
        ctx.meta[COMMAND_KEY] = ctx.command_path
        return super().invoke(ctx)


def _asked_for_json(ctx: Any, args: Any) -> bool:
    """True when a usage error hit a command that has --json and the command line gave it (before any ``--``)."""
    command = getattr(ctx, "command", None)
    if command is None or not any("--json" in getattr(p, "opts", ()) for p in command.params):
        return False
    args = [str(a) for a in (args or ())]
    return "--json" in (args[:args.index("--")] if "--" in args else args)


def _json_error(message: str, code: int, command: str, kind: str) -> None:
    """The failure as one JSON object on stdout, for a run given --json: ``error`` (the one-line message, as on
    stderr), ``exit`` (the status), ``command`` (``rotavat info``) and ``kind`` (what failed: ``InputError``,
    ``DegenerateSceneError``, ``GateError``, ``UsageError``, ``OSError``, ...)."""
    text = " ".join(str(message).split())
    typer.echo(json.dumps({"error": text, "exit": code, "command": command, "kind": kind}, indent=2))


def _build(entry: CommandEntry, ctx: Any) -> Any:
    """The click command of ``entry``: its module imported, typer's command built from its function,
    the entry's summary heading its help, and its --help polished (defaults and ranges from the config)."""
    function = getattr(importlib.import_module(f"{__package__}.{entry.module}"), entry.function)
    details = inspect.cleandoc(function.__doc__) if function.__doc__ else ""  # more than the summary
    app = typer.Typer(add_completion=False, rich_markup_mode="rich")
    app.command(entry.name, help=entry.summary + (f"\n\n{details}" if details else ""),
                short_help=entry.summary, cls=_Command)(function)
    command = typer.main.get_command(app)
    from ._common import polish_command_help  # the CLI's shared plumbing: loaded with the first command built

    polish_command_help(command, entry.section)
    help_option = command.get_help_option(ctx)  # click adds --help itself (cached per command)
    if help_option is not None:
        help_option.metavar = ""
    return command


def error_line(message: str) -> None:
    """One line on stderr: ``error: <message>``. The message is text, not markup: "rotavat[fast]" or a
    path with brackets stays intact; it is never wrapped, so CI logs and tests see one line."""
    from rich.markup import escape  # lazy: rich only when there is something to say

    from ._common import console

    text = " ".join(str(message).split())
    console.print(f"[bold red]error:[/] {escape(text)}", highlight=False, markup=True, soft_wrap=True)
