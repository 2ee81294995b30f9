"""Do a sequence's meshes fit its own pixels? A wrong or mismatched body model, or a wrong image size, named.

An HPS tool's meshes project, through the intrinsics the tool used, onto the people it saw: onto the
tool's own 2D keypoints, and inside the image. A body model other than the tool's (``--smpl-model``
of another family member, a stand-in whose template sits elsewhere) or a wrong ``--image-size`` (a
rule's focal and the principal point follow it) breaks that silently: the import succeeds, calibrate
fits a camera to people drawn where nobody stood. This module measures, per person of a frame,

- **the offset to its own 2D evidence** (px, and in person heights), the first there is of: the
  per-axis median, over the joints the 3D and 2D layouts share by name (:mod:`rotavat_cli.bodies.joint_layouts`),
  of projected joint minus keypoint; the projected mesh mid-sole and crown minus ``feet_2d`` and
  ``heads_2d``; the centre of the projection's bounding box minus that of ``boxes_2d`` (GVHMR's crops);
- **the share of its projection outside the image** (the mesh's vertices, else its joints), and
  where its median point lies beyond the image's edges (px);

and, over a sequence, says in one line (:func:`model_fit_finding`) when the median person is off. A
person's height in pixels is the extent of its own projection (its longer side), so the offset is
relative to the size the body is drawn at. People not placed in the camera (root-centred, behind it)
are not measured: the import warns of them on its own.

Thresholds, from measurements (docs/formats.md, "A body model that does not fit the pixels", the
table): the median person of correct imports of the real files lies within 0.046 person heights of its
own 2D evidence, of ``rotavat synth``'s leaning predictions within 0.108; stand-in models 1.2-1.3 m
from the real one's pelvis put it 0.64-0.74 away, a doubled or halved ``--image-size`` 0.34-0.69.
Named: the median person beyond :data:`OFF_HEIGHTS` (0.2), or else (no 2D evidence) with more than
:data:`OUTSIDE_SHARE` of its projection outside the image (correct imports: at most 0.22; a person
cut by the image's border, 0.47).

A long sequence is read in proportion: at most :data:`MAX_FRAMES` frames, spread evenly over it.

>>> sampled_names(tuple(f"{i:06d}" for i in range(1000)), 4)
('000000', '000333', '000666', '000999')
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import project_cam_to_px
from ..bodies.joint_layouts import LAYOUT_NAMES, layout_by_count, layout_key
from ..bodies.landmarks import foot_head_points
from ..sequence import Frame, Intrinsics, Sequence, people_not_placed

__all__ = ["MAX_FRAMES", "OFF_HEIGHTS", "OUTSIDE_SHARE", "PeopleFit", "FitSummary", "frame_model_fit",
           "model_fit_finding", "sampled_names", "sequence_model_fit"]

MAX_FRAMES = 100  # frames measured per sequence, spread evenly: a long sequence costs what a short one does
OFF_HEIGHTS = 0.2  # median person this far from its own 2D evidence, in person heights: named (module docstring)
OUTSIDE_SHARE = 0.5  # median person with more than this share of its projection outside the image: named
MIN_SHARED_JOINTS = 4  # fewer joints shared by name between the 3D and 2D layouts: use feet/heads instead


@dataclass(frozen=True)
class PeopleFit:
    """How the people of one frame (or of many, concatenated) fit their own pixels; NaN = not measured.

    offset_px: (P, 2) per-axis median of projected 3D point minus its 2D evidence (u right, v down), px
    size_px: (P,) the person's drawn size: the longer side of its projection's bounding box, px
    outside: (P,) share of the person's projected points outside the image (0..1)
    beyond_px: (P, 2) how far the projection's median point lies beyond the image's edges (0 inside), px
    evidence_outside: (P,) share of the person's 2D evidence outside the image (0..1)
    """

    offset_px: np.ndarray
    size_px: np.ndarray
    outside: np.ndarray
    beyond_px: np.ndarray
    evidence_outside: np.ndarray

    @classmethod
    def empty(cls, n_people: int = 0) -> "PeopleFit":
        """``n_people`` people, none measured."""
        nan = np.full(n_people, np.nan)
        return cls(np.full((n_people, 2), np.nan), nan, nan.copy(), np.full((n_people, 2), np.nan), nan.copy())

    @property
    def offset_heights(self) -> np.ndarray:
        """(P,) the offset's length in person heights."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.linalg.norm(self.offset_px, axis=-1) / self.size_px

    @classmethod
    def concatenate(cls, fits: Iterable["PeopleFit"]) -> "PeopleFit":
        """Every person of ``fits``, in order."""
        fits = list(fits) or [cls.empty()]
        return cls(*(np.concatenate([getattr(f, name) for f in fits]) for name in
                     ("offset_px", "size_px", "outside", "beyond_px", "evidence_outside")))


