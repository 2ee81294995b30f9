"""The fixed fuzz corpus: hostile inputs of every class the hostile-input report lists (issue 15).

Every generator returns a list of :class:`Case`: the command line (paths relative to the case's
own temporary folder), the files to write there (bytes, or a callable of the case folder for
payloads that must name an absolute path), what is expected (``ok``: exit 0 and a correct
result; ``refuse``: exit 2 and one ``error:`` line naming the file or option; ``either``: one of
the two, never anything else; ``gate``: a ``--fail-if`` gate that trips, exit 1) and optional
result checks. The harness adds foreign sentinel files around every case and hashes the whole
folder before and after.

Everything is deterministic (fixed seeds) and small: files are a few KB, except the compressed
bombs (1 KB for bzip2, 0.8-1.2 MB for deflate, which cannot pack more than ~1000:1), which inflate
to gigabytes. Nothing large is ever written to disk.

Every importer is covered (``FORMATS``: the tool's own files written by the test fixture writers on a
tiny 50-vertex body, with the SMPL, SMPL-X or SMPL-H model file its parameters need); the torch-file
importers (GVHMR's ``torch.save`` archive, TRAM's ``np.save`` of tensors, PyMAF-X's tensors inside a
pickle) also get storages that are missing, short, or declare terabytes, and code-running globals
where a tensor is rebuilt. :func:`slow_cases` are the memory and time bombs measured as real
processes: ``make fuzz`` (run_fuzz.py) runs them, ``make test`` does not.

>>> cases = all_cases()
>>> len({c.id for c in cases}) == len(cases)           # ids are unique
True
>>> sum(c.subprocess for c in cases) <= 22               # the slow, measured runs stay few
True
"""

from __future__ import annotations

import base64
import functools
import io
import json
import os
import pickle
import re
import struct
import sys
import tempfile
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

import numpy as np

TESTS_DIR = Path(__file__).resolve().parents[1]
if str(TESTS_DIR) not in sys.path:
    sys.path.insert(0, str(TESTS_DIR))

import _body_models as B  # noqa: E402
import _fixtures_pymafx_trace as PT  # noqa: E402
import _fixtures_slahmr_glamr as SG  # noqa: E402
import _fixtures_comotion_prompthmr as CP  # noqa: E402
import _fixtures_torch as T  # noqa: E402
import _fixtures_wham_hybrik as WH  # noqa: E402
import _format_fixtures as F  # noqa: E402

from rotavat_cli import unpickle  # noqa: E402
from rotavat_cli.geometry.camera import Camera, camera_to_yaml_dict  # noqa: E402
from rotavat_cli.formats.smpl import SMPL_PARENTS, load_body_model  # noqa: E402

Content = Union[bytes, str, Callable[[Path], bytes]]
Check = Callable[[Path, Any], "list[str]"]

W, H = 640, 480
MARKER = "PWNED"  # a payload that runs creates <case folder>/PWNED...
MAX_RSS_MB = 700.0  # rule 4: clean runs take 120-250 MB (numpy, scipy, numba); see harness.baseline
FORMATS = ["cliff", "bev", "romp", "4dhumans", "multihmr", "spec", "agora", "bedlam",
           "wham", "gvhmr", "tram", "hybrik", "pymafx", "trace", "slahmr", "glamr", "comotion", "prompthmr"]


@dataclass
class Case:
    """One fuzz case; paths in ``args`` are relative to the case folder (the working directory)."""

    id: str
    cls: str
    args: list[str]
    files: dict[str, Content] | Callable[[], dict[str, Content]] = field(default_factory=dict)
    expect: str = "refuse"  # ok | refuse | either | gate
    inputs: list[str] = field(default_factory=list)  # input files/folders: never modified (rule 2)
    outputs: list[str] = field(default_factory=list)  # what rotavat may create or replace on success
    names: list[str] = field(default_factory=list)  # the error line names one of these (file/option)
    checks: list[Check] = field(default_factory=list)  # result checks of a successful run
    pre: list[list[str]] = field(default_factory=list)  # commands run first (must succeed)
    dirs: list[str] = field(default_factory=list)  # extra (empty) folders
    symlinks: dict[str, str] = field(default_factory=dict)  # link -> target ("{root}" = case folder)
    fifos: list[str] = field(default_factory=list)  # named pipes
    readonly: list[str] = field(default_factory=list)  # folders made read-only (mode 0555)
    cwd: str = "."
    subprocess: bool = False  # run as a real process: peak RSS, child processes, wall time measured
    max_rss_mb: float = MAX_RSS_MB
    timeout_s: float = 20.0
    max_children: int | None = None  # rule 6: most processes the run may have at once
    max_seconds: float | None = None
    payload: bool = False  # the input carries a code-running payload (rule 5)
    note: str = ""

    def command(self) -> str:
        return "rotavat " + " ".join(_quote(a) for a in self.args)

    def resolve_files(self) -> dict[str, Content]:
        return self.files() if callable(self.files) else dict(self.files)


def _quote(arg: str) -> str:
    import shlex

    text = shlex.quote(arg)
    return text if len(text) <= 90 else text[:60] + "...'"


# =================================================================================================
# Base material: a tiny SMPL-layout body (50 vertices), its scene, contract sequences and every
# importer's own format (written with tests/_format_fixtures.py's writers)
# =================================================================================================
_RING_Y = np.array([0.0, 0.08, 0.5, 0.9, 1.1, 1.3, 1.5, 1.7])
_RING_R = np.array([0.12, 0.10, 0.10, 0.17, 0.15, 0.20, 0.08, 0.05])
_JOINT_Y = np.array([0.95, 0.9, 0.9, 1.05, 0.5, 0.5, 1.15, 0.08, 0.08, 1.25, 0.03, 0.03, 1.5, 1.42, 1.42, 1.6,
                     1.4, 1.4, 1.12, 1.12, 0.85, 0.85, 0.78, 0.78])
_JOINT_X = np.array([0, .1, -.1, 0, .1, -.1, 0, .1, -.1, 0, .1, -.1, 0, .08, -.08, 0, .18, -.18, .22, -.22, .24,
                     -.24, .25, -.25])


@functools.lru_cache(maxsize=None)
def tiny_body() -> tuple[np.ndarray, np.ndarray]:
    """(50, 3) canonical vertices (y up, soles at y = 0, crown 1.70 m) and their triangles."""
    ang = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    rings = [np.stack([r * np.cos(ang), np.full(6, y), r * np.sin(ang)], axis=1) for y, r in zip(_RING_Y, _RING_R)]
    verts = np.concatenate(rings + [np.array([[0.0, 0.0, 0.0], [0.0, 1.7, 0.0]])])
    faces = []
    for k in range(len(_RING_Y) - 1):
        a, b = 6 * k, 6 * (k + 1)
        for i in range(6):
            j = (i + 1) % 6
            faces += [[a + i, b + i, b + j], [a + i, b + j, a + j]]
    bottom, top, last = 48, 49, 6 * (len(_RING_Y) - 1)
    for i in range(6):
        j = (i + 1) % 6
        faces += [[bottom, j, i], [top, last + i, last + j]]
    return verts, np.asarray(faces, dtype=np.int32)


@functools.lru_cache(maxsize=None)
def tiny_model_bytes() -> bytes:
    """An SMPL-layout .npz model on the tiny body (24 joints, SMPL's tree; 10 shape directions)."""
    verts, faces = tiny_body()
    rng = np.random.default_rng(3)
    n = len(verts)
    joints = np.stack([_JOINT_X, _JOINT_Y, np.zeros(24)], axis=1)
    reg = np.zeros((24, n))
    for j, p in enumerate(joints):
        reg[j, np.argsort(np.linalg.norm(verts - p, axis=1))[:3]] = 1.0 / 3.0
    weights = np.zeros((n, 24))
    weights[np.arange(n), np.argmin(np.linalg.norm(verts[:, None] - (reg @ verts)[None], axis=-1), axis=1)] = 1.0
    kintree = np.array([[4294967295] + list(SMPL_PARENTS[1:]), list(range(24))], dtype=np.uint32)
    buf = io.BytesIO()
    np.savez(buf, v_template=verts.astype(np.float32), shapedirs=(0.003 * rng.standard_normal((n, 3, 10))).astype(np.float32),
             posedirs=np.zeros((n, 3, 207), np.float32), J_regressor=reg.astype(np.float32),
             weights=weights.astype(np.float32), kintree_table=kintree, f=faces.astype(np.uint32))
    return buf.getvalue()


@functools.lru_cache(maxsize=None)
def tiny_model():
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.npz"
        path.write_bytes(tiny_model_bytes())
        return load_body_model(path)


def camera(pitch_deg: float = 15.0, height_m: float = 3.0) -> Camera:
    return Camera((W, H), 500.0, None, np.deg2rad(pitch_deg), 0.0, height_m)


def camera_yaml(cam: Camera | None = None, **override: Any) -> bytes:
    """A user-written camera.yaml (no rotavat header)."""
    import yaml

    d = json.loads(json.dumps(camera_to_yaml_dict(cam or camera())))
    d.update(override)
    return yaml.safe_dump(d, sort_keys=False).encode()


# people of the contract scene: (x, z) on the ground in world metres (the camera looks along -Z)
_PLACES = [(-2.0, -6.0), (-0.5, -8.5), (1.0, -11.0), (2.5, -14.0), (-3.0, -12.0), (0.5, -5.5)]


def scene_frames(n_frames: int = 3, n_people: int = 4, cam: Camera | None = None, dtype=np.float32,
                 places: list[tuple[float, float]] | None = None) -> list[dict[str, np.ndarray]]:
    """Contract frames of tiny people standing on the ground of ``cam`` (all keys of the contract)."""
    cam = cam or camera()
    model = tiny_model()
    verts0, faces = tiny_body()
    frames = []
    for f in range(n_frames):
        people = []
        for k in range(n_people):
            x, z = (places or _PLACES)[k % len(places or _PLACES)]
            people.append(F.standing_person(model, cam, x + 0.15 * f, z - 0.2 * f, pid=10 + k))
        if people:
            verts = np.stack([p.verts_cam for p in people])
            joints = np.stack([p.joints_cam for p in people])
            feet = np.stack([cam.project(p.verts_cam[48]) for p in people])
            heads = np.stack([cam.project(p.verts_cam[49]) for p in people])
        else:
            verts, joints = np.zeros((0, len(verts0), 3)), np.zeros((0, 24, 3))
            feet = heads = np.zeros((0, 2))
        frames.append({"vertices": verts.astype(dtype), "faces": faces, "joints": joints.astype(dtype),
                       "feet_2d": feet, "heads_2d": heads,
                       "person_ids": np.array([p.pid for p in people], dtype=np.int64)})
    return frames


def npz_bytes(arrays: dict[str, Any], compressed: bool = False) -> bytes:
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, **arrays)
    return buf.getvalue()


META = b"image_size: [640, 480]\nfocal_length: 500.0\nfocal_kind: camera\nsource: fuzz\n"


def contract_seq(prefix: str = "seq", n_frames: int = 3, n_people: int = 4, form: str = "npz",
                 meta: bytes | None = META, frames: list[dict] | None = None) -> dict[str, Content]:
    """A contract sequence (npz or OBJ form) under ``prefix``."""
    files: dict[str, Content] = {}
    for i, fr in enumerate(frames if frames is not None else scene_frames(n_frames, n_people)):
        if form == "npz":
            files[f"{prefix}/{i:06d}.npz"] = npz_bytes(fr)
        else:
            for pid, v in zip(fr["person_ids"], fr["vertices"]):
                files[f"{prefix}/{i:06d}/{int(pid)}.obj"] = obj_text(v, fr["faces"]).encode()
    if meta is not None:
        files[f"{prefix}/meta.yaml"] = meta
    return files


def obj_text(verts: np.ndarray, faces: np.ndarray) -> str:
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


@functools.lru_cache(maxsize=None)
def base_seq() -> dict[str, Content]:
    """seq/ (3 frames x 4 people) + cam.yaml (its true camera) + gt/ (ground truth, same people)."""
    files = contract_seq("seq")
    files.update({k.replace("seq/", "gt/", 1): v for k, v in contract_seq("gt").items()})
    files["cam.yaml"] = camera_yaml()
    return files


def seq_with(frame_index: int = 1, content: Content | None = None, drop: tuple[str, ...] = (),
             prefix: str = "seq", **arrays: Any) -> dict[str, Content]:
    """base_seq() with frame ``frame_index`` replaced by ``content`` or by its arrays updated."""
    files = dict(base_seq())
    name = f"{prefix}/{frame_index:06d}.npz"
    if content is None:
        fr = dict(scene_frames()[frame_index])
        for key in drop:
            fr.pop(key, None)
        fr.update(arrays)
        content = npz_bytes(fr)
    files[name] = content
    return files


# ---- importers' own formats --------------------------------------------------------------------
FORMAT_SRC = {"cliff": "src/demo_cliff_hr48.npz", "bev": "src/bev", "romp": "src/romp", "4dhumans": "src/demo_video.pkl",
              "multihmr": "src/mh", "spec": "src/spec_out", "agora": "src/agora", "bedlam": "src/scene.npz",
              "wham": "src/wham_output.pkl", "gvhmr": "src/gvhmr", "tram": "src/tram", "hybrik": "src/res.pk",
              "pymafx": "src/output.pkl", "trace": "src/trace_demo.npz", "slahmr": "src/slahmr_run",
              "glamr": "src/glamr_out", "comotion": "src/video.pt", "prompthmr": "src/results/video"}
# The file each importer reads first (damaged by the generic cases), when it is not the first in name order.
_SLAHMR_WORLD = "src/slahmr_run/motion_chunks/demo_000060_world_results.npz"
FORMAT_MAIN = {"slahmr": _SLAHMR_WORLD, "tram": "src/tram/hps/hps_track_0.npy"}
# The body model each format's parameters need (the tiny body in that model's joint layout): model.npz.
FORMAT_MODEL = {"gvhmr": "smplx", "slahmr": "smplh", "prompthmr": "smplx"}


def _capture(write: Callable[[Path], Any]) -> dict[str, bytes]:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write(root)
        return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@functools.lru_cache(maxsize=None)
def format_files(fmt: str) -> dict[str, bytes]:
    """Valid files of ``fmt`` (the default fixture scene on the tiny body) under src/, + model.npz."""
    model, cam = tiny_model(), camera()
    scene = F.default_scene(model, cam)

    def write(root: Path) -> None:
        (root / "src").mkdir()
        path = root / FORMAT_SRC[fmt]
        if fmt == "cliff":
            F.write_cliff(path, scene, (W, H))
        elif fmt in ("bev", "romp"):
            F.write_bev(path, scene, (W, H), fmt=fmt)
        elif fmt == "4dhumans":
            F.write_phalp(path, scene, (W, H))
        elif fmt == "multihmr":
            F.write_multihmr(path, scene, image_size=(W, H))
        elif fmt == "spec":
            F.write_spec(path, scene, (W, H), model, cam.focal_px, cam.pitch_rad)
        elif fmt == "agora":
            F.write_agora(path, scene)
        elif fmt == "bedlam":
            F.write_bedlam(path, scene)
        elif fmt == "wham":
            WH.write_wham(path, scene)
        elif fmt == "gvhmr":  # one tracked person per frame: the scene's people one after another
            T.write_gvhmr(path, [p for frame in scene for p in frame], (W, H))
        elif fmt == "tram":
            T.write_tram(path, scene, (W, H))
        elif fmt == "hybrik":
            WH.write_hybrik(path, scene, (W, H))
        elif fmt == "pymafx":
            PT.write_pymafx(path, scene, (W, H))
        elif fmt == "trace":
            PT.write_trace(path, scene, (W, H))
        elif fmt == "slahmr":
            SG.write_slahmr(path, scene, model)
        elif fmt == "glamr":
            SG.write_glamr(path / "grecon" / "demo_seed1.pkl", scene)
        elif fmt == "comotion":
            CP.write_comotion(path, scene)
        elif fmt == "prompthmr":
            CP.write_prompthmr(path, scene, cam, (W, H))

    files = _capture(write)
    files["model.npz"] = model_bytes(FORMAT_MODEL.get(fmt, "smpl"))
    return files


@functools.lru_cache(maxsize=None)
def model_bytes(kind: str = "smpl") -> bytes:
    """The tiny body as an SMPL (24 joints), SMPL-X (55: tests/_fixtures_torch.py) or SMPL-H (52:
    tests/_fixtures_slahmr_glamr.py) .npz: the same mesh and body joints in each layout."""
    if kind == "smpl":
        return tiny_model_bytes()
    writer = {"smplx": B.write_smplx_on_smpl, "smplh": B.write_synthetic_smplh}[kind]
    with tempfile.TemporaryDirectory() as tmp:
        smpl = Path(tmp) / "smpl.npz"
        smpl.write_bytes(tiny_model_bytes())
        return writer(Path(tmp) / f"{kind}.npz", smpl).read_bytes()


def import_args(fmt: str, src: str | None = None, out: str = "out", model: bool = True) -> list[str]:
    args = ["import", "--from", fmt, src or FORMAT_SRC[fmt], out, "--image-size", str(W), str(H)]
    return args + (["--smpl-model", "model.npz"] if model else [])


def format_members(fmt: str) -> list[str]:
    """The files of ``fmt``'s source, in order, the one its importer reads first first (FORMAT_MAIN)."""
    members = [k for k in format_files(fmt) if k.startswith("src/")]
    main = FORMAT_MAIN.get(fmt)
    return [main] + [m for m in members if m != main] if main in members else members


