"""What ``rotavat export`` can vary for whole sequences: the frame rate assumed, BVH's Euler order.

Defaults: the packaged ``configs/default.yaml``, section ``export`` (colours: section ``render``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, ClassVar

from ..settings.config import default_config, packaged_default
from ..errors import file_error
from ..settings.option_rules import Rule, check_fields
from ..sequence import Sequence

__all__ = ["ExportOptions", "FORMATS", "EULER_ORDERS", "sequence_fps"]

FORMATS = ("glb", "bvh", "amass")  # --format: one animated .glb; a BVH, or an AMASS-style .npz, per person
EULER_ORDERS = ("ZXY", "XYZ")  # BVH rotation channels, outermost first (R = R_Z R_X R_Y for ZXY)
MAX_FPS = 10_000.0  # a frame rate above this is a typo (high-speed cameras film at a few thousand)


@functools.lru_cache(maxsize=1)
def _packaged_options() -> "ExportOptions":
    """ExportOptions of the packaged ``export:`` section (read once)."""
    return ExportOptions.from_config(default_config()["export"])


@dataclass(frozen=True)
class ExportOptions:
    """Options of the animated exports (:mod:`rotavat_cli.exchange`)."""

    fps: float = packaged_default(_packaged_options, "fps")  # assumed when meta.yaml states none
    euler: str = packaged_default(_packaged_options, "euler")  # BVH channels' order

    RULES: ClassVar[dict[str, Rule]] = {"fps": Rule(low=0, open_low=True), "euler": Rule(names=EULER_ORDERS)}

    def __post_init__(self) -> None:
        check_fields(self, self.RULES)

    @classmethod
    def from_config(cls, section: dict[str, Any]) -> "ExportOptions":
        """Options from the merged ``export`` config section; ValueError naming a bad value."""
        return cls(float(section["fps"]), str(section["euler"]))


def sequence_fps(seq: Sequence, default_fps: float) -> tuple[float, str]:
    """(frames per second, where it came from): meta.yaml's ``fps``, else ``default_fps`` ('assumed').

    Raises InputError naming meta.yaml when its ``fps`` is not a positive finite number.
    """
    value = seq.meta.get("fps") if isinstance(seq.meta, dict) else None
    if value is None:
        return float(default_fps), "assumed"
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not 0 < value <= MAX_FPS:
        raise file_error(seq.path / "meta.yaml", f"key 'fps' must be a positive number of frames per second, got {value!r}")
    return float(value), "meta.yaml"
