"""The restricted unpickler: numpy arrays, numpy scalars and builtin containers in; everything else out,
with a one-line InputError and without running any code."""

from __future__ import annotations

import io
import os
import pickle
import re
import subprocess
import tarfile
import zipfile
import zlib
from collections import OrderedDict
from pathlib import Path

import _fixtures_torch as T
import _format_fixtures as F
import numpy as np
import pytest

from rotavat_cli import unpickle

from rotavat_cli.settings import limits
from rotavat_cli.errors import InputError


def _sample() -> dict:
    rng = np.random.default_rng(0)
    obj = np.empty(2, dtype=object)
    obj[0], obj[1] = {"inner": np.arange(3)}, [1, "two"]
    return {
        "f32": rng.standard_normal((3, 4)).astype(np.float32),
        "fortran": np.asfortranarray(rng.standard_normal((2, 5))),
        "ints": np.arange(6, dtype=np.int16).reshape(2, 3),
        "big_endian": np.arange(4, dtype=">f8"),
        "empty": np.zeros((0, 3)),
        "strings": np.array(["a", "bcd"]),
        "record": np.zeros(2, dtype=[("x", "<f4"), ("n", "<i8")]),
        "object": obj,
        "scalars": [np.float32(1.5), np.int64(-3), np.bool_(True), 2.5, 7, None, True],
        "containers": ((1, 2), {3, 4}, frozenset({5}), b"raw", bytearray(b"ba"), "text", 1 + 2j),
        "ordered": OrderedDict(a=1, b=2),
    }


def _assert_same(got: dict, want: dict) -> None:
    for key, value in want.items():
        if isinstance(value, np.ndarray) and value.dtype != object:
            # numpy itself may hand big-endian data back in native order: compare kind and size
            assert got[key].dtype.str[1:] == value.dtype.str[1:] and got[key].shape == value.shape, key
            np.testing.assert_array_equal(got[key], value)
    assert got["object"][0]["inner"].tolist() == [0, 1, 2] and got["object"][1] == [1, "two"]
    assert got["scalars"] == want["scalars"] and type(got["scalars"][0]) is np.float32
    assert got["containers"] == want["containers"]
    assert dict(got["ordered"]) == {"a": 1, "b": 2}


@pytest.mark.parametrize("protocol", range(pickle.HIGHEST_PROTOCOL + 1))
def test_round_trip_of_allowed_content(protocol):
    data = _sample()
    _assert_same(unpickle.loads(pickle.dumps(data, protocol=protocol), "x.pkl"), data)


def test_python2_style_pickle_with_latin1_strings():
    """Protocol-2 pickles of numpy arrays store the raw bytes through _codecs.encode(str, 'latin1')."""
    arr = np.arange(300, dtype=np.float64)
    assert np.array_equal(unpickle.loads(pickle.dumps(arr, protocol=2), "py2.pkl"), arr)
    hand_made = b"\x80\x02c__builtin__\nset\nq\x00]q\x01K\x01a\x85q\x02Rq\x03."  # Python 2 names
    assert unpickle.loads(hand_made, "py2.pkl") == {1}


@pytest.mark.parametrize("compress", [0, 3])
@pytest.mark.parametrize("protocol", [2, 3, 4, 5])
@pytest.mark.parametrize("align", [True, False])
def test_joblib_files(tmp_path, compress, protocol, align):
    data = _sample()
    path = tmp_path / "x.pkl"
    path.write_bytes(F.joblib_bytes(data, compress=compress, protocol=protocol, align=align))
    _assert_same(unpickle.load_file(path), data)


@pytest.mark.parametrize("codec", ["gzip", "bz2", "xz", "lzma"])
def test_joblib_compressors(tmp_path, codec):
    import bz2
    import gzip
    import lzma

    raw = F.joblib_bytes({"a": np.arange(5)}, compress=0)
    packed = {"gzip": gzip.compress, "bz2": bz2.compress, "xz": lzma.compress,
              "lzma": lambda b: lzma.compress(b, format=lzma.FORMAT_ALONE)}[codec](raw)
    (tmp_path / "x.pkl").write_bytes(packed)
    assert unpickle.load_file(tmp_path / "x.pkl")["a"].tolist() == [0, 1, 2, 3, 4]


