"""Who stands? Posture from 3D joints: what supports the person, and the people a calibration may take as verticals.

Calibration takes each person's foot and crown pixels as the ends of a 1.70 m vertical; a person who
sits, kneels or bends is not one. This module tells them apart from the joints an HPS tool wrote
(camera frame; only the body's own segments are used, so the result does not depend on the camera's
orientation, position or on the body's size). Joints are read by name
(:data:`rotavat_cli.bodies.joint_layouts.LAYOUT_NAMES`): hips, knees, ankles and shoulders, which every
layout there has.

It decides by **what touches the ground**, not by how bent the knees are: a dancer in plie, a
tennis player crouching before a serve, a runner, someone on one leg stand on their feet with
their pelvis well above them; a sitter's pelvis is down near the knees, a kneeler's knee is on the
ground. The measures, per person (:class:`PostureMeasures`):

- **support leg**: the leg whose ankle is lower along the body's axis (mid-ankles -> mid-shoulders):
  the standing foot of a one-leg stance, a runner's or walker's stance foot (the foot the ground
  contact point of :func:`rotavat_cli.bodies.landmarks.ground_contact` is on);
- **pelvis height**: the mid-hips above the support ankle, along the axis from that ankle to the
  mid-shoulders, in the support leg's lengths (thigh + shank): 1 standing straight, ~0.85 a tennis
  player's ready crouch, 0.65 seated on a chair, 0.4 squatting or on a sofa;
- **thigh to trunk** (the support leg's hip flexion): the angle between the trunk reversed
  (mid-shoulders -> mid-hips) and the thigh; 0 = in line, 90 = thigh square to the trunk (seated);
- **knee height**: the lower knee above the support ankle along the trunk (mid-hips ->
  mid-shoulders), in shank lengths: ~0 with a knee on the ground;
- **trunk bend**: between the trunk (mid-hips -> mid-shoulders) and the body's axis (mid-ankles ->
  mid-shoulders): 0 when the trunk stands over the feet.

The names (:func:`classify_postures`), in this order: **unknown** for non-finite or coincident
joints; **bending** when the trunk bend reaches :data:`TRUNK_BEND_MAX_RAD`; **kneeling** when a knee
is down at the support foot's level (knee height <= :data:`KNEE_DOWN_MAX`); **sitting** when the
pelvis is low: under :data:`PELVIS_LOW_MAX` leg whatever the thighs (a squat, sitting on the heels
or the floor), or under :data:`PELVIS_SEATED_MAX` with the thigh at least
:data:`THIGH_SEATED_MIN_RAD` off the trunk (the thighs towards horizontal: a chair, a bench);
**standing** otherwise (knees bent or straight, one leg or two). The mask is what calibration and
align use; the name is for messages and people.csv.

How the thresholds were measured (pelvis in leg lengths; knee in shank lengths; thigh, the support
leg's, and trunk in degrees; ranges over the group):

=========================================  ====  ===========  ===========  ===========  ===========
source (joints layout), who                n     pelvis       knee         thigh        trunk
=========================================  ====  ===========  ===========  ===========  ===========
packaged bodies (smpl24), standing A-pose  8     1.01         1.00         5.3-8.8      0.3-2.6
``rotavat synth`` gt / pred (smpl24)       960   0.99-1.03    0.99-1.00    1.8-11.8     0.0-4.0
4D-Humans gait video (phalp44), 1 walker   67    0.92-1.00    0.76-0.99    6.8-38.0     0.2-8.4
HybrIK video (smpl24), 1 dancer, steps     135   0.95-1.00    0.92-1.00    0.3-19.5     0.9-9.8
GVHMR tennis video (smpl24 of SMPL-X),     296   0.74-1.03    0.24-1.00    5.4-91.8     6.1-29.8
1 player: frames read standing
  the same, frames read otherwise          16    0.67-0.95    0.07-0.97    50.1-95.0    24.6-33.3
BEV photos (smpl24), standing: flickr boy  7     0.90-0.99    0.70-0.96    2.5-11.2     4.1-13.2
and photographer, bev_live image_1 (2),
image_5 (2, legs cut by the edge),
flickr woman kneeling (shins hidden)
BEV flickr: person on a bench behind the   1     0.90         0.93         31.8         1.7
photographer (drawn as a crouching
stander: read standing)
BEV flickr: person sitting at the right    3     0.40-0.68    0.88-0.93    72.0-108.5   5.1-14.7
edge; bev_live image_8: two on a sofa
hand-built (tests): chair, squat; kneeling 4     0.37-0.67    0.98-1.00;   0-120        0.0-24.5
(upright, and on one knee)                                   kneelers 0
=========================================  ====  ===========  ===========  ===========  ===========

(``rotavat synth`` seeds 0-2, 20 frames of 8 people each, pred with its 5 mm joint noise; the real
files are muelea/buddi's BEV demo data and the others of /work/shared/realfiles, imported with
``rotavat import``; the tennis player's joints are those of a synthetic SMPL-X-layout model
(tests/_body_models.py) under GVHMR's poses, his real model being licensed. Who stands, sits or kneels
was read from the photos; the tennis player stands throughout, his height seen in GVHMR's own
gravity-aligned world: his crown is at 96-98 % of his standing height in his ready stance, 86-89 %
in his deepest crouch, 78-85 % in his landing lunges.)

- Pelvis: standing people >= 0.67 leg (the tennis player's landing lunge; 0.74 read standing, his
  crouch before a serve); seated people 0.40-0.68. :data:`PELVIS_LOW_MAX` = 0.6 leaves every
  stander standing whatever the thighs; below :data:`PELVIS_SEATED_MAX` = 0.8 the thighs decide.
- Thighs: seated people's are >= 72 deg off the trunk (the hand-built chair: 90); the tennis
  player's, with his pelvis under 0.8 leg, <= 48 deg (a landing lunge; his crouches <= 39):
  :data:`THIGH_SEATED_MIN_RAD` = 50 deg. The measured standers come within 2 deg (thigh) and 0.035
  leg (pelvis) of these two lines only in the lunges that land his serves, where his crown is at
  83-88 % of his height anyway.
- Knees: a kneeler's is at the support foot's level (0); standing people's >= 0.24 shank (one
  frame of a lunge, the trunk leaning 28 deg; else >= 0.32): :data:`KNEE_DOWN_MAX` = 0.2.
- Trunk: standing people reach 29.8 deg (the tennis player leaning into a stroke, his crown at
  88-96 % of his height); :data:`TRUNK_BEND_MAX_RAD` = 30 deg is a bow of ~47 deg over straight
  legs, its shoulders 12 % lower: no lower than the deepest crouch read standing.

Limits: joints alone cannot see which way gravity points, so a person lying straight "stands", and a
body tilted far over (the tennis player's lunges with one leg kicked up behind: the body's axis
then leans 30-39 deg, and the kicked foot reads lower) gets its names from the wrong support foot.
They cannot see what the HPS tool did not either: BEV gives the woman kneeling behind the boy in the
flickr photo (her shins hidden) knees of 46-50 deg with straight hips, and the person sitting on the
bench behind the photographer knees of 53-65 deg, thighs 32 deg off the trunk and the pelvis 0.90 leg
above the feet: a crouching stander, less bent than the tennis player's crouch, so both read
standing. The rule before this one (knee bend + hip flexion of the straighter leg under 75 deg)
caught that bench sitter, and read 133 of the tennis player's 312 frames as bending, sitting or
kneeling.

Examples
--------
A straight body, a seated one and one standing on one leg, built by hand (x left, y up, z forward;
metres):

>>> import numpy as np
>>> names = ("left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
...          "left_shoulder", "right_shoulder")
>>> standing = np.array([[0.1, 0.9, 0], [-0.1, 0.9, 0], [0.1, 0.5, 0], [-0.1, 0.5, 0],
...                      [0.1, 0.1, 0], [-0.1, 0.1, 0], [0.2, 1.4, 0], [-0.2, 1.4, 0]])
>>> seated = standing.copy()
>>> seated[2:4] = [[0.1, 0.9, 0.4], [-0.1, 0.9, 0.4]]       # thighs forward (hips at 90 deg)
>>> seated[4:6] = [[0.1, 0.5, 0.4], [-0.1, 0.5, 0.4]]       # shanks down (knees at 90 deg)
>>> one_leg = standing.copy()
>>> one_leg[[3, 5]] = [[-0.1, 0.6, 0.35], [-0.1, 0.55, -0.05]]   # right thigh forward, foot up by the left knee
>>> joints = np.zeros((3, 24, 3))
>>> joints[:, [LAYOUT_NAMES["smpl24"].index(n) for n in names]] = np.stack([standing, seated, one_leg])
>>> standing_mask(joints, "smpl24").tolist()
[True, False, True]
>>> postures(joints, "smpl24").tolist()
['standing', 'sitting', 'standing']
>>> m = posture_measures(joints, "smpl24")
>>> m.pelvis_height.round(2).tolist(), m.support_leg.tolist()
([1.01, 0.67, 1.01], [0, 0, 0])
>>> posture_reasons(joints, None)[1]            # layout None: by the joint count (24: smpl24)
'sitting: pelvis 0.67 leg above the left foot (sitting under 0.6, or under 0.8 with the thigh 50 deg off the trunk: 90); knee 1.00 shank above it (kneeling under 0.2); trunk 24 deg off the body axis (bending from 30)'
>>> summarize_postures(postures(joints, "smpl24"))
'1 sitting'
>>> print(standing_mask(joints, "hands21"))       # a layout without those joints
None
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from .joint_layouts import LAYOUT_NAMES, layout_by_count, layout_key
from ..geometry.rotations import cross3

__all__ = [
    "KNEE_DOWN_MAX",
    "PELVIS_LOW_MAX",
    "PELVIS_SEATED_MAX",
    "POSTURES",
    "POSTURE_JOINTS",
    "PostureMeasures",
    "THIGH_SEATED_MIN_RAD",
    "TRUNK_BEND_MAX_RAD",
    "classify_postures",
    "posture_measures",
    "posture_reasons",
    "postures",
    "standing_mask",
    "summarize_postures",
]

POSTURES = ("standing", "sitting", "kneeling", "bending", "unknown")
SIDES = ("left", "right")  # the order of the per-leg columns
# The joints the measures read, by name; every layout of LAYOUT_NAMES has them.
POSTURE_JOINTS = tuple(f"{side}_{part}" for part in ("hip", "knee", "ankle", "shoulder") for side in SIDES)

# Thresholds (measured: module docstring table).
# Trunk to the body axis (mid-ankles -> mid-shoulders): standing people <= 26.4 deg (GVHMR's tennis player leaning into
# his ready stance, crown at 96-98 % of his height); a bow over straight legs reaches 30 deg at ~47 deg, its shoulders
# 12 % lower, as low as the deepest crouch kept standing.
TRUNK_BEND_MAX_RAD = np.deg2rad(30.0)
# A knee as low as the standing foot, along the trunk (a knee on the ground): kneelers ~0 (shins on the ground),
# standing people >= 0.38 shank (the tennis player's deepest crouch, trunk leaning 25 deg).
KNEE_DOWN_MAX = 0.2
# Pelvis above the standing foot, along that foot -> mid-shoulders axis, in leg lengths (thigh + shank): below this
# whatever the thighs, nobody stands (a squat 0.37, a sofa 0.40); standing people >= 0.67.
PELVIS_LOW_MAX = 0.6
# ... and below this with the standing leg's thigh >= THIGH_SEATED_MIN_RAD off the trunk (thighs towards horizontal):
# sitting. Seated people: pelvis <= 0.68 with thighs >= 72 deg off the trunk; standing people with bent knees have
# their thighs <= 39 deg off the trunk, or their pelvis >= 0.80 (module docstring table).
PELVIS_SEATED_MAX = 0.8
THIGH_SEATED_MIN_RAD = np.deg2rad(50.0)
_LEVEL_TIE_M = 1e-6  # ankles this close in level are level (rounding must not pick the support foot)


@dataclass(frozen=True)
class PostureMeasures:
    """Per-person posture measures; NaN where a person's joints are not finite or coincide.

    knee_rad: (P, 2) left, right; thigh (hip -> knee) to shank (knee -> ankle), radians, 0 = straight.
    hip_flexion_rad: (P, 2) left, right; trunk reversed (mid-shoulders -> mid-hips) to thigh, radians, 0 = in line.
    trunk_bend_rad: (P,) trunk (mid-hips -> mid-shoulders) to the body axis (mid-ankles -> mid-shoulders), radians.
    support_leg: (P,) int, 0 left / 1 right: the leg whose ankle is lower along the body axis (what stands on the
        ground; the foot :func:`rotavat_cli.bodies.landmarks.ground_contact` puts there); 0 for people with NaN joints.
    pelvis_height: (P,) mid-hips above the support ankle along the support ankle -> mid-shoulders axis, in support
        leg lengths (thigh + shank): ~1 standing straight, ~0.65 seated on a chair, ~0.4 squatting.
    knee_height: (P,) the lower knee above the support ankle along the trunk (mid-hips -> mid-shoulders), in that
        leg's shank lengths: ~1 standing, ~0 with a knee on the ground.
    """

    knee_rad: np.ndarray
    hip_flexion_rad: np.ndarray
    trunk_bend_rad: np.ndarray
    support_leg: np.ndarray
    pelvis_height: np.ndarray
    knee_height: np.ndarray

    @property
    def support_hip_flexion_rad(self) -> np.ndarray:
        """(P,) the support leg's hip flexion: how far its thigh is off the trunk's line (radians)."""
        return np.take_along_axis(self.hip_flexion_rad, self.support_leg[:, None], axis=1)[:, 0]

    @property
    def valid(self) -> np.ndarray:
        """(P,) bool: every measure is finite."""
        return (np.isfinite(self.knee_rad).all(axis=1) & np.isfinite(self.hip_flexion_rad).all(axis=1)
                & np.isfinite(self.trunk_bend_rad) & np.isfinite(self.pelvis_height) & np.isfinite(self.knee_height))


def _angle_rad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) angle in [0, pi] between vectors a, b (..., 3); NaN where either is zero or not finite."""
    cross = np.linalg.norm(cross3(a, b), axis=-1)
    dot = np.einsum("...i,...i->...", a, b)
    degenerate = (np.linalg.norm(a, axis=-1) == 0.0) | (np.linalg.norm(b, axis=-1) == 0.0)
    return np.where(degenerate, np.nan, np.arctan2(cross, dot))  # arctan2: accurate near 0 and pi


