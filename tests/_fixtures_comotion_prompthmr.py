"""Writers of CoMotion and PromptHMR output files, laid out as their demos write them (structure only, read from
the tools' code; nothing copied): see the module docstrings of ``rotavat_cli/formats/comotion.py`` and
``rotavat_cli/formats/prompthmr.py`` for the sources.

- CoMotion ``demo.py`` (``track_poses``): ``torch.save`` of ``{"id", "pose", "trans", "betas", "frame_idx"}``, one
  row per tracked person-frame, the rows of each track together in frame order (``convert_to_idxs``); written
  without torch by :mod:`_fixtures_torch`. One image (``run_detection``): the detections, no ids or frames.
- PromptHMR ``scripts/demo_video.py``: ``joblib.dump`` (uncompressed, joblib's default) of the pipeline's results
  after ``save_only_essential`` (masks, 2D keypoints and image features removed), ``results/<video>/results.pkl``.

People come from ``_format_fixtures`` scenes (camera-frame ground truth computed without the readers). What a reader
must not use is made wrong on purpose: PromptHMR's image-model estimates (``smplx_transl``) and its world
(``smplx_world``: the scene's true world, a different frame from the camera's).
"""

from __future__ import annotations

from pathlib import Path

import _fixtures_torch as T
import _format_fixtures as F
import numpy as np

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.geometry.rotations import matrix_to_axis_angle

__all__ = ["comotion_rows", "write_comotion", "write_comotion_image", "prompthmr_results", "write_prompthmr",
           "world_pelvis", "world_root"]


# ---- CoMotion -----------------------------------------------------------------------------------------------
def comotion_rows(scene, body_pose: np.ndarray | None = None, frame_offset: int = 0) -> dict[str, np.ndarray]:
    """The rows ``track_poses`` saves for ``scene``: tracks (person ids) in id order, each in frame order;
    ``body_pose`` (23, 3) poses every row's body (SMPL joints 1-23) besides the scene's root."""
    seen = sorted(((p.pid, i + frame_offset, p) for i, frame in enumerate(scene) for p in frame), key=lambda r: r[:2])
    pose = np.stack([p.pose.reshape(24, 3) for _, _, p in seen]).astype(np.float32)
    if body_pose is not None:
        pose[:, 1:] = body_pose
    return {"id": np.array([pid for pid, _, _ in seen], np.int64),
            "pose": pose.reshape(-1, 72),
            "trans": np.stack([p.transl for _, _, p in seen]).astype(np.float32),
            "betas": np.stack([p.betas for _, _, p in seen]).astype(np.float32),
            "frame_idx": np.array([i for _, i, _ in seen], np.int64)}


