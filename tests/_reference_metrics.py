"""Textbook per-person reference implementations, shared by tests and benchmarks as the baseline."""

from __future__ import annotations

import numpy as np


def reference_pa_errors_mm(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-person textbook Umeyama (SPIN's compute_similarity_transform), (N, 3) -> (N,)."""
    x = pred.T - pred.mean(axis=0)[:, None]
    y = gt.T - gt.mean(axis=0)[:, None]
    u, s, vt = np.linalg.svd(x @ y.T)
    z = np.eye(3)
    z[-1, -1] = np.sign(np.linalg.det(u @ vt))
    rot = vt.T @ z @ u.T
    scale = np.trace(rot @ x @ y.T) / np.sum(x**2)
    aligned = scale * rot @ x + gt.mean(axis=0)[:, None]
    return np.linalg.norm(aligned.T - gt, axis=1) * 1000.0
