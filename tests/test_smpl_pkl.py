"""The official SMPL-family ``.pkl`` model files, read by the restricted unpickler without chumpy or scipy
(``rotavat_cli/unpickle/model_files.py``, ``formats/smpl.py``).

The files are written here in the layout of the released ones, without chumpy: Python 2's
``pickle.dump(model, f, -1)`` (smpl_webuser ``serialization.save_model``): protocol 2, every ``str`` a
``BINSTRING`` read as latin-1, Python 2 module names (``copy_reg``, ``__builtin__``,
``numpy.core.multiarray``), each ``chumpy.ch.Ch`` an empty instance then ``BUILD`` with its ``__dict__``
less the weak caches (value under ``x``), each ``scipy.sparse.csc.csc_matrix`` the same with old scipy's
``__dict__`` (``_shape``, ``maxprint``, ``format``, ``data``, ``indices``, ``indptr``). The arrays come
from the synthetic npz models of ``tests/_body_models.py``, so the .pkl must load to the same model.
"""

from __future__ import annotations

import codecs
import io
import json
import os
import pickle
import re
import subprocess
import sys
from pathlib import Path

import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke

from rotavat_cli import unpickle

from rotavat_cli.settings import limits
from rotavat_cli.errors import InputError
from rotavat_cli.formats.smpl import BodyModel, lbs, load_body_model
from rotavat_cli.sequence import open_sequence
from rotavat_cli.unpickle.model_files import loads_model

ROOT = Path(__file__).resolve().parents[1]
TOL_M = 1e-4  # float32 storage of metre-scale coordinates (~1e-6) plus LBS round-off (as tests/test_formats.py)


# ---- a Python 2 pickler, and the chumpy / scipy objects as they pickle ---------------------------------
class Ch:
    """Pickles as ``chumpy.ch.Ch``: its ``__getstate__`` is the ``__dict__`` without ``_parents`` and
    ``_cache`` (mattloper/chumpy ch.py), the value as float64 under ``x``."""

    def __init__(self, x):
        self.x = np.asarray(x, dtype=np.float64)

    def __getstate__(self):
        return {"_dirty_vars": {"x"}, "_itr": None, "_make_dense": False, "_make_sparse": False,
                "_depends_on_deps": {}, "x": self.x}


class ChOp:
    """Pickles as a chumpy operation (``chumpy.ch_ops.add`` by default): not a plain ``Ch``."""

    def __init__(self, a, b, name=("chumpy.ch_ops", "add")):
        self.a, self.b, self.name = a, b, name

    def __getstate__(self):
        return {"a": self.a, "b": self.b, "_dirty_vars": set(), "_itr": None}


def compressed(dense: np.ndarray, fmt: str = "csc") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(data, indices, indptr) of ``dense`` in scipy's csc (or csr) layout, sorted indices, int32."""
    major_first = dense.T if fmt == "csc" else dense
    major, minor = np.nonzero(major_first)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(major, minlength=major_first.shape[0]))])
    return major_first[major, minor], minor.astype(np.int32), indptr.astype(np.int32)


class Sparse:
    """Pickles as a scipy compressed matrix with old scipy's ``__dict__`` (the released files:
    ``scipy.sparse.csc.csc_matrix``), or any ``state`` given."""

    def __init__(self, dense=None, fmt="csc", module=None, state=None):
        self.name = (module or f"scipy.sparse.{fmt}", f"{fmt}_matrix")
        if state is None:
            data, indices, indptr = compressed(np.asarray(dense, dtype=np.float64), fmt)
            state = {"_shape": tuple(int(n) for n in np.shape(dense)), "maxprint": 50, "format": fmt, "data": data,
                     "indices": indices, "indptr": indptr}
        self.state = state

    def __getstate__(self):
        return self.state


_PY2_MODULES = {"builtins": "__builtin__", "copyreg": "copy_reg", "numpy._core.multiarray": "numpy.core.multiarray",
                "numpy._core.numeric": "numpy.core.numeric"}


