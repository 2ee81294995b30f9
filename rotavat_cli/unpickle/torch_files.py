"""PyTorch files (``torch.save``) read without torch and without running pickled code.

Several HPS demos save their results with ``torch.save`` (GVHMR's ``hmr4d_results.pt``) or
``np.save`` a dict of torch tensors (TRAM's ``hps_track_{k}.npy``). Both are pickles that name
torch's functions to rebuild each tensor; :class:`TensorUnpickler` is the restricted unpickler
(:mod:`rotavat_cli.unpickle.core`) plus the allow-list of those names, mapped to inert numpy
builders (:mod:`rotavat_cli.unpickle.torch_tensors`); any other global is refused, exactly as for
plain pickles. The result is plain nested containers of numpy arrays.

The layouts, read from PyTorch's own code (pytorch/pytorch @000a1a5 ``torch/serialization.py``:
``_save``, ``_legacy_save``, ``_load``, ``_legacy_load``), and checked against what torch 2.13
writes:

- **zip archive** (the default since PyTorch 1.6): ``<name>/data.pkl`` is the pickle; each storage
  is the record ``<name>/data/<key>`` (raw little-endian bytes, ``<name>/byteorder`` says otherwise
  when ``big``); ``<name>/version`` and ``.data/serialization_id`` are bookkeeping. In ``data.pkl``
  a storage is the persistent id ``('storage', storage_type, key, location, numel)``.
- **legacy stream** (``_use_new_zipfile_serialization=False``, and every storage pickled inside a
  plain pickle): pickles of the magic number ``0x1950A86A20F9469CFC6C``, protocol version 1001 and
  a ``sys_info`` dict, then the object pickle (persistent ids ``('storage', storage_type, key,
  location, numel, view_metadata)``), then the sorted list of storage keys, then per key an int64
  element count and the raw bytes. The pre-1.0 *tar* layout is refused with a message.

Every declared size is checked before anything is allocated: a storage's bytes against
``limits.max_array_mb`` and against the record (or stream) that should hold them, a tensor's
against its storage and ``limits.max_array_mb`` (:mod:`~rotavat_cli.unpickle.torch_tensors`), the
total against the pickle budget (:class:`~rotavat_cli.unpickle.checks.Budget`). Errors are one-line
:class:`~rotavat_cli.errors.InputError` that say the file is a torch archive and what was refused,
never "a bad pickle".

>>> load_torch_bytes(b"PK\\x05\\x06" + bytes(18), "empty.pt")
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: empty.pt: torch archive: no '<name>/data.pkl' record (the pickle of a torch.save archive)
"""

from __future__ import annotations

import io
import struct
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ..settings import limits as _limits
from ..errors import InputError
from ..settings.limits import human_bytes
from .checks import Budget
from .core import RestrictedUnpickler
from .expansion import check_expansion
from .refusal import Refused, unpickling_errors
from .streams import INFLATE_CHUNK, chunked, fill, read_bytes
from .torch_tensors import Builder, Storage, StorageType, check_storage_bytes, non_negative_int, resolve, torch_global

__all__ = ["MAGIC_NUMBER", "TensorUnpickler", "is_legacy_torch", "is_torch_zip", "load_blob", "load_torch",
           "load_torch_bytes"]

MAGIC_NUMBER = 0x1950A86A20F9469CFC6C  # torch/serialization.py
PROTOCOL_VERSION = 1001  # torch/serialization.py (legacy stream)
_TORCH_REFUSAL = "(only tensors, numpy arrays and builtin containers are allowed)"


