"""The lens from the scene's straight lines (plumb-line calibration of the division model).

A straight edge of the scene (a kerb, a door frame, a wall's corner, a lamp post) is straight in the
pinhole image and bent by the lens. Given a few such edges clicked as polylines of image pixels, the
division coefficient ``lam`` (:mod:`rotavat_cli.geometry.lens`) is the one that makes them straight
again: it minimises the summed squared orthogonal distance of each line's undistorted points to that
line's own best-fitting straight line (total least squares: the smaller eigenvalue of the points'
2x2 scatter). One parameter, so a grid over the whole admissible range then a bounded refinement
finds the global minimum; its std comes from the curvature of that sum and the residual scatter.

Lines far from the principal point and long ones carry the information; lines through the centre
carry none (they are straight whatever the lens). The fit says how many lines and points it used,
its std and the residual, and refuses input that cannot determine it (fewer than 2 lines of 3
points, or a std as large as the range).

>>> from rotavat_cli.geometry.lens import distort_px, lens_radius_px
>>> size, pp = (1280, 720), (640.0, 360.0)
>>> straight = [np.stack([np.linspace(50, 1230, 12), np.full(12, v)], axis=1) for v in (40.0, 680.0)]
>>> straight += [np.stack([np.full(12, u), np.linspace(30, 690, 12)], axis=1) for u in (60.0, 1220.0)]
>>> bent = [distort_px(line, -0.2, pp, lens_radius_px(size)) for line in straight]
>>> fit = fit_plumb_lines(bent, size)
>>> round(fit.distortion, 6), fit.lines, fit.points
(-0.2, 4, 48)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..files.yaml_io import read_yaml
from ..geometry.lens import MAX_DISTORTION, lens_radius_px, undistort_px

__all__ = ["PlumbLineFit", "fit_plumb_lines", "straightness_px2", "read_lines_file", "MIN_LINES", "MIN_POINTS_PER_LINE"]

MIN_LINES = 2  # one line confounds the lens with the line's own curvature... of which there is none: two to be sure
MIN_POINTS_PER_LINE = 3  # two points always lie on a line
MAX_LINES, MAX_POINTS_PER_LINE = 1_000, 10_000  # what a file may hold (clicked edges: a few, tens of points each)
_GRID = 201  # coefficients tried over [-MAX_DISTORTION, MAX_DISTORTION] before refining (0.005 apart)


@dataclass(frozen=True)
class PlumbLineFit:
    """The lens that straightens the lines: distortion (lam), its std, the rms orthogonal residual (px, undistorted)
    of the points to their lines, and how many lines and points were used."""

    distortion: float
    std: float
    rms_px: float
    lines: int
    points: int

    def as_dict(self) -> dict:
        """Plain-typed summary (camera.yaml's ``fit.lens`` block, JSON output)."""
        return {"from": "lines", "distortion": float(self.distortion), "std": float(self.std),
                "rms_px": float(self.rms_px), "lines": int(self.lines), "points": int(self.points)}


def straightness_px2(lines_px: list[np.ndarray], distortion: np.ndarray | float, principal_point: tuple[float, float],
                     radius_px: float) -> np.ndarray:
    """Summed squared orthogonal distance (px^2) of every line's undistorted points to its own best straight line.

    lines_px: K arrays (n_k, 2) of distorted pixels; distortion: lam, scalar or (G,) -> result () or (G,).
    Per line: the distances along the normal of its total-least-squares line (the scatter's eigenvector of the
    smaller eigenvalue), squared and summed; computed as distances, not as that eigenvalue's closed form, whose
    cancellation leaves 1e-11 px^2 of noise on exactly straight lines.
    """
    lam = np.asarray(distortion, dtype=np.float64)
    total = np.zeros(lam.size)
    for line in lines_px:
        pts = undistort_px(line[None], lam.reshape(-1, 1), principal_point, radius_px)  # (G, n, 2)
        d = pts - pts.mean(axis=1, keepdims=True)
        scatter = np.einsum("gni,gnj->gij", d, d)
        if not np.all(np.isfinite(scatter)):
            scatter = np.where(np.isfinite(scatter), scatter, 0.0)
            bad = ~np.all(np.isfinite(pts), axis=(1, 2))
        else:
            bad = None
        normal = np.linalg.eigh(scatter)[1][..., 0]  # (G, 2): eigenvalues ascending
        total += np.sum(np.einsum("gni,gi->gn", d, normal) ** 2, axis=1)
        if bad is not None:
            total[bad] = np.nan  # a point with no pinhole pixel at that coefficient: not admissible
    return total.reshape(lam.shape)


def fit_plumb_lines(lines_px: list[np.ndarray], image_size: tuple[int, int],
                    principal_point: tuple[float, float] | None = None) -> PlumbLineFit:
    """The division coefficient that makes ``lines_px`` (K arrays (n_k, 2) of image pixels) straight.

    principal_point: (cx, cy) px, default the image centre; the model's radius is the half-diagonal.
    ValueError when the lines cannot determine it (module docstring).
    """
    from scipy.optimize import minimize_scalar  # lazy: scipy.optimize costs 0.1 s to import

    lines = [np.asarray(line, dtype=np.float64) for line in lines_px]
    lines = [line[np.all(np.isfinite(line), axis=1)] for line in lines]
    lines = [line for line in lines if len(line) >= MIN_POINTS_PER_LINE]
    if len(lines) < MIN_LINES:
        raise ValueError(f"the lens needs at least {MIN_LINES} lines of {MIN_POINTS_PER_LINE}+ points each, "
                         f"got {len(lines)}")
    pp = (image_size[0] / 2.0, image_size[1] / 2.0) if principal_point is None else tuple(map(float, principal_point))
    radius = lens_radius_px(image_size)
    grid = np.linspace(-MAX_DISTORTION, MAX_DISTORTION, _GRID)
    cost = straightness_px2(lines, grid, pp, radius)
    best = int(np.nanargmin(cost))
    step = grid[1] - grid[0]
    low, high = max(grid[0], grid[best] - step), min(grid[-1], grid[best] + step)
    found = minimize_scalar(lambda lam: float(straightness_px2(lines, lam, pp, radius)), bounds=(low, high),
                            method="bounded", options={"xatol": 1e-10})
    lam, sse = float(found.x), float(found.fun)
    points = sum(len(line) for line in lines)
    dof = max(points - 2 * len(lines) - 1, 1)  # each line: a direction and an offset; the lens: one
    std = _curvature_std(lines, lam, sse, dof, pp, radius)
    if not std < MAX_DISTORTION:
        raise ValueError(f"the {len(lines)} lines do not determine the lens (std {std:.2g}): click longer lines "
                         "nearer the image's border")
    return PlumbLineFit(lam, std, math.sqrt(sse / points), len(lines), points)


def _curvature_std(lines: list[np.ndarray], lam: float, sse_px2: float, dof: int, pp: tuple[float, float],
                   radius_px: float) -> float:
    """std of lam from the least-squares curvature: ``var = 2 s^2 / S''(lam)``, ``s^2 = S / dof`` (px^2)."""
    h = 1e-4
    values = straightness_px2(lines, np.array([lam - h, lam, lam + h]), pp, radius_px)
    second = (values[0] - 2.0 * values[1] + values[2]) / (h * h)
    if not second > 0:
        return math.inf
    noise_px2 = max(sse_px2 / dof, 1e-6)  # exact lines (synthetic) still get a finite std: 1e-3 px of noise
    return math.sqrt(2.0 * noise_px2 / second)


def read_lines_file(path: str | Path) -> list[np.ndarray]:
    """Polylines (K arrays (n_k, 2) px) from a YAML or JSON file ``{lines: [[[u, v], ...], ...]}``; InputError
    naming the file and the problem otherwise."""
    data = read_yaml(path)
    raw = data.get("lines") if isinstance(data, dict) else None
    if not isinstance(raw, list) or not raw:
        raise InputError(f"{path}: expected a mapping with 'lines': a list of polylines, each a list of [u, v] pixels")
    if len(raw) > MAX_LINES:
        raise InputError(f"{path}: {len(raw)} lines, more than the {MAX_LINES} a lens needs (at most)")
    lines = []
    for k, line in enumerate(raw):
        if isinstance(line, list) and len(line) > MAX_POINTS_PER_LINE:  # checked before converting: YAML aliases
            raise InputError(f"{path}: lines[{k}] has {len(line)} points, more than {MAX_POINTS_PER_LINE}")
        if not isinstance(line, list) or not all(_is_pixel(point) for point in line):  # before numpy sees a nest
            raise InputError(f"{path}: lines[{k}] must be a list of [u, v] pixel pairs")
        arr = np.asarray(line, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 2 or not np.all(np.isfinite(arr)):
            raise InputError(f"{path}: lines[{k}] must be a list of finite [u, v] pixel pairs, got shape {list(arr.shape)}")
        lines.append(arr)
    return lines


def _is_pixel(point: object) -> bool:
    """Whether a YAML value is one ``[u, v]`` pair of numbers."""
    return (isinstance(point, list) and len(point) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in point))