# =================================================================================================
# Hostile byte builders
# =================================================================================================
def npy_header(descr: str, shape: tuple, fortran: bool = False, version: int = 1) -> bytes:
    """A .npy header (no data) declaring ``shape`` of dtype ``descr``."""
    text = "{'descr': %r, 'fortran_order': %s, 'shape': %s, }" % (descr, fortran, repr(tuple(shape)))
    pad = (64 - (10 + len(text) + 1) % 64) % 64
    body = (text + " " * pad + "\n").encode("latin1")
    if version == 1:
        return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(body)) + body
    return b"\x93NUMPY\x02\x00" + struct.pack("<I", len(body)) + body


def npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr)  # object arrays are pickled into the .npy (np.save's default)
    return buf.getvalue()


def zip_raw(members: list[tuple[str, int, int, bytes, int]]) -> bytes:
    """A zip archive from raw members: (name, method, crc32, compressed bytes, declared size)."""
    out, central = io.BytesIO(), []
    for name, method, crc, data, size in members:
        raw_name = name.encode("utf-8")
        offset = out.tell()
        version = 46 if method == zipfile.ZIP_BZIP2 else 20
        out.write(struct.pack("<4s5H3L2H", b"PK\x03\x04", version, 0x800, method, 0, 0x21, crc, len(data), size,
                              len(raw_name), 0))
        out.write(raw_name + data)
        central.append(struct.pack("<4s6H3L5H2L", b"PK\x01\x02", version, version, 0x800, method, 0, 0x21, crc,
                                   len(data), size, len(raw_name), 0, 0, 0, 0, 0, offset) + raw_name)
    start = out.tell()
    for entry in central:
        out.write(entry)
    end = out.tell()
    out.write(struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(central), len(central), end - start, start, 0))
    return out.getvalue()


def stored(name: str, data: bytes) -> tuple[str, int, int, bytes, int]:
    return name, zipfile.ZIP_STORED, zlib.crc32(data), data, len(data)


def deflated(name: str, data: bytes, declared: int | None = None) -> tuple[str, int, int, bytes, int]:
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    packed = c.compress(data) + c.flush()
    return name, zipfile.ZIP_DEFLATED, zlib.crc32(data), packed, len(data) if declared is None else declared


def npz_from_members(members: dict[str, bytes]) -> bytes:
    return zip_raw([stored(k, v) for k, v in members.items()])


def frame_members(index: int = 1, **replace: bytes) -> dict[str, bytes]:
    """The .npy members of contract frame ``index``, some replaced by raw bytes."""
    fr = scene_frames()[index]
    members = {f"{k}.npy": npy_bytes(v) for k, v in fr.items()}
    members.update({f"{k}.npy": v for k, v in replace.items()})
    return members


# bz2 bombs: a .npy header then zeros, bzip2-compressed (bzip2 packs 45 MB of zeros into ~40 bytes).
# Compressing a gigabyte takes seconds, so the 1.2 GB stream is stored here, built by
# _bz2_zeros_stream(npy_header('<f4', (1, 100_000_000, 3)), 1_200_000_000) (level 9).
@functools.lru_cache(maxsize=None)
def _bz2_zeros_stream(header: bytes, n_zeros: int) -> tuple[bytes, int]:
    import bz2

    comp, crc, block = bz2.BZ2Compressor(9), zlib.crc32(header), bytes(1 << 24)
    parts = [comp.compress(header)]
    left = n_zeros
    while left:
        chunk = block if left >= len(block) else bytes(left)
        parts.append(comp.compress(chunk))
        crc = zlib.crc32(chunk, crc)
        left -= len(chunk)
    parts.append(comp.flush())
    return b"".join(parts), crc


def bz2_member(name: str, descr: str, shape: tuple) -> tuple[str, int, int, bytes, int]:
    header = npy_header(descr, shape)
    n = int(np.prod(shape)) * np.dtype(descr).itemsize
    data, crc = _bz2_zeros_stream(header, n)
    return name, zipfile.ZIP_BZIP2, crc, data, len(header) + n


# ---- pickles ------------------------------------------------------------------------------------
class Reduce:
    """Pickles as ``func(*args)``: what a hostile file can ask an unpickler to call."""

    def __init__(self, func: Any, args: tuple):
        self.func, self.args = func, args

    def __reduce__(self):
        return self.func, self.args


def _global(module: str, name: str) -> bytes:
    return b"c" + module.encode() + b"\n" + name.encode() + b"\n"


def _str0(text: str) -> bytes:
    return b"V" + text.encode("raw_unicode_escape") + b"\n"


def gadget_pickles(marker: Path) -> dict[str, bytes]:
    """Code-running gadgets beyond tests/test_safe_pickle.py's (os/posix.system, eval, exec, subprocess)."""
    cmd = f"touch {marker}"
    code = f"open({str(marker)!r}, 'w').close()"
    g = {
        # numpy's own exec helper, reachable by its module path
        "numpy-runstring": _global("numpy.testing._private.utils", "runstring") + b"(" + _str0(code) + b"(dtR.",
        # builtins.__import__('os').system(cmd) in two REDUCEs via getattr
        "import-getattr": (_global("builtins", "getattr") + b"(" + _global("builtins", "__import__") + b"(" + _str0("os")
                           + b"tR" + _str0("system") + b"tR(" + _str0(cmd) + b"tR."),
        # functools.partial(os.system, cmd)() through the allowed-looking containers
        "functools-partial": pickle.dumps({"results": Reduce(__import__("functools").partial, (os.system, cmd))}),
        # numpy array reconstruction with a hostile "subclass"
        "ndarray-subclass": (_global("numpy.core.multiarray", "_reconstruct") + _global("os", "system") + b"(K\x00tb"
                             + _str0("b") + b"\x87R."),
        # copyreg._reconstructor(os.system ...) as old pickles build objects
        "copyreg-reconstructor": (_global("copyreg", "_reconstructor") + b"(" + _global("subprocess", "Popen")
                                  + _global("builtins", "object") + b"N\x87R."),
        # a nested reduce inside a joblib-like NumpyArrayWrapper state
        "joblib-wrapper-state": (_global("joblib.numpy_pickle", "NumpyArrayWrapper") + b")\x81}("
                                 + _str0("subclass") + _global("os", "system") + _str0("shape") + b"K\x01\x85"
                                 + b"ub."),
        # builtins.exec reached via the _codecs / builtins aliases Python 2 pickles use
        "builtin-exec-py2": _global("__builtin__", "exec") + b"(" + _str0(code) + b"tR.",
        # operator.methodcaller('system', cmd)(os) – a chain of allowed-looking callables
        "operator-methodcaller": (_global("operator", "methodcaller") + b"(" + _str0("system") + _str0(cmd) + b"tR("
                                  + _global("os", "path") + b"tR."),
        # pickle protocol 5 out-of-band buffer + dtype with a hostile type
        "dtype-object-fields": pickle.dumps({"v": Reduce(np.dtype, ([("a", "O")],)), "x": Reduce(os.system, (cmd,))}),
        # the payload deep inside a list of dicts, protocol 0 (text)
        "deep-protocol0": pickle.dumps([{"a": [{"b": (1, Reduce(os.system, (cmd,)))}]}], protocol=0),
    }
    return g


def object_npz(marker: Path, plain: bool = False) -> bytes:
    """An npz frame with an object-array member (a payload, or plain Python content)."""
    fr = dict(scene_frames()[1])
    obj = np.empty((), dtype=object)
    obj[()] = {"a": [1, 2]} if plain else F.Evil(marker)
    fr["extra"] = obj
    return npz_bytes(fr)


def shared_reference_bomb(dims: tuple[int, ...] = (5000, 10000, 3)) -> Any:
    """A list nested like an array of ``dims`` that shares every row: a few KB pickled, GBs as an array."""
    inner: Any = [0.0] * dims[-1]
    for n in reversed(dims[:-1]):
        inner = [inner] * n
    return [inner]


def bytearray_bomb(n: int = 2**31) -> bytes:
    """Unpickling calls bytearray(n): n zero bytes from a 30-byte file."""
    return _global("builtins", "bytearray") + b"(J" + struct.pack("<i", n - 1 if n > 2**31 - 1 else n) + b"tR." \
        if n < 2**31 else _global("builtins", "bytearray") + b"(\x8a\x05" + n.to_bytes(5, "little") + b"tR."


def list_range_bomb(n: int = 2**27) -> bytes:
    """Unpickling calls list(range(n))."""
    return (_global("builtins", "list") + b"(" + _global("builtins", "range") + b"(J" + struct.pack("<i", n)
            + b"tRtR.")


def huge_array_pickle(shape: tuple[int, ...] = (10**6, 10**6, 3)) -> bytes:
    """A pickled ndarray whose state declares ``shape`` with 8 bytes of data."""
    arr = np.zeros(1, dtype="<f8")
    data = bytearray(pickle.dumps(arr, protocol=2))
    # rewrite the shape tuple (1,) -> shape in the BUILD state: (1, (1,), dtype, False, b'...')
    old = b"K\x01K\x01\x85"
    new = b"K\x01(" + b"".join(b"J" + struct.pack("<i", d) for d in shape) + b"t"
    idx = bytes(data).find(old)
    assert idx > 0
    return bytes(data[:idx]) + new + bytes(data[idx + len(old):])


def subarray_dtype_pickle(side: int = 10_000) -> bytes:
    """A pickled structured array whose field is a (side, side) float64 sub-array: 800 MB per element,
    two elements declared, 16 bytes of data (numpy.dtype and _reconstruct are allowed globals)."""
    data = pickle.dumps({"smpl_vertices": np.zeros(2, dtype=[("a", "f8", (7, 9))])}, protocol=2)
    size = 8 * side * side
    for old, new in [(b"X\x04\x00\x00\x00V504", b"X" + struct.pack("<I", len(f"V{size}")) + f"V{size}".encode()),
                     (b"K\x07K\t\x86", b"M" + struct.pack("<H", side) + b"M" + struct.pack("<H", side) + b"\x86"),
                     (b"M\xf8\x01", b"J" + struct.pack("<i", size))]:
        assert old in data
        data = data.replace(old, new)
    return data


# ---- YAML ------------------------------------------------------------------------------------
def yaml_alias_bomb(levels: int = 12, width: int = 9, key: str = "extra") -> str:
    """Billion laughs: 9^12 = 2.8e11 leaves from 12 short lines."""
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * width) + "]")
    lines.append(f"{key}: *a{levels - 1}")
    return "\n".join(lines) + "\n"


def yaml_alias_bomb_inline(levels: int = 12, width: int = 9) -> str:
    """The same bomb as one flow value: [&a0 [lol, ...], &a1 [*a0, ...], ..., &a11 [*a10, ...]]."""
    items = ["&a0 [" + ", ".join(["lol"] * width) + "]"]
    items += [f"&a{i} [" + ", ".join([f"*a{i - 1}"] * width) + "]" for i in range(1, levels)]
    return "[" + ", ".join(items) + "]"


def yaml_deep(depth: int = 100_000) -> str:
    return "extra: " + "[" * depth + "]" * depth + "\n"


# =================================================================================================
# Result checks (rule 1: "a correct result"): independent of rotavat's readers
# =================================================================================================
def _load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def check_seq(out: str, n_frames: int | None = None, people: list[int] | None = None, finite: bool = True,
              form: str = "npz") -> Check:
    """The output folder is a sequence of ``n_frames`` frames with these people counts, finite meshes."""

    def check(root: Path, run: Any) -> list[str]:
        folder = root / out
        if not folder.is_dir():
            return [f"{out}/ was not written"]
        problems = []
        if form == "npz":
            frames = sorted(folder.glob("*.npz"))
            counts, bad = [], []
            for f in frames:
                try:
                    d = _load_npz(f)
                except Exception as exc:  # noqa: BLE001
                    problems.append(f"{f.name} unreadable: {exc}")
                    continue
                v = d.get("vertices", d.get("joints"))
                counts.append(0 if v is None else len(v))
                for key in ("vertices", "joints"):
                    if finite and key in d and d[key].dtype.kind == "f" and not np.all(np.isfinite(d[key])):
                        bad.append(f"{f.name}:{key}")
            if bad:
                problems.append(f"non-finite output arrays: {', '.join(bad[:4])}")
        else:
            frames = sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))
            counts = [len(list(p.glob("*.obj"))) for p in frames]
            for p in frames:
                for obj in p.glob("*.obj"):
                    vals = [float(x) for line in obj.read_text().splitlines() if line.startswith("v ")
                            for x in line.split()[1:4]]
                    if finite and not np.all(np.isfinite(vals)):
                        problems.append(f"{obj.relative_to(folder)} has non-finite vertices")
        if n_frames is not None and len(frames) != n_frames:
            problems.append(f"{out}/ has {len(frames)} frames, expected {n_frames}")
        if people is not None and counts != people:
            problems.append(f"{out}/ people per frame {counts}, expected {people}")
        return problems

    return check


def check_people_csv(out: str, n_rows: int) -> Check:
    def check(root: Path, run: Any) -> list[str]:
        path = root / out / "people.csv"
        if not path.is_file():
            return [f"{out}/people.csv missing"]
        rows = [r for r in path.read_text().splitlines()[1:] if r.strip()]
        return [] if len(rows) == n_rows else [f"people.csv has {len(rows)} rows, expected {n_rows}"]

    return check


def check_camera_yaml(path: str) -> Check:
    def check(root: Path, run: Any) -> list[str]:
        import yaml

        p = root / path
        if not p.is_file():
            return [f"{path} not written"]
        d = yaml.safe_load(p.read_text())
        vals = [d.get(k) for k in ("focal_px", "pitch_deg", "height_m")]
        if any(not isinstance(v, (int, float)) or not np.isfinite(v) for v in vals):
            return [f"{path}: non-finite camera {vals}"]
        return []

    return check


def check_meta(out: str, max_side_px: int = 100_000) -> Check:
    """``out/meta.yaml`` states an image size of two integers in 1..100,000 px (the contract's bound,
    docs/conventions.md) and a finite positive focal length and finite principal point when present:
    an import writes nothing its own readers refuse."""

    def check(root: Path, run: Any) -> list[str]:
        import yaml

        path = root / out / "meta.yaml"
        if not path.is_file():
            return [f"{out}/meta.yaml not written"]
        meta = yaml.safe_load(path.read_text())
        if not isinstance(meta, dict):
            return [f"{out}/meta.yaml is not a mapping"]
        problems = []
        size = meta.get("image_size")
        if size is not None and not (isinstance(size, list) and len(size) == 2 and all(
                isinstance(v, int) and 0 < v <= max_side_px for v in size)):
            problems.append(f"{out}/meta.yaml image_size {str(size)[:60]} is not two integers in 1..{max_side_px}")
        focal = meta.get("focal_length")
        if focal is not None and not (isinstance(focal, (int, float)) and np.isfinite(focal) and focal > 0):
            problems.append(f"{out}/meta.yaml focal_length {str(focal)[:40]} is not a positive number")
        pp = meta.get("principal_point")
        if pp is not None and not (isinstance(pp, list) and len(pp) == 2
                                   and np.all(np.isfinite(np.asarray(pp, float)))):
            problems.append(f"{out}/meta.yaml principal_point {str(pp)[:60]} is not two finite numbers")
        return problems

    return check


def check_marker(folder: str) -> Check:
    """The output folder carries rotavat's ownership marker."""

    def check(root: Path, run: Any) -> list[str]:
        return [] if (root / folder / ".rotavat-output").is_file() else [f"{folder}/.rotavat-output marker missing"]

    return check


def check_files(*paths: str) -> Check:
    def check(root: Path, run: Any) -> list[str]:
        return [f"{p} not written" for p in paths if not (root / p).exists()]

    return check


def check_ids(out: str, frame: str, ids: list[int]) -> Check:
    def check(root: Path, run: Any) -> list[str]:
        got = _load_npz(root / out / frame).get("person_ids")
        return [] if got is not None and [int(v) for v in got] == ids else [f"{out}/{frame} person_ids {got}, expected {ids}"]

    return check


# =================================================================================================
# Generators, one per input class
# =================================================================================================
SEQ_INPUTS = ["seq", "gt", "cam.yaml"]
ALIGN = ["align", "--in", "seq", "--camera", "cam.yaml", "--out", "out"]
INFO = ["info", "seq"]
OK_ALIGN_CHECKS = [check_seq("out", 3, [4, 4, 4]), check_people_csv("out", 12)]


def _frame_case(name: str, content: Content | Callable[[], dict], expect: str, align: bool = False, note: str = "",
                payload: bool = False, align_checks: list[Check] | None = None, cls: str = "npz-frame") -> list[Case]:
    """``info`` (and optionally ``align``) on the base sequence with frame 000001.npz hostile."""
    def files() -> dict[str, Content]:
        c = content() if callable(content) and not isinstance(content, bytes) and content.__code__.co_argcount == 0 else content
        return seq_with(1, c) if not isinstance(c, dict) else c

    names = ["000001.npz"]
    cases = [Case(f"{cls}/{name}/info", cls, INFO, files, expect, SEQ_INPUTS, [], names, note=note, payload=payload)]
    if align:
        checks = align_checks if align_checks is not None else OK_ALIGN_CHECKS
        cases.append(Case(f"{cls}/{name}/align", cls, ALIGN, files, expect, SEQ_INPUTS, ["out"], names,
                          checks=checks, note=note, payload=payload))
    return cases


def _frame_arrays(**arrays: Any) -> Callable[[], dict]:
    return lambda: seq_with(1, None, **arrays)


def _frame_drop(*keys: str, **arrays: Any) -> Callable[[], dict]:
    return lambda: seq_with(1, None, drop=keys, **arrays)


def _fr(key: str) -> np.ndarray:
    return scene_frames()[1][key]


