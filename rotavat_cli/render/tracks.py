"""Per-track plots over time: foot height, lean and stature of every person of a sequence (PNG, Pillow).

For each frame and person (``person_id`` = the track), in the row's camera (its world: ground at
``Y = 0``): the foot point's height above the ground (m, signed: below 0 = sunk; the foot point is the
ground contact, :func:`rotavat_cli.bodies.landmarks.ground_contact`), the lean of the foot -> crown axis from
the vertical (deg) and the stature (the foot -> crown length, m).
Mid-sole and crown are those ``rotavat align`` uses (:func:`rotavat_cli.bodies.frame_points.frame_foot_head_cam`:
the mesh landmarks, or for joints-only people their ``feet_2d``/``heads_2d`` at the joints' depth),
else for joints without those pixels the layout's keypoint recipe applied to the 3D joints
(:func:`rotavat_cli.formats.keypoints.feet_heads_cam`). These
are the quantities ``rotavat eval --per-person`` reports per matched pair, here for one sequence
alone (no ground truth needed), so a foot that drifts into the ground or a body that tilts over a
walk shows as a curve.

The plot is drawn with Pillow: three stacked panels sharing the frame axis, one line per track
in its palette colour, a legend of the track ids.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from ..files.atomic import atomic_open
from ..geometry.camera import Camera
from ..formats.keypoints import feet_heads_cam
from ..bodies.frame_points import MeshIntrinsics, frame_foot_head_cam
from ..metrics.scene import lean_deg, stature_m
from ..sequence import Frame, Sequence, can_align
from .geometry import nice_length_m
from .rows import sequence_layout
from .style import RGB, font, person_colors, rgb8

__all__ = ["TRACK_SERIES", "Tracks", "frame_track_values", "sequence_tracks", "plot_tracks"]

# (key, panel title, unit, reference line, smallest span shown): what the plot shows, top to bottom
TRACK_SERIES = (("foot_height_m", "foot height above the ground", "m", 0.0, 0.1),
                ("lean_deg", "lean from vertical", "°", 0.0, 2.0),
                ("stature_m", "stature (foot point to crown)", "m", None, 0.1))


@dataclass
class Tracks:
    """Per-track series: ``values[key][person_id]`` = list of (frame index, value)."""

    label: str
    n_frames: int
    values: dict[str, dict[int, list[tuple[int, float]]]] = field(default_factory=lambda: {k: {} for k, *_ in TRACK_SERIES})
    source: str = ""  # what gave the foot point and crown (mesh landmarks or the joints' recipe)

    @property
    def ids(self) -> list[int]:
        """Track ids with at least one value, sorted."""
        return sorted({pid for series in self.values.values() for pid in series})


def _feet_heads(seq: Sequence, frame: Frame, camera: Camera) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Mid-soles and crowns (P, 3) of a frame's people and where they came from; None without a way."""
    if can_align(frame):
        mesh = MeshIntrinsics.of_frame(frame, seq.frame_intrinsics(frame), camera)
        feet, heads = frame_foot_head_cam(frame, mesh)
        return feet, heads, "mesh landmarks" if frame.get("vertices") is not None else "feet_2d/heads_2d (as align)"
    joints = frame.get("joints")
    layout = None if joints is None else sequence_layout(seq, joints.shape[1])
    got = None if joints is None else feet_heads_cam(joints, layout)
    return None if got is None else (got[0], got[1], f"joints ({layout} recipe)")


def frame_track_values(seq: Sequence, frame: Frame, camera: Camera) -> tuple[dict[str, np.ndarray], np.ndarray, str] | None:
    """One frame's track values in ``camera``'s world: ``{key: (P,)}`` for each :data:`TRACK_SERIES` key,
    the (P, 3) foot points (camera frame) they were measured from, and where those came from; None for a
    frame without people or without a way to find their foot points and crowns."""
    got = _feet_heads(seq, frame, camera) if frame.n_people else None
    if got is None:
        return None
    feet, heads, source = got
    values = {"foot_height_m": camera.height_above_ground(feet), "lean_deg": lean_deg(feet, heads, camera.up_cam),
              "stature_m": stature_m(feet, heads)}
    return values, feet, source


def sequence_tracks(seq: Sequence, camera: Camera, label: str, progress: Callable[[], None] | None = None) -> Tracks:
    """Foot height, lean and stature of every person of every frame of ``seq``, in ``camera``'s world."""
    tracks = Tracks(label, len(seq))
    for index, name in enumerate(seq.frame_names):
        frame = seq.read_frame(name)
        got = frame_track_values(seq, frame, camera)
        if got is not None:
            values, _, tracks.source = got
            for key, column in values.items():
                for pid, value in zip(frame.person_ids, column):
                    if np.isfinite(value):
                        tracks.values[key].setdefault(int(pid), []).append((index, float(value)))
        if progress:
            progress()
    return tracks


