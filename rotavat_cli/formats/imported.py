"""What every reader takes and returns: :class:`ImportOptions` in, an :class:`ImportedSequence` out
(frame names, each frame built on demand with its :class:`FrameNotes`, the sequence-level content,
and the :class:`Conclusion` drawn from every frame's notes), and the one warning every import
concludes with: people not placed in the camera."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..geometry.camera import Camera
from ..sequence import Frame, people_not_placed
from .smpl import BodyModel

__all__ = ["Conclusion", "FrameNotes", "ImportOptions", "ImportedSequence", "conclude_placement", "placement_warnings"]


# ---- what a reader takes and returns -------------------------------------------------------
@dataclass(frozen=True)
class ImportOptions:
    """What the user told us: image size (W, H) px, a posable body model, a field of view (deg),
    which video to read of a file that holds several (HybrIK's ``res.pk``), and which body model's
    predictions to read of a folder that mixes them (AGORA's: ``smpl`` or ``smplx``)."""

    image_size: tuple[int, int] | None = None
    body_model: BodyModel | None = None
    fov_deg: float | None = None
    video: str | None = None
    model_kind: str | None = None


@dataclass
class FrameNotes:
    """What building one frame found besides the frame: its warnings (dropped people, duplicate
    ids), and facts the reader sums up over every frame (``ImportedSequence.conclude``), e.g. the
    joints layout the frame showed or its people's heights above the ground. Plain, picklable data."""

    warnings: list[str] = field(default_factory=list)
    facts: dict[str, Any] = field(default_factory=dict)


@dataclass
class Conclusion:
    """The part of an import that depends on every frame: entries of meta.yaml's ``import:`` block,
    warnings, and (SPEC) the camera."""

    import_meta: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    camera: Camera | None = None
    camera_fit: dict | None = None


@dataclass
class ImportedSequence:
    """A converted sequence: frame names, any frame built on demand, meta.yaml content, optional camera.

    ``build(i, notes)`` builds frame ``i`` from what the reader loaded (kept in its closure: the
    parsed files, never the frames) and records what it found in ``notes``; frames can be built
    in any order, again, or in another process with the same reader. ``meta`` and ``warnings``
    hold what is known before any frame is built; ``conclude`` (optional) turns the notes of
    every frame, in frame order, into the rest (:class:`Conclusion`).

    Iterating ``frames`` builds every frame in order and then completes ``warnings``, ``meta``
    and ``camera`` as ``rotavat import`` writes them: read those after the iterator is exhausted.
    """

    names: tuple[str, ...]
    build: Callable[[int, FrameNotes], Frame]
    meta: dict
    warnings: list[str] = field(default_factory=list)
    camera: Camera | None = None
    camera_fit: dict | None = None
    conclude: Callable[[list[FrameNotes]], Conclusion] | None = None
    camera_from_frames: bool = False  # the conclusion holds the camera (SPEC): reading one needs every frame

    @property
    def n_frames(self) -> int:
        return len(self.names)

    def frame_at(self, index: int) -> tuple[Frame, FrameNotes]:
        """Frame ``index`` (0-based, frame order) and what building it found, including how many of its
        people are not placed in the camera (:func:`rotavat_cli.sequence.people_not_placed`), whatever the reader."""
        notes = FrameNotes()
        frame = self.build(index, notes)
        notes.facts["unplaced"] = [int(np.logical_or(*people_not_placed(frame)).sum()), frame.n_people]
        return frame, notes

    def concluded(self, notes: list[FrameNotes]) -> Conclusion:
        """The frame-dependent part of the import from every frame's notes, in frame order: the
        reader's own (``conclude``), and one warning for the people not placed in the camera."""
        conclusion = self.conclude(notes) if self.conclude is not None else Conclusion()
        source = self.meta.get("import", {}).get("source_path", "the import")
        conclusion.warnings.extend(conclude_placement(notes, source))
        return conclusion

    def apply(self, conclusion: Conclusion) -> None:
        """Complete ``meta``, ``warnings`` and the camera with a conclusion."""
        self.meta.setdefault("import", {}).update(conclusion.import_meta)
        self.warnings.extend(conclusion.warnings)
        if conclusion.camera is not None:
            self.camera, self.camera_fit = conclusion.camera, conclusion.camera_fit

    @property
    def frames(self) -> Iterator[Frame]:
        """Every frame in order, one at a time (one pass; see the class docstring)."""
        return self._frames()

    def _frames(self) -> Iterator[Frame]:
        notes = []
        for index in range(self.n_frames):
            frame, found = self.frame_at(index)
            self.warnings.extend(found.warnings)
            notes.append(found)
            yield frame
        self.apply(self.concluded(notes))


# ---- people not placed in the camera ---------------------------------------------------------
def placement_warnings(unplaced: int, people: int, source: Any) -> list[str]:
    """The warning for ``unplaced`` of ``people`` people not placed in the camera (none when 0)."""
    if unplaced == 0:
        return []
    scope = "every person" if unplaced == people else f"{unplaced} of {people} people"
    message = (f"{source}: {scope} at the camera centre or (partly) behind the camera (z <= 0): root-centred "
               "output (no translation) or another frame, not people placed in the camera; calibrate and align "
               "cannot use them (root-aligned metrics such as MPJPE, PVE and PA-MPJPE still apply)")
    return [message]


def conclude_placement(notes: list[FrameNotes], source: Any) -> list[str]:
    """Sum every frame's ``unplaced`` fact (:meth:`ImportedSequence.frame_at`) into one warning."""
    counts = [n.facts["unplaced"] for n in notes if n.facts.get("unplaced")]
    return placement_warnings(sum(c[0] for c in counts), sum(c[1] for c in counts), source)
