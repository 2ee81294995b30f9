"""The per-person metrics: a registry (a new metric = one entry) and the matched pairs they score.

Each :class:`PersonMetric` names the metrics it reports and computes them from the matched pairs
(:class:`MatchedPairs`) and the two cameras; :data:`PERSON_METRICS` lists every registered name in
report order. A metric of a frame's whole group (group PA-MPJPE, PCRD: :mod:`.multi_person`) is
still one value per matched person, and says how a sequence pools them (:data:`PERSON_METRIC_POOLS`:
per frame, per pair of people; the others: the mean over matched people). :mod:`.protocols` says
which of them each benchmark reports and under which name, :mod:`.evaluate` scores them, and
metrics.json and the per-person CSV list them.
"""

from __future__ import annotations

from collections.abc import Callable
from collections.abc import Sequence as Seq
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera
from ..bodies.landmarks import foot_head_points
from .fused import person_errors_mm
from .multi_person import depth_order_shares, group_pa_errors_mm, mean_over_groups, pooled_over_pairs
from .scene import lean_deg, root_err_mm, stature_err_mm

__all__ = ["MatchedPairs", "concat_pairs", "PersonMetric", "PERSON_METRIC_FAMILIES", "PERSON_METRICS",
           "PERSON_METRIC_POOLS"]


@dataclass(frozen=True)
class MatchedPairs:
    """The matched people of one or more frames, gathered: joints (M, J, 3) (the protocol's joint
    set), their roots (M, 3) float64 (the protocol's rule, from all the joints), vertices (M, V, 3); or None;
    frames (M,) int: the frame of each pair, 0, 1, ... in gathering order (None: all of one frame)."""

    pred_joints: np.ndarray | None
    gt_joints: np.ndarray | None
    pred_verts: np.ndarray | None
    gt_verts: np.ndarray | None
    pred_root: np.ndarray | None = None
    gt_root: np.ndarray | None = None
    frames: np.ndarray | None = None

    def __len__(self) -> int:
        """The number of matched pairs."""
        return next((len(a) for a in (self.pred_joints, self.pred_verts, self.pred_root, self.frames)
                     if a is not None), 0)

    def frame_of_each(self) -> np.ndarray:
        """(M,) int: the frame of each pair (zeros when the gathering is one frame)."""
        return self.frames if self.frames is not None else np.zeros(len(self), np.int64)

    def kind(self) -> tuple:
        """What must agree for two gatherings to be scored in one call: which arrays, their point counts, dtypes."""
        return tuple(None if a is None else (a.shape[1], a.dtype.str)
                     for a in (self.pred_joints, self.gt_joints, self.pred_verts, self.gt_verts))


_PAIR_FIELDS = ("pred_joints", "gt_joints", "pred_verts", "gt_verts", "pred_root", "gt_root")


def concat_pairs(parts: Seq[MatchedPairs]) -> MatchedPairs:
    """One gathering from several of the same kind, in order; each part's frames follow the previous part's."""
    if len(parts) == 1:
        return parts[0]
    frames, offset = [], 0
    for part in parts:
        own = part.frame_of_each()
        frames.append(own + offset)
        offset += int(own.max()) + 1 if len(own) else 0
    return MatchedPairs(*(None if getattr(parts[0], f) is None else np.concatenate([getattr(p, f) for p in parts])
                          for f in _PAIR_FIELDS), frames=np.concatenate(frames))


@dataclass(frozen=True)
class PersonMetric:
    """One family of per-person metrics: the names it reports and how to compute them from matched pairs.

    ``compute(pairs, pred_cam, gt_cam, engine)`` returns a dict name -> (M,) values for the names it
    can compute (a missing name stays NaN: e.g. no vertices, no ground-truth camera); ``engine`` is
    the vertex metrics' engine (:data:`.fused.ENGINES`). ``pool(values, frames)`` turns a sequence's
    per-person values (M,) and their frame names (M,) into its value (None: the mean of the finite
    values); ``no_value`` is the note when a sequence with matched pairs gets none.
    """

    names: tuple[str, ...]
    compute: Callable[[MatchedPairs, Camera | None, Camera | None, str], dict[str, np.ndarray]]
    pool: Callable[[np.ndarray, np.ndarray], float] | None = None
    no_value: str = ""