def test_npz_with_object_members(tmp_path):
    results = {"verts": np.ones((2, 4, 3)), "ids": [1, 2]}
    np.savez(tmp_path / "r.npz", results=results, plain=np.arange(3))
    data = unpickle.load_npz(tmp_path / "r.npz")
    assert data["plain"].tolist() == [0, 1, 2]
    assert data["results"].shape == () and data["results"].item()["ids"] == [1, 2]
    np.save(tmp_path / "o.npy", np.array([np.zeros(2), np.ones(3)], dtype=object))
    assert [a.tolist() for a in unpickle.load_npy(tmp_path / "o.npy")] == [[0, 0], [1, 1, 1]]


# ---- hostile -----------------------------------------------------------------------------------
class _RunsCode:
    def __init__(self, func, args):
        self.func, self.args = func, args

    def __reduce__(self):
        return self.func, self.args


def _hostile_payloads(marker: Path):
    cmd = f"touch {marker}"
    yield "os.system", pickle.dumps(_RunsCode(os.system, (cmd,)))
    yield "builtins.eval", pickle.dumps(_RunsCode(eval, (f"__import__('os').system('{cmd}')",)))
    yield "builtins.exec", pickle.dumps([1, {"k": _RunsCode(exec, (f"open('{marker}', 'w')",))}], protocol=2)
    yield "subprocess.call", pickle.dumps((_RunsCode(subprocess.call, (["touch", str(marker)],)),), protocol=0)
    yield "builtins.getattr", pickle.dumps(_RunsCode(getattr, ("text", "upper")))
    yield "posix.system", b"cos\nsystem\n(V" + cmd.encode() + b"\ntR."  # protocol 0, GLOBAL + REDUCE
    yield "posix.system", b"(V" + cmd.encode() + b"\nios\nsystem\n."  # INST opcode
    inner = np.empty(1, dtype=object)
    inner[0] = _RunsCode(os.system, (cmd,))
    yield "os.system (inside an object array)", pickle.dumps({"a": inner})


@pytest.mark.parametrize("index", range(8))
def test_hostile_pickles_are_refused_without_running(tmp_path, index):
    marker = tmp_path / "pwned"
    what, payload = list(_hostile_payloads(marker))[index]
    with pytest.raises(InputError, match=r"^evil\.pkl: refused to unpickle global '[\w.]+' \(only numpy arrays"):
        unpickle.loads(payload, "evil.pkl")
    assert not marker.exists(), what


def test_refusal_message_names_file_and_global(tmp_path):
    path = tmp_path / "evil.pkl"
    path.write_bytes(F.evil_pickle(tmp_path / "pwned"))
    with pytest.raises(InputError) as info:
        unpickle.load_file(path)
    message = str(info.value)
    assert message.startswith(str(path)) and "'posix.system'" in message and "\n" not in message
    assert not (tmp_path / "pwned").exists()


def test_hostile_content_inside_containers(tmp_path):
    marker = tmp_path / "pwned"
    payload = F.joblib_bytes({"a": np.arange(3), "b": _RunsCode(os.system, (f"touch {marker}",))})
    (tmp_path / "j.pkl").write_bytes(payload)
    with pytest.raises(InputError, match="refused to unpickle global"):
        unpickle.load_file(tmp_path / "j.pkl")
    F.evil_npz(tmp_path / "e.npz", marker)
    with pytest.raises(InputError, match=r"e\.npz \['results'\]: refused"):
        unpickle.load_npz(tmp_path / "e.npz")
    obj = np.empty(1, dtype=object)
    obj[0] = _RunsCode(os.system, (f"touch {marker}",))
    (tmp_path / "o.pkl").write_bytes(F.joblib_bytes({"obj": obj}))  # joblib pickles object arrays inline
    with pytest.raises(InputError, match="refused"):
        unpickle.load_file(tmp_path / "o.pkl")
    assert not marker.exists()


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")
@pytest.mark.parametrize("make, needle", [
    (lambda: np.ma.masked_array([1.0, 2.0], mask=[False, True]), "numpy.ma"),
    (lambda: np.matrix([[1, 2]]), "numpy.matrix"),
    (lambda: np.datetime64("2020-01-01"), None),
])
def test_numpy_beyond_plain_arrays(make, needle):
    payload = make()
    data = pickle.dumps(payload)
    if needle is None:  # numpy scalars of any dtype are plain data
        assert unpickle.loads(data, "x") == payload
        return
    with pytest.raises(InputError, match="refused"):
        unpickle.loads(data, "x")