def gen_npz_frames() -> list[Case]:
    """Corrupt / malicious .npz frames for the contract reader (info, and align for a subset)."""
    valid = lambda: npz_bytes(scene_frames()[1])  # noqa: E731
    rng = np.random.default_rng(15)
    cases: list[Case] = []
    cases += _frame_case("valid-control", lambda: base_seq(), "ok", align=True)
    cases += _frame_case("truncated-half", lambda: valid()[: len(valid()) // 2], "refuse", align=True)
    cases += _frame_case("truncated-30-bytes", lambda: valid()[:30], "refuse")
    cases += _frame_case("random-bytes", rng.bytes(700), "refuse", align=True)
    cases += _frame_case("text-named-npz", b"vertices: this is a text file, not a zip\n", "refuse")
    cases += _frame_case("empty-file", b"", "refuse")
    cases += _frame_case("raw-npy-named-npz", npy_bytes(np.zeros((2, 5, 3), np.float32)), "refuse")
    cases += _frame_case("zip-no-members", zip_raw([]), "either")
    cases += _frame_case("npy-huge-shape-header", lambda: npz_from_members(frame_members(
        vertices=npy_header("<f4", (10**6, 10**6, 3)))), "refuse", align=True,
        note="header declares 12 TB; no data")
    cases += _frame_case("npy-960MB-short-data", lambda: npz_from_members(frame_members(
        vertices=npy_header("<f8", (4, 10**7, 3)) + bytes(1024))), "refuse",
        note="960 MB declared (under max_array_mb), 1 KB given: truncation found before allocating")
    cases += _frame_case("npy-negative-shape", lambda: npz_from_members(frame_members(
        vertices=npy_header("<f4", (4, -50, 3)))), "refuse")
    cases += _frame_case("npy-bad-header-length", lambda: npz_from_members(frame_members(
        vertices=b"\x93NUMPY\x01\x00\xff\xff" + b"{'descr': '<f4'" + bytes(64))), "refuse")
    cases += _frame_case("npy-header-python-expr", lambda: npz_from_members(frame_members(
        vertices=b"\x93NUMPY\x01\x00" + struct.pack("<H", 64) + b"__import__('os').system('touch PWNED')".ljust(63) + b"\n")),
        "refuse", payload=True)
    cases += _frame_case("zip-crc-mismatch", lambda: zip_raw([(n, m, c ^ 0xFFFF, d, s) for n, m, c, d, s in
                                                              (stored(k, v) for k, v in frame_members().items())]),
                         "refuse")
    cases += _frame_case("zip-declared-size-lie", lambda: zip_raw(
        [deflated(k, v, declared=3_000_000_000 if k == "vertices.npy" else None) for k, v in frame_members().items()]),
        "refuse", note="central directory says 3 GB for a 600-byte member")
    cases += _frame_case("object-array-payload", lambda root: object_npz(root / MARKER), "refuse", align=True,
                         payload=True)
    cases += _frame_case("object-array-plain", lambda root: object_npz(root / MARKER, plain=True), "refuse")
    cases += _frame_case("pickle-named-npz", lambda root: F.evil_pickle(root / MARKER), "refuse", payload=True)
    cases += _frame_case("member-dotdot-path", lambda: npz_from_members(
        {**frame_members(), "../../evil.npy": npy_bytes(np.arange(3.0))}), "either", align=True,
        note="a member named ../../evil.npy: never a file outside the output")
    cases += _frame_case("member-absolute-path", lambda root: npz_from_members(
        {**frame_members(), f"{root}/EVIL_ABS.npy": npy_bytes(np.arange(3.0))}), "either", align=True)
    cases += _frame_case("member-duplicate-vertices", lambda: zip_raw(
        [stored(k, v) for k, v in frame_members().items()]
        + [stored("vertices.npy", npy_bytes(np.zeros((7, 50, 3), np.float32)))]), "either")
    # wrong dtypes
    v = lambda: _fr("vertices")  # noqa: E731
    cases += _frame_case("vertices-int32", _frame_arrays(vertices=(v() * 100).astype(np.int32)), "either", align=True)
    cases += _frame_case("vertices-uint8", _frame_arrays(vertices=np.abs(v()).astype(np.uint8)), "either", align=True)
    cases += _frame_case("vertices-float16", _frame_arrays(vertices=v().astype(np.float16)), "ok", align=True)
    cases += _frame_case("vertices-complex", _frame_arrays(vertices=v().astype(np.complex64)), "refuse", align=True)
    cases += _frame_case("vertices-bool", _frame_arrays(vertices=v() > 0), "either")
    cases += _frame_case("vertices-strings", _frame_arrays(vertices=v().astype("U8")), "refuse")
    cases += _frame_case("vertices-datetime", _frame_arrays(vertices=np.zeros((4, 50, 3), "datetime64[s]")), "refuse")
    cases += _frame_case("vertices-structured", _frame_arrays(vertices=np.zeros((4, 50), [("x", "<f4"), ("y", "<f4"),
                                                                                          ("z", "<f4")])), "refuse")
    cases += _frame_case("K-string", _frame_arrays(K=np.array("500 0 320; 0 500 240; 0 0 1")), "refuse", align=True)
    cases += _frame_case("K-2x2", _frame_arrays(K=np.eye(2) * 500), "refuse")
    cases += _frame_case("K-zero-focal", _frame_arrays(K=np.diag([0.0, 0.0, 1.0])), "refuse")
    cases += _frame_case("person-ids-uint64-huge", _frame_arrays(person_ids=np.array(
        [2**64 - 1, 2**63, 2**63 + 1, 5], np.uint64)), "either", align=True,
        align_checks=OK_ALIGN_CHECKS + [check_ids("out", "000001.npz", [2**64 - 1, 2**63, 2**63 + 1, 5])],
        note="ids that do not fit int64: refused, or kept exactly")
    cases += _frame_case("person-ids-float", _frame_arrays(person_ids=np.array([0.5, 1.5, 2.5, 3.5])), "refuse")
    cases += _frame_case("person-ids-duplicate", _frame_arrays(person_ids=np.array([3, 3, 4, 5])), "refuse")
    cases += _frame_case("person-ids-strings", _frame_arrays(person_ids=np.array(["a", "b", "c", "d"])), "refuse")
    # non-finite and out-of-range values
    nan_v = lambda: np.where(np.arange(50)[None, :, None] == 7, np.nan, v()).astype(np.float32)  # noqa: E731
    cases += _frame_case("vertices-nan", _frame_arrays(vertices=nan_v()), "refuse", align=True)
    cases += _frame_case("vertices-inf", _frame_arrays(vertices=np.where(nan_v() != nan_v(), np.inf, v()).astype(
        np.float32)), "refuse")
    cases += _frame_case("joints-nan", _frame_arrays(joints=np.full((4, 24, 3), np.nan, np.float32)), "refuse")
    cases += _frame_case("keypoints-nan-allowed", _frame_arrays(keypoints_2d=np.full((4, 17, 2), np.nan)), "ok",
                         align=True)
    cases += _frame_case("focal-nan", _frame_arrays(focal_length=np.float64(np.nan)), "refuse")
    cases += _frame_case("focal-inf", _frame_arrays(focal_length=np.float64(np.inf)), "refuse", align=True)
    cases += _frame_case("focal-negative", _frame_arrays(focal_length=np.float64(-500.0)), "refuse")
    cases += _frame_case("focal-per-person-wrong-count", _frame_arrays(focal_length=np.array([500.0, 510.0, 520.0])),
                         "refuse")
    cases += _frame_case("image-size-zero", _frame_arrays(image_size=np.array([0, 480])), "refuse")
    cases += _frame_case("image-size-3-values", _frame_arrays(image_size=np.array([640, 480, 3])), "refuse")
    cases += _frame_case("image-size-1e300", _frame_arrays(image_size=np.array([1e300, 1e300])), "refuse")
    cases += _frame_case("principal-point-nan", _frame_arrays(principal_point=np.array([np.nan, 240.0])), "refuse")
    cases += _frame_case("vertices-1e30", _frame_arrays(vertices=(v() * 1e30).astype(np.float32)), "either",
                         align=True)
    cases += _frame_case("vertices-float32-max", _frame_arrays(vertices=np.full((4, 50, 3), np.finfo(np.float32).max,
                                                                                np.float32)), "either", align=True)
    # shapes and counts
    cases += _frame_case("people-count-mismatch", _frame_arrays(joints=_fr("joints")[:3]), "refuse", align=True)
    cases += _frame_case("feet-2d-3-columns", _frame_arrays(feet_2d=np.zeros((4, 3))), "refuse")
    cases += _frame_case("vertices-2d", _frame_arrays(vertices=v()[:, :, 0]), "refuse")
    cases += _frame_case("vertices-4-columns", _frame_arrays(vertices=np.concatenate([v(), v()[..., :1]], -1)),
                         "refuse")
    cases += _frame_case("vertices-scalar", _frame_arrays(vertices=np.float32(1.0)), "refuse")
    cases += _frame_case("vertices-zero-vertices", _frame_drop("faces", "joints", vertices=np.zeros((4, 0, 3),
                                                                                                  np.float32)),
                         "either", align=True)
    cases += _frame_case("faces-out-of-range", _frame_arrays(faces=_fr("faces") + 1000), "refuse", align=True)
    cases += _frame_case("faces-negative", _frame_arrays(faces=_fr("faces") - 100), "refuse")
    cases += _frame_case("faces-float", _frame_arrays(faces=_fr("faces").astype(np.float64)), "refuse")
    cases += _frame_case("faces-quads", _frame_arrays(faces=np.zeros((5, 4), np.int32)), "refuse")
    cases += _frame_case("vertex-count-differs-between-frames", _frame_drop("faces", "joints",
                                                                            vertices=v()[:, :20]), "either",
                         align=True)
    return cases


def gen_importers() -> list[Case]:
    """Corrupt / malicious files for every importer (``rotavat import --from FMT``)."""
    rng = np.random.default_rng(16)
    cases: list[Case] = []
    for i, fmt in enumerate(FORMATS):
        members = format_members(fmt)
        first = members[0]
        base = lambda fmt=fmt: dict(format_files(fmt))  # noqa: E731
        names = [Path(first).name, Path(FORMAT_SRC[fmt]).name, Path(first).stem]

        def with_file(name: str, content: Content, fmt=fmt) -> Callable[[], dict]:
            return lambda: {**format_files(fmt), name: content}

        ok_checks = [check_files("out/meta.yaml"), check_seq("out", None, None), check_meta("out")]
        if fmt in PELVIS_TRUTH:  # the new importers: every person back at its known camera-frame position
            ok_checks = [check_meta("out"), check_seq("out", None, [len(p) for p in PELVIS_TRUTH[fmt]()]),
                         check_pelvis("out", PELVIS_TRUTH[fmt]())]
        cls = "importer"
        inputs = ["src", "model.npz"]
        cases.append(Case(f"{cls}/{fmt}/valid-control", cls, import_args(fmt), base, "ok", inputs, ["out"],
                          checks=ok_checks))
        data = format_files(fmt)[first]
        cases.append(Case(f"{cls}/{fmt}/truncated", cls, import_args(fmt), with_file(first, data[: len(data) * 2 // 5]),
                          "refuse", inputs, [], names))
        cases.append(Case(f"{cls}/{fmt}/random-bytes", cls, import_args(fmt), with_file(first, rng.bytes(400)),
                          "refuse", inputs, [], names))
        cases.append(Case(f"{cls}/{fmt}/text-file", cls, import_args(fmt),
                          with_file(first, b"not the tool's output, just text\n" * 4), "refuse", inputs, [], names))
        cases.append(Case(f"{cls}/{fmt}/empty-file", cls, import_args(fmt), with_file(first, b""), "refuse", inputs, [],
                          names))
        # the hostile SMPL model (formats that pose parameters)
        if fmt in ("cliff", "4dhumans", "bedlam"):
            cases.append(Case(f"{cls}/{fmt}/model-object-array", cls, import_args(fmt),
                              lambda fmt=fmt: {**format_files(fmt), "model.npz": lambda root: npz_bytes(
                                  {**_load_npz_bytes(tiny_model_bytes()), "J_regressor": _obj(F.Evil(root / MARKER))})},
                              "refuse", inputs, [], ["model.npz"], payload=True))
            cases.append(Case(f"{cls}/{fmt}/model-truncated", cls, import_args(fmt),
                              lambda fmt=fmt: {**format_files(fmt), "model.npz": tiny_model_bytes()[:3000]},
                              "refuse", inputs, [], ["model.npz"]))
            cases.append(Case(f"{cls}/{fmt}/model-huge-shape", cls, import_args(fmt),
                              lambda fmt=fmt: {**format_files(fmt), "model.npz": npz_from_members({
                                  **{f"{k}.npy": npy_bytes(v) for k, v in _load_npz_bytes(tiny_model_bytes()).items()},
                                  "shapedirs.npy": npy_header("<f4", (10**6, 3, 10**6))})},
                              "refuse", inputs, [], ["model.npz"]))
    # format-specific structure damage
    cases += _importer_structure_cases()
    cases += _new_importer_cases()
    return cases


def _load_npz_bytes(data: bytes) -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _obj(value: Any) -> np.ndarray:
    arr = np.empty((), dtype=object)
    arr[()] = value
    return arr


def _npz_edit(fmt: str, member: str, edit: Callable[[dict], dict], objects: bool = False) -> Callable[[], dict]:
    """A fixture whose npz ``member`` is read (object members through the restricted unpickler when
    ``objects``), edited and written again."""
    def files() -> dict[str, Content]:
        all_files = dict(format_files(fmt))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "member.npz"
            path.write_bytes(all_files[member])
            data = unpickle.load_npz(path, objects=objects)
        all_files[member] = npz_bytes(edit(data))
        return all_files

    return files


def _pickle_edit(fmt: str, member: str, edit: Callable[[Any], Any], joblib: bool = False,
                 compress: int = 3) -> Callable[[], dict]:
    from rotavat_cli import unpickle

    def files() -> dict[str, Content]:
        all_files = dict(format_files(fmt))
        obj = unpickle.loads(_maybe_unzlib(all_files[member]), member)
        new = edit(obj)
        all_files[member] = F.joblib_bytes(new, compress=compress) if joblib else pickle.dumps(new, protocol=4)
        return all_files

    return files


def _maybe_unzlib(data: bytes) -> bytes:
    try:
        return zlib.decompress(data)
    except zlib.error:
        return data


def _bev_results(data: dict, fn: Callable[[dict], dict]) -> dict:
    res = dict(data["results"].item())
    data["results"] = _obj(fn(res))
    return data


def _set(d: dict, **kv: Any) -> dict:
    d = dict(d)
    d.update(kv)
    return d


def _drop(d: dict, *keys: str) -> dict:
    return {k: v for k, v in d.items() if k not in keys}


def _importer_structure_cases() -> list[Case]:
    cls = "importer-structure"
    inputs = ["src", "model.npz"]
    out: list[Case] = []

    def add(fmt: str, name: str, files: Callable[[], dict], expect: str = "refuse", names: list[str] | None = None,
            note: str = "", checks: list[Check] | None = None) -> None:
        out.append(Case(f"{cls}/{fmt}/{name}", cls, import_args(fmt), files, expect, inputs,
                        ["out"] if expect != "refuse" else [], names or [Path(format_members(fmt)[0]).name,
                                                                         Path(format_members(fmt)[0]).stem],
                        checks=checks or ([check_seq("out"), check_meta("out")] if expect != "refuse" else []),
                        note=note))

    cliff = format_members("cliff")[0]
    add("cliff", "pose-rows-mismatch", _npz_edit("cliff", cliff, lambda d: _set(d, pose=d["pose"][:-1])), "either",
        note="fewer parameter rows than detections is CLIFF's --infill layout")
    add("cliff", "member-dotdot-path", lambda: {**format_files("cliff"), cliff: zip_raw(
        [stored(n, b) for n, b in _members_of(format_files("cliff")[cliff]).items()]
        + [stored("../../../evil.npy", npy_bytes(np.arange(3.0)))])}, "either")
    add("cliff", "pose-strings", _npz_edit("cliff", cliff, lambda d: _set(d, pose=d["pose"].astype("U6"))), "either")
    add("cliff", "global-t-nan", _npz_edit("cliff", cliff, lambda d: _set(d, global_t=d["global_t"] * np.nan)), "either",
        note="people with non-finite values: refused, or dropped with a warning")
    add("cliff", "missing-pose", _npz_edit("cliff", cliff, lambda d: _drop(d, "pose")))
    add("cliff", "key-renamed", _npz_edit("cliff", cliff, lambda d: {("Pose" if k == "pose" else k): v for k, v in d.items()}))
    add("cliff", "focal-negative", _npz_edit("cliff", cliff, lambda d: _set(d, focal_l=-d["focal_l"])))
    add("cliff", "detection-frame-index-huge", _npz_edit("cliff", cliff, lambda d: _set(
        d, detection_all=np.concatenate([np.full((len(d["detection_all"]), 1), 1e12), d["detection_all"][:, 1:]], 1))),
        "either", note="a frame index of 1e12 must not make 1e12 frames")
    add("cliff", "imgname-object-payload", lambda: {**format_files("cliff"), cliff: lambda root: npz_bytes(
        _set(_load_npz_bytes(format_files("cliff")[cliff]), imgname=_obj(F.Evil(root / MARKER))))})
    out[-1].payload = True
    bev0 = format_members("bev")[0]
    add("bev", "results-not-dict", _npz_edit("bev", bev0, lambda d: _set(d, results=_obj([1, 2, 3])), True))
    add("bev", "verts-int8", _npz_edit("bev", bev0, lambda d: _bev_results(d, lambda r: _set(
        r, verts=r["verts"].astype(np.int8))), True), "either")
    add("bev", "verts-wrong-shape", _npz_edit("bev", bev0, lambda d: _bev_results(d, lambda r: _set(
        r, verts=r["verts"][..., :2])), True))
    add("bev", "cam-trans-inf", _npz_edit("bev", bev0, lambda d: _bev_results(d, lambda r: _set(
        r, cam_trans=r["cam_trans"] * np.inf)), True), "either")
    add("bev", "people-count-mismatch", _npz_edit("bev", bev0, lambda d: _bev_results(d, lambda r: _set(
        r, cam_trans=r["cam_trans"][:1])), True))
    add("bev", "track-ids-uint64", _npz_edit("bev", bev0, lambda d: _bev_results(d, lambda r: _set(
        r, track_ids=np.array([2**64 - 1] * len(r["track_ids"]), np.uint64))), True), "either")
    add("bev", "member-dotdot-path", lambda: {**format_files("bev"), bev0: zip_raw(
        [stored(n, b) for n, b in _members_of(format_files("bev")[bev0]).items()]
        + [stored("../../../evil.npy", npy_bytes(np.arange(3.0)))])}, "either")
    romp0 = format_members("romp")[0]
    add("romp", "results-shared-scalar", _npz_edit("romp", romp0, lambda d: _set(d, results=_obj(7.0)), True))
    add("romp", "cam-zero-scale", _npz_edit("romp", romp0, lambda d: _bev_results(d, lambda r: _set(
        r, cam=r["cam"] * 0.0, cam_trans=r["cam_trans"] * 0.0)), True), "either")
    ph = format_members("4dhumans")[0]
    add("4dhumans", "not-a-dict", _pickle_edit("4dhumans", ph, lambda o: list(o.values()), joblib=True))
    add("4dhumans", "smpl-entry-missing", _pickle_edit("4dhumans", ph, lambda o: {
        k: _set(v, smpl=[]) for k, v in o.items()}, joblib=True))
    add("4dhumans", "camera-nan", _pickle_edit("4dhumans", ph, lambda o: {
        k: _set(v, camera=[np.full(3, np.nan, np.float32) for _ in v["camera"]]) for k, v in o.items()}, joblib=True),
        "either")
    add("4dhumans", "tid-strings", _pickle_edit("4dhumans", ph, lambda o: {
        k: _set(v, tid=[f"id{t}" for t in v["tid"]]) for k, v in o.items()}, joblib=True), "either")
    mh0 = format_members("multihmr")[0]
    add("multihmr", "verts-nan", _npz_edit("multihmr", mh0, lambda d: _set(d, verts_smplx=d["verts_smplx"] * np.nan)),
        "either")
    add("multihmr", "key-renamed", _npz_edit("multihmr", mh0, lambda d: {k.upper(): v for k, v in d.items()}))
    spec = [m for m in format_members("spec") if "spec_results" in m][0]
    add("spec", "results-list", _pickle_edit("spec", spec, lambda o: [o], joblib=True), names=[Path(spec).name])
    add("spec", "vertices-complex", _pickle_edit("spec", spec, lambda o: _set(
        o, smpl_vertices=o["smpl_vertices"].astype(np.complex64)), joblib=True), names=[Path(spec).name])
    calib = [m for m in format_members("spec") if "camcalib" in m][0]
    add("spec", "calib-fpix-negative", _pickle_edit("spec", calib, lambda o: _set(o, f_pix=np.float64(-1.0)),
                                                      joblib=True), names=[Path(calib).name])
    ag = format_members("agora")[0]
    add("agora", "verts-string", _pickle_edit("agora", ag, lambda o: _set(o, verts="not an array")))
    add("agora", "joints-one-column", _pickle_edit("agora", ag, lambda o: _set(o, joints=np.zeros((24, 1)))))
    add("agora", "verts-nan", _pickle_edit("agora", ag, lambda o: _set(o, verts=o["verts"] * np.nan)), "either")
    bed = format_members("bedlam")[0]
    add("bedlam", "cam-int-singular", _npz_edit("bedlam", bed, lambda d: _set(d, cam_int=d["cam_int"] * 0.0)))
    add("bedlam", "pose-width-7", _npz_edit("bedlam", bed, lambda d: _set(d, pose_cam=d["pose_cam"][:, :7])))
    add("bedlam", "imgname-missing", _npz_edit("bedlam", bed, lambda d: _drop(d, "imgname")))
    add("bedlam", "imgname-code-point-beyond-unicode", _npz_edit("bedlam", bed, lambda d: _set(
        d, imgname=bad_text(d["imgname"]))), note="found by run_fuzz.py --seed 21 (iteration 94)")
    add("bedlam", "imgname-uint8", _npz_edit("bedlam", bed, lambda d: _set(d, imgname=np.zeros(len(d["imgname"]),
                                                                                               np.uint8))), "either")
    return out


# ---- the importers added with torch files (WHAM, GVHMR, TRAM, HybrIK, PyMAF-X, TRACE, SLAHMR, GLAMR) ---------
@functools.lru_cache(maxsize=None)
def fixture_scene() -> list[list[Any]]:
    """format_files' scene: people 3 and 5 in frame 0, person 3 in frame 1, nobody in frame 2."""
    return F.default_scene(tiny_model(), camera())


def _pelvis(frames: list[list[Any]]) -> list[np.ndarray]:
    return [np.array([p.joints_cam[0] for p in frame]).reshape(-1, 3) for frame in frames]


_SCENE_FRAMES = {  # the scene's frames each tool writes (frames with nobody: kept or not, as the tool does)
    "wham": lambda s: s[:2], "hybrik": lambda s: s[:2], "pymafx": lambda s: s[:2],
    "gvhmr": lambda s: [[p] for frame in s for p in frame],  # one tracked person per frame
    "tram": lambda s: s, "trace": lambda s: s, "slahmr": lambda s: s, "glamr": lambda s: s,
}
PELVIS_TRUTH = {fmt: (lambda pick=pick: _pelvis(pick(fixture_scene()))) for fmt, pick in _SCENE_FRAMES.items()}


def check_pelvis(out: str, truth: list[np.ndarray], atol_m: float = 2e-3) -> Check:
    """Frame ``i`` of ``out`` holds people whose joint 0 (camera frame, metres) is at ``truth[i]`` (P, 3)
    (both sorted by x): the importer undid the tool's conventions."""

    def check(root: Path, run: Any) -> list[str]:
        frames = sorted((root / out).glob("*.npz"))
        if len(frames) != len(truth):
            return [f"{out}/ has {len(frames)} frames, expected {len(truth)}"]
        problems = []
        for path, want in zip(frames, truth):
            joints = _load_npz(path).get("joints")
            got = np.zeros((0, 3)) if joints is None else joints[:, 0].astype(np.float64)
            if got.shape != want.shape or not np.allclose(got[np.argsort(got[:, 0])], want[np.argsort(want[:, 0])],
                                                           atol=atol_m):
                problems.append(f"{out}/{path.name}: pelvis {np.round(got, 3).tolist()}, expected "
                                f"{np.round(want, 3).tolist()}")
        return problems

    return check


def _cmd(root: Path) -> str:
    return f"touch {root / MARKER}"


def _replace(fmt: str, member: str, content: Content) -> Callable[[], dict]:
    return lambda: {**format_files(fmt), member: content}


def _tensors(obj: Any) -> Any:
    """``obj`` with every numeric numpy array made a torch tensor (tests/_fixtures_torch.py stand-ins)."""
    if isinstance(obj, np.ndarray) and obj.dtype in T._STORAGE_NAMES:
        return T.tensor(obj)
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f":
        return T.tensor(obj.astype(np.float32))
    if isinstance(obj, dict):
        return {k: _tensors(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_tensors(v) for v in obj)
    return obj


def npy_tensors_bytes(obj: Any) -> bytes:
    """``np.save`` of ``obj`` (a dict holding torch tensors), as TRAM writes hps_track_{k}.npy."""
    with tempfile.TemporaryDirectory() as tmp:
        return T.np_save_tensors(Path(tmp) / "x.npy", obj).read_bytes()


def torch_pickle_bytes(obj: Any) -> bytes:
    """A plain pickle (protocol 2) holding torch tensors, each storage a legacy stream (_load_from_bytes)."""
    return T._renamed(pickle.dumps(obj, protocol=2))


def _huge_storage_tensor(declared: int = 10**12) -> Any:
    """A tensor whose storage declares ``declared`` float32 elements and holds 4."""
    return T.Tensor(T.Storage(np.zeros(4, np.float32), declared=declared), 0, (2, 2), (2, 1))


def _gvhmr_bytes(edit: Callable[[dict], dict] = lambda r: r, legacy: bool = False, **kw: Any) -> bytes:
    """hmr4d_results.pt of the fixture scene (people one per frame), its results dict edited first."""
    results = edit(T.gvhmr_results([p for frame in fixture_scene() for p in frame], (W, H)))
    return T.legacy_bytes(results) if legacy else T.torch_zip_bytes(results, name="hmr4d_results", **kw)


def _incam(edit: Callable[[dict], dict]) -> Callable[[dict], dict]:
    return lambda r: _set(r, smpl_params_incam=edit(r["smpl_params_incam"]))


def _load_any_npy(data: bytes) -> Any:
    from rotavat_cli import unpickle

    arr = unpickle.load_npy_bytes(data, "x.npy")
    return arr.item() if arr.dtype.hasobject and arr.shape == () else arr


def _tram_edit(member: str, edit: Callable[[dict], dict], tensors: bool = True) -> Callable[[], dict]:
    """TRAM's files with ``member`` (a np.save of a dict) re-saved after ``edit``; tensors as torch's."""

    def files() -> dict[str, Content]:
        all_files = dict(format_files("tram"))
        new = edit(dict(_load_any_npy(all_files[member])))
        all_files[member] = npy_tensors_bytes(_tensors(new) if tensors else new)
        return all_files

    return files


def bad_text(strings: Any, code_point: int = 0x110000) -> np.ndarray:
    """A unicode array whose first string holds ``code_point`` (beyond U+10FFFF) in its file name:
    numpy stores and reads it, and makes a broken str of it (SystemError when sliced)."""
    arr = np.asarray(strings).astype(str)
    raw = np.frombuffer(arr.tobytes(), "<u4").copy()
    raw[max(0, len(str(arr.reshape(-1)[0])) - 5)] = code_point  # in the file name, before its extension
    return np.frombuffer(raw.tobytes(), arr.dtype.newbyteorder("<")).reshape(arr.shape)


def _trace_outputs(data: dict, fn: Callable[[dict], dict]) -> dict:
    data["outputs"] = _obj(fn(dict(data["outputs"].item())))
    return data


def _rows_of(d: dict, key: str, fn: Callable[[np.ndarray], Any]) -> dict:
    return _set(d, **{key: fn(np.asarray(d[key]))})


def _glamr_people(fn: Callable[[dict], dict]) -> Callable[[dict], dict]:
    return lambda o: _set(o, person_data={k: fn(dict(v)) for k, v in o["person_data"].items()})


def _track_info(fn: Callable[[dict], Any]) -> Callable[[], dict]:
    def files() -> dict[str, Content]:
        all_files = dict(format_files("slahmr"))
        info = json.loads(all_files[SLAHMR_TRACKS])
        out = fn(info)
        all_files[SLAHMR_TRACKS] = out if isinstance(out, bytes) else json.dumps(out).encode()
        return all_files

    return files


SLAHMR_TRACKS = "src/slahmr_run/track_info.json"


def _new_importer_cases() -> list[Case]:
    """Format-specific damage and code-running globals for the importers of torch files and joblib
    dicts (issue 15's classes: payloads, sizes declared but absent, wrong shapes, NaN, mismatched lengths)."""
    structure, gadget = "importer-structure", "pickle-gadget"
    inputs = ["src", "model.npz"]
    out: list[Case] = []

    def add(fmt: str, name: str, files: Callable[[], dict], expect: str = "refuse", names: list[str] | None = None,
            note: str = "", payload: bool = False, args: list[str] | None = None,
            checks: list[Check] | None = None) -> None:
        first = format_members(fmt)[0]
        out.append(Case(f"{gadget if payload else structure}/{fmt}/{name}", gadget if payload else structure,
                        args or import_args(fmt), files, expect, inputs, ["out"] if expect != "refuse" else [],
                        names or [Path(first).name, Path(first).stem],
                        checks=(checks if checks is not None else [check_seq("out")]) + [check_meta("out")]
                        if expect != "refuse" else [],
                        note=note, payload=payload))

    # ---- WHAM: joblib dump of defaultdict(dict) {track id: arrays} -----------------------------------
    wham = format_members("wham")[0]

    def tracks(fn: Callable[[dict], dict]) -> Callable[[dict], dict]:
        return lambda o: {k: fn(dict(v)) for k, v in o.items()}

    def wham_edit(edit: Callable[[Any], Any]) -> Callable[[], dict]:
        return _pickle_edit("wham", wham, edit, joblib=True)

    add("wham", "track-posix-system", _replace("wham", wham, lambda root: pickle.dumps(
        {1: {"verts": Reduce(os.system, (_cmd(root),)), "frame_ids": np.arange(2)}}, protocol=2)), payload=True)
    add("wham", "defaultdict-factory-os-system", lambda: {**format_files("wham"), wham: lambda root: pickle.dumps(
        __import__("collections").defaultdict(os.system, {1: {"frame_ids": np.arange(2)}}), protocol=2)},
        payload=True, note="a factory runs on every missing key")
    add("wham", "defaultdict-factory-numpy-dtype", wham_edit(lambda o: __import__("collections").defaultdict(
        np.dtype, dict(o))), note="an allowed global that is no builtin type: not a defaultdict factory")
    add("wham", "verts-2-columns", wham_edit(tracks(lambda t: _rows_of(t, "verts", lambda v: v[..., :2]))))
    add("wham", "frame-ids-rows-mismatch", wham_edit(tracks(lambda t: _rows_of(t, "frame_ids", lambda v: v[:-1]))))
    add("wham", "frame-ids-negative", wham_edit(tracks(lambda t: _rows_of(t, "frame_ids", lambda v: v - 100))))
    add("wham", "frame-ids-1e15", wham_edit(tracks(lambda t: _rows_of(t, "frame_ids", lambda v: v + 10**15))),
        "either", note="frames are the indices seen: 1e15 must not make 1e15 frames")
    add("wham", "pose-width-69", wham_edit(tracks(lambda t: _rows_of(t, "pose", lambda v: v[:, :69]))))
    add("wham", "betas-fewer-rows", wham_edit(tracks(lambda t: _rows_of(t, "betas", lambda v: v[:0]))))
    add("wham", "verts-nan", wham_edit(tracks(lambda t: _rows_of(t, "verts", lambda v: v * np.nan))), "either")
    add("wham", "track-not-dict", wham_edit(lambda o: {k: [1, 2, 3] for k in o}))
    add("wham", "track-key-string", wham_edit(lambda o: {f"id{k}": v for k, v in o.items()}))
    add("wham", "track-key-2**70", wham_edit(lambda o: {2**70 + int(k): v for k, v in o.items()}), "either",
        note="a track id no int64 holds: refused, or kept exactly")
    add("wham", "verts-other-vertex-count", wham_edit(tracks(lambda t: _rows_of(t, "verts", lambda v: v[:, :20]))))

    # ---- GVHMR: torch.save zip archive (data.pkl + storage records) ----------------------------------
    gv = format_members("gvhmr")[0]
    add("gvhmr", "data-pkl-os-system", _replace("gvhmr", gv, lambda root: _gvhmr_bytes(lambda r: _set(
        r, smpl_params_incam=T.Call(T.Global("os", "system"), (_cmd(root),))))), payload=True)
    add("gvhmr", "storage-built-by-eval", _replace("gvhmr", gv, lambda root: _gvhmr_bytes(_incam(lambda p: _set(
        p, transl=T.Call(T.Global("torch._utils", "_rebuild_tensor_v2"), (
            T.Call(T.Global("builtins", "eval"), (f"open({str(root / MARKER)!r}, 'w')",)), 0, (3, 3), (3, 1),
            False, __import__("collections").OrderedDict())))))), payload=True)
    add("gvhmr", "storage-record-missing", _replace("gvhmr", gv, _gvhmr_bytes(drop=("data/0",))))
    add("gvhmr", "storage-record-short", _replace("gvhmr", gv, _gvhmr_bytes(resize={"0": 8})),
        note="a storage record holding fewer bytes than its storage declares")
    add("gvhmr", "storage-declares-4TB", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, betas=_huge_storage_tensor()))), ))
    add("gvhmr", "tensor-shape-1e12", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, transl=T.Tensor(T.Storage(np.zeros(9, np.float32)), 0, (10**6, 10**6, 3), (3 * 10**6, 3, 1)))))))
    add("gvhmr", "tensor-past-its-storage", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, transl=T.Tensor(T.Storage(np.zeros(9, np.float32)), 5, (300, 3), (3, 1)))))))
    add("gvhmr", "tensor-negative-stride", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, transl=T.Tensor(T.Storage(np.zeros(9, np.float32)), 8, (3, 3), (-3, -1)))))))
    add("gvhmr", "byteorder-unknown", _replace("gvhmr", gv, _gvhmr_bytes(byteorder="middle")))
    add("gvhmr", "legacy-stream-truncated", _replace("gvhmr", gv, _gvhmr_bytes(legacy=True)[:-200]))
    add("gvhmr", "legacy-stream-valid", _replace("gvhmr", gv, _gvhmr_bytes(legacy=True)), "ok",
        checks=[check_seq("out", 3, [1, 1, 1]), check_pelvis("out", PELVIS_TRUTH["gvhmr"]())],
        note="torch.save(..., _use_new_zipfile_serialization=False): the same people")
    add("gvhmr", "transl-nan", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, transl=T.tensor(np.full((3, 3), np.nan, np.float32)))))), "either")
    add("gvhmr", "betas-fewer-frames", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, betas=T.tensor(np.zeros((2, 10), np.float32)))))))
    add("gvhmr", "body-pose-width-10", _replace("gvhmr", gv, _gvhmr_bytes(_incam(lambda p: _set(
        p, body_pose=T.tensor(np.zeros((3, 10), np.float32)))))))
    add("gvhmr", "K-zero", _replace("gvhmr", gv, _gvhmr_bytes(lambda r: _set(
        r, K_fullimg=T.tensor(np.zeros((3, 3, 3), np.float32))))))
    add("gvhmr", "K-inf", _replace("gvhmr", gv, _gvhmr_bytes(lambda r: _set(
        r, K_fullimg=T.tensor(np.full((3, 3, 3), np.inf, np.float32))))))
    add("gvhmr", "incam-not-dict", _replace("gvhmr", gv, _gvhmr_bytes(lambda r: _set(r, smpl_params_incam=[1, 2]))))
    add("gvhmr", "K-centre-1e300-no-image-size", _replace("gvhmr", gv, _gvhmr_bytes(lambda r: _set(
        r, K_fullimg=T.tensor(np.array([[500.0, 0, 1e300], [0, 500.0, 1e300], [0, 0, 1]], np.float64))))), "either",
        args=import_args("gvhmr")[:5] + ["--smpl-model", "model.npz"],
        note="the image size comes from 2 x K's principal point: 2e300 px")
    add("gvhmr", "model-is-smpl", lambda: {**format_files("gvhmr"), "model.npz": tiny_model_bytes()},
        note="GVHMR's parameters are SMPL-X: a 24-joint model is refused")

    # ---- TRAM: np.save of dicts of torch tensors (storages as legacy streams) --------------------------
    tram = format_members("tram")[0]
    cam = "src/tram/camera.npy"
    add("tram", "track-posix-system", _replace("tram", tram, lambda root: npy_tensors_bytes(
        {"pred_rotmat": T.Call(T.Global("posix", "system"), (_cmd(root),)), "frame": T.tensor(np.arange(2))})),
        payload=True)
    add("tram", "camera-posix-system", _replace("tram", cam, lambda root: npy_tensors_bytes(
        {"img_focal": T.Call(T.Global("posix", "system"), (_cmd(root),))})), payload=True, names=["camera.npy"])
    add("tram", "storage-declares-4TB", _tram_edit(tram, lambda d: _set(d, pred_shape=_huge_storage_tensor())))
    add("tram", "storage-stream-short", _tram_edit(tram, lambda d: _set(d, pred_shape=T.Tensor(
        T.Storage(np.zeros(20, np.float32), declared=4000), 0, (2, 10), (10, 1)))),
        note="a storage stream whose count promises more bytes than follow")
    add("tram", "rotmat-24x3", _tram_edit(tram, lambda d: _rows_of(d, "pred_rotmat", lambda v: v[..., 0])))
    add("tram", "shape-rows-mismatch", _tram_edit(tram, lambda d: _rows_of(d, "pred_shape", lambda v: v[:1])))
    add("tram", "frame-duplicate", _tram_edit(tram, lambda d: _rows_of(d, "frame", lambda v: v * 0)))
    add("tram", "frame-negative", _tram_edit(tram, lambda d: _rows_of(d, "frame", lambda v: v - 5)))
    add("tram", "frame-float", _tram_edit(tram, lambda d: _rows_of(d, "frame", lambda v: v + 0.5)))
    add("tram", "trans-nan", _tram_edit(tram, lambda d: _rows_of(d, "pred_trans", lambda v: v * np.nan)), "either")
    add("tram", "camera-focal-nan", _tram_edit(cam, lambda d: _set(d, img_focal=np.float64(np.nan)), tensors=False),
        names=["camera.npy"])
    add("tram", "camera-center-negative", _tram_edit(cam, lambda d: _set(d, img_center=np.array([-320.0, 240.0])),
                                                     tensors=False), names=["camera.npy"])
    add("tram", "camera-not-a-dict", _replace("tram", cam, npy_bytes(np.zeros((3, 3)))), names=["camera.npy"])
    add("tram", "camera-R-2x2", _tram_edit(cam, lambda d: _rows_of(d, "pred_cam_R", lambda v: v[:, :2, :2]),
                                           tensors=False), names=["camera.npy"])
    add("tram", "camera-center-1e300-no-image-size", _tram_edit(cam, lambda d: _set(d, img_center=np.array(
        [1e300, 1e300])), tensors=False), "either", names=["camera.npy"],
        args=import_args("tram")[:5] + ["--smpl-model", "model.npz"],
        note="the image size comes from 2 x img_center: 2e300 px")
    add("tram", "model-is-smplx", lambda: {**format_files("tram"), "model.npz": model_bytes("smplx")},
        names=["tram", "model.npz"])

    # ---- HybrIK: pickle of res_db (stacked rows) -----------------------------------------------------------
    hy = format_members("hybrik")[0]

    def hy_edit(edit: Callable[[dict], dict]) -> Callable[[], dict]:
        return _pickle_edit("hybrik", hy, edit)

    def boxes(fn: Callable[[np.ndarray], np.ndarray]) -> Callable[[dict], dict]:
        return lambda o: _rows_of(o, "bbox", lambda b: fn(b.astype(np.float64).copy()))

    def zero_width(b: np.ndarray) -> np.ndarray:
        b[:, 2] = b[:, 0]
        return b

    def zero_height(b: np.ndarray) -> np.ndarray:
        b[:, 3] = b[:, 1]
        return b

    add("hybrik", "res-db-posix-system", _replace("hybrik", hy, lambda root: pickle.dumps(
        {"pred_xyz_29": Reduce(os.system, (_cmd(root),))}, protocol=2)), payload=True)
    add("hybrik", "bbox-zero-width", hy_edit(boxes(zero_width)))
    add("hybrik", "bbox-zero-height", hy_edit(boxes(zero_height)), "either",
        note="HybrIK's focal scales with the box width only")
    add("hybrik", "bbox-all-zero", hy_edit(boxes(lambda b: b * 0.0)))
    add("hybrik", "bbox-negative-width", hy_edit(boxes(lambda b: b[:, [2, 1, 0, 3]])))
    add("hybrik", "bbox-nan", hy_edit(boxes(lambda b: b * np.nan)))
    add("hybrik", "width-nan", hy_edit(lambda o: _rows_of(o, "width", lambda v: v * np.nan)))
    add("hybrik", "width-inf", hy_edit(lambda o: _rows_of(o, "width", lambda v: v * np.inf)))
    add("hybrik", "width-zero", hy_edit(lambda o: _rows_of(o, "width", lambda v: v * 0)))
    add("hybrik", "xyz-24-joints", hy_edit(lambda o: _rows_of(o, "pred_xyz_29", lambda v: v[:, :24])))
    add("hybrik", "transl-fewer-rows", hy_edit(lambda o: _rows_of(o, "transl", lambda v: v[:1])))
    add("hybrik", "uvd-nan", hy_edit(lambda o: _rows_of(o, "pred_uvd", lambda v: v * np.nan)))
    add("hybrik", "uvd-other-camera", hy_edit(lambda o: _rows_of(o, "pred_uvd", lambda v: v * 1.7)),
        note="2D and 3D that no depth factor reconciles")
    add("hybrik", "img-path-ints", hy_edit(lambda o: _set(o, img_path=np.arange(len(o["img_path"])))))
    add("hybrik", "img-path-code-point-beyond-unicode", hy_edit(lambda o: _set(o, img_path=bad_text(o["img_path"]))))
    add("hybrik", "thetas-wrong-size", hy_edit(lambda o: _rows_of(o, "pred_thetas", lambda v: v[:, :100])))

    # ---- PyMAF-X: joblib dump of per-detection arrays (torch tensors possible in smplx_params) -------------
    pm = format_members("pymafx")[0]

    def pm_edit(edit: Callable[[dict], dict]) -> Callable[[], dict]:
        return _pickle_edit("pymafx", pm, edit, joblib=True, compress=0)

    def pm_torch(tensor: Any) -> Callable[[], dict]:
        from rotavat_cli import unpickle

        return lambda: {**format_files("pymafx"), pm: torch_pickle_bytes(_set(
            unpickle.loads(format_files("pymafx")[pm], pm), smplx_params=[{"shape": tensor}]))}

    add("pymafx", "output-posix-system", _replace("pymafx", pm, lambda root: F.evil_pickle(root / MARKER)),
        payload=True)
    add("pymafx", "torch-storage-declares-4TB", pm_torch(_huge_storage_tensor()))
    add("pymafx", "torch-storage-stream-short", pm_torch(T.Tensor(T.Storage(np.zeros(4, np.float32), declared=400),
                                                                  0, (2, 2), (2, 1))))
    add("pymafx", "frame-ids-negative", pm_edit(lambda o: _set(o, frame_ids=[-1 - i for i in o["frame_ids"]])))
    add("pymafx", "verts-2-columns", pm_edit(lambda o: _rows_of(o, "verts", lambda v: v[..., :2])))
    add("pymafx", "verts-fewer-rows", pm_edit(lambda o: _rows_of(o, "verts", lambda v: v[:1])))
    add("pymafx", "orig-cam-t-nan", pm_edit(lambda o: _rows_of(o, "orig_cam_t", lambda v: v * np.nan)), "either")
    add("pymafx", "joints2d-mixed-shapes", pm_edit(lambda o: _set(o, joints2d=[np.zeros((5, 3))] + list(
        o["joints2d"][1:]))))
    add("pymafx", "joints2d-strings", pm_edit(lambda o: _set(o, joints2d=["x"] * len(o["joints2d"]))), "either")
    add("pymafx", "model-vertex-count-differs", lambda: {**format_files("pymafx"), "model.npz": npz_bytes(_set(
        _load_npz_bytes(tiny_model_bytes()), v_template=np.zeros((7, 3), np.float32)))}, names=["model.npz"])

    # ---- TRACE: np.savez(outputs=dict, imgpaths=...) -----------------------------------------------------
    tr = format_members("trace")[0]

    def tr_edit(fn: Callable[[dict], dict]) -> Callable[[], dict]:
        return _npz_edit("trace", tr, lambda d: _trace_outputs(d, fn), objects=True)

    add("trace", "outputs-posix-system", _replace("trace", tr, lambda root: npz_bytes(
        {"outputs": _obj({"cam_trans": F.Evil(root / MARKER)}), "imgpaths": np.array(["/data/00000000.jpg"])})),
        payload=True)
    add("trace", "reorganize-idx-1e12", tr_edit(lambda o: _rows_of(o, "reorganize_idx", lambda v: v + 10**12)))
    add("trace", "reorganize-idx-negative", tr_edit(lambda o: _rows_of(o, "reorganize_idx", lambda v: v - 7)))
    add("trace", "reorganize-idx-fraction", tr_edit(lambda o: _rows_of(o, "reorganize_idx", lambda v: v + 0.5)))
    add("trace", "j3d-20-joints", tr_edit(lambda o: _rows_of(o, "j3d", lambda v: v[:, :20])))
    add("trace", "j3d-fewer-rows", tr_edit(lambda o: _rows_of(o, "j3d", lambda v: v[:1])))
    add("trace", "cam-trans-nan", tr_edit(lambda o: _rows_of(o, "cam_trans", lambda v: v * np.nan)), "either")
    add("trace", "track-ids-uint64-max", tr_edit(lambda o: _set(o, track_ids=np.full(len(o["track_ids"]), 2**64 - 1,
                                                                                      np.uint64))), "either",
        note="two people, one id no int64 holds: refused, dropped, or kept exactly")
    add("trace", "track-ids-fewer", tr_edit(lambda o: _rows_of(o, "track_ids", lambda v: v[:1])))
    add("trace", "thetas-width-69", tr_edit(lambda o: _rows_of(o, "smpl_thetas", lambda v: v[:, :69])))
    add("trace", "outputs-list", _npz_edit("trace", tr, lambda d: _set(d, outputs=_obj([1, 2])), objects=True))
    add("trace", "imgpaths-code-point-beyond-unicode", _npz_edit("trace", tr, lambda d: _set(
        d, imgpaths=bad_text(d["imgpaths"])), objects=True), note="found by run_fuzz.py --seed 21 (iteration 493)")
    add("trace", "imgpaths-ints", _npz_edit("trace", tr, lambda d: _set(d, imgpaths=np.arange(3)), objects=True))

    # ---- SLAHMR: *_world_results.npz + track_info.json ----------------------------------------------------
    sl = format_members("slahmr")[0]

    def sl_edit(edit: Callable[[dict], dict]) -> Callable[[], dict]:
        return _npz_edit("slahmr", sl, edit)

    add("slahmr", "trans-object-posix-system", lambda: {**format_files("slahmr"), sl: lambda root: npz_bytes(_set(
        _load_npz_bytes(format_files("slahmr")[sl]), trans=_obj(F.Evil(root / MARKER))))}, payload=True)
    add("slahmr", "trans-nan", sl_edit(lambda d: _rows_of(d, "trans", lambda v: v * np.nan)), "either")
    add("slahmr", "pose-body-width-60", sl_edit(lambda d: _rows_of(d, "pose_body", lambda v: v[..., :60])))
    add("slahmr", "betas-rows-mismatch", sl_edit(lambda d: _rows_of(d, "betas", lambda v: v[:1])))
    add("slahmr", "cam-R-3x2", sl_edit(lambda d: _rows_of(d, "cam_R", lambda v: v[..., :2])))
    add("slahmr", "cam-t-fewer-frames", sl_edit(lambda d: _rows_of(d, "cam_t", lambda v: v[:, :1])))
    add("slahmr", "intrins-zero", sl_edit(lambda d: _rows_of(d, "intrins", lambda v: v * 0)))
    add("slahmr", "intrins-nan", sl_edit(lambda d: _rows_of(d, "intrins", lambda v: v * np.nan)))
    tnames = ["track_info.json"]
    add("slahmr", "track-info-not-json", _track_info(lambda i: b"{tracks: not json"), names=tnames)
    add("slahmr", "track-info-deep-nesting", _track_info(lambda i: b"[" * 100_000 + b"]" * 100_000), names=tnames,
        note="json.loads recursion on 100,000 nested lists")
    add("slahmr", "track-info-id-2**70", _track_info(lambda i: _set(i, tracks={
        str(2**70 + int(k)): v for k, v in i["tracks"].items()})), "either", names=tnames,
        note="a track id no int64 holds: refused, or kept exactly")
    add("slahmr", "track-info-index-infinity", _track_info(lambda i: json.dumps(i).replace(
        '"index": 0', '"index": Infinity').encode()), names=tnames, note="JSON's Infinity token (json.loads reads it)")
    add("slahmr", "track-info-seq-start-nan", _track_info(lambda i: json.dumps(i).replace(
        '"seq_interval": [2', '"seq_interval": [NaN').encode()), names=tnames)
    add("slahmr", "track-info-vis-mask-short", _track_info(lambda i: _set(i, tracks={
        k: _set(v, vis_mask=v["vis_mask"][:3]) for k, v in i["tracks"].items()})), names=tnames)
    add("slahmr", "track-info-other-run", _track_info(lambda i: _set(i, tracks={
        k: _set(v, index=v["index"] + 5) for k, v in i["tracks"].items()})), names=tnames)
    add("slahmr", "track-info-seq-start-1e30", _track_info(lambda i: _set(i, meta=_set(
        i["meta"], seq_interval=[10**30, 10**30 + 3]))), names=tnames)
    add("slahmr", "intrins-1e30-no-image-size", sl_edit(lambda d: _rows_of(d, "intrins", lambda v: v * 1e30)),
        "either", args=import_args("slahmr")[:5] + ["--smpl-model", "model.npz"],
        note="the image size comes from 2 x (cx, cy): 6.4e32 px")
    add("slahmr", "model-is-smplx", lambda: {**format_files("slahmr"), "model.npz": model_bytes("smplx")},
        names=[Path(sl).name, "model.npz"])

    # ---- GLAMR: pickle of the optimiser's data dict (person_data per track id) ------------------------------
    gl = format_members("glamr")[0]

    def gl_edit(edit: Callable[[dict], dict]) -> Callable[[], dict]:
        return _pickle_edit("glamr", gl, edit)

    add("glamr", "person-data-posix-system", _replace("glamr", gl, lambda root: pickle.dumps(
        {"person_data": {3: Reduce(os.system, (_cmd(root),))}, "cam_pose": np.zeros((3, 4, 4))}, protocol=2)),
        payload=True)
    add("glamr", "person-key-inf", gl_edit(lambda o: _set(o, person_data={
        float("inf") if k == 3 else k: v for k, v in o["person_data"].items()})), note="int(inf) overflows")
    add("glamr", "person-key-2**70", gl_edit(lambda o: _set(o, person_data={
        2**70 + k: v for k, v in o["person_data"].items()})), "either",
        note="a person id no int64 holds: refused, or kept exactly")
    add("glamr", "person-key-string", gl_edit(lambda o: _set(o, person_data={
        f"p{k}": v for k, v in o["person_data"].items()})))
    add("glamr", "person-data-list", gl_edit(lambda o: _set(o, person_data=list(o["person_data"].values()))))
    add("glamr", "smpl-pose-width-72", gl_edit(_glamr_people(lambda p: _rows_of(
        p, "smpl_pose", lambda v: np.concatenate([v, v[:, :3]], axis=1)))))
    add("glamr", "cam-pose-3x3", gl_edit(lambda o: _rows_of(o, "cam_pose", lambda v: v[:, :3, :3])))
    add("glamr", "cam-pose-fewer-frames", gl_edit(lambda o: _rows_of(o, "cam_pose", lambda v: v[:2])))
    add("glamr", "root-trans-nan", gl_edit(_glamr_people(lambda p: _rows_of(
        p, "root_trans_world", lambda v: v * np.nan))), "either")
    add("glamr", "nobody-visible", gl_edit(_glamr_people(lambda p: _set(
        p, visible_orig=p["visible_orig"] * 0, visible=p["visible"] * 0))))
    add("glamr", "scale-zero", gl_edit(_glamr_people(lambda p: _set(p, scale=np.zeros(3, np.float32)))), "either",
        note="every mesh collapsed onto its root")
    add("glamr", "kp-2d-17-joints", gl_edit(_glamr_people(lambda p: _rows_of(p, "kp_2d_pred", lambda v: v[:, :17]))))
    def principal_inf(K: np.ndarray) -> np.ndarray:
        K = K.copy()
        K[:, 0, 2] = np.inf
        return K

    add("glamr", "cam-K-inf-no-image-size", gl_edit(_glamr_people(lambda p: _rows_of(p, "cam_K", principal_inf))),
        args=import_args("glamr")[:5] + ["--smpl-model", "model.npz"],
        note="the image size comes from 2 x cam_K's principal point: infinite here")
    return out