def _errors(pairs: MatchedPairs, pred_cam: Camera | None, gt_cam: Camera | None, engine: str) -> dict[str, np.ndarray]:
    """MPJPE, PA-MPJPE, W-MPJPE, PVE, PA-PVE, W-PVE and SPEC's pair, in one fused pass (:func:`.fused.person_errors_mm`)."""
    rotations = (pred_cam.R_cam_from_world.T, gt_cam.R_cam_from_world.T) if pred_cam and gt_cam else (None, None)
    return person_errors_mm(pairs.pred_joints, pairs.gt_joints, pairs.pred_verts, pairs.gt_verts, *rotations,
                            engine=engine, pred_root=pairs.pred_root, gt_root=pairs.gt_root)


def _root_error(pairs: MatchedPairs, pred_cam: Camera | None, gt_cam: Camera | None, engine: str) -> dict[str, np.ndarray]:
    """Pelvis position error, no alignment (scored where the ground truth has a camera, as the ground-aware ones)."""
    if pairs.pred_root is None or gt_cam is None:
        return {}
    return {"root_err": root_err_mm(pairs.pred_root, pairs.gt_root)}


def _ground_aware(pairs: MatchedPairs, pred_cam: Camera | None, gt_cam: Camera | None, engine: str) -> dict[str, np.ndarray]:
    """Foot height above the true ground, lean from the true vertical, stature error (meshes and a true camera)."""
    if gt_cam is None or pairs.pred_verts is None:
        return {}
    feet_p, heads_p = foot_head_points(pairs.pred_verts)
    feet_g, heads_g = foot_head_points(pairs.gt_verts)
    return {"foot_height": np.abs(gt_cam.height_above_ground(feet_p)) * 1000.0,
            "lean_deg": lean_deg(feet_p, heads_p, gt_cam.up_cam),
            "stature_err": stature_err_mm(feet_p, heads_p, feet_g, heads_g)}


def _group_alignment(pairs: MatchedPairs, pred_cam: Camera | None, gt_cam: Camera | None,
                     engine: str) -> dict[str, np.ndarray]:
    """Each person's joint error after one similarity fitted to its frame's matched people together."""
    if pairs.pred_joints is None:
        return {}
    return {"group_pa_mpjpe": group_pa_errors_mm(pairs.pred_joints, pairs.gt_joints, pairs.frame_of_each())}


def _depth_order(pairs: MatchedPairs, pred_cam: Camera | None, gt_cam: Camera | None,
                 engine: str) -> dict[str, np.ndarray]:
    """Each person's share of right depth relations (root z) with the other matched people of its frame."""
    if pairs.pred_root is None:
        return {}
    return {"pcrd": depth_order_shares(pairs.pred_root[:, 2], pairs.gt_root[:, 2], pairs.frame_of_each())}


_NO_GROUP = "no frame has two matched people with joints"
PERSON_METRIC_FAMILIES: tuple[PersonMetric, ...] = (
    PersonMetric(("mpjpe", "pa_mpjpe", "w_mpjpe", "pve", "pa_pve", "w_pve", "w_mpjpe_spec", "w_pve_spec"), _errors),
    PersonMetric(("root_err",), _root_error),
    PersonMetric(("foot_height", "lean_deg", "stature_err"), _ground_aware),
    PersonMetric(("group_pa_mpjpe",), _group_alignment, mean_over_groups, _NO_GROUP),  # per frame
    PersonMetric(("pcrd",), _depth_order, pooled_over_pairs, _NO_GROUP),  # per pair of people
)
PERSON_METRICS = tuple(name for family in PERSON_METRIC_FAMILIES for name in family.names)  # report order
# name -> (how a sequence pools its per-person values, the note when it gets none), for the metrics not
# simply averaged over matched people.
PERSON_METRIC_POOLS: dict[str, tuple[Callable[[np.ndarray, np.ndarray], float], str]] = {
    name: (family.pool, family.no_value) for family in PERSON_METRIC_FAMILIES if family.pool for name in family.names}
