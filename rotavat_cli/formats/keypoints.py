"""Foot (ground contact: the mid-sole with both feet down) and head (crown) pixels from an HPS tool's own 2D
keypoints.

Calibration and joint-level alignment need, per person, the pixel of the foot point and of the
crown (``feet_2d`` / ``heads_2d``, docs/conventions.md). Meshes give them through their landmark
vertices (:mod:`rotavat_cli.bodies.landmarks`); without a body model, an importer still has the tool's
2D keypoints, and the importer passes its layout's name to
:func:`rotavat_cli.formats.frames.people_frame` (``keypoints_layout=``), which writes
``feet_2d``/``heads_2d`` and records which points were used (``meta.yaml``
``import.feet_heads_from``).

Each layout has a recipe: a :class:`PointRule` for each foot's sole point (their midpoint is the
mid-sole) and one for the crown. A rule is an affine combination of keypoint means (weights summing
to one), so it moves, turns and scales with the person in the image. The foot pixel written is the
ground contact (:func:`rotavat_cli.bodies.landmarks.ground_contact`): the two soles' and the crown's pixels
weighted as the person's own 3D joints' ground contact is (:func:`contact_weights_3d`; the image
cannot tell a raised foot from a nearer one), the mid-sole without 3D joints. The rules:

- **points the layout has**: the mean of named keypoints (OpenPose's big toes, small toes and
  heels for the mid-sole, as the mesh landmark's own recipe in :data:`rotavat_cli.bodies.landmarks.SMPL`;
  LSP's top of head or HybrIK's head-top leaf for the crown);
- **estimates**, where the layout has no such point: ``anchor + k (anchor - away_from)``, i.e.
  the anchor pushed along the body axis by a fraction ``k`` of a body segment in pixels (e.g. the
  crown above the ears by 0.632 of the shoulders-to-ears segment, the sole below the ankles by
  0.081 of the hips-to-ankles one), plus for COCO a forward shift along the face's direction
  (nose - ears: the mid-sole lies ~9 cm in front of the ankles, in the direction the person faces).

How the estimates were measured (numbers in % of the person's pixel stature, mean / max):
two sets of bodies with a known mid-sole (landmark recipe) and crown, each body turned to 12
directions (every 30 deg) and seen from 0, 15, 30 and 45 deg above at 5 and 12 m (f = 1000 px),
i.e. 96 views per body:

- ``anny``: rotavat's 8 packaged synthetic adults (``data/bodies.npz``, standing, A-pose,
  1.55-1.90 m); their joints are anny's skeleton (close to SMPL's, not equal), and their nose,
  eyes, ears, heels and toes were located on the mesh (nose = foremost head vertex, ear = the
  outermost 1.2 cm of each side of the head, heel = hindmost foot vertex, toes = foremost vertices
  of the inner / outer foot; about +-1 cm);
- ``smpl``: the 4 SMPL people of BEV's own outputs on real photos (muelea/buddi demo data, the
  ``verts`` and 71 ``joints`` BEV wrote) whose sole-to-crown length exceeds 1.4 m (1.63-1.79 m;
  sitting or embracing couples): SMPL's own joint regressors and vertex keypoints, mesh landmarks
  from SMPL's vertices (re-measured by tests/test_formats_realfiles.py).

Coefficients were fitted by least squares on the set(s) named in brackets; the errors are over
every view of each set (leave-one-body-out errors differ by < 0.1 % on ``anny``):

===============================  ============================================  ===========  ===========
layout                           rule                                          anny         smpl
===============================  ============================================  ===========  ===========
sole, OpenPose toes and heels    mean of big toes, small toes, heels (no fit)  1.5 / 2.6    1.7 / 2.8
sole, SMPL-24 (also HybrIK-29)   ankles+feet, k = 0.047 from the hips [both]   0.8 / 1.4    0.7 / 1.3
sole, COCO-17                    ankles, k = 0.07 from the hips, + 0.556       1.1 / 2.3    1.5 / 3.8
                                 (nose - mid-ears) [both]
sole, H36M-17                    ankles, k = 0.116 from the hips [smpl]        --           3.9 / 6.8
crown, ears (OpenPose, COCO,     mid-ears, k = 0.632 from the mid-shoulders    0.6 / 1.1    1.3 / 3.5
SMPL-45, SMPL-X)                 [both]
crown, SMPL-24                   head joint, k = 0.314 from the mid-hips       3.0 / 3.7    1.1 / 2.9
                                 [smpl] (anny: another skeleton's head joint)
crown, H36M-17                   H36M head, k = 0.462 from the thorax [smpl]   --           0.7 / 1.7
crown, LSP top of head           the point itself (no fit)                     --           1.8 / 3.3
===============================  ============================================  ===========  ===========

For comparison, the ankles alone miss the mid-sole by 5.7 % (anny), the SMPL head joint misses
the crown by ~10 %, and the H36M "head" is ~4.5 % of stature below it. Limits: upright bodies
(bending or sitting change the proportions: on the two other people of those photos, a seated
man and a woman BEV shaped as a child, the ears rule is 3.6 % off on average and the SMPL-24
crown 4.8 %); children have larger heads; the COCO sole assumes the face looks where the feet
point; detectors' ear and shoulder points are not mesh vertices. On 4D-Humans' real walker
(/work/shared/realfiles gait, HMR 2.0 joints) the COCO sole rule is 1.4 % (max 3.5 %) from the
mean of OpenPose toes and heels, while the ears rule puts the crown 6.7 % of stature above LSP's
top of head: the two crowns of that file disagree, which no rule here settles.

A person whose recipe points are missing (not finite, or zero confidence where the layout has a
third column) gets NaN for that point.

>>> import numpy as np
>>> kp = np.zeros((1, 49, 2)); kp[0, [19, 20, 21, 22, 23, 24]] = [[10, 100], [12, 100], [8, 102], [20, 100], [22, 100], [18, 102]]
>>> kp[0, 38] = [15, 10]
>>> feet, heads, used = feet_heads_px(kp, "spin49")
>>> feet.tolist(), heads.tolist()
([[15.0, 100.66666666666667]], [[15.0, 10.0]])
>>> used.split(";")[0]
'spin49: mid-sole = mean of OpenPose big toes, small toes and heels (1.5-1.7 % of stature from the mesh mid-sole)'
>>> coco = np.zeros((1, 17, 2)); coco[0, [3, 4]] = [[40, 20], [60, 20]]; coco[0, [5, 6]] = [[30, 40], [70, 40]]
>>> feet_heads_px(coco, "coco17")[1].round(3).tolist()        # crown = mid-ears + 0.632 (mid-ears - mid-shoulders)
[[50.0, 7.36]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bodies.joint_layouts import LAYOUT_NAMES, layout_key
from ..bodies.landmarks import contact_weights, ground_contact

__all__ = [
    "LAYOUTS",
    "KeypointRecipe",
    "PointRule",
    "averaged",
    "contact_weights_3d",
    "extrapolated",
    "feet_heads_cam",
    "feet_heads_px",
    "mean_of",
    "recipe_for",
]


@dataclass(frozen=True)
class PointRule:
    """A point from keypoints: ``sum_i weight_i * mean(keypoints[indices_i])`` with weights summing to 1.

    ``estimated``: the layout has no such point; the rule extrapolates it (measured, module docstring).
    """

    terms: tuple[tuple[float, tuple[int, ...]], ...]
    estimated: bool = False

    def __post_init__(self) -> None:
        if not self.terms or any(not idx for _, idx in self.terms):
            raise ValueError("a PointRule needs at least one term with keypoint indices")
        if abs(sum(w for w, _ in self.terms) - 1.0) > 1e-9:
            raise ValueError(f"a PointRule's weights must sum to 1 (affine), got {sum(w for w, _ in self.terms)}")

    @property
    def indices(self) -> tuple[int, ...]:
        """Every keypoint index the rule reads."""
        return tuple(sorted({i for _, idx in self.terms for i in idx}))


def mean_of(*indices: int) -> PointRule:
    """The mean of keypoints ``indices`` (a point the layout has)."""
    return PointRule(((1.0, tuple(indices)),))


def extrapolated(anchor: tuple[int, ...], away_from: tuple[int, ...], k: float,
                 facing: tuple[tuple[int, ...], tuple[int, ...], float] | None = None) -> PointRule:
    """``A + k (A - B)`` [``+ k2 (mean(f0) - mean(f1))``] with A, B the means of ``anchor``, ``away_from``;
    ``facing`` = (f0, f1, k2). An estimate (``estimated=True``)."""
    terms: list[tuple[float, tuple[int, ...]]] = [(1.0 + k, tuple(anchor)), (-k, tuple(away_from))]
    if facing is not None:
        terms += [(facing[2], tuple(facing[0])), (-facing[2], tuple(facing[1]))]
    return PointRule(tuple(terms), estimated=True)


def averaged(a: PointRule, b: PointRule) -> PointRule:
    """The midpoint of two rules' points (one rule: each term at half weight)."""
    return PointRule(tuple((w / 2.0, idx) for w, idx in a.terms + b.terms), estimated=a.estimated or b.estimated)


