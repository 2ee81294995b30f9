"""Foot point (ground contact) and head point (crown) of each person's mesh, in the mesh's frame.

The contract (docs/conventions.md, "People") defines the **head point** as the top of the head and
the **foot point** as where the person meets the ground, the **ground contact point**
(:func:`ground_contact`): the mid-sole (the midpoint of the two feet's sole points) when both soles
are level along the body's own axis (mid-sole -> crown); when one foot is raised, a point on the lower
sole's level. Up to a raise of :data:`SHARED_RAISE` of the mid-sole -> crown length (~17 cm on a 1.7
m person) both feet share the weight, as in walking and stepping, and the point is the mid-sole slid
down the axis (it stays under the head, and moves only along the axis as the feet take turns); from
:data:`FULL_RAISE` (~35 cm: a one-leg stance, a passe, an arabesque, a kick) the raised foot carries
nothing and the point is the standing sole itself, over which a balanced person's head is; linearly
between. RotAvat puts this point on the ground: the standing foot ends there, instead of half the
raise under it. Meshes are in the OpenCV camera frame (x right, y down, z forward, metres); so are
the results.

The thresholds: the soles' level difference reaches 8.5 % of the axis for 4D-Humans' walker (5.8 %
in 9 frames of 10) and 8.8 % for HybrIK's dancer's steps (/work/shared/realfiles). A first rule that
moved the point toward the lower sole from the smallest raise on (all the way at 6 %) took the
walker's foot pixel up to half a stride off its head's vertical: calibration kept 35 of its 67 pairs
(66 with this rule). On rotavat's eight packaged bodies (A-pose, both feet down) the point is within
0.9 mm of the mid-sole.

Two modes, chosen per call by the vertex count ``V``:

- **Known topology** (SMPL 6890, SMPL-X 10475, rotavat's packaged synthetic bodies, or
  anything added with :func:`register_topology`): sole point of a foot = mean of that foot's sole vertices;
  crown = the crown vertex. Pure fancy indexing.
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

A person on the left foot (x left, y up; metres; the crown over the mid-sole): the right foot raised
0.4 m (27 % of the axis), the foot point is the left sole; raised 0.1 m (6 %), it is under the mid-sole
on the left sole's level; raised 0.25 m (15.9 %), 59 % of the way from there to the left sole.

>>> left, crown = np.array([0.1, 0.0]), np.array([0.0, 1.7])
>>> ground_contact(left, [-0.1, 0.4], crown).round(6).tolist()
[0.1, 0.0]
>>> (ground_contact(left, [-0.1, 0.1], crown).round(6) + 0.0).tolist()
[0.0, 0.0]
>>> ground_contact(left, [-0.1, 0.25], crown).round(4).tolist()
[0.0587, 0.0]
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
    "FULL_RAISE",
    "SHARED_RAISE",
    "contact_weights",
    "ground_contact",
    "sole_crown_points",
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

# The soles' level difference, as a fraction of the mid-sole -> crown length, below which both feet share the weight
# (the foot point stays on the axis) and from which the raised one carries none (the foot point is the other sole);
# linear between. Walking stays under the first: 4D-Humans' walker <= 8.5 % (5.8 % in 9 frames of 10), HybrIK's
# dancer's steps <= 8.8 %; a passe, an arabesque or a kick is over the second (~35 cm on 1.7 m). Module docstring.
SHARED_RAISE, FULL_RAISE = 0.10, 0.20


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
PACKAGED_BODIES = Path(__file__).resolve().parents[1] / "data" / "bodies.npz"


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


def contact_weights(left_sole: np.ndarray, right_sole: np.ndarray, crown: np.ndarray) -> np.ndarray:
    """(..., 3) the weights (left sole, right sole, crown), summing to 1, that make the ground contact point
    (:func:`ground_contact`) of points (..., D): the same person's weights carry the point to other views of
    it (its 2D keypoints: :func:`rotavat_cli.formats.keypoints.feet_heads_px`).

    With ``f`` the lower sole's depth under the mid-sole along the axis (a fraction of the mid-sole -> crown
    length) and ``w`` where the soles' level difference ``2 f`` lies from :data:`SHARED_RAISE` (0) to
    :data:`FULL_RAISE` (1): the point on the axis is ``(1 + f) mid - f crown``, and the contact ``(1 - w)``
    of it plus ``w`` of the lower sole.
    Weights (0.5, 0.5, 0) (the mid-sole) where the crown coincides with the mid-sole; NaN where an input is.
    """
    left, right, top = (np.asarray(a, dtype=np.float64) for a in (left_sole, right_sole, crown))
    mid = 0.5 * (left + right)
    axis = top - mid
    length = np.linalg.norm(axis, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        level = np.einsum("...i,...i->...", left - mid, axis) / np.where(length > 0, length, np.nan) ** 2
    level = np.where(length > 0, level, np.where(np.isfinite(length), 0.0, np.nan))  # left's height, in axis lengths
    drop = np.abs(level)  # the lower sole's depth under the mid-sole, in axis lengths
    weight = np.clip((2.0 * drop - SHARED_RAISE) / (FULL_RAISE - SHARED_RAISE), 0.0, 1.0)  # the raised foot's unweighting
    on_axis = np.stack([(1.0 + drop) / 2.0, (1.0 + drop) / 2.0, -drop], axis=-1)
    lower = np.stack([level <= 0, level > 0, np.zeros_like(level, dtype=bool)], axis=-1).astype(np.float64)
    return (1.0 - weight)[..., None] * on_axis + weight[..., None] * lower


def ground_contact(left_sole: np.ndarray, right_sole: np.ndarray, crown: np.ndarray) -> np.ndarray:
    """The point a person stands on (..., D) (the module docstring): the mid-sole when the soles are level along
    the mid-sole -> crown axis; with one raised, a point on the lower sole's level: under the mid-sole on the
    axis (a raise under :data:`SHARED_RAISE` of the axis), the lower sole itself (from :data:`FULL_RAISE`).

    left_sole, right_sole, crown: (..., D) float, any frame: D = 3 (metres) or D = 2 (pixels, the image
    axis standing in for the body's). NaN where an input is; the mid-sole where the crown coincides with it.
    """
    weights = contact_weights(left_sole, right_sole, crown)
    return sum(weights[..., k, None] * np.asarray(point, dtype=np.float64)
               for k, point in enumerate((left_sole, right_sole, crown)))


def sole_crown_points(
    verts_cam: np.ndarray, up_hint_cam: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P, V, 3) meshes -> left soles, right soles, crowns (P, 3) each; float64, NaN rows if degenerate.

    verts_cam and up_hint_cam as for :func:`foot_head_points`. In geometry mode the two soles are the
    lowest patches of the two halves of the body (which is left is not known: the order is arbitrary).
    """
    verts = np.asarray(verts_cam)
    if verts.dtype.kind != "f":
        verts = verts.astype(np.float64)
    if verts.ndim != 3 or verts.shape[-1] != 3:
        raise ValueError(f"verts_cam must have shape (P, V, 3), got {verts.shape}")
    n_people, n_verts = verts.shape[:2]
    if n_people == 0 or n_verts == 0:
        return tuple(np.full((n_people, 3), np.nan) for _ in range(3))
    topology = topology_for(n_verts)
    if topology is not None:
        left, right, crown = _points_by_topology(verts, topology)
        # all vertices identical <=> a collapsed mesh: its crown coincides with its soles
        valid = np.isfinite(verts).all(axis=(1, 2)) & np.any(left != crown, axis=1)
    else:
        verts = verts.astype(np.float64, copy=False)
        valid = _valid_people(verts)
        hint_cam = _up_hint(up_hint_cam, n_people)
        safe_verts = np.where(valid[:, None, None], verts, 0.0)  # keeps NaN out of eigh
        left, right, crown, ok = _points_by_geometry(safe_verts, hint_cam)
        valid &= ok
    for points in (left, right, crown):
        points[~valid] = np.nan
    return left, right, crown


def foot_head_points(
    verts_cam: np.ndarray, up_hint_cam: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(P, V, 3) meshes -> feet_cam (P, 3) ground contact points, heads_cam (P, 3) crowns; float64, NaN if degenerate.

    verts_cam: (P, V, 3) float, camera frame, metres; P may be 0.
    up_hint_cam: (3,) or (P, 3), roughly "up" for the people (any norm); only its sign along the
        body axis matters. Default ``(0, -1, 0)``, up in the image. Unused for known topologies.
    The foot point is :func:`ground_contact` of the two soles and the crown (the mid-sole when the
    soles are level).
    """
    left, right, crown = sole_crown_points(verts_cam, up_hint_cam)
    return ground_contact(left, right, crown), crown


def _valid_people(verts: np.ndarray) -> np.ndarray:
    """(P, V, 3) -> (P,) bool: every vertex finite and not all vertices the same point."""
    finite = np.isfinite(verts).all(axis=(1, 2))
    varied = (verts != verts[:, :1]).any(axis=(1, 2))  # one pass; cheaper than a peak-to-peak
    return finite & varied


def _points_by_topology(verts: np.ndarray, topology: Topology) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P, V, 3) -> left and right soles (P, 3) = the mean of each foot's sole vertices, crowns (P, 3)."""
    left_sole = verts[:, topology.left_sole_indices].astype(np.float64).mean(axis=1)
    right_sole = verts[:, topology.right_sole_indices].astype(np.float64).mean(axis=1)
    return left_sole, right_sole, verts[:, topology.crown_index].astype(np.float64)


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


def _points_by_geometry(verts: np.ndarray, hint_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Finite (P, V, 3), hint (P, 3) -> the two halves' soles (P, 3) each, crowns (P, 3), ok (P,) bool (False = NaN row)."""
    center = verts.mean(axis=1)
    centered = verts - center[:, None, :]
    up, lateral, ok = _body_axes(centered, hint_cam)
    extent = np.ptp(np.einsum("pvi,pi->pv", centered, up), axis=1)  # sole-to-crown length
    across = np.einsum("pvi,pi->pv", centered, lateral)  # which half of the body, per vertex
    sole_a = _lowest_patch_point(centered, up, lateral, across > 0.0, _SOLE_BAND * extent)
    sole_b = _lowest_patch_point(centered, up, lateral, across < 0.0, _SOLE_BAND * extent)
    crown = _lowest_patch_point(centered, -up, lateral, np.ones_like(across, dtype=bool), _CROWN_BAND * extent)
    sole_a, sole_b, crown = center + sole_a, center + sole_b, center + crown
    ok &= np.isfinite(sole_a).all(axis=1) & np.isfinite(sole_b).all(axis=1) & np.isfinite(crown).all(axis=1)
    return sole_a, sole_b, crown, ok
