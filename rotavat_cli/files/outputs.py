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
- a run killed half-way leaves at most hidden staging folders and temporary files, which the next
  write of the same output removes (:func:`remove_stale_staging`): never a half-written output
  presented as complete. Each one is locked by its writer for its whole life (``flock``, which the
  kernel releases when the writer dies, zombie or not): one that can be locked is abandoned.

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

import contextlib
import errno
import json
import os
import re
import shutil
import socket
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import InputError
from ..version import WRITTEN_BY

try:
    import fcntl
except ImportError:  # not a POSIX system: no locks; staging folders fall back to their owner's pid
    fcntl = None

__all__ = ["MARKER", "TEXT_HEADER", "STAGING_OWNER", "TEMP_TAG", "check_output_dir", "check_output_file",
           "mark_output_dir", "is_rotavat_dir", "written_by_rotavat", "remove_stale_staging", "own_staging",
           "own_temporary", "release", "in_own_staging", "beside", "imported_output", "as_typed", "RRD_APPLICATION_ID"]

MARKER = ".rotavat-output"  # written into every output folder rotavat creates
RRD_APPLICATION_ID = "rotavat"  # the application id of the Rerun recordings rotavat writes (rotavat view)
TEXT_HEADER = "# written by rotavat"  # first line of the YAML files rotavat writes
STAGING_OWNER = ".rotavat-staging"  # inside a staging folder: the host and pid building it, locked by it
TEMP_TAG = "rotavat-"  # a temporary file of <name>: .<name>.rotavat-XXXXXXXX.tmp, locked by its writer
_STALE_FOREIGN_HOST_S = 24 * 3600  # an unlocked staging folder of another host is removed after a day


def beside(path: str | os.PathLike, suffix: str) -> Path:
    """The default output next to an input: ``<parent>/<name><suffix>`` (a file input: its stem).

    ``.`` and ``..`` are resolved first, so ``rotavat align --in .`` writes ``../<cwd name>_aligned``.
    """
    src = _resolved(path)
    if src.parent == src:
        raise InputError(f"{path}: no default output beside the file system root; pass --out")
    return src.with_name((src.stem if src.is_file() else src.name) + suffix)


def imported_output(src: str | os.PathLike, suffix: str) -> Path:
    """Where a command writes for an HPS tool's own output read with ``--from`` (``src``: its file or folder):
    ``<name><suffix>`` in the current folder, never into the user's data folder; relative to the current
    folder, as the user would type it.

    >>> imported_output("/data/bev/a.npz", "_camera.yaml")
    PosixPath('a_camera.yaml')
    """
    src = Path(src)
    return as_typed(Path.cwd() / ((src.stem if src.suffix and not src.is_dir() else _resolved(src).name) + suffix))


def as_typed(path: str | os.PathLike) -> Path:
    """``path`` as the user would type it: relative to the current folder when it lies below it, else as is."""
    try:
        return Path(path).relative_to(Path.cwd())
    except ValueError:
        return Path(path)


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
    info = {"written_by": WRITTEN_BY, "command": command}  # no time: reruns stay byte-identical
    Path(folder, MARKER).write_text(json.dumps(info) + "\n", encoding="utf-8")


def is_rotavat_dir(folder: str | os.PathLike) -> bool:
    """True for a folder that holds rotavat's marker (a regular file, not a link)."""
    marker = Path(folder, MARKER)
    return marker.is_file() and not marker.is_symlink()


def written_by_rotavat(path: str | os.PathLike, signature: bytes | None = None) -> bool:
    """True for a file rotavat wrote: its YAML header line, ``"written_by": "rotavat ..."`` in JSON,
    a ``<!-- written by rotavat -->`` Markdown header, a glTF whose generator is rotavat, a Rerun recording
    (.rrd) whose application id is rotavat, a file starting with ``signature``, or any file in a folder
    carrying the marker."""
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
    if head[:4] == b"RRF2":  # the store info that opens the file carries the application id
        return b"\x0a" + bytes([len(RRD_APPLICATION_ID)]) + RRD_APPLICATION_ID.encode() in head  # protobuf field 1
    if path.suffix == ".json":
        try:
            with open(path, encoding="utf-8") as handle:
                data = json.load(handle)
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(data, dict) and str(data.get("written_by", "")).startswith("rotavat")
    return False