@dataclass(frozen=True)
class KeypointRecipe:
    """How a layout gives each foot's sole point and the crown (the mid-sole: :attr:`sole`).

    ``n_keypoints``: the layout's length (a longer array is accepted: extra points are ignored);
    ``describes``: what the recipe uses, for meta.yaml.
    """

    left_sole: PointRule
    right_sole: PointRule
    crown: PointRule
    n_keypoints: int
    describes: str

    @property
    def sole(self) -> PointRule:
        """The mid-sole: the midpoint of the two sole points."""
        return averaged(self.left_sole, self.right_sole)


# ---- layouts: the joint names of each layout live in rotavat_cli.bodies.joint_layouts (LAYOUT_NAMES) ----------


def _at(layout: str, *names: str) -> tuple[int, ...]:
    """Indices of ``names`` in ``layout`` (each rule written by name, never by bare index)."""
    order = LAYOUT_NAMES[layout]
    return tuple(order.index(n) for n in names)


_FOOT = ("big_toe", "small_toe", "heel")  # OpenPose's foot points, per side
_EARS, _SHOULDERS, _HIPS = ("left_ear", "right_ear"), ("left_shoulder", "right_shoulder"), ("left_hip", "right_hip")
_SIDES = ("left", "right")

# Measured coefficients (module docstring).
K_SOLE_SMPL = 0.047  # SMPL-24 ankles + feet, away from the hips
K_SOLE_COCO, K_SOLE_COCO_FACING = 0.07, 0.556  # COCO ankles away from the hips, + (nose - mid-ears)
K_SOLE_H36M = 0.116  # H36M ankles, away from the hips
K_CROWN_EARS = 0.632  # mid-ears away from the mid-shoulders
K_CROWN_SMPL = 0.314  # SMPL head joint away from the mid-hips
K_CROWN_H36M = 0.462  # H36M head away from the thorax