@dataclass(frozen=True)
class FitSummary:
    """A sequence's people measured (:func:`sequence_model_fit`): their fit, the frames read of how many,
    what the 3D points were ('meshes' | 'joints'), the 2D evidence ('2D keypoints' | 'foot and crown
    points' | 'person boxes' | ''), the image sizes (W, H) seen and the ``--smpl-model`` the import posed
    the meshes with (None: the tool's own, or not an import)."""

    people: PeopleFit
    frames: int
    frames_total: int
    points: str = "meshes"
    evidence: str = ""
    image_sizes: tuple[tuple[int, int], ...] = ()
    body_model: str | None = None
    reprojects: str | None = None  # the reader's own word on how its meshes reproject (ROMP's: approximately)

    @property
    def offsets(self) -> np.ndarray:
        """(N,) the offsets of the people measured against 2D evidence, in person heights."""
        off = self.people.offset_heights
        return off[np.isfinite(off)]

    @property
    def outside(self) -> np.ndarray:
        """(N,) the share outside the image of each person measured against a known image size."""
        return self.people.outside[np.isfinite(self.people.outside)]

    def to_dict(self) -> dict:
        """Plain numbers for --json: frames and people measured, and the medians the finding reports."""
        measured = np.isfinite(self.people.offset_heights)
        return {
            "frames": self.frames,
            "frames_total": self.frames_total,
            "evidence": self.evidence or None,
            "people_with_evidence": int(measured.sum()),
            "median_offset_px": _median(np.linalg.norm(self.people.offset_px[measured], axis=-1)),
            "median_offset_heights": _median(self.offsets),
            "people_off": int((self.offsets > OFF_HEIGHTS).sum()),
            "people_in_image": len(self.outside),
            "median_outside": _median(self.outside),
            "people_outside": int((self.outside > OUTSIDE_SHARE).sum()),
        }


def _median(values: np.ndarray) -> float | None:
    """The median of ``values`` as a float, None when empty."""
    return float(np.median(values)) if len(values) else None


# ---- one frame -------------------------------------------------------------------------------------------
def sampled_names(names: tuple[str, ...], max_frames: int = MAX_FRAMES) -> tuple[str, ...]:
    """At most ``max_frames`` of ``names``, spread evenly from the first to the last."""
    if len(names) <= max_frames:
        return tuple(names)
    return tuple(names[i] for i in np.unique(np.linspace(0, len(names) - 1, max_frames).round().astype(int)))


