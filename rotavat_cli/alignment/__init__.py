"""Alignment: the RotAvat transform (:mod:`.transform`, pure and vectorised over people) and its
application to frames and whole sequences (:mod:`.align`: re-expression into the camera, people.csv);
who of a track is in the air (:mod:`.flight`);
which camera a sequence is aligned into (:mod:`.camera_choice`) and the gate every camera passes before
align, render or batch use it (:mod:`.camera_gate`); its options (:mod:`.options`)."""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".align": (
        "FLIGHT", "IMPLAUSIBLE_STATURE", "PEOPLE_COLUMNS", "AlignSummary", "align_frame", "align_sequence",
        "aligned_meta", "flight_plan", "summarize_people_csv", "track_statures"
    ),
    ".flight": ("foot_elevation_m", "flight_rows"),
    ".camera_choice": ("CALIBRATED", "GIVEN", "AlignCamera", "camera_for_align"),
    ".camera_gate": (
        "ImplausibleCameraError", "Remedies", "accepted_fit", "align_remedies", "batch_remedies",
        "check_align_camera", "check_fit", "implausible_findings", "is_accepted", "reader_flags", "render_remedies"
    ),
    ".options": ("HEIGHT_FROM", "AlignOptions"),
    ".transform": ("FLAGS", "UPRIGHT", "AlignTransform", "apply_transforms", "method_rays_cam", "rotavat_transforms"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