def test_array_reconstruction_rejects_subclasses_and_bad_arguments():
    with pytest.raises(InputError, match="subclass"):
        unpickle.loads(b"\x80\x02cnumpy.core.multiarray\n_reconstruct\ncnumpy\ndtype\nK\x00\x85C\x01b\x87R.", "x")
    with pytest.raises(InputError, match="malformed numpy scalar"):
        unpickle.loads(b"\x80\x02cnumpy.core.multiarray\nscalar\nK\x01K\x02\x86R.", "x")


def test_persistent_ids_are_refused():
    class _P(pickle.Pickler):
        def persistent_id(self, obj):
            return "external" if obj == "x" else None

    buf = io.BytesIO()
    _P(buf).dump(["x"])
    with pytest.raises(InputError, match="persistent id"):
        unpickle.loads(buf.getvalue(), "p.pkl")


# ---- broken -----------------------------------------------------------------------------------
@pytest.mark.parametrize("data, needle", [
    (b"", "empty file"),
    (pickle.dumps({"a": np.arange(100)})[:-30], "truncated|not a readable"),
    (b"\xff\xfe garbage", "invalid opcode|not a readable"),
    (zlib.compress(b"\x80\x04garbage")[:-4], "truncated|not a readable|corrupt"),
    (b"x\x9c not really zlib", "corrupt compressed"),
    (b'\x04"M\x18rest', "lz4"),
])
def test_broken_files_give_one_line_errors(tmp_path, data, needle):
    path = tmp_path / "b.pkl"
    path.write_bytes(data)
    with pytest.raises(InputError, match=needle) as info:
        unpickle.load_file(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_truncated_joblib_array_is_detected_before_allocating(tmp_path):
    data = F.joblib_bytes({"a": np.zeros(1000)}, compress=0)
    (tmp_path / "t.pkl").write_bytes(data[:-4000])
    with pytest.raises(InputError, match="truncated joblib array"):
        unpickle.load_file(tmp_path / "t.pkl")


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        unpickle.load_file(tmp_path / "nope.pkl")
    with pytest.raises(InputError, match="is a directory"):
        unpickle.load_file(tmp_path)
    with pytest.raises(InputError, match="file not found"):
        unpickle.load_npz(tmp_path / "nope.npz")


def test_broken_npz_and_npy(tmp_path):
    np.savez(tmp_path / "a.npz", x=np.arange(10))
    F.truncate(tmp_path / "a.npz", 0.5)
    with pytest.raises(InputError, match=r"not a (readable|valid) \.npz"):
        unpickle.load_npz(tmp_path / "a.npz")
    with pytest.raises(InputError, match="bad magic"):
        unpickle.load_npy_bytes(b"not an npy file", "x.npy")
    header = b"\x93NUMPY\x01\x00" + (60).to_bytes(2, "little") + b"{'descr': '<f8', 'fortran_order': False, 'shape': (-1,), }".ljust(60)
    with pytest.raises(InputError, match="malformed .npy header"):
        unpickle.load_npy_bytes(header, "x.npy")
    np.save(tmp_path / "t.npy", np.arange(100.0))
    F.truncate(tmp_path / "t.npy", 0.5)
    with pytest.raises(InputError, match="corrupt or truncated"):
        unpickle.load_npy(tmp_path / "t.npy")


def test_decompression_bomb_is_capped(tmp_path):
    small = limits.Limits(max_file_bytes=1 << 16, max_array_bytes=1 << 16, max_frame_bytes=1 << 16, max_pickle_items=10**6,
                          max_grid_cells=10**6)
    (tmp_path / "bomb.pkl").write_bytes(zlib.compress(b"\x80\x04" + b"N" * (1 << 20)))
    with limits.applied(small), pytest.raises(InputError, match=r"decompresses to more than 64\.0 KiB \(limit: limits\.max_file_mb\)"):
        unpickle.load_file(tmp_path / "bomb.pkl")


@pytest.mark.parametrize("protocol", [0, 2, 4, 5])
def test_defaultdict_with_a_builtin_factory_is_read(tmp_path, protocol):
    """WHAM saves a collections.defaultdict of per-track dicts with joblib (wham_output.pkl)."""
    from collections import defaultdict

    tracks = defaultdict(dict)
    tracks[0]["pose"] = np.arange(6.0).reshape(2, 3)
    tracks[3]["frame_ids"] = np.array([4, 5])
    path = tmp_path / "wham_output.pkl"
    path.write_bytes(F.joblib_bytes(tracks, protocol=protocol) if protocol >= 2 else pickle.dumps(tracks, protocol))
    loaded = unpickle.load_file(path)
    assert isinstance(loaded, defaultdict) and loaded.default_factory is dict
    assert loaded[0]["pose"].tolist() == [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]] and loaded[3]["frame_ids"].tolist() == [4, 5]


