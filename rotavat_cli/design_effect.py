"""How much correlated consecutive measurements are worth: the design effect of a track's residuals.

A walker seen in 300 frames whose errors drift slowly is worth far fewer than 300 independent people.
The calibration weights its pairs by it (:func:`rotavat_cli.calibration.objective.design_effect`) and a
measured stature's std divides by it (:func:`rotavat_cli.bodies.stature_error.stature_design_effect`):
one rule, here.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_RHO", "MAX_LAG", "autocorrelation_time"]

MIN_RHO = 0.05  # autocorrelations below this end the sum (they are noise)
MAX_LAG = 200  # lags summed at most


def autocorrelation_time(residuals: np.ndarray, track: np.ndarray, max_lag: int = MAX_LAG) -> float:
    """The integrated autocorrelation time ``1 + 2 sum_k rho_k`` (>= 1) of residuals along their tracks.

    residuals: (N,) or (N, d), ordered by track then time (components pooled); track: (N,) int, the same
    order. ``rho_k`` pools the products of residuals ``k`` apart within a track over every track; the sum
    stops at the first ``rho_k`` below :data:`MIN_RHO` or at ``max_lag``; the result is at most the mean
    track length. 1 for fewer than 3 residuals or all zero.

    >>> track = np.zeros(40, int)
    >>> autocorrelation_time((-1.0) ** np.arange(40), track)   # no memory from one to the next
    1.0
    >>> round(autocorrelation_time(np.repeat([-1.0, 1.0], 20), track), 1)   # off one way, then the other
    15.1
    """
    r = np.asarray(residuals, dtype=np.float64)
    r = r.reshape(len(r), -1)
    track = np.asarray(track)
    denom = float(np.sum(r * r))
    if denom <= 0.0 or len(r) < 3:
        return 1.0
    _, lengths = np.unique(track, return_counts=True)
    tau = 1.0
    for k in range(1, min(max_lag, int(lengths.max()))):
        same = track[k:] == track[:-k]
        if not same.any():
            break
        rho = float(np.sum(r[k:][same] * r[:-k][same])) / denom * len(r) / same.sum()
        if rho < MIN_RHO:
            break
        tau += 2.0 * rho
    return float(min(max(tau, 1.0), float(np.mean(lengths))))
