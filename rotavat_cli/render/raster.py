"""The renderer choice, made here only: OpenGL (:mod:`.gl`) or the NumPy z-buffer (:mod:`.fallback`).

Both rasterise the same way: ``rasterize(points (N, 3), faces (F, 3), colors (N, 3),
clip_from_points (4, 4), size (W, H)) -> (H, W, 4) float32 RGBA``, row 0 at the top, alpha =
coverage. ``auto`` tries OpenGL and falls back, recording why in :attr:`Rasterizer.note`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..errors import RotavatError
from .fallback import rasterize_numpy
from .gl import open_gl_context

__all__ = ["RENDERERS", "Rasterizer", "open_rasterizer"]

RENDERERS = ("auto", "gl", "fallback")


@dataclass
class Rasterizer:
    """A rasterise function plus which renderer it is (``gl`` or ``fallback``) and why, if it fell back."""

    name: str
    rasterize: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[int, int]], np.ndarray]
    note: str = ""
    detail: str = ""  # e.g. the GL renderer string
    _release: Callable[[], None] | None = field(default=None, repr=False)

    def release(self) -> None:
        """Free the GL context, if any."""
        if self._release is not None:
            self._release()
            self._release = None

    def __enter__(self) -> "Rasterizer":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def open_rasterizer(kind: str = "auto") -> Rasterizer:
    """``gl`` (moderngl via EGL; RotavatError if it cannot start), ``fallback`` (NumPy z-buffer), or
    ``auto``: gl if it starts, else the fallback with the reason as its note."""
    if kind not in RENDERERS:
        raise ValueError(f"unknown renderer {kind!r} (expected one of {', '.join(RENDERERS)})")
    note = "requested"
    if kind != "fallback":
        try:
            context = open_gl_context()
        except RotavatError as exc:
            if kind == "gl":
                raise
            note = str(exc)
        else:
            return Rasterizer("gl", context.rasterize, detail=context.renderer_name, _release=context.release)
    return Rasterizer("fallback", rasterize_numpy, note=note, detail="numpy z-buffer")