def write_comotion(path: Path, scene, **kw) -> Path:
    """``<output-dir>/<input>.pt`` as ``track_poses`` saves it (a torch zip archive named after the file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = comotion_rows(scene, **kw)
    path.write_bytes(T.torch_zip_bytes({key: T.tensor(value) for key, value in rows.items()}, name=path.stem))
    return path


def write_comotion_image(path: Path, people: list[F.Person], image_size, focal: float) -> Path:
    """``<output-dir>/<image>.pt`` as ``run_detection`` saves it: the decoded detections of one image (betas, pose,
    trans, 27 joints ``pred_3d`` and their pixels ``pred_2d``, ``conf``), no ids or frames."""
    path.parent.mkdir(parents=True, exist_ok=True)
    joints = np.stack([np.concatenate([p.joints_cam[:22], F.fake_extra_joints(p, 5)]) for p in people])
    detections = {"betas": np.stack([p.betas for p in people]), "pose": np.stack([p.pose.reshape(72) for p in people]),
                  "trans": np.stack([p.transl for p in people]), "pred_3d": joints,
                  "pred_2d": F.project(joints, focal, (image_size[0] / 2, image_size[1] / 2)),
                  "conf": np.full((len(people), 1), 0.9)}
    path.write_bytes(T.torch_zip_bytes({k: T.tensor(np.asarray(v, np.float32)) for k, v in detections.items()},
                                       name=path.stem))
    return path


# ---- PromptHMR ----------------------------------------------------------------------------------------------
def world_root(person: F.Person, camera: Camera) -> np.ndarray:
    """(3,) the person's root orientation in the camera's world (axis-angle): ``R_world_from_cam R_root``."""
    return matrix_to_axis_angle(camera.R_cam_from_world.T @ F.rotmats(person.pose[:1])[0])


def world_pelvis(person: F.Person, camera: Camera) -> np.ndarray:
    """(3,) the person's pelvis in the camera's world (rotavat's world frame: Y up, z toward the camera)."""
    return camera.world_from_cam(person.joints_cam[0])


def _box(person: F.Person, focal: float, centre) -> np.ndarray:
    """The person's tight box [x1, y1, x2, y2] px through ``focal`` (what SAM2's masks give)."""
    uv = F.project(person.verts_cam, focal, centre)
    return np.concatenate([uv.min(axis=0), uv.max(axis=0)])


def prompthmr_results(scene, camera: Camera, frames_size, focal: float | None = None, world: bool = True,
                      moving: bool = False, body_pose: np.ndarray | None = None) -> dict:
    """``Pipeline.__call__``'s results for ``scene`` on frames of ``frames_size`` (W, H) px: ``camera`` (est_calib:
    focal max(W, H) unless ``focal``, centre (W/2, H/2); the identity and zero motion of ``--static_camera``, or a
    sideways drift with ``moving``), ``people`` (per track ``frames``, ``bboxes``, the image model's ``smplx_*`` (made
    wrong), ``smplx_cam`` and ``smplx_world``: the true world of ``camera``, the track's mean shape) and
    ``camera_world``. ``body_pose`` (n, 21, 3) poses each track's rows."""
    width, height = frames_size
    n_frames = len(scene)
    focal = float(max(width, height)) if focal is None else float(focal)
    centre = [width / 2.0, height / 2.0]  # est_calib: a list of Python floats (cam_int[2:])
    R = np.repeat(np.eye(3, dtype=np.float32)[None], n_frames, axis=0)
    T_ = np.zeros((n_frames, 3), np.float32)
    if moving:
        T_[:, 0] = np.linspace(0.0, 0.5, n_frames)
    tracks: dict[int, list[tuple[int, F.Person]]] = {}
    for index, frame in enumerate(scene):
        for person in frame:
            tracks.setdefault(person.pid, []).append((index, person))
    people = {}
    for pid, rows in tracks.items():
        n = len(rows)
        root = np.stack([p.pose[0] for _, p in rows])
        body = np.zeros((n, 21, 3)) if body_pose is None else np.asarray(body_pose)[:n]
        pose75 = np.concatenate([root, body.reshape(n, 63), np.zeros((n, 9))], axis=1).astype(np.float32)
        shape = np.stack([p.betas for _, p in rows]).astype(np.float32)
        trans = np.stack([p.transl for _, p in rows]).astype(np.float32)
        rotmat = np.zeros((n, 55, 3, 3), np.float32)  # phmr_vid.py: 25 rotations, then 30 zero hand matrices
        rotmat[:, :25] = F.rotmats(pose75.reshape(-1, 3).astype(np.float64)).reshape(n, 25, 3, 3)
        track = {"track_id": pid, "bbox_format": "x1y1x2y2", "frames": np.array([i for i, _ in rows], np.int64),
                 "bboxes": np.stack([_box(p, focal, centre) for _, p in rows]).astype(np.float32),
                 "smplx_pose": rotmat.copy(), "smplx_transl": trans + np.float32(0.3), "smplx_betas": shape + 1,
                 "smplx_cam": {"rotmat": rotmat, "pose": pose75, "shape": shape, "trans": trans,
                               "contact": np.zeros((n, 6), bool), "static_conf_logits": np.zeros((n, 6), np.float32)}}
        if world:
            pose165 = np.zeros((n, 165), np.float32)
            pose165[:, :3] = np.stack([world_root(p, camera) for _, p in rows])
            pose165[:, 3:66] = body.reshape(n, 63)
            pelvis = np.stack([world_pelvis(p, camera) for _, p in rows])
            rest_pelvis = np.stack([p.joints_cam[0] - p.transl for _, p in rows])  # J0(betas): the root turns about it
            track["smplx_world"] = {"pose": pose165, "shape": np.repeat(shape.mean(0, keepdims=True), n, axis=0),
                                    "trans": (pelvis - rest_pelvis).astype(np.float32)}
        people[pid] = track
    Rcw = np.repeat(camera.R_cam_from_world[None], n_frames, axis=0).astype(np.float32)
    Tcw = np.repeat(camera.t_cam_from_world[None], n_frames, axis=0).astype(np.float32)
    results = {"camera": {"pred_cam_R": R, "pred_cam_T": T_, "img_focal": np.int64(focal) if focal.is_integer() else
                          np.float64(focal), "img_center": centre},
               "people": people, "timings": {}, "has_tracks": True, "has_hps_cam": True, "has_hps_world": world,
               "has_slam": True, "has_hands": False, "has_2d_kpts": True, "has_post_opt": True,
               "contact_joint_ids": [7, 10, 8, 11, 20, 21]}
    if world:
        results["camera_world"] = {"pred_cam_R": Rcw.transpose(0, 2, 1), "pred_cam_T": -np.einsum("tji,tj->ti", Rcw, Tcw),
                                   "Rwc": Rcw.transpose(0, 2, 1), "Twc": -np.einsum("tji,tj->ti", Rcw, Tcw),
                                   "Rcw": Rcw, "Tcw": Tcw, "img_focal": results["camera"]["img_focal"],
                                   "img_center": centre, "viz_scale": 10.0, "viz_center": [0.0, 0, -8.0]}
    return results


def write_prompthmr(folder: Path, scene, camera: Camera, frames_size, **kw) -> Path:
    """``results/<video>/results.pkl`` as ``scripts/demo_video.py`` leaves it (``joblib.dump``, uncompressed)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "results.pkl"
    path.write_bytes(F.joblib_bytes(prompthmr_results(scene, camera, frames_size, **kw), compress=0))
    return path
