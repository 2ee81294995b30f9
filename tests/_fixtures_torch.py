"""Torch files written by hand, without torch: ``torch.save`` archives (zip and legacy stream),
``np.save`` of dicts of tensors, and the GVHMR / TRAM outputs made of them.

The layouts follow PyTorch's ``torch/serialization.py`` (``_save``: ``<name>/data.pkl``,
``<name>/data/<key>``, ``byteorder``, ``version``; ``_legacy_save``: magic number, protocol
version, sys_info, the object pickle, the sorted storage keys, each storage as an int64 count and
its bytes) and ``torch/_tensor.py`` / ``torch/storage.py`` (a tensor pickles as
``torch._utils._rebuild_tensor_v2(storage, offset, size, stride, requires_grad, OrderedDict())``;
a storage inside a plain pickle as ``torch.storage._load_from_bytes(<legacy stream>)``). They were
checked against torch 2.13 (outside the project): ``torch.load`` reads what these writers make
and gives the same values.

How: Python's own pickler writes the containers; tensors and storages are stand-in objects whose
``__reduce__`` names stand-in functions of this module, and the pickle's ``GLOBAL`` opcodes
(protocols 2 and 3: ``c<module>\\n<name>\\n``, no length field) are then renamed to torch's names.
"""

from __future__ import annotations

import io
import pickle
import struct
import zipfile
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import _format_fixtures as F
import numpy as np


MAGIC_NUMBER = 0x1950A86A20F9469CFC6C
PROTOCOL_VERSION = 1001
_STORAGE_NAMES = {np.dtype("<f8"): "DoubleStorage", np.dtype("<f4"): "FloatStorage", np.dtype("<f2"): "HalfStorage",
                  np.dtype("<i8"): "LongStorage", np.dtype("<i4"): "IntStorage", np.dtype("<i2"): "ShortStorage",
                  np.dtype("i1"): "CharStorage", np.dtype("u1"): "ByteStorage", np.dtype("?"): "BoolStorage"}


# ---- stand-ins, renamed to torch's globals after pickling -----------------------------------------
def _rebuild_tensor_v2(*args):  # pragma: no cover -- only its name is pickled
    raise AssertionError("stand-in")


def _load_from_bytes(*args):  # pragma: no cover
    raise AssertionError("stand-in")


def _storage_type(name: str) -> type:
    cls = type(name, (), {"__module__": __name__})
    globals()[name] = cls
    return cls


_STORAGE_TYPES = {dtype: _storage_type(name) for dtype, name in _STORAGE_NAMES.items()}


@dataclass(frozen=True)
class Global:
    """Any global, by name (hostile fixtures): pickled as ``c<module>\\n<name>\\n`` through a stand-in."""

    module: str
    name: str


@dataclass(frozen=True)
class Call:
    """``func(*args)`` in the pickle (REDUCE), ``func`` a :class:`Global`."""

    func: Global
    args: tuple

    def __reduce__(self):
        return _stand_in(self.func), self.args


_RENAMES: dict[str, tuple[str, str]] = {
    "_rebuild_tensor_v2": ("torch._utils", "_rebuild_tensor_v2"),
    "_load_from_bytes": ("torch.storage", "_load_from_bytes"),
    **{name: ("torch", name) for name in _STORAGE_NAMES.values()},
}


def _stand_in(target: Global):
    """A function of this module standing for ``target`` (renamed in the bytes afterwards)."""
    name = f"_g_{len(_RENAMES)}"
    for known, where in _RENAMES.items():
        if where == (target.module, target.name) and known in globals():
            return globals()[known]

    def stand_in(*args):  # pragma: no cover
        raise AssertionError("stand-in")

    stand_in.__name__ = stand_in.__qualname__ = name
    stand_in.__module__ = __name__
    globals()[name] = stand_in
    _RENAMES[name] = (target.module, target.name)
    return stand_in


def _renamed(data: bytes) -> bytes:
    """Rename this module's stand-ins to the globals they stand for (GLOBAL opcodes only)."""
    for name, (module, real) in _RENAMES.items():
        data = data.replace(f"c{__name__}\n{name}\n".encode(), f"c{module}\n{real}\n".encode())
    if f"c{__name__}\n".encode() in data:
        raise AssertionError("a stand-in was not renamed (use pickle protocol 2 or 3)")
    return data


