"""pymafx: importer being written (issue 17); registered, reads nothing yet."""

from __future__ import annotations

from pathlib import Path

READERS: dict = {}


def sniff(path: Path) -> str | None:
    """Nothing recognised yet."""
    return None