def test_defaultdict_with_another_factory_is_refused():
    """Only builtin types may be a factory: an allowed global that is not one (numpy.dtype) is refused too."""
    from collections import defaultdict

    with pytest.raises(InputError, match="d.pkl: defaultdict with factory 'dtype' is not allowed"):
        unpickle.loads(pickle.dumps(defaultdict(np.dtype)), "d.pkl")


# ---- torch files (rotavat_cli.unpickle.torch_files): read without torch, written by hand (tests/_fixtures_torch.py) ----
REALFILES = Path(__file__).resolve().parents[2] / "shared" / "realfiles"


def _torch_sample() -> tuple[dict, dict]:
    """(fixture object, the arrays a reader must give back): dtypes, strided and shared views, 0-d, empty, nesting."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal((3, 4)).astype(np.float32)
    shared = T.tensor(np.arange(12, dtype=np.float64))
    obj = {"f32": T.tensor(a), "transposed": T.transposed(a), "i64": T.tensor(np.arange(-2, 3)),
           "i32": T.tensor(np.arange(6, dtype=np.int32).reshape(2, 3)), "i16": T.tensor(np.array([-7, 8], np.int16)),
           "i8": T.tensor(np.array([-1, 2], np.int8)), "u8": T.tensor(np.array([1, 255], np.uint8)),
           "f16": T.tensor(np.array([1.5, -2.0], np.float16)), "bool": T.tensor(np.array([True, False])),
           "zero_d": T.tensor(np.float32(2.5)), "empty": T.tensor(np.zeros((0, 3), np.float32)),
           "shared": shared, "shared_view": T.Tensor(shared.storage, 2, (2, 3), (1, 2)),
           "nested": [{"x": T.tensor(np.ones(2, np.int32))}, (1, "s", None)], "python": 3.5}
    want = {"f32": a, "transposed": a, "i64": np.arange(-2, 3), "i32": np.arange(6, dtype=np.int32).reshape(2, 3),
            "i16": np.array([-7, 8], np.int16), "i8": np.array([-1, 2], np.int8), "u8": np.array([1, 255], np.uint8),
            "f16": np.array([1.5, -2.0], np.float16), "bool": np.array([True, False]), "zero_d": np.array(2.5, np.float32),
            "empty": np.zeros((0, 3), np.float32), "shared": np.arange(12.0),
            "shared_view": np.array([[2.0, 4.0, 6.0], [3.0, 5.0, 7.0]])}
    return obj, want


def _assert_torch_sample(got: dict, want: dict) -> None:
    for key, value in want.items():
        assert got[key].dtype == value.dtype and got[key].shape == value.shape, key
        np.testing.assert_array_equal(got[key], value, err_msg=key)
    assert got["nested"][0]["x"].tolist() == [1, 1] and got["nested"][1] == (1, "s", None) and got["python"] == 3.5
    assert got["shared"].base is None or got["shared"].base is not got["shared_view"].base  # independent copies


@pytest.mark.parametrize("form", ["zip", "zip_protocol3", "legacy", "big_endian"])
def test_torch_save_files_read_without_torch(tmp_path, form):
    obj, want = _torch_sample()
    data = {"zip": lambda: T.torch_zip_bytes(obj), "zip_protocol3": lambda: T.torch_zip_bytes(obj, protocol=3),
            "legacy": lambda: T.legacy_bytes(obj), "big_endian": lambda: T.torch_zip_bytes(obj, byteorder="big")}[form]()
    path = tmp_path / "x.pt"
    path.write_bytes(data)
    _assert_torch_sample(unpickle.load_file(path), want)  # load_file opens torch files transparently
    _assert_torch_sample(unpickle.load_torch(path), want)


def test_np_save_of_torch_tensors_reads_each_storage_blob(tmp_path):
    """TRAM's hps_track_k.npy: np.save of a dict of tensors; each storage is torch.storage._load_from_bytes(b)."""
    rotmat = np.broadcast_to(np.eye(3, dtype=np.float32), (4, 24, 3, 3)).copy()
    path = T.np_save_tensors(tmp_path / "hps_track_0.npy", {"pred_rotmat": T.tensor(rotmat),
                                                            "frame": T.tensor(np.array([0, 1, 5, 6])),
                                                            "pred_trans": T.transposed(np.arange(6.0).reshape(2, 3))})
    got = unpickle.load_npy(path).item()
    assert got["pred_rotmat"].shape == (4, 24, 3, 3) and np.array_equal(got["pred_rotmat"][2, 7], np.eye(3))
    assert got["frame"].tolist() == [0, 1, 5, 6] and got["frame"].dtype == np.int64
    assert got["pred_trans"].tolist() == [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]]


