"""CoMotion (``demo.py``): ``<output-dir>/<input>.pt``, a ``torch.save`` of SMPL parameters per tracked person-frame.

Source: apple/ml-comotion ``demo.py`` (``track_poses``: ``tracks = {k: getattr(tracks, k) for k in ["id", "pose",
"trans", "betas"]}``, ``frame_idxs, track_idxs = track_utils.convert_to_idxs(...)``, ``preds = {k: v[0, frame_idxs,
track_idxs] ...}``, ``preds["id"] = preds["id"].squeeze(-1).long()``, ``preds["frame_idx"] = frame_idxs``,
``torch.save(preds, cache_path)`` with ``cache_path = output_dir / f"{input_name}.pt"``; ``run_detection``, one image:
``torch.save({k: v[0].cpu() ...})`` of ``decode_network_outputs``; the renderer: ``SMPLLayer(model_type="smpl",
gender="neutral")``, ``poses_root = pose[..., :3]``, ``OpenCVCamera(K, eye(4)[:3])``),
``src/comotion_demo/utils/dataloading.py`` (``get_default_K``: ``[[2 max_res, 0, 0.5 W], [0, 2 max_res, 0.5 H]]``,
given to every frame by ``yield_image_and_K``), ``src/comotion_demo/utils/smpl_kinematics.py`` (``BETA_DOF = 10``,
``POSE_DOF = 72``; ``SMPLKinematics.forward``: ``smpl_output + trans``), ``src/comotion_demo/utils/track.py``
(``convert_to_idxs``: the rows of each kept track in frame order), ``src/comotion_demo/models/detect.py``
(``decode_network_outputs``: ``betas`` (P, 10), ``pose`` (P, 72), ``trans`` (P, 3), ``pred_3d``, ``pred_2d``,
``conf``). Apple's repository is not in the index searched; its code was read in forks that carry it with Apple's
copyright: hunminkim98/ml-comotion @790463d ``demo.py`` (``track_poses``, ``run_detection``), @bc4643a
``dataloading.py``; GPenksik/ml-comotion @1f5646f ``smpl_kinematics.py`` (its loaded file edited to the male model;
the original line, kept commented, loads ``SMPL_NEUTRAL.pkl``); owenyang55/ml-comotion @0149cfc ``detect.py``.

- File: a torch zip archive (read by :func:`rotavat_cli.unpickle.torch_files.load_torch`, without torch) holding
  ``{"id" (N,) int64, "pose" (N, 72), "trans" (N, 3), "betas" (N, 10), "frame_idx" (N,) int64}``: one row per
  tracked person-frame, grouped by track. ``person_ids`` = ``id``. A single image (``run_detection``) saves the
  detections instead: ``betas``, ``pose``, ``trans`` (P rows), ``pred_3d``, ``pred_2d``, ``conf``: one frame,
  named as the file (``<image stem>.pt``), no track ids.
- Frame: ``SMPL(pose, betas) + trans`` (axis-angle, joint 0 the root in the camera) is the camera frame: OpenCV
  axes (the renderer's ``OpenCVCamera`` at the identity), metres.
- Focal: ``get_default_K``: f = 2 max(W, H), principal point at the image centre (rule ``comotion``): CoMotion's
  guess, never the camera's (``focal_kind: assumed``). The demo has no option to give another K.
- Image size: not stored (the demo reads it from the video): ``--image-size`` is required.
- Frames: ``frame_idx`` counts the frames the demo processed (the video's from ``--start-frame``, every
  ``--frameskip``-th; neither is stored), from 0 to the last tracked one; frames where nobody was tracked are empty.
- Parameters only: vertices and joints need ``--smpl-model`` (SMPL, neutral); nothing else is stored.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import file_error
from ..geometry.focal import ASSUMED, focal_from_rule
from ..sequence import Frame
from ..unpickle.torch_files import load_torch
from .content import as_array, get
from .frame_names import frame_names
from .frames import people_frame
from .ids import check_frame_range
from .image_size import need_image_size
from .imported import FrameNotes, ImportedSequence, ImportOptions
from .meta import base_meta, feet_heads_from
from .model_checks import model_faces, require_model
from .row_blocks import RowBlocks, posing_block_rows
from .smpl import lbs, smpl_param_arrays

__all__ = ["sniff", "read_comotion", "READERS"]

_MAX_PICKLE_BYTES = 16 << 20  # the data.pkl record of a results file: names and tensor references, a few kB
_TRACK_KEYS = (b"frame_idx", b"id")  # track_poses' keys beside the parameters
_IMAGE_KEYS = (b"pred_2d", b"conf")  # run_detection's keys beside the parameters


def _pickle_record(path: Path) -> bytes | None:
    """The ``data.pkl`` record of a torch zip archive (no tensor loaded), or None when ``path`` is none."""
    if not (path.is_file() and path.suffix in (".pt", ".pth")) or not zipfile.is_zipfile(path):
        return None
    with zipfile.ZipFile(path) as archive:
        pickles = [info for info in archive.infolist()
                   if info.filename.count("/") == 1 and info.filename.endswith("/data.pkl")]
        if len(pickles) != 1 or pickles[0].file_size > _MAX_PICKLE_BYTES:
            return None
        return archive.read(pickles[0])


def sniff(path: Path) -> str | None:
    """'comotion' for a torch archive whose pickle names ``pose``, ``trans`` and ``betas`` with either
    ``frame_idx`` and ``id`` (a tracked video) or ``pred_2d`` and ``conf`` (one image)."""
    text = _pickle_record(path)
    if text is None or not all(key in text for key in (b"pose", b"trans", b"betas")):
        return None
    if b"smpl_params_incam" in text:  # GVHMR's
        return None
    return "comotion" if all(k in text for k in _TRACK_KEYS) or all(k in text for k in _IMAGE_KEYS) else None


def _rows(data: Mapping, path: Path) -> dict[str, np.ndarray]:
    """The file's rows, checked: pose (N, 72), trans (N, 3), betas (N, B), ids (N,) or None, frame (N,)."""
    pose = as_array(get(data, "pose", path), "pose", path, ndim=2, last=(72,))
    trans = as_array(get(data, "trans", path), "trans", path, ndim=2, last=(3,))
    betas = as_array(get(data, "betas", path), "betas", path, ndim=2)
    n_rows = len(pose)
    tracked = "frame_idx" in data or "id" in data
    if tracked:
        ids = as_array(get(data, "id", path), "id", path, kinds="iu")
        frame = as_array(get(data, "frame_idx", path), "frame_idx", path, ndim=1, kinds="iu")
        if ids.ndim == 2 and ids.shape[1] == 1:  # the tracker's (N, 1) ids, before demo.py squeezes them
            ids = ids[:, 0]
        if ids.ndim != 1:
            raise file_error(path, f"'id' must be (N,) track ids, got {list(ids.shape)}")
    else:
        ids, frame = None, np.zeros(n_rows, np.int64)
    for name, array in (("trans", trans), ("betas", betas), ("id", ids), ("frame_idx", frame)):
        if array is not None and len(array) != n_rows:
            raise file_error(path, f"'{name}' has {len(array)} rows, 'pose' {n_rows}")
    if n_rows == 0:
        raise file_error(path, "no tracked person in the file")
    if frame.min() < 0:
        raise file_error(path, "'frame_idx' holds negative frame indices")
    if ids is not None and ids.dtype.kind == "u" and ids.max() > np.iinfo(np.int64).max:
        raise file_error(path, f"track id {ids.max()} does not fit in a 64-bit integer")
    return {"pose": pose, "trans": trans, "betas": betas, "frame": frame.astype(np.int64),
            "ids": None if ids is None else ids.astype(np.int64)}


