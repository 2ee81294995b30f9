"""Foot point (mid-sole) and head point (crown) of each person's mesh, in the mesh's frame.

The contract (docs/conventions.md, "People") defines the **foot point** as the
midpoint of the two feet's sole points and the **head point** as the top of the head. Meshes are
in the OpenCV camera frame (x right, y down, z forward, metres); so are the results.

Two modes, chosen per call by the vertex count ``V``:

- **Known topology** (SMPL 6890, SMPL-X 10475, rotavat's packaged synthetic bodies, or
  anything added with :func:`register_topology`): sole point of a foot = mean of that foot's sole vertices;
  mid-sole = midpoint of the two sole points; crown = the crown vertex. Pure fancy indexing.
- **Any other mesh: geometry.** The body axis is the principal axis of the vertices (largest
  variance; for a standing person that is head-feet), turned to point along ``up_hint_cam``.
  When the two largest variances are close (e.g. a T-pose, arm span ~ stature) the one of the two
  axes closer to the hint is taken instead. The mesh is cut in two halves through its centroid
  along the second principal axis (left/right when standing, front/back leg in a long stride);
  each half's lowest part is one foot. A foot's sole point is the centre of the extent of that
  half's vertices lying within ``_SOLE_BAND`` of the half's lowest vertex, at the lowest height
  (the middle of the footprint); the crown is the same thing at the top end (``_CROWN_BAND``). Limitations:
  the principal axes count vertices, not area, so a mesh whose horizontal spread clearly
  dominates (arms spread far wider than the stature, or very densely meshed outstretched arms)
  gets a horizontal "body axis"; a hand raised above the head becomes the "crown"; a sitting or
  lying person has no meaningful axis; the result is only as upright as the mesh.

Degenerate people never raise: a person with any non-finite vertex, with all vertices identical
(or, in geometry mode, collinear), or with no vertices, gets a NaN row in both outputs.

Examples
--------
>>> feet_cam, heads_cam = foot_head_points(np.zeros((0, 6890, 3)))
>>> feet_cam.shape, heads_cam.shape
((0, 3), (0, 3))
>>> topology_for(10475).name
'smplx'
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

__all__ = [
    "SMPL_JOINT_NAMES",
    "Topology",
    "SMPL",
    "SMPLX",
    "register_topology",
    "topology_for",
    "topology_from_npz",
    "foot_head_points",
    "DEFAULT_UP_HINT_CAM",
]

# SMPL's 24 joints in order (joint 0, the pelvis, is the root of every metric; docs/conventions.md).
SMPL_JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
)

# "Up in the image" in the OpenCV camera frame: people in surveillance views stand roughly upright.
DEFAULT_UP_HINT_CAM = np.array([0.0, -1.0, 0.0])

# Geometry-mode tolerances, as fractions of the body's extent along its axis (~1.7 m):
_SOLE_BAND = 0.02  # 3.4 cm: the flat underside of a shoe/foot, not the ankle (~7 cm up)
_CROWN_BAND = 0.01  # 1.7 cm: a cap ~6 cm across on a 11 cm head, centred on the top
_AMBIGUOUS_AXIS_RATIO = 0.8  # 2nd/1st variance above this: choose between them by the up hint
_REL_EPS = 1e-9  # a variance below this fraction of the largest one counts as zero (flat mesh)


@dataclass(frozen=True, eq=False)
class Topology:
    """Vertex indices of a body mesh's crown and soles; index arrays are stored read-only int64."""

    name: str
    n_verts: int
    crown_index: int  # one vertex at the top of the head
    left_sole_indices: np.ndarray  # (n,) vertex indices on the left sole (repeats = weights)
    right_sole_indices: np.ndarray  # (m,) vertex indices on the right sole

    def __post_init__(self) -> None:
        """Validate the indices against ``n_verts`` and freeze them as int64 arrays."""
        if int(self.n_verts) <= 0:
            raise ValueError(f"topology {self.name!r}: n_verts must be positive, got {self.n_verts}")
        object.__setattr__(self, "n_verts", int(self.n_verts))
        object.__setattr__(self, "crown_index", int(self.crown_index))
        for field_name in ("left_sole_indices", "right_sole_indices"):
            idx = np.array(getattr(self, field_name), dtype=np.int64).reshape(-1)
            if idx.size == 0:
                raise ValueError(f"topology {self.name!r}: {field_name} is empty")
            idx.setflags(write=False)
            object.__setattr__(self, field_name, idx)
        all_idx = np.concatenate([[self.crown_index], self.left_sole_indices, self.right_sole_indices])
        if all_idx.min() < 0 or all_idx.max() >= self.n_verts:
            raise ValueError(
                f"topology {self.name!r}: vertex indices must lie in [0, {self.n_verts}), "
                f"got range [{all_idx.min()}, {all_idx.max()}]"
            )