_TXT_FEET = "mid-sole = mean of OpenPose big toes, small toes and heels (1.5-1.7 % of stature from the mesh mid-sole)"
_TXT_LSP = "crown = LSP top of head (1.8 % of stature from the mesh crown)"
_TXT_EARS = (f"crown estimated as mid-ears + {K_CROWN_EARS} (mid-ears - mid-shoulders) (estimate: 0.6-1.3 % of "
             "stature on average, up to 3.5 %)")
_TXT_SMPL_SOLE = (f"mid-sole estimated as mean(ankles, feet) + {K_SOLE_SMPL} (that - mid-hips) (estimate: 0.7-0.8 % "
                  "of stature on average, up to 1.4 %)")


def _per_side(make) -> tuple[PointRule, PointRule]:
    """(left, right) sole rules from ``make(side)``; their midpoint is the layout's mid-sole rule."""
    left, right = (make(side) for side in _SIDES)
    return left, right


def _feet_soles(layout: str) -> tuple[PointRule, PointRule]:
    return _per_side(lambda side: mean_of(*_at(layout, *(f"{side}_{part}" for part in _FOOT))))


def _ankle_soles(layout: str, k: float, extra: tuple[str, ...] = (),
                 facing: tuple[tuple[int, ...], tuple[int, ...], float] | None = None) -> tuple[PointRule, PointRule]:
    """Each side's ankle (and ``{side}_{extra}`` joints) pushed away from the mid-hips by ``k`` [+ facing]."""
    return _per_side(lambda side: extrapolated(_at(layout, f"{side}_ankle", *(f"{side}_{e}" for e in extra)),
                                               _at(layout, *_HIPS), k, facing))


