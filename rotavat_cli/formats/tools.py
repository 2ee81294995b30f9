"""The formats rotavat reads, by ``--from`` name, and how messages name each one's tool.

A leaf of the package (it imports nothing of rotavat): whatever names a tool in a message (a file
that is no tool's output, a file that looks like another tool's, ``--video`` on a format holding
one video) reads this table. Every reader of :mod:`.registry` has its name here (checked there).

>>> tool_name("hybrik"), tool_name("agora")
('a HybrIK', 'an AGORA')
>>> FORMATS[:3]
('4dhumans', 'agora', 'bedlam')
"""

from __future__ import annotations

__all__ = ["FORMATS", "TOOL_NAMES", "tool_name"]

# --from name -> the tool's own name
TOOL_NAMES = {"cliff": "CLIFF", "bev": "BEV", "romp": "ROMP", "4dhumans": "4D-Humans", "multihmr": "Multi-HMR",
              "spec": "SPEC", "agora": "AGORA", "bedlam": "BEDLAM", "wham": "WHAM", "gvhmr": "GVHMR", "tram": "TRAM",
              "hybrik": "HybrIK", "pymafx": "PyMAF-X", "slahmr": "SLAHMR", "glamr": "GLAMR", "trace": "TRACE",
              "comotion": "CoMotion", "prompthmr": "PromptHMR"}
FORMATS = tuple(sorted(TOOL_NAMES))  # what --from takes, sorted (as messages list them)


def tool_name(fmt: str) -> str:
    """How messages name the tool of format ``fmt``, with its article: 'a HybrIK', 'an AGORA'."""
    name = TOOL_NAMES.get(fmt, fmt)
    return f"{'an' if name[:1] in 'AEIOU' else 'a'} {name}"