# ---- unpicklers ----------------------------------------------------------------------------------
class TensorUnpickler(RestrictedUnpickler):
    """The restricted unpickler plus torch's tensor-rebuilding globals (inert numpy builders), for
    any pickle (a plain one may hold tensors: ``np.save`` of a dict of tensors). ``depth``: storages
    pickled inside storages."""

    def __init__(self, file: Any, budget: Budget | None = None, depth: int = 0) -> None:
        super().__init__(file, budget)
        self.depth = depth
        self._torch_builder: Builder | None = None

    def find_extra_global(self, module: str, name: str) -> Any:
        """torch's tensor-rebuilding globals, mapped to inert numpy builders (:mod:`.torch_tensors`)."""
        if not (isinstance(module, str) and module.startswith("torch")):
            return None
        if self._torch_builder is None:
            self._torch_builder = Builder(self.budget, self.depth, load_blob)
        return torch_global(module, name, self._torch_builder)

    def nested_unpickler(self) -> TensorUnpickler:
        return TensorUnpickler(self.raw, self.budget)

    @property
    def named_torch(self) -> bool:
        """Whether the pickle named one of torch's globals (its result may hold storages to resolve)."""
        return self._torch_builder is not None


class _TorchUnpickler(TensorUnpickler):
    """The tensor unpickler plus torch's storage persistent ids (``data.pkl``, legacy streams)."""

    def __init__(self, file: Any, budget: Budget, depth: int, storage: Any) -> None:
        super().__init__(file, budget, depth)
        self._storage = storage  # pid tuple -> Storage

    def find_class(self, module: str, name: str) -> Any:
        try:
            return super().find_class(module, name)
        except Refused:
            raise Refused(f"refused to unpickle global '{module}.{name}' {_TORCH_REFUSAL}") from None

    def persistent_load(self, pid: Any) -> Any:
        if not isinstance(pid, tuple) or not pid:
            raise Refused("malformed persistent id")
        kind = pid[0].decode("ascii", "replace") if isinstance(pid[0], bytes) else pid[0]
        if kind != "storage":
            raise Refused(f"refused persistent id '{kind}' (only storages are allowed)")
        return self._storage(pid)


def _storage_from_pid(pid: tuple, legacy: bool, registry: dict[str, Storage]) -> Storage:
    """Validate a storage persistent id; the same key gives the same storage."""
    if len(pid) != (6 if legacy else 5):
        raise Refused("malformed storage id")
    storage_type, key, _location, numel = pid[1:5]
    if legacy and pid[5] is not None:
        raise Refused("storage views of the pre-1.0 format are not supported")
    if not isinstance(storage_type, StorageType):
        raise Refused("malformed storage id (unknown storage type)")
    if isinstance(key, bytes):
        key = key.decode("ascii", "replace")
    if not isinstance(key, str):
        raise Refused("malformed storage key")
    numel = non_negative_int(numel, "storage size")
    known = registry.get(key)
    if known is not None:
        if known.nbytes != numel * storage_type.dtype.stored.itemsize:
            raise Refused(f"storage '{key}' is declared with two sizes")
        return known
    check_storage_bytes(storage_type.dtype, numel)
    registry[key] = Storage(storage_type.dtype, numel, key, storage_type.untyped)
    return registry[key]


# ---- zip archives --------------------------------------------------------------------------------
def _open_record(archive: zipfile.ZipFile, name: str, declared: int | None = None,
                 at_most: int | None = None) -> tuple[Any, int]:
    """One zip record opened for reading (inflated as it is read) and its size, the declared size
    checked (and equal to ``declared`` when given, at most ``at_most`` bytes for a small record) first."""
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise Refused(f"record '{name}' is missing") from None
    limit = _limits.current().max_file_bytes
    if info.file_size > limit:
        raise Refused(f"record '{name}' holds {human_bytes(info.file_size)} (limit {human_bytes(limit)}: "
                      "limits.max_file_mb)")
    if at_most is not None and info.file_size > at_most:
        raise Refused(f"record '{name}' holds {info.file_size:,} bytes (at most {at_most} expected)")
    if declared is not None and info.file_size != declared:
        raise Refused(f"record '{name}' holds {info.file_size:,} bytes, its storage declares {declared:,}")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise Refused(f"record '{name}' uses an unsupported compression method ({info.compress_type})")
    return archive.open(info), info.file_size


def _read_record(archive: zipfile.ZipFile, name: str, at_most: int) -> bytes:
    """A small zip record whole (see :func:`_open_record`)."""
    stream, size = _open_record(archive, name, at_most=at_most)
    with stream:
        data = stream.read()
    if len(data) != size:
        raise Refused(f"record '{name}' is truncated")
    return data