def _ears_crown(layout: str) -> PointRule:
    return extrapolated(_at(layout, *_EARS), _at(layout, *_SHOULDERS), K_CROWN_EARS)


def _recipe(layout: str, soles: tuple[PointRule, PointRule], crown: PointRule, describes: str) -> KeypointRecipe:
    return KeypointRecipe(*soles, crown, len(LAYOUT_NAMES[layout]), describes)


LAYOUTS: dict[str, KeypointRecipe] = {
    "openpose25": _recipe("openpose25", _feet_soles("openpose25"), _ears_crown("openpose25"), f"{_TXT_FEET}; {_TXT_EARS}"),
    **{name: _recipe(name, _feet_soles(name), mean_of(*_at(name, "head_top_lsp")), f"{_TXT_FEET}; {_TXT_LSP}")
       for name in ("spin49", "phalp44", "phalp45", "romp54", "romp71", "trace44")},
    **{name: _recipe(name, _feet_soles(name), _ears_crown(name), f"{_TXT_FEET}; {_TXT_EARS}")
       for name in ("smpl45", "smplx127", "smplx144", "body26fk")},
    "coco17": _recipe(
        "coco17",
        _ankle_soles("coco17", K_SOLE_COCO, facing=(_at("coco17", "nose"), _at("coco17", *_EARS), K_SOLE_COCO_FACING)),
        _ears_crown("coco17"),
        f"mid-sole estimated as mid-ankles + {K_SOLE_COCO} (mid-ankles - mid-hips) + {K_SOLE_COCO_FACING} "
        "(nose - mid-ears) (estimate: 1.1-1.5 % of stature on average, up to 3.8 %; assumes the face looks where "
        f"the feet point); {_TXT_EARS}"),
    "h36m17": _recipe(
        "h36m17",
        _ankle_soles("h36m17", K_SOLE_H36M),
        extrapolated(_at("h36m17", "head"), _at("h36m17", "thorax"), K_CROWN_H36M),
        f"mid-sole estimated as mid-ankles + {K_SOLE_H36M} (mid-ankles - mid-hips) (estimate: 3.9 % of stature on "
        f"average, up to 6.8 %); crown estimated as head + {K_CROWN_H36M} (head - thorax) (estimate: 0.7 % of "
        "stature on average, up to 1.7 %)"),
    "smpl24": _recipe(
        "smpl24", _ankle_soles("smpl24", K_SOLE_SMPL, ("foot",)),
        extrapolated(_at("smpl24", "head"), _at("smpl24", *_HIPS), K_CROWN_SMPL),
        f"{_TXT_SMPL_SOLE}; crown estimated as head joint + {K_CROWN_SMPL} (head - mid-hips) (estimate: 1.1 % of "
        "stature on average, up to 2.9 %, on SMPL's own joints)"),
    "hybrik29": _recipe(
        "hybrik29", _ankle_soles("hybrik29", K_SOLE_SMPL, ("foot",)), mean_of(*_at("hybrik29", "head_top_411")),
        f"{_TXT_SMPL_SOLE}; crown = HybrIK's head-top leaf (SMPL vertex 411, 2-3.5 % of stature from the crown "
        "vertex 412)"),
}

def recipe_for(layout: str | None) -> KeypointRecipe | None:
    """The recipe of a layout (:func:`layout_key`), or None for a layout without one."""
    return LAYOUTS.get(layout_key(layout)) if layout is not None else None


def _mean_points(keypoints: np.ndarray, indices: tuple[int, ...], dims: int = 2) -> np.ndarray:
    """(P, dims) mean of the chosen points (P, K, dims [+ confidence]); NaN where any of them is missing."""
    chosen = keypoints[:, list(indices)]  # (P, n, dims or dims + 1)
    points = chosen[..., :dims].astype(np.float64)
    missing = ~np.isfinite(points).all(axis=-1)
    if chosen.shape[-1] > dims:
        missing |= ~(chosen[..., dims] > 0)
    points = points.mean(axis=1)
    points[missing.any(axis=1)] = np.nan
    return points