def shared_joints(joints_layout: str | None, n_joints: int, keypoints_layout: str | None,
                  n_keypoints: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices (S,), (S,) of the joints and keypoints that bear the same name in their layouts (a layout
    not named is recognised by its count, :func:`rotavat_cli.bodies.joint_layouts.layout_by_count`); empty when
    either layout is unknown or its names do not fit its count.

    >>> [ix.tolist()[:3] for ix in shared_joints("smpl24", 24, "hybrik29", 29)]
    [[0, 1, 2], [0, 1, 2]]
    >>> len(shared_joints("smpl24", 24, None, 17)[0])     # 17 keypoints of no named layout
    0
    """
    names = [LAYOUT_NAMES.get(layout_key(layout) or layout_by_count(n) or "", ()) for layout, n in
             ((joints_layout, n_joints), (keypoints_layout, n_keypoints))]
    where = {name: k for k, name in enumerate(names[1])}
    fits = len(names[0]) == n_joints and len(names[1]) == n_keypoints
    pairs = np.array([(j, where[name]) for j, name in enumerate(names[0]) if fits and name in where], int)
    return pairs.reshape(-1, 2)[:, 0], pairs.reshape(-1, 2)[:, 1]


def median_offset_px(drawn_px: np.ndarray, observed_px: np.ndarray) -> np.ndarray:
    """(P, 2) per-axis median over the points both sides have of ``drawn_px - observed_px`` ((P, N, 2)
    each, NaN = missing); NaN rows for people with no such point.

    >>> drawn = np.array([[[10.0, 20.0], [30.0, 40.0], [50.0, 60.0]]])
    >>> median_offset_px(drawn, drawn - [[[1.0, 5.0], [2.0, 400.0], [np.nan, np.nan]]]).tolist()
    [[1.5, 202.5]]
    """
    diff = np.asarray(drawn_px, np.float64) - np.asarray(observed_px, np.float64)
    diff[~np.isfinite(diff).all(axis=-1)] = np.nan
    out = np.full(diff.shape[::2], np.nan)
    some = np.isfinite(diff[..., 0]).any(axis=1)
    out[some] = np.nanmedian(diff[some], axis=1)
    return out


def share_outside(points_px: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(P,) share of each person's finite points (P, N, 2) outside the image ``(W, H)`` px (NaN: none finite).

    >>> share_outside(np.array([[[10.0, 10.0], [10.0, 900.0]]]), (640, 480)).tolist()
    [0.5]
    """
    px = np.asarray(points_px, np.float64)
    finite = np.isfinite(px).all(axis=-1)
    with np.errstate(invalid="ignore"):
        out = ((px < 0) | (px > np.asarray(image_size, np.float64))).any(axis=-1) & finite
        return out.sum(axis=1) / np.where(finite.any(axis=1), finite.sum(axis=1), np.nan)


def beyond_image_px(points_px: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """(P, 2) how far the median point of each person's projection (P, N, 2) lies beyond the image's
    edges, signed (u: − left, + right; v: − above, + below; 0 inside).

    >>> beyond_image_px(np.array([[[100.0, 900.0], [120.0, 1100.0]]]), (640, 480)).tolist()
    [[0.0, 520.0]]
    """
    centre = np.full((len(points_px), 2), np.nan)
    some = np.isfinite(points_px[..., 0]).any(axis=1)
    centre[some] = np.nanmedian(points_px[some], axis=1)
    return np.minimum(centre, 0.0) + np.maximum(centre - np.asarray(image_size, np.float64), 0.0)


def bounds_px(points_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P, 2), (P, 2): the lowest and highest (u, v) of each person's finite points (P, N, 2) px, its
    bounding box; NaN rows for people without any.

    >>> [b.tolist() for b in bounds_px(np.array([[[0.0, 0.0], [10.0, 2.0], [4.0, 40.0]]]))]
    [[[0.0, 0.0]], [[10.0, 40.0]]]
    """
    px = np.asarray(points_px, np.float64)
    low, high = np.full((len(px), 2), np.nan), np.full((len(px), 2), np.nan)
    some = np.isfinite(px).all(axis=-1).any(axis=1)
    low[some], high[some] = np.nanmin(px[some], axis=1), np.nanmax(px[some], axis=1)
    return low, high


def box_centres_px(points_px: np.ndarray) -> np.ndarray:
    """(P, 2) the centre of each person's bounding box (:func:`bounds_px`) px."""
    low, high = bounds_px(points_px)
    return (low + high) / 2.0


def drawn_size_px(points_px: np.ndarray) -> np.ndarray:
    """(P,) the longer side of each person's bounding box (:func:`bounds_px`) px: its height as drawn."""
    low, high = bounds_px(points_px)
    return (high - low).max(axis=-1)


def _evidence_px(frame: Frame, body_px: np.ndarray, joints_layout: str | None, keypoints_layout: str | None,
                 focal_px: np.ndarray, principal_point: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, str]:
    """(drawn (P, N, 2), observed (P, N, 2), what the evidence is), first of: the joints the layouts share
    projected against the 2D keypoints; the mesh's mid-sole and crown projected against ``feet_2d`` /
    ``heads_2d``; the centre of the body's projection ``body_px`` (P, M, 2) against that of ``boxes_2d``.
    N = 0 when the frame has none of them."""
    joints, keypoints = frame.get("joints"), frame.get("keypoints_2d")
    if joints is not None and keypoints is not None:
        j, k = shared_joints(joints_layout, joints.shape[1], keypoints_layout, keypoints.shape[1])
        if len(j) >= MIN_SHARED_JOINTS:
            observed = np.asarray(keypoints[:, k, :2], np.float64).copy()
            if keypoints.shape[-1] > 2:  # a confidence column: 0 marks an undetected keypoint
                observed[~(keypoints[:, k, 2] > 0)] = np.nan
            return project_cam_to_px(joints[:, j], focal_px[:, None], principal_point), observed, "2D keypoints"
    verts, feet, heads, boxes = (frame.get(key) for key in ("vertices", "feet_2d", "heads_2d", "boxes_2d"))
    if verts is not None and verts.shape[1] and feet is not None and heads is not None:
        drawn = project_cam_to_px(np.stack(foot_head_points(verts), axis=1), focal_px[:, None], principal_point)
        return drawn, np.stack([feet, heads], axis=1).astype(np.float64), "foot and crown points"
    if boxes is not None:
        corners = np.asarray(boxes, np.float64).reshape(-1, 2, 2)  # (P, 2, 2): [x1, y1], [x2, y2]
        return box_centres_px(body_px)[:, None], box_centres_px(corners)[:, None], "person boxes"
    empty = np.zeros((frame.n_people, 0, 2))
    return empty, empty, ""


def frame_model_fit(frame: Frame, intrinsics: Intrinsics, joints_layout: str | None = None,
                    keypoints_layout: str | None = None) -> tuple[PeopleFit, str]:
    """How each person of ``frame`` fits its own pixels (:class:`PeopleFit`), projected with the intrinsics
    its mesh was made with (``intrinsics``: the frame's, with the sequence's defaults, as
    ``Sequence.frame_intrinsics`` gives them), and what the 2D evidence was ('' for none). People not placed
    in the camera (root-centred, behind it), and every person of a frame without a focal, are not measured."""
    n_people = frame.n_people
    focal, pp, size = intrinsics.focals_px(n_people), intrinsics.principal_point, intrinsics.image_size
    verts, joints = frame.get("vertices"), frame.get("joints")
    body = verts if verts is not None and verts.shape[1] else joints
    if n_people == 0 or focal is None or pp is None or body is None:
        return PeopleFit.empty(n_people), ""
    body_px = project_cam_to_px(body, focal[:, None], pp)  # (P, N, 2)
    drawn, observed, evidence = _evidence_px(frame, body_px, joints_layout, keypoints_layout, focal, pp)
    placed = ~np.logical_or(*people_not_placed(frame))
    no_image = np.full((n_people, 2), np.nan)

    def measured(values: np.ndarray) -> np.ndarray:
        return np.where(placed.reshape(-1, *([1] * (values.ndim - 1))), values, np.nan)

    return PeopleFit(
        offset_px=measured(median_offset_px(drawn, observed)),
        size_px=measured(drawn_size_px(body_px)),
        outside=measured(no_image[:, 0] if size is None else share_outside(body_px, size)),
        beyond_px=measured(no_image if size is None else beyond_image_px(body_px, size)),
        evidence_outside=measured(no_image[:, 0] if size is None else share_outside(observed, size))), evidence


# ---- a sequence ------------------------------------------------------------------------------------------
def _import_entry(seq: Sequence, key: str) -> str | None:
    """A text entry of meta.yaml's ``import:`` block (``keypoints_2d_layout``, ``body_model``, ...), or None."""
    block = seq.meta.get("import") if isinstance(seq.meta, dict) else None
    value = block.get(key) if isinstance(block, dict) else None
    return value if isinstance(value, str) else None


def sequence_model_fit(seq: Sequence, max_frames: int = MAX_FRAMES) -> FitSummary:
    """Every person of at most ``max_frames`` frames of ``seq`` spread over it (:func:`sampled_names`),
    measured against its own pixels (:func:`frame_model_fit`)."""
    joints_layout, keypoints_layout = seq.joints_layout, _import_entry(seq, "keypoints_2d_layout")
    fits, points, evidence, sizes = [], set(), set(), set()
    names = sampled_names(seq.frame_names, max_frames)
    for name in names:
        frame = seq.read_frame(name)
        intrinsics = seq.frame_intrinsics(frame)
        fit, found = frame_model_fit(frame, intrinsics, joints_layout, keypoints_layout)
        fits.append(fit)
        if frame.n_people:
            points.add("meshes" if frame.get("vertices") is not None else "joints")
            evidence.add(found)
            if intrinsics.image_size is not None:
                sizes.add(tuple(intrinsics.image_size))
    model, reprojects = (_import_entry(seq, key) for key in ("body_model", "meshes_reproject"))
    return FitSummary(PeopleFit.concatenate(fits), len(names), len(seq.frame_names),
                      "/".join(sorted(points)) or "meshes", "/".join(sorted(evidence - {""})), tuple(sorted(sizes)),
                      model, reprojects)


def _direction(offset_px: np.ndarray) -> str:
    """Where a (2,) pixel offset (u right, v down) points: 'below', 'above', 'to the right of', 'to the left
    of', or two of them joined when the smaller axis is over half the larger.

    >>> _direction(np.array([5.0, 398.0])), _direction(np.array([628.0, 738.0]))
    ('below', 'below and to the right of')
    """
    du, dv = (float(x) for x in offset_px)
    vertical = "below" if dv > 0 else "above"
    horizontal = "to the right of" if du > 0 else "to the left of"
    major, minor = (vertical, horizontal) if abs(dv) >= abs(du) else (horizontal, vertical)
    return f"{major} and {minor}" if min(abs(du), abs(dv)) > 0.5 * max(abs(du), abs(dv)) else major


def fit_finding(summary: FitSummary, label: str) -> str | None:
    """One line when the median person measured is more than :data:`OFF_HEIGHTS` person heights from its own
    2D evidence, or else has more than :data:`OUTSIDE_SHARE` of its projection outside the image; None
    otherwise (and when nothing could be measured)."""
    frames = (f"{summary.frames} of {summary.frames_total} frames" if summary.frames < summary.frames_total
              else f"{summary.frames} frame{'s' if summary.frames != 1 else ''}")
    if len(summary.offsets) and np.median(summary.offsets) > OFF_HEIGHTS:
        return f"{label}: {_offset_words(summary, frames)}"
    if len(summary.outside) and np.median(summary.outside) > OUTSIDE_SHARE:
        return f"{label}: {_outside_words(summary, frames)}"
    return None


def _offset_words(summary: FitSummary, frames: str) -> str:
    """'the meshes project 399 px (0.74 person heights) below their own person boxes (...): cause'."""
    people, offsets = summary.people, summary.offsets
    measured = np.isfinite(people.offset_heights)
    offset_px = people.offset_px[measured]
    return (f"the {summary.points} project {np.median(np.linalg.norm(offset_px, axis=-1)):.0f} px "
            f"({np.median(offsets):.2f} person heights) {_direction(np.median(offset_px, axis=0))} their own "
            f"{summary.evidence} (median of {len(offsets)} people in {frames}, {(offsets > OFF_HEIGHTS).sum()} "
            f"of them beyond {OFF_HEIGHTS} person heights): {_cause(summary, people.evidence_outside[measured])}")


def _outside_words(summary: FitSummary, frames: str) -> str:
    """'the meshes project outside the 640x480 image: a median 100% of each person, its centre ... : cause'."""
    people, outside = summary.people, summary.outside
    inside = np.isfinite(people.outside)
    beyond = np.median(people.beyond_px[inside], axis=0)
    place = f", its centre {np.linalg.norm(beyond):.0f} px {_direction(beyond)} the image" if np.any(beyond) else ""
    return (f"the {summary.points} project outside the {_image(summary)} image: a median {np.median(outside):.0%} "
            f"of each person{place} ({len(outside)} people in {frames}, {(outside > OUTSIDE_SHARE).sum()} of them "
            f"mostly outside): {_cause(summary, people.evidence_outside[inside])}")


def _image(summary: FitSummary) -> str:
    """The image size(s) seen: '812x720' (or '640x480 or 1280x720')."""
    return " or ".join(f"{w}x{h}" for w, h in summary.image_sizes)


def _cause(summary: FitSummary, evidence_outside: np.ndarray) -> str:
    """What to suspect: the image size when the people's own 2D evidence (``evidence_outside`` (N,), the
    share of each person's outside the image) lies mostly outside the image too, else the body model
    (named when the import posed the meshes with one) or the image size."""
    known = evidence_outside[np.isfinite(evidence_outside)]
    if len(known) and np.median(known) > OUTSIDE_SHARE:
        return f"their {summary.evidence} lie outside the {_image(summary)} image too: a wrong --image-size"
    model = f"--smpl-model {summary.body_model}" if summary.body_model else "--smpl-model"
    suspects = f"a wrong or mismatched body model ({model}), or a wrong --image-size"
    return f"its meshes reproject {summary.reprojects}, or {suspects}" if summary.reprojects else suspects


def model_fit_finding(seq: Sequence, label: str | None = None, max_frames: int = MAX_FRAMES) -> str | None:
    """One line when ``seq``'s meshes (or joints) do not fit its own pixels: most people far from their own 2D
    keypoints (or foot and crown points), or projected outside the image; None when they fit or nothing
    could be measured. ``label`` names the sequence (default ``seq.label``). Reads at most ``max_frames``
    frames (:func:`sampled_names`)."""
    return fit_finding(sequence_model_fit(seq, max_frames), seq.label if label is None else label)
