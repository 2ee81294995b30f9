"""The covariance of a camera's parameters as camera.yaml holds it (``fit.covariance``): one format, written by
calibrate (:func:`rotavat_cli.calibration.footprint.report_covariance`) and read by measure
(:mod:`rotavat_cli.bodies.stature_error`).

``names`` are report names of camera parameters, each with its unit: :data:`COVARIANCE_UNITS`; ``matrix``
is their covariance in those units squared.

>>> block = CameraCovariance(("pitch_deg", "height_m"), np.array([[0.25, 0.01], [0.01, 0.04]])).to_dict()
>>> block
{'names': ['pitch_deg', 'height_m'], 'matrix': [[0.25, 0.01], [0.01, 0.04]]}
>>> CameraCovariance.from_fit({"covariance": block}).names
('pitch_deg', 'height_m')
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["COVARIANCE_UNITS", "CameraCovariance"]

# Every name a covariance may hold, and its unit: the estimated parameters, then what a fit assumes and the camera
# holds (the principal point's components, an unfitted lens).
COVARIANCE_UNITS = {"focal_px": "px", "pitch_deg": "deg", "roll_deg": "deg", "height_m": "m", "distortion": "1",
                    "cx_px": "px", "cy_px": "px"}


@dataclass(frozen=True)
class CameraCovariance:
    """Covariance of named camera parameters: ``names`` (k,) among :data:`COVARIANCE_UNITS`, ``matrix`` (k, k) in
    their units squared."""

    names: tuple[str, ...]
    matrix: np.ndarray

    def to_dict(self) -> dict:
        """camera.yaml's ``fit.covariance``: ``{names: [...], matrix: [[...]]}`` (NaN as None, inf kept)."""
        return {"names": list(self.names),
                "matrix": [[None if math.isnan(v) else float(v) for v in row] for row in self.matrix]}

    @classmethod
    def from_fit(cls, fit: Mapping | None) -> "CameraCovariance | None":
        """The ``fit.covariance`` block of a fit block, None when absent; ValueError naming the key when malformed.
        The shape is checked before any value is read: a small file of YAML aliases can stand for millions."""
        block = fit.get("covariance") if isinstance(fit, Mapping) else None
        if block is None:
            return None
        names = block.get("names") if isinstance(block, Mapping) else None
        if not isinstance(names, list) or any(n not in COVARIANCE_UNITS for n in names):
            raise ValueError(f"fit.covariance.names must list some of {', '.join(COVARIANCE_UNITS)}, got {names!r}")
        rows = block.get("matrix")
        k = len(names)
        matrix = None
        if isinstance(rows, list) and len(rows) == k and all(isinstance(r, list) and len(r) == k for r in rows):
            try:
                matrix = np.array([[math.nan if v is None else float(v) for v in r] for r in rows]).reshape(k, k)
            except (TypeError, ValueError):
                matrix = None
        if matrix is None:
            raise ValueError(f"fit.covariance.matrix must be {k}x{k} numbers (one row and column per name)")
        return cls(tuple(names), matrix)
