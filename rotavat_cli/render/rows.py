"""Rows of a figure read from sequences on disk: which frames, which camera, which intrinsics.

Which camera places a row in the world (orthographic views, GLB): the sequence's own
``camera.yaml`` (the ground truth's is the true camera, an aligned output's the camera it was
aligned with), else ``camera_path`` (``--camera``, for rows without one, e.g. a raw prediction),
else an :class:`InputError` saying to run ``rotavat calibrate`` or pass ``--camera``; whichever it is
passes the camera gate (:func:`rotavat_cli.alignment.check_fit`, in :mod:`.sequences`). The front view
uses the intrinsics the people were made with (the frame's ``focal_length``/``K``, else
``meta.yaml``), falling back to the camera's. Frames are chosen by index in the first sequence and
matched by name in the others. People are meshes, point clouds (vertices without faces) or joints
(``joints_layout`` from meta.yaml's ``import.joints_layout``, else SMPL's by count).
"""

from __future__ import annotations

import csv
import re
import shlex
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from ..geometry.camera import Camera, reexpress_cam
from ..errors import InputError, input_errors
from ..files.outputs import imported_output
from ..sequence import Frame, Sequence, read_camera_yaml
from .skeleton import layout_name
from .views import RowFrame

__all__ = ["IMAGE_MEDIA_TYPES", "IMAGE_SUFFIXES", "OWN", "GIVEN_FILE", "select_frames", "frame_names", "row_labels", "label_stem", "sequence_camera",
           "sequence_camera_fit", "sequence_layout", "frame_image_path", "no_camera", "people_flags", "read_row"]

IMAGE_MEDIA_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".bmp": "image/bmp",
                     ".webp": "image/webp"}  # the video frames --image reads, by suffix
IMAGE_SUFFIXES = tuple(IMAGE_MEDIA_TYPES)
OWN, GIVEN_FILE = "own", "given"  # where a row's camera came from: the sequence's own, or the camera.yaml given (--camera)


def select_frames(n_frames: int, frames: str | None, every: int | None) -> list[int]:
    """Frame indices from '0,10,-1' (negative = from the end) or every N-th; default the first frame."""
    if frames is not None and every is not None:
        raise ValueError("give --frames or --every, not both")
    if every is not None:
        if every < 1:
            raise ValueError(f"--every must be >= 1, got {every}")
        return list(range(0, n_frames, every))
    if frames is None:
        return [0]
    picked = []
    for part in str(frames).split(","):
        try:
            index = int(part.strip())
        except ValueError:
            raise ValueError(f"--frames must be comma-separated integers, got {frames!r}") from None
        if not -n_frames <= index < n_frames:
            raise ValueError(f"frame index {index} out of range: the sequence has {n_frames} frames")
        picked.append(index % n_frames)
    return picked


def frame_names(seq: Sequence, frames: str | None, every: int | None) -> list[str]:
    """Names of the frames :func:`select_frames` picks in ``seq``; InputError naming the sequence."""
    with input_errors(seq.label):
        return [seq.frame_names[i] for i in select_frames(len(seq), frames, every)]


def row_labels(paths: list[Path]) -> list[str]:
    """Short row labels: directory (or file) names, with their parent's name when two share a name,
    then numbered (``pred #2``) if still the same; never a whole path.

    >>> row_labels([Path("/data/a/pred"), Path("/data/b/pred"), Path("/x/gt")])
    ['a/pred', 'b/pred', 'gt']
    >>> row_labels([Path("/data/a/pred"), Path("/data/a/pred")])
    ['pred #1', 'pred #2']
    """
    names = [p.resolve().name or str(p) for p in paths]
    dup = {n for n in names if names.count(n) > 1}
    labels = [f"{p.resolve().parent.name}/{n}" if n in dup and p.resolve().parent.name else n for p, n in zip(paths, names)]
    if len(set(labels)) < len(labels):
        labels = [f"{n} #{names[:i + 1].count(n)}" if n in dup else n for i, n in enumerate(names)]
    return labels


def label_stem(label: str) -> str:
    """A row label as a name part of a file or a recording's entity path: runs of anything but letters,
    digits, '.', '_' and '-' become one '_'.

    >>> label_stem("a/pred #2"), label_stem("pred_aligned"), label_stem("///")
    ('a_pred_2', 'pred_aligned', 'row')
    """
    return re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("_") or "row"


