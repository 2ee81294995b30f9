"""An HPS tool's own output read as a :class:`~rotavat_cli.sequence.Sequence`: each frame converted
when it is read, nothing written (``--from`` on calibrate, align and eval).

:class:`ImporterSource` is the sequence's frame source (``sequence.FrameSource``). It keeps what
the reader loaded (the parsed files, in the reader's closure), never the frames it built, so
memory stays that of the loaded source however many frames are read. Frames come out exactly as
``rotavat import`` would write and ``open_sequence`` read them back (same arrays, dtypes and
meta.yaml content), so a command gives the same results either way.

In a worker process the source is its :class:`ImportRecipe` (source path, format, image size,
body-model file, field of view, video, body-model kind): unpickling looks the recipe up in a per-process cache and reads
the source once per process on a miss (a forked worker inherits its parent's entry). What building
frames finds (warnings, facts such as SPEC's ground heights) travels back with
:meth:`ImporterSource.frame_notes` / :meth:`ImporterSource.add_frame_notes`, so the warnings reach
the user once, and ``meta['import']`` (joints layout, warnings) is complete once every frame was read.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..geometry.camera import camera_from_yaml_dict, camera_to_yaml_dict
from ..errors import file_error, input_errors
from ..plain import to_plain
from ..sequence import Frame, Sequence
from .imported import Conclusion, FrameNotes, ImportedSequence
from .read import read_format, reading_errors
from .smpl import BodyModel

__all__ = ["ImportRecipe", "ImporterSource", "open_imported", "forget", "recipe_cached"]


@dataclass(frozen=True)
class ImportRecipe:
    """What reads an HPS tool's output again the same way: source path, format and import options.

    ``smpl_model`` is the model file's path; a model given as an already loaded object is named
    by ``object:<name>:<id>`` instead (it cannot be read again: only a process holding it, or a
    fork of one, can use that recipe).
    """

    src: str
    fmt: str
    image_size: tuple[int, int] | None = None
    smpl_model: str | None = None
    fov_deg: float | None = None
    video: str | None = None
    model_kind: str | None = None

    @classmethod
    def of(cls, src: str | Path, fmt: str, image_size: tuple[int, int] | None = None,
           smpl_model: str | Path | BodyModel | None = None, fov_deg: float | None = None,
           video: str | None = None, model_kind: str | None = None) -> "ImportRecipe":
        """The recipe of these import options (as ``read_format`` takes them)."""
        if isinstance(smpl_model, BodyModel):
            model = f"object:{smpl_model.name}:{id(smpl_model)}"
        else:
            model = None if smpl_model is None else str(smpl_model)
        size = None if image_size is None else tuple(image_size)
        return cls(str(src), fmt, size, model, None if fov_deg is None else float(fov_deg), video, model_kind)

    def read(self) -> ImportedSequence:
        """Open the source with its reader (what it loads is kept; frames are built on demand)."""
        if self.smpl_model is not None and self.smpl_model.startswith("object:"):
            raise file_error(self.src, "the body model was given as an object, which this process does not hold; "
                                       "pass the model file's path instead")
        with read_errors(self):
            return read_format(self.src, self.fmt, image_size=self.image_size, smpl_model=self.smpl_model,
                               fov_deg=self.fov_deg, video=self.video, model_kind=self.model_kind)


def read_errors(recipe: ImportRecipe) -> Any:
    """Context: what malformed content raises while reading becomes a one-line InputError (as on import)."""
    return reading_errors(Path(recipe.src), recipe.fmt)


# Readers opened in this process, by recipe: a worker unpickling a source reads it once, and a
# forked worker finds its parent's. ``open_imported`` counts its users (two sequences of one recipe
# share what was loaded); ``forget`` (the end of ``imported_sequence``) drops the last one's entry.
# A worker's entries live as long as the worker.
_OPENED: dict[ImportRecipe, ImportedSequence] = {}
_USERS: dict[ImportRecipe, int] = {}
_MODELS: dict[ImportRecipe, BodyModel] = {}  # models given as objects, alive while open (their id is in the recipe)


def _opened(recipe: ImportRecipe) -> ImportedSequence:
    """The recipe's reader, read once per process."""
    if recipe not in _OPENED:
        _OPENED[recipe] = recipe.read()
    return _OPENED[recipe]


