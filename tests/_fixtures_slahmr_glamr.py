"""Writers of SLAHMR and GLAMR outputs, laid out as their code saves them (the sources are cited in
``rotavat_cli/formats/slahmr.py`` and ``glamr.py``), from a scene of camera-frame people
(:mod:`_format_fixtures`). Both tools keep their people in a world frame and the camera's pose per
frame, so the writers move each person into a world through a camera that pans and travels
(:func:`moving_cameras`): an importer that ignored the per-frame camera would put people elsewhere.

Nothing is copied from those repositories; the SMPL-H model is synthetic (the synthetic SMPL body
with SMPL-H's 52-joint tree), so no licensed model is needed.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import _format_fixtures as F
import numpy as np
from scipy.spatial.transform import Rotation

from rotavat_cli.formats.smpl import BodyModel

W, H = 640, 480


# ---- the world the tools store ------------------------------------------------------------------------
def moving_cameras(n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """World -> camera poses of a camera panning and travelling: R (T, 3, 3), t (T, 3), metres."""
    R = np.stack([Rotation.from_euler("yxz", [35.0 + 7.0 * i, -12.0, 4.0 * i], degrees=True).as_matrix()
                  for i in range(n_frames)])
    t = np.stack([[0.4 - 0.3 * i, -1.5 + 0.05 * i, 2.0 + 0.5 * i] for i in range(n_frames)])
    return R, t


def world_params(person: F.Person, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(root orientation (3,) axis-angle, pelvis position (3,)) in the world of a camera-frame person
    seen by the camera ``X_cam = R X_world + t``."""
    R_root_cam = F.rotmats(person.pose)[0]
    orient_world = Rotation.from_matrix(R.T @ R_root_cam).as_rotvec()
    return orient_world, R.T @ (person.joints_cam[0] - t)


def _tracks(scene) -> list[int]:
    return sorted({p.pid for frame in scene for p in frame})