def sequence_camera(seq: Sequence, camera_path: Path | None, own_first: bool = False) -> Camera | None:
    """The camera a sequence is drawn in: ``camera_path`` (a camera.yaml the user gave), else the
    sequence's own camera.yaml, else None. ``own_first``: the sequence's own camera wins and
    ``camera_path`` only fills in for a sequence without one (render's rows: each in its own camera)."""
    return sequence_camera_fit(seq, camera_path, own_first)[0]


def sequence_camera_fit(seq: Sequence, camera_path: Path | None,
                        own_first: bool = False) -> tuple[Camera | None, dict, str | None]:
    """:func:`sequence_camera`, with the camera's ``fit:`` block ({} when none) and where it came from:
    :data:`OWN` (the sequence's), :data:`GIVEN_FILE` (``camera_path``) or None (no camera)."""
    if seq.camera is not None and (own_first or camera_path is None):
        return seq.camera, dict(seq.camera_fit or {}), OWN
    if camera_path is not None:
        camera, fit = read_camera_yaml(camera_path, seq.image_size)
        return camera, fit, GIVEN_FILE
    return None, {}, None


def no_camera(seq: Sequence, what: str, reader_flags: tuple[str, ...] = (), rows: tuple[str, ...] = (),
              command: str = "render") -> InputError:
    """The error for a view that needs a camera the sequence does not have, naming commands that run as
    written. A folder: ``rotavat calibrate SEQ`` writes its camera.yaml. An HPS tool's output read with
    ``--from`` (``reader_flags``: ``--from FMT [--image-size W H] [--smpl-model FILE]``, as given): calibrate
    it with the same flags into ``<name>_camera.yaml`` in the current folder (never into the user's data folder:
    :func:`rotavat_cli.files.outputs.imported_output`), then render (or another ``command``: ``view``) the ``rows``
    (every SEQ, as given) with ``--camera`` that file.

    >>> print(no_camera(Sequence(Path("bev/a.npz"), "npz", ("a",), origin="bev/a.npz"), "side views",
    ...                 ("--from", "bev"), ("bev/a.npz", "b")))
    bev/a.npz: no camera for the side views: run `rotavat calibrate bev/a.npz --from bev --out a_camera.yaml`, \
then `rotavat render bev/a.npz b --from bev --camera a_camera.yaml` (your other options as before), or pass \
--camera FILE (a camera.yaml you wrote)
    """
    if seq.origin is None or not reader_flags:
        return InputError(f"{seq.path}: no camera.yaml for the {what}: run `{_join('rotavat', 'calibrate', seq.path)}` "
                          "or pass --camera camera.yaml")
    camera_file = imported_output(seq.label, "_camera.yaml")
    calibrate = _join("rotavat", "calibrate", seq.label, *reader_flags, "--out", camera_file)
    render = _join("rotavat", command, *(rows or (seq.label,)), *reader_flags, "--camera", camera_file)
    return InputError(f"{seq.label}: no camera for the {what}: run `{calibrate}`, then `{render}` (your other options "
                      "as before), or pass --camera FILE (a camera.yaml you wrote)")


def _join(*parts: object) -> str:
    """A command line, each part quoted for a POSIX shell when needed (paths with spaces)."""
    return " ".join(shlex.quote(str(p)) for p in parts)


def people_flags(seq: Sequence, warnings: list[str] | None = None) -> dict[tuple[str, int], str] | None:
    """An aligned sequence's flags from its ``people.csv`` (``rotavat align``): ``{(frame name, person_id):
    flag}``, ``""`` for the people aligned without one; None for a sequence without a people.csv (or read
    with --from). The flags only mark people, so a people.csv that cannot be read, or lacks the ``frame``,
    ``person_id`` or ``flag`` column, gives None and a line in ``warnings`` rather than an error."""
    path = Path(seq.path) / "people.csv"
    if seq.origin is not None or not path.is_file():
        return None
    flags: dict[tuple[str, int], str] = {}
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            reader = csv.DictReader(handle)
            missing = [c for c in ("frame", "person_id", "flag") if c not in (reader.fieldnames or ())]
            if missing:
                problem = f"no {', '.join(missing)} column"
            else:
                problem = ""
                for record in reader:
                    try:
                        flags[(record["frame"], int(float(record["person_id"])))] = (record["flag"] or "").strip()
                    except (TypeError, ValueError):
                        continue  # a row without a person id names nobody
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        problem = f"unreadable ({exc})"
    if problem:
        if warnings is not None:
            warnings.append(f"{path}: {problem}: no person is marked as flagged")
        return None
    return flags


