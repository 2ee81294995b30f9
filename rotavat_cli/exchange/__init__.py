"""Whole sequences in other tools' formats: an animated glTF scene, BVH skeletons, AMASS-style parameters.

Modules (docs/export.md):

- :mod:`.glb`: a glTF 2.0 binary written in two passes (layout, then bytes), memory flat in the frames;
- :mod:`.scan`: the first pass (who is in which frame, what each person is drawn from);
- :mod:`.scene`: the document's shared parts (camera node, ground, frustum, materials, keyframe times);
- :mod:`.frames`: people as one mesh per person-frame, shown on its frame only;
- :mod:`.skinned`: people as skinned body models (rest mesh, skeleton, keyframes);
- :mod:`.animated`: :func:`export_animated`, what ``rotavat export SEQ`` (no ``--frame``) runs;
- :mod:`.body`: body-model parameters in the world, rest shapes, quaternions;
- :mod:`.motion`, :mod:`.bvh`, :mod:`.amass`: each track's motion as BVH or an AMASS-style ``.npz``;
- :mod:`.options`: :class:`ExportOptions` (section ``export`` of configs/default.yaml).
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".animated": ("animated_steps", "export_animated"),
    ".amass": ("R_AMASS_FROM_WORLD", "amass_arrays", "gender_from_model_name"),
    ".body": ("BodyFrame", "body_frame", "joint_names", "rest_shape"),
    ".bvh": ("BvhData", "bvh_joint_positions", "bvh_text", "read_bvh"),
    ".glb": ("BinLayout", "GlbWriter", "json_chunk"),
    ".motion": ("TrackMotion", "export_motion", "motion_steps"),
    ".options": ("EULER_ORDERS", "FORMATS", "ExportOptions", "sequence_fps"),
    ".skinned": ("inverse_bind_matrices", "skin_weights"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