# SMPL (6890 vertices; SMPL-H shares the topology).
# Sole of each foot = {big toe, small toe, heel, heel underside}, so the sole point sits mid-foot
# (half heel, half toes), on the underside, not at the ankle joint.
# - big toe / small toe / heel (OpenPose foot keypoints): 'LBigToe': 3216, 'LSmallToe': 3226,
#   'LHeel': 3387, 'RBigToe': 6617, 'RSmallToe': 6624, 'RHeel': 6787
#   -- vchoutas/smplx, smplx/vertex_ids.py, vertex_ids['smplh'].
# - heel underside used for stature: "LEFT_HEEL": 3458, "RIGHT_HEEL": 6858
#   -- DavidBoja/SMPL-Anthropometry, landmark_definitions.py, SMPL_LANDMARK_INDICES.
_SMPL_LEFT_SOLE = (3216, 3226, 3387, 3458)
_SMPL_RIGHT_SOLE = (6617, 6624, 6787, 6858)
# Crown: "HEAD_TOP": 412 -- DavidBoja/SMPL-Anthropometry, landmark_definitions.py; its
# measurement_definitions.py measures "height" from HEAD_TOP to HEELS, i.e. our crown-to-sole.
# 411 is another common head-top choice (e.g. the head vertex of Xinyu-Yi/TransPose,
# preprocess.py, vi_mask = [1961, 5424, 1176, 4662, 411, 3021]); not cross-checked on the mesh.
_SMPL_CROWN = 412

# SMPL-X (10475 vertices), same recipe.
# - 'LBigToe': 5770, 'LSmallToe': 5780, 'LHeel': 8846, 'RBigToe': 8463, 'RSmallToe': 8474,
#   'RHeel': 8635 -- vchoutas/smplx, smplx/vertex_ids.py, vertex_ids['smplx'].
# - "LEFT_HEEL": 8847, "RIGHT_HEEL": 8635 -- DavidBoja/SMPL-Anthropometry,
#   landmark_definitions.py, SMPLX_LANDMARK_INDICES. The right one coincides with smplx's 'RHeel',
#   so 8635 is listed twice to keep both feet weighted alike (half heel, half toes).
_SMPLX_LEFT_SOLE = (5770, 5780, 8846, 8847)
_SMPLX_RIGHT_SOLE = (8463, 8474, 8635, 8635)
# Crown: "HEAD_TOP": 8976 -- DavidBoja/SMPL-Anthropometry, landmark_definitions.py (its SMPL-X
# "height" is HEAD_TOP to HEELS too, measurement_definitions.py).
_SMPLX_CROWN = 8976

SMPL = Topology("smpl", 6890, _SMPL_CROWN, np.array(_SMPL_LEFT_SOLE), np.array(_SMPL_RIGHT_SOLE))
SMPLX = Topology("smplx", 10475, _SMPLX_CROWN, np.array(_SMPLX_LEFT_SOLE), np.array(_SMPLX_RIGHT_SOLE))

_TOPOLOGIES: dict[int, Topology] = {SMPL.n_verts: SMPL, SMPLX.n_verts: SMPLX}

# rotavat's own synthetic bodies (``rotavat synth``; data/bodies.npz) carry their sole and crown
# indices in the package data. They are a built-in topology like SMPL's, read on first use, so
# every process finds the same points whether or not it has synthesised anything.
PACKAGED_BODIES = Path(__file__).resolve().parent / "data" / "bodies.npz"


def topology_from_npz(npz: Mapping[str, np.ndarray], name: str) -> Topology:
    """Topology from arrays ``vertices`` (B, V, 3), ``crown_index``, ``left/right_sole_indices``."""
    return Topology(name, int(npz["vertices"].shape[1]), int(npz["crown_index"]),
                    np.asarray(npz["left_sole_indices"]), np.asarray(npz["right_sole_indices"]))