@pytest.mark.skipif(not (REALFILES / "gvhmr").is_dir(), reason="shared real files absent")
def test_real_gvhmr_archive_matches_torch_load():
    """Values measured with torch 2.13's own torch.load (outside the project) on the same file."""
    data = unpickle.load_file(REALFILES / "gvhmr" / "tennis" / "hmr4d_results.pt")
    incam = data["smpl_params_incam"]
    assert {k: v.shape for k, v in incam.items()} == {"body_pose": (312, 63), "betas": (312, 10), "global_orient": (312, 3),
                                                      "transl": (312, 3)}
    np.testing.assert_allclose(incam["transl"][0], [-0.0539887, 0.41385126, 4.1407447], rtol=1e-6)  # stored with stride (1, 312)
    np.testing.assert_allclose(data["K_fullimg"][0], [[1085.2391, 0, 406], [0, 1085.2391, 360], [0, 0, 1]], rtol=1e-7)
    assert data["net_outputs"]["model_output"]["pred_context"].shape == (1, 312, 512)


# ---- hostile and broken torch files: one line, naming the file as a torch archive, nothing run ----
def _torch_file(tmp_path: Path, obj, **kw) -> Path:
    path = tmp_path / "hmr4d_results.pt"
    path.write_bytes(T.torch_zip_bytes(obj, name="hmr4d_results", **kw))
    return path


def _torch_error(path: Path) -> str:
    with pytest.raises(InputError) as info:
        unpickle.load_file(path)
    message = str(info.value)
    assert message.startswith(f"{path}: torch archive: ") and "\n" not in message and "pickle (" not in message
    return message


def test_torch_archive_naming_os_system_is_refused_without_running(tmp_path):
    marker = tmp_path / "pwned"
    path = _torch_file(tmp_path, {"a": T.tensor(np.ones(2)), "b": T.Call(T.Global("os", "system"), (f"touch {marker}",))})
    assert "refused to unpickle global 'os.system' (only tensors, numpy arrays" in _torch_error(path)
    assert not marker.exists()


def test_hostile_storage_blob_inside_a_plain_pickle_is_refused(tmp_path):
    """A _load_from_bytes blob is itself a pickle: its globals go through the same allow-list."""
    marker = tmp_path / "pwned"

    class EvilStorage(T.Storage):
        def __reduce__(self):
            inner = T.legacy_bytes(T.Call(T.Global("os", "system"), (f"touch {marker}",)))
            return T._load_from_bytes, (inner,)

    path = T.np_save_tensors(tmp_path / "hps_track_0.npy", {"x": T.Tensor(EvilStorage(np.ones(2)), 0, (2,), (1,))})
    with pytest.raises(InputError, match=r"hps_track_0\.npy: refused to unpickle global 'os\.system'"):
        unpickle.load_npy(path)
    assert not marker.exists()


@pytest.mark.parametrize("make, needle", [
    (lambda t: _torch_file(t, {"a": T.tensor(np.ones(4))}, drop=("data/0",)), r"record 'hmr4d_results/data/0' is missing"),
    (lambda t: _torch_file(t, {"a": T.tensor(np.ones(4))}, resize={"0": 8}),
     r"record 'hmr4d_results/data/0' holds 8 bytes, its storage declares 32"),
    (lambda t: _torch_file(t, {"a": T.Tensor(T.Storage(np.ones(2), declared=2_000_000_000), 0, (2,), (1,))}),
     r"storage declares 14\.9 GiB \(torch\.float64 x 2,000,000,000; limit 1\.0 GiB: limits\.max_array_mb\)"),
    (lambda t: _torch_file(t, {"a": T.Tensor(T.Storage(np.ones(12)), 10, (5,), (1,))}),
     r"tensor of size \[5\] \(offset 10, stride \[1\]\) reaches element 14 of storage '0', which holds 12"),
    (lambda t: _torch_file(t, {"a": T.Tensor(T.Storage(np.ones(1)), 0, (10**6, 10**6), (0, 0))}),
     r"array declares 7\.3 TiB"),
    (lambda t: _torch_file(t, {"a": 1}, drop=("data.pkl",)), r"no '<name>/data\.pkl' record"),
])
def test_broken_torch_archives_give_one_line_before_allocating(tmp_path, make, needle):
    assert re.search(needle, _torch_error(make(tmp_path)))


