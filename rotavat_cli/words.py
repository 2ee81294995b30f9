"""Words for messages: a count with its noun in the right number.

>>> count(1, "person", "people"), count(3, "frame"), count(0, "pair")
('1 person', '3 frames', '0 pairs')
>>> count(1, "aligned person has", "aligned people have")
'1 aligned person has'
"""

from __future__ import annotations

__all__ = ["count"]


def count(n: int, one: str, many: str | None = None) -> str:
    """``"<n> <one>"`` for n == 1, else ``"<n> <many>"`` (default: ``one`` + "s")."""
    return f"{n} {one if n == 1 else (many if many is not None else one + 's')}"