def _members_of(zip_bytes: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(zip_bytes)) as z:
        return {n: z.read(n) for n in z.namelist()}


def gen_pickles() -> list[Case]:
    """Code-running gadgets where each tool stores a pickle (payload must not run)."""
    cls = "pickle-gadget"
    targets = [("4dhumans", None), ("agora", None), ("spec", "spec_results"), ("multihmr", "pkl"), ("bev", "npz")]
    cases = []
    gadget_names = list(gadget_pickles(Path("/x")))
    for i, gname in enumerate(gadget_names):
        fmt, where = targets[i % len(targets)]

        def files(gname=gname, fmt=fmt, where=where) -> dict[str, Content]:
            all_files = dict(format_files(fmt))
            if fmt == "multihmr":
                all_files = {k: v for k, v in all_files.items() if not k.startswith("src/mh/")}
                all_files["src/mh/img_000.pkl"] = lambda root: gadget_pickles(root / MARKER)[gname]
            elif fmt == "bev":
                member = format_members("bev")[0]
                all_files[member] = lambda root: npz_from_members({"results.npy": _npy_object_raw(
                    gadget_pickles(root / MARKER)[gname])})
            else:
                member = [m for m in format_members(fmt) if where is None or where in m][0]
                all_files[member] = lambda root: gadget_pickles(root / MARKER)[gname]
            return all_files

        cases.append(Case(f"{cls}/{gname}/{fmt}", cls, import_args(fmt), files, "refuse", ["src", "model.npz"], [],
                          [], payload=True))
    return cases


