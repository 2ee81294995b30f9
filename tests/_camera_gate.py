"""Helpers for the camera gate's tests (align, render, batch): cameras with findings, and the commands a
refusal names."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import _cli
import typer

from rotavat_cli.sequence import read_camera_yaml, write_camera_yaml

FINDINGS = ("camera height 0.11 m is under 0.3 m",
            "focal length 96 px is outside the lens prior (0.25-2.2 x the image diagonal)")
DOCS = Path(__file__).resolve().parents[1] / "docs"


def write_camera(src: Path, dst: Path, fit: dict | None) -> Path:
    """``src``'s camera written to ``dst`` (as rotavat writes it) with ``fit`` as its fit block (None: none)."""
    camera, _ = read_camera_yaml(src)
    dst.parent.mkdir(parents=True, exist_ok=True)
    write_camera_yaml(dst, camera, fit)
    return dst


def implausible(src: Path, dst: Path, **extra) -> Path:
    """``src``'s camera written to ``dst`` with a fit block listing :data:`FINDINGS`."""
    return write_camera(src, dst, {"method": "refine", "implausible": list(FINDINGS), **extra})


def error_line(stderr: str) -> str:
    """The one error line of a refusal (asserting it is one line, after any warnings)."""
    errors = [line for line in stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, stderr
    return errors[0][len("error: "):]


def named_commands(message: str) -> list[list[str]]:
    """Every ``rotavat CMD ...`` a message names, as argument lists (up to the next bracket, comma or paren)."""
    found = re.finditer(r"rotavat (\S+(?: [^,()]*?)?)(?= \(|,|\)|$)", message)
    return [shlex.split(m.group(1).replace("[", "").replace("]", "")) for m in found]


def assert_named_flags_exist(message: str) -> None:
    """Every --flag a message names after ``rotavat CMD`` is an option of CMD."""
    group = _cli.command()
    ctx = typer.Context(group)
    commands = {name: group.get_command(ctx, name) for name in group.list_commands(ctx)}
    for args in named_commands(message):
        command = commands[args[0]]
        options = {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)}
        for flag in (a for a in args[1:] if a.startswith("--")):
            assert flag in options, (args[0], flag)
        for flag in re.findall(r"--[a-z][a-z-]+", message):  # the ones named alone (e.g. "or --accept-camera")
            assert any(flag in {opt for p in c.params for opt in (*p.opts, *p.secondary_opts)}
                       for c in commands.values()), flag


def markdown_anchors(page: Path) -> set[str]:
    """GitHub's anchors of a Markdown page's headings (lower case, punctuation dropped, spaces to hyphens)."""
    heads = re.findall(r"^#+ (.+)$", page.read_text(), re.M)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in heads}


def assert_doc_link_exists(message: str) -> None:
    """The docs/<page>#<anchor> a message points to is a heading of that page."""
    for page, anchor in re.findall(r"docs/([\w.]+\.md)#([\w-]+)", message):
        assert anchor in markdown_anchors(DOCS / page), (page, anchor)
