"""Readers for the files HPS methods actually write, converted into the data contract.

One module per external tool; each exports ``READERS = {"name": read_name}`` (trimesh's loader
registry) and a ``sniff(path) -> name | None`` used by :func:`detect_format`. Every reader takes the
source path and :class:`ImportOptions` and returns the same type, :class:`ImportedSequence`: contract
:class:`~rotavat_cli.sequence.Frame` objects (OpenCV camera frame, metres, float32) built one at a
time on demand from what the reader loaded, the sequence-level ``meta.yaml`` content, and (SPEC
only) a camera. :func:`import_sequence` writes them as a sequence directory; :func:`imported_sequence`
reads them as a :class:`~rotavat_cli.sequence.Sequence` without writing anything
(:mod:`rotavat_cli.formats.source`). Conventions of each tool, with the source files they were
read from, are in ``docs/formats.md``.

Frame keys written: ``vertices`` (P, V, 3) when meshes are known (given by the tool, or posed from
its SMPL parameters with ``--smpl-model``), ``faces`` when the model file gives them, ``joints``
(P, J, 3) in SMPL-24 order whenever possible (``meta.yaml`` ``import.joints_layout`` says which),
``keypoints_2d`` (P, K, 2) in original-image pixels, ``person_ids`` (P,) for tracked sources, ``boxes_2d``
(P, 4) where a tool's person boxes are its only 2D (GVHMR), and per-frame ``focal_length`` /
``principal_point`` / ``image_size`` only when they vary per frame.

Modules, from the converting down:

- :mod:`.convert`: :func:`import_sequence` (a sequence directory written), :func:`imported_sequence` (read as a
  Sequence, nothing written);
- :mod:`.source`: the frame source behind ``imported_sequence`` (each frame converted when read, worker
  processes re-reading the source from its recipe);
- :mod:`.read`: :func:`read_format` (a file opened with its format's reader), :func:`reading_errors` (what a
  reader raises said in one line naming the file, and the format the file looks like instead);
- :mod:`.registry`: ``READERS`` of every tool, :func:`available_formats`, :func:`detect_format`,
  :func:`other_format` (the tools' sniffers asked);
- the per-tool readers: :mod:`.cliff`, :mod:`.bev` (and ROMP), :mod:`.fourdhumans`, :mod:`.multihmr`, :mod:`.spec`,
  :mod:`.agora`, :mod:`.bedlam`, :mod:`.wham`, :mod:`.gvhmr`, :mod:`.tram`, :mod:`.hybrik`, :mod:`.pymafx`,
  :mod:`.slahmr`, :mod:`.glamr`, :mod:`.trace`, :mod:`.comotion`, :mod:`.prompthmr`;
- what the readers share: :mod:`.imported` (:class:`ImportOptions`, :class:`ImportedSequence`, its frame notes
  and conclusion, the warning for people not placed in the camera), :mod:`.frames` (``people_frame``: the
  contract frame of one image), :mod:`.meta` (``meta.yaml`` content), :mod:`.frame_names` (frame names from
  image names), :mod:`.content` (arrays and keys of a loaded file checked), :mod:`.ids` (64-bit ids, frame
  ranges), :mod:`.image_size` (the image size from ``--image-size``, a centred principal point or a PNG/JPEG
  header; the padded square), :mod:`.model_checks` (the body model a tool's parameters need),
  :mod:`.files` (a tool's file found), :mod:`.file_kinds` (files that are no tool's output, refused),
  :mod:`.tools` (the format names and how messages name each tool);
- :mod:`.smpl` (posing SMPL-family parameters) and :mod:`.keypoints` (foot and head pixels from each 2D
  keypoint layout);
- :mod:`.model_fit`: whether a sequence's meshes fit its own pixels (a wrong or mismatched body model, a wrong
  image size), said by ``import`` and ``calibrate``.
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".convert": ("import_sequence", "imported_sequence"),
    ".imported": ("ImportOptions", "ImportedSequence"),
    ".model_fit": ("model_fit_finding", "sequence_model_fit"),
    ".read": ("read_format", "reading_errors"),
    ".registry": ("available_formats", "detect_format", "other_format"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
