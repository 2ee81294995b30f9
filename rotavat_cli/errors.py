"""Exception hierarchy of rotavat: one root, an exit code per class (click's pattern)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["RotavatError", "InputError", "DegenerateSceneError", "GateError", "TaskError", "BatchFailedError",
           "file_error", "input_errors"]


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


class TaskError(RotavatError):
    """A task of one batch sequence failed: the one-line reason (the sequence is reported failed)."""

    exit_code = 1


class BatchFailedError(RotavatError):
    """``rotavat batch`` finished, but some sequences failed (the others' outputs are complete); exit 1."""

    exit_code = 1


def file_error(source: object, message: str) -> InputError:
    """The one-line refusal of a file: ``"{source}: {message}"`` (every reader's errors start with the file).

    >>> str(file_error("scene/meta.yaml", "image_size must be [W, H]"))
    'scene/meta.yaml: image_size must be [W, H]'
    """
    return InputError(f"{source}: {message}")


@contextlib.contextmanager
def input_errors(what: object | None = None) -> Iterator[None]:
    """A ValueError raised inside (a pure function's refusal) becomes an InputError ``"{what}: {message}"``
    (the message alone when ``what`` is None: it names the option or file already).

    >>> with input_errors("--size"):
    ...     raise ValueError("must be positive")
    Traceback (most recent call last):
    ...
    rotavat_cli.errors.InputError: --size: must be positive
    """
    try:
        yield
    except ValueError as exc:
        raise InputError(str(exc) if what is None else f"{what}: {exc}") from None