def _panel(draw, box: tuple[int, int, int, int], title: str, unit: str, ref: float | None, min_span: float,
           series: dict[int, list[tuple[int, float]]], n_frames: int, colors: dict[int, RGB], face, small) -> None:
    """One plot panel inside ``box`` (x0, y0, x1, y1): axes, ticks, reference line, one line per track."""
    x0, y0, x1, y1 = box
    values = [v for pts in series.values() for _, v in pts]
    lo, hi = (min(values), max(values)) if values else (0.0, 1.0)
    if ref is not None:
        lo, hi = min(lo, ref), max(hi, ref)
    grow = max(0.05 * (hi - lo), 0.5 * (min_span - (hi - lo)), 0.0)  # millimetre noise is not drawn as a cliff
    lo, hi = lo - grow, hi + grow
    draw.text((x0, y0 - 4), f"{title} ({unit})", fill=(34, 34, 34), font=face, anchor="ld")
    draw.rectangle([x0, y0, x1, y1], outline=(150, 150, 150))
    to_x = lambda i: x0 + (x1 - x0) * (i / max(n_frames - 1, 1))  # noqa: E731
    to_y = lambda v: y1 - (y1 - y0) * (v - lo) / (hi - lo)  # noqa: E731
    step = nice_length_m((hi - lo) / 4)
    for k in range(math.ceil(lo / step), math.floor(hi / step) + 1):
        y = to_y(k * step)
        draw.line([(x0, y), (x1, y)], fill=(225, 225, 220))
        draw.text((x0 - 4, y), f"{k * step:g}", fill=(34, 34, 34), font=small, anchor="rm")
    if ref is not None:
        draw.line([(x0, to_y(ref)), (x1, to_y(ref))], fill=(140, 130, 115), width=2)
    for pid, pts in series.items():
        xy = [(to_x(i), to_y(v)) for i, v in pts]
        ink = rgb8(colors[pid])
        if len(xy) > 1:
            draw.line(xy, fill=ink, width=2, joint="curve")
        for x, y in xy if len(xy) <= 30 else ():
            draw.ellipse([x - 2, y - 2, x + 2, y + 2], fill=ink)


def plot_tracks(path: Path, tracks: Tracks, palette: tuple[RGB, ...], size: tuple[int, int] = (900, 720)) -> Path:
    """Write the three stacked per-track plots of ``tracks`` as a PNG, atomically."""
    W, H = size
    img = Image.new("RGB", (W, H), (255, 255, 255))
    draw = ImageDraw.Draw(img)
    face, small = font(15), font(12)
    ids = tracks.ids
    colors = dict(zip(ids, person_colors(np.asarray(ids, dtype=np.int64), palette))) if ids else {}
    title = f"{tracks.label}: {len(ids)} track(s) over {tracks.n_frames} frame(s)"
    draw.text((10, 8), title + (f"; foot point and crown from {tracks.source}" if tracks.source else "; no people"),
              fill=(34, 34, 34), font=face)
    left, right, top, legend_h = 60, W - 20, 56, 28
    slot = (H - top - legend_h - 30) / len(TRACK_SERIES)
    for k, (key, name, unit, ref, min_span) in enumerate(TRACK_SERIES):
        y0 = int(top + k * slot)
        _panel(draw, (left, y0, right, int(y0 + slot - 34)), name, unit, ref, min_span, tracks.values[key],
               tracks.n_frames, colors, face, small)
    y_axis = H - legend_h - 22
    draw.text(((left + right) / 2, y_axis), "frame", fill=(34, 34, 34), font=small, anchor="mt")
    draw.text((left, y_axis), "0", fill=(34, 34, 34), font=small, anchor="mt")
    draw.text((right, y_axis), str(max(tracks.n_frames - 1, 0)), fill=(34, 34, 34), font=small, anchor="mt")
    x = left
    for pid in ids[:40]:
        draw.rectangle([x, H - 20, x + 12, H - 8], fill=rgb8(colors[pid]))
        draw.text((x + 16, H - 14), str(pid), fill=(34, 34, 34), font=small, anchor="lm")
        x += 16 + draw.textlength(str(pid), font=small) + 12
    with atomic_open(path, "wb") as handle:
        img.save(handle, format="PNG")
    return path
