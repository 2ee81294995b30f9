"""The ``meta.yaml`` content of an import: what every format writes (:func:`base_meta`) and which
points gave its foot and head pixels (:func:`feet_heads_from`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..bodies.joint_layouts import layout_key
from .imported import ImportOptions
from .keypoints import recipe_for

__all__ = ["base_meta", "feet_heads_from"]


def base_meta(fmt: str, src: Path, opts: ImportOptions, image_size: tuple[int, int] | None,
              focal_px: float | None, principal_point: tuple[float, float] | None, *, focal_kind: str,
              focal_rule: str | None = None) -> dict:
    """meta.yaml content common to all formats (plain types only).

    focal_kind: ``camera`` when the tool's focal is the camera's own (ground truth), ``assumed``
    when the tool guessed it (its documented rule, ``focal_rule``; rotavat.focal).
    """
    meta: dict[str, Any] = {"source": fmt, "focal_kind": focal_kind}
    if focal_rule is not None:
        meta["focal_rule"] = focal_rule
    if image_size is not None:
        meta["image_size"] = [int(image_size[0]), int(image_size[1])]
    if focal_px is not None:
        meta["focal_length"] = float(focal_px)
    if principal_point is not None:
        meta["principal_point"] = [float(principal_point[0]), float(principal_point[1])]
    if opts.body_model is not None:  # the model the meshes (and any body-model parameters) were made with
        model = opts.body_model
        meta["body_model"] = {"kind": model.kind, "file": model.name, "joints": model.n_joints}
    meta["import"] = {
        "format": fmt,
        "source_path": str(src.resolve()),
        "body_model": opts.body_model.name if opts.body_model is not None else None,
    }
    return meta


def feet_heads_from(keypoints_layout: str | None, has_vertices: bool) -> str | None:
    """meta.yaml ``import.feet_heads_from``: which points give the foot and head pixels of an import."""
    if has_vertices:
        return "mesh landmarks (sole vertices' ground contact, crown vertex)"
    recipe = recipe_for(keypoints_layout)
    return None if recipe is None else (f"keypoints_2d, {layout_key(keypoints_layout)}: {recipe.describes}; foot point "
                                        "moved to the ground contact where the 3D joints show one foot raised")
