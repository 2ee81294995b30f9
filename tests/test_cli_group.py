"""The command group: its list is cli/commands.py, a command is built when used, and `rotavat` alone,
an unknown command or a command's --help answer as users expect."""

from __future__ import annotations

import typer
from _cli import invoke

from rotavat_cli.cli import app
from rotavat_cli.cli.commands import COMMANDS, command_entry


def test_help_lists_every_command_with_its_summary_in_order(runner):
    result = invoke(runner, "--help")
    assert result.exit_code == 0
    lines = " ".join(result.stdout.split())  # the summaries wrap at the terminal's width
    positions = [lines.index(f"{entry.name} {entry.summary[:40]}") for entry in COMMANDS]
    assert positions == sorted(positions)


def test_rotavat_alone_prints_its_help_and_no_error(runner):
    result = invoke(runner)
    assert result.exit_code == 0 and result.stdout.startswith("Usage: rotavat") and "error" not in result.stderr


def test_an_unknown_command_is_one_line_naming_it(runner):
    result = invoke(runner, "calibate")
    assert result.exit_code == 2 and result.stderr.strip() == "error: rotavat: No such command 'calibate'. (see rotavat --help)"


def test_a_command_is_built_from_its_entry_once_per_group():
    group = typer.main.get_command(app)
    ctx = typer.Context(group)
    assert group.list_commands(ctx) == [entry.name for entry in COMMANDS]
    built = group.get_command(ctx, "batch")
    assert built is group.get_command(ctx, "batch")  # cached
    assert built.short_help == command_entry("batch").summary
    assert built.help.startswith(command_entry("batch").summary + "\n\nA sequence whose outputs")  # its docstring below
    assert group.get_command(ctx, "nope") is None


def test_listing_the_commands_imports_none_of_them():
    """While the group's help is written its commands are stubs: no command module is imported."""
    group = typer.main.get_command(app)
    ctx = typer.Context(group)
    group._listing = True
    try:
        stub = group.get_command(ctx, "render")
    finally:
        group._listing = False
    assert stub.short_help == command_entry("render").summary and stub.params == []
    assert "render" not in group._built
