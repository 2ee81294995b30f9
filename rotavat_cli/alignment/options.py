"""Every option of ``rotavat align``, validated in one place: :class:`AlignOptions`.

One field per key of the ``align`` section of ``configs/default.yaml``, named like it; the YAML is
the source of their defaults (``AlignOptions()`` is ``AlignOptions.from_config(default_config()["align"])``,
a test checks it).

>>> AlignOptions(upright="full").height_from
'frame'
>>> AlignOptions(stature_range_m=(2.0, 1.0))
Traceback (most recent call last):
...
ValueError: stature_range_m must be [low, high] with low < high, got [2.0, 1.0]
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from ..settings.config import default_config, packaged_default
from ..settings.option_rules import Rule, check_fields
from .transform import UPRIGHT

__all__ = ["HEIGHT_FROM", "AlignOptions"]

HEIGHT_FROM = ("frame", "track")  # each mesh keeps its stature, or one per person_id


@functools.lru_cache(maxsize=1)
def _packaged_options() -> "AlignOptions":
    """AlignOptions of the packaged ``align:`` section (read once)."""
    return AlignOptions.from_config(default_config()["align"])


@dataclass(frozen=True)
class AlignOptions:
    """How to align (docs: README "Align"); ValueError naming the option on a bad value."""

    upright: str = packaged_default(_packaged_options, "upright")  # paper (camera-foot-head plane) | full (true vertical)
    height_from: str = packaged_default(_packaged_options, "height_from")  # frame | track (median stature per person_id)
    jobs: int = packaged_default(_packaged_options, "jobs")  # worker processes; 0 = one per core (never more than the cores)
    stature_range_m: tuple[float, float] = packaged_default(_packaged_options, "stature_range_m")  # plausible aligned statures

    RULES: ClassVar[dict[str, Rule]] = {  # the ``align`` keys' bounds and names (rotavat_cli/settings/option_rules.py)
        "upright": Rule(names=UPRIGHT), "height_from": Rule(names=HEIGHT_FROM), "jobs": Rule(low=0),
        "stature_range_m": Rule(low=0, high=10, ordered="<", unit="m"),
    }

    def __post_init__(self) -> None:
        if not isinstance(self.jobs, int) or isinstance(self.jobs, bool):
            raise ValueError(f"jobs must be a whole number >= 0, got {self.jobs!r}")
        check_fields(self, self.RULES)
        object.__setattr__(self, "stature_range_m", tuple(float(v) for v in self.stature_range_m))

    @classmethod
    def from_config(cls, section: Mapping) -> "AlignOptions":
        """Options from a merged ``align`` config section."""
        return cls(str(section["upright"]), str(section["height_from"]), int(section["jobs"]),
                   tuple(section["stature_range_m"]))
