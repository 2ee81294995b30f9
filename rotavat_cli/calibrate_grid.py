"""The seed paper's calibration grid: focal, pitch and camera height from foot/head pixels.

Model (roll 0 in the paper, principal point ``pp``, stature ``S``): back-project each foot pixel
onto the ground, put the head ``S`` metres above it along world up ``n``, project it, and sum the
squared pixel distances to the observed heads. :func:`predict_heads_px` is that model written with
:mod:`rotavat_cli.camera`'s functions; :func:`grid_costs` evaluates it on every cell of the grid
fast, using its structure:

- with ``F`` the foot and ``Hd`` the observed head (pixels relative to ``pp``), ``k = S / c``
  (``c`` the camera height) and ``d = -n . (F/f, 1)`` (foot ray against up), the predicted head is
  ``F + M / (1/k - g)`` with ``g = -n_z d`` and ``M = d (f n_xy - n_z F)``. ``d``, ``g`` and ``M``
  depend on the focal and pitch only, never on ``c``;
- so the head residual is ``e = D + w M`` with ``D = F - Hd`` and ``w = 1 / (c/S - g)``, and the
  cost of a cell is ``sum|D|^2 + 2 w.(D.M) + (w*w).|M|^2``: one subtraction, one reciprocal and
  one square per cell and pair (float32, cache-sized blocks of pairs), and two matrix-vector
  products. The sum is re-evaluated exactly (float64, :func:`predict_heads_px`) on the cells
  within the float32 error of the minimum, so :func:`paper_grid_search` returns the grid's true
  best cell;
- a cell is invalid (cost ``inf``, skipped) when a foot ray misses the ground (``d <= 0``) or a
  head lands behind the camera (``c/S <= g``); both are per-(focal, pitch) maxima, no extra pass.

Memory is bounded by the block size, whatever the number of pairs (a few MB per worker thread).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .camera import backproject_px_to_plane, project_cam_to_px, up_vector_cam

__all__ = [
    "GridSpec",
    "GridFit",
    "predict_heads_px",
    "head_residuals_px",
    "reference_cell_costs",
    "grid_costs",
    "robust_grid_costs",
    "paper_grid_search",
    "order_invariant_subset",
    "seed_cells",
]

_RAY_EPS = 1e-12  # same "ray parallel to the ground" threshold as camera.backproject_px_to_plane
_BLOCK_ELEMS = 200_000  # float32 cells x pairs per block: ~0.8 MB, stays in L2
_RECHECK_REL = 2e-3  # float32 costs are trusted to this relative error; closer cells are re-checked ...
_RECHECK_ABS = 1e-5  # ... plus this fraction of sum|foot - head|^2 (float32 cancellation; measured ~1e-7)
_RECHECK_MAX = 4096  # at most this many cells are re-evaluated in float64
# Row-wise dot product without BLAS gemv (OpenBLAS worker threads spin and starve the grid's threads).
_DOT = getattr(np, "vecdot", lambda a, b: np.einsum("ij,j->i", a, b))


@dataclass(frozen=True)
class GridSpec:
    """The paper's search grid, inclusive and evenly spaced (defaults = the paper's)."""

    focal_range_h: tuple[float, float] = (0.1, 6.0)  # times the image height H
    pitch_range_deg: tuple[float, float] = (-45.0, 90.0)
    height_range_m: tuple[float, float] = (0.5, 40.0)
    steps: tuple[int, int, int] = (50, 50, 50)  # focal, pitch, height

    def __post_init__(self) -> None:
        for name in ("focal_range_h", "pitch_range_deg", "height_range_m"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise ValueError(f"grid {name} must be [low, high] with low <= high, got {getattr(self, name)}")
            object.__setattr__(self, name, (lo, hi))
        steps = tuple(int(s) for s in self.steps)
        if len(steps) != 3 or min(steps) < 1:
            raise ValueError(f"grid steps must be three positive integers, got {self.steps}")
        object.__setattr__(self, "steps", steps)
        self._check_size()
        if self.focal_range_h[0] <= 0 or self.height_range_m[0] <= 0:
            raise ValueError("grid focal and height ranges must be positive")

    def _check_size(self) -> None:
        """ValueError naming ``calibrate.grid.steps`` when a search over this grid would be larger than
        ``limits.max_grid_cells``: the paper's grid (steps[0] x steps[1] x steps[2] cells, float64 costs),
        or the refine method's seeding grid (its own focal and height counts x steps[1] pitches)."""
        from .calibrate_model import _INIT_STEPS  # noqa: PLC0415 -- calibrate_model imports this module
        from .limits import current

        limit = current().max_grid_cells
        cells = math.prod(self.steps)
        seeding = _INIT_STEPS[0] * self.steps[1] * _INIT_STEPS[1]
        if cells > limit:
            raise ValueError(f"calibrate.grid.steps {list(self.steps)} make {cells:,} grid cells "
                             f"(limit {limit:,}: limits.max_grid_cells)")
        if seeding > limit:
            raise ValueError(f"calibrate.grid.steps {list(self.steps)}: {self.steps[1]:,} pitch steps make the refine "
                             f"method's seeding grid {seeding:,} cells ({_INIT_STEPS[0]} x {self.steps[1]} x "
                             f"{_INIT_STEPS[1]}; limit {limit:,}: limits.max_grid_cells)")

    def focal_values_px(self, image_height_px: float) -> np.ndarray:
        """(F,) candidate focal lengths in pixels."""
        lo, hi = self.focal_range_h
        return np.linspace(lo, hi, self.steps[0]) * float(image_height_px)

    def pitch_values_rad(self) -> np.ndarray:
        """(P,) candidate pitches in radians."""
        return np.deg2rad(np.linspace(*self.pitch_range_deg, self.steps[1]))

    def height_values_m(self) -> np.ndarray:
        """(C,) candidate camera heights in metres."""
        return np.linspace(*self.height_range_m, self.steps[2])


