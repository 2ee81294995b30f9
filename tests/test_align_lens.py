"""align through a camera with a lens (camera.yaml's ``distortion``): each person keeps the image pixels of
its foot and crown that the method drew, the lens removed from the rays (rotavat_cli/alignment/align.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rotavat_cli.alignment.align import align_frame
from rotavat_cli.bodies.frame_points import MeshIntrinsics, frame_foot_head_cam
from rotavat_cli.geometry.camera import project_cam_to_px
from rotavat_cli.synth import SynthOptions, synth_frames


@pytest.fixture(scope="module")
def scene():
    camera, focal, frames = synth_frames(SynthOptions(seed=4, frames=1, people=6))
    _, pred = next(frames)
    return camera, pred


@pytest.mark.parametrize("distortion", [-0.25, 0.15])
def test_the_drawn_foot_and_crown_pixels_are_kept_in_the_image(scene, distortion):
    camera, pred = scene
    lensed = camera.replace(distortion=distortion)
    mesh = MeshIntrinsics(np.full(pred.n_people, float(pred.data["focal_length"])), lensed.principal_point)
    feet_cam, heads_cam = frame_foot_head_cam(pred, mesh)
    drawn_feet = project_cam_to_px(feet_cam, mesh.focal_px, mesh.principal_point)
    drawn_heads = project_cam_to_px(heads_cam, mesh.focal_px, mesh.principal_point)
    aligned, cols = align_frame(pred, lensed)
    ok = np.array(cols["flag"]) == ""
    assert ok.sum() >= 4
    new_feet, new_heads = frame_foot_head_cam(aligned, MeshIntrinsics.of_frame(aligned, None, lensed))
    feet_px, heads_px = lensed.project(new_feet), lensed.project(new_heads)
    np.testing.assert_allclose(feet_px[ok], drawn_feet[ok], atol=1e-3)  # through the lens: the same image pixels
    assert np.all(np.abs(lensed.height_above_ground(new_feet[ok])) < 1e-6)  # on the ground
    # the crown stays on its ray in the paper's upright (the head pixel kept up to head_drift_px)
    np.testing.assert_allclose(heads_px[ok], drawn_heads[ok], atol=np.max(cols["head_drift_px"][ok]) + 1e-3)
    # without the lens (a pinhole with the same focal), the feet would land elsewhere in the image
    pinhole_feet, _ = frame_foot_head_cam(align_frame(pred, camera)[0], mesh)
    assert np.max(np.abs(lensed.project(pinhole_feet[ok]) - drawn_feet[ok])) > 2.0
