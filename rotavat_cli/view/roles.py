"""Each row's role in a recording, and the two rules that follow from it: which rows the 3D view frames,
and how a row tints its people's colours. Written once, here (docs/render.md, "rotavat view").

A row's role comes from its meta.yaml and its place on the command line:

- ``truth``: the ground truth (``--gt``);
- ``aligned``: a row placed in a known camera: its meta.yaml says ``aligned_from`` (``rotavat align``'s
  output) or ``focal_kind: camera``;
- ``raw``: any other row (an HPS tool's output in its own focal guess, possibly a hundred metres off).

The 3D view starts framed on the aligned rows and the truth (:func:`framed_rows`); a raw row stays drawn,
outside that framing when it is far. Without an aligned row or a truth, or with ``--frame-all``, every row.

>>> roles = [row_role({"focal_kind": "assumed"}), row_role({"aligned_from": {"focal_kind": "assumed"}}), row_role({}, truth=True)]
>>> roles
['raw', 'aligned', 'truth']
>>> framed_rows(roles), framed_rows(["raw", "raw"]), framed_rows(roles, frame_all=True)
([False, True, True], [True, True], [True, True, True])
>>> [tuple(round(float(c), 3) for c in row_tint(np.array([[1.0, 0.0, 0.0]]), tone)[0]) for tone in row_tones(roles)]
[(0.598, 0.258, 0.258), (1.0, 0.0, 0.0), (1.0, 0.5, 0.5)]
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["ROLES", "RowTone", "row_role", "framed_rows", "row_tones", "row_tint"]

ROLES = ("aligned", "truth", "raw")
_LUMA = np.array([0.2126, 0.7152, 0.0722])  # a colour's grey (Rec. 709 luma)
_WHITE, _BLACK = np.ones(3), np.zeros(3)
RowTone = tuple[tuple[str, float], ...]  # mixes applied in turn: ("white" | "black" | "grey", amount in [0, 1])
# the role's own tone: the aligned rows in the palette's colours, the truth paled, a raw row greyed and a little lighter
# (so that even the palette's grey differs between the three, and a raw row still shows on the viewer's dark ground)
_ROLE_TONE: dict[str, RowTone] = {"aligned": (), "truth": (("white", 0.5),), "raw": (("grey", 0.6), ("white", 0.15))}
# the 2nd, 3rd ... row of one role, on top of the role's tone: darker, lighter, much darker, much lighter (then again)
_REPEAT_TONE: tuple[RowTone, ...] = ((), (("black", 0.3),), (("white", 0.3),), (("black", 0.55),), (("white", 0.55),))


def row_role(meta: Mapping | None, truth: bool = False) -> str:
    """``"truth"`` for the ground truth, ``"aligned"`` for a row whose meta.yaml says ``aligned_from`` or
    ``focal_kind: camera``, else ``"raw"``."""
    if truth:
        return "truth"
    meta = meta or {}
    return "aligned" if "aligned_from" in meta or meta.get("focal_kind") == "camera" else "raw"


def framed_rows(roles: list[str], frame_all: bool = False) -> list[bool]:
    """Which rows the 3D view starts framed on: the aligned rows and the truth; every row with ``frame_all``
    or when there is neither."""
    if frame_all or all(role == "raw" for role in roles):
        return [True] * len(roles)
    return [role != "raw" for role in roles]


def row_tones(roles: list[str]) -> list[RowTone]:
    """Each row's tone: its role's, then, for the 2nd, 3rd ... row of the same role, darker, lighter, much darker,
    much lighter (cycling after the 5th): no two rows of up to five of a role, or of different roles, share one."""
    seen: dict[str, int] = {}
    tones = []
    for role in roles:
        k = seen.get(role, 0)
        seen[role] = k + 1
        tones.append(_ROLE_TONE[role] + _REPEAT_TONE[k % len(_REPEAT_TONE)])
    return tones


def row_tint(colors: np.ndarray, tone: RowTone) -> np.ndarray:
    """(..., 3) RGB in [0, 1] -> the same colours in a row's ``tone`` (each mix toward white, black or the colour's
    own grey, in turn)."""
    out = np.array(colors, dtype=np.float64)
    for toward, amount in tone:
        target = {"white": _WHITE, "black": _BLACK}.get(toward)
        if target is None:  # "grey": the colour's own luma, so its lightness stays
            target = (out @ _LUMA)[..., None]
        out = (1.0 - amount) * out + amount * target
    return out