@dataclass(eq=False)
class Storage:
    """A storage: its elements (1-D, little-endian); ``key`` given when an archive is written."""

    data: np.ndarray
    key: str | None = None
    declared: int | None = None  # a size to declare instead of the data's (hostile fixtures)

    @property
    def numel(self) -> int:
        return int(self.data.size) if self.declared is None else self.declared

    def __reduce__(self):  # inside a plain pickle: a legacy stream of the storage alone
        return _load_from_bytes, (legacy_bytes(self),)


@dataclass(eq=False)
class Tensor:
    """A view of a storage, as torch pickles it."""

    storage: Storage
    offset: int
    size: tuple[int, ...]
    stride: tuple[int, ...]
    requires_grad: bool = False
    hooks: OrderedDict = field(default_factory=OrderedDict)

    def __reduce__(self):
        return _rebuild_tensor_v2, (self.storage, self.offset, tuple(self.size), tuple(self.stride), self.requires_grad,
                                    self.hooks)


def tensor(array) -> Tensor:
    """A contiguous tensor holding ``array`` (its own storage)."""
    array = np.asarray(array)
    array = array.astype(array.dtype.newbyteorder("<"))
    strides = tuple(int(s) for s in np.cumprod((1,) + array.shape[::-1][:-1])[::-1]) if array.ndim else ()
    return Tensor(Storage(np.ascontiguousarray(array).reshape(-1)), 0, tuple(array.shape), strides)


def transposed(array) -> Tensor:
    """A tensor holding ``array`` (2-D) through a transposed, non-contiguous view of its storage."""
    base = tensor(np.ascontiguousarray(np.asarray(array).T))
    return Tensor(base.storage, 0, base.size[::-1], base.stride[::-1])


# ---- writers ---------------------------------------------------------------------------------
def _keyed(obj) -> list[Storage]:
    """Every storage reachable in ``obj`` (tensors, containers), in order of first appearance."""
    found: dict[int, Storage] = {}

    def walk(value):
        if isinstance(value, Tensor):
            found.setdefault(id(value.storage), value.storage)
        elif isinstance(value, Storage):
            found.setdefault(id(value), value)
        elif isinstance(value, dict):
            for v in value.values():
                walk(v)
        elif isinstance(value, (list, tuple)):
            for v in value:
                walk(v)
        elif isinstance(value, Call):
            walk(value.args)

    walk(obj)
    return list(found.values())


def _pickle_with_ids(obj, legacy: bool, protocol: int) -> bytes:
    class Pickler(pickle.Pickler):
        def persistent_id(self, value):
            if isinstance(value, Storage):
                pid = ("storage", _STORAGE_TYPES[value.data.dtype], value.key, "cpu", value.numel)
                return pid + (None,) if legacy else pid
            return None

    buf = io.BytesIO()
    Pickler(buf, protocol=protocol).dump(obj)
    return _renamed(buf.getvalue())


def torch_zip_bytes(obj, name: str = "archive", byteorder: str = "little", drop: tuple[str, ...] = (),
                    resize: dict[str, int] | None = None, protocol: int = 2) -> bytes:
    """What ``torch.save(obj, f)`` writes (zip archive ``<name>/...``); ``drop`` leaves out records
    and ``resize`` shortens storage records (broken fixtures)."""
    storages = _keyed(obj)
    for key, storage in enumerate(storages):
        storage.key = str(key)
    records = {"data.pkl": _pickle_with_ids(obj, False, protocol), ".format_version": b"1", ".storage_alignment": b"64",
               "byteorder": byteorder.encode()}
    for storage in storages:
        data = storage.data.astype(storage.data.dtype.newbyteorder(">" if byteorder == "big" else "<")).tobytes()
        records[f"data/{storage.key}"] = data[:(resize or {}).get(storage.key, len(data))]
    records["version"] = b"3\n"
    records[".data/serialization_id"] = b"0" * 40
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as archive:
        for record, data in records.items():
            if record not in drop:
                archive.writestr(_member(f"{name}/{record}"), data)
    return buf.getvalue()


def _member(name: str) -> zipfile.ZipInfo:
    """A stored zip member dated 1980-01-01 (as ``np.savez`` dates its members): the same object gives the
    same bytes whenever it is written (``writestr`` of a bare name stamps the current time)."""
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
    info.compress_type, info.external_attr = zipfile.ZIP_STORED, 0o600 << 16
    return info


