"""``rotavat export SEQ --format bvh|amass``: each person's motion as a BVH file or an AMASS-style ``.npz``.

One pass over the sequence gathers, per track, its body-model parameters in the world (:mod:`.body`):
a few hundred bytes per person-frame (SMPL: 0.7 kB; no meshes), kept until the files are written into a
new folder (``person_<id>.bvh`` / ``person_<id>.npz``), built beside the output and swapped in complete.

A file covers its person's own frames, from the first to the last they are in; a frame inside that range
where they are missing repeats the frame before (the summary counts them per file; AMASS files mark them
in ``rotavat_filled``). Both formats need the parameters and the model file: BVH for the rest skeleton
(the joints of the person's betas), AMASS for the root joint's rest position (``trans``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..files.atomic import staged_directory
from ..geometry.camera import Camera
from ..errors import InputError, file_error
from ..formats.smpl import BodyModel
from ..render.rows import OWN, no_camera, sequence_camera_fit
from ..sequence import SMPL_PARAM_KEYS, Sequence
from ..words import count
from .amass import amass_arrays, gender_from_model_name, lift_m
from .animated import fps_note
from .body import body_frame, check_frame_fits, check_model, has_body_params, joint_names, rest_shape
from .bvh import bvh_text
from .options import ExportOptions, sequence_fps

__all__ = ["TrackMotion", "collect_motion", "export_motion", "motion_steps", "SCALE_SPREAD_NOTE"]

SCALE_SPREAD_NOTE = 0.01  # a track whose scale varies by more than this (relative) gets a note in BVH


def motion_steps(seq: Sequence) -> int:
    """How many ``progress()`` calls :func:`export_motion` makes: one per frame."""
    return len(seq)


@dataclass(frozen=True)
class TrackMotion:
    """One person's motion over its own frame range (N frames, first to last it is in).

    frames: (N,) frame indices; present: (N,) False where the frame was filled from the one before;
    root_world_from_model: (N, 3, 3); body_pose: (N, J - 1, 3) axis-angle; pelvis_world: (N, 3) m;
    scale: (N,) about the pelvis; betas: (B,) the mean of its frames' betas.
    """

    track: int
    frames: np.ndarray
    present: np.ndarray
    root_world_from_model: np.ndarray
    body_pose: np.ndarray
    pelvis_world: np.ndarray
    scale: np.ndarray
    betas: np.ndarray


def _missing_params(seq: Sequence, fmt: str, source: str) -> InputError:
    """The refusal of a frame without body-model parameters."""
    return InputError(f"{source}: no body-model parameters ({', '.join(SMPL_PARAM_KEYS)}): --format {fmt} needs them: "
                      "import the HPS tool's output with --smpl-model, then align it (docs/export.md)")


def collect_motion(seq: Sequence, camera: Camera, model: BodyModel, model_path: Path, fmt: str, stored_world: bool,
                   progress: Callable[[], None] | None = None) -> tuple[list[TrackMotion], bool]:
    """Every track's motion (by track id) and whether some frame had no person_ids (frame-local ids).
    InputError for a frame with people but no parameters, or parameters the model does not fit."""
    rows: dict[int, list[tuple]] = {}
    frame_local = False
    for index, frame in enumerate(seq.frames()):
        if frame.n_people:
            if not has_body_params(frame):
                raise _missing_params(seq, fmt, frame.source)
            check_frame_fits(frame, model, model_path)
            frame_local |= frame.get("person_ids") is None
            body = body_frame(frame, camera, model.n_joints, stored_world)
            pose = np.asarray(frame.data["smpl_body_pose"], dtype=np.float64).reshape(frame.n_people, -1, 3)
            for p, track in enumerate(frame.person_ids.tolist()):
                rows.setdefault(int(track), []).append((index, body.local_rot[p, 0], pose[p], body.pelvis_world[p],
                                                        body.scale[p], body.betas[p]))
        if progress is not None:
            progress()
    return [_track_motion(track, rows[track]) for track in sorted(rows)], frame_local


def _track_motion(track: int, rows: list[tuple]) -> TrackMotion:
    """A track's rows (frame, root, pose, pelvis, scale, betas) over its whole range, gaps held."""
    frames = np.array([r[0] for r in rows])
    span = np.arange(frames[0], frames[-1] + 1)
    present = np.isin(span, frames)
    source = np.maximum.accumulate(np.where(present, np.cumsum(present) - 1, 0))  # the row each frame shows
    width = min(len(r[5]) for r in rows)
    betas = np.mean([r[5][:width] for r in rows], axis=0)
    return TrackMotion(track, span, present, np.stack([r[1] for r in rows])[source], np.stack([r[2] for r in rows])[source],
                       np.stack([r[3] for r in rows])[source], np.array([r[4] for r in rows])[source], betas)


