"""Ground-aware person errors, detection scores and camera errors."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ._common import CAMERA_KEYS, MM_PER_M, _unit_vector

__all__ = ["lean_deg", "root_err_mm", "stature_m", "stature_err_mm", "detection_scores",
           "normalize_by_f1", "camera_errors"]



def lean_deg(feet_cam: np.ndarray, heads_cam: np.ndarray, up_cam: np.ndarray) -> np.ndarray:
    """Angle between each foot→crown axis and world up, degrees: (P, 3) x2 -> (P,).

    0 = upright. NaN where head and foot coincide (no axis).
    """
    feet, heads = np.asarray(feet_cam, np.float64), np.asarray(heads_cam, np.float64)
    if feet.shape != heads.shape or feet.shape[-1:] != (3,):
        raise ValueError(f"feet_cam {feet.shape} and heads_cam {heads.shape} must both be (P, 3)")
    up = _unit_vector(up_cam, "up_cam")
    axis = heads - feet
    along = axis @ up
    across = np.linalg.norm(np.cross(axis, up), axis=-1)
    angle = np.degrees(np.arctan2(across, along))  # stable near 0 and 180, unlike arccos
    return np.where((along == 0.0) & (across == 0.0), np.nan, angle)


def root_err_mm(pred_root: np.ndarray, gt_root: np.ndarray) -> np.ndarray:
    """Euclidean distance between predicted and true roots, mm: (P, 3) x2 -> (P,)."""
    pred, gt = np.asarray(pred_root, np.float64), np.asarray(gt_root, np.float64)
    if pred.shape != gt.shape or pred.shape[-1:] != (3,):
        raise ValueError(f"pred_root {pred.shape} and gt_root {gt.shape} must both be (P, 3)")
    return np.linalg.norm(pred - gt, axis=-1) * MM_PER_M


def stature_m(feet: np.ndarray, heads: np.ndarray) -> np.ndarray:
    """Foot-to-crown length ‖head − foot‖, metres: (P, 3) x2 -> (P,)."""
    feet64, heads64 = np.asarray(feet, np.float64), np.asarray(heads, np.float64)
    if feet64.shape != heads64.shape or feet64.shape[-1:] != (3,):
        raise ValueError(f"feet {feet64.shape} and heads {heads64.shape} must both be (P, 3)")
    return np.linalg.norm(heads64 - feet64, axis=-1)


def stature_err_mm(
    pred_feet: np.ndarray, pred_heads: np.ndarray, gt_feet: np.ndarray, gt_heads: np.ndarray
) -> np.ndarray:
    """Absolute stature error ``|‖head−foot‖ pred − ‖head−foot‖ gt|``, mm: (P, 3) x4 -> (P,)."""
    return np.abs(stature_m(pred_feet, pred_heads) - stature_m(gt_feet, gt_heads)) * MM_PER_M


# --------------------------------------------------------------------------- detection


def detection_scores(matched: int, missed: int, false_positives: int) -> dict[str, float]:
    """Precision, recall and F1 from match counts (TP, FN, FP).

    ``f1 = TP / (TP + (FP + FN) / 2)``, the harmonic mean of precision and recall. Empty-case
    convention (rotavat's choice): a ratio with nothing to count is perfect, so no predictions
    gives precision 1, no ground truth gives recall 1, and a frame with neither gives
    precision = recall = f1 = 1 (nothing to find, nothing wrongly found). F1 is then 0
    whenever one side is empty and the other is not. agora_evaluation instead returns
    (0, 0, 0) when there is no ground truth (``compute_prf1`` in
    pixelite1201/agora_evaluation ``agora_evaluation/compute_average_error.py``) and rounds to
    2 decimals; rotavat does not round here.

    Example:
        >>> detection_scores(matched=8, missed=2, false_positives=2)
        {'precision': 0.8, 'recall': 0.8, 'f1': 0.8}
        >>> detection_scores(0, 0, 0)
        {'precision': 1.0, 'recall': 1.0, 'f1': 1.0}
    """
    counts = {"matched": matched, "missed": missed, "false_positives": false_positives}
    for name, value in counts.items():
        if int(value) != value or value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    tp, fn, fp = int(matched), int(missed), int(false_positives)
    precision = tp / (tp + fp) if tp + fp else 1.0
    recall = tp / (tp + fn) if tp + fn else 1.0
    f1 = tp / (tp + 0.5 * (fp + fn)) if tp + fp + fn else 1.0
    return {"precision": precision, "recall": recall, "f1": f1}


def normalize_by_f1(err_mm: float | np.ndarray, f1: float) -> float | np.ndarray:
    """AGORA's normalised errors: NMJE = MPJPE / F1, NMVE = PVE / F1 (mm); inf when F1 = 0.

    Source: pixelite1201/agora_evaluation, ``agora_evaluation/compute_average_error.py``
    (``error_dict['body-NMJE'] = body-MPJPE / f1``, same for NMVE, with MPJPE/MVE averaged
    over matched pairs only) and ``docs/evaluation_metric.md``. AGORA divides by F1 rounded to
    2 decimals; rotavat uses the exact F1.
    """
    if not 0.0 <= f1 <= 1.0:
        raise ValueError(f"f1 must be in [0, 1], got {f1!r}")
    err = np.asarray(err_mm, dtype=np.float64)
    out = err / f1 if f1 > 0.0 else np.where(np.isnan(err), np.nan, np.inf)
    return float(out) if out.ndim == 0 else out


# --------------------------------------------------------------------------- camera


def camera_errors(pred: Mapping[str, float], gt: Mapping[str, float]) -> dict[str, float]:
    """Camera errors, absolute and signed (pred − gt): focal/height in % of gt, angles in deg.

    pred, gt: mappings with ``focal_px``, ``pitch_deg``, ``roll_deg``, ``height_m`` (camera.yaml
    keys). Returns ``focal_pct``, ``pitch_deg``, ``roll_deg``, ``height_pct`` (absolute) and the
    same keys with ``_signed``; angle differences are wrapped to [-180, 180).

    Example:
        >>> gt = {"focal_px": 1000, "pitch_deg": 20, "roll_deg": 0, "height_m": 5}
        >>> pred = {"focal_px": 1100, "pitch_deg": 18, "roll_deg": 1, "height_m": 4.5}
        >>> errs = camera_errors(pred, gt)
        >>> {k: round(v, 9) for k, v in errs.items()}  # doctest: +NORMALIZE_WHITESPACE
        {'focal_pct': 10.0, 'focal_pct_signed': 10.0, 'pitch_deg': 2.0, 'pitch_deg_signed': -2.0,
         'roll_deg': 1.0, 'roll_deg_signed': 1.0, 'height_pct': 10.0, 'height_pct_signed': -10.0}
    """
    for side, cam in (("pred", pred), ("gt", gt)):
        missing = [key for key in CAMERA_KEYS if key not in cam]
        if missing:
            raise ValueError(f"{side} camera is missing {', '.join(missing)}")
    for key in ("focal_px", "height_m"):
        if float(gt[key]) == 0.0:
            raise ValueError(f"gt {key} is 0; a percentage error is undefined")

    def pct(key: str) -> float:
        return 100.0 * (float(pred[key]) - float(gt[key])) / float(gt[key])

    def wrapped(key: str) -> float:
        return (float(pred[key]) - float(gt[key]) + 180.0) % 360.0 - 180.0

    signed = {
        "focal_pct": pct("focal_px"),
        "pitch_deg": wrapped("pitch_deg"),
        "roll_deg": wrapped("roll_deg"),
        "height_pct": pct("height_m"),
    }
    out: dict[str, float] = {}
    for key, value in signed.items():
        out[key] = abs(value)
        out[f"{key}_signed"] = value
    return out