@dataclass(frozen=True)
class GridFit:
    """Best cell of a grid search and the cost of every cell (``inf`` = invalid)."""

    focal_px: float
    pitch_rad: float
    height_m: float
    cost: float  # float64 sum of squared head residuals at the best cell, px^2
    index: tuple[int, int, int]  # (focal, pitch, height) indices of the best cell
    costs: np.ndarray  # (F, P, C) float64 costs (float32 accuracy away from the minimum)


# ---- the model, written plainly (reference for the fast kernel and for refinement) ---------------
def predict_heads_px(feet_px: np.ndarray, focal_px: np.ndarray | float, pitch_rad: np.ndarray | float,
                     roll_rad: np.ndarray | float, height_m: np.ndarray | float, principal_point: tuple | np.ndarray,
                     person_height_m: np.ndarray | float) -> np.ndarray:
    """Predicted head pixels (..., N, 2) of people standing on feet_px (N, 2); NaN where invalid.

    Camera parameters broadcast over leading dimensions ``(...)``; ``person_height_m`` is a
    scalar or (N,). Invalid: the foot ray misses the ground or the head is behind the camera.
    """
    f = np.asarray(focal_px, dtype=np.float64)[..., None]
    h = np.asarray(height_m, dtype=np.float64)[..., None]
    n = up_vector_cam(pitch_rad, roll_rad)[..., None, :]
    feet_cam = backproject_px_to_plane(feet_px, f, principal_point, n, h)
    heads_cam = feet_cam + np.asarray(person_height_m, dtype=np.float64)[..., None] * n
    return project_cam_to_px(heads_cam, f, principal_point)


def head_residuals_px(feet_px: np.ndarray, heads_px: np.ndarray, focal_px, pitch_rad, roll_rad, height_m,
                      principal_point, person_height_m) -> np.ndarray:
    """Predicted minus observed head pixels (..., N, 2); NaN where the model is invalid."""
    pred = predict_heads_px(feet_px, focal_px, pitch_rad, roll_rad, height_m, principal_point, person_height_m)
    return pred - np.asarray(heads_px, dtype=np.float64)


