"""Where rotavat may write: never over or into an input, never over anything it did not write.

The rules (README "What rotavat promises", SECURITY.md):

- an output is never an input, never inside an input folder and never a folder that holds an
  input. One documented exception: ``rotavat calibrate SEQ`` writes ``SEQ/camera.yaml`` (the
  contract's place for a sequence's camera), and only over a camera.yaml rotavat wrote;
- an existing output folder is replaced only when it is empty or rotavat's own output (it holds
  the marker file :data:`MARKER` that rotavat writes into every output folder); an existing output
  file only when rotavat wrote it (:func:`written_by_rotavat`). Anything else is an
  :class:`~rotavat_cli.errors.InputError` (exit 2) saying why, and ``--force`` replaces it anyway
  (but never an input);
- outputs are checked before any work (writable place, not an input), so a refusal costs nothing;
- a run killed half-way leaves at most hidden staging folders, which the next run removes
  (:func:`remove_stale_staging`): never a half-written output presented as complete.

Examples
--------
>>> import tempfile
>>> root = Path(tempfile.mkdtemp())
>>> (root / "seq").mkdir()
>>> check_output_dir(root / "seq" / "out", inputs=[root / "seq"])
Traceback (most recent call last):
...
rotavat_cli.errors.InputError: ...seq/out: the output would be inside the input ...seq; choose an output outside it
>>> check_output_dir(root / "seq_aligned", inputs=[root / "seq"])   # a new folder beside it: fine
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import time
from collections.abc import Iterable
from pathlib import Path

from .errors import InputError

__all__ = ["MARKER", "TEXT_HEADER", "STAGING_OWNER", "check_output_dir", "check_output_file", "mark_output_dir",
           "is_rotavat_dir", "written_by_rotavat", "remove_stale_staging", "own_staging", "beside"]

MARKER = ".rotavat-output"  # written into every output folder rotavat creates
TEXT_HEADER = "# written by rotavat"  # first line of the YAML files rotavat writes
STAGING_OWNER = ".rotavat-staging"  # inside a staging folder: the host and pid building it
_STALE_FOREIGN_HOST_S = 24 * 3600  # a staging folder of another host is removed after a day


def beside(path: str | os.PathLike, suffix: str) -> Path:
    """The default output next to an input: ``<parent>/<name><suffix>`` (a file input: its stem).

    ``.`` and ``..`` are resolved first, so ``rotavat align --in .`` writes ``../<cwd name>_aligned``.
    """
    src = _resolved(path)
    if src.parent == src:
        raise InputError(f"{path}: no default output beside the file system root; pass --out")
    return src.with_name((src.stem if src.is_file() else src.name) + suffix)


def _resolved(path: str | os.PathLike) -> Path:
    """Absolute path with symlinks resolved (the path itself need not exist)."""
    return Path(path).expanduser().resolve(strict=False)


def _relation(out: Path, inputs: Iterable[str | os.PathLike]) -> str | None:
    """Why ``out`` may not be written for these inputs, or None."""
    target = _resolved(out)
    for given in inputs:
        src = _resolved(given)
        if target == src:
            return f"the output is the input {given}"
        if src in target.parents:
            return f"the output would be inside the input {given}"
        if target in src.parents:
            return f"the output would hold the input {given}"
    return None


def _check_writable_place(path: Path) -> None:
    """The nearest existing ancestor of ``path`` must be a writable folder (checked before any work)."""
    for parent in [path.parent, *path.parent.parents]:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(f"{path}: {parent} is not a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise InputError(f"{path}: cannot write in {parent} (permission denied)")
            return


def _check_name(path: Path) -> None:
    """Each part of the path must fit the file system's name limit (a clear message, not an OSError)."""
    for part in path.parts:
        if len(os.fsencode(part)) > 255:
            raise InputError(f"{str(path)[:80]}...: a name in this path is longer than 255 bytes")


def check_output_dir(out: str | os.PathLike, inputs: Iterable[str | os.PathLike] = (), force: bool = False) -> None:
    """Raise an InputError unless the folder ``out`` may be created or replaced.

    It may not be, hold, or lie inside any of ``inputs``; if it exists it must be a folder that is
    empty or rotavat's own output (its :data:`MARKER`), unless ``force``. Its parent must be writable.
    """
    out = Path(out)
    _check_name(out)
    why = _relation(out, inputs)
    if why:
        raise InputError(f"{out}: {why}; choose an output outside it")
    if out.exists() or out.is_symlink():
        if not out.is_dir() or out.is_symlink():
            raise InputError(f"{out}: exists and is not a folder; choose another output (rotavat never replaces it)")
        if not force and any(out.iterdir()) and not is_rotavat_dir(out):
            raise InputError(f"{out}: is a folder rotavat did not write (no {MARKER}) and is not empty; choose a new "
                             "output, or pass --force to replace it")
        if not os.access(out, os.W_OK | os.X_OK):
            raise InputError(f"{out}: cannot write in it (permission denied)")
    _check_writable_place(out)


