"""The calibration's parameter vector: named slots, the refined (internal) form, search bounds.

A parameter set is a float64 vector ``(6,)`` (or ``(Q, 6)``: Q sets, broadcast by the model) with
one slot each for the camera and the point model:

====================  =====  ==============================================================
slot                  unit   meaning
====================  =====  ==============================================================
``FOCAL``             px     focal length
``PITCH``             rad    camera pitch (+ = looking down)
``ROLL``              rad    camera roll
``HEIGHT``            m      camera centre above the ground
``DISTORTION``        1      division-model coefficient (relative displacement at the corner)
``BOX_DEPTH``         m      box top's extra distance from the camera (box-derived points)
====================  =====  ==============================================================

Code reads ``params[..., FOCAL]``, never ``params[0]``. The refinement works on the internal form
(:func:`to_internal`): the logarithm of the focal and of the height, the other slots as they are.

>>> p = param_vector(focal=800.0, pitch=0.3, roll=0.0, height=5.0)
>>> float(p[FOCAL]), float(p[HEIGHT]), SLOT_LABELS[HEIGHT]
(800.0, 5.0, 'camera height')
>>> bool(np.allclose(from_internal(to_internal(p)[None], p, np.ones(N_PARAMS, bool))[0], p))
True
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.lens import MAX_DISTORTION  # the bound a Camera's lens is held to as well

__all__ = ["FOCAL", "PITCH", "ROLL", "HEIGHT", "DISTORTION", "BOX_DEPTH", "N_PARAMS", "SLOT_LABELS", "PARAM_NAMES",
           "MODEL_NAMES", "param_vector", "slot", "describe", "to_internal", "from_internal", "param_bounds"]

FOCAL, PITCH, ROLL, HEIGHT, DISTORTION, BOX_DEPTH = range(6)
N_PARAMS = 6
SLOT_LABELS = ("focal length", "pitch", "roll", "camera height", "distortion", "box depth")  # in messages
_LOG_SLOTS = [FOCAL, HEIGHT]  # refined as their logarithm
# Report keys (CalibrationResult.std / fixed, per-frame summaries): the camera's, then the lens model's.
PARAM_NAMES = ("focal_px", "pitch_deg", "roll_deg", "height_m")
MODEL_NAMES = PARAM_NAMES + ("distortion",)


def param_vector(*, focal, pitch, roll, height, distortion=0.0, box_depth=0.0, dtype=np.float64) -> np.ndarray:
    """A ``(6,)`` vector from its named slots (``dtype=bool`` for a mask of slots)."""
    out = np.zeros(N_PARAMS, dtype)
    for index, value in ((FOCAL, focal), (PITCH, pitch), (ROLL, roll), (HEIGHT, height), (DISTORTION, distortion),
                         (BOX_DEPTH, box_depth)):
        out[index] = value
    return out


def slot(params: np.ndarray, index: int) -> np.ndarray:
    """Column ``(Q, 1)`` of one slot of ``(Q, 6)`` parameter sets (broadcasts against ``(N,)`` pairs)."""
    return params[:, index : index + 1]


def describe(params: np.ndarray) -> tuple[str, ...]:
    """Each slot of a ``(6,)`` vector in words and units, for messages (index by slot)."""
    return (f"{params[FOCAL]:.0f} px", f"{math.degrees(params[PITCH]):.1f} deg",
            f"{math.degrees(params[ROLL]):.1f} deg", f"{params[HEIGHT]:.2f} m", f"{params[DISTORTION]:+.3f}",
            f"{params[BOX_DEPTH]:.2f} m")


def to_internal(params: np.ndarray) -> np.ndarray:
    """``(..., 6)`` params -> the refined form: log focal, pitch, roll, log height, distortion, box depth."""
    internal = np.array(params, dtype=np.float64)
    internal[..., _LOG_SLOTS] = np.log(internal[..., _LOG_SLOTS])
    return internal


def from_internal(x: np.ndarray, full0: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Internal vectors of the free slots ``x (Q, n_free)`` -> params ``(Q, 6)``; fixed slots from ``full0 (6,)``."""
    internal = np.repeat(to_internal(full0)[None], len(x), axis=0)
    internal[:, free] = x
    internal[:, _LOG_SLOTS] = np.exp(internal[:, _LOG_SLOTS])
    return internal


def param_bounds(image_height_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Internal-form bounds ``(6,)`` each: focal 0.02-50 H, pitch -80..89.9 deg, roll +-45 deg, height
    0.05-1000 m, distortion +-0.5 (corner displacement over the half-diagonal), box depth -1..2 m."""
    lo = param_vector(focal=math.log(0.02 * image_height_px), pitch=np.deg2rad(-80.0), roll=np.deg2rad(-45.0),
                      height=math.log(0.05), distortion=-MAX_DISTORTION, box_depth=-1.0)
    hi = param_vector(focal=math.log(50.0 * image_height_px), pitch=np.deg2rad(89.9), roll=np.deg2rad(45.0),
                      height=math.log(1000.0), distortion=MAX_DISTORTION, box_depth=2.0)
    return lo, hi