class Py2Pickler(pickle._Pickler):  # noqa: SLF001 -- the pure-Python pickler lets each opcode be chosen
    """Writes what Python 2's ``pickle.dump(obj, f, protocol)`` wrote: every ``str`` (and ``bytes``, which
    Python 2 did not tell apart) as a byte string, Python 2 module names, the stand-ins above under
    chumpy's and scipy's names."""

    dispatch = pickle._Pickler.dispatch.copy()  # noqa: SLF001

    def save_string(self, obj):
        data = obj.encode("latin1") if isinstance(obj, str) else bytes(obj)
        if not self.bin:
            self.write(pickle.STRING + b"'" + codecs.escape_encode(data)[0] + b"'\n")  # escapes quotes too
        elif len(data) < 256:
            self.write(pickle.SHORT_BINSTRING + bytes([len(data)]) + data)
        else:
            self.write(pickle.BINSTRING + len(data).to_bytes(4, "little") + data)
        self.memoize(obj)

    dispatch[str] = save_string
    dispatch[bytes] = save_string

    def save_global(self, obj, name=None):
        if obj in (Ch, ChOp, Sparse):
            raise AssertionError("stand-ins are named by their instance (save_stand_in)")
        module = _PY2_MODULES.get(obj.__module__, obj.__module__)
        self.write(pickle.GLOBAL + f"{module}\n{name or obj.__qualname__}\n".encode())
        self.memoize(obj)

    dispatch[type] = save_global
    dispatch[type(len)] = save_global
    dispatch[type(save_global)] = save_global

    def save_stand_in(self, obj):
        """Ch, ChOp, Sparse: an empty instance of chumpy's / scipy's class, then BUILD with the state."""
        module, name = ("chumpy.ch", "Ch") if isinstance(obj, Ch) else obj.name
        if self.proto >= 2:
            self.write(pickle.GLOBAL + f"{module}\n{name}\n".encode() + pickle.EMPTY_TUPLE + pickle.NEWOBJ)
        else:  # copy_reg._reconstructor(cls, object, None)
            self.write(pickle.GLOBAL + b"copy_reg\n_reconstructor\n" + pickle.MARK + pickle.GLOBAL
                       + f"{module}\n{name}\n".encode() + pickle.GLOBAL + b"__builtin__\nobject\n" + pickle.NONE
                       + pickle.TUPLE + pickle.REDUCE)
        self.memoize(obj)
        self.save(obj.__getstate__())
        self.write(pickle.BUILD)
        return None

    def save(self, obj, save_persistent_id=True):
        if isinstance(obj, (Ch, ChOp, Sparse)):
            memoed = self.memo.get(id(obj))
            if memoed is not None:
                self.write(self.get(memoed[0]))
                return None
            return self.save_stand_in(obj)
        return super().save(obj, save_persistent_id)


def py2_pickle(obj, protocol: int = 2) -> bytes:
    buf = io.BytesIO()
    Py2Pickler(buf, protocol=protocol).dump(obj)
    return buf.getvalue()


# ---- official layouts ------------------------------------------------------------------------------------
def _npz_arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def official_smpl(arrays: dict) -> dict:
    """The dict of ``basicModel_*_lbs_10_207_0_v1.0.0.pkl`` (smpl_webuser save_model): chumpy arrays,
    csc regressors, int64 kintree_table, the training leftovers."""
    regressor = arrays["J_regressor"].astype(np.float64)
    return {"v_template": Ch(arrays["v_template"]), "shapedirs": Ch(arrays["shapedirs"]),
            "posedirs": arrays["posedirs"].astype(np.float64), "weights": Ch(arrays["weights"]),
            "J_regressor": Sparse(regressor), "J_regressor_prior": Sparse(regressor),
            "weights_prior": Ch(arrays["weights"]), "J": Ch(regressor @ arrays["v_template"].astype(np.float64)),
            "kintree_table": arrays["kintree_table"].astype(np.int64), "f": arrays["f"],
            "vert_sym_idxs": np.arange(len(arrays["v_template"]), dtype=np.int64),
            "bs_style": "lbs", "bs_type": "lrotmin", "pose_training_info": {"ordering": "lrotmin", "n": 207}}


