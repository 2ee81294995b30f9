"""Foot (mid-sole) and head (crown) pixels from an HPS tool's own 2D keypoints.

Calibration and joint-level alignment need, per person, the pixel of the mid-sole and of the
crown (``feet_2d`` / ``heads_2d``, docs/conventions.md). Meshes give them through their landmark
vertices (:mod:`rotavat_cli.landmarks`); without a body model, an importer still has the tool's
2D keypoints, and many layouts carry the same points: OpenPose's heels and toes, LSP's top of the
head. A layout here is a recipe of named keypoints for each, and the importer passes its
layout's name to :func:`rotavat_cli.formats._common.people_frame` (``keypoints_layout=``), which
writes ``feet_2d``/``heads_2d`` and records which points were used (``meta.yaml``
``import.feet_heads_from``).

- Mid-sole: the mean of both feet's big toe, small toe and heel (the mesh landmark's own recipe,
  :data:`rotavat_cli.landmarks.SMPL`: half heel, half toes, on the underside).
- Crown: a head-top keypoint (LSP's "top of head", H36M's "head").

A person whose recipe points are missing (not finite, or zero confidence where the layout has
a third column) gets NaN for that point: calibration drops the pair, align flags the person.

>>> import numpy as np
>>> kp = np.zeros((1, 49, 2)); kp[0, [19, 20, 21, 22, 23, 24]] = [[10, 100], [12, 100], [8, 102], [20, 100], [22, 100], [18, 102]]
>>> kp[0, 38] = [15, 10]
>>> feet, heads, used = feet_heads_px(kp, "spin49")
>>> feet.tolist(), heads.tolist()
([[15.0, 100.66666666666667]], [[15.0, 10.0]])
>>> used
'spin49: mid-sole = mean of OpenPose big toes, small toes and heels; crown = LSP top of head'
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["KeypointRecipe", "LAYOUTS", "feet_heads_px", "recipe_for"]


@dataclass(frozen=True)
class KeypointRecipe:
    """Which keypoints of a layout make the mid-sole and the crown.

    ``sole``: indices averaged into the mid-sole; ``crown``: indices averaged into the crown;
    ``n_keypoints``: the layout's length (a longer array is accepted: extra points are ignored);
    ``describes``: what the recipe uses, for meta.yaml.
    """

    sole: tuple[int, ...]
    crown: tuple[int, ...]
    n_keypoints: int
    describes: str


# OpenPose BODY_25 (CMU-Perceptual-Computing-Lab/openpose, doc/02_output.md, "Pose Output Format
# (BODY_25)"): 19 LBigToe, 20 LSmallToe, 21 LHeel, 22 RBigToe, 23 RSmallToe, 24 RHeel.
_OPENPOSE_FEET = (19, 20, 21, 22, 23, 24)
_OPENPOSE_SOLE_TEXT = "mean of OpenPose big toes, small toes and heels"
# SPIN's 49 joints = OpenPose-25 + 24 extra (nkolot/SPIN constants.py JOINT_NAMES): extra 13 is
# 'Top of Head (LSP)', i.e. index 38. 4D-Humans/PHALP keep the first 19 extra (44 joints, +1 pad).
_LSP_HEAD_TOP = 25 + 13

LAYOUTS: dict[str, KeypointRecipe] = {
    "openpose25": KeypointRecipe(_OPENPOSE_FEET, (), 25, _OPENPOSE_SOLE_TEXT + "; no crown point"),
    "spin49": KeypointRecipe(_OPENPOSE_FEET, (_LSP_HEAD_TOP,), 49, _OPENPOSE_SOLE_TEXT + "; crown = LSP top of head"),
    "phalp44": KeypointRecipe(_OPENPOSE_FEET, (_LSP_HEAD_TOP,), 44, _OPENPOSE_SOLE_TEXT + "; crown = LSP top of head"),
}


def recipe_for(layout: str) -> KeypointRecipe | None:
    """The recipe of a layout name (the text before the first space: 'phalp44 (OpenPose-25 + 19 extra)'
    is 'phalp44'), or None for a layout without one."""
    return LAYOUTS.get(str(layout).split(" ", 1)[0])


def _mean_points(keypoints: np.ndarray, indices: tuple[int, ...]) -> np.ndarray:
    """(P, 2) mean of the chosen keypoints; NaN where any of them is missing (or no indices)."""
    if not indices:
        return np.full((keypoints.shape[0], 2), np.nan)
    chosen = keypoints[:, list(indices)]  # (P, n, 2 or 3)
    points = chosen[..., :2].astype(np.float64)
    missing = ~np.isfinite(points).all(axis=-1)
    if chosen.shape[-1] > 2:
        missing |= ~(chosen[..., 2] > 0)
    points = points.mean(axis=1)
    points[missing.any(axis=1)] = np.nan
    return points


def feet_heads_px(keypoints_2d: np.ndarray, layout: str) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Mid-sole and crown pixels (P, 2) each from keypoints (P, K, 2|3) in ``layout``, and what was used.

    None when the layout has no recipe or the array is shorter than the layout; NaN rows for
    people whose recipe points are missing.
    """
    recipe = recipe_for(layout)
    keypoints = np.asarray(keypoints_2d)
    if recipe is None or keypoints.ndim != 3 or keypoints.shape[1] < recipe.n_keypoints or keypoints.shape[2] < 2:
        return None
    name = str(layout).split(" ", 1)[0]
    return _mean_points(keypoints, recipe.sole), _mean_points(keypoints, recipe.crown), f"{name}: {recipe.describes}"