def forget(recipe: ImportRecipe) -> None:
    """One user of the recipe's reader is done; the last one drops it from this process's cache (what
    it loaded is freed with the last source over it)."""
    _USERS[recipe] = _USERS.get(recipe, 1) - 1
    if _USERS[recipe] <= 0:
        _USERS.pop(recipe, None)
        _OPENED.pop(recipe, None)
        _MODELS.pop(recipe, None)


def recipe_cached(recipe: ImportRecipe) -> bool:
    """True while this process holds the recipe's reader (what it loaded)."""
    return recipe in _OPENED


def _source_of(recipe: ImportRecipe) -> "ImporterSource":
    """Unpickling: a source over this process's reader of the recipe (read when first used)."""
    return ImporterSource(recipe)


class ImporterSource:
    """Frames of an HPS tool's output, each converted when it is read (a ``sequence.FrameSource``).

    ``meta`` is the meta.yaml content ``rotavat import`` would write: what the reader knows up
    front at once; the parts that depend on the frames (``import.joints_layout`` of some formats,
    the warnings of built frames) once every frame was built. ``warnings`` lists what the user
    should hear of, each once: the reader's, then every built frame's in frame order, then those
    that need every frame. Pickles as its recipe (see the module docstring).
    """

    def __init__(self, recipe: ImportRecipe, imported: ImportedSequence | None = None):
        self.recipe = recipe
        if imported is not None:
            self.__dict__["imported"] = imported
        self._built: set[int] = set()  # frames built here, or in a worker that said so
        self._notes: dict[int, FrameNotes] = {}  # those whose building found something
        self._conclusion: Conclusion | None = None

    def __reduce__(self) -> tuple:
        return _source_of, (self.recipe,)

    @cached_property
    def imported(self) -> ImportedSequence:
        """The reader: what it loaded and how it builds each frame (read once per process)."""
        return _opened(self.recipe)

    @cached_property
    def _index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self.imported.names)}

    @cached_property
    def _base_warnings(self) -> list[str]:
        return [str(w) for w in self.imported.warnings]

    @cached_property
    def _base_import(self) -> dict:
        return to_plain(dict(self.imported.meta.get("import") or {}))

    @cached_property
    def meta(self) -> dict:
        meta = to_plain(dict(self.imported.meta))
        meta["import"] = {}
        self.__dict__["meta"] = meta
        self._refresh_meta()
        return meta

    @property
    def meta_name(self) -> str:
        """What errors about the sequence-level metadata name."""
        return f"{self.recipe.src} (read as {self.recipe.fmt})"

    @property
    def frame_names(self) -> tuple[str, ...]:
        return self.imported.names

    def read_frame(self, name: str) -> Frame:
        """Convert one frame (validated as the contract's; arrays as an npz frame would hold them)."""
        index = self._index.get(name)
        if index is None:
            raise file_error(self.recipe.src, f"has no frame named {name}")
        frame = self._build(index)
        return Frame(frame.name, {key: np.asarray(value) for key, value in frame.data.items()}, frame.source)

    @property
    def warnings(self) -> list[str]:
        """Everything to tell the user so far, each once (see the class docstring)."""
        found = [w for i in sorted(self._notes) for w in self._notes[i].warnings]
        return self._base_warnings + found + (self._conclusion.warnings if self._conclusion else [])

    def conclusion(self) -> Conclusion:
        """The frame-dependent part of the import, building (and dropping) every frame not built yet."""
        for index in range(self.imported.n_frames):
            if index not in self._built:
                self._build(index)
        return self._conclude()

    def frame_notes(self, names: tuple[str, ...]) -> dict[int, FrameNotes]:
        """What building these frames found here (for :meth:`add_frame_notes` in the owning process)."""
        wanted = {self._index[n] for n in names if n in self._index}
        return {i: self._notes.get(i, FrameNotes()) for i in wanted & self._built}

    def add_frame_notes(self, notes: dict[int, FrameNotes]) -> None:
        """Take in what building frames found in another process."""
        for index, found in notes.items():
            self._record(index, found)

    def _build(self, index: int) -> Frame:
        with read_errors(self.recipe):
            frame, found = self.imported.frame_at(index)
        self._record(index, found)
        return frame

    def _record(self, index: int, found: FrameNotes) -> None:
        """Keep a frame's notes the first time it is built (a frame built again finds the same)."""
        if index in self._built:
            return
        self._built.add(index)
        if found.warnings or found.facts:
            self._notes[index] = found
        if len(self._built) == self.imported.n_frames:
            self._conclude()

    def _conclude(self) -> Conclusion:
        if self._conclusion is None:
            notes = [self._notes.get(i, FrameNotes()) for i in range(self.imported.n_frames)]
            self._conclusion = self.imported.concluded(notes)
            self._refresh_meta()
        return self._conclusion

    def _refresh_meta(self) -> None:
        """meta['import'] as import writes it: the reader's entries, then (every frame built) the
        concluded ones and every warning; before that, the reader's warnings only."""
        block = dict(self._base_import)
        if self._conclusion is not None:
            block.update(to_plain(self._conclusion.import_meta))
        block["warnings"] = self.warnings
        self.meta["import"].clear()
        self.meta["import"].update(block)