def _bvh_file(motion: TrackMotion, model: BodyModel, fps: float, order: str) -> tuple[str, float]:
    """A track's BVH text and the scale its bones use (the median of its frames')."""
    scale = float(np.median(motion.scale))
    _, rest_joints = rest_shape(model, motion.betas)
    parents = model.parents
    offsets = scale * (rest_joints - np.where(parents[:, None] >= 0, rest_joints[np.maximum(parents, 0)], rest_joints))
    local = np.concatenate([motion.root_world_from_model[:, None], _matrices(motion.body_pose)], axis=1)
    return bvh_text(joint_names(model), parents, offsets, motion.pelvis_world, local, 1.0 / fps, order), scale


def _matrices(rotvec: np.ndarray) -> np.ndarray:
    """Axis-angle (N, K, 3) -> (N, K, 3, 3)."""
    n, k = rotvec.shape[:2]
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(n, k, 3, 3)


def export_motion(seq: Sequence, out: Path, fmt: str, camera_path: Path | None = None,
                  options: ExportOptions | None = None, model: BodyModel | None = None, model_path: Path | None = None,
                  progress: Callable[[], None] | None = None) -> dict:
    """Write each person of ``seq`` as ``out/person_<id>.bvh`` (``fmt`` 'bvh') or ``.npz`` ('amass'); a summary.

    camera_path: a camera.yaml (default the sequence's own: the world the files are in); options: the
    frame rate assumed without meta.yaml's ``fps`` and BVH's Euler order; model (and its file): required.
    """
    options = options or ExportOptions()
    if model is None or model_path is None:
        declared = seq.meta.get("body_model") if isinstance(seq.meta, dict) else None
        named = f"{declared['file']}, " if isinstance(declared, dict) and declared.get("file") else ""
        raise InputError(f"--format {fmt} needs the body model the parameters were made with: pass --smpl-model "
                         f"with its .npz file ({named}docs/export.md)")
    camera, _, origin = sequence_camera_fit(seq, camera_path)
    if camera is None:
        raise no_camera(seq, f"{fmt.upper()} files' world")
    check_model(model, model_path, seq.meta, str(seq.path / "meta.yaml"))
    fps, fps_from = sequence_fps(seq, options.fps)
    motions, frame_local = collect_motion(seq, camera, model, model_path, fmt, origin == OWN, progress)
    if not motions:
        raise file_error(seq.label, f"nobody in any frame: no {fmt.upper()} file to write")
    gender = gender_from_model_name(model_path.name)
    notes = [note for note in (fps_note(fps, fps_from),) if note]
    if frame_local:
        notes.append("frames without person_ids: person_<k> is the k-th person of every frame, not one body "
                     "followed in time")
    files, lifts, spread = [], [], []
    with staged_directory(out, command="export") as stage:
        for motion in motions:
            name = f"person_{motion.track}.{'bvh' if fmt == 'bvh' else 'npz'}"
            if fmt == "bvh":
                text, scale = _bvh_file(motion, model, fps, options.euler)
                (stage / name).write_text(text, encoding="utf-8")
                if np.ptp(motion.scale) > SCALE_SPREAD_NOTE * scale:
                    spread.append(f"person_{motion.track} ({motion.scale.min():.3f}-{motion.scale.max():.3f})")
            else:
                arrays = amass_arrays(model, motion.betas, motion.root_world_from_model, motion.body_pose,
                                      motion.pelvis_world, fps, gender or "neutral")
                arrays.update(rotavat_person_id=np.array(motion.track), rotavat_scale=motion.scale,
                              rotavat_filled=~motion.present, rotavat_model_file=np.array(model_path.name),
                              rotavat_frame_names=np.array([seq.frame_names[i] for i in motion.frames]))
                with open(stage / name, "wb") as handle:
                    np.savez(handle, **arrays)
                lifts.append((lift_m(model, motion.betas, float(np.median(motion.scale))), motion.track))
            files.append({"person_id": motion.track, "file": name, "first_frame": seq.frame_names[motion.frames[0]],
                          "last_frame": seq.frame_names[motion.frames[-1]], "frames": len(motion.frames),
                          "filled": int((~motion.present).sum())})
    if spread:
        notes.append(f"{count(len(spread), 'person', 'people')} {'changes' if len(spread) == 1 else 'change'} scale over "
                     f"their frames ({', '.join(spread[:3])}"
                     f"{', ...' if len(spread) > 3 else ''}): BVH bones take the median scale; the pelvis path stays exact")
    if fmt == "amass":
        if gender is None:
            notes.append(f"{model_path.name} does not name a gender: written as 'neutral'")
        worst = max(lifts, key=lambda item: abs(item[0]))
        if abs(worst[0]) >= 0.005:
            notes.append(f"AMASS has no scale: unscaled about the pelvis, people stand off the ground by up to "
                         f"{100 * worst[0]:+.1f} cm (person_{worst[1]}; rotavat_scale holds each frame's scale)")
    return {"out": str(out), "format": fmt, "sequence": seq.label, "frames": len(seq), "fps": fps, "fps_from": fps_from,
            "people": len(motions), "model": model_path.name, "files": files, "notes": notes, "warnings": []}
