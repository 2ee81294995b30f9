"""The seed paper's calibration grid, its fast kernel, and the refinement's robust seeding grid.

The paper: focal, pitch and camera height on a grid (roll 0, principal point ``pp``, stature
``S``), the summed squared head error of the person model (:mod:`.model`) per cell, the best cell
wins. :func:`reference_cell_costs` scores cells with the model itself (:func:`.model.head_errors`);
:func:`grid_costs` is the fast form of the same model on every cell:

- with ``D = F - Hd`` (foot minus observed head) and ``d``, ``M`` of :func:`.model.foot_terms`
  (focal and pitch only, never the height ``c``), the model's ``k / z`` is ``w = 1 / (c/S - g)``
  with ``g = -n_z d``, so the head error is ``e = D + w M`` and a cell's cost is
  ``sum|D|^2 + 2 w.(D.M) + (w*w).|M|^2`` over the residual kind's pixel axes: one subtraction,
  one reciprocal and one square per cell and pair (float32, cache-sized blocks of pairs), and two
  matrix-vector products. The cells within the float32 error of the minimum are re-scored with
  the model in float64, so :func:`paper_grid_search` returns the grid's true best cell (a test
  checks it against a cell-by-cell brute force);
- a cell is invalid (cost ``inf``, skipped) when a foot ray misses the ground (``d <= 0``) or a
  head lands behind the camera (``c/S <= g``, the model's ``z <= 0``); both are per-(focal, pitch)
  maxima, no extra pass.

From 2,000 pairs :func:`paper_grid_search` first bounds every cell from below on every 8th pair and scores
in full only the cells that may still be the least (:func:`_cells_that_may_win`): the same best cell and cost.
Memory is bounded by the block size, whatever the number of pairs (a few MB per worker thread).
The refinement's seeds (:func:`seed_params`) come from a truncated, log-spaced variant of the same
kernel (:func:`robust_grid_costs`) on an order-independent subsample (:func:`order_invariant_subset`).
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..geometry.camera import up_vector_cam
from ..settings.limits import current as current_limits
from ..settings.option_rules import Rule, check_fields
from .model import RAY_EPS, foot_ray_d, foot_terms, head_errors
from .params import FOCAL, HEIGHT, N_PARAMS, PITCH, ROLL, param_vector
from .residuals import ResidualKind, residual_kind

__all__ = ["GridSpec", "GridFit", "SEED_STEPS", "reference_cell_costs", "grid_costs", "robust_grid_costs",
           "paper_grid_search", "order_invariant_subset", "seed_cells", "seed_params"]

_BLOCK_ELEMS = 200_000  # float32 cells x pairs per block: ~0.8 MB, stays in L2
_RECHECK_REL = 2e-3  # float32 costs are trusted to this relative error; closer cells are re-checked ...
_RECHECK_ABS = 1e-5  # ... plus this fraction of sum|foot - head|^2 (float32 cancellation; measured ~1e-7)
_RECHECK_MAX = 4096  # at most this many cells are re-evaluated in float64
_PRUNE_MIN_PAIRS = 2000  # from this many pairs the paper grid first bounds every cell on a share of them ...
_PRUNE_STRIDE = 8  # ... every 8th pair ...
_PRUNE_PROBES = 16  # ... and scores in full only the cells whose bound is below the exact cost of the 16 best there
# Row-wise dot product without BLAS gemv (OpenBLAS worker threads spin and starve the grid's threads).
_DOT = getattr(np, "vecdot", lambda a, b: np.einsum("ij,j->i", a, b))
SEED_STEPS = (40, 30)  # robust seeding grid: log-spaced focal and height values over the GridSpec ranges
_SEED_PAIRS = 600  # the seeding grid and the multi-start run on at most this many pairs
_SEED_TRUNCATE = 0.25  # seeding grid: head errors beyond 25% of the person's pixel length are outliers
_SEED_MAX_PITCH = np.deg2rad(89.0)  # seeds stay below straight down (the refinement's bound is 89.9 deg)


@dataclass(frozen=True)
class GridSpec:
    """The paper's search grid, inclusive and evenly spaced (defaults = the paper's = ``calibrate.grid``)."""

    focal_range_h: tuple[float, float] = (0.1, 6.0)  # times the image height H
    pitch_range_deg: tuple[float, float] = (-45.0, 90.0)
    height_range_m: tuple[float, float] = (0.5, 40.0)
    steps: tuple[int, int, int] = (50, 50, 50)  # focal, pitch, height

    RULES: ClassVar[dict[str, Rule]] = {  # the ``calibrate.grid`` keys' bounds (rotavat_cli/settings/option_rules.py)
        "focal_range_h": Rule(low=1e-3, high=1e3, ordered="<=", unit="H"),
        "pitch_range_deg": Rule(low=-90, high=90, ordered="<=", unit="deg"),
        "height_range_m": Rule(low=1e-2, high=1e5, ordered="<=", unit="m"),
        "steps": Rule(low=1, high=100_000),
    }

    def __post_init__(self) -> None:
        for name in ("focal_range_h", "pitch_range_deg", "height_range_m"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        if len(self.steps) != 3:
            raise ValueError(f"grid steps must be three positive integers, got {self.steps}")
        check_fields(self, self.RULES, prefix="grid ")
        object.__setattr__(self, "steps", tuple(int(s) for s in self.steps))
        self._check_size()

    def _check_size(self) -> None:
        """ValueError naming ``calibrate.grid.steps`` when a search over this grid would be larger than
        ``limits.max_grid_cells``: the paper's grid (steps[0] x steps[1] x steps[2] cells, float64 costs),
        or the refine method's seeding grid (its own focal and height counts x steps[1] pitches)."""
        limit = current_limits().max_grid_cells
        cells = math.prod(self.steps)
        seeding = SEED_STEPS[0] * self.steps[1] * SEED_STEPS[1]
        if cells > limit:
            raise ValueError(f"calibrate.grid.steps {list(self.steps)} make {cells:,} grid cells "
                             f"(limit {limit:,}: limits.max_grid_cells)")
        if seeding > limit:
            raise ValueError(f"calibrate.grid.steps {list(self.steps)}: {self.steps[1]:,} pitch steps make the refine "
                             f"method's seeding grid {seeding:,} cells ({SEED_STEPS[0]} x {self.steps[1]} x "
                             f"{SEED_STEPS[1]}; limit {limit:,}: limits.max_grid_cells)")

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
    costs: np.ndarray  # (F, P, C) float64 costs (float32 accuracy away from the minimum); inf: invalid, or pruned
    # (from 2,000 pairs, cells that cannot be the least are not scored: _cells_that_may_win)