def rule_px(keypoints_2d: np.ndarray, rule: PointRule, dims: int = 2) -> np.ndarray:
    """(P, dims) point of ``rule`` from keypoints (P, K, 2|3) in pixels (or joints (P, K, 3) in metres with
    ``dims=3``: the same affine rule in 3D); NaN for people missing any point it reads."""
    return sum(weight * _mean_points(keypoints_2d, indices, dims) for weight, indices in rule.terms)


def _recipe_points(points: np.ndarray, recipe: KeypointRecipe, dims: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Left sole, right sole and crown (P, dims) of keypoints or joints (P, K, dims [+ confidence])."""
    return tuple(rule_px(points, rule, dims) for rule in (recipe.left_sole, recipe.right_sole, recipe.crown))


def _joints_recipe(joints_cam: np.ndarray | None, layout: str | None) -> tuple[np.ndarray, KeypointRecipe] | None:
    """Joints (P, J, 3) as float64 and their layout's recipe; None without joints, recipe or enough joints."""
    recipe = recipe_for(layout)
    if joints_cam is None or recipe is None:
        return None
    joints = np.asarray(joints_cam, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[-1] != 3 or joints.shape[1] < recipe.n_keypoints:
        return None
    return joints, recipe


def feet_heads_cam(joints_cam: np.ndarray, layout: str | None) -> tuple[np.ndarray, np.ndarray] | None:
    """Foot points (ground contact, :func:`rotavat_cli.bodies.landmarks.ground_contact`) and crowns (P, 3) of joints
    (P, J, 3) by the layout's recipe applied in 3D; None for a layout without a recipe (or fewer joints than
    the layout has)."""
    found = _joints_recipe(joints_cam, layout)
    if found is None:
        return None
    left, right, crown = _recipe_points(*found, 3)
    return ground_contact(left, right, crown), crown


def contact_weights_3d(joints_cam: np.ndarray | None, layout: str | None) -> np.ndarray | None:
    """(P, 3) each person's ground contact weights (left sole, right sole, crown;
    :func:`rotavat_cli.bodies.landmarks.contact_weights`) from 3D joints in ``layout``; the mid-sole's (0.5, 0.5, 0)
    where a person's joints give no axis; None without joints in a layout with a recipe.

    The image cannot tell a raised foot from a foot nearer the camera (a walker seen from above has its
    front foot lower in the picture with both feet down), so the 2D foot point takes the raise from the
    body, in 3D, where a raised foot is one that lies higher along the body's own axis.
    """
    found = _joints_recipe(joints_cam, layout)
    if found is None:
        return None
    weights = contact_weights(*_recipe_points(*found, 3))
    return np.where(np.isfinite(weights).all(axis=-1, keepdims=True), weights, [0.5, 0.5, 0.0])


_TXT_CONTACT = ("; foot point = ground contact: the soles' and crown's points weighted as the 3D joints' raise of the "
                "lower foot says (docs/conventions.md)")


def feet_heads_px(keypoints_2d: np.ndarray, layout: str | None, joints_cam: np.ndarray | None = None,
                  joints_layout: str | None = None) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Foot and crown pixels (P, 2) each from keypoints (P, K, 2|3) in ``layout``, and what was used.

    The foot pixel is the mid-sole; with the person's 3D joints (``joints_cam`` (P, J, 3) in
    ``joints_layout``, the same people), the ground contact: the two soles' and the crown's pixels
    weighted as in 3D (:func:`contact_weights_3d`). None when the layout has no recipe or the array is
    shorter than the layout; NaN rows for people whose recipe points are missing.
    """
    recipe = recipe_for(layout)
    keypoints = np.asarray(keypoints_2d)
    if recipe is None or keypoints.ndim != 3 or keypoints.shape[1] < recipe.n_keypoints or keypoints.shape[2] < 2:
        return None
    left, right, crown = _recipe_points(keypoints, recipe, 2)
    feet = 0.5 * (left + right)
    used = f"{layout_key(layout)}: {recipe.describes}"
    weights = contact_weights_3d(joints_cam, joints_layout)
    if weights is not None and len(weights) == len(feet):
        feet = np.einsum("pk,pkd->pd", weights, np.stack([left, right, crown], axis=1))
        used += _TXT_CONTACT
    return feet, crown, used
