"""``.npz`` archives: the one place that reads their members (declared zip sizes, ``.npy`` headers,
then the data in bounded chunks). Object members go through the restricted unpickler, or with
``objects=False`` (contract frames, ``sequence.read_frame_npz``) are refused, as numpy's
``allow_pickle=False`` would.

>>> load_npz("no/such/frame.npz")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: no/such/frame.npz: file not found
"""

from __future__ import annotations

import math
import zipfile
import zlib
from collections.abc import Iterable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import BinaryIO, NamedTuple

import numpy as np

from ..settings import limits as _limits
from ..errors import InputError
from ..settings.limits import human_bytes
from .checks import array_refusal
from .npy import read_npy_data, read_npy_header

__all__ = ["NpzArchive", "load_npz", "open_npz"]

_NPZ_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, zlib.error, NotImplementedError, RuntimeError)
_NOT_A_ZIP = "File is not a zip file"  # zipfile's BadZipFile when a file has no end-of-archive record
_NPZ_COMPRESSION = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)  # what np.savez / np.savez_compressed write


class NpzArchive:
    """An open ``.npz``: its ``.npy`` members by key (from the zip directory, nothing read yet).

    :meth:`read` reads some members with every check made first: compression method, declared
    uncompressed size (``max_file_mb``, also for the members' total), ``.npy`` header
    (``max_array_mb``, and no more data than the member declares). Members whose name does not end
    in ``.npy`` are not arrays and are ignored, as ``np.savez`` never writes them.
    """

    def __init__(self, path: Path, archive: zipfile.ZipFile) -> None:
        self.path, self._archive = path, archive
        self.members = {info.filename[:-4]: info for info in archive.infolist() if info.filename.endswith(".npy")}

    def keys(self) -> list[str]:
        return list(self.members)

    def _open(self, key: str) -> tuple[BinaryIO, zipfile.ZipInfo]:
        info = self.members[key]
        if info.compress_type not in _NPZ_COMPRESSION:
            raise InputError(f"{self.path}: member '{key}' uses an unsupported compression method "
                             f"({info.compress_type}; numpy writes stored or deflated members)")
        return self._archive.open(info), info

    def _opened(self, key: str, objects: bool, stack: ExitStack) -> _Member:
        """One member opened and its header read and checked (declared sizes, object arrays), its data not read yet.

        The stream stays open on ``stack``, positioned at the data: each member is opened, and its
        header read, once."""
        stream, info = self._open(key)
        stack.enter_context(stream)
        source, what = f"{self.path} ['{key}']", f"{self.path}: member '{key}'"
        header = read_npy_header(stream, source)
        dtype, shape, _, offset = header
        why = array_refusal(dtype, shape)
        if why is not None:
            raise InputError(f"{what} {why}")
        if dtype.hasobject and not objects:
            raise InputError(f"{what} is an object array: cannot read without pickle (only numeric arrays are allowed here)")
        limit = _limits.current().max_file_bytes
        if info.file_size > limit:
            raise InputError(f"{what} holds {human_bytes(info.file_size)} uncompressed "
                             f"(limit {human_bytes(limit)}: limits.max_file_mb)")
        nbytes = math.prod(shape) * dtype.itemsize
        if not dtype.hasobject and offset + nbytes > info.file_size:
            raise InputError(f"{source}: corrupt or truncated array (its header declares {nbytes:,} bytes of "
                             f"data, the member holds {max(0, info.file_size - offset):,})")
        return _Member(stream, info.file_size, header, source, what)

    def read(self, keys: Iterable[str] | None = None, objects: bool = True,
             total_limit: tuple[int, str] | None = None) -> dict[str, np.ndarray]:
        """The members ``keys`` (default all; absent keys are skipped) as arrays, all checked before any is read.

        total_limit: (bytes, config key) for the members' total; default ``limits.max_file_mb``.
        """
        wanted = list(self.members) if keys is None else [k for k in dict.fromkeys(keys) if k in self.members]
        limit, key_name = total_limit or (_limits.current().max_file_bytes, "limits.max_file_mb")
        try:
            with ExitStack() as stack:
                members = {key: self._opened(key, objects, stack) for key in wanted}
                total = sum(member.size for member in members.values())
                if total > limit:
                    raise InputError(f"{self.path}: members total {human_bytes(total)} uncompressed "
                                     f"(limit {human_bytes(limit)}: {key_name})")
                return {key: read_npy_data(m.stream, m.size, m.header, m.source, m.what, objects)
                        for key, m in members.items()}
        except _NPZ_ERRORS as exc:
            raise InputError(f"{self.path}: not a readable .npz file ({exc})") from None
        except OSError as exc:
            raise InputError(f"{self.path}: cannot read ({exc.strerror or exc})") from None


class _Member(NamedTuple):
    """A member opened by :meth:`NpzArchive.read`: its stream at the data, uncompressed size, header, names."""

    stream: BinaryIO
    size: int
    header: tuple[np.dtype, tuple[int, ...], bool, int]
    source: str
    what: str


@contextmanager
def open_npz(path: str | Path) -> Iterator[NpzArchive]:
    """Open an ``.npz`` (zip directory only); InputError for missing files, non-zips, broken zips."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: {'expected a .npz file' if path.exists() else 'file not found'}")
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile as exc:
        if str(exc) == _NOT_A_ZIP:  # no end-of-archive record (what zipfile.is_zipfile looks for)
            raise InputError(f"{path}: not a valid .npz file (not a zip archive)") from None
        raise InputError(f"{path}: not a readable .npz file ({exc})") from None
    except _NPZ_ERRORS as exc:
        raise InputError(f"{path}: not a readable .npz file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    with archive:
        yield NpzArchive(path, archive)


def load_npz(path: str | Path, keys: Iterable[str] | None = None, objects: bool = True,
             total_limit: tuple[int, str] | None = None) -> dict[str, np.ndarray]:
    """Read the members ``keys`` (default: all) of an ``.npz`` file, every declared size checked
    first; object arrays go through the restricted unpickler (or are refused without ``objects``).
    total_limit: as :meth:`NpzArchive.read`."""
    with open_npz(path) as npz:
        return npz.read(keys, objects, total_limit)
