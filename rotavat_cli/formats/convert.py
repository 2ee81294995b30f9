"""An HPS tool's output converted into the data contract: written as a sequence directory
(:func:`import_sequence`, ``rotavat import``) or read as a :class:`~rotavat_cli.sequence.Sequence`
without writing anything (:func:`imported_sequence`, ``--from`` on calibrate, align and eval)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..files.atomic import staged_directory
from ..errors import file_error
from ..files.outputs import check_output_dir
from ..plain import to_plain
from ..sequence import Sequence, write_camera_yaml, write_frame, write_meta
from .model_fit import fit_finding, sequence_model_fit
from .read import read_format, reading_errors
from .smpl import BodyModel
from .source import forget, open_imported

__all__ = ["import_sequence", "imported_sequence"]


def import_sequence(src: str | Path, out: str | Path, fmt: str, *, image_size: tuple[int, int] | None = None,
                    smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None,
                    video: str | None = None, progress: Callable[[], None] | None = None,
                    overwrite: bool = False, model_kind: str | None = None) -> dict:
    """Convert ``src`` (format ``fmt``) into a contract sequence directory ``out``.

    Frames are written to a staging directory beside ``out`` and swapped in whole only when every
    frame converted, so a failed import leaves ``out`` untouched. An existing ``out`` is replaced
    only when it is empty or rotavat's own output, or with ``overwrite``; never when it is, holds or
    lies inside ``src`` (:func:`rotavat_cli.files.outputs.check_output_dir`). ``progress()`` is called
    after each frame.

    Every import ends with :mod:`.model_fit`'s check, on at most a few hundred frames read back: a warning
    when the meshes do not fit the people's own 2D evidence or the image (a wrong or mismatched
    ``--smpl-model``, a wrong ``--image-size``).

    Returns a summary: out, format, frames, people, empty_frames, empty_why (why they are empty, when the reader
    says: ``import.empty_frames_why``), image_size, focal_px,
    has_vertices, joints_layout, camera_yaml, warnings, model_fit (the check's numbers).
    """
    src, out = Path(src), Path(out)
    check_output_dir(out, [src], overwrite)
    with reading_errors(src, fmt):
        imported = read_format(src, fmt, image_size=image_size, smpl_model=smpl_model, fov_deg=fov_deg, video=video,
                               model_kind=model_kind)
    with staged_directory(out, "import") as staging:
        frames = people = empty = 0
        has_vertices = False
        names = []
        with reading_errors(src, fmt):
            for frame in imported.frames:
                write_frame(staging, frame, "npz")
                names.append(frame.name)
                frames += 1
                people += frame.n_people
                empty += frame.n_people == 0
                has_vertices |= frame.n_people > 0 and frame.get("vertices") is not None
                if progress is not None:
                    progress()
        if frames == 0:
            raise file_error(src, f"no frames found for format '{fmt}'")
        meta = to_plain(dict(imported.meta))
        meta.setdefault("import", {})["warnings"] = [str(w) for w in imported.warnings]
        write_meta(staging, meta)
        if imported.camera is not None:
            write_camera_yaml(staging / "camera.yaml", imported.camera, imported.camera_fit)
        fit = sequence_model_fit(Sequence(staging, "npz", tuple(names), meta))  # meta.yaml keeps what --from reads
    finding = fit_finding(fit, str(src))
    info = meta.get("import", {})
    return {
        "out": str(out),
        "format": fmt,
        "frames": frames,
        "people": people,
        "empty_frames": empty,
        "empty_why": info.get("empty_frames_why"),  # what the reader knows of them (4D-Humans: no detection)
        "image_size": meta.get("image_size"),
        "focal_px": meta.get("focal_length"),
        "has_vertices": has_vertices,
        "joints_layout": info.get("joints_layout"),
        "camera_yaml": imported.camera is not None,
        "warnings": [*imported.warnings, *([finding] if finding else [])],
        "model_fit": fit.to_dict(),
    }


@contextlib.contextmanager
def imported_sequence(src: str | Path, fmt: str, *, read_camera: bool = True, **options: Any) -> Iterator[Sequence]:
    """Convert on the fly (``--from`` in calibrate/align/eval): ``src`` read as a Sequence whose
    frames are converted when read; no file is written.

    The sequence is named by ``src`` (its ``path``, ``origin`` and ``label``) and says form 'npz'
    (what ``align`` writes for it). Its frames, ``meta`` and camera are those ``rotavat import``
    would write and :func:`~rotavat_cli.sequence.open_sequence` read back, so every command gives
    the same results either way; ``meta['import']`` (joints layout, warnings) is complete once
    every frame was read, and ``seq.warnings`` lists what the user should hear of. ``options``:
    ``image_size``, ``smpl_model``, ``fov_deg``, ``video`` as for :func:`read_format`; ``read_camera``: include
    a camera the format carries (SPEC's: it needs every frame once). Worker processes re-read the
    source from its recipe, once each (:mod:`rotavat_cli.formats.source`); on exit this process
    forgets what it loaded.
    """
    seq = open_imported(src, fmt, read_camera=read_camera, **options)
    try:
        yield seq
    finally:
        forget(seq.frame_source.recipe)