def official_smplx(arrays: dict, sparse_regressor: bool = True) -> dict:
    """The dict of ``SMPLX_NEUTRAL.pkl``: plain arrays, hand PCA, landmarks, ``J_regressor`` sparse or dense."""
    rng = np.random.default_rng(5)
    regressor = arrays["J_regressor"].astype(np.float64)
    out = {k: arrays[k] for k in ("v_template", "shapedirs", "posedirs", "weights", "kintree_table", "f")}
    out["J_regressor"] = Sparse(regressor) if sparse_regressor else regressor
    for side in "lr":
        out[f"hands_components{side}"] = rng.standard_normal((45, 45))
        out[f"hands_mean{side}"] = rng.standard_normal(45)
        out[f"hands_coeffs{side}"] = rng.standard_normal((1554, 45))
    out.update(dynamic_lmk_faces_idx=rng.integers(0, 100, (79, 17)), dynamic_lmk_bary_coords=rng.random((79, 17, 3)),
               lmk_faces_idx=rng.integers(0, 100, 51), lmk_bary_coords=rng.random((51, 3)),
               vt=rng.random((20, 2)), ft=rng.integers(0, 20, (30, 3)),
               joint2num={"pelvis": 0, "jaw": 22}, part2num={"global": 0, "head": 15})
    return out


def assert_same_model(got: BodyModel, want: BodyModel) -> None:
    for field in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "parents", "faces"):
        a, b = getattr(got, field), getattr(want, field)
        assert a.dtype == b.dtype and a.shape == b.shape, field
        np.testing.assert_array_equal(a, b, err_msg=field)
    assert got.kind == want.kind


@pytest.fixture(scope="module")
def smpl_pkl(model_path, tmp_path_factory) -> Path:
    """The synthetic SMPL model as the released SMPL .pkl (Python 2, protocol 2)."""
    path = tmp_path_factory.mktemp("pkl") / "basicModel_neutral_lbs_10_207_0_v1.0.0.pkl"
    path.write_bytes(py2_pickle(official_smpl(_npz_arrays(model_path))))
    return path


# ---- the model loads to the same BodyModel as the npz ----------------------------------------------
def test_official_smpl_pkl_loads_to_the_npz_model(smpl_pkl, model_path):
    data = smpl_pkl.read_bytes()
    assert data[:2] == b"\x80\x02" and b"cchumpy.ch\nCh\n" in data and b"cscipy.sparse.csc\ncsc_matrix\n" in data
    assert b"U\x03lbs" in data and b"U\x07lrotmin" in data and b"ccopy_reg" not in data  # py2 strings, NEWOBJ
    got, want = load_body_model(smpl_pkl), load_body_model(model_path)
    assert_same_model(got, want)
    assert got.kind == "smpl" and got.n_verts == want.n_verts == 6591 and got.name == smpl_pkl.name
    rng = np.random.default_rng(0)
    betas, pose = rng.normal(0, 1, (2, 10)), rng.normal(0, 0.3, (2, 24, 3))
    for a, b in zip(lbs(got, betas, pose), lbs(want, betas, pose)):
        np.testing.assert_array_equal(a, b)


def test_pkl_model_is_cached_read_only(smpl_pkl):
    first = load_body_model(smpl_pkl)
    assert load_body_model(str(smpl_pkl)) is first
    assert not first.v_template.flags.writeable and not first.J_regressor.flags.writeable


@pytest.mark.parametrize("layout", ["smplx sparse", "smplx dense", "smplh"])
def test_smplx_and_smplh_pkl_load_to_the_npz_model(layout, smplx_on_smpl_path, smplh_path, tmp_path):
    npz = smplh_path if layout == "smplh" else smplx_on_smpl_path
    arrays = _npz_arrays(npz)
    content = official_smpl(arrays) if layout == "smplh" else official_smplx(arrays, layout == "smplx sparse")
    path = tmp_path / f"{layout.split()[0].upper()}_NEUTRAL.pkl"
    path.write_bytes(py2_pickle(content))
    got, want = load_body_model(path), load_body_model(npz)
    assert_same_model(got, want)
    assert got.kind == layout.split()[0]