def test_truncated_or_garbled_torch_archive_is_still_named_a_torch_archive(tmp_path):
    path = _torch_file(tmp_path, {"a": T.tensor(np.arange(1000.0))})
    F.truncate(path, 0.5)
    assert "corrupt" in _torch_error(path)
    legacy = tmp_path / "legacy.pt"
    legacy.write_bytes(T.legacy_bytes({"a": T.tensor(np.arange(1000.0))})[:-100])
    assert "truncated torch stream (storage" in _torch_error(legacy)


def test_other_torch_layouts_are_refused_by_name(tmp_path):
    script = tmp_path / "model.pt"  # torch.jit.save: code and constants.pkl, no data.pkl of saved data
    with zipfile.ZipFile(script, "w") as archive:
        archive.writestr("model/data.pkl", b"")
        archive.writestr("model/constants.pkl", b"")
    tar = io.BytesIO()
    with tarfile.open(fileobj=tar, mode="w") as archive:
        info = tarfile.TarInfo("storages")
        archive.addfile(info, io.BytesIO(b""))
    (tmp_path / "old.pt").write_bytes(tar.getvalue())
    with pytest.raises(InputError, match=r"old\.pt: torch archive: the pre-1\.0 tar layout"):
        unpickle.load_torch(tmp_path / "old.pt")
    with pytest.raises(InputError, match=r"model\.pt: torch archive: a TorchScript model archive \(torch\.jit\.save\)"):
        unpickle.load_file(script)


def test_torch_persistent_ids_other_than_storages_are_refused(tmp_path):
    class ModulePid(T.Storage):
        pass

    buf = io.BytesIO()

    class Pickler(pickle.Pickler):
        def persistent_id(self, value):
            return ("module", "Linear", "nn.py", "source") if isinstance(value, ModulePid) else None

    Pickler(buf, protocol=2).dump({"m": ModulePid(np.ones(1))})
    path = tmp_path / "m.pt"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("m/data.pkl", buf.getvalue())
    assert "refused persistent id 'module' (only storages are allowed)" in _torch_error(path)


def test_torch_globals_map_only_to_inert_builders():
    assert ("torch._utils", "_rebuild_tensor_v2") in unpickle.TORCH_GLOBALS
    assert not any(name in ("load", "jit", "_load", "eval") or module == "torch.serialization"
                   for module, name in unpickle.TORCH_GLOBALS)
    with pytest.raises(InputError, match=r"refused to unpickle global 'torch\.load'"):
        unpickle.loads(b"\x80\x02ctorch\nload\n.", "x.pkl")


def test_torch_byteorder_record_is_read_bounded(tmp_path):
    """The byteorder record says 'little' or 'big': a large one is refused from its declared size, unread."""
    import _fixtures_torch as T

    path = tmp_path / "t.pt"
    path.write_bytes(T.torch_zip_bytes({"x": T.tensor(np.arange(3.0))}, name="t", byteorder="little" * 100))
    with pytest.raises(InputError, match=r"t.pt: torch archive: record 't/byteorder' holds 600 bytes \(at most 16"):
        unpickle.load_file(path)


def test_pickled_text_arrays_with_impossible_code_points_are_refused():
    """numpy rebuilds a unicode array from raw bytes: a code point beyond U+10FFFF is refused when read."""
    good = np.array(["img_001.jpg", "img_002.jpg"])
    blob = pickle.dumps({"img_path": good}, protocol=2)
    raw = good.tobytes()
    bad = raw[:4] + (0x110000).to_bytes(4, "little") + raw[8:]
    assert raw in blob
    with pytest.raises(InputError, match=r"x.pkl: an array holds invalid text"):
        unpickle.loads(blob.replace(raw, bad), "x.pkl")
    assert unpickle.loads(blob, "x.pkl")["img_path"].tolist() == good.tolist()
