"""The body model a tool's parameters need: the family checked against ``--smpl-model``, the model
required when a format stores parameters only, the warning when it is missing, its faces for meshes."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import file_error
from .smpl import BodyModel

__all__ = ["check_model_kind", "model_faces", "no_model_warning", "require_model"]

_MODEL_FILES = {"smpl": ("SMPL", 24, "SMPL_NEUTRAL.npz"), "smplx": ("SMPL-X", 55, "SMPLX_NEUTRAL.npz"),
                "smplh": ("SMPL-H", 52, "the SMPL-H model.npz")}


def check_model_kind(model: BodyModel | None, source: Any, tool: str, kind: str) -> BodyModel | None:
    """``model`` when it is of the family the tool's parameters are (``kind``: smpl | smplx | smplh)
    or None; an InputError naming the file, the tool and the joint count it needs otherwise."""
    family, joints, _ = _MODEL_FILES[kind]
    if model is not None and model.kind != kind:
        raise file_error(source, f"{tool} uses {family}; --smpl-model {model.name} has {model.n_joints} joints "
                                 f"(need {joints})")
    return model


def require_model(model: BodyModel | None, source: Any, tool: str, kind: str) -> BodyModel:
    """The body model a format that stores nothing but parameters needs (:func:`check_model_kind`);
    an InputError saying to pass it when it is missing."""
    family, _, file_name = _MODEL_FILES[kind]
    if model is None:
        raise file_error(source, f"{tool} stores {family} parameters only (no joints, no 2D keypoints): pass "
                                 f"--smpl-model {file_name} (the {family} model file) to pose them")
    return check_model_kind(model, source, tool, kind)


def no_model_warning(fmt: str) -> str:
    """The message for parameter-only formats imported without --smpl-model."""
    return (f"{fmt} stores SMPL parameters, not meshes, and no --smpl-model was given: imported joints only; "
            "PVE/W-PVE are unavailable and align works at joint level (from the 2D keypoints' feet and heads)")


def model_faces(model: BodyModel | None, n_verts: int | None) -> np.ndarray | None:
    """The body model's triangles when they fit meshes of ``n_verts`` vertices."""
    if model is None or model.faces is None or n_verts is None or model.n_verts != n_verts:
        return None
    return model.faces
