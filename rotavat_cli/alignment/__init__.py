"""Alignment: the RotAvat transform (:mod:`.transform`, pure and vectorised over people) and its
application to frames and whole sequences (:mod:`.align`: re-expression into the camera, people.csv)."""

from .align import (HEIGHT_FROM, IMPLAUSIBLE_STATURE, PEOPLE_COLUMNS, STATURE_RANGE_M, AlignSummary, MeshIntrinsics,
                    align_frame, align_sequence, aligned_meta, summarize_people_csv, track_statures)
from .transform import FLAGS, UPRIGHT, AlignTransform, apply_transforms, method_rays_cam, rotavat_transforms

__all__ = ["HEIGHT_FROM", "IMPLAUSIBLE_STATURE", "PEOPLE_COLUMNS", "STATURE_RANGE_M", "AlignSummary", "MeshIntrinsics",
           "align_frame", "align_sequence", "aligned_meta", "summarize_people_csv", "track_statures", "FLAGS", "UPRIGHT",
           "AlignTransform", "apply_transforms", "method_rays_cam", "rotavat_transforms"]
