"""The ``rotavat`` command line: a thin layer over the Python API, one module per command.

Exit status: 0 ok; 1 a ``--fail-if`` gate tripped; 2 bad input or usage.
"""

from __future__ import annotations

from typing import Annotated

import typer

from ..version import WRITTEN_BY
from . import align, batch, calibrate, eval, export, import_, info, measure, render, synth
from ._common import RotavatGroup

app = typer.Typer(
    name="rotavat",
    cls=RotavatGroup,
    help="Put the people of a static-camera HPS output back on the ground. "
    "Exit status: 0 ok, 1 a --fail-if gate tripped, 2 bad input or usage.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
    rich_markup_mode="rich",
)


def _version(value: bool) -> None:
    """Print the version and exit."""
    if value:
        typer.echo(WRITTEN_BY)
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Show the version and exit.")] = False,
) -> None:
    """rotavat: auto-calibrate a static camera from its people, re-seat HPS meshes on the ground, and score them."""


# The commands, registered here in the order `rotavat --help` lists them (a new command: one module + one line).
app.command()(info.info)
app.command()(synth.synth)
app.command()(calibrate.calibrate)
app.command()(measure.measure)
app.command()(align.align)
app.command("eval")(eval.eval_)
app.command()(render.render)
app.command()(export.export)
app.command("import")(import_.import_)
app.command()(batch.batch)


def main() -> None:
    """Console-script entry point."""
    app()
