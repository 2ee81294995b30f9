"""A package's public names, each imported from its own module on first use (PEP 562).

Every package of rotavat lists its public names in one table, ``{".module": ("name", ...)}``, and
hands it to :func:`public_names`. Importing the package then imports none of its modules:
``rotavat --help`` loads no numpy, and ``rotavat calibrate`` loads no renderer. The first
``rotavat_cli.calibration.fit_camera`` (or ``from rotavat_cli.calibration import fit_camera``)
imports ``calibration/fit.py``, and only it.

Code inside rotavat imports from the module that defines a name, never through a package's
table, so the import graph (``tests/test_import_graph.py``) is the graph of real dependencies.

>>> getattr_, dir_, all_ = public_names("json", {".decoder": ("JSONDecodeError",)})
>>> getattr_("JSONDecodeError").__name__, all_
('JSONDecodeError', ['JSONDecodeError'])
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping


def public_names(package: str, table: Mapping[str, tuple[str, ...]]
                 ) -> tuple[Callable[[str], object], Callable[[], list[str]], list[str]]:
    """``(__getattr__, __dir__, __all__)`` for ``package`` whose public names are ``table``'s.

    ``table`` maps a module relative to ``package`` (``".fit"``) to the names it defines. A name is
    imported from its module when first asked for, then kept on the package."""
    home = {name: module for module, names in table.items() for name in names}

    def __getattr__(name: str) -> object:
        if name not in home:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(home[name], package), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(home) | set(vars(sys.modules[package])))

    return __getattr__, __dir__, sorted(home)