def legacy_bytes(obj, protocol: int = 2) -> bytes:
    """What ``torch.save(obj, f, _use_new_zipfile_serialization=False)`` writes."""
    storages = _keyed(obj)
    for key, storage in enumerate(storages):
        storage.key = str(1000 + key)  # torch uses the storages' addresses, sorted as strings
    sys_info = {"protocol_version": PROTOCOL_VERSION, "little_endian": True, "type_sizes": {"short": 2, "int": 4, "long": 8}}
    parts = [pickle.dumps(v, protocol=protocol) for v in (MAGIC_NUMBER, PROTOCOL_VERSION, sys_info)]
    parts.append(_pickle_with_ids(obj, True, protocol))
    keys = sorted(s.key for s in storages)
    parts.append(pickle.dumps(keys, protocol=protocol))
    by_key = {s.key: s for s in storages}
    for key in keys:
        storage = by_key[key]
        parts.append(struct.pack("<q", storage.numel) + storage.data.astype(storage.data.dtype.newbyteorder("<")).tobytes())
    return b"".join(parts)


def np_save_tensors(path: Path, obj, protocol: int = 3) -> Path:
    """``np.save(path, obj)`` where ``obj`` (a dict) holds torch tensors: a ``.npy`` header, then the
    pickled 0-d object array (numpy 1.x pickles it with protocol 3, numpy 2 with 4; the renaming
    needs 2 or 3)."""
    array = np.empty((), dtype=object)
    array[()] = obj
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, np.lib.format.header_data_from_array_1_0(array))
    pickle.dump(array, buf, protocol=protocol)
    path.write_bytes(_renamed(buf.getvalue()))
    return path


# ---- GVHMR ------------------------------------------------------------------------------------------
def gvhmr_K(image_size) -> np.ndarray:
    """GVHMR's ``estimate_K``: f = sqrt(W^2 + H^2), principal point = image centre (float32)."""
    width, height = image_size
    focal = (width ** 2 + height ** 2) ** 0.5
    return np.array([[focal, 0, width / 2.0], [0, focal, height / 2.0], [0, 0, 1]], np.float32)


def gvhmr_pred_cam(people: list[F.Person], transl: np.ndarray, K: np.ndarray) -> np.ndarray:
    """GVHMR's weak-perspective cameras (L, 3) (s, tx, ty) for one person per frame: its square crop
    ``bbx_xys`` from the person's projected box as ``get_bbx_xys_from_xyxy`` makes it (fitted to a 192:256
    aspect, side 1.2 x the longer), then ``get_a_pred_cam`` (hmr_cam.py), the inverse of
    ``compute_transl_full_cam`` that made ``transl`` (L, 3)."""
    focal, principal = K[:, 0, 0].astype(np.float64), K[:, :2, 2].astype(np.float64)
    uv = np.stack([principal[i] + focal[i] * p.verts_cam[:, :2] / p.verts_cam[:, 2:] for i, p in enumerate(people)])
    low, high = uv.min(axis=1), uv.max(axis=1)
    centre, (w, h) = (low + high) / 2, (high - low).T
    side = 1.2 * np.maximum(h, w / 0.75)
    s = 2 * focal / (transl[:, 2] * side)
    t_xy = transl[:, :2] - transl[:, 2:3] / focal[:, None] * (centre - principal)
    return np.column_stack([s, t_xy])


def gvhmr_results(people: list[F.Person], image_size, body_pose: np.ndarray | None = None, K=None) -> dict:
    """GVHMR ``DemoPL.predict``'s dict for a track of one person per frame (``people``, one per frame):
    SMPL-X parameters in the camera (``smpl_params_incam``) and gravity-view frames, ``K_fullimg``
    (L, 3, 3) and intermediate ``net_outputs``. ``transl`` is stored transposed, as in real files."""
    n = len(people)
    orient = np.stack([p.pose[0] for p in people]).astype(np.float32)
    pose = np.zeros((n, 63), np.float32) if body_pose is None else np.asarray(body_pose, np.float32).reshape(n, 63)
    betas = np.stack([p.betas for p in people]).astype(np.float32)
    transl = np.stack([p.transl for p in people]).astype(np.float32)
    K = np.repeat((gvhmr_K(image_size) if K is None else np.asarray(K, np.float32))[None], n, axis=0)
    params = {"body_pose": pose, "betas": betas, "global_orient": orient, "transl": transl}
    incam = {k: transposed(v) if k == "transl" else tensor(v) for k, v in params.items()}
    world = {"body_pose": tensor(pose), "betas": tensor(betas), "global_orient": tensor(orient[:, ::-1].copy()),
             "transl": transposed(transl + np.array([0.0, 1.0, -5.0], np.float32))}
    net = {"model_output": {"pred_cam": tensor(gvhmr_pred_cam(people, transl, K)[None].astype(np.float32))},
           "pred_smpl_params_incam": {k: tensor(v[None]) for k, v in params.items()}}
    return {"smpl_params_global": world, "smpl_params_incam": incam, "K_fullimg": tensor(K), "net_outputs": net}


