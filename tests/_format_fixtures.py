"""Writers of small files in each HPS tool's own format, made from the structure its code documents.

Nothing here is copied from those repositories: each writer lays out the keys, shapes, frames and
camera conventions listed in ``docs/formats.md`` (with the source file of each tool), so the tests
can check that ``rotavat import`` undoes them. A scene is a list of frames; a frame is a list of
:class:`Person` (camera-frame ground truth computed independently of the readers).

The body model is synthetic (``_body_models.py``): SMPL's file layout and kinematic tree on the
packaged body mesh (``rotavat_cli/data/bodies.npz``), so no licensed model is needed.
"""

from __future__ import annotations

import io
import os
import pickle
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rotavat_cli.geometry.camera import Camera
from rotavat_cli.formats.smpl import BodyModel, load_body_model
from rotavat_cli.geometry.rotations import axis_angle_to_matrix


# ---- scene -------------------------------------------------------------------------------------
W, H = 640, 480  # the test image of the format fixtures (conftest.py: the session's model, camera and scenes)
BEV_FOCAL_PX = 443.4 / 512 * W  # BEV's focal rule on the 640-px test image


@dataclass
class Person:
    """One person: SMPL parameters and its camera-frame mesh/joints (OpenCV, metres)."""

    pid: int
    pose: np.ndarray  # (24, 3) axis-angle; joint 0 in the camera frame
    betas: np.ndarray  # (10,)
    transl: np.ndarray  # (3,) SMPL transl in the camera frame
    verts_cam: np.ndarray  # (V, 3)
    joints_cam: np.ndarray  # (24, 3)


def scene_camera(image_size=(640, 480), focal_px=500.0) -> Camera:
    """The true camera of the fixture scenes: 15 deg down, 3 m high."""
    return Camera(image_size, focal_px, None, np.deg2rad(15.0), 0.0, 3.0)


def standing_person(model: BodyModel, camera: Camera, x_world: float, z_world: float, pid: int) -> Person:
    """A person of template shape standing on the ground at (x, z) facing the camera.

    Expected camera-frame vertices are a rigid transform of the template (body pose = 0), computed
    here without LBS: ``X_cam = R_cam_from_world (v + (x, 0, z)) + t_cam_from_world``; the template
    stands on y = 0 with its mid-sole at x = z = 0 (bodies.npz canonical frame = SMPL's).
    """
    R = camera.R_cam_from_world
    t = camera.t_cam_from_world
    offset = np.array([x_world, 0.0, z_world])
    rest_joints = model.J_regressor @ model.v_template
    verts_cam = (model.v_template + offset) @ R.T + t
    joints_cam = (rest_joints + offset) @ R.T + t
    rotvec = _matrix_to_rotvec(R)
    pose = np.zeros((24, 3))
    pose[0] = rotvec
    j0 = rest_joints[0]
    transl = joints_cam[0] - j0  # global_orient turns about the root joint: root lands at j0 + transl
    return Person(pid, pose, np.zeros(10), transl, verts_cam, joints_cam)


def seen_with_focal(person: Person, factor: float) -> Person:
    """The person as a tool with ``factor`` times the camera's focal places it: the rigid body moved straight
    back to ``factor`` times its root's depth, so that through that focal its root keeps its pixel and its size
    (4D-Humans' and PyMAF-X's fixed focals put people tens of metres away)."""
    shift = np.array([0.0, 0.0, (factor - 1.0) * person.joints_cam[0, 2]])
    return replace(person, transl=person.transl + shift, verts_cam=person.verts_cam + shift,
                   joints_cam=person.joints_cam + shift)