def _unit(v: np.ndarray) -> np.ndarray:
    """(..., 3) unit vectors; NaN where a vector is zero or not finite."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, v / norm, np.nan)


def _level(points: np.ndarray, origin: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Height of points (P, ..., 3) above origin (P, 3) along unit up (P, 3): (P, ...)."""
    extra = (slice(None),) + (None,) * (points.ndim - 2)
    return np.einsum("p...i,p...i->p...", points - origin[extra], np.broadcast_to(up[extra], points.shape))


def _joint_indices(layout: str | None, n_joints: int) -> dict[str, int] | None:
    """Index of each of POSTURE_JOINTS in ``layout`` (by count when None); None when the layout is unknown,
    lacks one of them, or is longer than the joints array."""
    key = layout_key(layout) if layout is not None else layout_by_count(n_joints)
    names = LAYOUT_NAMES.get(key) if key is not None else None
    if names is None or len(names) > n_joints or not set(POSTURE_JOINTS) <= set(names):
        return None
    return {name: names.index(name) for name in POSTURE_JOINTS}


def posture_measures(joints_cam: np.ndarray, layout: str | None) -> PostureMeasures | None:
    """Posture measures of each person from joints (P, J, 3) in ``layout``; None for a layout without them.

    joints_cam: (P, J, 3) float, any frame (camera frame, metres, in practice); P may be 0.
    layout: a name of :data:`~rotavat_cli.bodies.joint_layouts.LAYOUT_NAMES`, with or without its description
        ('phalp44 (OpenPose-25 + 19 extra)', meta.yaml ``import.joints_layout``); None: by the joint count
        (SMPL family, :func:`~rotavat_cli.bodies.joint_layouts.layout_by_count`).
    """
    joints = np.asarray(joints_cam, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[-1] != 3:
        raise ValueError(f"joints_cam must have shape (P, J, 3), got {joints.shape}")
    index = _joint_indices(layout, joints.shape[1])
    if index is None:
        return None

    def pair(part: str) -> np.ndarray:  # (P, 2, 3): left, right; inf made NaN (NaN propagates without warnings)
        chosen = joints[:, [index[f"{side}_{part}"] for side in SIDES]]
        return np.where(np.isfinite(chosen), chosen, np.nan)

    hips, knees, ankles, shoulders = pair("hip"), pair("knee"), pair("ankle"), pair("shoulder")
    mid_hips, mid_shoulders, mid_ankles = hips.mean(axis=1), shoulders.mean(axis=1), ankles.mean(axis=1)
    thighs, shanks = knees - hips, ankles - knees  # (P, 2, 3)
    trunk_up = mid_shoulders - mid_hips  # (P, 3)
    people = np.arange(len(joints))
    levels = _level(ankles, mid_ankles, _unit(mid_shoulders - mid_ankles))  # (P, 2)
    with np.errstate(invalid="ignore"):
        support = (levels[:, 1] < levels[:, 0] - _LEVEL_TIE_M).astype(np.int64)  # feet level: the left
    ankle = ankles[people, support]  # (P, 3)
    leg_m = np.linalg.norm(thighs[people, support], axis=-1) + np.linalg.norm(shanks[people, support], axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        pelvis = _level(mid_hips, ankle, _unit(mid_shoulders - ankle)) / leg_m
        knee = np.min(_level(knees, ankle, _unit(trunk_up)) / np.linalg.norm(shanks, axis=-1), axis=1)
    return PostureMeasures(
        knee_rad=_angle_rad(thighs, shanks),
        hip_flexion_rad=_angle_rad(-trunk_up[:, None, :], thighs),
        trunk_bend_rad=_angle_rad(trunk_up, mid_shoulders - mid_ankles),
        support_leg=support,
        pelvis_height=np.where(np.isfinite(pelvis), pelvis, np.nan),
        knee_height=np.where(np.isfinite(knee), knee, np.nan),
    )


def classify_postures(measures: PostureMeasures) -> np.ndarray:
    """(P,) posture names (:data:`POSTURES`) from the measures; rules in the module docstring."""
    m = measures
    with np.errstate(invalid="ignore"):  # NaN compares False: those people are 'unknown' below
        bends = m.trunk_bend_rad >= TRUNK_BEND_MAX_RAD
        kneels = m.knee_height <= KNEE_DOWN_MAX
        sits = (m.pelvis_height < PELVIS_LOW_MAX) | ((m.pelvis_height < PELVIS_SEATED_MAX)
                                                     & (m.support_hip_flexion_rad >= THIGH_SEATED_MIN_RAD))
    return np.select([~m.valid, bends, kneels, sits], ["unknown", "bending", "kneeling", "sitting"],
                     default="standing").astype(f"<U{max(map(len, POSTURES))}")


def postures(joints_cam: np.ndarray, layout: str | None) -> np.ndarray | None:
    """(P,) posture name of each person (:data:`POSTURES`); None when the layout lacks the joints."""
    measures = posture_measures(joints_cam, layout)
    return None if measures is None else classify_postures(measures)


def standing_mask(joints_cam: np.ndarray, layout: str | None) -> np.ndarray | None:
    """(P,) bool, True for people who stand (or walk, run, crouch on their feet); None when the layout lacks the joints.

    joints_cam: (P, J, 3) float; layout as for :func:`posture_measures`. People with non-finite or
    coincident joints are False (:func:`posture_reasons` says why).
    """
    names = postures(joints_cam, layout)
    return None if names is None else names == "standing"


def posture_reasons(joints_cam: np.ndarray, layout: str | None) -> tuple[str, ...] | None:
    """One line per person: the posture and the measures that decided it (for messages); None when the
    layout lacks the joints."""
    measures = posture_measures(joints_cam, layout)
    if measures is None:
        return None
    names = classify_postures(measures)
    joints = np.asarray(joints_cam, dtype=np.float64)
    index = _joint_indices(layout, joints.shape[1])
    finite = np.isfinite(joints[:, list(index.values())]).all(axis=(1, 2))
    thigh, trunk = np.rad2deg(measures.support_hip_flexion_rad), np.rad2deg(measures.trunk_bend_rad)
    reasons = []
    for p, name in enumerate(names):  # formatting only: the decisions above are vectorised
        if name == "unknown":
            reasons.append("unknown: " + ("non-finite joints" if not finite[p] else "coincident joints (a zero-length "
                                          "thigh, shank or trunk)"))
            continue
        reasons.append(
            f"{name}: pelvis {measures.pelvis_height[p]:.2f} leg above the {SIDES[measures.support_leg[p]]} foot "
            f"(sitting under {PELVIS_LOW_MAX:g}, or under {PELVIS_SEATED_MAX:g} with the thigh "
            f"{np.rad2deg(THIGH_SEATED_MIN_RAD):.0f} deg off the trunk: {thigh[p]:.0f}); knee {measures.knee_height[p]:.2f} "
            f"shank above it (kneeling under {KNEE_DOWN_MAX:g}); trunk {trunk[p]:.0f} deg off the body axis (bending "
            f"from {np.rad2deg(TRUNK_BEND_MAX_RAD):.0f})")
    return tuple(reasons)


def summarize_postures(names: Iterable[str]) -> str:
    """'2 sitting, 1 kneeling': how many people of each posture other than standing ('' if none)."""
    names = list(names)
    return ", ".join(f"{names.count(name)} {name}" for name in POSTURES[1:] if name in names)
