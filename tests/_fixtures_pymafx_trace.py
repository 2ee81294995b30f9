"""Writers of PyMAF-X and TRACE output files, laid out as their demos write them (structure only, read
from the tools' code; nothing copied): see the module docstrings of ``rotavat_cli/formats/pymafx.py``
and ``rotavat_cli/formats/trace.py`` for the sources.

People come from ``_format_fixtures`` scenes (camera-frame ground truth computed without the readers),
so the tests check that the importers undo each tool's conventions. A synthetic SMPL-X-layout model
(55 joints, SMPL-X's kinematic tree, on the packaged body mesh) stands in for the licensed one.
"""

from __future__ import annotations

import io
import pickle
from pathlib import Path

import _format_fixtures as F
import numpy as np


PYMAFX_FOCAL_PX = 5000.0  # apps/demo_smplx.py: convert_to_full_img_cam(..., focal_length=5000.)
TRACE_FOCAL_ON_512 = 548.0  # simple_romp/trace2/utils/utils.py: focal_length = 548 on the 512 px input
TRACE_HIPS = (35, 36)  # SMPL_ALL_44 'R_Hip', 'L_Hip': TRACE root-aligns j3d on their mean
TRACE_FEET = tuple(range(29, 35))  # L_BigToe, L_SmallToe, L_Heel, R_BigToe, R_SmallToe, R_Heel
TRACE_HEAD_TOP = 38

# ---- PyMAF-X ---------------------------------------------------------------------------------------
TORCH_MAGIC = 0x1950A86A20F9469CFC6C  # torch/serialization.py: legacy stream magic number


class TorchTensor:
    """A float32 CUDA tensor as plain pickle (joblib) writes it, from torch's ``Tensor.__reduce_ex__`` and
    ``TypedStorage.__reduce__``: ``_rebuild_tensor_v2(_load_from_bytes(<legacy torch.save stream>), 0, size,
    stride, False, OrderedDict())``."""

    def __init__(self, array):
        self.array = np.ascontiguousarray(array, dtype="<f4")


def _unicode(text: str) -> bytes:
    data = text.encode()
    return pickle.BINUNICODE + len(data).to_bytes(4, "little") + data


def torch_storage_stream(array: np.ndarray, key: str = "94316283102880", location: str = "cuda:0") -> bytes:
    """``torch.save(storage, f, _use_new_zipfile_serialization=False)`` of a float32 storage (opcodes written
    out: the persistent id ('storage', torch.FloatStorage, key, location, numel, None), then the storage keys,
    then an int64 count and the raw bytes)."""
    sys_info = {"protocol_version": 1001, "little_endian": True, "type_sizes": {"short": 2, "int": 4, "long": 8}}
    head = b"".join(pickle.dumps(value, protocol=2) for value in (TORCH_MAGIC, 1001, sys_info))
    pid = (pickle.PROTO + b"\x02" + pickle.MARK + _unicode("storage") + pickle.GLOBAL + b"torch\nFloatStorage\n"
           + _unicode(key) + _unicode(location) + pickle.BININT + int(array.size).to_bytes(4, "little")
           + pickle.NONE + pickle.TUPLE + pickle.BINPERSID + pickle.STOP)
    return head + pid + pickle.dumps([key], protocol=2) + int(array.size).to_bytes(8, "little") + array.tobytes()