def _read_storage(archive: zipfile.ZipFile, name: str, found: Storage, stored: np.dtype,
                  budget: Budget) -> np.ndarray:
    """A storage's elements from its record, read in chunks into their array: held once, never also
    as the record's bytes (reading the record's last byte checks its CRC)."""
    stream, size = _open_record(archive, name, declared=found.nbytes)
    with stream:
        budget.add_data(size)
        data = np.empty(found.numel, stored)
        if size and fill(stream.read, data.view(np.uint8)) != size:
            raise Refused(f"record '{name}' is truncated")
    return data


def _archive_prefix(archive: zipfile.ZipFile) -> str:
    """The ``<name>`` of ``<name>/data.pkl`` (torch names the archive after the file)."""
    names = archive.namelist()
    if any(n.count("/") == 1 and n.endswith("/constants.pkl") for n in names):  # torch's _is_torchscript_zip
        raise Refused("a TorchScript model archive (torch.jit.save), not data saved with torch.save")
    pickles = [n for n in names if n.count("/") == 1 and n.endswith("/data.pkl")]
    if not pickles:
        raise Refused("no '<name>/data.pkl' record (the pickle of a torch.save archive)")
    if len(pickles) > 1:
        raise Refused(f"{len(pickles)} data.pkl records (expected one)")
    return pickles[0][:-len("/data.pkl")]


def _load_zip(data: bytes, budget: Budget, depth: int) -> Any:
    """A torch zip archive -> its object, storages read from the records as the pickle names them."""
    archive = zipfile.ZipFile(io.BytesIO(data))
    prefix = _archive_prefix(archive)
    order_record = f"{prefix}/byteorder"
    byteorder = _read_record(archive, order_record, 16) if order_record in archive.namelist() else b"little"
    if byteorder not in (b"little", b"big"):
        raise Refused(f"unknown byte order {byteorder[:16]!r}")
    registry: dict[str, Storage] = {}

    def storage(pid: tuple) -> Storage:
        found = _storage_from_pid(pid, False, registry)
        if found.data is None:
            stored = found.dtype.stored.newbyteorder(">" if byteorder == b"big" else "<")
            found.data = _read_storage(archive, f"{prefix}/data/{found.key}", found, stored, budget)
        return found

    # data.pkl is unpickled as it inflates (a deflated record can hold a gigabyte in a megabyte)
    pickled, _ = _open_record(archive, f"{prefix}/data.pkl")
    with pickled:
        stream = chunked(pickled)
        value = _TorchUnpickler(stream, budget, depth, storage).load()
        while stream.read(INFLATE_CHUNK):  # the end of the record: its CRC is checked there
            pass
    return value


# ---- legacy streams ------------------------------------------------------------------------------
def _load_legacy(data: bytes, budget: Budget, depth: int) -> Any:
    """A legacy torch stream -> its object (storages follow the object pickle, so tensors are resolved last)."""
    stream = io.BytesIO(data)

    def header() -> Any:
        return TensorUnpickler(stream, budget, depth).load()

    if header() != MAGIC_NUMBER:
        raise Refused("not a torch stream (bad magic number)")
    version = header()
    if version != PROTOCOL_VERSION:
        raise Refused(f"unsupported legacy torch protocol version {version!r}")
    sys_info = header()
    if not isinstance(sys_info, dict):
        raise Refused("malformed legacy torch header")
    order = "<" if sys_info.get("little_endian", True) else ">"
    registry: dict[str, Storage] = {}
    value = _TorchUnpickler(stream, budget, depth, lambda pid: _storage_from_pid(pid, True, registry)).load()
    keys = header()
    if not isinstance(keys, list) or not all(isinstance(k, str) for k in keys):
        raise Refused("malformed legacy torch storage list")
    for key in keys:
        if key not in registry:
            raise Refused(f"storage '{key}' is listed but never used")
        found = registry[key]
        head = stream.read(8)
        if len(head) != 8:
            raise Refused(f"truncated torch stream (storage '{key}' missing)")
        (numel,) = struct.unpack(order + "q", head)
        if numel != found.numel:
            raise Refused(f"storage '{key}' holds {numel:,} elements, its tensors declare {found.numel:,}")
        left = len(data) - stream.tell()
        if found.nbytes > left:
            raise Refused(f"truncated torch stream (storage '{key}' declares {found.nbytes:,} bytes, {left:,} follow)")
        budget.add_data(found.nbytes)
        found.data = np.frombuffer(stream.read(found.nbytes), found.dtype.stored.newbyteorder(order)).copy()
    missing = sorted(set(registry) - set(keys))
    if missing:
        raise Refused(f"storage '{missing[0]}' is used but its data is missing")
    return value


