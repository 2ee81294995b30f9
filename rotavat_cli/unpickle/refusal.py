"""Refusals of the restricted readers, and the one place where they become a one-line
:class:`~rotavat_cli.errors.InputError` naming the file.

Everything below the file level (the unpickler, the allowed builders, the budget, the torch
stand-ins, the stream readers) raises :class:`Refused` with a message that does not know the
file; :func:`unpickling_errors` adds the file's name, as it does to every way unpickling hostile or
broken bytes fails.

>>> with unpickling_errors("x.pkl"):
...     raise Refused("pickle nests too deeply")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: x.pkl: pickle nests too deeply
"""

from __future__ import annotations

import pickle
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from ..errors import InputError

__all__ = ["Refused", "MALFORMED", "shown", "unpickling_errors"]


class Refused(Exception):
    """Raised inside the restricted readers; turned into an InputError naming the file."""


def shown(value: Any) -> str:
    """A pickled value as a refusal names it, always short and on one line: a class or function by its
    name, a short number or string by its repr, anything else by its type (never its repr: a pickle
    chooses what sits where a class is expected, e.g. a dict of arrays).

    >>> shown(dict), shown(-3), shown({"x": [1, 2]}), shown("x" * 100)
    ("'dict'", '-3', 'a dict', 'a str')
    """
    name = getattr(value, "__name__", None) if isinstance(value, type) or callable(value) else None
    if isinstance(name, str) and len(name) <= 60:
        return repr(name)
    short = not isinstance(value, (str, bytes)) or len(value) <= 40
    if short and isinstance(value, (int, float, str, bytes, type(None))):
        try:
            return repr(value)
        except ValueError:  # an int of more than sys.get_int_max_str_digits() digits
            pass
    return f"a {type(value).__name__}"


# What malformed pickle bytes raise in the pure-Python unpickler and the builders it calls.
# (SystemError: a C builder that "returned NULL without setting an exception".)
MALFORMED = (pickle.UnpicklingError, ValueError, TypeError, IndexError, AttributeError, struct.error, UnicodeDecodeError,
             OverflowError, SystemError)


@contextmanager
def unpickling_errors(source: str, what: str = "") -> Iterator[None]:
    """Context: every way unpickling hostile or broken bytes fails becomes a one-line InputError naming
    ``source`` (and ``what`` was read, e.g. ``"torch archive: "``)."""
    prefix = f"{source}: {what}"
    try:
        yield
    except Refused as exc:
        raise InputError(f"{prefix}{exc}") from None
    except EOFError:
        raise InputError(f"{prefix}truncated pickle (unexpected end of data)") from None
    except RecursionError:
        raise InputError(f"{prefix}pickle nests too deeply") from None
    except MemoryError:
        raise InputError(f"{prefix}pickle needs more memory than available") from None
    except KeyError:  # the dispatch table has no entry for the byte read
        raise InputError(f"{prefix}not a readable pickle (invalid opcode)") from None
    except MALFORMED as exc:
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if len(detail) > 100:  # e.g. float() of the bytes a broken protocol-0 pickle runs into
            detail = detail[:100] + "..."
        raise InputError(f"{prefix}not a readable pickle ({detail})") from None
