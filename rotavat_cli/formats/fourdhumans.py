"""4D-Humans tracking results: the PHALP ``.pkl`` (``joblib.dump`` of ``final_visuals_dic``).

Source: brjathu/PHALP ``phalp/trackers/PHALP.py`` (``track``: ``final_visuals_dic``,
``get_human_features``), ``phalp/models/hmar/hmar.py`` (``get_3d_parameters``),
``phalp/configs/base.py`` (``EXTRA.FOCAL_LENGTH = 5000``, ``render.res = 256``),
``phalp/utils/smpl_utils.py`` (joint order); shubham-goel/4D-Humans ``track.py`` (HMR 2.0 inside
PHALP: ``HMR2_4dhuman``).

- File: a dict ``{frame path: {...}}``; per frame ``time`` (index), and per-track lists
  ``tid``, ``tracked_time`` (0 = detected in this frame; other entries repeat a track's last
  detection and are skipped here), ``smpl`` (dicts ``global_orient`` (1, 3, 3), ``body_pose``
  (23, 3, 3) rotation matrices, ``betas`` (10,)), ``camera`` (3,) translation, ``3d_joints``
  (45, 3) (25 OpenPose + 19 extra + 1 zero row, *without* the translation), ``2d_joints`` (90,)
  normalized by the padded square, ``size`` [H, W], ``bbox``, ``conf``.
- Frame: ``smpl(...) + camera`` is the camera frame: OpenCV axes, metres.
- Focal: PHALP places the image in a centred zero-padded square of side S = max(W, H), seen at
  ``render.res`` = 256 px with f = 5000 px: f = 5000 * S / 256 on the original image (the method's
  own large focal length, ~ a 3 degree field of view); principal point = padded-square centre,
  ``(S/2 - left, S/2 - top)``.
- 2D: ``2d_joints * S - (left, top)`` are original-image pixels.
- Meshes: parameters only; vertices need ``--smpl-model`` (SMPL). Without it, joints are the
  file's 44 joints (OpenPose-25 + 19 extra, pelvis = index 8).
- Empty frames say why (meta.yaml ``import.empty_frames_why``, the import's summary line): PHALP
  detected no one there, or only carried tracks on (``tracked_time`` > 0 for each: their last state
  repeated, not a detection, so not imported).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.dispatch import load_file
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .image_size import padded_square
from .imported import Conclusion, FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import check_model_kind, model_faces, no_model_warning
from .row_blocks import RowBlocks, frame_offsets, posing_block_rows
from .smpl import lbs, smpl_param_arrays

_KEYPOINTS_LAYOUT = "phalp44 (OpenPose-25 + 19 extra)"


def sniff(path: Path) -> str | None:
    """'4dhumans' for a pickle whose values are PHALP frame dicts."""
    if not (path.is_file() and path.suffix == ".pkl") or path.stat().st_size > 512 << 20:
        return None
    data = load_file(path)
    if isinstance(data, Mapping) and data:
        first = next(iter(data.values()))
        if isinstance(first, Mapping) and "tid" in first and ("camera" in first or "smpl" in first):
            return "4dhumans"
    return None


def _frame_order(data: Mapping, source: Path) -> list[str]:
    """Frame keys sorted by PHALP's ``time`` (then key)."""
    for key, value in data.items():
        if not isinstance(value, Mapping):
            raise file_error(source, f"frame {key!r} is not a dict")
    return sorted(data, key=lambda k: (data[k].get("time", 0) if isinstance(data[k].get("time", 0), (int, np.integer)) else 0, str(k)))


def _detections(frame: Mapping, source: str) -> list[int]:
    """The indices of a frame's per-track lists detected there (``tracked_time`` 0): PHALP repeats a track's last
    state, not a detection, where ``tracked_time`` > 0."""
    tids = list(get(frame, "tid", source))
    tracked = frame.get("tracked_time")
    tracked = [0] * len(tids) if tracked is None else list(tracked)
    if len(tracked) != len(tids):
        raise file_error(source, "'tracked_time' and 'tid' differ in length")
    return [i for i, t in enumerate(tracked) if t == 0]