@pytest.mark.parametrize("writer", ["pickle", "joblib"])
def test_python3_resaved_model_with_modern_scipy_matrices(writer, model_path, tmp_path):
    """``smplx/tools/clean_ch.py`` output: a Python 3 pickle whose chumpy arrays became numpy arrays and
    whose J_regressor is still a scipy matrix (``scipy.sparse._csc``, pickled here by scipy itself);
    or the same dict saved by ``joblib.dump(..., compress=3)``."""
    import scipy.sparse

    arrays = _npz_arrays(model_path)
    content = dict(arrays, J_regressor=scipy.sparse.csc_matrix(arrays["J_regressor"].astype(np.float64)))
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    if writer == "pickle":
        path.write_bytes(pickle.dumps(content, protocol=pickle.HIGHEST_PROTOCOL))
        assert b"scipy.sparse._csc" in path.read_bytes()
    else:
        path.write_bytes(F.joblib_bytes(content, compress=3))
    assert_same_model(load_body_model(path), load_body_model(model_path))


# ---- the stand-ins, one by one -------------------------------------------------------------------------
@pytest.mark.parametrize("protocol", [0, 1, 2])
def test_chumpy_arrays_and_sparse_matrices_in_every_python2_protocol(protocol):
    rng = np.random.default_rng(protocol)
    x = rng.normal(size=(4, 3))
    dense = np.where(rng.random((3, 5)) < 0.5, rng.normal(size=(3, 5)), 0.0)
    shared = Ch(x)
    data = py2_pickle({"a": shared, "b": shared, "csc": Sparse(dense), "csr": Sparse(dense, "csr"),
                       "tag": "lbs"}, protocol)
    assert (b"copy_reg\n_reconstructor" in data) == (protocol < 2)
    got = loads_model(data, "m.pkl")
    assert got["a"] is got["b"]  # a Ch referenced twice (memo) is one array
    np.testing.assert_array_equal(got["a"], x)
    np.testing.assert_array_equal(got["csc"], dense)
    np.testing.assert_array_equal(got["csr"], dense)
    assert got["tag"] == "lbs"


def test_sparse_matrices_match_scipys_toarray_with_repeated_entries():
    """Entries given twice are summed, as scipy's toarray does; csc and csr, float32 and int data."""
    import scipy.sparse

    rng = np.random.default_rng(7)
    for fmt, cls in (("csc", scipy.sparse.csc_matrix), ("csr", scipy.sparse.csr_matrix)):
        for dtype in (np.float32, np.int64):
            shape, n_major = (6, 9), 9 if fmt == "csc" else 6
            counts = rng.integers(0, 4, n_major)
            indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
            indices = rng.integers(0, 6 if fmt == "csc" else 9, indptr[-1]).astype(np.int32)  # repeats likely
            data = rng.integers(1, 9, indptr[-1]).astype(dtype)
            want = cls((data, indices, indptr), shape=shape).toarray()
            state = {"_shape": shape, "maxprint": 50, "data": data, "indices": indices, "indptr": indptr}
            got = loads_model(py2_pickle({"m": Sparse(fmt=fmt, module=f"scipy.sparse._{fmt}", state=state)}), "m.pkl")
            assert got["m"].dtype == dtype
            np.testing.assert_array_equal(got["m"], want)


