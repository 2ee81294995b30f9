"""The contract frame a reader builds for one image: its people's arrays validated, people with
non-finite vertices or joints dropped, and foot/head pixels from the 2D keypoints when no mesh gives
them (:mod:`.keypoints`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import file_error
from ..bodies.joint_layouts import layout_by_count
from ..sequence import Frame, validate_frame
from .ids import check_int64_ids
from .keypoints import feet_heads_px

__all__ = ["people_frame"]


def people_frame(name: str, source: Any, warnings: list[str], *, vertices: np.ndarray | None = None,
                 joints: np.ndarray | None = None, keypoints_2d: np.ndarray | None = None,
                 person_ids: np.ndarray | None = None, faces: np.ndarray | None = None,
                 n_verts: int | None = None, extra: Mapping[str, np.ndarray] | None = None,
                 keypoints_layout: str | None = None, boxes_2d: np.ndarray | None = None,
                 joints_layout: str | None = None, body_params: Mapping[str, np.ndarray] | None = None) -> Frame:
    """A validated contract frame; people with non-finite vertices or joints are dropped (with a warning).

    keypoints_layout: the layout of ``keypoints_2d`` (:mod:`.keypoints`); when it has a recipe and
    the frame has no meshes, ``feet_2d``/``heads_2d`` (foot point, crown) are written from them, so
    calibration and joint-level alignment work without a body model (meshes give their own
    landmarks, which take precedence: :func:`.meta.feet_heads_from`). The foot point is the ground
    contact when the frame's 3D ``joints`` show which foot is lower (their layout ``joints_layout``, by
    default the SMPL family's of their count; :func:`.keypoints.feet_heads_px`), else the mid-sole. A
    person missing a recipe point gets a NaN row (calibration drops the pair, align flags the person).

    boxes_2d: (P, 4) the tool's own person boxes [x1, y1, x2, y2] px, where it stores nothing else in 2D
    (GVHMR's crops): evidence that the meshes fit the image (:mod:`.model_fit`).
    body_params: the people's body-model parameters (:func:`.smpl.smpl_param_arrays`, P rows each), kept
    in float64 for the people kept.
    """
    arrays = {"vertices": vertices, "joints": joints, "keypoints_2d": keypoints_2d, "boxes_2d": boxes_2d,
              "person_ids": person_ids}
    counts = {k: len(v) for k, v in arrays.items() if v is not None}
    if len(set(counts.values())) > 1:
        raise file_error(source, f"inconsistent people counts ({', '.join(f'{k}={v}' for k, v in counts.items())})")
    n_people = next(iter(counts.values()), 0)
    keep = np.ones(n_people, dtype=bool)
    for key in ("vertices", "joints"):
        if arrays[key] is not None and n_people:
            keep &= np.isfinite(arrays[key]).reshape(n_people, -1).all(axis=1)
    if not keep.all():
        warnings.append(f"{source}: dropped {int((~keep).sum())} person(s) with non-finite vertices or joints")
    if person_ids is not None:
        check_int64_ids(np.asarray(person_ids), source)
    data: dict[str, np.ndarray] = {}
    for key, value in arrays.items():
        if value is None:
            continue
        value = value[keep]
        with np.errstate(over="ignore", invalid="ignore"):  # out-of-range values become inf: refused below
            data[key] = value.astype(np.int64) if key == "person_ids" else value.astype(np.float32)
    if "vertices" not in data and n_verts is not None and not keep.any():
        data["vertices"] = np.zeros((0, n_verts, 3), np.float32)
    if faces is not None and "vertices" in data and data["vertices"].shape[1] == 0:
        faces = None
    if faces is not None:
        data["faces"] = faces.astype(np.int32)
    if "person_ids" in data and len(np.unique(data["person_ids"])) != len(data["person_ids"]):
        warnings.append(f"{source}: duplicate person ids in one frame; ids dropped for this frame")
        del data["person_ids"]
    if not data:
        data["person_ids"] = np.zeros(0, np.int64)
    if keypoints_layout is not None and "keypoints_2d" in data and "vertices" not in data:
        joints3d = data.get("joints")
        if joints_layout is None and joints3d is not None:
            joints_layout = layout_by_count(joints3d.shape[1])
        found = feet_heads_px(data["keypoints_2d"], keypoints_layout, joints3d, joints_layout)
        if found is not None:
            data["feet_2d"], data["heads_2d"] = (points.astype(np.float32) for points in found[:2])
    data.update({key: np.asarray(value, dtype=np.float64)[keep] for key, value in (body_params or {}).items()})
    data.update(extra or {})
    validate_frame(data, str(source))
    return Frame(name, data, str(source))