@lru_cache(maxsize=1)
def _packaged_topologies() -> dict[int, Topology]:
    """The packaged synthetic bodies' topology by vertex count (empty if the data file is absent)."""
    if not PACKAGED_BODIES.exists():
        return {}
    with np.load(PACKAGED_BODIES, allow_pickle=False) as npz:
        topology = topology_from_npz(npz, "rotavat-synth")
    return {topology.n_verts: topology}


def register_topology(topology: Topology) -> None:
    """Make ``topology`` the one used for meshes with ``topology.n_verts`` vertices (replaces any)."""
    if not isinstance(topology, Topology):
        raise TypeError(f"expected a Topology, got {type(topology).__name__}")
    _TOPOLOGIES[topology.n_verts] = topology


def topology_for(n_verts: int) -> Topology | None:
    """The topology with ``n_verts`` vertices (registered, else built-in), or None (geometry mode)."""
    n_verts = int(n_verts)
    return _TOPOLOGIES.get(n_verts) or _packaged_topologies().get(n_verts)


def foot_head_points(
    verts_cam: np.ndarray, up_hint_cam: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(P, V, 3) meshes -> feet_cam (P, 3) mid-soles, heads_cam (P, 3) crowns; float64, NaN if degenerate.

    verts_cam: (P, V, 3) float, camera frame, metres; P may be 0.
    up_hint_cam: (3,) or (P, 3), roughly "up" for the people (any norm); only its sign along the
        body axis matters. Default ``(0, -1, 0)``, up in the image. Unused for known topologies.
    """
    verts = np.asarray(verts_cam)
    if verts.dtype.kind != "f":
        verts = verts.astype(np.float64)
    if verts.ndim != 3 or verts.shape[-1] != 3:
        raise ValueError(f"verts_cam must have shape (P, V, 3), got {verts.shape}")
    n_people, n_verts = verts.shape[:2]
    if n_people == 0 or n_verts == 0:
        nan_rows = np.full((n_people, 3), np.nan)
        return nan_rows, nan_rows.copy()
    topology = topology_for(n_verts)
    if topology is not None:
        feet_cam, heads_cam = _points_by_topology(verts, topology)
        # all vertices identical <=> a collapsed mesh: its crown coincides with its mid-sole
        valid = np.isfinite(verts).all(axis=(1, 2)) & np.any(feet_cam != heads_cam, axis=1)
    else:
        verts = verts.astype(np.float64, copy=False)
        valid = _valid_people(verts)
        hint_cam = _up_hint(up_hint_cam, n_people)
        safe_verts = np.where(valid[:, None, None], verts, 0.0)  # keeps NaN out of eigh
        feet_cam, heads_cam, ok = _points_by_geometry(safe_verts, hint_cam)
        valid &= ok
    feet_cam[~valid] = np.nan
    heads_cam[~valid] = np.nan
    return feet_cam, heads_cam


def _valid_people(verts: np.ndarray) -> np.ndarray:
    """(P, V, 3) -> (P,) bool: every vertex finite and not all vertices the same point."""
    finite = np.isfinite(verts).all(axis=(1, 2))
    varied = (verts != verts[:, :1]).any(axis=(1, 2))  # one pass; cheaper than a peak-to-peak
    return finite & varied


def _points_by_topology(verts: np.ndarray, topology: Topology) -> tuple[np.ndarray, np.ndarray]:
    """(P, V, 3) -> feet (P, 3) = midpoint of the two sole means, heads (P, 3) = crown vertex."""
    left_sole = verts[:, topology.left_sole_indices].astype(np.float64).mean(axis=1)
    right_sole = verts[:, topology.right_sole_indices].astype(np.float64).mean(axis=1)
    return 0.5 * (left_sole + right_sole), verts[:, topology.crown_index].astype(np.float64)


def _up_hint(up_hint_cam: np.ndarray | None, n_people: int) -> np.ndarray:
    """Hint (3,) / (P, 3) / None -> (P, 3) float64; raises ValueError if not finite and non-zero."""
    hint = DEFAULT_UP_HINT_CAM if up_hint_cam is None else np.asarray(up_hint_cam, dtype=np.float64)
    if hint.shape not in ((3,), (n_people, 3)):
        raise ValueError(f"up_hint_cam must have shape (3,) or ({n_people}, 3), got {hint.shape}")
    if not np.isfinite(hint).all() or (np.linalg.norm(hint, axis=-1) == 0.0).any():
        raise ValueError("up_hint_cam must be finite and non-zero")
    return np.broadcast_to(hint, (n_people, 3))


def _body_axes(centered: np.ndarray, hint_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centred (P, V, 3), hint (P, 3) -> up (P, 3) unit, lateral (P, 3) unit, ok (P,) bool."""
    cov = np.einsum("pvi,pvj->pij", centered, centered) / centered.shape[1]
    evals, evecs = np.linalg.eigh(cov)  # ascending; eigenvectors in columns
    first, second = evecs[:, :, 2], evecs[:, :, 1]
    ambiguous = evals[:, 1] > _AMBIGUOUS_AXIS_RATIO * evals[:, 2]
    align_first = np.abs(np.einsum("pi,pi->p", first, hint_cam))
    align_second = np.abs(np.einsum("pi,pi->p", second, hint_cam))
    swap = (ambiguous & (align_second > align_first))[:, None]
    up = np.where(swap, second, first)
    lateral = np.where(swap, first, second)
    up = up * np.where(np.einsum("pi,pi->p", up, hint_cam) < 0.0, -1.0, 1.0)[:, None]
    ok = (evals[:, 2] > 0.0) & (evals[:, 1] > _REL_EPS * evals[:, 2])
    return up, lateral, ok


def _lowest_patch_point(centered: np.ndarray, axis: np.ndarray, lateral: np.ndarray, side: np.ndarray, band: np.ndarray) -> np.ndarray:
    """Lowest patch along ``axis`` of each person's ``side`` vertices -> (P, 3) point (NaN if empty).

    centered: (P, V, 3); axis, lateral: (P, 3) unit, orthogonal; side: (P, V) bool; band: (P,) metres.
    The patch is the side's vertices within ``band`` of its lowest one; the point is the centre of
    the patch's extent across the axis (not its vertex mean: toes are meshed more densely than
    heels) at the lowest height, so a flat sole gives the middle of its footprint.
    """
    forward = np.cross(axis, lateral)
    height = np.einsum("pvi,pi->pv", centered, axis)
    lowest = np.where(side, height, np.inf).min(axis=1)  # (P,)
    patch = side & (height <= (lowest + band)[:, None])
    count = patch.sum(axis=1)
    centre = []
    for direction in (lateral, forward):
        coord = np.einsum("pvi,pi->pv", centered, direction)
        lo = np.where(patch, coord, np.inf).min(axis=1)
        hi = np.where(patch, coord, -np.inf).max(axis=1)
        centre.append(0.5 * (np.where(count > 0, lo, 0.0) + np.where(count > 0, hi, 0.0)))
    lowest = np.where(count > 0, lowest, 0.0)  # an empty side has lowest = inf
    point = centre[0][:, None] * lateral + centre[1][:, None] * forward + lowest[:, None] * axis
    point[count == 0] = np.nan
    return point


def _points_by_geometry(verts: np.ndarray, hint_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Finite (P, V, 3), hint (P, 3) -> feet (P, 3), heads (P, 3), ok (P,) bool (False = NaN row)."""
    center = verts.mean(axis=1)
    centered = verts - center[:, None, :]
    up, lateral, ok = _body_axes(centered, hint_cam)
    extent = np.ptp(np.einsum("pvi,pi->pv", centered, up), axis=1)  # sole-to-crown length
    across = np.einsum("pvi,pi->pv", centered, lateral)  # which half of the body, per vertex
    sole_a = _lowest_patch_point(centered, up, lateral, across > 0.0, _SOLE_BAND * extent)
    sole_b = _lowest_patch_point(centered, up, lateral, across < 0.0, _SOLE_BAND * extent)
    crown = _lowest_patch_point(centered, -up, lateral, np.ones_like(across, dtype=bool), _CROWN_BAND * extent)
    feet_cam = center + 0.5 * (sole_a + sole_b)
    heads_cam = center + crown
    ok &= np.isfinite(feet_cam).all(axis=1) & np.isfinite(heads_cam).all(axis=1)
    return feet_cam, heads_cam, ok
