"""``rotavat export SEQ`` (no ``--frame``): the whole sequence as one animated glTF 2.0 binary scene.

Two passes over the sequence (:mod:`.glb` says why): the first (:func:`.scan.scan_sequence`) finds who is
in which frame; the file is then laid out, its size checked against ``limits.max_file_mb`` before
anything is written, and the second pass writes every frame's people to a temporary file beside the
output, renamed when complete. People are skinned body models (:mod:`.skinned`) when the frames carry
body-model parameters and the model file is given, else one mesh per person-frame (:mod:`.frames`).
The world is the camera's (docs/conventions.md: Y up, metres, origin on the ground below the camera).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..settings import limits
from ..files.atomic import atomic_open
from ..errors import InputError
from ..formats.smpl import BodyModel
from ..render.rows import OWN, no_camera, sequence_camera_fit
from ..render.style import RGB, RenderStyle
from ..sequence import Frame, Sequence
from ..words import count
from .body import check_frame_fits, check_model, has_body_params
from .frames import FramesPlan, plan_frames
from .glb import GlbWriter, glb_size, json_chunk
from .options import ExportOptions, sequence_fps
from .scan import SequenceScan, scan_sequence
from .scene import write_stage
from .skinned import SkinnedPlan, plan_skinned

__all__ = ["export_animated", "animated_steps", "MAX_GLB_BYTES", "fps_note"]

MAX_GLB_BYTES = (1 << 32) - 1  # a GLB's length is a 32-bit number, whatever the limits allow
WEIGHT_WARNING = 0.01  # a skinning weight left out above this is worth a warning (4 joints per vertex kept)


def animated_steps(seq: Sequence) -> int:
    """How many ``progress()`` calls :func:`export_animated` makes: one per frame and pass."""
    return 2 * len(seq)


def fps_note(fps: float, fps_from: str) -> str | None:
    """The note saying the frame rate was assumed (None when meta.yaml gave it)."""
    if fps_from == "meta.yaml":
        return None
    return f"meta.yaml states no fps: {fps:g} frames per second assumed (config export.fps, or --fps)"


def _model_check(seq: Sequence, model: BodyModel | None, model_path: Path | None) -> Callable[[Frame], None] | None:
    """What the first pass checks on each frame: that the parameters it carries fit the model."""
    if model is None or model_path is None:
        return None
    check_model(model, model_path, seq.meta, str(seq.path / "meta.yaml"))

    def check(frame: Frame) -> None:
        if has_body_params(frame):
            check_frame_fits(frame, model, model_path)

    return check


def _notes(scan: SequenceScan, skinned: bool, model: BodyModel | None, fps: float, fps_from: str) -> list[str]:
    """What the user should know about how the scene was made."""
    notes = [note for note in (fps_note(fps, fps_from),) if note]
    if scan.frame_local_ids:
        notes.append("frames without person_ids: people are numbered 0..P-1 within each frame, so person_<k> is the "
                     "k-th person of every frame, not one body followed in time")
    if skinned:
        notes.append("skinned bodies: each person's shaped rest mesh bent by its skeleton; the model's pose-corrective "
                     "blend shapes are not in glTF (a few millimetres at bent joints)")
        varied = {track: spread for track, spread in scan.betas_spread.items() if spread > 1e-6}
        if varied:
            worst = max(varied, key=varied.get)
            notes.append(f"{count(len(varied), 'track')} {'changes' if len(varied) == 1 else 'change'} body shape over "
                         f"their frames (betas up to "
                         f"{varied[worst]:.2g} apart, person_{worst}): each is skinned with its mean betas")
    elif scan.person_frames and scan.params_everywhere and model is None:
        notes.append("the frames carry body-model parameters: pass --smpl-model FILE (the model they were made with) "
                     "for skinned bodies, a far smaller file")
    elif model is not None and scan.person_frames and not scan.params_everywhere:
        notes.append("not every frame carries body-model parameters: per-frame meshes (--smpl-model gives skinned "
                     "bodies only when every frame with people carries them)")
    return notes


def _check_size(seq: Sequence, total: int, scan: SequenceScan, skinned: bool) -> None:
    """InputError before writing when the file would exceed ``limits.max_file_mb`` (or GLB's 4 GiB)."""
    limit = min(limits.current().max_file_bytes, MAX_GLB_BYTES)
    if total <= limit:
        return
    points = sum(pf.n_points for pf in scan.person_frames)
    hint = "" if skinned else (" (skinned bodies are far smaller: --smpl-model FILE, for frames with body-model "
                               "parameters)")
    what = "limits.max_file_mb" if limit < MAX_GLB_BYTES else "the 4 GiB a .glb can hold"
    raise InputError(f"{seq.label}: the animated scene would take {limits.human_bytes(total)} "
                     f"({count(len(scan.person_frames), 'person-frame')}, {points:,} points), over {what} "
                     f"({limits.human_bytes(limit)}); raise limits.max_file_mb in a --config file if this is meant"
                     f"{hint}")


def export_animated(seq: Sequence, out: Path, camera_path: Path | None = None, palette: tuple[RGB, ...] | None = None,
                    options: ExportOptions | None = None, model: BodyModel | None = None,
                    model_path: Path | None = None, progress: Callable[[], None] | None = None) -> dict:
    """Write every frame of ``seq`` as one animated ``.glb`` at ``out``; returns a summary (plain types).

    camera_path: a camera.yaml (default the sequence's own); palette: person colours (default the packaged
    ``render.palette``); options: the frame rate assumed without meta.yaml's ``fps``; model (and the file it
    was read from): skinned bodies for frames that carry body-model parameters.
    """
    options = options or ExportOptions()
    palette = RenderStyle().palette if palette is None else palette
    camera, _, origin = sequence_camera_fit(seq, camera_path)
    if camera is None:
        raise no_camera(seq, "animated scene's world")
    fps, fps_from = sequence_fps(seq, options.fps)
    scan = scan_sequence(seq, model, progress, _model_check(seq, model, model_path))
    plan: FramesPlan | SkinnedPlan
    if model is not None and scan.params_everywhere and scan.person_frames:
        stored_world = origin == OWN  # the frames' world parameters are in this camera's world
        plan = plan_skinned(scan, model, camera, palette, fps, stored_world)
    else:
        plan = plan_frames(scan, camera, palette, fps)
    skinned = isinstance(plan, SkinnedPlan)
    builder = plan.builder
    builder.extras = {"fps": fps, "fps_from": fps_from, "frames": len(scan.names), "first_frame": scan.names[0],
                      "last_frame": scan.names[-1]}
    json_bytes = len(json_chunk(builder.gltf()))  # placeholder bounds: the widest the real ones can be
    total = glb_size(json_bytes, builder.layout.size)
    _check_size(seq, total, scan, skinned)
    with atomic_open(out, "wb") as handle:
        writer = GlbWriter(handle, json_bytes, builder.layout)
        lo, hi = plan.write(writer, seq, camera, seq.frames(), progress)
        write_stage(writer, builder, plan.stage, camera, lo, hi)
        writer.finish(builder.gltf())
    kinds = sorted({pf.kind for pf in scan.person_frames})  # the one-frame export's words: mesh, points, skeleton
    W, H = camera.image_size
    summary = {
        "out": str(out), "format": "glb", "sequence": seq.label, "frames": len(scan.names), "fps": fps,
        "fps_from": fps_from, "people": len(scan.tracks), "person_frames": len(scan.person_frames),
        "drawn_as": "skinned" if skinned else "+".join(kinds) or "nothing",
        "track_ids": "frame-local" if scan.frame_local_ids else "person_ids", "bytes": total,
        "image_size": [W, H], "aspect_ratio": W / H, "yfov_deg": float(np.rad2deg(camera.vertical_fov_rad)),
        "notes": _notes(scan, skinned, model, fps, fps_from), "warnings": [],
    }
    if isinstance(plan, SkinnedPlan):
        summary["skin_weight_dropped"] = plan.weight_dropped
        if plan.weight_dropped > WEIGHT_WARNING:
            summary["warnings"].append(f"{model_path}: some vertices have more than 4 skinning joints; the 4 largest "
                                       f"were kept (largest weight left out: {plan.weight_dropped:.3f})")
    return summary
