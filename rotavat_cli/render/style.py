"""Colours, palette, shading and fonts of the pictures.

Defaults: the packaged ``configs/default.yaml``, section ``render``, is their one source:
``RenderStyle()`` is ``RenderStyle.from_config(default_config()["render"])`` (each field's default
is read from it, see :func:`packaged_default`). Every person has the colour
``palette[person_id mod len(palette)]``, the same in every frame, row and view.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from PIL import ImageFont
from scipy.sparse import csr_matrix

from ..settings.config import default_config, packaged_default
from ..settings.option_rules import Rule, check_fields

__all__ = ["RGB", "RenderStyle", "parse_color", "person_colors", "vertex_normals", "shade_vertices"]

RGB = tuple[float, float, float]  # in [0, 1]
_AMBIENT = 0.35  # shading: light that reaches every surface


def parse_color(text: str) -> RGB:
    """'#rrggbb' -> (r, g, b) in [0, 1]; raises ValueError otherwise.

    >>> parse_color("#ff0000")
    (1.0, 0.0, 0.0)
    """
    s = str(text).strip().lstrip("#")
    if len(s) != 6 or any(ch not in "0123456789abcdefABCDEF" for ch in s):
        raise ValueError(f"colour {text!r} must be '#rrggbb'")
    return tuple(int(s[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


@functools.lru_cache(maxsize=1)
def _packaged_style() -> "RenderStyle":
    """RenderStyle of the packaged ``render:`` section (read once)."""
    return RenderStyle.from_config(default_config()["render"])


@dataclass(frozen=True)
class RenderStyle:
    """Colours (RGB in [0, 1]) and the margin around people in orthographic views."""

    background: RGB = packaged_default(_packaged_style, "background")
    ground: RGB = packaged_default(_packaged_style, "ground")
    grid: RGB = packaged_default(_packaged_style, "grid")
    camera: RGB = packaged_default(_packaged_style, "camera")
    text: RGB = packaged_default(_packaged_style, "text")
    palette: tuple[RGB, ...] = packaged_default(_packaged_style, "palette")
    margin: float = packaged_default(_packaged_style, "margin")  # orthographic views: fraction of the people's extent added

    RULES: ClassVar[dict[str, Rule]] = {"margin": Rule(low=0, high=10)}  # rotavat_cli/settings/option_rules.py

    def __post_init__(self) -> None:
        check_fields(self, self.RULES, prefix="render.")

    @classmethod
    def from_config(cls, opts: dict) -> "RenderStyle":
        """Style from a ``render:`` config section (hex colours, palette as comma-separated hex)."""
        palette = tuple(parse_color(c) for c in str(opts["palette"]).split(",") if c.strip())
        if not palette:
            raise ValueError("palette must list at least one colour")
        return cls(parse_color(opts["background"]), parse_color(opts["ground"]), parse_color(opts["grid"]),
                   parse_color(opts["camera_color"]), parse_color(opts["text"]), palette, float(opts["margin"]))


def person_colors(person_ids: np.ndarray, palette: tuple[RGB, ...]) -> np.ndarray:
    """(P,) ids -> (P, 3) colours: ``palette[id mod len(palette)]``, stable across frames and rows."""
    pal = np.asarray(palette, dtype=np.float64).reshape(-1, 3)
    return pal[np.mod(np.asarray(person_ids, dtype=np.int64), len(pal))]


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P, V, 3) vertices, (F, 3) faces -> (P, V, 3) unit area-weighted normals (0 where undefined), in the
    vertices' precision (float32 stays float32; anything else is float64)."""
    v = np.asarray(verts)
    v = v if v.dtype in (np.float32, np.float64) else v.astype(np.float64)
    P, V = v.shape[:2]
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    by_vertex = np.ascontiguousarray(v.transpose(1, 0, 2))  # (V, P, 3): a face's corners gather whole rows
    corner = by_vertex[f[:, 0]]
    face_n = _cross(by_vertex[f[:, 1]] - corner, by_vertex[f[:, 2]] - corner)  # (F, P, 3), |n| = 2 area
    n = (_incidence(V, f, v.dtype.str) @ face_n.reshape(f.shape[0], P * 3)).reshape(V, P, 3)
    norm = np.sqrt(np.einsum("vpk,vpk->vp", n, n))[..., None]
    undefined = np.broadcast_to(~(norm > 0), n.shape)  # no face, or a NaN vertex in one of its faces
    np.divide(n, norm, out=n, where=~undefined)
    n[undefined] = 0.0
    return n.transpose(1, 0, 2)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (..., 3) arrays (np.cross's work without its generality: about half the time)."""
    out = np.empty_like(a)
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(a[..., j], b[..., k], out=out[..., i])
        out[..., i] -= a[..., k] * b[..., j]
    return out


# The incidence matrices of the last few topologies (faces, V, dtype, matrix), newest first: a sequence's frames
# share one list of faces, read again with every frame, so it is compared (a memcmp), never hashed.
_INCIDENCE: list[tuple[np.ndarray, int, str, csr_matrix]] = []
_INCIDENCE_KEPT = 8
_INCIDENCE_LOCK = threading.Lock()  # rotavat view computes normals on worker threads


def _incidence(n_verts: int, faces: np.ndarray, dtype: str) -> csr_matrix:
    """(V, F) vertex-face incidence of (F, 3) int64 ``faces``: one mesh topology is built once, not per frame."""
    with _INCIDENCE_LOCK:
        for kept, v, kind, matrix in _INCIDENCE:
            if v == n_verts and kind == dtype and (kept is faces or (kept.shape == faces.shape and np.array_equal(kept, faces))):
                return matrix
    f = np.array(faces, dtype=np.int64)  # a copy: the caller's array may change later
    matrix = csr_matrix((np.ones(f.size, dtype=dtype), (f.reshape(-1), np.repeat(np.arange(len(f)), 3))),
                        shape=(n_verts, len(f)))
    with _INCIDENCE_LOCK:
        _INCIDENCE.insert(0, (f, n_verts, dtype, matrix))
        del _INCIDENCE[_INCIDENCE_KEPT:]
    return matrix


def shade_vertices(colors: np.ndarray, normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Two-sided Lambert: colours and unit normals (..., 3) (broadcast), light (3,) -> lit colours (..., 3)."""
    lambert = np.abs(np.asarray(normals, dtype=np.float64) @ np.asarray(light, dtype=np.float64))
    return np.asarray(colors, dtype=np.float64) * (_AMBIENT + (1.0 - _AMBIENT) * lambert)[..., None]


def rgb8(color: RGB) -> tuple[int, int, int]:
    """Colour in [0, 1] -> 8-bit tuple."""
    return tuple(int(round(255 * min(max(c, 0.0), 1.0))) for c in color)  # type: ignore[return-value]


def mix(a: RGB, b: RGB, t: float) -> RGB:
    """(1 - t) a + t b."""
    return tuple((1 - t) * x + t * y for x, y in zip(a, b))  # type: ignore[return-value]


def font(size_px: int) -> Any:
    """Pillow's default font at a size (bitmap default on Pillow builds without FreeType)."""
    try:
        return ImageFont.load_default(size=size_px)
    except (TypeError, OSError, ImportError):
        return ImageFont.load_default()