def _glb_generator(path: Path) -> str:
    """``asset.generator`` of a binary glTF file ('' when unreadable); reads the JSON chunk only (<= 1 MB; of a
    longer one, its opening ``asset`` block)."""
    try:
        with open(path, "rb") as handle:
            header = handle.read(20)
            length = int.from_bytes(header[12:16], "little")
            if len(header) < 20 or header[16:20] != b"JSON":
                return ""
            if length > (1 << 20):  # a long animated scene: rotavat writes its "asset" block first
                found = re.match(rb'\s*\{\s*"asset"\s*:\s*(\{[^{}]*\})', handle.read(4096))
                data = {"asset": json.loads(found.group(1))} if found else {}
            else:
                data = json.loads(handle.read(length))
    except (OSError, ValueError, RecursionError):
        return ""
    asset = data.get("asset") if isinstance(data, dict) else None
    return str(asset.get("generator", "")) if isinstance(asset, dict) else ""


# ---- staging folders and temporary files: locked by their writer, removed once abandoned ----------
# The lock is an exclusive flock(2) on a file the writer opened (a staging folder's owner file, the
# temporary file itself), held for as long as the folder or file is being written. The kernel releases
# it when the writer dies, by any signal, before its parent reaps it; a pid is no proof (a zombie's pid
# answers kill(pid, 0), and pids are reused). flock belongs to the open file: forked workers would
# share it, so they close their copies at once (_forget_in_child) and the lock dies with the writer;
# they still know the staging folders they write into for it (nothing to clean or lock there).
_HELD: dict[Path, int] = {}  # folder or temporary file -> the descriptor holding its lock
_INHERITED: set[Path] = set()  # what the process that forked this one held
_OPEN_FLAGS = getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOFOLLOW", 0)


def _forget_in_child() -> None:
    """In a forked child: close the copies of the parent's locks (they must die with the parent)."""
    _INHERITED.update(_HELD)
    for fd in _HELD.values():
        with contextlib.suppress(OSError):
            os.close(fd)
    _HELD.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_in_child)


def _try_lock(fd: int) -> bool | None:
    """Take ``fd``'s exclusive lock without waiting: True; False when another open file holds it; None
    where the file system has no locks."""
    if fcntl is None:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EACCES):
            return False
        return None
    return True


def release(path: str | os.PathLike) -> None:
    """Release the lock this process holds on a staging folder or temporary file (no-op if none)."""
    fd = _HELD.pop(Path(path), None)
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)


def own_staging(folder: str | os.PathLike) -> None:
    """Claim a new staging folder for this process until :func:`release`: its owner file (this host,
    this pid, now), locked before it says anything, so a reader sees an owner only once it is locked."""
    folder = Path(folder)
    fd = os.open(folder / STAGING_OWNER, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _OPEN_FLAGS, 0o644)
    _try_lock(fd)  # no lock support (some network file systems): the owner's pid is checked instead
    _HELD[folder] = fd
    os.write(fd, f"{socket.gethostname()} {os.getpid()} {time.time():.0f}\n".encode())


def own_temporary(tmp: str | os.PathLike) -> bool:
    """Lock the temporary file ``tmp`` this process just created, until :func:`release`. False when a
    cleaner removed it in the moment before the lock (the caller makes another); the lock is taken on a
    second open file, so forked workers, which close it, never hold it."""
    tmp = Path(tmp)
    try:
        fd = os.open(tmp, os.O_RDONLY | _OPEN_FLAGS)
    except FileNotFoundError:
        return False
    if _try_lock(fd) is False:  # a cleaner holds it: it is about to be removed
        os.close(fd)
        return False
    if os.fstat(fd).st_nlink == 0:  # removed by a cleaner that held the lock before us
        os.close(fd)
        return False
    _HELD[tmp] = fd
    return True