def open_imported(src: str | Path, fmt: str, *, read_camera: bool = True, **options: Any) -> Sequence:
    """``src`` (format ``fmt``) as a Sequence whose frames are converted when read; nothing is written.

    ``options``: ``image_size``, ``smpl_model``, ``fov_deg``, ``video``, ``model_kind`` as for ``read_format``. With
    ``read_camera`` a camera the format carries (SPEC's) is included: working it out needs every
    frame once (each built and dropped). The reader stays in this process's cache until
    :func:`forget` (``imported_sequence`` does it when its block ends).
    """
    recipe = ImportRecipe.of(src, fmt, **options)
    if recipe in _OPENED:
        imported = _OPENED[recipe]
    else:
        with read_errors(recipe):
            imported = read_format(src, fmt, **options)
        _OPENED[recipe] = imported
    _USERS[recipe] = _USERS.get(recipe, 0) + 1
    if isinstance(options.get("smpl_model"), BodyModel):
        _MODELS[recipe] = options["smpl_model"]
    try:
        return _sequence(src, fmt, ImporterSource(recipe, imported), read_camera)
    except BaseException:
        forget(recipe)
        raise


def _sequence(src: str | Path, fmt: str, source: ImporterSource, read_camera: bool) -> Sequence:
    """The Sequence over an importer source, validated as ``open_sequence`` validates a directory's."""
    if not source.frame_names:
        raise file_error(src, f"no frames found for format '{fmt}'")  # as import says it
    seq = Sequence(Path(src), "npz", source.frame_names, source.meta, origin=str(src), source=source)
    seq.intrinsics, seq.focal_kind  # validated up front, as open_sequence does
    if not read_camera:
        return seq
    camera, fit = source.imported.camera, source.imported.camera_fit
    if source.imported.camera_from_frames:
        concluded = source.conclusion()
        if concluded.camera is not None:
            camera, fit = concluded.camera, concluded.camera_fit
    if camera is None:
        return seq
    # as camera.yaml is written and read back, so that the numbers are an import's to the bit
    data = yaml.safe_load(yaml.safe_dump(camera_to_yaml_dict(camera, fit), sort_keys=False))
    with input_errors(f"{src} (camera read as {fmt})"):
        camera = camera_from_yaml_dict(data, seq.intrinsics.image_size)
    return replace(seq, camera=camera, camera_fit=data.get("fit") or {})
