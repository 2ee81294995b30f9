"""Which camera a sequence is aligned into: one rule for ``rotavat align``, batch and the Python API.

1. a camera given for this run: ``align --camera FILE``, or the camera batch's calibrate step
   just estimated (calibrate-then-align, as ``rotavat calibrate`` then ``align --camera``);
2. else the sequence's own: its ``camera.yaml``, or the camera its format carried (SPEC);
3. else the people's: calibrated from the sequence now.

Whichever it is then passes the camera gate (:mod:`.camera_gate`: an implausible calibration is
refused unless the user accepts it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from ..geometry.camera import Camera
from ..sequence import Sequence

__all__ = ["GIVEN", "CALIBRATED", "AlignCamera", "camera_for_align"]

GIVEN, CALIBRATED = "given", "calibrated"  # where the camera came from (batch reports name it)


@dataclass(frozen=True)
class AlignCamera:
    """A camera to align into, its ``fit`` block (camera.yaml's, {} when none) and its provenance.

    ``origin``: :data:`GIVEN` (a file, or the sequence's own) or :data:`CALIBRATED` (from the people,
    for this run); ``source``: what messages name (the file, or how it was estimated).
    """

    camera: Camera
    fit: dict = field(default_factory=dict)
    origin: str = GIVEN
    source: str = ""


def camera_for_align(seq: Sequence, given: AlignCamera | None,
                     calibrate: Callable[[Sequence], AlignCamera]) -> AlignCamera:
    """The camera ``seq`` is aligned into, by the module's rule; ``calibrate(seq)`` runs only when
    neither a given camera nor the sequence's own exists."""
    if given is not None:
        return given
    if seq.camera is not None:
        return AlignCamera(seq.camera, dict(seq.camera_fit or {}), GIVEN, seq.camera_label)
    return calibrate(seq)
