"""Exception hierarchy of rotavat: one root, an exit code per class (click's pattern)."""

from __future__ import annotations

__all__ = ["RotavatError", "InputError", "DegenerateSceneError", "GateError"]


class RotavatError(Exception):
    """Root of every error rotavat reports to a user; ``exit_code`` is the CLI's status."""

    exit_code: int = 2


class InputError(RotavatError):
    """Bad input: the message names the file (and key) and the problem; exit status 2."""

    exit_code = 2


class DegenerateSceneError(RotavatError):
    """The scene cannot determine what was asked (e.g. fewer than 3 usable foot-head pairs)."""

    exit_code = 2


class GateError(RotavatError):
    """A ``--fail-if`` quality gate tripped; exit status 1."""

    exit_code = 1