# ---- SLAHMR ------------------------------------------------------------------------------------------------
def write_slahmr(folder: Path, scene, model: BodyModel, *, intrins=None, cameras=None, occluded=(),
                 track_info: bool = True, extras: bool = False, seq: str = "demo", data_start: int = 10,
                 seq_start: int = 2, iteration: int = 60) -> Path:
    """A SLAHMR run folder: motion_chunks/<seq>_<iteration>_{world,prior}_results.npz and track_info.json.

    ``occluded``: (track id, frame) pairs where the track has no keypoints (SLAHMR still rolls it out);
    ``extras``: also an older iteration and an earlier phase (wrong people: must not be read), the
    phalp/ inputs (no cameras) and cameras.json, as a real run folder has.
    """
    pids = _tracks(scene)
    n_tracks, n_frames = len(pids), len(scene)
    R, t = moving_cameras(n_frames) if cameras is None else cameras
    rest_root = (model.J_regressor @ model.v_template)[0]
    trans = np.zeros((n_tracks, n_frames, 3))
    root_orient = np.zeros((n_tracks, n_frames, 3))
    pose_body = np.zeros((n_tracks, n_frames, 63))
    visible = np.zeros((n_tracks, n_frames), dtype=bool)
    for i, frame in enumerate(scene):
        for p in frame:
            b = pids.index(p.pid)
            root_orient[b, i], pelvis_world = world_params(p, R[i], t[i])
            trans[b, i] = pelvis_world - rest_root  # SMPL-H's trans is added after skinning: pelvis = rest root + trans
            pose_body[b, i] = p.pose[1:22].reshape(63)
            visible[b, i] = True
    track_mask = np.zeros_like(visible)  # moving_scene.synchronize_preds: each track's interval, occlusions included
    for b in range(n_tracks):
        seen = np.flatnonzero(visible[b])
        track_mask[b, seen.min():seen.max() + 1] = True
    for pid, i in occluded:
        visible[pids.index(pid), i] = False
    intrins = np.array([0.5 * (W + H), 0.5 * (W + H), W / 2, H / 2] if intrins is None else intrins)
    f32 = np.float32
    world = {  # base_scene.get_optim_result + moving_scene.get_optim_result (motion phase): float32 torch tensors
        "trans": trans.astype(f32), "root_orient": root_orient.astype(f32), "pose_body": pose_body.astype(f32),
        "betas": np.zeros((n_tracks, 16), f32), "latent_pose": np.zeros((n_tracks, 1, 32), f32),
        "latent_motion": np.zeros((n_tracks, n_frames - 1, 48), f32), "trans_vel": np.zeros((n_tracks, 1, 3), f32),
        "root_orient_vel": np.zeros((n_tracks, 1, 3), f32), "joints_vel": np.zeros((n_tracks, 1, 66), f32),
        "floor_plane": np.array([[0.0, -1.0, 0.5]], f32), "floor_idcs": np.zeros(n_tracks, np.int64),
        "world_scale": np.ones((1, 1), f32), "track_mask": track_mask,
        "cam_R": np.repeat(R[None], n_tracks, axis=0).astype(f32),
        "cam_t": np.repeat(t[None], n_tracks, axis=0).astype(f32),
        "intrins": intrins.astype(f32),
    }
    run = folder
    motion = run / "motion_chunks"
    motion.mkdir(parents=True, exist_ok=True)
    np.savez(motion / f"{seq}_{iteration:06d}_world_results.npz", **world)
    prior = {k: world[k] + 1.0 for k in ("trans", "root_orient", "pose_body")}  # the prior's canonical frame
    np.savez(motion / f"{seq}_{iteration:06d}_prior_results.npz", **prior, betas=world["betas"], track_mask=track_mask)
    if track_info:
        n_images = data_start + seq_start + n_frames + 3
        info = {"tracks": {str(pid): {"index": b, "vis_mask": [False] * seq_start + visible[b].tolist() + [False] * 3}
                           for b, pid in enumerate(pids)},
                "meta": {"seq_interval": [seq_start, seq_start + n_frames], "data_interval": [data_start, n_images]}}
        (run / "track_info.json").write_text(json.dumps(info))
    if extras:
        wrong = dict(world, trans=world["trans"] + f32(3.0))
        np.savez(motion / f"{seq}_{iteration // 2:06d}_world_results.npz", **wrong)
        (run / "smooth_fit").mkdir()
        np.savez(run / "smooth_fit" / f"{seq}_{iteration + 100:06d}_world_results.npz",
                 **{k: v for k, v in wrong.items() if k != "track_mask"})
        (run / "phalp").mkdir()
        np.savez(run / "phalp" / f"{seq}_{0:06d}_phalp_world_results.npz", pose_body=pose_body[..., None].astype(f32),
                 trans=trans.astype(f32), root_orient=root_orient.astype(f32))
        (run / "cameras.json").write_text(json.dumps({"rotation": R.reshape(n_frames, 9).tolist(),
                                                      "translation": t.tolist(), "intrinsics": intrins.tolist()}))
    return run


# ---- GLAMR -------------------------------------------------------------------------------------------------
# GLAMR's body26fk joints (lib/models/smpl.py get_ordered_joint_names) that are SMPL kinematic joints
# (JOINT_MAP): pelvis is SPIN's MPII pelvis there, taken as SMPL's in this fixture.
BODY26FK_SMPL = {0: 0, 1: 1, 2: 2, 4: 4, 5: 5, 6: 12, 7: 7, 8: 8, 20: 16, 21: 17, 22: 18, 23: 19, 24: 20, 25: 21}


def body26fk_points(person: F.Person) -> np.ndarray:
    """(26, 3) camera-frame stand-ins of GLAMR's body26fk joints: SMPL joints where body26fk has them."""
    points = F.fake_extra_joints(person, 26).copy()
    for k, j in BODY26FK_SMPL.items():
        points[k] = person.joints_cam[j]
    return points


