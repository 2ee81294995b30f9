"""Which folders under a dataset root are sequences, and fingerprints of their inputs (for resuming)."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Iterable
from pathlib import Path

from ..errors import InputError
from ..formats.registry import READERS, available_formats, detect_format
from ..sequence import is_sequence_dir

__all__ = ["discover_sequences", "fingerprint", "frames_hint"]


def discover_sequences(root: str | Path, fmt: str | None = None, exclude: Iterable[str | Path] = ()) -> list[tuple[str, Path]]:
    """Every sequence under ``root`` as (rel, path), sorted by rel ('.' when ``root`` is one).

    Contract sequences: a folder holding ``*.npz`` frames, or sub-folders of ``*.obj`` files. With
    ``fmt`` (an importer format): a folder the importer recognises as a whole, else each file it
    recognises (rel then drops the file's suffix). Sequences are not searched inside; folders whose
    name starts with '.' or '_', and the ``exclude`` paths (the output and ground-truth roots), are skipped.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: no such directory")
    skip = {Path(p).resolve() for p in exclude}
    matches = _format_matcher(fmt) if fmt else None
    found: list[tuple[str, Path]] = []
    seen: set[Path] = set()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        here = Path(dirpath)
        real = here.resolve()
        if real in seen or real in skip:  # symlink loops; output or GT root inside ROOT
            dirnames[:] = []
            continue
        seen.add(real)
        dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "_")))
        if matches is None:
            if is_sequence_dir(here):
                found.append((_rel(here, root), here))
                dirnames[:] = []
        elif matches(here):
            found.append((_rel(here, root), here))
            dirnames[:] = []
        else:
            found += [(_rel(here / f, root, strip=True), here / f) for f in sorted(filenames)
                      if not f.startswith(".") and matches(here / f)]
    found.sort(key=lambda item: item[0])
    rels = [rel for rel, _ in found]
    clash = sorted({rel for rel in rels if rels.count(rel) > 1})
    if clash:
        raise InputError(f"{root}: two sequences would share the output folder {clash[0]} (a file and a folder of the same name?)")
    return found


def _rel(path: Path, root: Path, strip: bool = False) -> str:
    """POSIX path of ``path`` under ``root`` ('.' for root), the suffix dropped for file sequences."""
    rel = path.relative_to(root)
    return (rel.with_suffix("") if strip else rel).as_posix()



def _format_matcher(fmt: str) -> Callable[[Path], bool]:
    """path -> True when the importers detect ``fmt`` (or a sibling format of the same reader module)."""
    if fmt not in available_formats():
        raise InputError(f"unknown format '{fmt}' for --from (known: {', '.join(available_formats())})")
    family = getattr(READERS.get(fmt), "__module__", fmt)

    def matches(path: Path) -> bool:
        found = detect_format(path)
        return found is not None and (found == fmt or getattr(READERS.get(found), "__module__", found) == family)
    return matches


def fingerprint(path: str | Path, exclude: Iterable[str | Path] = ()) -> dict:
    """Files, bytes, newest mtime (ns) and a digest of every (name, size, mtime) under ``path`` (hidden skipped)."""
    path = Path(path)
    skip = {Path(p).resolve() for p in exclude}
    entries = []
    if path.is_file():
        st = path.stat()
        entries.append((path.name, st.st_size, st.st_mtime_ns))
    for dirpath, dirnames, filenames in os.walk(path, followlinks=True):
        here = Path(dirpath)
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".") and (here / d).resolve() not in skip)
        for name in sorted(filenames):
            if not name.startswith("."):
                st = (here / name).stat()
                entries.append(((here / name).relative_to(path).as_posix(), st.st_size, st.st_mtime_ns))
    digest = hashlib.sha256("".join(f"{n}\0{s}\0{m}\n" for n, s, m in entries).encode()).hexdigest()
    return {"files": len(entries), "bytes": sum(e[1] for e in entries),
            "newest_mtime_ns": max((e[2] for e in entries), default=0), "digest": digest}


def frames_hint(path: Path) -> int | None:
    """Frames of a contract sequence from its listing (None for imported sources: known after import)."""
    if not path.is_dir():
        return None
    npz = sum(1 for p in path.glob("*.npz") if not p.name.startswith("."))
    return npz or sum(1 for p in path.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))

