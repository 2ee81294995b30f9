"""The ``rotavat`` command line: a thin layer over the Python API, one module per command (listed in
:mod:`rotavat_cli.cli.commands`, imported only when used: :mod:`rotavat_cli.cli.group`).

Exit status: 0 ok; 1 a ``--fail-if`` gate tripped; 2 bad input or usage.
"""

from __future__ import annotations

import os

# BLAS runs single-threaded unless the environment says otherwise (set before numpy loads OpenBLAS): rotavat
# parallelises over frames (processes) and grid pitches (threads) itself, and OpenBLAS's own threads, spinning
# for the small products a fit makes, only compete with them (calibrate, 20,000 pairs on 2 cores: CPU 3.2 s ->
# 1.8 s, wall 2.2 s -> 1.8 s; docs/performance.md).
for _blas_threads in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_blas_threads, "1")

from typing import Annotated  # noqa: E402

from ..allocator import keep_freed_memory  # noqa: E402

keep_freed_memory()  # frames' arrays are reused, not faulted in again page by page (rotavat_cli.allocator)

import typer  # noqa: E402

from ..version import WRITTEN_BY
from .group import RotavatGroup  # lists the commands of .commands; imports one when it is used

app = typer.Typer(
    name="rotavat",
    cls=RotavatGroup,
    help="Put the people of a static-camera HPS output back on the ground. "
    "Exit status: 0 ok, 1 a --fail-if gate tripped, 2 bad input or usage.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
    rich_markup_mode=None,  # the command list in click's plain layout: rich's would cost `--help` ~0.15 s of imports
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


def main() -> None:
    """Console-script entry point."""
    app()
