"""The one entry point for a pickled result file: a ``torch.save`` file (zip archive or legacy
stream, recognised from its first bytes) goes to the torch reader, anything else to the pickle
reader (``pickle.dump``, ``joblib.dump`` with any compression).

>>> load_file("no/such/results.pkl")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: no/such/results.pkl: file not found
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import InputError
from .pickles import load_pickle_bytes
from .streams import read_bytes
from .torch_files import is_legacy_torch, is_torch_zip, load_torch_bytes

__all__ = ["load_file"]


def load_file(path: str | Path) -> Any:
    """Unpickle a ``.pkl`` file written by ``pickle.dump`` or ``joblib.dump`` (any compression), or a
    ``torch.save`` file (zip archive or legacy stream: :func:`~.torch_files.load_torch`)."""
    path = Path(path)
    data = read_bytes(path)
    if not data:
        raise InputError(f"{path}: empty file")
    if is_torch_zip(data) or is_legacy_torch(data):
        return load_torch_bytes(data, str(path))
    return load_pickle_bytes(data, str(path))
