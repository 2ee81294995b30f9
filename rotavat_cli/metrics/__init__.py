"""Per-person error metrics for multi-person HPS evaluation: pure arrays, no I/O.

Inputs are metres (any float dtype); outputs are float64 and carry their unit in the name
(``*_mm``, ``*_deg``, ``*_pct``). Point sets are ``(P, N, 3)``: ``P`` people, ``N`` joints or
vertices, all in one frame (the camera frame of docs/conventions.md). Every function is
vectorised over people (one batched SVD for Procrustes, no per-person loop), and ``P = 0`` is
valid everywhere.

One switch picks the alignment, so the metric families cannot drift apart:

- ``alignment="none"``: W-MPJPE / W-PVE (no alignment at all; rotavat's definition),
- ``alignment="root"``: MPJPE / PVE (pelvis joint subtracted on both sides),
- ``alignment="procrustes"``: PA-MPJPE / PA-PVE (per-person similarity, Umeyama).

SPEC's "W-MPJPE" is a different quantity (gravity frame + pelvis alignment); it lives in
:func:`w_spec_errors_mm`, see the note there.

Precision: the single-metric functions compute in float64; :func:`person_errors_mm` works in
float32 per vertex, within 2e-4 mm of them on realistic scenes (see :mod:`.fused`). Its vertex
pass runs compiled (numba, :mod:`._compiled`) when ``rotavat[fast]`` is installed, else numpy.

Modules: :mod:`.points` (the single-metric functions, float64), :mod:`.fused`
(:func:`person_errors_mm`, all of them at once for ``evaluate``; its precision note),
:mod:`.scene` (ground-aware, detection and camera errors), :mod:`.temporal` (acceleration error,
jitter, foot sliding, GVHMR's chunked W-/WA-MPJPE and RTE of tracks), :mod:`.ground_free` (the
measures without ground truth: feet height, penetration, sliding on contact, lean, stature,
acceleration) and :mod:`.ground_free_eval` (a sequence measured in its scene camera), :mod:`.person_metrics` (the
registry of per-person metrics ``evaluate`` scores), :mod:`.multi_person` (a frame's matched people
together: group PA-MPJPE, BEV's PCRD), :mod:`.protocols` (each benchmark's root, joint set, matching,
units and rounding: ``evaluate(..., protocol=...)``).
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    "._common": ("ALIGNMENTS", "CAMERA_KEYS", "Alignment"),
    ".fused": (
        "ENGINES", "JOINT_ERROR_KEYS", "VERTEX_ERROR_KEYS", "compiled_kernels", "person_errors_mm", "resolve_engine"
    ),
    ".points": (
        "mpjpe", "point_errors_mm", "procrustes_align", "pve", "to_gravity_frame", "umeyama", "w_spec_errors_mm",
        "w_spec_mpjpe", "w_spec_pve"
    ),
    ".ground_free": (
        "acceleration_m", "consecutive_windows", "contact_sliding_m", "feet_height_summary", "lean_summary",
        "stature_summary"
    ),
    ".ground_free_eval": ("GroundFreeResult", "SceneCamera", "measure_sequence", "scene_cameras"),
    ".multi_person": (
        "DEPTH_EQUAL_M", "depth_order_shares", "group_pa_errors_mm", "group_pairs", "mean_over_groups", "pcrd",
        "pooled_over_pairs"
    ),
    ".scene": (
        "camera_errors", "detection_scores", "lean_deg", "normalize_by_f1", "root_err_mm", "stature_err_mm",
        "stature_m"
    ),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