def reference_cell_costs(feet_px: np.ndarray, heads_px: np.ndarray, focal_px: np.ndarray, pitch_rad: np.ndarray,
                         height_m: np.ndarray, principal_point, person_height_m: float, residual: str = "full",
                         roll_rad: float = 0.0) -> np.ndarray:
    """Exact float64 cost (G,) of cells given as (G,) parameter arrays; ``inf`` if any pair is invalid."""
    e = head_residuals_px(feet_px, heads_px, focal_px, pitch_rad, roll_rad, height_m, principal_point,
                          person_height_m)
    sq = e[..., 1] ** 2 if residual == "vertical" else np.sum(e**2, axis=-1)
    cost = np.sum(sq, axis=-1)
    return np.where(np.isfinite(cost), cost, np.inf)


# ---- fast kernel -----------------------------------------------------------------------------------
def _pair_terms(rel_feet_px: np.ndarray, focal_px: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per (focal, pair) terms d, g, M_u, M_v, each (F, B), for one up vector (3,)."""
    f = focal_px[:, None]
    u, v = rel_feet_px[None, :, 0], rel_feet_px[None, :, 1]
    d = -(up[0] * u + up[1] * v) / f - up[2]
    g = -up[2] * d
    return d, g, d * (f * up[0] - up[2] * u), d * (f * up[1] - up[2] * v)


def _blocks(n: int, cells_per_pair: int) -> list[slice]:
    """Pair blocks so that cells x pairs stays near the cache budget."""
    size = max(256, min(n, _BLOCK_ELEMS // max(1, cells_per_pair)))
    return [slice(i, min(n, i + size)) for i in range(0, n, size)]


def _paper_costs_one_pitch(rel_feet: np.ndarray, diff: np.ndarray, focal_px: np.ndarray, up: np.ndarray,
                           inv_k: np.ndarray, vertical: bool) -> np.ndarray:
    """Costs (F, C) for one up vector; ``inv_k = c / S`` (C,), diff = foot - head (N, 2)."""
    n_pairs, C = len(rel_feet), len(inv_k)
    costs = np.zeros((len(focal_px), C))
    g_max = np.full(len(focal_px), -np.inf)
    ray_ok = np.ones(len(focal_px), bool)
    inv_k32 = inv_k.astype(np.float32)[:, None]
    blocks = _blocks(n_pairs, max(C, len(focal_px)))  # (F, pairs) terms and (C, pairs) scratch both stay small
    work = np.empty((C, max((blk.stop - blk.start for blk in blocks), default=0)), np.float32)
    for blk in blocks:
        d, g, m_u, m_v = _pair_terms(rel_feet[blk], focal_px, up)
        ray_ok &= np.all(d > _RAY_EPS, axis=1)
        g_max = np.maximum(g_max, g.max(axis=1))
        du, dv = diff[blk, 0], diff[blk, 1]
        if vertical:
            base, dm, mm = float(dv @ dv), (dv * m_v).astype(np.float32), (m_v * m_v).astype(np.float32)
        else:
            base = float(du @ du + dv @ dv)
            dm = (du * m_u + dv * m_v).astype(np.float32)
            mm = (m_u * m_u + m_v * m_v).astype(np.float32)
        g32 = g.astype(np.float32)
        z = work[:, : blk.stop - blk.start]
        for i in range(len(focal_px)):
            np.subtract(inv_k32, g32[i], out=z)
            np.reciprocal(z, out=z)
            lin = _DOT(z, dm[i])
            np.multiply(z, z, out=z)
            costs[i] += base + 2.0 * lin.astype(np.float64) + _DOT(z, mm[i]).astype(np.float64)
    valid = ray_ok[:, None] & (inv_k[None, :] > g_max[:, None])
    return np.where(valid, costs, np.inf)


def _check_pairs(feet_px: np.ndarray, heads_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Float64 (N, 2) copies of the pixel arrays, or ValueError."""
    feet, heads = np.asarray(feet_px, np.float64), np.asarray(heads_px, np.float64)
    if feet.ndim != 2 or feet.shape[-1] != 2 or feet.shape != heads.shape:
        raise ValueError(f"feet_px and heads_px must both be (N, 2), got {feet.shape} and {heads.shape}")
    return feet, heads


def _workers(n_pitch: int, work: float, workers: int | None) -> int:
    """Threads to use: one for small problems, else up to the CPU count."""
    if workers is not None:
        return max(1, int(workers))
    return 1 if work < 5e6 else max(1, min(n_pitch, os.cpu_count() or 1, 8))


def grid_costs(feet_px: np.ndarray, heads_px: np.ndarray, principal_point, focal_values_px: np.ndarray,
               pitch_values_rad: np.ndarray, height_values_m: np.ndarray, person_height_m: float,
               residual: str = "full", roll_rad: float = 0.0, workers: int | None = None) -> np.ndarray:
    """Sum of squared head residuals (F, P, C) on the grid (float32 accuracy); ``inf`` = invalid cell.

    feet_px, heads_px: (N, 2) px; focal_values_px (F,), pitch_values_rad (P,), height_values_m (C,).
    """
    feet, heads = _check_pairs(feet_px, heads_px)
    pp = np.asarray(principal_point, np.float64)
    rel_feet, diff = feet - pp, feet - heads
    focal = np.asarray(focal_values_px, np.float64)
    pitches = np.asarray(pitch_values_rad, np.float64)
    inv_k = np.asarray(height_values_m, np.float64) / float(person_height_m)
    ups = up_vector_cam(pitches, roll_rad)
    vertical = residual == "vertical"

    def one(j: int) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # per thread
            return _paper_costs_one_pitch(rel_feet, diff, focal, ups[j], inv_k, vertical)

    n_threads = _workers(len(pitches), float(len(feet)) * len(focal) * len(pitches) * len(inv_k), workers)
    if n_threads == 1:
        per_pitch = [one(j) for j in range(len(pitches))]
    else:
        with ThreadPoolExecutor(n_threads) as pool:
            per_pitch = list(pool.map(one, range(len(pitches))))
    return np.stack(per_pitch, axis=1)


def paper_grid_search(feet_px: np.ndarray, heads_px: np.ndarray, principal_point, focal_values_px: np.ndarray,
                      pitch_values_rad: np.ndarray, height_values_m: np.ndarray, person_height_m: float,
                      residual: str = "full", roll_rad: float = 0.0, workers: int | None = None) -> GridFit | None:
    """Best cell of the grid (exact float64 cost, the float32 scan re-checked); None if no cell is valid."""
    focal = np.asarray(focal_values_px, np.float64)
    pitches = np.asarray(pitch_values_rad, np.float64)
    heights = np.asarray(height_values_m, np.float64)
    costs = grid_costs(feet_px, heads_px, principal_point, focal, pitches, heights, person_height_m, residual,
                       roll_rad, workers)
    finite = np.isfinite(costs)
    if not finite.any():
        return None
    best = float(costs[finite].min())
    diff = np.asarray(feet_px, np.float64) - np.asarray(heads_px, np.float64)
    scale = float(np.sum(diff[:, 1] ** 2 if residual == "vertical" else diff**2))  # size of the cancelling terms
    near = np.flatnonzero(costs.ravel() <= best * (1.0 + _RECHECK_REL) + _RECHECK_ABS * scale + 1e-9)
    near = near[np.argsort(costs.ravel()[near])][:_RECHECK_MAX]
    i, j, k = np.unravel_index(near, costs.shape)
    exact = np.concatenate([
        reference_cell_costs(feet_px, heads_px, focal[i[s]], pitches[j[s]], heights[k[s]], principal_point,
                             person_height_m, residual, roll_rad)
        for s in _chunks(len(near), max(1, 2_000_000 // max(1, len(feet_px))))])
    if not np.isfinite(exact).any():
        return None
    b = int(np.argmin(exact))
    index = (int(i[b]), int(j[b]), int(k[b]))
    return GridFit(float(focal[index[0]]), float(pitches[index[1]]), float(heights[index[2]]), float(exact[b]),
                   index, costs)


def _chunks(n: int, size: int) -> list[slice]:
    """Consecutive slices of at most ``size`` covering range(n)."""
    return [slice(i, min(n, i + size)) for i in range(0, n, size)]


# ---- robust variant (initialisation of the refinement) --------------------------------------------
def robust_grid_costs(feet_px: np.ndarray, heads_px: np.ndarray, principal_point, focal_values_px: np.ndarray,
                      pitch_values_rad: np.ndarray, height_values_m: np.ndarray, person_height_m: float,
                      residual: str = "full", truncate: float = 0.25) -> np.ndarray:
    """Truncated relative cost (F, P, C): sum over pairs of min((|e| / L)^2, truncate^2).

    ``L`` is the pair's observed foot-head pixel length; a pair whose foot ray misses the ground or
    whose head lands behind the camera counts as ``truncate^2`` (an outlier), so no cell is invalid.
    """
    feet, heads = _check_pairs(feet_px, heads_px)
    pp = np.asarray(principal_point, np.float64)
    rel_feet = feet - pp
    length = np.maximum(np.linalg.norm(feet - heads, axis=1), 1.0)
    diff = (feet - heads) / length[:, None]
    focal = np.asarray(focal_values_px, np.float64)
    inv_k = (np.asarray(height_values_m, np.float64) / float(person_height_m)).astype(np.float32)[None, :, None]
    t2 = np.float32(truncate**2)
    ups = up_vector_cam(np.asarray(pitch_values_rad, np.float64), 0.0)
    out = np.empty((len(focal), len(ups), inv_k.shape[1]))
    per_focal = max(1, _BLOCK_ELEMS // (inv_k.shape[1] * len(feet)))
    fs = _chunks(len(focal), per_focal)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for j, up in enumerate(ups):
            d, g, m_u, m_v = _pair_terms(rel_feet, focal, up)
            bad = d <= _RAY_EPS
            m_u, m_v = (m / length for m in (m_u, m_v))
            du = np.where(bad, 1e3, diff[:, 0]).astype(np.float32)[:, None, :]
            dv = np.where(bad, 1e3, diff[:, 1]).astype(np.float32)[:, None, :]
            m_u, m_v = (np.where(bad, 0.0, m).astype(np.float32)[:, None, :] for m in (m_u, m_v))
            g32 = g.astype(np.float32)[:, None, :]
            for fb in fs:
                z = inv_k - g32[fb]
                np.maximum(z, np.float32(1e-9), out=z)  # head behind the camera -> huge error
                np.reciprocal(z, out=z)
                ev = z * m_v[fb]
                ev += dv[fb]
                ev *= ev
                if residual != "vertical":
                    eu = z * m_u[fb]
                    eu += du[fb]
                    eu *= eu
                    ev += eu
                np.minimum(ev, t2, out=ev)
                out[fb, j] = ev.sum(axis=-1, dtype=np.float64)
    return out


def order_invariant_subset(feet: np.ndarray, heads: np.ndarray, m: int) -> np.ndarray:
    """Indices of at most ``m`` pairs, chosen from the sorted pairs (independent of their order)."""
    order = np.lexsort((heads[:, 1], heads[:, 0], feet[:, 1], feet[:, 0]))
    if len(order) <= m:
        return np.sort(order)
    return np.sort(order[np.linspace(0, len(order) - 1, m).round().astype(int)])


def seed_cells(costs: np.ndarray, focal: np.ndarray, max_seeds: int = 4) -> list[tuple[int, int, int]]:
    """Start cells (F, P, C indices) of a robust grid: the best, other minima along the valley, f x 0.5 and x 2.

    The profile runs over the focal axis, or over the pitch axis when the focal is fixed.
    """
    ax = 0 if costs.shape[0] > 1 else 1
    moved = np.moveaxis(costs, ax, 0)
    flat = moved.reshape(moved.shape[0], -1)
    prof, best_at = flat.min(axis=1), flat.argmin(axis=1)
    n = len(prof)
    i0 = int(np.argmin(prof))
    picks = [i0]
    local = sorted((i for i in range(n) if i != i0 and prof[i] <= prof[max(i - 1, 0)]
                    and prof[i] <= prof[min(i + 1, n - 1)] and prof[i] <= 1.5 * prof[i0]), key=lambda i: prof[i])
    picks += local[:2]
    if ax == 0:
        for factor in (0.5, 2.0):  # along the focal/pitch valley
            i = int(np.argmin(np.abs(focal - focal[i0] * factor)))
            if i not in picks:
                picks.append(i)
    cells = []
    for i in picks[:max_seeds]:
        rest = np.unravel_index(best_at[i], moved.shape[1:])
        cell = [int(v) for v in rest]
        cell.insert(ax, int(i))
        cells.append(tuple(cell))
    return cells
