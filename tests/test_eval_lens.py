"""eval matches people in the image: a sequence in its camera (ground truth, aligned output) projects its joints
through the camera's lens (Sequence.image_lens), as the HPS method's own pinhole drew them."""

from __future__ import annotations

import numpy as np

from rotavat_cli.geometry.camera import Camera, project_cam_to_px
from rotavat_cli.metrics.evaluate import EvalOptions, match_frame
from rotavat_cli.sequence import Frame, Intrinsics, open_sequence, write_camera_yaml, write_frame, write_meta

CAM = Camera((1280, 720), 900.0, None, np.deg2rad(20.0), 0.0, 4.0, distortion=-0.3)


def _people_near_the_corners() -> np.ndarray:
    """(2, 24, 3) joints of two people standing near the left and right image borders, camera frame (m)."""
    feet = CAM.backproject_px_to_ground(np.array([[90.0, 650.0], [1190.0, 640.0]]))
    offsets = np.linspace(0.0, 1.6, 24)[:, None] * CAM.up_cam  # a vertical column of joints
    return feet[:, None, :] + offsets[None]


def test_the_ground_truths_joints_are_projected_through_its_lens_to_match_the_methods_pixels():
    gt_joints = _people_near_the_corners()
    drawn = CAM.project(gt_joints)  # where the people are in the image
    # the method's pinhole (its own focal) drew them at those image pixels, at its own depth
    method_f = 1500.0
    rays = np.concatenate([(drawn - CAM.principal_point) / method_f, np.ones(drawn.shape[:-1] + (1,))], axis=-1)
    pred_joints = rays * 8.0
    np.testing.assert_allclose(project_cam_to_px(pred_joints, method_f, CAM.principal_point), drawn, atol=1e-9)
    pred = Frame("000000", {"joints": pred_joints, "person_ids": np.array([0, 1])})
    gt = Frame("000000", {"joints": gt_joints, "person_ids": np.array([5, 6])})
    opts = EvalOptions(match="hungarian", threshold_px=20.0)
    pred_intr = Intrinsics(CAM.image_size, method_f, CAM.principal_point)
    gt_intr = Intrinsics(CAM.image_size, CAM.focal_px, CAM.principal_point)
    pi, gi, _ = match_frame(pred, gt, pred_intr, gt_intr, opts, lenses=(None, CAM))
    assert pi.tolist() == [0, 1] and gi.tolist() == [0, 1]
    # as a pinhole, the ground truth's corners sit tens of pixels away: nobody within 20 px
    pi, _, _ = match_frame(pred, gt, pred_intr, gt_intr, opts)
    assert len(pi) == 0


def test_only_a_sequence_in_its_camera_with_a_lens_has_one(tmp_path):
    for name, kind, lam in (("gt", "camera", -0.3), ("pred", "assumed", -0.3), ("flat", "camera", 0.0)):
        seq = tmp_path / name
        write_frame(seq, Frame("000000", {"joints": _people_near_the_corners()}), "npz")
        write_meta(seq, {"image_size": [1280, 720], "focal_length": 900.0, "focal_kind": kind})
        write_camera_yaml(seq / "camera.yaml", CAM.replace(distortion=lam))
    lenses = {name: open_sequence(tmp_path / name).image_lens for name in ("gt", "pred", "flat")}
    assert lenses["gt"] is not None and lenses["gt"].distortion == -0.3
    assert lenses["pred"] is None and lenses["flat"] is None