def test_reading_a_model_imports_neither_chumpy_nor_scipy_sparse(smpl_pkl):
    """Nothing of the file runs, and no chumpy or scipy class is built: a fresh process loads the model
    without importing scipy.sparse (nor chumpy, absent here)."""
    code = ("import sys; from rotavat_cli.formats.smpl import load_body_model; "
            f"m = load_body_model({str(smpl_pkl)!r}); "
            "print(m.kind, sorted(k for k in sys.modules if k.startswith(('chumpy', 'scipy.sparse'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.split() == ["smpl", "[]"], out.stdout + out.stderr


# ---- refusals: one line naming the file -----------------------------------------------------------------
def test_code_in_a_model_pickle_is_refused_without_running(tmp_path):
    marker = tmp_path / "pwned"
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    path.write_bytes(pickle.dumps({"v_template": F.Evil(marker), "bs_style": "lbs"}, protocol=2))
    with pytest.raises(InputError, match=r"^.*SMPL_NEUTRAL\.pkl: refused to unpickle global 'posix\.system' "
                                         r"\(only numpy arrays.*chumpy\.ch\.Ch and scipy csc/csr matrices"):
        load_body_model(path)
    assert not marker.exists()


@pytest.mark.parametrize("name", [("chumpy.ch_ops", "add"), ("chumpy.reordering", "Select"), ("chumpy.ch", "ChLambda"),
                                  ("scipy.sparse._coo", "coo_matrix"), ("scipy.sparse.csc", "cs_matrix")])
def test_other_chumpy_and_scipy_classes_are_refused(name, tmp_path):
    path = tmp_path / "model.pkl"
    path.write_bytes(py2_pickle({"v_template": ChOp(Ch(np.ones((2, 3))), Ch(np.ones((2, 3))), name)}))
    with pytest.raises(InputError) as info:
        load_body_model(path)
    assert str(info.value).startswith(f"{path}: refused to unpickle global '{name[0]}.{name[1]}'")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("state, needle", [
    ({"_shape": (10**6, 10**6)}, r"sparse csc matrix declares 7\.3 TiB \(float64 \(1000000, 1000000\); limit 1\.0 GiB: "
                                 r"limits\.max_array_mb\)"),
    ({"_shape": (30000, 30000)}, r"sparse csc matrix declares 6\.7 GiB"),
    ({"_shape": (2, 3, 4)}, "malformed sparse matrix shape"),
    ({"_shape": (-2, 3)}, "malformed sparse matrix shape"),
    ({"_shape": (3, 3), "indptr": np.array([0, 1, 2], np.int32)}, "indptr of 3"),
    ({"_shape": (3, 3), "indptr": np.array([0, 2, 1, 2], np.int32)}, "not a running count"),
    ({"_shape": (3, 3), "indices": np.array([0, 3], np.int32)}, "an index is outside its 3 rows/columns"),
    ({"_shape": (3, 3), "data": np.array(["a", "b"])}, r"'data' is a <U1 array"),
])
def test_malformed_or_huge_sparse_matrices_are_refused_before_allocating(state, needle):
    base = {"data": np.array([1.0, 2.0]), "indices": np.array([0, 2], np.int32),
            "indptr": np.array([0, 1, 1, 2], np.int32)}
    data = py2_pickle({"J_regressor": Sparse(state={**base, **state})})
    assert len(data) < 1000
    with pytest.raises(InputError, match=f"^m.pkl: .*{needle}"):
        loads_model(data, "m.pkl")


def test_sparse_matrix_size_follows_the_limits_in_force():
    """The dense J_regressor (24 x 6890 float64: 1.3 MB) is refused under max_array_mb = 1 (and the
    packaged limits read it: the test above)."""
    with limits.applied(limits.Limits.from_config({"max_array_mb": 1})):
        small = py2_pickle({"J_regressor": Sparse(np.eye(24, 6890))})
        with pytest.raises(InputError, match=r"sparse csc matrix declares 1\.3 MiB \(float64 \(24, 6890\); limit 1\.0 MiB"):
            loads_model(small, "m.pkl")


@pytest.mark.parametrize("x, needle", [
    ([1.0, 2.0], "'x' is a list"),
    (np.array(["a"]), "'x' is a <U1 array"),
    (np.array([None], dtype=object), "'x' is an object array"),
])
def test_chumpy_arrays_hold_numbers_only(x, needle):
    class Odd(Ch):
        def __getstate__(self):
            return {"x": x, "_itr": None}

    with pytest.raises(InputError, match=f"^m.pkl: malformed chumpy array \\({needle}"):
        loads_model(py2_pickle({"v_template": Odd(0.0)}), "m.pkl")


def test_pickles_that_are_not_body_models(tmp_path, model_path, scene):
    arrays = _npz_arrays(model_path)
    cases = {
        "results.pkl": (F.write_phalp(tmp_path / "results.pkl", scene, (F.W, F.H), compress=0), r"missing v_template"),
        "list.pkl": ([1, 2, 3], "it holds a list, not a dict of arrays"),
        "text.pkl": ({**official_smpl(arrays), "weights": "lbs"}, "'weights' is a str, not a numeric array"),
        "truncated.pkl": (py2_pickle(official_smpl(arrays))[:5000], "truncated pickle"),
        "empty.pkl": (b"", "empty file"),
    }
    for name, (content, needle) in cases.items():
        path = tmp_path / name
        if not isinstance(content, Path):
            path.write_bytes(content if isinstance(content, bytes) else py2_pickle(content))
        with pytest.raises(InputError, match=f"^{re.escape(str(path))}: .*{needle}"):
            load_body_model(path)


# ---- through the CLI: a 4D-Humans file imported with the .pkl model -------------------------------
def test_fourdhumans_import_with_the_pkl_model_gives_the_npz_meshes(tmp_path, scene, smpl_pkl, model_path, runner):
    src = F.write_phalp(tmp_path / "demo_video.pkl", scene, (F.W, F.H))
    for model, out in ((smpl_pkl, "out_pkl"), (model_path, "out_npz")):
        result = invoke(runner, "import", "--from", "4dhumans", src, tmp_path / out, "--smpl-model", model, "--json")
        assert result.exit_code == 0, result.output
        assert json.loads(result.stdout)["has_vertices"]
    with_pkl, with_npz = open_sequence(tmp_path / "out_pkl"), open_sequence(tmp_path / "out_npz")
    frames = list(zip(with_pkl.frames(), with_npz.frames()))
    assert [a.n_people for a, _ in frames] == [2, 1, 0]
    for a, b in frames:
        np.testing.assert_array_equal(a.data["vertices"], b.data["vertices"])
        np.testing.assert_array_equal(a.data["faces"], b.data["faces"])
    np.testing.assert_allclose(frames[0][0].data["vertices"], np.stack([p.verts_cam for p in scene[0]]),
                               atol=TOL_M)


def test_cli_refuses_a_pkl_that_is_not_a_model_in_one_line(tmp_path, scene, runner):
    src = F.write_phalp(tmp_path / "demo_video.pkl", scene, (F.W, F.H))
    result = invoke(runner, "import", "--from", "4dhumans", src, tmp_path / "out", "--smpl-model", src)
    assert result.exit_code == 2
    lines = [line for line in result.output.strip().splitlines() if line.strip()]
    assert lines[0].startswith("error:") and "demo_video.pkl: not an SMPL-family .pkl model (missing" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()
    evil = tmp_path / "evil.pkl"
    evil.write_bytes(pickle.dumps({"v_template": F.Evil(tmp_path / "pwned")}, protocol=2))
    result = invoke(runner, "import", "--from", "4dhumans", src, tmp_path / "out", "--smpl-model", evil)
    assert result.exit_code == 2 and "evil.pkl: refused to unpickle global 'posix.system'" in result.output
    assert not (tmp_path / "pwned").exists() and os.path.exists(evil)


# ---- hostile dtype states (met fuzzing this reader; every pickle reader shares the fix) ---------------
_F8 = b"cnumpy\ndtype\nX\x02\x00\x00\x00f8\x89\x88\x87R"  # numpy.dtype('f8', False, True)


def _dtype_pickle(head: bytes, state: bytes) -> bytes:
    """``head`` (a dtype built), then BUILD with the opcodes of ``state``."""
    return b"\x80\x02" + head + state + b"b."


_STATE_F8 = b"(K\x03X\x01\x00\x00\x00<NNNJ\xff\xff\xff\xffJ\xff\xff\xff\xffK\x00t"


@pytest.mark.parametrize("reader", [loads_model, unpickle.loads])
@pytest.mark.parametrize("head, state, needle", [
    # a 6-item version-3 state: numpy 2.4's dtype.__setstate__ crashes the process on it
    (b"cnumpy\ndtype\nX\x02\x00\x00\x00i4\x89\x88\x87R", b"(K\x03X\x01\x00\x00\x00<NJ\xff\xff\xff\xffJ\xff\xff\xff\xffK\x00t",
     "malformed dtype state"),
    # 9 items for version 3, fields given as a list: numpy returned NULL without an exception (SystemError)
    (_F8, b"(K\x03X\x01\x00\x00\x00<NN]NJ\xff\xff\xff\xffJ\xff\xff\xff\xffK\x00t", "malformed dtype state$"),
    (_F8, b"(K\x03X\x01\x00\x00\x00<NN]J\xff\xff\xff\xffJ\xff\xff\xff\xffK\x00t", r"malformed dtype state \(fields\)"),
    # fields that describe a 12-byte record, given to a float64
    (_F8, b"(K\x03X\x01\x00\x00\x00|NX\x01\x00\x00\x00xq\x00\x85}h\x00cnumpy\ndtype\nX\x02\x00\x00\x00f4\x89\x88\x87R"
          + _STATE_F8 + b"bK\x00\x86sK\x04K\x01K\x10t", "it describes a V4, not a f8"),
    # a dtype from something other than a type string
    (b"cnumpy\ndtype\n]\x89\x88\x87R", _STATE_F8, "numpy pickles a dtype from its type string"),
])
def test_hostile_dtype_states_are_refused_in_one_line(reader, head, state, needle):
    with pytest.raises(InputError, match=f"^m.pkl: .*{needle}"):
        reader(_dtype_pickle(head, state), "m.pkl")


def test_dtype_flags_and_shared_dtypes_come_from_numpy_not_the_pickle():
    """A state whose flags say 'holds objects' (63) cannot make float64 read its bytes as pointers; a
    dtype asked for without copy is a new one, so a state never reaches numpy's shared float64."""
    flagged = _dtype_pickle(_F8, _STATE_F8[:-3] + b"K?t")
    assert pickle.loads(flagged).hasobject  # what numpy alone would make of it
    got = unpickle.loads(flagged, "m.pkl")
    assert got == np.dtype("f8") and not got.hasobject
    shared = _dtype_pickle(b"cnumpy\ndtype\nX\x02\x00\x00\x00f8\x89\x89\x87R", _STATE_F8.replace(b"<", b">"))
    got = loads_model(shared, "m.pkl")
    assert got.str == ">f8" and got is not np.dtype("f8") and np.dtype("f8").str == "<f8"


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # pickle's escape_decode of mangled protocol-0 strings
def test_mutated_model_pickles_fail_in_one_line_or_load():
    """Seeded byte mutations of a small Python 2 model pickle (protocols 0-2, chumpy arrays, csc/csr
    matrices, a record array): each loads or is one InputError line, never another exception or a crash."""
    rng = np.random.default_rng(11)
    dense = np.where(rng.random((4, 6)) < 0.4, 1.0, 0.0)
    content = {"v": Ch(rng.normal(size=(5, 3))), "J": Sparse(dense), "r": Sparse(dense, "csr"), "s": "lbs",
               "k": np.arange(4), "rec": np.zeros(2, [("x", "<f4"), ("n", ">i8")])}
    bases = [py2_pickle(content, protocol) for protocol in (0, 1, 2)]
    outcomes = {"loaded": 0, "refused": 0}
    for _ in range(600):
        data = bytearray(bases[int(rng.integers(0, 3))])
        for _ in range(int(rng.integers(1, 4))):
            at = int(rng.integers(0, len(data)))
            op = int(rng.integers(0, 3))
            if op == 0:
                data[at] = int(rng.integers(0, 256))
            elif op == 1:
                del data[at]
            else:
                data.insert(at, int(rng.integers(0, 256)))
        try:
            loads_model(bytes(data), "m.pkl")
            outcomes["loaded"] += 1
        except InputError as exc:
            assert "\n" not in str(exc) and len(str(exc)) < 400 and str(exc).startswith("m.pkl: ")
            outcomes["refused"] += 1
    assert outcomes["loaded"] > 10 and outcomes["refused"] > 100