def frame_image_path(image_dir: Path, name: str) -> Path:
    """The video frame of frame ``name``: ``image_dir/<name>.<png|jpg|...>`` (:data:`IMAGE_SUFFIXES`, the
    first in name order); InputError when there is none (images are matched to frames by name)."""
    for path in sorted(image_dir.glob(f"{name}.*")):
        if path.suffix.lower() in IMAGE_SUFFIXES and path.is_file():
            return path
    raise InputError(f"{image_dir}: no image named {name}.png/.jpg (images are matched to frames by name)")


def _frame_image(image_dir: Path, name: str) -> np.ndarray:
    """The video frame :func:`frame_image_path` finds, as (H, W, 3) uint8."""
    path = frame_image_path(image_dir, name)
    try:
        with Image.open(path) as img:
            return np.asarray(img.convert("RGB"))
    except (OSError, UnidentifiedImageError) as exc:
        raise InputError(f"{path}: not a readable image ({exc})") from None


def sequence_layout(seq: Sequence, n_joints: int) -> str | None:
    """The layout of a sequence's ``n_joints`` joints: meta.yaml's ``import.joints_layout``, else SMPL's by count."""
    return layout_name(seq.joints_layout, n_joints)


def read_row(seq: Sequence, name: str, label: str, camera: Camera | None, image_dir: Path | None = None,
             flags: Mapping[tuple[str, int], str] | None = None, frame: Frame | None = None) -> RowFrame:
    """One row of a figure: frame ``name`` of ``seq`` with its intrinsics, camera and video frame.

    People are drawn from their meshes (``vertices`` + ``faces``), their vertices alone (a point
    cloud) or their ``joints`` (a skeleton); a frame with people but neither is refused. ``flags``
    (:func:`people_flags`) gives each person its flag by frame name and ``person_id`` ("" when absent).
    ``frame``: that frame when the caller has read it already.
    """
    if name not in seq.frame_names:
        raise InputError(f"{seq.path}: has no frame named {name} (frames are matched by name across sequences)")
    frame = seq.read_frame(name) if frame is None else frame
    verts, faces, joints = frame.get("vertices"), frame.get("faces"), frame.get("joints")
    if frame.n_people and verts is None and joints is None:
        raise InputError(f"{frame.source}: neither 'vertices' nor 'joints': nothing to draw")
    intr = seq.frame_intrinsics(frame)
    size = intr.image_size or (camera.image_size if camera else None)
    focals = intr.focals_px(frame.n_people)
    focal = float(np.median(focals)) if focals is not None and len(focals) else (intr.focal_px or (camera.focal_px if camera else None))
    if size is None or focal is None:
        raise InputError(f"{frame.source}: unknown {'image size' if size is None else 'focal length'} for the front view: "
                         "add image_size and focal_length to meta.yaml or pass --camera")
    pp = intr.principal_point or (camera.principal_point if camera and camera.image_size == size else (size[0] / 2, size[1] / 2))
    if focals is not None and frame.n_people and np.any(focals != focal):
        # one focal per person (HybrIK): the front view shows each body re-expressed in one camera
        roots = (verts if verts is not None else joints).mean(axis=1)
        verts = None if verts is None else reexpress_cam(verts, roots, focals, pp, focal, pp).astype(verts.dtype)
        joints = None if joints is None else reexpress_cam(joints, roots, focals, pp, focal, pp).astype(joints.dtype)
    image = _frame_image(image_dir, name) if image_dir is not None else None
    P = frame.n_people
    layout = sequence_layout(seq, joints.shape[1]) if joints is not None else None
    row_flags = None if flags is None else tuple(flags.get((name, int(pid)), "") for pid in frame.person_ids)
    return RowFrame(label, np.zeros((P, 0, 3)) if verts is None else verts,
                    np.zeros((0, 3), np.int64) if faces is None else faces, frame.person_ids,
                    size, float(focal), pp, camera, image, joints, layout, flags=row_flags, lens=seq.image_lens)
