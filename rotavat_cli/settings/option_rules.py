"""What an option's value may be: its bounds, its names, its order, written once per option.

Each options class (``CalibrateOptions``, ``AlignOptions``, ``EvalOptions``, ``FigureOptions``,
``SynthOptions``, ``BatchOptions``, ``GridSpec``) holds a ``RULES`` table, option name -> :class:`Rule`,
and checks itself against it. The same table answers a ``--config`` file (the command line names the
file and the key) and a flag (it names the flag), and ``--help`` shows each option's range and names
from it (``rotavat_cli/cli/_common.py``). The config (:mod:`rotavat_cli.settings.config`) only loads and merges:
it checks that a file is shaped like the defaults, never what a value means.

>>> Rule(low=0.5, high=3.0, unit="m").problem(5)
'must be within 0.5..3.0 m, got 5'
>>> Rule(names=("grid", "refine")).problem("fast")
"must be one of grid, refine, got 'fast'"
>>> Rule(low=0, ordered="<").problem([2.0, 1.0])
'must be [low, high] with low < high, got [2.0, 1.0]'
>>> check_rules({"method": "fast"}, {"method": Rule(names=("grid", "refine"))})
Traceback (most recent call last):
...
ValueError: method must be one of grid, refine, got 'fast'
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Rule", "check_fields", "check_rules", "is_number", "short_repr"]

_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxstring, _SHORT.maxother = 2, 4, 40, 40
short_repr = _SHORT.repr  # a value as messages quote it: a long list or text shortened


@dataclass(frozen=True)
class Rule:
    """One option's constraint. Numbers (each item of a list) lie in ``[low, high]`` (None: open);
    a name is one of ``names``; a ``[low, high]`` pair is ordered by ``ordered`` ("<" or "<=").
    ``None`` (an option not given) passes every rule."""

    low: float | None = None
    high: float | None = None
    names: tuple[str, ...] = ()
    ordered: str = ""
    unit: str = ""
    or_number: bool = False  # a name or a number, "2000" too (synth.hps_focal: cliff | ... | 2000)
    open_low: bool = False  # low itself is refused (a positive number: low=0, open_low=True)

    def span(self) -> str:
        """The range as --help and the messages write it: ``0.5..3.0 m``, ``> 0``, ``>= 1``, ``<= 10``."""
        unit = f" {self.unit}" if self.unit else ""
        if self.high is None:
            return f"{'>' if self.open_low else '>='} {_number(self.low)}{unit}"
        if self.low is None:
            return f"<= {_number(self.high)}{unit}"
        return f"{_number(self.low)}..{_number(self.high)}{unit}"

    def problem(self, value: Any) -> str | None:
        """What is wrong with ``value`` ("must be ..., got ..."), or None when it is fine."""
        if value is None:
            return None
        if self.names:
            if isinstance(value, str) and value in self.names:
                return None
            if self.or_number and isinstance(value, str):
                value = _as_number(value)
            if not (self.or_number and is_number(value)):
                alternatives = ", ".join(self.names) + (" or a number" if self.or_number else "")
                return f"must be one of {alternatives}, got {short_repr(value)}"
        items = list(value) if isinstance(value, (list, tuple)) else [value]
        for item in items:
            if (self.low is not None or self.high is not None) and not self.names and not is_number(item):
                return f"must be a number, got {short_repr(item)}"
            if is_number(item):
                if not math.isfinite(item):
                    return f"must be finite, got {item}"
                below = self.low is not None and (item <= self.low if self.open_low else item < self.low)
                if below or (self.high is not None and item > self.high):
                    span = self.span()
                    return f"must be {'within ' if '..' in span else ''}{span}, got {short_repr(item)}"
        if self.ordered and len(items) == 2 and all(map(is_number, items)):
            lo, hi = items
            if not (lo < hi if self.ordered == "<" else lo <= hi):
                return f"must be [low, high] with low {self.ordered} high, got {list(value)}"
        return None

    def describe(self) -> str:
        """The rule for --help: ``0.5..3.0 m``, ``one of grid, refine``, ``[low < high], 0..10 m``."""
        parts = []
        if self.ordered:
            parts.append(f"low {self.ordered} high")
        if self.low is not None or self.high is not None:
            parts.append(self.span())
        return ", ".join(parts)


def check_rules(values: Mapping[str, Any], rules: Mapping[str, Rule], prefix: str = "") -> None:
    """ValueError ``"{prefix}{name} {problem}"`` for the first value of ``values`` its rule refuses."""
    for name, rule in rules.items():
        if name in values:
            problem = rule.problem(values[name])
            if problem is not None:
                raise ValueError(f"{prefix}{name} {problem}")


def check_fields(options: object, rules: Mapping[str, Rule], prefix: str = "") -> None:
    """:func:`check_rules` on the attributes of ``options`` (a dataclass) that ``rules`` names."""
    check_rules({name: getattr(options, name) for name in rules if hasattr(options, name)}, rules, prefix)


def is_number(value: Any) -> bool:
    """A real number (numpy's too), not a flag."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and type(value).__name__ != "bool_"


def _as_number(text: str) -> float | str:
    """``"2000"`` -> 2000.0 (a number given on the command line); other text unchanged."""
    try:
        return float(text)
    except ValueError:
        return text


def _number(value: float) -> str:
    """A bound as Python writes it (``0.5``, ``3.0``, ``1e-09``)."""
    return str(value)