def _matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Axis-angle of a rotation matrix (angle < pi)."""
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    if angle < 1e-12:
        return np.zeros(3)
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2 * np.sin(angle))
    return axis * angle


def bev_scene(model: BodyModel, frames: int, people: int, seed: int = 3) -> list[list[Person]]:
    """``frames`` frames of ``people`` people (ids 0..people-1) standing at random spots 6-16 m in front of
    BEV's camera on the test image (:data:`BEV_FOCAL_PX`); the spots are drawn frame after frame, so a
    longer scene of the same seed starts with the shorter one."""
    cam = scene_camera((W, H), BEV_FOCAL_PX)
    rng = np.random.default_rng(seed)
    return [[standing_person(model, cam, rng.uniform(-3, 3), -rng.uniform(6, 16), pid) for pid in range(people)]
            for _ in range(frames)]


def default_scene(model: BodyModel, camera: Camera) -> list[list[Person]]:
    """Three frames: two people, one person (same track id), nobody."""
    return [
        [standing_person(model, camera, -1.0, -7.0, 3), standing_person(model, camera, 1.2, -10.0, 5)],
        [standing_person(model, camera, -0.8, -7.5, 3)],
        [],
    ]


def project(points_cam: np.ndarray, focal: float, pp) -> np.ndarray:
    return focal * points_cam[..., :2] / points_cam[..., 2:3] + np.asarray(pp)


def rotmats(pose: np.ndarray) -> np.ndarray:
    """(J, 3) axis-angle -> (J, 3, 3)."""
    return axis_angle_to_matrix(pose, np.linalg.norm(pose, axis=-1))


def fake_extra_joints(person: Person, n: int) -> np.ndarray:
    """n camera-frame points on the mesh (stand-ins for a tool's extra joints)."""
    idx = np.linspace(0, len(person.verts_cam) - 1, n).astype(int)
    return person.verts_cam[idx]


# ---- CLIFF ----------------------------------------------------------------------------------
def write_cliff(path: Path, scene, image_size, pose_format="aa", fork=False) -> Path:
    """demo.py --save_results: imgname, pose, shape, global_t, pred_joints, focal_l, detection_all."""
    focal = float(np.hypot(*image_size))
    rows, poses, betas, trans, pj = [], [], [], [], []
    for i, frame in enumerate(scene):
        for person in frame:
            kp = project(person.verts_cam, focal, (image_size[0] / 2, image_size[1] / 2))
            x1, y1 = kp.min(axis=0)
            x2, y2 = kp.max(axis=0)
            rows.append([i, x1, y1, x2, y2, 0.9, 0.99, person.pid if fork else 0])
            poses.append(person.pose.reshape(72) if pose_format == "aa" else rotmats(person.pose))
            betas.append(person.betas)
            trans.append(person.transl)
            joints = np.concatenate([person.joints_cam, fake_extra_joints(person, 21)])  # smplx SMPL: 24 + 21
            pj.append(joints if not fork else np.concatenate([joints, fake_extra_joints(person, 4)]))
    np.savez(path, imgname=[f"/data/imgs/{i:06d}.png" for i in range(len(scene))], pose=np.array(poses),
             shape=np.array(betas), global_t=np.array(trans), pred_joints=np.array(pj),
             focal_l=np.full(len(rows), focal), detection_all=np.array(rows))
    return path


# ---- BEV / ROMP -------------------------------------------------------------------------------
def bev_geometry(image_size):
    side = max(image_size)
    left, top = (side - image_size[0]) // 2, (side - image_size[1]) // 2
    return side, left, top


def write_bev(folder: Path, scene, image_size, fmt="bev", video=False, sizes=None, suffix="") -> Path:
    """simple_romp ResultSaver: <image>.npz with results=dict (verts/joints without cam_trans).

    sizes: one (W, H) per frame (photos of different sizes; default ``image_size`` for all);
    suffix: appended to the file stems as ResultSaver's prefix does (image mode: ``_<center_thresh>``).
    """
    folder.mkdir(parents=True, exist_ok=True)
    all_results = {}
    for i, frame in enumerate(scene):
        if not frame:
            continue  # simple_romp saves nothing when nobody is detected
        side, left, top = bev_geometry(image_size if sizes is None else sizes[i])
        joints71 = np.stack([np.concatenate([p.joints_cam, fake_extra_joints(p, 47)]) for p in frame])
        joints71[:, 45], joints71[:, 46] = joints71[:, 1], joints71[:, 2]  # the hips BEV root-aligns on
        verts = np.stack([p.verts_cam for p in frame])
        if fmt == "bev":
            cam_trans = joints71[:, [45, 46]].mean(axis=1)
            n = 443.4 / 256.0 * joints71[..., :2] / joints71[..., 2:3]  # perspective_projection(normalize=True)
            cam = np.stack([np.full(len(frame), 0.3), np.zeros(len(frame)), np.zeros(len(frame))], axis=1)
            betas = np.zeros((len(frame), 11))
        else:  # ROMP: weak perspective (s, tx, ty), cam_trans = 2 (tx/s, ty/s, 1/s); verts = SMPL output
            cam_trans = np.stack([p.transl for p in frame])  # SMPL(thetas, betas) + cam_trans = camera frame
            s = 2.0 / cam_trans[:, 2]
            cam = np.stack([s, cam_trans[:, 0] * s / 2, cam_trans[:, 1] * s / 2], axis=1)
            rel = joints71 - cam_trans[:, None]
            n = rel[..., :2] * cam[:, None, :1] + cam[:, None, 1:]  # batch_orth_proj
            betas = np.zeros((len(frame), 10))
        pj2d_org = np.empty_like(n)
        pj2d_org[..., 0] = (n[..., 0] + 1) * side / 2 - left
        pj2d_org[..., 1] = (n[..., 1] + 1) * side / 2 - top
        results = {
            "cam": cam, "cam_trans": cam_trans, "center_confs": np.full(len(frame), 0.8),
            "smpl_thetas": np.stack([p.pose.reshape(72) for p in frame]), "smpl_betas": betas,
            "verts": verts - cam_trans[:, None], "joints": joints71 - cam_trans[:, None], "pj2d_org": pj2d_org,
            "track_ids": np.array([p.pid for p in frame], dtype=np.int32),
        }
        name = f"frame_{i:04d}{suffix}"
        if video:
            all_results[name + ".png"] = results
        else:
            np.savez(folder / f"{name}.npz", results=results)
    if video:
        np.savez(folder / "video_results.npz", results=all_results, sequence_results={})
    return folder


# ---- joblib-format pickles (4D-Humans/PHALP, SPEC) --------------------------------------------
class _JoblibPickler(pickle._Pickler):  # noqa: SLF001
    """Writes numpy arrays as joblib does: a NumpyArrayWrapper placeholder, then the raw bytes."""

    def __init__(self, file, protocol=4, align=True):
        super().__init__(file, protocol=protocol)
        self._fh = file
        self._align = align

    def save(self, obj, save_persistent_id=True):
        if type(obj) is not np.ndarray:
            return super().save(obj, save_persistent_id)
        order = "F" if obj.flags.f_contiguous and not obj.flags.c_contiguous else "C"
        state = {"subclass": np.ndarray, "shape": obj.shape, "order": order, "dtype": obj.dtype, "allow_mmap": False}
        if self._align:
            state["numpy_array_alignment_bytes"] = 16
        self.write(pickle.GLOBAL + b"joblib.numpy_pickle\nNumpyArrayWrapper\n")
        self.write(pickle.EMPTY_TUPLE + pickle.NEWOBJ)
        super().save(state)
        self.write(pickle.BUILD)
        if self.proto >= 4:
            self.framer.commit_frame(force=True)
        if obj.dtype.hasobject:
            pickle.dump(obj, self._fh, protocol=2)
            return None
        if self._align:
            pad = 16 - ((self._fh.tell() + 1) % 16)
            self._fh.write(bytes([pad]) + b"\xff" * pad)
        self._fh.write(obj.tobytes(order=order))
        return None


def joblib_bytes(obj, compress: int = 3, protocol: int = 4, align: bool = True) -> bytes:
    """``joblib.dump(obj, compress=compress)`` bytes (zlib, as joblib's default compressor)."""
    buf = io.BytesIO()
    _JoblibPickler(buf, protocol=protocol, align=align).dump(obj)
    data = buf.getvalue()
    return zlib.compress(data, compress) if compress else data


def write_phalp(path: Path, scene, image_size, compress=3, protocol=4, ghost=True) -> Path:
    """PHALP final_visuals_dic: {frame path: {'time', 'tid', 'tracked_time', 'smpl', 'camera', ...}}."""
    side, left, top = bev_geometry(image_size)
    out = {}
    for i, frame in enumerate(scene):
        key = f"/data/video/img/{i + 1:06d}.jpg"
        entry = {"time": i, "shot": 0, "frame_path": key, "tid": [], "bbox": [], "tracked_time": [], "tracked_ids": [],
                 "tracked_bbox": [], "center": [], "scale": [], "size": [], "img_path": [], "img_name": [],
                 "class_name": [], "conf": [], "annotations": [], "smpl": [], "camera": [], "camera_bbox": [],
                 "3d_joints": [], "2d_joints": [], "mask": []}
        people = list(frame)
        if ghost and i == 2:  # a track not detected here: PHALP repeats its last state with tracked_time > 0
            people = [scene[1][0]]
        for person in people:
            model_space = person.joints_cam - person.transl  # SMPL output without translation
            j44 = np.concatenate([model_space, fake_extra_joints(person, 20) - person.transl])
            j45 = np.concatenate([j44, np.zeros((1, 3))])  # PHALP appends a zero joint
            cam_space = j45 + person.transl
            uv01 = 5000.0 / 256.0 * cam_space[:, :2] / cam_space[:, 2:3] + 0.5  # get_3d_parameters, / res
            rot = rotmats(person.pose)
            entry["tid"].append(person.pid)
            entry["tracked_time"].append(1 if (ghost and i == 2) else 0)
            if not (ghost and i == 2):
                entry["tracked_ids"].append(person.pid)
            entry["bbox"].append(np.array([10.0, 20.0, 50.0, 120.0]))
            entry["size"].append([image_size[1], image_size[0]])
            entry["img_path"].append(key)
            entry["img_name"].append(Path(key).name)
            entry["class_name"].append(np.int64(0))
            entry["conf"].append(np.float32(0.95))
            entry["annotations"].append([])
            entry["smpl"].append({"global_orient": rot[:1].astype(np.float32), "body_pose": rot[1:].astype(np.float32),
                                  "betas": person.betas.astype(np.float32)})
            entry["camera"].append(person.transl.astype(np.float32))
            entry["camera_bbox"].append(np.array([0.9, 0.0, 0.1], np.float32))
            entry["3d_joints"].append(j45.astype(np.float32))
            entry["2d_joints"].append(uv01.reshape(-1).astype(np.float32))
            entry["mask"].append([{"size": [image_size[1], image_size[0]], "counts": "abc"}])
        out[key] = entry
    path.write_bytes(joblib_bytes(out, compress=compress, protocol=protocol))
    return path


# ---- Multi-HMR --------------------------------------------------------------------------------
def smplx127_from_smpl24(person: Person) -> np.ndarray:
    """A 127-joint SMPL-X-ordered set whose joints 0-21, 28, 43 are the person's SMPL-24 joints."""
    j = fake_extra_joints(person, 127).copy()
    j[:22] = person.joints_cam[:22]
    j[28], j[43] = person.joints_cam[22], person.joints_cam[23]
    return j


def write_multihmr(folder: Path, scene, form="npz", net_size=896, fov=60.0, image_size=(640, 480),
                   model_name=None) -> Path:
    """Per-image outputs: <image>.npy (verts only) / .npz (stacked keys) / .pkl (list of dicts).

    model_name: name the files as the official demo does, ``<image>_<model_name>.png.npy``.
    """
    folder.mkdir(parents=True, exist_ok=True)
    f_net = net_size / (2 * np.tan(np.radians(fov) / 2))  # j2d_smplx live in the padded network input
    for i, frame in enumerate(scene):
        stem = folder / (f"img_{i:03d}" if model_name is None else f"img_{i:03d}_{model_name}.png")
        verts = np.array([p.verts_cam for p in frame], dtype=np.float32)
        j3d = np.array([smplx127_from_smpl24(p) for p in frame], dtype=np.float32).reshape(len(frame), 127, 3)
        j2d = project(j3d, f_net, (net_size // 2, net_size // 2)) if len(frame) else np.zeros((0, 127, 2))
        humans = [{"scores": np.float32(0.9), "loc": j2d[k, 15], "transl": j3d[k, 15], "transl_pelvis": j3d[k, 0],
                   "rotvec": np.zeros((55, 3), np.float32), "shape": np.zeros(10, np.float32),
                   "expression": np.zeros(10, np.float32), "verts_smplx": verts[k], "j3d_smplx": j3d[k],
                   "j2d_smplx": j2d[k].astype(np.float32)} for k in range(len(frame))]
        if form == "npy":
            np.save(f"{stem}.npy", np.asarray([h["verts_smplx"] for h in humans]))
        elif form == "npz":
            np.savez(f"{stem}.npz", **{k: np.array([h[k] for h in humans]) for k in ("verts_smplx", "j3d_smplx", "j2d_smplx", "scores")})
        else:
            Path(f"{stem}.pkl").write_bytes(pickle.dumps(humans, protocol=4))
    return folder


# ---- SPEC ---------------------------------------------------------------------------------------
def spec_rotation(pitch, roll):
    rx = axis_angle_to_matrix(np.array([1.0, 0, 0]), pitch)
    rz = axis_angle_to_matrix(np.array([0, 0, 1.0]), roll)
    return rx @ rz


def write_spec(folder: Path, scene, image_size, model: BodyModel, focal: float, pitch: float, roll: float = 0.0,
               names=None) -> Path:
    """SPEC demo output: camcalib/<img>.jpg.pkl and spec_results/<img>.pkl (joblib dumps)."""
    (folder / "camcalib").mkdir(parents=True, exist_ok=True)
    (folder / "spec_results").mkdir(parents=True, exist_ok=True)
    R = spec_rotation(pitch, roll)
    vfov = 2 * np.arctan(image_size[1] / 2 / focal)
    rest_j0 = (model.J_regressor @ model.v_template)[0]
    for i, frame in enumerate(scene):
        stem = names[i] if names else f"{i:06d}"
        name = f"{stem}.jpg"
        calib = {"vfov": np.array(vfov, np.float32), "f_pix": np.float64(focal), "pitch": np.array(pitch, np.float32),
                 "roll": np.array(roll, np.float32)}
        (folder / "camcalib" / f"{name}.pkl").write_bytes(joblib_bytes(calib))
        if not frame:
            continue  # spec_tester skips images without detections
        pose_world, verts_world, j49_world, t_all, j2d = [], [], [], [], []
        for p in frame:
            rot = rotmats(p.pose)
            rot[0] = R.T @ rot[0]  # global orientation in SPEC's gravity-aligned frame
            pose_world.append(rot)
            t = p.joints_cam[0] - R @ rest_j0  # X_cam = R X + t with X the SMPL output without transl
            t_all.append(t)
            verts_world.append((p.verts_cam - t) @ R)
            j49 = np.concatenate([fake_extra_joints(p, 25), p.joints_cam])  # SPIN order: 25 OP + 24
            j49_world.append((j49 - t) @ R)
            j2d.append(project(j49, focal, (image_size[0] / 2, image_size[1] / 2)))
        out = {"smpl_vertices": np.array(verts_world, np.float32), "smpl_joints3d": np.array(j49_world, np.float32),
               "smpl_joints2d": np.array(j2d, np.float32), "pred_cam_t": np.array(t_all, np.float32),
               "pred_pose": np.array(pose_world, np.float32), "pred_shape": np.zeros((len(frame), 10), np.float32),
               "pred_cam": np.zeros((len(frame), 3), np.float32)}
        (folder / "spec_results" / f"{stem}.pkl").write_bytes(joblib_bytes(out))
    return folder


# ---- AGORA ----------------------------------------------------------------------------------------
def write_agora(folder: Path, scene, image_size=(3840, 2160), scene_tag="cam01", params=False, joints_2d=24,
                root_centred=False, batch_axis=False) -> Path:
    """<image>_personId_<k>.pkl dicts: verts + allSmplJoints3d (camera) and joints (24, 2) at 3840x2160.

    joints_2d: 45 appends 21 points to 'joints' (smplx.create's SMPL output, as AGORA's own files);
    root_centred: people written without their translation (pelvis at the camera centre, transl = 0),
    as AGORA's sample predictions are; batch_axis: 'joints' (1, K, 2) and 'verts' (1, V, 3), as those
    samples' joints are.
    """
    folder.mkdir(parents=True, exist_ok=True)
    focal_4k = 18.0 / 36.0 * 3840 if scene_tag.startswith("cam0") else 28.0 / 36.0 * 3840
    for i, frame in enumerate(scene):
        image = f"ag_validationset_renderpeople_bfh_archviz_5_10_{scene_tag}_{i:05d}"
        for k, p in enumerate(frame):
            joints_4k = project(p.joints_cam, focal_4k, (1920.0, 1080.0))
            if joints_2d == 45:
                joints_4k = np.concatenate([joints_4k, project(fake_extra_joints(p, 21), focal_4k, (1920.0, 1080.0))])
            shift = p.joints_cam[0] if root_centred else np.zeros(3)
            if params:
                d = {"pose2rot": True, "joints": joints_4k,
                     "params": {"transl": (p.transl - shift)[None], "betas": p.betas[None],
                                "global_orient": p.pose[None, :1], "body_pose": p.pose[None, 1:]}}
            else:
                d = {"joints": joints_4k, "verts": p.verts_cam - shift, "allSmplJoints3d": p.joints_cam - shift}
            if batch_axis:
                d = {**d, "joints": d["joints"][None], **({"verts": d["verts"][None]} if "verts" in d else {})}
            (folder / f"{image}_personId_{k}.pkl").write_bytes(pickle.dumps(d, protocol=2))
    return folder


# ---- BEDLAM ----------------------------------------------------------------------------------------
def write_bedlam(path: Path, scene, image_size=(1280, 720), focal_mm=28.0) -> Path:
    """Per-scene npz (SMPL variant, pose_cam (N, 72)): camera = smpl(pose_cam, shape, trans_cam) + cam_ext[:3, 3]."""
    focal = focal_mm / 36.0 * image_size[0]
    K = np.array([[focal, 0, image_size[0] / 2], [0, focal_mm / 20.25 * image_size[1], image_size[1] / 2], [0, 0, 1]])
    rows = {k: [] for k in ("imgname", "pose_cam", "shape", "trans_cam", "cam_ext", "cam_int", "gtkps", "sub", "gender", "center", "scale")}
    for i, frame in enumerate(scene):
        for p in frame:
            cam_t = np.array([0.3, -0.2, 1.5]) + 0.1 * p.pid  # per-person camera offset, as BEDLAM's get_cam_trans
            ext = np.eye(4)
            ext[:3, :3] = axis_angle_to_matrix(np.array([1.0, 0, 0]), np.deg2rad(15.0))
            ext[:3, 3] = cam_t
            rows["imgname"].append(f"seq_000001/seq_000001_{i:04d}.png")
            rows["pose_cam"].append(p.pose.reshape(72))
            rows["shape"].append(p.betas)
            rows["trans_cam"].append(p.transl - cam_t)
            rows["cam_ext"].append(ext)
            rows["cam_int"].append(K)
            kp = project(p.joints_cam, focal, (image_size[0] / 2, image_size[1] / 2))
            rows["gtkps"].append(np.concatenate([kp, np.ones((24, 1))], axis=1))
            rows["sub"].append(f"rp_subject_{p.pid:02d}")
            rows["gender"].append("neutral")
            rows["center"].append(kp.mean(axis=0))
            rows["scale"].append(1.0)
    np.savez(path, **{k: np.array(v) for k, v in rows.items()})
    return path


# ---- hostile and broken files -------------------------------------------------------------------
class Evil:
    """Unpickling this runs ``os.system`` (it touches ``marker``)."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def evil_pickle(marker: Path, protocol: int = 4) -> bytes:
    """A pickle that would create ``marker`` if loaded with plain pickle."""
    return pickle.dumps({"results": Evil(marker)}, protocol=protocol)


def evil_npz(path: Path, marker: Path) -> Path:
    """An .npz whose 'results' member is an object array pickling a code-executing object."""
    obj = np.empty((), dtype=object)
    obj[()] = {"verts": Evil(marker)}
    np.savez(path, results=obj)
    return path


def truncate(path: Path, fraction: float = 0.5) -> Path:
    """Cut a file to ``fraction`` of its size."""
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * fraction)])
    return path


def load_model(path: Path) -> BodyModel:
    return load_body_model(path)



# ---- worker processes ------------------------------------------------------------------------------
def read_in_worker(seq, names):
    """In a worker process: whether the sequence's source was already loaded there, which reader object
    serves it, the frames' arrays and what reading them found (``Sequence.frame_notes``)."""
    from rotavat_cli.formats.source import recipe_cached

    cached = recipe_cached(seq.frame_source.recipe)
    frames = [dict(seq.read_frame(name).data) for name in names]
    return cached, os.getpid(), id(seq.frame_source.imported), frames, seq.frame_notes(names)


# ---- keypoint recipes: the views their errors are measured from (formats/keypoints.py docstring) ------------
def measurement_views() -> list[tuple[np.ndarray, np.ndarray]]:
    """(R_cam_from_body, t) of the keypoint-rule measurement: 12 directions (every 30 deg) x 0, 15, 30, 45 deg
    above x 5 and 12 m, looking at hip height; the body frame is +Y up, facing +Z, sole at the origin."""
    views = []
    for dist in (5.0, 12.0):
        for pitch in np.radians([0, 15, 30, 45]):
            for yaw in np.radians(np.arange(0, 360, 30)):
                turn = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
                down = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
                R = down @ np.diag([1.0, -1.0, -1.0]) @ turn  # body +Y up, facing +Z -> camera y down, facing it
                views.append((R, np.array([0.0, 0.0, dist]) - R @ np.array([0.0, 0.9, 0.0])))
    return views