class _PymafxPickler(F._JoblibPickler):
    """joblib's layout, plus torch's reduction of :class:`TorchTensor` (opcodes only: no torch needed)."""

    def save(self, obj, save_persistent_id=True):
        if not isinstance(obj, TorchTensor):
            return super().save(obj, save_persistent_id)
        array = obj.array
        stride = tuple(int(s) // array.itemsize for s in array.strides)
        self.write(pickle.GLOBAL + b"torch._utils\n_rebuild_tensor_v2\n" + pickle.MARK)
        self.write(pickle.GLOBAL + b"torch.storage\n_load_from_bytes\n")
        super().save(torch_storage_stream(array.reshape(-1)))
        self.write(pickle.TUPLE1 + pickle.REDUCE)
        for value in (0, tuple(array.shape), stride, False):
            super().save(value)
        self.write(pickle.GLOBAL + b"collections\nOrderedDict\n" + pickle.EMPTY_TUPLE + pickle.REDUCE)
        self.write(pickle.TUPLE + pickle.REDUCE)
        return None


def pymafx_box(person: F.Person, image_size) -> tuple[float, float, float]:
    """(cx, cy, side) px of the square crop the fixture gives a person: around its mesh in the 5000 px camera."""
    px = F.project(person.verts_cam, PYMAFX_FOCAL_PX, (image_size[0] / 2, image_size[1] / 2))
    lo, hi = px.min(axis=0), px.max(axis=0)
    return float((lo[0] + hi[0]) / 2), float((lo[1] + hi[1]) / 2), float(1.2 * np.max(hi - lo))


def pymafx_cams(person: F.Person, image_size) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pred_cam [s, tx, ty], orig_cam [sx, sy, tx, ty], bbox [cx, cy, h, h]) consistent with orig_cam_t = transl.

    Inverts ``convert_to_full_img_cam`` (tz = 2 f / (s b), tx_full = tx + 2 (cx - W/2) / (s b)) and applies
    ``convert_crop_cam_to_orig_img``.
    """
    width, height = image_size
    cx, cy, side = pymafx_box(person, image_size)
    t = person.transl
    s = 2 * PYMAFX_FOCAL_PX / (side * t[2])
    tx, ty = t[0] - 2 * (cx - width / 2) / (s * side), t[1] - 2 * (cy - height / 2) / (s * side)
    sx, sy = s * side / width, s * side / height
    orig = [sx, sy, (cx - width / 2) / (width / 2) / sx + tx, (cy - height / 2) / (height / 2) / sy + ty]
    return np.array([s, tx, ty]), np.array(orig), np.array([cx, cy, side, side])


def pymafx_keypoints(person: F.Person, image_size) -> np.ndarray:
    """(17, 3) stand-ins for openpifpaf's COCO-17 detections: the first 17 joints projected, confidence 1."""
    kp = F.project(person.joints_cam[:17], PYMAFX_FOCAL_PX, (image_size[0] / 2, image_size[1] / 2))
    return np.concatenate([kp, np.ones((17, 1))], axis=1).astype(np.float32)


def pymafx_spin49(person: F.Person) -> np.ndarray:
    """(49, 3) model-frame stand-ins for SPIN's joints: OpenPose MidHip (8) at the pelvis, the rest on the mesh."""
    joints = F.fake_extra_joints(person, 49) - person.transl
    joints[8] = person.joints_cam[0] - person.transl
    return joints


def write_pymafx(path: Path, scene, image_size, *, stems: str = "video", torch_params: bool = False,
                 offsets: dict | None = None, with_cams: bool = True) -> Path:
    """apps/demo_smplx.py: joblib.dump(pred_results, output.pkl) (uncompressed), one row per detection.

    Meshes and joints are stored in the model frame (camera frame minus orig_cam_t = the person's transl).
    stems: 'video' (every detection named after the video's frame folder) or 'images' (after its image).
    offsets: metres added to a mesh key ('verts' / 'smplx_verts'), to tell which one a reader used.
    """
    offsets = offsets or {}
    rows: dict[str, list] = {k: [] for k in ("pred_cam", "orig_cam", "orig_cam_t", "verts", "smplx_verts", "pose",
                                             "betas", "joints3d", "joints2d", "bboxes", "frame_ids", "person_ids")}
    for i, frame in enumerate(scene):
        for k, person in enumerate(frame):
            pred_cam, orig_cam, bbox = pymafx_cams(person, image_size)
            stem = "dancer" if stems == "video" else f"img_{i:04d}"
            mesh = person.verts_cam - person.transl
            rows["pred_cam"].append(pred_cam)
            rows["orig_cam"].append(orig_cam)
            rows["orig_cam_t"].append(person.transl)
            rows["verts"].append(mesh + offsets.get("verts", 0.0))
            rows["smplx_verts"].append(mesh + offsets.get("smplx_verts", 0.0))
            rows["pose"].append(person.pose.reshape(72))
            rows["betas"].append(person.betas)
            rows["joints3d"].append(pymafx_spin49(person))
            rows["joints2d"].append(pymafx_keypoints(person, image_size))
            rows["bboxes"].append(bbox)
            rows["frame_ids"].append(i)
            rows["person_ids"].append(f"{stem}_f{i}_p{k}")
    results = {k: np.array(v, dtype=np.float32) for k, v in rows.items()
               if k not in ("joints2d", "frame_ids", "person_ids")}
    results.update(joints2d=rows["joints2d"], frame_ids=rows["frame_ids"], person_ids=rows["person_ids"])
    if not with_cams:
        for key in ("pred_cam", "orig_cam", "bboxes"):
            del results[key]
    if torch_params:  # one batch: the demo appends the model's tensors as they are (not converted)
        results["smplx_params"] = [{"shape": TorchTensor(results["betas"]),
                                    "expression": TorchTensor(np.zeros((len(results["betas"]), 10)))}]
    buf = io.BytesIO()
    _PymafxPickler(buf, protocol=4).dump(results)
    path.write_bytes(buf.getvalue())
    return path


