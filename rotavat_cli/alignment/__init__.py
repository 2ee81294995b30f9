"""Alignment: the RotAvat transform (:mod:`.transform`, pure and vectorised over people) and its
application to frames and whole sequences (:mod:`.align`: re-expression into the camera, people.csv);
which camera a sequence is aligned into (:mod:`.camera_choice`) and the gate every camera passes before
align, render or batch use it (:mod:`.camera_gate`); its options (:mod:`.options`)."""

from .align import (IMPLAUSIBLE_STATURE, PEOPLE_COLUMNS, AlignSummary, MeshIntrinsics, align_frame, align_sequence,
                    aligned_meta, frame_foot_head_cam, summarize_people_csv, track_statures)
from .camera_choice import CALIBRATED, GIVEN, AlignCamera, camera_for_align
from .camera_gate import (ImplausibleCameraError, Remedies, accepted_fit, align_remedies, batch_remedies,
                          check_align_camera, check_fit, implausible_findings, is_accepted, reader_flags,
                          render_remedies)
from .options import HEIGHT_FROM, AlignOptions
from .transform import FLAGS, UPRIGHT, AlignTransform, apply_transforms, method_rays_cam, rotavat_transforms

__all__ = ["HEIGHT_FROM", "IMPLAUSIBLE_STATURE", "PEOPLE_COLUMNS", "AlignOptions", "AlignSummary", "MeshIntrinsics",
           "align_frame", "align_sequence", "aligned_meta", "frame_foot_head_cam", "summarize_people_csv",
           "track_statures", "FLAGS", "UPRIGHT",
           "AlignTransform", "apply_transforms", "method_rays_cam", "rotavat_transforms", "CALIBRATED", "GIVEN",
           "AlignCamera", "camera_for_align", "ImplausibleCameraError", "Remedies", "accepted_fit", "align_remedies",
           "batch_remedies", "check_align_camera", "check_fit", "implausible_findings", "is_accepted", "reader_flags",
           "render_remedies"]