def write_glamr(path: Path, scene, *, focal: float = 1000.0, cameras=None, occluded=(), scale=None,
                protocol: int = 4) -> Path:
    """GLAMR's grecon/<seq>_seed<seed>.pkl: tensor_to_numpy of GlobalReconOptimizer's data dict.

    ``occluded``: (person id, frame) pairs where the detector missed the person (GLAMR infills it);
    ``scale``: {person id: root scale} (GLAMR's ``scale``; None for HybrIK input).
    """
    pids = _tracks(scene)
    n_frames = len(scene)
    R, t = moving_cameras(n_frames) if cameras is None else cameras
    cam_pose = np.tile(np.eye(4), (n_frames, 1, 1))
    cam_pose[:, :3, :3], cam_pose[:, :3, 3] = R, t
    K = np.array([[focal, 0.0, W / 2], [0.0, focal, H / 2], [0.0, 0.0, 1.0]])
    person_data = {}
    for pid in pids:
        seen = {i: p for i, frame in enumerate(scene) for p in frame if p.pid == pid}
        first = min(seen)
        orient, root, pose, kp = (np.zeros((n_frames, 3)), np.zeros((n_frames, 3)), np.zeros((n_frames, 69)),
                                  np.zeros((n_frames, 26, 2)))
        for i in range(n_frames):
            p = seen.get(i, seen[first])  # frames without a detection: GLAMR's infilled guess (here: a copy)
            orient[i], root[i] = world_params(p, R[i], t[i])
            pose[i] = p.pose[1:].reshape(69)
            kp[i] = F.project(body26fk_points(p), focal, (W / 2, H / 2))
        visible = np.array([1.0 if i in seen and (pid, i) not in occluded else 0.0 for i in range(n_frames)])
        exist = np.zeros(n_frames, dtype=bool)
        exist[first:max(seen) + 1] = True
        person_data[pid] = {
            "visible": visible.astype(np.float32), "visible_orig": visible.astype(np.float32),
            "fr_start": np.int64(first), "fr_end": np.int64(max(seen) + 1), "exist_frames": exist,
            "exist_len": np.int64(exist.sum()), "max_len": n_frames, "frames": np.arange(n_frames),
            "vis_frames": visible == 1, "invis_frames": visible == 0,
            "frame2ind": {f: i for i, f in enumerate(np.arange(n_frames))}, "scale": None,
            "smpl_pose": pose.astype(np.float32), "smpl_beta": np.zeros((n_frames, 10), np.float32),
            "smpl_orient_world": orient.astype(np.float32), "root_trans_world": root.astype(np.float32),
            "smpl_orient_cam": np.zeros((n_frames, 3), np.float32),
            "root_trans_cam": np.zeros((n_frames, 3), np.float32),
            "cam_K": (K[None] * visible[:, None, None]).astype(np.float32),
            "kp_2d": kp.astype(np.float32), "kp_2d_score": np.ones((n_frames, 26), np.float32),
            "kp_2d_pred": kp.astype(np.float32),
            "person_transform_world": np.tile(np.eye(4, dtype=np.float32), (n_frames, 1, 1)),
        }
        if scale is not None and pid in scale:
            person_data[pid]["scale"] = np.full(n_frames, scale[pid], np.float32)
    data = {
        "seq_name": path.stem.split("_seed")[0], "person_data": person_data, "seq_len": n_frames,
        "fr_num_persons": sum(d["vis_frames"].astype(np.float32) for d in person_data.values()),
        "cam_pose": cam_pose.astype(np.float32), "cam_pose_inv": np.linalg.inv(cam_pose).astype(np.float32),
        "cam_inv_rot_residual": np.zeros((0, 6), np.float32),
        "cam_inv_trans_residual": np.zeros((n_frames, 3), np.float32),
        "rel_transform_cam": {(i, j): np.tile(np.eye(4, dtype=np.float32), (n_frames, 1, 1))
                              for i in range(len(pids)) for j in range(len(pids)) if i != j},
        "gt": {}, "gt_meta": {},
        "meta": {"algo": "global_recon", "mt_cfg": {"model_name": "motion_traj_joint_model", "seed": 1},
                 "num_fr": n_frames},
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(data, protocol=protocol))
    return path