def _npy_object_raw(pickled: bytes) -> bytes:
    """A .npy of dtype object whose data is ``pickled`` (what np.save writes for object arrays)."""
    return npy_header("|O", ()) + pickled


def gen_yaml() -> list[Case]:
    """Hostile meta.yaml, camera.yaml and --config files."""
    cls = "yaml"
    cases: list[Case] = []

    def meta(text: str | Callable[[Path], bytes]) -> Callable[[], dict]:
        return lambda: {**base_seq(), "seq/meta.yaml": text if callable(text) else text.encode()}

    def cam(text: str | Callable[[Path], bytes]) -> Callable[[], dict]:
        return lambda: {**base_seq(), "cam.yaml": text if callable(text) else text.encode()}

    def config(text: str | Callable[[Path], bytes]) -> Callable[[], dict]:
        return lambda: {**base_seq(), "config.yaml": text if callable(text) else text.encode()}

    def add(name: str, files: Callable[[], dict], args: list[str], expect: str, names: list[str], **kw: Any) -> None:
        outs = kw.pop("outputs", ["out"] if expect != "refuse" else [])
        checks = kw.pop("checks", OK_ALIGN_CHECKS if "align" in args and expect != "refuse" else [])
        cases.append(Case(f"{cls}/{name}", cls, args, files, expect, SEQ_INPUTS + ["config.yaml"], outs, names,
                          checks=checks, **kw))

    tag_cmd = lambda root: f"touch {root / MARKER}"  # noqa: E731
    for tag_name, tag in [("apply-os-system", "!!python/object/apply:os.system [{cmd!r}]"),
                          ("new-subprocess", "!!python/object/new:subprocess.Popen [[touch, {marker}]]"),
                          ("name-eval", "!!python/name:os.system")]:
        def text(root: Path, tag=tag) -> bytes:
            return ("image_size: [640, 480]\nfocal_length: 500.0\nsource: " + tag.format(cmd=tag_cmd(root), marker=root / MARKER)
                    + "\n").encode()

        add(f"meta-python-tag-{tag_name}", meta(text), INFO, "refuse", ["meta.yaml"], payload=True)

    def cam_tag(root: Path) -> bytes:
        return camera_yaml() + f"extra: !!python/object/apply:os.system [{tag_cmd(root)!r}]\n".encode()

    add("camera-python-tag", cam(cam_tag), ALIGN, "refuse", ["cam.yaml"], payload=True)
    add("config-python-tag", config(lambda root: f"align:\n  upright: !!python/object/apply:os.system [{tag_cmd(root)!r}]\n"
                                    .encode()), ALIGN + ["--config", "config.yaml"], "refuse", ["config.yaml"],
        payload=True)
    # alias bombs and deep nesting: measured in a subprocess
    add("meta-alias-bomb", meta(META.decode() + yaml_alias_bomb()), ALIGN, "either", ["meta.yaml"], subprocess=True,
        note="9^12 leaves through aliases in an unknown key that align copies to its output meta.yaml")
    add("config-alias-bomb", config("align:\n  stature_range_m: " + yaml_alias_bomb_inline() + "\n"),
        ALIGN + ["--config", "config.yaml"], "refuse", ["config.yaml"], subprocess=True,
        note="a wrong-typed value of 9^12 leaves: the error must not print (or copy) it expanded")
    add("meta-deep-nesting", meta(META.decode() + yaml_deep()), INFO, "either", ["meta.yaml"], subprocess=True,
        outputs=[])
    # wrong types and values
    add("config-deep-nesting", config("align:\n  stature_range_m: " + "[" * 100_000 + "]" * 100_000 + "\n"),
        ALIGN + ["--config", "config.yaml"], "refuse", ["config.yaml"])
    add("camera-deep-nesting", cam(camera_yaml().decode() + yaml_deep()), ALIGN, "either", ["cam.yaml"])
    add("meta-source-mapping", meta(META.decode().replace("source: fuzz", "source: {a: 1, b: [2, 3]}")), INFO,
        "either", ["meta.yaml"], outputs=[])
    add("meta-top-level-list", meta("- 640\n- 480\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-scalar", meta("just a string\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-focal-kind-bogus", meta("image_size: [640, 480]\nfocal_length: 500\nfocal_kind: true\n"), INFO,
        "refuse", ["meta.yaml", "focal_kind"])
    add("meta-image-size-zero", meta("image_size: [0, 480]\nfocal_length: 500\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-image-size-string", meta("image_size: big\nfocal_length: 500\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-image-size-binary", meta("image_size: !!binary AAAA\nfocal_length: 500\n"), INFO, "refuse",
        ["meta.yaml"])
    add("meta-focal-1e400", meta("image_size: [640, 480]\nfocal_length: 1e400\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-focal-string", meta("image_size: [640, 480]\nfocal_length: five hundred\n"), INFO, "refuse",
        ["meta.yaml"])
    add("meta-K-2x2", meta("image_size: [640, 480]\nK: [[500, 0], [0, 500]]\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-not-utf8", meta(lambda root: b"image_size: [640, 480]\nsource: caf\xe9 \xff\xfe\n"), INFO, "either",
        ["meta.yaml"], outputs=[])
    add("meta-invalid-yaml", meta("image_size: [640, 480\nfocal_length: : :\n"), INFO, "refuse", ["meta.yaml"])
    add("meta-empty", meta(""), INFO, "either", ["meta.yaml"], outputs=[])
    add("camera-height-1e300", cam(camera_yaml(height_m=1e300).decode()), ALIGN, "either", ["cam.yaml"],
        note="a camera 1e300 m high: refused, or finite results")
    add("camera-principal-point-1e12", cam(camera_yaml(principal_point=[1e12, 1e12]).decode()), ALIGN, "either",
        ["cam.yaml"])
    add("camera-height-negative", cam(_camera_min(height_m=-3.0)), ALIGN, "refuse", ["cam.yaml"])
    add("camera-focal-zero", cam(_camera_min(focal_px=0.0)), ALIGN, "refuse", ["cam.yaml"])
    add("camera-pitch-nan", cam(_camera_min(pitch_deg=".nan")), ALIGN, "refuse", ["cam.yaml"])
    add("camera-missing-focal", cam("image_size: [640, 480]\npitch_deg: 15\nheight_m: 3\n"), ALIGN, "refuse",
        ["cam.yaml"])
    add("camera-list", cam("[1, 2, 3]\n"), ALIGN, "refuse", ["cam.yaml"])
    add("camera-up-disagrees", cam(camera_yaml(up_cam=[0.0, 1.0, 0.0]).decode()), ALIGN, "refuse", ["cam.yaml"])
    add("camera-is-directory", lambda: {**base_seq()}, ["align", "--in", "seq", "--camera", "seq", "--out", "out"],
        "refuse", ["seq", "--camera"])
    add("config-unknown-key", config("align:\n  uprite: paper\n"), ALIGN + ["--config", "config.yaml"], "refuse",
        ["config.yaml"])
    add("config-wrong-type", config("align:\n  jobs: many\n"), ALIGN + ["--config", "config.yaml"], "refuse",
        ["config.yaml"])
    add("config-section-scalar", config("align: 3\n"), ALIGN + ["--config", "config.yaml"], "refuse", ["config.yaml"])
    add("config-negative-jobs", config("align:\n  jobs: -4\n"), ALIGN + ["--config", "config.yaml"], "refuse",
        ["config.yaml", "jobs"])
    add("config-jobs-1e100", config("align:\n  jobs: 1e100\n"), ALIGN + ["--config", "config.yaml"], "either",
        ["config.yaml", "jobs"])
    add("config-stature-range-inverted", config("align:\n  stature_range_m: [2.3, 1.0]\n"),
        ALIGN + ["--config", "config.yaml"], "refuse", ["config.yaml", "stature_range_m"])
    add("config-grid-steps-zero", config("calibrate:\n  method: grid\n  grid:\n    steps: [0, 0, 0]\n"),
        ["calibrate", "seq", "--out", "cal.yaml", "--config", "config.yaml"], "refuse", ["config.yaml", "steps"],
        outputs=[])
    add("config-grid-steps-5000", config("calibrate:\n  method: grid\n  grid:\n    steps: [5000, 5000, 5000]\n"),
        ["calibrate", "seq", "--out", "cal.yaml", "--config", "config.yaml"], "refuse", ["config.yaml", "steps"],
        subprocess=True, outputs=[], note="1.25e11 grid cells (limits.max_grid_cells is 2e6)")
    add("config-python-bool-as-int", config("align:\n  jobs: true\n"), ALIGN + ["--config", "config.yaml"], "refuse",
        ["config.yaml", "jobs"])
    add("config-is-binary", config(lambda root: bytes(range(256))), ALIGN + ["--config", "config.yaml"], "refuse",
        ["config.yaml"])
    add("config-missing", lambda: dict(base_seq()), ALIGN + ["--config", "nope.yaml"], "refuse", ["nope.yaml"])
    add("config-empty", config(""), ALIGN + ["--config", "config.yaml"], "ok", ["config.yaml"])
    return cases


def _camera_min(**override: Any) -> str:
    d = {"image_size": [W, H], "focal_px": 500.0, "pitch_deg": 15.0, "roll_deg": 0.0, "height_m": 3.0}
    d.update(override)
    return "".join(f"{k}: {v}\n" for k, v in d.items())


def gen_paths() -> list[Case]:
    """Hostile output places: the input, inside it, around it, foreign files, bad names."""
    cls = "paths"
    cases: list[Case] = []
    s_files = lambda: {**{k.replace("seq/", "s/pred/", 1).replace("gt/", "s/gt/", 1): v  # noqa: E731
                          for k, v in base_seq().items()}, "s/notes.txt": b"the user's notes\n"}
    s_inputs = ["s/pred", "cam.yaml"]
    a = lambda *rest: ["align", "--in", "s/pred", "--camera", "cam.yaml", *rest]  # noqa: E731

    def add(name: str, args: list[str], expect: str, names: list[str] | None = None, files: Any = s_files,
            inputs: list[str] | None = None, outputs: list[str] | None = None, **kw: Any) -> None:
        cases.append(Case(f"{cls}/{name}", cls, args, files, expect, inputs if inputs is not None else s_inputs,
                          outputs if outputs is not None else [], names or [], **kw))

    add("align-out-holds-input", a("--out", "s"), "refuse", ["s"])
    add("align-out-inside-input", a("--out", "s/pred/aligned"), "refuse", ["s/pred"])
    add("align-out-is-input", a("--out", "s/pred"), "refuse", ["s/pred"])
    add("align-out-dot-holds-input", a("--out", "."), "refuse", ["."])
    add("align-out-dot-foreign-cwd", ["align", "--in", "../s/pred", "--camera", "../cam.yaml", "--out", "."], "refuse",
        ["."], files=lambda: {**s_files(), "work/report.docx": b"someone's document"}, cwd="work")
    add("align-out-regular-file", a("--out", "s/notes.txt"), "refuse", ["notes.txt"])
    add("align-out-foreign-folder", a("--out", "mine"), "refuse", ["mine"],
        files=lambda: {**s_files(), "mine/thesis.tex": b"\\documentclass{article}", "mine/data.npz": b"PK"})
    add("align-out-foreign-folder-force", a("--out", "mine", "--force"), "ok",
        files=lambda: {**s_files(), "mine/thesis.tex": b"\\documentclass{article}"}, outputs=["mine"],
        checks=[check_seq("mine", 3, [4, 4, 4])], note="--force replaces a foreign folder (only that folder)")
    add("align-out-empty-folder", a("--out", "empty"), "ok", dirs=["empty"], outputs=["empty"],
        checks=[check_seq("empty", 3, [4, 4, 4]), check_marker("empty")])
    add("align-out-own-previous-output", a("--out", "prev"), "ok", pre=[a("--out", "prev", "--quiet")],
        outputs=["prev"], checks=[check_seq("prev", 3, [4, 4, 4]), check_marker("prev")])
    add("align-force-never-input", a("--out", "s", "--force"), "refuse", ["s"])
    add("align-out-symlink-to-input", a("--out", "link"), "refuse", ["link"], symlinks={"link": "s/pred"})
    add("align-out-symlink-to-foreign", a("--out", "link"), "refuse", ["link"],
        files=lambda: {**s_files(), "elsewhere/keep.txt": b"keep"}, symlinks={"link": "elsewhere"})
    add("align-out-name-300-chars", a("--out", "o" * 300), "refuse", ["o" * 40])
    add("align-out-proc-self", a("--out", "/proc/self/x"), "refuse", ["/proc/self/x"])
    add("align-out-under-regular-file", a("--out", "s/notes.txt/out"), "refuse", ["notes.txt"])
    add("align-out-readonly-parent", a("--out", "ro/out"), "refuse" if os.geteuid() != 0 else "either", ["ro"],
        dirs=["ro"], readonly=["ro"], outputs=["ro/out"] if os.geteuid() == 0 else [],
        note="root ignores mode 0555: then either" if os.geteuid() == 0 else "")
    add("align-in-dot", ["align", "--in", ".", "--camera", "../../cam.yaml"], "either", ["."], cwd="s/pred",
        outputs=["s/pred_aligned", "s/._aligned", "s/_aligned"])
    add("align-in-file", ["align", "--in", "s/notes.txt", "--camera", "cam.yaml", "--out", "out"], "refuse",
        ["notes.txt"])
    add("align-in-missing", ["align", "--in", "nope", "--camera", "cam.yaml", "--out", "out"], "refuse", ["nope"])
    add("info-seq-dot", ["info", "."], "ok", cwd="s/pred")
    add("calibrate-out-is-frame", ["calibrate", "s/pred", "--out", "s/pred/000000.npz"], "refuse", ["000000.npz"])
    add("calibrate-out-is-input-dir", ["calibrate", "s/pred", "--out", "s/pred"], "refuse", ["s/pred"])
    add("calibrate-out-meta", ["calibrate", "s/pred", "--out", "s/pred/meta.yaml"], "refuse", ["meta.yaml"])
    add("calibrate-default-out", ["calibrate", "s/pred"], "ok", outputs=["s/pred/camera.yaml"],
        checks=[check_camera_yaml("s/pred/camera.yaml")], note="SEQ/camera.yaml: the documented exception")
    add("calibrate-over-user-camera", ["calibrate", "s/pred"], "refuse", ["camera.yaml"],
        files=lambda: {**s_files(), "s/pred/camera.yaml": camera_yaml()},
        note="a camera.yaml rotavat did not write is never replaced")
    add("calibrate-out-foreign-file", ["calibrate", "s/pred", "--out", "s/notes.txt"], "refuse", ["notes.txt"])
    add("calibrate-seq-dot", ["calibrate", ".", "--out", "../../cal.yaml"], "ok", cwd="s/pred", outputs=["cal.yaml"],
        checks=[check_camera_yaml("cal.yaml")])
    add("batch-out-inside-input", ["batch", "s", "--out", "s/pred", "--steps", "calibrate,align"], "refuse",
        ["s/pred"], inputs=["s"])
    add("batch-out-is-root", ["batch", "s", "--out", "s", "--steps", "calibrate,align"], "refuse", ["s"], inputs=["s"])
    add("batch-out-foreign-folder", ["batch", "s", "--out", "mine", "--steps", "calibrate,align"], "refuse", ["mine"],
        inputs=["s"], files=lambda: {**s_files(), "mine/keep.txt": b"keep"})
    add("import-out-is-src", import_args("bev", out="src/bev"), "refuse", ["bev"], files=lambda: format_files("bev"),
        inputs=["src", "model.npz"])
    add("import-out-inside-src", import_args("bev", out="src/bev/out"), "refuse", ["bev"],
        files=lambda: format_files("bev"), inputs=["src", "model.npz"])
    add("import-out-holds-src", import_args("bev", out="src"), "refuse", ["src"], files=lambda: format_files("bev"),
        inputs=["src", "model.npz"])
    add("import-out-regular-file", import_args("cliff", out="model.npz"), "refuse", ["model.npz"],
        files=lambda: format_files("cliff"), inputs=["src", "model.npz"])
    add("eval-out-inside-input", ["eval", "s/pred", "--gt", "s/gt", "--out", "s/pred"], "refuse", ["s/pred"],
        inputs=["s/pred", "s/gt"])
    add("eval-out-foreign-metrics", ["eval", "s/pred", "--gt", "s/gt", "--out", "res"], "refuse", ["metrics"],
        inputs=["s/pred", "s/gt"], files=lambda: {**s_files(), "res/metrics.json": b'{"mine": 1}\n'})
    add("eval-per-person-is-input", ["eval", "s/pred", "--gt", "s/gt", "--out", "res", "--per-person",
                                     "s/pred/000000.npz"], "refuse", ["000000.npz"], inputs=["s/pred", "s/gt"])
    add("render-out-is-input", ["render", "s/pred", "--camera", "cam.yaml", "--out", "s/pred", "--renderer", "fallback"],
        "refuse", ["s/pred"])
    add("export-out-is-frame", ["export", "s/pred", "--camera", "cam.yaml", "--out", "s/pred/000000.npz"], "refuse",
        ["000000.npz"])
    add("export-out-inside-input", ["export", "s/pred", "--camera", "cam.yaml", "--out", "s/pred/scene.glb"], "refuse",
        ["s/pred"])
    add("render-out-foreign-folder", ["render", "s/pred", "--camera", "cam.yaml", "--out", "mine", "--renderer",
                                      "fallback"], "refuse", ["mine"],
        files=lambda: {**s_files(), "mine/holiday.png": b"\x89PNG not rotavat's"})
    add("export-out-foreign-glb", ["export", "s/pred", "--camera", "cam.yaml", "--out", "scene.glb"], "refuse",
        ["scene.glb"], files=lambda: {**s_files(), "scene.glb": b"glTF user file"})
    add("synth-out-is-foreign-folder", ["synth", "s", "--frames", "1", "--people", "1"], "refuse", ["s"])
    return cases


def gen_obj() -> list[Case]:
    """OBJ frame folders: stray files, a folder named 0.obj, symlinks, non-UTF-8, broken values."""
    cls = "obj"
    base = lambda: {**contract_seq("seq", form="obj"), "cam.yaml": camera_yaml()}  # noqa: E731
    info = ["info", "seq"]
    align = ["align", "--in", "seq", "--camera", "cam.yaml", "--out", "out"]
    good = obj_text(tiny_body()[0] + [0, 0, -8], tiny_body()[1])
    cases: list[Case] = []

    def add(name: str, extra: dict, args: list[str], expect: str, names: list[str] | None = None, **kw: Any) -> None:
        outs = ["out"] if "align" in args and expect != "refuse" else []
        cases.append(Case(f"{cls}/{name}", cls, args, lambda: {**base(), **extra}, expect, ["seq", "cam.yaml"], outs,
                          names or [], **kw))

    add("valid-control/info", {}, info, "ok")
    add("valid-control/align", {}, align, "ok", checks=[check_seq("out", 3, [4, 4, 4], form="obj"),
                                                         check_people_csv("out", 12)])
    add("stray-file/info", {"seq/000001/notes.txt": b"hello"}, info, "either", ["000001", "notes.txt"])
    add("stray-file/align", {"seq/000001/notes.txt": b"hello"}, align, "either", ["000001", "notes.txt"])
    add("non-integer-stem", {"seq/000001/alice.obj": good.encode()}, info, "either", ["alice.obj"])
    add("non-utf8-comment", {"seq/000001/10.obj": b"# caf\xe9 \xff\xfe\n" + good.encode()}, info, "either",
        ["10.obj"])
    add("non-utf8-vertex", {"seq/000001/10.obj": good.replace("v ", "v \xff", 1).encode("latin1")}, info, "refuse",
        ["10.obj"])
    add("binary-garbage", {"seq/000001/10.obj": np.random.default_rng(5).bytes(2000)}, info, "refuse", ["10.obj"])
    add("vertex-nan", {"seq/000001/10.obj": re.sub(r"^v .*$", "v nan nan nan", good, count=1, flags=re.M).encode()},
        info, "refuse", ["10.obj"])
    add("vertex-inf", {"seq/000001/10.obj": re.sub(r"^v .*$", "v 0 inf 8", good, count=1, flags=re.M).encode()},
        align, "refuse", ["10.obj"])
    add("face-index-out-of-range", {"seq/000001/10.obj": (good + "f 1 2 999999\n").encode()}, info, "refuse",
        ["10.obj"])
    add("topology-differs", {"seq/000001/10.obj": obj_text(tiny_body()[0][:30] + [0, 0, -8], tiny_body()[1][
        np.all(tiny_body()[1] < 30, axis=1)]).encode()}, info, "refuse", ["10.obj", "11.obj", "000001"])
    add("empty-obj", {"seq/000001/10.obj": b""}, info, "refuse", ["10.obj"])
    add("mixed-npz-and-obj", {"seq/000009.npz": npz_bytes(scene_frames()[0])}, info, "refuse", ["seq"])
    cases.append(Case(f"{cls}/subfolder-named-0.obj", cls, info, base, "either", ["seq", "cam.yaml"], [],
                      ["0.obj", "000001"], dirs=["seq/000001/0.obj"]))
    cases.append(Case(f"{cls}/subfolder-named-0.obj/align", cls, align, base, "either", ["seq", "cam.yaml"], ["out"],
                      ["0.obj", "000001"], dirs=["seq/000001/0.obj"]))
    cases.append(Case(f"{cls}/symlink-to-foreign-obj", cls, align, lambda: {**base(), "elsewhere/99.obj": good.encode()},
                      "either", ["seq", "cam.yaml", "elsewhere"], ["out"], ["99.obj"],
                      symlinks={"seq/000001/99.obj": "{root}/elsewhere/99.obj"},
                      note="the link's target is read at most, never written"))
    cases.append(Case(f"{cls}/symlink-loop", cls, info, base, "either", ["seq", "cam.yaml"], [], ["98.obj"],
                      symlinks={"seq/000001/98.obj": "98.obj"}))
    cases.append(Case(f"{cls}/symlink-dangling", cls, info, base, "either", ["seq", "cam.yaml"], [], ["97.obj"],
                      symlinks={"seq/000001/97.obj": "{root}/nowhere/97.obj"}))
    cases.append(Case(f"{cls}/symlink-to-dev-zero", cls, info, base, "either", ["seq", "cam.yaml"], [], ["96.obj"],
                      symlinks={"seq/000001/96.obj": "/dev/zero"}, subprocess=True, timeout_s=20,
                      note="an endless file: read with a bound, skipped, or refused"))
    cases.append(Case(f"{cls}/frame-npz-is-fifo", "npz-frame", INFO, lambda: dict(base_seq()), "either", SEQ_INPUTS,
                      [], ["000005.npz"], fifos=["seq/000005.npz"], timeout_s=5,
                      note="a named pipe among the frames must not hang the reader"))
    cases.append(Case(f"{cls}/camera-yaml-is-fifo", "yaml", INFO, lambda: dict(base_seq()), "either", SEQ_INPUTS,
                      [], ["seq/camera.yaml", "camera.yaml"], fifos=["seq/camera.yaml"],
                      timeout_s=5, note="SEQ/camera.yaml a named pipe: refused or skipped, never waited on"))
    return cases


def gen_degenerate() -> list[Case]:
    """Degenerate scenes: one depth, above the horizon, nobody, a camera looking straight down/up."""
    cls = "degenerate"
    cases: list[Case] = []

    def seq(frames: list[dict], extra: dict | None = None) -> Callable[[], dict]:
        return lambda: {**contract_seq("seq", frames=frames), "cam.yaml": camera_yaml(), **(extra or {})}

    same_row = [(x, -9.0) for x in (-3.0, -1.5, 0.0, 1.5, 3.0)]
    fr_row = lambda: scene_frames(3, 5, places=same_row)  # noqa: E731
    above = lambda: scene_frames(2, 3, cam=Camera((W, H), 500.0, None, np.deg2rad(-30.0), 0.0, 3.0))  # noqa: E731
    empty = lambda: scene_frames(3, 0)  # noqa: E731
    calib = ["calibrate", "seq", "--out", "cal.yaml"]

    def add(name: str, files: Callable[[], dict], args: list[str], expect: str, outputs: list[str] | None = None,
            checks: list[Check] | None = None, names: list[str] | None = None, note: str = "") -> None:
        cases.append(Case(f"{cls}/{name}", cls, args, files, expect, ["seq", "cam.yaml"],
                          outputs if outputs is not None else [], names or ["seq"], checks=checks or [], note=note))

    add("same-foot-row/calibrate", lambda: seq(fr_row())(), calib, "either", ["cal.yaml"], [check_camera_yaml("cal.yaml")])
    add("same-foot-row/align-calibrating", lambda: seq(fr_row())(), ["align", "--in", "seq", "--out", "out"], "either",
        ["out"], [check_seq("out", 3, [5, 5, 5])])
    add("above-horizon/align", lambda: seq(above())(), ALIGN, "ok", ["out"],
        [check_seq("out", 2, [3, 3]), check_people_csv("out", 6)],
        note="people seen by a camera looking up have their feet above the horizon: flagged, never dropped")
    add("above-horizon/calibrate", lambda: seq(above())(), calib, "either", ["cal.yaml"], [check_camera_yaml("cal.yaml")])
    add("nobody/calibrate", lambda: seq(empty())(), calib, "refuse")
    add("nobody/align", lambda: seq(empty())(), ALIGN, "ok", ["out"], [check_seq("out", 3, [0, 0, 0])])
    add("nobody/align-calibrating", lambda: seq(empty())(), ["align", "--in", "seq", "--out", "out"], "refuse")
    add("nobody/info", lambda: seq(empty())(), INFO, "ok")
    add("nobody/eval", lambda: {**seq(empty())(), **{k.replace("seq/", "gt/", 1): v for k, v in
                                                      contract_seq("seq", frames=empty()).items()}},
        ["eval", "seq", "--gt", "gt", "--out", "ev"], "either", ["ev"])
    add("one-person/calibrate", lambda: seq(scene_frames(1, 1))(), calib, "ok", ["cal.yaml"],
        [check_camera_yaml("cal.yaml")], note="one pair: the priors answer, and fit.implausible says what is open")
    add("heads-below-feet/calibrate", lambda: seq([_swap_2d(f) for f in scene_frames()])(), calib, "refuse")
    add("identical-points/calibrate", lambda: seq([_set(f, feet_2d=np.full_like(f["feet_2d"], 100.0),
                                                        heads_2d=np.full_like(f["heads_2d"], 100.0))
                                                   for f in scene_frames()])(), calib, "refuse")
    for pitch in (90.0, -90.0, 89.999):
        add(f"camera-pitch-{pitch:+g}/align", lambda pitch=pitch: {**seq(scene_frames())(),
                                                                   "cam.yaml": _camera_min(pitch_deg=pitch).encode()},
            ALIGN, "either", ["out"], [check_seq("out", 3, [4, 4, 4]), check_people_csv("out", 12)], ["cam.yaml"])
    add("camera-roll-180/align", lambda: {**seq(scene_frames())(), "cam.yaml": _camera_min(roll_deg=180.0).encode()},
        ALIGN, "either", ["out"], [check_seq("out", 3, [4, 4, 4])], ["cam.yaml"])
    add("person-at-camera-centre/align", lambda: seq([_set(f, vertices=np.zeros_like(f["vertices"]),
                                                           joints=np.zeros_like(f["joints"])) for f in scene_frames()])(),
        ALIGN, "ok", ["out"], [check_seq("out", 3, [4, 4, 4]), check_people_csv("out", 12)],
        note="every vertex at the camera centre: flagged degenerate_mesh")
    add("people-behind-camera/align", lambda: seq([_set(f, vertices=f["vertices"] * np.array([1, 1, -1], np.float32))
                                                   for f in scene_frames()])(),
        ALIGN, "ok", ["out"], [check_seq("out", 3, [4, 4, 4]), check_people_csv("out", 12)])
    add("nobody/render", lambda: seq(empty())(), ["render", "seq", "--camera", "cam.yaml", "--out", "r",
                                                  "--renderer", "fallback"], "either", ["r"])
    add("nobody/export", lambda: seq(empty())(), ["export", "seq", "--camera", "cam.yaml", "--out", "e.glb"], "either",
        ["e.glb"])
    return cases


def _swap_2d(fr: dict) -> dict:
    return _set(fr, feet_2d=fr["heads_2d"], heads_2d=fr["feet_2d"])


def gen_options() -> list[Case]:
    """Bad option values (usage errors are exit 2 and one line too) and the one legitimate exit 1."""
    cls = "options"
    cases: list[Case] = []

    def add(name: str, args: list[str], expect: str, names: list[str], outputs: list[str] | None = None,
            **kw: Any) -> None:
        cases.append(Case(f"{cls}/{name}", cls, args, lambda: dict(base_seq()), expect, SEQ_INPUTS, outputs or [],
                          names, **kw))

    cal = ["calibrate", "seq", "--out", "cal.yaml"]
    add("unknown-option", ["align", "--in", "seq", "--bogus"], "refuse", ["--bogus"])
    add("jobs-negative", ALIGN + ["--jobs", "-1"], "refuse", ["--jobs"])
    add("jobs-not-int", ALIGN + ["--jobs", "lots"], "refuse", ["--jobs"])
    add("missing-argument", ["calibrate"], "refuse", ["SEQ", "seq"])
    add("unknown-command", ["frobnicate"], "refuse", ["frobnicate"])
    add("focal-nan", cal + ["--focal", "nan"], "refuse", ["--focal", "focal_px"])
    add("focal-inf", cal + ["--focal", "inf"], "refuse", ["--focal", "focal_px"])
    add("focal-negative", cal + ["--focal", "-500"], "refuse", ["--focal", "focal_px"])
    add("camera-height-zero", cal + ["--camera-height", "0"], "refuse", ["--camera-height", "camera_height"])
    add("principal-point-nan", cal + ["--principal-point", "nan", "nan"], "refuse", ["--principal-point", "principal_point"])
    add("person-height-1e300", cal + ["--person-height", "1e300"], "refuse", ["--person-height", "person_height"])
    add("method-bogus", cal + ["--method", "magic"], "refuse", ["--method", "magic"])
    add("upright-bogus", ALIGN + ["--upright", "sideways"], "refuse", ["--upright", "sideways"])
    add("from-bogus", ALIGN + ["--from", "nope"], "refuse", ["nope", "--from"])
    add("render-size-zero", ["render", "seq", "--camera", "cam.yaml", "--out", "r", "--size", "0", "0"], "refuse",
        ["--size"])
    add("render-frames-garbage", ["render", "seq", "--camera", "cam.yaml", "--out", "r", "--frames", "1,x,;"],
        "refuse", ["--frames"])
    add("export-frame-out-of-range", ["export", "seq", "--camera", "cam.yaml", "--out", "e.glb", "--frame", "999"],
        "refuse", ["--frame", "999"])
    add("eval-fail-if-malformed", ["eval", "seq", "--gt", "gt", "--out", "ev", "--fail-if", "w_mpjpe>>"], "refuse",
        ["--fail-if", "w_mpjpe"])
    add("eval-fail-if-unknown-metric", ["eval", "seq", "--gt", "gt", "--out", "ev", "--fail-if", "happiness<3"],
        "refuse", ["--fail-if", "happiness"])
    add("eval-fail-if-trips", ["eval", "seq", "--gt", "gt", "--out", "ev", "--fail-if", "w_mpjpe>-1"], "gate",
        ["w_mpjpe"], outputs=["ev"], note="the one legitimate exit 1")
    add("eval-joints-garbage", ["eval", "seq", "--gt", "gt", "--out", "ev", "--joints", "0-x"], "refuse", ["--joints"])
    add("eval-joints-huge-range", ["eval", "seq", "--gt", "gt", "--out", "ev", "--joints", "0-1000000000000"], "refuse",
        ["--joints"], subprocess=True, note="a range of 1e12 joints must not be expanded")
    add("render-size-huge", ["render", "seq", "--camera", "cam.yaml", "--out", "r", "--size", "100000", "100000",
                             "--renderer", "fallback"], "refuse", ["--size"], subprocess=True,
        note="1e10-pixel panels")
    add("synth-image-size-zero", ["synth", "new", "--image-size", "0", "0"], "refuse", ["--image-size"])
    return cases


def gen_process() -> list[Case]:
    """Worker counts: --jobs 10000 and jobs: 10000 in a config must be capped; plus the clean baseline."""
    cls = "process"
    cap = max(16, 4 * (os.cpu_count() or 1))
    long_seq = lambda: {**contract_seq("seq", n_frames=12, n_people=3), "cam.yaml": camera_yaml(),  # noqa: E731
                        "config.yaml": b"align:\n  jobs: 10000\nbatch:\n  jobs: 10000\n  chunk_frames: 1\n"}
    batch_root = lambda: {**{f"root/{k}": v for k, v in contract_seq("a", n_frames=4, n_people=4).items()},  # noqa: E731
                          **{f"root/{k}": v for k, v in contract_seq("b", n_frames=4, n_people=4).items()}}
    return [
        Case(f"{cls}/baseline-align", cls, ["align", "--in", "seq", "--camera", "cam.yaml", "--out", "out"],
             lambda: dict(base_seq()), "ok", SEQ_INPUTS, ["out"], checks=OK_ALIGN_CHECKS, subprocess=True,
             note="the clean run: its peak RSS is the baseline the 700 MB bound is set against"),
        Case(f"{cls}/align-jobs-10000", cls, ["align", "--in", "seq", "--camera", "cam.yaml", "--out", "out", "--jobs",
                                             "10000"], long_seq, "ok", ["seq", "cam.yaml"], ["out"],
             checks=[check_seq("out", 12, [3] * 12)], subprocess=True, max_children=cap, max_seconds=20),
        Case(f"{cls}/align-config-jobs-10000", cls, ["align", "--in", "seq", "--camera", "cam.yaml", "--out", "out",
                                                     "--config", "config.yaml"], long_seq, "ok",
             ["seq", "cam.yaml", "config.yaml"], ["out"], checks=[check_seq("out", 12, [3] * 12)], subprocess=True,
             max_children=cap, max_seconds=20),
        Case(f"{cls}/batch-jobs-10000", cls, ["batch", "root", "--out", "bout", "--jobs", "10000", "--steps",
                                              "calibrate,align", "--chunk-frames", "1"], batch_root, "ok", ["root"],
             ["bout"], checks=[check_seq("bout/a/aligned", 4, [4] * 4), check_seq("bout/b/aligned", 4, [4] * 4),
                     check_files("bout/batch_report.json")],
             subprocess=True, max_children=cap, max_seconds=30, timeout_s=40,
             note="batch may fail a sequence (exit 1) only for a sequence error; none here"),
    ]


def gen_bombs() -> list[Case]:
    """Small files that would take gigabytes: measured in a subprocess (rule 4)."""
    cls = "bomb"
    cases = [
        Case(f"{cls}/npz-bz2-member-1.2GB", cls, INFO, lambda: seq_with(1, _bz2_bomb_npz()), "refuse", SEQ_INPUTS, [],
             ["000001.npz"], subprocess=True, note="1 KB on disk, a 1.2 GB vertices array inflated"),
        Case(f"{cls}/npz-12-deflated-members-of-100MB", cls, INFO, lambda: seq_with(1, _many_members_npz()), "either",
             SEQ_INPUTS, [], ["000001.npz"], subprocess=True, timeout_s=30,
             note="1.2 MB on disk; each member within the limits, all of them at once 1.2 GB"),
        Case(f"{cls}/npz-deflated-npy-header-800MB", cls, INFO, lambda: seq_with(1, _header_bomb_npz()), "refuse",
             SEQ_INPUTS, [], ["000001.npz"], subprocess=True,
             note="a .npy v2 header declaring an 800 MB header (numpy reads it all before its own size check)"),
        Case(f"{cls}/npz-deflate-declares-3GB", cls, ALIGN, lambda: seq_with(1, _deflate_lie_npz()),
             "refuse", SEQ_INPUTS, [], ["000001.npz"], subprocess=True),
        Case(f"{cls}/pickle-bytearray-2GB", cls, import_args("agora"),
             lambda: {**format_files("agora"), format_members("agora")[0]: bytearray_bomb(2**31)}, "refuse",
             ["src", "model.npz"], [], [Path(format_members("agora")[0]).name], subprocess=True,
             note="a 30-byte pickle calling bytearray(2**31)"),
        Case(f"{cls}/pickle-list-of-range", cls, import_args("agora"),
             lambda: {**format_files("agora"), format_members("agora")[0]: list_range_bomb()}, "refuse",
             ["src", "model.npz"], [], [Path(format_members("agora")[0]).name], subprocess=True,
             note="a 40-byte pickle calling list(range(2**27)): 5 GB of ints"),
        Case(f"{cls}/pickle-shared-reference-expansion", cls, import_args("agora"),
             lambda: {**format_files("agora"), format_members("agora")[0]: pickle.dumps(
                 {"verts": shared_reference_bomb(), "joints": np.zeros((24, 2)), "allSmplJoints3d": np.zeros((24, 3))},
                 protocol=2)}, "refuse", ["src", "model.npz"], [], [Path(format_members("agora")[0]).name],
             subprocess=True, timeout_s=30, note="30 KB of shared lists that np.asarray expands to 1.2 GB"),
        Case(f"{cls}/pickle-array-huge-shape", cls, import_args("4dhumans"),
             lambda: {**format_files("4dhumans"), format_members("4dhumans")[0]: huge_array_pickle()}, "refuse", ["src", "model.npz"], [],
             [Path(format_members("4dhumans")[0]).name], subprocess=True),
        Case(f"{cls}/wham-joblib-zlib-1GB", cls, import_args("wham"),
             lambda: {**format_files("wham"), format_members("wham")[0]: _wham_zlib_bomb()}, "refuse",
             ["src", "model.npz"], [], [Path(format_members("wham")[0]).name], subprocess=True,
             note="WHAM's joblib.dump zlib-compressed: 1 MB inflating to 1 GB of zeros (sound checksum, no valid "
                  "opcode): unpickled as it inflates, refused at once"),
        Case(f"{cls}/gvhmr-data-pkl-deflated-1GB", cls, import_args("gvhmr"),
             lambda: {**format_files("gvhmr"), format_members("gvhmr")[0]: _gvhmr_big_pickle(1 << 30)}, "refuse",
             ["src", "model.npz"], [], [Path(format_members("gvhmr")[0]).name], subprocess=True,
             note="a 1 MB torch archive whose data.pkl record inflates to 1 GB of zeros (sound CRC, no valid opcode)"),
        Case(f"{cls}/pickle-subarray-dtype", cls, import_args("spec"),
             lambda: {**format_files("spec"), [m for m in format_members("spec") if "spec_results" in m][0]:
                      subarray_dtype_pickle()}, "refuse", ["src", "model.npz"], [], [], subprocess=True,
             note="numpy.dtype(('f8', (1e6, 1e6))) scalar: 8 TB per element"),
    ]
    return cases


# The stored bz2 stream of a 1.2 GB npy (see _bz2_zeros_stream); verified against a fresh build by
# run_fuzz.py --check-bomb (slow: 5 s).
_BOMB_SHAPE = (1, 100_000_000, 3)
_BOMB_B64 = (
    "QlpoOTFBWSZTWQ1jGOsFfkFfoOQQQOxsFAEDQiCvRd0KCAAACCAAlIZEpoBozUepoMTD1HpBFVMIYIDAAIAh/KIAqqJAAoAqqJD7"
    "gBQBJJIIsp6vzEe4RVCpFr0odDJI0S8S7GEuAw4gLbP9bc18c3Xo8NBlugwatdPc5hZ8qWFjqASAASSUT+YoKyTKayHBPFvgK/HI"
    "ABgAAAEEAAYQCajIVAS1IVAS5igrJMprIcE8W+Ar8cgAGAAAAQQABhAJqMhUBLUhUBLmKCskymshwTxb4CvxyAAYAAABBAAGEAmo"
    "yFQEtSFQEuYoKyTKayHBPFvgK/HIABgAAAEEAAYQCajIVAS1IVAS5igrJMprIcE8W+Ar8cgAGAAAAQQABhAJqMhUBLUhUBLmKCsk"
    "ymshwTxb4CvxyAAYAAABBAAGEAmoyFQEtSFQEuYoKyTKayHBPFvgK/HIABgAAAEEAAYQCajIVAS1IVAS5igrJMprIcE8W+Ar8cgA"
    "GAAAAQQABhAJqMhUBLUhUBLmKCskymshwTxb4CvxyAAYAAABBAAGEAmoyFQEtSFQEuYoKyTKayHBPFvgK/HIABgAAAEEAAYQCajI"
    "VAS1IVAS5igrJMprIcE8W+Ar8cgAGAAAAQQABhAJqMhUBLUhUBLmKCskymshwTxb4CvxyAAYAAABBAAGEAmoyFQEtSFQEuYoKyTK"
    "ayHBPFvgK/HIABgAAAEEAAYQCajIVAS1IVAS5igrJMprIcE8W+Ar8cgAGAAAAQQABhAJqMhUBLUhUBLmKCskymshwTxb4CvxyAAY"
    "AAABBAAGEAmoyFQEtSFQEuYoKyTKayHBPFvgK/HIABgAAAEEAAYQCajIVAS1IVAS5igrJMprIcE8W+Ar8cgAGAAAAQQABhAJqMhU"
    "BLUhUBLmKCskymshwTxb4CvxyAAYAAABBAAGEAmoyFQEtSFQEuYoKyTKayHBPFvgK/HIABgAAAEEAAYQCajIVAS1IVAS5igrJMpr"
    "IcE8W+Ar8cgAGAAAAQQABhAJqMhUBLUhUBLmKCskymshwTxb4CvxyAAYAAABBAAGEAmoyFQEtSFQEuYoKyTKayHBPFvgK/HIABgA"
    "AAEEAAYQCajIVAS1IVAS5igrJMprIcE8W+Ar8cgAGAAAAQQABhAJqMhUBLUhUBLmKCskymshwTxb4CvxyAAYAAABBAAGEAmoyFQE"
    "tSFQEuYoKyTKayHBPFvgK/HIABgAAAEEAAYQCajIVAS1IVAS5igrJMprNGBsnaAGV5hAGAAAIAABBAAGGYE1TTKCSm1SCSni7kin"
    "ChIaGgksQA=="
)
_BOMB_CRC = 2482861798


@functools.lru_cache(maxsize=None)
def _bz2_bomb_npz() -> bytes:
    members = frame_members()
    entries = [stored(k, v) for k, v in members.items() if k != "vertices.npy"]
    header = npy_header("<f4", _BOMB_SHAPE)
    n = int(np.prod(_BOMB_SHAPE)) * 4
    data, crc = base64.b64decode(_BOMB_B64), _BOMB_CRC  # == _bz2_zeros_stream(header, n)
    entries.insert(0, ("vertices.npy", zipfile.ZIP_BZIP2, crc, data, len(header) + n))
    return zip_raw(entries)



@functools.lru_cache(maxsize=None)
def _many_members_npz(n: int = 12, floats: int = 25_000_000) -> bytes:
    entries = [stored(k, v) for k, v in frame_members().items()]
    header = npy_header("<f4", (floats,))
    data, crc, _ = _repeated_zeros(header, 4 * floats)
    for i in range(n):
        entries.append((f"extra_{i:02d}.npy", zipfile.ZIP_DEFLATED, crc, data, len(header) + 4 * floats))
    return zip_raw(entries)


@functools.lru_cache(maxsize=None)
def _header_bomb_npz(header_bytes: int = 800_000_000) -> bytes:
    entries = [stored(k, v) for k, v in frame_members().items() if k != "vertices.npy"]
    head = b"\x93NUMPY\x02\x00" + struct.pack("<I", header_bytes) + b"{'descr': '<f4', 'fortran_order': False, "
    data, crc, _ = _repeated_zeros(head, header_bytes - 42, b" ")
    entries.insert(0, ("vertices.npy", zipfile.ZIP_DEFLATED, crc, data, len(head) + header_bytes - 42))
    return zip_raw(entries)


@functools.lru_cache(maxsize=None)
def _deflate_lie_npz() -> bytes:
    members = frame_members(vertices=npy_header("<f4", (1, 250_000_000, 3)) + bytes(1 << 20))
    return zip_raw([deflated(k, v, declared=3_000_000_000 if k == "vertices.npy" else None)
                    for k, v in members.items()])


# ---- slow cases: measured processes that ``make fuzz`` runs (run_fuzz.py), not ``make test`` ----------
def _zip_with(data: bytes, name: str, content: tuple[bytes, int], size: int) -> bytes:
    """The zip ``data`` with member ``name`` replaced by a raw deflate stream (content, crc) of ``size`` bytes."""
    members = _members_of(data)
    packed, crc = content
    return zip_raw([(n, zipfile.ZIP_DEFLATED, crc, packed, size) if n == name else stored(n, b)
                    for n, b in members.items()])


@functools.lru_cache(maxsize=None)
def _gvhmr_big_storage(nbytes: int) -> bytes:
    """hmr4d_results.pt whose net_outputs hold a float64 tensor of ``nbytes`` zeros in a deflated storage
    record (~nbytes / 1000 on disk): within limits.max_array_mb, read whole by the loader."""
    numel = nbytes // 8
    big = T.Tensor(T.Storage(np.zeros(1, np.float64), declared=numel), 0, (numel,), (1,))
    data = _gvhmr_bytes(lambda r: _set(r, net_outputs=_set(r["net_outputs"], extra=big)))
    name = next(n for n, b in _members_of(data).items() if "/data/" in n and len(b) == 8)
    return _zip_with(data, name, _repeated_zeros(b"", numel * 8)[:2], numel * 8)


@functools.lru_cache(maxsize=None)
def _repeated_zeros(prefix: bytes, n_zeros: int, fill: bytes = b"\0") -> tuple[bytes, int, int]:
    """Raw deflate of ``prefix`` + ``n_zeros`` zero (or ``fill``) bytes, built fast (a 16 MiB block
    compressed once after a full flush, so it stands alone, then repeated: 1 GB in 1 MB and well under a
    second), and the CRC-32 and Adler-32 of the whole (a zip member's and a zlib stream's checksums)."""
    size = 1 << 24
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    head = comp.compress(prefix) + comp.flush(zlib.Z_FULL_FLUSH)
    full, rest = divmod(n_zeros, size)
    zeros = fill * size
    block = comp.compress(zeros) + comp.flush(zlib.Z_FULL_FLUSH)
    tail = comp.compress(fill * rest) + comp.flush(zlib.Z_FINISH)
    crc, adler = zlib.crc32(prefix), zlib.adler32(prefix)
    for _ in range(full):
        crc, adler = zlib.crc32(zeros, crc), zlib.adler32(zeros, adler)
    crc, adler = zlib.crc32(fill * rest, crc), zlib.adler32(fill * rest, adler)
    return head + block * full + tail, crc, adler


@functools.lru_cache(maxsize=None)
def _gvhmr_big_pickle(nbytes: int) -> bytes:
    """hmr4d_results.pt whose data.pkl record inflates to ``nbytes`` (a protocol-2 header, then zeros)."""
    packed, crc, _ = _repeated_zeros(b"\x80\x02", nbytes - 2)
    return _zip_with(_gvhmr_bytes(), "hmr4d_results/data.pkl", (packed, crc), nbytes)


@functools.lru_cache(maxsize=None)
def _wham_zlib_bomb(nbytes: int = 1 << 30) -> bytes:
    """A zlib stream (joblib's zlib compression: 'x' first) of a protocol-2 header then zeros, ``nbytes`` in all."""
    packed, _, adler = _repeated_zeros(b"\x80\x02", nbytes - 2)
    return b"\x78\xda" + packed + adler.to_bytes(4, "big")


def gen_slow() -> list[Case]:
    """Hostile inputs whose failure mode is memory or time: real processes, peak RSS measured. Too slow
    (or too many processes) for the seeded corpus of ``make test``; run by ``make fuzz`` first."""
    cls = "slow"
    inputs = ["src", "model.npz"]
    tram, pm, gv = format_members("tram")[0], format_members("pymafx")[0], format_members("gvhmr")[0]
    cases = [
        Case(f"{cls}/tram/frame-index-1e12", cls, import_args("tram"), _tram_edit(tram, lambda d: _rows_of(
            d, "frame", lambda v: v + 10**12)), "either", inputs, ["out"], [Path(tram).name, "tram"],
             checks=[check_seq("out"), check_meta("out")], subprocess=True, timeout_s=30, max_seconds=20,
             note="frames 0 .. max('frame'): an image index of 1e12 must not make 1e12 frames"),
        Case(f"{cls}/pymafx/frame-ids-1e12", cls, import_args("pymafx"), _pickle_edit(
            "pymafx", pm, lambda o: _set(o, frame_ids=[10**12 + i for i in o["frame_ids"]]), joblib=True, compress=0),
             "either", inputs, ["out"], [Path(pm).name], checks=[check_seq("out"), check_meta("out")],
             subprocess=True, timeout_s=30, max_seconds=20,
             note="frames 0 .. max(frame_ids): a frame index of 1e12 must not make 1e12 frames"),
        Case(f"{cls}/gvhmr/storage-deflated-256MB", cls, import_args("gvhmr"), _replace(
            "gvhmr", gv, _gvhmr_big_storage(256 << 20)), "either", inputs, ["out"], [Path(gv).name],
             checks=[check_seq("out"), check_meta("out")], subprocess=True, timeout_s=40,
             note="a 0.3 MB file, one 256 MB tensor (within limits.max_array_mb): peak RSS ~2x the storage"),
    ]
    return cases


SLOW_GENERATORS: dict[str, Callable[[], list[Case]]] = {"slow": gen_slow}


def slow_cases() -> list[Case]:
    """The measured slow cases (``make fuzz`` only; not in :func:`all_cases`)."""
    return [c for gen in SLOW_GENERATORS.values() for c in gen()]


GENERATORS: dict[str, Callable[[], list[Case]]] = {
    "npz-frame": gen_npz_frames,
    "importer": gen_importers,
    "pickle-gadget": gen_pickles,
    "yaml": gen_yaml,
    "paths": gen_paths,
    "obj": gen_obj,
    "degenerate": gen_degenerate,
    "options": gen_options,
    "process": gen_process,
    "bomb": gen_bombs,
}


@functools.lru_cache(maxsize=None)
def _all_cases() -> tuple[Case, ...]:
    cases = [c for gen in GENERATORS.values() for c in gen()]
    return tuple(cases)


def all_cases() -> list[Case]:
    """The fixed corpus, every class (deterministic order)."""
    return list(_all_cases())
