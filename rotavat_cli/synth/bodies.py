"""The packaged library of synthetic body meshes (``data/bodies.npz``; source in data/README.md).

Canonical body frame of the stored arrays: metres, +Y up, the person faces +Z, +X is the
person's left; the ground is ``y = 0`` and the mid-sole point sits at ``x = z = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..bodies.landmarks import PACKAGED_BODIES, Topology, topology_from_npz

__all__ = ["BodyLibrary", "load_bodies", "BODIES_PATH"]

BODIES_PATH = PACKAGED_BODIES


@dataclass(frozen=True)
class BodyLibrary:
    """B bodies of one topology in the canonical body frame."""

    vertices: np.ndarray  # (B, V, 3) float64
    faces: np.ndarray  # (F, 3) int64
    joints: np.ndarray  # (B, 24, 3) float64, SMPL order
    stature_m: np.ndarray  # (B,)
    topology: Topology

    def __len__(self) -> int:
        return int(self.vertices.shape[0])


@lru_cache(maxsize=1)
def load_bodies(path: str | None = None) -> BodyLibrary:
    """Load the body library (the packaged one by default; its topology is built into landmarks)."""
    with np.load(Path(path) if path else BODIES_PATH, allow_pickle=False) as npz:
        return BodyLibrary(npz["vertices"].astype(np.float64), npz["faces"].astype(np.int64),
                           npz["joints"].astype(np.float64), npz["stature_m"].astype(np.float64),
                           topology_from_npz(npz, "rotavat-synth"))