def in_own_staging(folder: str | os.PathLike) -> bool:
    """True for a staging folder this process, or the one that forked it, is building (nothing in it
    can be another run's: it is removed whole if the run fails)."""
    folder = Path(folder)
    return folder in _HELD or folder in _INHERITED


@contextlib.contextmanager
def _abandoned(lock_file: Path) -> Iterator[bool | None]:
    """Whether the staging folder or temporary whose lock is on ``lock_file`` is abandoned, its lock
    held meanwhile: True when it could be locked, False when a live writer holds it, None where it is
    gone or locks are unsupported."""
    try:
        fd = os.open(lock_file, os.O_RDONLY | _OPEN_FLAGS)
    except OSError:
        fd, state = None, None
    else:
        state = _try_lock(fd)
        if state:  # the name must still be that file: a finished temporary was renamed over its target
            try:
                state = True if os.path.samestat(os.fstat(fd), os.lstat(lock_file)) else None
            except OSError:
                state = None
    try:
        yield state
    finally:
        if fd is not None:
            os.close(fd)


def remove_stale_staging(target: str | os.PathLike) -> list[Path]:
    """Remove rotavat's hidden staging siblings of ``target`` and temporary files of it left by killed
    runs; returns what was removed.

    Staging folders (``.<name>.partial-*``, ``.<name>.old-*``, ``.<name>.import-*``) hold an owner file
    (host, pid, time) that their run keeps locked; temporary files (``.<name>.rotavat-XXXXXXXX.tmp``)
    are locked by their writer. One rule: whatever can be locked is abandoned (its writer died: the
    kernel released the lock) and is removed. A folder of another host is removed only a day after it
    was started (network file systems may not share locks); where locks are unsupported the owner's
    process is checked instead. Folders without an owner file and files not named as rotavat names
    its temporaries are left alone (not provably rotavat's).
    """
    target = Path(target)
    removed: list[Path] = []
    if not target.parent.is_dir():
        return removed
    prefix = f".{target.name}."
    temporary = re.compile(re.escape(prefix + TEMP_TAG) + r"[a-z0-9_]{8}\.tmp")
    try:
        entries = [e for e in os.scandir(target.parent) if e.name.startswith(prefix)]
    except OSError:
        return removed
    for entry in entries:
        path = Path(entry.path)
        if entry.is_symlink() or in_own_staging(path):
            continue
        if entry.is_dir() and "-" in entry.name[len(prefix):]:
            if _remove_abandoned_staging(path):
                removed.append(path)
        elif temporary.fullmatch(entry.name) and entry.is_file():
            with _abandoned(path) as abandoned:
                if abandoned:
                    with contextlib.suppress(FileNotFoundError):
                        path.unlink()
                    removed.append(path)
    return removed


def _remove_abandoned_staging(folder: Path) -> bool:
    """Remove the staging folder ``folder`` if its run is gone (:func:`remove_stale_staging`)."""
    owner = folder / STAGING_OWNER
    if owner.is_symlink() or not owner.is_file():
        return False
    try:
        host, pid, started = owner.read_text(encoding="utf-8").split()[:3]
        pid_number, started_s = int(pid), float(started)
    except (OSError, ValueError):  # also an owner file not yet written (its run is starting)
        return False
    with _abandoned(owner) as abandoned:
        if abandoned is False:
            return False
        if host != socket.gethostname():
            stale = time.time() - started_s > _STALE_FOREIGN_HOST_S
        else:
            stale = bool(abandoned) or (abandoned is None and owner.exists() and not _alive(pid_number))
        if stale:
            shutil.rmtree(folder, ignore_errors=True)
        return stale


def _alive(pid: int) -> bool:
    """True when a process with this pid runs on this host (where locks are unsupported; a zombie is dead)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in ("Z", "X")