# ---- recognising torch files ---------------------------------------------------------------------
_FIRST_RECORDS = (b"data.pkl", b".format_version", b".storage_alignment", b"byteorder", b"version")


def is_torch_zip(data: bytes) -> bool:
    """True for a zip archive whose first record is one of ``torch.save``'s (``<name>/data.pkl``, or
    ``<name>/.format_version`` & co.), read from the first local header: a truncated archive, or one
    missing records, is still recognised (and reported) as a torch archive."""
    if len(data) < 30 or data[:4] != b"PK\x03\x04":
        return False
    (name_length,) = struct.unpack("<H", data[26:28])
    first = data[30:30 + name_length].split(b"/")
    return len(first) == 2 and bool(first[0]) and first[1] in _FIRST_RECORDS


def is_legacy_torch(data: bytes) -> bool:
    """True for bytes starting with the pickled legacy magic number (``torch.save(...,
    _use_new_zipfile_serialization=False)``): ``PROTO n``, a ``FRAME`` from protocol 4 on, ``LONG1``."""
    if len(data) < 4 or data[0] != 0x80 or not 2 <= data[1] <= 5:
        return False
    position = 11 if data[2] == 0x95 else 2  # FRAME + its 8-byte length
    body = MAGIC_NUMBER.to_bytes((MAGIC_NUMBER.bit_length() + 8) // 8, "little", signed=True)
    return data[position:position + 2 + len(body)] == bytes([0x8A, len(body)]) + body


def _is_tar(data: bytes) -> bool:
    return len(data) > 262 and data[257:262] == b"ustar"


def load_blob(data: bytes, budget: Budget, depth: int) -> Any:
    """A torch file's bytes (zip archive or legacy stream) -> its object, storages read (tensors of a legacy
    stream may still be deferred: :func:`~.torch_tensors.resolve`)."""
    if _is_tar(data):
        raise Refused("the pre-1.0 tar layout of torch.save is not supported (re-save with a recent PyTorch)")
    if data[:2] == b"PK":
        value = _load_zip(data, budget, depth)
    elif is_legacy_torch(data):
        value = _load_legacy(data, budget, depth)
    else:
        raise Refused("neither a torch zip archive nor a legacy torch stream")
    return value


# ---- public ------------------------------------------------------------------------------------
_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, NotImplementedError, RuntimeError, EOFError)


def load_torch_bytes(data: bytes, source: str) -> Any:
    """The object a ``torch.save`` file holds (bytes of a zip archive or a legacy stream), as plain
    containers of numpy arrays; every failure is a one-line InputError naming ``source``."""
    budget = Budget()
    try:
        with unpickling_errors(source, "torch archive: "):
            value = resolve(load_blob(data, budget, 0))
            check_expansion(value)
            return value
    except _ERRORS as exc:  # the archive around the pickle
        raise InputError(f"{source}: torch archive: corrupt ({str(exc).splitlines()[0] or type(exc).__name__})") from None


def load_torch(path: str | Path) -> Any:
    """Read a ``torch.save`` file (``.pt``/``.pth``: zip archive or legacy stream) without torch."""
    path = Path(path)
    data = read_bytes(path)
    if not data:
        raise InputError(f"{path}: empty file")
    return load_torch_bytes(data, str(path))