def read_comotion(src: Path, opts: ImportOptions) -> ImportedSequence:
    """CoMotion ``<input>.pt`` -> contract frames (camera frame, SMPL posed with ``--smpl-model``; ``person_ids`` =
    CoMotion's track ids)."""
    if not (src.is_file() and src.suffix in (".pt", ".pth")):
        raise file_error(src, "no CoMotion results: expected the .pt file demo.py saves (<output-dir>/<input>.pt)")
    data = load_torch(src)
    if not isinstance(data, Mapping):
        raise file_error(src, f"not a CoMotion output (expected the dict demo.py saves, got {type(data).__name__})")
    rows = _rows(data, src)
    image_size = need_image_size(opts, src, "CoMotion's demo.py reads it from the video")
    model = opts.body_model
    require_model(model, src, "CoMotion", "smpl")
    n_frames = check_frame_range(int(rows["frame"].max()) + 1, len(rows["frame"]), src, "frame_idx")
    order = np.lexsort((np.zeros(len(rows["frame"])) if rows["ids"] is None else rows["ids"], rows["frame"]))
    starts = np.searchsorted(rows["frame"][order], np.arange(n_frames + 1))  # frame i: order[starts[i]:starts[i + 1]]
    warnings: list[str] = []
    width = max(6, len(str(n_frames - 1)))
    # one image: named as the image (demo.py names the file after it), so other tools' results on it line up
    stems = [f"{i:0{width}d}" for i in range(n_frames)] if rows["ids"] is not None else [src.stem]
    names = frame_names(stems, warnings)
    faces = model_faces(model, model.n_verts)

    def posed(start: int, stop: int) -> dict[str, np.ndarray]:
        """Rows [start, stop) of the frame-by-frame table ``order`` posed at once (frames in batches, not one by one)."""
        picks = order[start:stop]
        betas, pose, trans = rows["betas"][picks], rows["pose"][picks], rows["trans"][picks]
        vertices, joints = lbs(model, betas, pose, trans)
        return {"vertices": vertices, "joints": joints, **smpl_param_arrays(model, betas, pose, trans, joints)}

    posed_rows = RowBlocks(len(order), posed, posing_block_rows(model))

    def build(index: int, notes: FrameNotes) -> Frame:
        start, stop = int(starts[index]), int(starts[index + 1])
        body = posed_rows.rows(start, stop)
        vertices, joints = body.pop("vertices"), body.pop("joints")
        ids = None if rows["ids"] is None else rows["ids"][order[start:stop]]
        return people_frame(names[index], f"{src} [frame {index}]", notes.warnings, vertices=vertices, joints=joints,
                            person_ids=ids, faces=faces, n_verts=model.n_verts, body_params=body)

    focal = focal_from_rule("comotion", image_size)
    principal_point = (image_size[0] / 2.0, image_size[1] / 2.0)
    meta = base_meta("comotion", src, opts, image_size, focal, principal_point, focal_kind=ASSUMED, focal_rule="comotion")
    meta["import"].update({
        "source_frames": list(range(n_frames)) if rows["ids"] is not None else [src.stem],
        "image_size_from": "--image-size",
        "frame_indices": "frame_idx: the frames demo.py processed (video frame = --start-frame + --frameskip x frame_idx)"
                         if rows["ids"] is not None else "one image (run_detection)",
        "joints_layout": "smpl24",
        "root_joint": 0,
        "keypoints_2d_layout": None,
        "feet_heads_from": feet_heads_from(None, True),
        "person_ids": "CoMotion track ids ('id')" if rows["ids"] is not None else None,
        "conventions": "camera frame = OpenCV, metres; vertices = SMPL(pose, betas) + trans; focal = 2 max(W, H), "
                       "principal point = image centre (get_default_K)",
    })
    return ImportedSequence(tuple(names), build, meta, warnings)


READERS = {"comotion": read_comotion}