# ---- the model, cell by cell (reference for the fast kernel) ----------------------------------------
def reference_cell_costs(feet_px: np.ndarray, heads_px: np.ndarray, focal_px: np.ndarray, pitch_rad: np.ndarray,
                         height_m: np.ndarray, principal_point, person_height_m: float, residual: str = "full",
                         roll_rad: float = 0.0) -> np.ndarray:
    """Exact float64 cost (G,) of cells given as (G,) parameter arrays; ``inf`` if any pair is invalid."""
    kind = residual_kind(residual)
    feet, heads = _check_pairs(feet_px, heads_px)
    focal, pitch, roll, height = np.broadcast_arrays(*(np.asarray(v, np.float64).ravel()
                                                       for v in (focal_px, pitch_rad, roll_rad, height_m)))
    params = np.zeros((len(focal), N_PARAMS))
    params[:, FOCAL], params[:, PITCH], params[:, ROLL], params[:, HEIGHT] = focal, pitch, roll, height
    e, _, valid = head_errors(feet - np.asarray(principal_point, np.float64), feet - heads, params,
                              float(person_height_m), z_min=0.0)
    cost = np.sum(kind.squared_px(e), axis=-1)
    return np.where(np.all(valid, axis=-1) & np.isfinite(cost), cost, np.inf)


