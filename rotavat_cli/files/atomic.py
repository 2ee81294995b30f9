"""Atomic file writing: write to a temporary file beside the target, then rename over it.

Temporary files and staging folders are locked by their writer for their whole life
(:mod:`rotavat_cli.files.outputs`), so whatever a killed run leaves is recognised and removed by the next
write of the same output, and a live writer's never is.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from .outputs import (STAGING_OWNER, TEMP_TAG, in_own_staging, mark_output_dir, own_staging, own_temporary, release,
                      remove_stale_staging)

__all__ = ["atomic_open", "atomic_path", "atomic_write_text", "staged_directory"]


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb") -> Iterator[IO]:
    """Open a temporary file next to ``path``; on success rename it to ``path``, else delete it.

    The temporary, ``.<name>.rotavat-XXXXXXXX.tmp``, is locked until it is renamed; temporaries of
    ``path`` that killed writers left are removed first (:func:`rotavat_cli.files.outputs.remove_stale_staging`).
    """
    with _atomic(path) as (fd, _):
        with os.fdopen(fd, mode) as handle:
            yield handle


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """:func:`atomic_open` for a writer that opens its file by name (a library's file sink): the path of the
    temporary, renamed to ``path`` when the block succeeds and deleted when it fails (locked meanwhile)."""
    with _atomic(path) as (fd, tmp):
        os.close(fd)
        yield Path(tmp)


@contextlib.contextmanager
def _atomic(path: str | os.PathLike) -> Iterator[tuple[int, str]]:
    """A locked temporary beside ``path`` (descriptor, path), renamed to ``path`` after the block, else deleted."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _temporary(target)
    try:
        yield fd, tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    finally:
        release(tmp)


def _temporary(target: Path) -> tuple[int, str]:
    """A new temporary file beside ``target`` (descriptor, path), locked. In a staging folder this
    process builds there is nothing to clean and nothing to lock: the folder is removed whole."""
    options = {"prefix": f".{target.name}.{TEMP_TAG}", "suffix": ".tmp", "dir": target.parent}
    if in_own_staging(target.parent):
        return tempfile.mkstemp(**options)
    remove_stale_staging(target)
    for _ in range(100):
        fd, tmp = tempfile.mkstemp(**options)
        if own_temporary(tmp):
            return fd, tmp
        os.close(fd)  # another run's cleaner took it in the instant before our lock: make another
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
    raise OSError(f"{target}: cannot lock a temporary file beside it")


def _umask() -> int:
    """Current process umask (mkstemp creates 0600 files; published files follow the umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_open(path, "w") as handle:
        handle.write(text)


@contextlib.contextmanager
def staged_directory(path: str | os.PathLike, command: str | None = None) -> Iterator[Path]:
    """Build a whole output directory in a hidden sibling, then swap it in; on error remove it.

    A half-finished output never stands at ``path``; an existing ``path`` is replaced only once
    the new one is complete. The caller has checked that ``path`` may be replaced
    (:func:`rotavat_cli.files.outputs.check_output_dir`). With ``command``, the new folder carries
    rotavat's output marker. Staging folders left by killed runs are removed first; while this one
    is built its owner file (host, pid) stays locked, so a later run can tell when it is abandoned.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_staging(target)
    stage = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
    try:
        own_staging(stage)
        yield stage
        (stage / STAGING_OWNER).unlink()
        if command is not None:
            mark_output_dir(stage, command)
        os.chmod(stage, 0o777 & ~_umask())
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
            try:
                own_staging(old)
                os.replace(target, old / target.name)
                os.replace(stage, target)
                shutil.rmtree(old, ignore_errors=True)
            finally:
                release(old)
        else:
            os.replace(stage, target)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    finally:
        release(stage)