def write_gvhmr(folder: Path, people: list[F.Person], image_size, **kw) -> Path:
    """``outputs/demo/<video>/hmr4d_results.pt`` as GVHMR's ``tools/demo/demo.py`` saves it."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "hmr4d_results.pt"
    path.write_bytes(torch_zip_bytes(gvhmr_results(people, image_size, **kw), name="hmr4d_results"))
    return path


# ---- TRAM -------------------------------------------------------------------------------------------
def write_tram(folder: Path, scene, image_size, focal: float | None = None, moving: bool = False,
               tracks_order: list[int] | None = None) -> Path:
    """``results/<seq>/`` as TRAM's ``estimate_camera.py`` + ``estimate_humans.py`` write it:
    ``camera.npy`` (dict: ``pred_cam_R`` (T, 3, 3), ``pred_cam_T`` (T, 3), ``img_focal``,
    ``img_center``) and ``hps/hps_track_{k}.npy`` (dict of torch tensors: ``pred_cam``,
    ``pred_pose`` (N, 144), ``pred_shape`` (N, 10), ``pred_rotmat`` (N, 24, 3, 3), ``pred_trans``
    (N, 1, 3), ``frame`` (N,)), tracks numbered longest first. ``focal`` default: TRAM's static
    camera guess ``max(W, H)``."""
    width, height = image_size
    n_frames = len(scene)
    hps = folder / "hps"
    hps.mkdir(parents=True, exist_ok=True)
    R = np.repeat(np.eye(3, dtype=np.float32)[None], n_frames, axis=0)
    T = np.zeros((n_frames, 3), np.float32)
    if moving:
        T[:, 0] = np.linspace(0.0, 0.5, n_frames)
    camera = {"pred_cam_R": R, "pred_cam_T": T, "img_focal": np.float64(max(width, height) if focal is None else focal),
              "img_center": np.array([width / 2.0, height / 2.0])}
    np.save(folder / "camera.npy", camera)  # a dict: pickled into the .npy, as TRAM writes it
    tracks: dict[int, list[tuple[int, F.Person]]] = {}
    for index, frame in enumerate(scene):
        for person in frame:
            tracks.setdefault(person.pid, []).append((index, person))
    order = tracks_order or sorted(tracks, key=lambda pid: -len(tracks[pid]))
    for k, pid in enumerate(order):
        rows = tracks[pid]
        n = len(rows)
        rotmat = np.stack([F.rotmats(p.pose) for _, p in rows]).astype(np.float32)
        results = {"pred_cam": tensor(np.ones((n, 3), np.float32)), "pred_pose": tensor(np.zeros((n, 144), np.float32)),
                   "pred_shape": tensor(np.stack([p.betas for _, p in rows]).astype(np.float32)),
                   "pred_rotmat": tensor(rotmat),
                   "pred_trans": tensor(np.stack([p.transl for _, p in rows]).astype(np.float32)[:, None]),
                   "frame": tensor(np.array([i for i, _ in rows], np.int64))}
        np_save_tensors(hps / f"hps_track_{k}.npy", results)
    return folder


def bent_elbow_pose(n: int) -> np.ndarray:
    """(n, 21, 3) SMPL-X body pose: left elbow (body joint 18 = body_pose row 17) bent 60 degrees."""
    pose = np.zeros((n, 21, 3))
    pose[:, 17] = [0.0, 0.0, np.deg2rad(60.0)]
    return pose


__all__ = ["Call", "Global", "Storage", "Tensor", "bent_elbow_pose", "gvhmr_K", "gvhmr_pred_cam", "gvhmr_results",
           "legacy_bytes", "np_save_tensors", "tensor", "torch_zip_bytes", "transposed", "write_gvhmr", "write_tram"]
