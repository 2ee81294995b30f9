"""Writers of WHAM and HybrIK output files, laid out as their demos write them (structure only,
read from the tools' code; nothing copied): see the module docstrings of
``rotavat_cli/formats/wham.py`` and ``rotavat_cli/formats/hybrik.py`` for the sources.

People come from ``_format_fixtures`` scenes (camera-frame ground truth computed without the
readers), so the tests check that the importers undo each tool's conventions.
"""

from __future__ import annotations

import pickle
from collections import defaultdict
from pathlib import Path

import _format_fixtures as F
import numpy as np

HYBRIK_FOCAL_ON_256 = 1000.0  # demo_video.py: focal = 1000 / 256 * box width


def write_wham(path: Path, scene, world_offset=(5.0, 1.0, -2.0)) -> Path:
    """demo.py --save_pkl: joblib dump of defaultdict(dict) {track id: per-track arrays}.

    verts = SMPL(pose, betas) + trans in the camera frame (the scene's verts_cam); the world
    trajectory (pose_world, trans_world) is deliberately elsewhere, so a reader using it is caught.
    """
    rows: dict[int, list] = {}
    for frame_id, frame in enumerate(scene):
        for person in frame:
            rows.setdefault(person.pid, []).append((frame_id, person))
    results = defaultdict(dict)
    for pid, seen in rows.items():
        people = [p for _, p in seen]
        pose = np.stack([p.pose.reshape(72) for p in people]).astype(np.float32)
        pose_world = pose.copy()
        pose_world[:, :3] = [np.pi / 2, 0.0, 0.0]
        results[np.int64(pid)] = {
            "pose": pose,
            "trans": np.stack([p.transl for p in people]).astype(np.float32),
            "pose_world": pose_world,
            "trans_world": (np.stack([p.transl for p in people]) + np.asarray(world_offset)).astype(np.float32),
            "betas": np.stack([p.betas for p in people]).astype(np.float32),
            "verts": np.stack([p.verts_cam for p in people]).astype(np.float32),
            "frame_ids": np.array([i for i, _ in seen], dtype=np.int64),
        }
    path.write_bytes(F.joblib_bytes(results))
    return path


def hybrik_joints29(person: F.Person) -> np.ndarray:
    """(29, 3) camera-frame joints: the person's SMPL-24, then 5 stand-ins for HybrIK's leaf vertices."""
    return np.concatenate([person.joints_cam, F.fake_extra_joints(person, 5)])


def hybrik_box_width(person: F.Person) -> float:
    """The crop-box side (px) the fixture gives a person: differs per person, so each has its own focal."""
    return 150.0 + 10.0 * person.pid


def hybrik_row(person: F.Person, image_size, depth_factor_m: float = 2.2) -> dict:
    """One res_db row for ``person`` as HRNetSMPLCam.forward makes it (unbatched, as the demo appends)."""
    width, height = image_size
    side = hybrik_box_width(person)
    focal = HYBRIK_FOCAL_ON_256 / 256.0 * side
    joints = hybrik_joints29(person)
    uv_px = F.project(joints, focal, (width / 2, height / 2))
    centre = uv_px.mean(axis=0)
    root = joints[0]
    xyz_rel = (joints - root) / depth_factor_m
    uvd = np.concatenate([(uv_px - centre) / side, xyz_rel[:, 2:3]], axis=1)  # d: root-relative depth, same unit
    return {
        "pred_uvd": uvd.astype(np.float32),
        "pred_xyz_17": np.zeros((17, 3), np.float32),
        "pred_xyz_29": xyz_rel.astype(np.float32),
        "pred_xyz_24_struct": xyz_rel[:24].astype(np.float32),
        "pred_scores": np.full(29, 0.02, np.float32),
        "pred_camera": np.array([0.9], np.float32),
        "pred_betas": person.betas.astype(np.float32),
        "pred_thetas": F.rotmats(person.pose).reshape(216).astype(np.float32),
        "pred_phi": np.tile(np.array([1.0, 0.0], np.float32), (23, 1)),
        "pred_cam_root": root.astype(np.float32),
        "transl": root.astype(np.float32),  # cam_root minus the root of the root-centred SMPL output (0)
        "transl_camsys": (root * 256 / side).astype(np.float32),
        "bbox": np.array([centre[0] - side / 2, centre[1] - side / 2, centre[0] + side / 2, centre[1] + side / 2]),
        "height": np.int64(height),
        "width": np.int64(width),
    }


def hybrik_res_db(scene, image_size, depth_factor_m: float = 2.2, drop=(), video: str = "walk") -> dict:
    """res_db of demo_video.py on one video: one stacked row per (image, person); images with nobody are
    skipped, as the demo skips images without a detection; the images are ffmpeg's
    ``<out-dir>/raw_images/<video>-%06d.png``. ``drop``: keys left out."""
    rows: dict[str, list] = {}
    for i, frame in enumerate(scene):
        for person in frame:
            row = hybrik_row(person, image_size, depth_factor_m)
            row["img_path"] = f"res_walk/raw_images/{video}-{i + 1:06d}.png"
            for key, value in row.items():
                rows.setdefault(key, []).append(value)
    return {key: np.stack(values) for key, values in rows.items() if key not in drop}


def write_hybrik(path: Path, scene, image_size, depth_factor_m: float = 2.2, drop=(), video: str = "walk") -> Path:
    """demo_video.py --save-pk: pickle.dump of res_db (:func:`hybrik_res_db`)."""
    path.write_bytes(pickle.dumps(hybrik_res_db(scene, image_size, depth_factor_m, drop, video)))
    return path


def write_hybrik_videos(path: Path, videos) -> Path:
    """demo_video.py run on several videos with one --out-dir: ``raw_images/`` keeps the earlier videos'
    frames, and the demo processes every file there, sorted by name, so res.pk holds each video's rows one
    video after the other. ``videos``: (video name, scene, image size) in that (name) order."""
    parts = [hybrik_res_db(scene, size, video=name) for name, scene, size in videos]
    path.write_bytes(pickle.dumps({key: np.concatenate([part[key] for part in parts]) for key in parts[0]}))
    return path


def single_person_scene(model, camera, n_frames: int = 3) -> list[list[F.Person]]:
    """The demo's case: one (tracked) person per image, walking away from the camera."""
    return [[F.standing_person(model, camera, -0.5 + 0.2 * i, -7.0 - 0.5 * i, 0)] for i in range(n_frames)]