# ---- fast kernel -----------------------------------------------------------------------------------
def _pair_terms(rel_feet_px: np.ndarray, focal_px: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per (focal, pair) terms d, g, M_u, M_v, each (F, B), for one up vector (3,) (:func:`.model.foot_terms`)."""
    d, m_u, m_v = foot_terms(rel_feet_px[None, :, 0], rel_feet_px[None, :, 1], focal_px[:, None], *up)
    return d, -up[2] * d, m_u, m_v


def _blocks(n: int, cells_per_pair: int) -> list[slice]:
    """Pair blocks so that cells x pairs stays near the cache budget."""
    size = max(256, min(n, _BLOCK_ELEMS // max(1, cells_per_pair)))
    return [slice(i, min(n, i + size)) for i in range(0, n, size)]


def _paper_costs_one_pitch(rel_feet: np.ndarray, diff: np.ndarray, focal_px: np.ndarray, up: np.ndarray,
                           inv_k: np.ndarray, kind: ResidualKind, wanted: np.ndarray | None = None) -> np.ndarray:
    """Costs (F, C) for one up vector; ``inv_k = c / S`` (C,), diff = foot - head (N, 2); ``wanted`` (F, C) bool:
    the cells to score (None: all), the others ``inf``.

    A first pass finds the invalid cells (:func:`_valid_cells`); only the valid ones are scored (on a
    typical scene about 40% of the paper grid's cells are invalid: cameras looking up at feet above
    their horizon, or below the people's heads)."""
    n_pairs, C = len(rel_feet), len(inv_k)
    costs = np.full((len(focal_px), C), np.inf)
    blocks = _blocks(n_pairs, max(C, len(focal_px)))  # (F, pairs) terms and (C, pairs) scratch both stay small
    valid = _valid_cells(rel_feet, focal_px, up, inv_k, blocks)
    if wanted is not None:
        valid &= wanted
    rows = np.flatnonzero(valid.any(axis=1))
    if not len(rows):
        return costs
    focal, valid = focal_px[rows], valid[rows]
    heights = [np.flatnonzero(ok) for ok in valid]
    sums = np.zeros((len(rows), C))
    inv_k32 = inv_k.astype(np.float32)[:, None]
    work = np.empty((C, max((blk.stop - blk.start for blk in blocks), default=0)), np.float32)
    for blk in blocks:
        d, g, m_u, m_v = _pair_terms(rel_feet[blk], focal, up)
        big_d, m = (diff[blk, 0], diff[blk, 1]), (m_u, m_v)
        base = float(sum(big_d[a] @ big_d[a] for a in kind.pixel_axes))
        dm = _axes_sum(big_d[a] * m[a] for a in kind.pixel_axes).astype(np.float32)
        mm = _axes_sum(m[a] * m[a] for a in kind.pixel_axes).astype(np.float32)
        g32 = g.astype(np.float32)
        for i, cells in enumerate(heights):
            z = work[: len(cells), : blk.stop - blk.start]
            np.subtract(inv_k32[cells], g32[i], out=z)
            np.reciprocal(z, out=z)
            lin = _DOT(z, dm[i])
            np.multiply(z, z, out=z)
            sums[i, cells] += base + 2.0 * lin.astype(np.float64) + _DOT(z, mm[i]).astype(np.float64)
    costs[rows] = np.where(valid, sums, np.inf)
    return costs


def _valid_cells(rel_feet: np.ndarray, focal_px: np.ndarray, up: np.ndarray, inv_k: np.ndarray,
                 blocks: list[slice]) -> np.ndarray:
    """(F, C) bool: the cells of one up vector (3,) where every foot ray meets the ground (``d > 0``) and every
    head is in front of the camera (``c/S > g``), from the model's ``d`` alone (:func:`.model.foot_ray_d`)."""
    g_max = np.full(len(focal_px), -np.inf)
    ray_ok = np.ones(len(focal_px), bool)
    for blk in blocks:
        d = foot_ray_d(rel_feet[None, blk, 0], rel_feet[None, blk, 1], focal_px[:, None], *up)
        ray_ok &= np.all(d > RAY_EPS, axis=1)
        g_max = np.maximum(g_max, (-up[2] * d).max(axis=1))
    return ray_ok[:, None] & (inv_k[None, :] > g_max[:, None])


def _axes_sum(terms) -> np.ndarray:
    """Sum of per-axis arrays, in axis order."""
    terms = iter(terms)
    total = next(terms)
    for term in terms:
        total = total + term
    return total


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
               residual: str = "full", roll_rad: float = 0.0, workers: int | None = None,
               wanted: np.ndarray | None = None) -> np.ndarray:
    """Sum of squared head residuals (F, P, C) on the grid (float32 accuracy); ``inf`` = invalid cell.

    feet_px, heads_px: (N, 2) px; focal_values_px (F,), pitch_values_rad (P,), height_values_m (C,); wanted:
    (F, P, C) bool, the cells to score (the others ``inf``; a scored cell's cost does not depend on the others).
    """
    kind = residual_kind(residual)
    feet, heads = _check_pairs(feet_px, heads_px)
    pp = np.asarray(principal_point, np.float64)
    rel_feet, diff = feet - pp, feet - heads
    focal = np.asarray(focal_values_px, np.float64)
    pitches = np.asarray(pitch_values_rad, np.float64)
    inv_k = np.asarray(height_values_m, np.float64) / float(person_height_m)
    ups = up_vector_cam(pitches, roll_rad)

    def one(j: int) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # per thread
            return _paper_costs_one_pitch(rel_feet, diff, focal, ups[j], inv_k, kind,
                                          None if wanted is None else wanted[:, j])

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
    grid = (principal_point, focal, pitches, heights, person_height_m, residual, roll_rad)
    wanted = _cells_that_may_win(feet_px, heads_px, grid, workers)
    costs = grid_costs(feet_px, heads_px, *grid, workers, wanted)
    finite = np.isfinite(costs)
    if not finite.any():
        return None
    best = float(costs[finite].min())
    diff = np.asarray(feet_px, np.float64) - np.asarray(heads_px, np.float64)
    scale = float(np.sum(residual_kind(residual).squared_px((diff[:, 0], diff[:, 1]))))  # the cancelling terms' size
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


def _cells_that_may_win(feet_px: np.ndarray, heads_px: np.ndarray, grid: tuple, workers: int | None
                        ) -> np.ndarray | None:
    """(F, P, C) bool: the cells whose cost may still be the grid's least, or None (all) for fewer than
    ``_PRUNE_MIN_PAIRS`` pairs. ``grid``: :func:`grid_costs`'s arguments after the pairs, up to ``roll_rad``.

    A cell's cost is a sum of squares over the pairs, so its sum over every ``_PRUNE_STRIDE``-th pair is a lower
    bound of it; the exact cost of the ``_PRUNE_PROBES`` cells best on that share is an upper bound of the least.
    A cell whose lower bound (less the float32 scan's error, as the re-check allows for it) exceeds that upper
    bound cannot be the best: it is not scored. The best cell and its cost are the unpruned search's; the
    other cells' costs are ``inf`` (20,000 walkers' pairs: 4% of the valid cells scored, with 10% outliers;
    0.003% without).
    """
    feet, heads = _check_pairs(feet_px, heads_px)
    if len(feet) < _PRUNE_MIN_PAIRS:
        return None
    share_feet, share_heads = feet[::_PRUNE_STRIDE], heads[::_PRUNE_STRIDE]
    lower = grid_costs(share_feet, share_heads, *grid, workers)
    finite = np.flatnonzero(np.isfinite(lower.ravel()))
    probes = finite[np.argsort(lower.ravel()[finite])][:_PRUNE_PROBES]
    principal_point, focal, pitches, heights, person_height_m, residual, roll_rad = grid
    i, j, k = np.unravel_index(probes, lower.shape)
    exact = reference_cell_costs(feet, heads, focal[i], pitches[j], heights[k], principal_point, person_height_m,
                                 residual, roll_rad)
    if not np.isfinite(exact).any():
        return None
    diff = share_feet - share_heads
    scale = float(np.sum(residual_kind(residual).squared_px((diff[:, 0], diff[:, 1]))))
    with np.errstate(invalid="ignore"):
        return lower * (1.0 - _RECHECK_REL) - _RECHECK_ABS * scale <= float(np.min(exact[np.isfinite(exact)]))


def _chunks(n: int, size: int) -> list[slice]:
    """Consecutive slices of at most ``size`` covering range(n)."""
    return [slice(i, min(n, i + size)) for i in range(0, n, size)]


# ---- robust variant (seeds of the refinement) -----------------------------------------------------
def robust_grid_costs(feet_px: np.ndarray, heads_px: np.ndarray, principal_point, focal_values_px: np.ndarray,
                      pitch_values_rad: np.ndarray, height_values_m: np.ndarray, person_height_m: float,
                      residual: str = "full", truncate: float = 0.25) -> np.ndarray:
    """Truncated relative cost (F, P, C): sum over pairs of min((|e| / L)^2, truncate^2).

    ``L`` is the pair's observed foot-head pixel length; a pair whose foot ray misses the ground or
    whose head lands behind the camera counts as ``truncate^2`` (an outlier), so no cell is invalid.
    """
    kind = residual_kind(residual)
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

    def one(j: int) -> None:  # out[:, j]: one pitch
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # per thread
            d, g, m_u, m_v = _pair_terms(rel_feet, focal, ups[j])
            bad = d <= RAY_EPS
            m_u, m_v = (m / length for m in (m_u, m_v))
            big_d = {a: np.where(bad, 1e3, diff[:, a]).astype(np.float32)[:, None, :] for a in kind.pixel_axes}
            m = {a: np.where(bad, 0.0, (m_u, m_v)[a]).astype(np.float32)[:, None, :] for a in kind.pixel_axes}
            g32 = g.astype(np.float32)[:, None, :]
            for fb in fs:
                z = inv_k - g32[fb]
                np.maximum(z, np.float32(1e-9), out=z)  # head behind the camera -> huge error
                np.reciprocal(z, out=z)
                sq = None
                for a in kind.pixel_axes:
                    e = z * m[a][fb]
                    e += big_d[a][fb]
                    e *= e
                    sq = e if sq is None else np.add(sq, e, out=sq)
                np.minimum(sq, t2, out=sq)
                out[fb, j] = sq.sum(axis=-1, dtype=np.float64)

    n_threads = _workers(len(ups), float(len(feet)) * len(focal) * len(ups) * inv_k.shape[1], None)
    if n_threads == 1:
        for j in range(len(ups)):
            one(j)
    else:  # the pitches on threads (numpy releases the GIL in its loops): each writes its own out[:, j]
        with ThreadPoolExecutor(n_threads) as pool:
            list(pool.map(one, range(len(ups))))
    return out


def order_invariant_subset(feet: np.ndarray, heads: np.ndarray, m: int) -> np.ndarray:
    """Indices of at most ``m`` pairs, chosen from the sorted pairs (independent of their order)."""
    order = np.lexsort((heads[:, 1], heads[:, 0], feet[:, 1], feet[:, 0]))
    if len(order) <= m:
        return np.sort(order)
    return np.sort(order[np.linspace(0, len(order) - 1, m).round().astype(int)])


def seed_cells(costs: np.ndarray, focal: np.ndarray, max_seeds: int = 4,
               extra_focals: tuple[float, ...] = ()) -> list[tuple[int, int, int]]:
    """Start cells (F, P, C indices) of a robust grid: the best, other minima along the valley, f x 0.5 and x 2,
    then the best cell at each of ``extra_focals`` (px; e.g. the lens prior's median).

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
    picks = picks[:max_seeds]
    if ax == 0:
        for value in extra_focals:
            i = int(np.argmin(np.abs(np.log(focal / value))))
            if i not in picks:
                picks.append(i)
    cells = []
    for i in picks:
        rest = np.unravel_index(best_at[i], moved.shape[1:])
        cell = [int(v) for v in rest]
        cell.insert(ax, int(i))
        cells.append(tuple(cell))
    return cells


def seed_params(feet: np.ndarray, heads: np.ndarray, pp: np.ndarray, image_height_px: float, focal_px: float | None,
                grid: GridSpec, person_height_m: float, residual: str, box_depth_m: float,
                extra_focals: tuple[float, ...] = ()) -> tuple[np.ndarray, list[np.ndarray]]:
    """The refinement's starts: (indices of the subsample they were found on, (6,) params per seed).

    A robust grid (log-spaced focal and height values over ``grid``'s ranges, roll 0, the given
    focal when fixed) on at most 600 pairs chosen independently of their order; the seeds are its
    best cells along the focal/pitch valley (:func:`seed_cells`, with the best cell at each of
    ``extra_focals`` px), pitch kept below 89 deg.
    """
    sub_idx = order_invariant_subset(feet, heads, _SEED_PAIRS)
    lo, hi = (v * image_height_px for v in grid.focal_range_h)
    focal = np.geomspace(lo, hi, SEED_STEPS[0]) if focal_px is None else np.array([float(focal_px)])
    pitch, height = grid.pitch_values_rad(), np.geomspace(*grid.height_range_m, SEED_STEPS[1])
    costs = robust_grid_costs(feet[sub_idx], heads[sub_idx], pp, focal, pitch, height, person_height_m, residual,
                              _SEED_TRUNCATE)
    seeds = [param_vector(focal=focal[i], pitch=min(pitch[j], _SEED_MAX_PITCH), roll=0.0, height=height[c],
                          box_depth=box_depth_m) for i, j, c in seed_cells(costs, focal, extra_focals=extra_focals)]
    return sub_idx, seeds