def _camera(frame: Mapping, i: int, source: str) -> np.ndarray:
    """(3,) detection ``i``'s ``camera``: SMPL's translation in the camera frame (metres)."""
    return as_array(frame["camera"][i], "camera", source).reshape(3)


def _image_size(data: Mapping, order: list[str], opts: ImportOptions, source: Path, warnings: list[str]) -> tuple[int, int]:
    """[H, W] from the first track's 'size', or --image-size."""
    stored = None
    for key in order:
        sizes = data[key].get("size") or []
        if len(sizes):
            h, w = (int(v) for v in np.asarray(sizes[0]).reshape(-1)[:2])
            stored = (w, h)
            break
    if opts.image_size is not None:
        if stored is not None and stored != opts.image_size:
            warnings.append(f"{source}: --image-size {opts.image_size[0]}x{opts.image_size[1]} differs from the "
                            f"stored {stored[0]}x{stored[1]}; using --image-size")
        return opts.image_size
    if stored is None:
        raise file_error(source, "no 'size' stored (no detections); pass --image-size W H")
    return stored


def read_fourdhumans(src: Path, opts: ImportOptions) -> ImportedSequence:
    """PHALP / 4D-Humans tracking .pkl -> contract frames."""
    data = load_file(src)
    if not isinstance(data, Mapping) or not data:
        raise file_error(src, "not a PHALP results file (expected a non-empty dict of frames)")
    order = _frame_order(data, src)
    warnings: list[str] = []
    image_size = _image_size(data, order, opts, src, warnings)
    side, left, top = padded_square(image_size)
    focal = focal_from_rule("4dhumans", image_size)  # 5000 px on the 256 px square = 5000 / 256 * S
    principal_point = (side / 2.0 - left, side / 2.0 - top)
    model = opts.body_model
    if model is None:
        warnings.append(no_model_warning("4D-Humans/PHALP"))
    check_model_kind(model, src, "4D-Humans", "smpl")

    def people(frame: Mapping, source: str, keep: list[int]) -> dict[str, Any]:
        """A frame's detections ``keep`` (indices into its per-track lists): ids, 2D keypoints and, without a model,
        the file's joints (with a model the table's blocks pose them)."""
        n = len(keep)
        tids = list(get(frame, "tid", source))
        out: dict[str, Any] = {"person_ids": np.asarray([tids[i] for i in keep], dtype=np.int64)}
        kp = [as_array(frame["2d_joints"][i], "2d_joints", source).reshape(-1, 2) for i in keep] if "2d_joints" in frame else []
        out["keypoints_2d"] = (np.stack(kp)[:, :44] * side - np.array([left, top])) if n and kp else None
        if model is None:
            cams = np.stack([_camera(frame, i, source) for i in keep]) if n else np.zeros((0, 3))
            j3d = [as_array(frame["3d_joints"][i], "3d_joints", source, ndim=2, last=(3,)) for i in keep]
            out["joints"] = np.stack(j3d)[:, :44] + cams[:, None] if n else np.zeros((0, 44, 3))
        return out

    names = frame_names([Path(str(k)).stem for k in order], warnings)
    sources = [f"{src} [{key}]" for key in order]
    kept = [_detections(data[key], source) for key, source in zip(order, sources)]  # tracked_time == 0
    table = [(index, i) for index, keep in enumerate(kept) for i in keep]  # (frame, detection), frame by frame
    offsets = frame_offsets([len(keep) for keep in kept])

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the table posed at once (frames posed in batches, not one by one)."""
        picks = [(data[order[index]], i, sources[index]) for index, i in table[start:stop]]
        cams = np.stack([_camera(frame, i, source) for frame, i, source in picks]) if picks else np.zeros((0, 3))
        smpl = [(get(frame, "smpl", source)[i], source) for frame, i, source in picks]
        rot = np.stack([np.concatenate([as_array(get(s, "global_orient", source), "global_orient", source).reshape(1, 3, 3),
                                        as_array(get(s, "body_pose", source), "body_pose", source).reshape(23, 3, 3)])
                        for s, source in smpl]) if picks else np.zeros((0, 24, 3, 3))
        betas = np.stack([as_array(get(s, "betas", source), "betas", source).reshape(-1) for s, source in smpl]) \
            if picks else np.zeros((0, 10))
        vertices, joints = lbs(model, betas, rot, cams)
        return {"vertices": vertices, "joints": joints, **smpl_param_arrays(model, betas, rot, cams, joints)}

    posed_rows = None if model is None else RowBlocks(len(table), posed, posing_block_rows(model))

    def build(index: int, notes: FrameNotes) -> Frame:
        key, source = order[index], sources[index]
        p = people(data[key], source, kept[index])
        if not len(p["person_ids"]):  # why nobody: only tracks carried on without a detection, or no track at all
            notes.facts["empty"] = "carried" if len(data[key].get("tid") or ()) else "none"
        verts = params = None
        if posed_rows is not None:  # posed a block of rows at a time (one block kept: memory stays flat)
            start, stop = int(offsets[index]), int(offsets[index + 1])
            params = posed_rows.rows(start, stop)
            verts, p["joints"] = params.pop("vertices"), params.pop("joints")
        return people_frame(names[index], source, notes.warnings, vertices=verts, joints=p["joints"],
                            keypoints_2d=p["keypoints_2d"], person_ids=p["person_ids"],
                            faces=model_faces(model, None if verts is None else verts.shape[1]),
                            n_verts=None if model is None else model.n_verts, keypoints_layout=_KEYPOINTS_LAYOUT,
                            joints_layout=_KEYPOINTS_LAYOUT if model is None else "smpl24", body_params=params)

    meta = base_meta("4dhumans", src, opts, image_size, focal, principal_point, focal_kind=ASSUMED, focal_rule="4dhumans")
    meta["import"].update({
        "source_frames": [Path(str(k)).name for k in order],
        "image_size_from": "--image-size" if opts.image_size else "PHALP 'size'",
        "joints_layout": "smpl24" if model is not None else "phalp44 (OpenPose-25 + 19 extra)",
        "root_joint": 0 if model is not None else 8,
        "keypoints_2d_layout": _KEYPOINTS_LAYOUT,
        "feet_heads_from": feet_heads_from(_KEYPOINTS_LAYOUT, model is not None),
        "conventions": f"camera frame = OpenCV, metres; vertices = SMPL(smpl) + camera; focal = 5000 * S / 256 "
                       f"(S = {side}); only detections with tracked_time == 0",
    })
    def conclude(notes: list[FrameNotes]) -> Conclusion:
        why = _empty_frames_why([(name, n.facts.get("empty")) for name, n in zip(names, notes)])
        return Conclusion({"empty_frames_why": why} if why else {})

    return ImportedSequence(tuple(names), build, meta, warnings, conclude=conclude)


def _empty_frames_why(reasons: list[tuple[str, str | None]]) -> str | None:
    """Why frames are empty, from each frame's (name, reason: 'carried', 'none' or None for a frame with people):
    '2 with only tracks PHALP carried on, no detection (tracked_time > 0: not imported; first 000003)'."""
    parts = []
    for reason, words in (("carried", "with only tracks PHALP carried on, no detection (tracked_time > 0: their "
                                      "last state repeated, not imported"),
                          ("none", "where PHALP found no one (no track")):
        found = [name for name, why in reasons if why == reason]
        if found:
            parts.append(f"{len(found)} {words}; first {found[0]})")
    return "; ".join(parts) or None


READERS = {"4dhumans": read_fourdhumans}