def check_output_file(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = (), force: bool = False,
                      inside_input_ok: tuple[str, ...] = (), signature: bytes | None = None) -> None:
    """Raise an InputError unless the file ``path`` may be created or replaced.

    It may not be an input or lie inside an input folder, except a file named in ``inside_input_ok``
    directly in an input folder (``calibrate``'s ``SEQ/camera.yaml``); an existing file must be one
    rotavat wrote (:func:`written_by_rotavat`, ``signature``: how the file rotavat writes there
    starts, for formats without a header, e.g. a CSV's column names), unless ``force``. Its folder
    must be writable.
    """
    path = Path(path)
    _check_name(path)
    target = _resolved(path)
    for given in inputs:
        src = _resolved(given)
        if target == src:
            raise InputError(f"{path}: the output is the input {given}; choose another output")
        if target in src.parents:
            raise InputError(f"{path}: the output would hold the input {given}; choose another output")
        if src in target.parents and not (target.parent == src and target.name in inside_input_ok):
            raise InputError(f"{path}: the output would be inside the input {given}; choose an output outside it")
    if path.exists() or path.is_symlink():
        if path.is_dir() or path.is_symlink() or not path.is_file():
            raise InputError(f"{path}: exists and is not a regular file; choose another output")
        if not force and not written_by_rotavat(path, signature):
            raise InputError(f"{path}: exists and rotavat did not write it; choose another output, or pass --force "
                             "to replace it")
    _check_writable_place(path)


def mark_output_dir(folder: str | os.PathLike, command: str) -> None:
    """Write the marker that says rotavat wrote this output folder (and may replace it later)."""
    from . import __version__

    info = {"written_by": f"rotavat {__version__}", "command": command}  # no time: reruns stay byte-identical
    Path(folder, MARKER).write_text(json.dumps(info) + "\n", encoding="utf-8")


def is_rotavat_dir(folder: str | os.PathLike) -> bool:
    """True for a folder that holds rotavat's marker (a regular file, not a link)."""
    marker = Path(folder, MARKER)
    return marker.is_file() and not marker.is_symlink()


def written_by_rotavat(path: str | os.PathLike, signature: bytes | None = None) -> bool:
    """True for a file rotavat wrote: its YAML header line, ``"written_by": "rotavat ..."`` in JSON,
    a ``<!-- written by rotavat -->`` Markdown header, a glTF whose generator is rotavat, a file
    starting with ``signature``, or any file in a folder carrying the marker."""
    path = Path(path)
    if is_rotavat_dir(path.parent):
        return True
    try:
        with open(path, "rb") as handle:
            head = handle.read(256)
    except OSError:
        return False
    if head.startswith(TEXT_HEADER.encode()) or head.startswith(b"<!-- written by rotavat"):
        return True
    if signature is not None and head.startswith(signature):
        return True
    if head[:4] == b"glTF":
        return _glb_generator(path).startswith("rotavat")
    if path.suffix == ".json":
        try:
            with open(path, encoding="utf-8") as handle:
                data = json.load(handle)
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(data, dict) and str(data.get("written_by", "")).startswith("rotavat")
    return False


def _glb_generator(path: Path) -> str:
    """``asset.generator`` of a binary glTF file ('' when unreadable); reads the JSON chunk only (<= 1 MB)."""
    try:
        with open(path, "rb") as handle:
            header = handle.read(20)
            length = int.from_bytes(header[12:16], "little")
            if len(header) < 20 or header[16:20] != b"JSON" or length > (1 << 20):
                return ""
            data = json.loads(handle.read(length))
    except (OSError, ValueError, RecursionError):
        return ""
    asset = data.get("asset") if isinstance(data, dict) else None
    return str(asset.get("generator", "")) if isinstance(asset, dict) else ""


def remove_stale_staging(target: str | os.PathLike) -> list[Path]:
    """Remove rotavat's hidden staging siblings of ``target`` left by killed runs; returns what was removed.

    A staging folder (``.<name>.partial-*``, ``.<name>.old-*``, ``.<name>.import-*``) is removed when
    its owner file names a process of this host that no longer runs, or another host more than a day
    ago. Folders without an owner file are left alone (not provably rotavat's).
    """
    target = Path(target)
    removed = []
    if not target.parent.is_dir():
        return removed
    for entry in target.parent.glob(f".{target.name}.*-*"):
        owner = entry / STAGING_OWNER
        if entry.is_symlink() or not entry.is_dir() or not owner.is_file():
            continue
        try:
            host, pid, started = owner.read_text(encoding="utf-8").split()[:3]
            stale = (not _alive(int(pid))) if host == socket.gethostname() else \
                time.time() - float(started) > _STALE_FOREIGN_HOST_S
        except (OSError, ValueError):
            continue
        if stale:
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    return removed


def own_staging(folder: str | os.PathLike) -> None:
    """Write the owner file of a staging folder (this host, this pid, now)."""
    Path(folder, STAGING_OWNER).write_text(f"{socket.gethostname()} {os.getpid()} {time.time():.0f}\n",
                                           encoding="utf-8")


def _alive(pid: int) -> bool:
    """True when a process with this pid runs on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