# ---- TRACE -----------------------------------------------------------------------------------------
def trace_joints44(person: F.Person) -> np.ndarray:
    """(44, 3) camera-frame SMPL_ALL_44 stand-ins: SMPL-24, 11 face/feet points and 9 extra on the mesh,
    the hips (35, 36) at SMPL's hips."""
    joints = np.concatenate([person.joints_cam, F.fake_extra_joints(person, 20)])
    joints[TRACE_HIPS[0]], joints[TRACE_HIPS[1]] = person.joints_cam[2], person.joints_cam[1]
    return joints


def trace_geometry(image_size) -> tuple[int, int, int]:
    """(S, left, top) of imgaug's padding to a square (the odd pixel goes right / bottom)."""
    side = max(image_size)
    return side, (side - image_size[0]) // 2, (side - image_size[1]) // 2


def write_trace(path: Path, scene, image_size, frame_dir: str = "/data/trace_demo_frames") -> Path:
    """trace2 save_results: np.savez(<seq>.npz, outputs=remove_large_keys(outputs), imgpaths=imgpaths).

    j3d = joints44 - mean(hips); cam_trans = mean(hips); pj2d = f X / Z / 256 with f = 548 (the 512 input,
    normalised); pj2d_org = (pj2d + 1) S / 2 - (left, top). No meshes (TRACE drops 'verts').
    """
    side, left, top = trace_geometry(image_size)
    rows: dict[str, list] = {k: [] for k in ("reorganize_idx", "track_ids", "cam_trans", "j3d", "pj2d", "pj2d_org",
                                             "smpl_thetas", "smpl_betas", "center_confs", "world_trans",
                                             "world_global_rots", "world_cams")}
    for i, frame in enumerate(scene):
        for person in frame:
            joints = trace_joints44(person)
            root = joints[list(TRACE_HIPS)].mean(axis=0)
            pj2d = TRACE_FOCAL_ON_512 / 256.0 * joints[:, :2] / joints[:, 2:3]
            rows["reorganize_idx"].append(i)
            rows["track_ids"].append(person.pid)
            rows["cam_trans"].append(root)
            rows["j3d"].append(joints - root)
            rows["pj2d"].append(pj2d)
            rows["pj2d_org"].append((pj2d + 1) * side / 2 - np.array([left, top]))
            rows["smpl_thetas"].append(person.pose.reshape(72))
            rows["smpl_betas"].append(person.betas)
            rows["center_confs"].append(0.7)
            rows["world_trans"].append(root + np.array([3.0, -1.0, 2.0]))  # TRACE's world frame: not the camera's
            rows["world_global_rots"].append(np.array([np.pi / 2, 0.0, 0.0]))
            rows["world_cams"].append(np.array([0.5, 0.1, 0.1]))
    outputs = {k: np.array(v, dtype=np.int64 if k in ("reorganize_idx", "track_ids") else np.float32)
               for k, v in rows.items()}
    imgpaths = np.array([f"{frame_dir}/{i:08d}.jpg" for i in range(len(scene))])
    np.savez(path, outputs=outputs, imgpaths=imgpaths)
    return path


def png_header(path: Path, image_size) -> Path:
    """A file starting like a PNG of ``image_size`` (W, H): enough for image-size readers of the header."""
    path.parent.mkdir(parents=True, exist_ok=True)
    ihdr = int(image_size[0]).to_bytes(4, "big") + int(image_size[1]).to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + len(ihdr).to_bytes(4, "big") + b"IHDR" + ihdr + b"\x00" * 16)
    return path
