"""Small hostile files must not make rotavat allocate gigabytes (issue 15, point 3).

Every case of the hostile-input campaign is rebuilt here as a small file (a zip bomb is a few MB of
repeated deflate blocks, a lying header a few hundred bytes; nothing large is ever written) and run
through the real command in a subprocess whose peak resident memory is measured (``os.wait4``):
each ends with exit status 2, one line on stderr naming the file and the number, and a peak far
below what the file declares (these are marked ``slow``: ``make test-slow``). Raising a limit with
``--config`` lets a large-but-legitimate input through; the usual fixtures are unaffected (the other
test modules).
"""

from __future__ import annotations

import io
import os
import pickle
import re
import resource
import struct
import subprocess
import sys
import tempfile
import zipfile
import zlib
from pathlib import Path

import _body_models as B
import _format_fixtures as F
import numpy as np
import pytest
from _cli import invoke
from conftest import tetra_frame

from rotavat_cli import unpickle

from rotavat_cli.settings import limits
from rotavat_cli.calibration import GridSpec
from rotavat_cli.errors import InputError
from rotavat_cli.settings.limits import Limits
from rotavat_cli.plain import to_plain
from rotavat_cli.unpickle.allowed import numpy_multiarray

PEAK_MB = 300  # every hostile case must stay under this (the files declare 4 to 48 GB; measured: 55-110 MB)
MEMORY_CAP = 6 << 30  # address-space cap of the subprocess: a regression fails instead of swamping the machine
SMALL = Limits(max_file_bytes=1 << 20, max_array_bytes=1 << 20, max_frame_bytes=1 << 20, max_pickle_items=10_000,
               max_grid_cells=10_000)


@pytest.fixture(autouse=True)
def _default_limits():
    """In-process CLI runs with --config set the process-wide limits: restore the defaults after each test."""
    yield
    limits.configure(None)


# ---- running the real command, measuring its memory ---------------------------------------------
# The child reports its own peak (VmHWM) at exit: ru_maxrss from wait4 would include the pytest
# process's memory, which a forked child counts until it execs.
_CHILD = """
import atexit, os
def _report_peak():
    with open("/proc/self/status") as status:
        peak_kb = next(line.split()[1] for line in status if line.startswith("VmHWM:"))
    with open(os.environ["ROTAVAT_TEST_PEAK_FILE"], "w") as out:
        out.write(peak_kb)
if os.path.exists("/proc/self/status"):
    atexit.register(_report_peak)
from rotavat_cli.cli import main
main()
"""


def run(*args: object) -> tuple[int, list[str], float]:
    """``rotavat ARGS`` in a fresh process (the console-script entry point): (exit status, stderr lines,
    peak resident memory in MB of that process alone)."""
    with open(os.devnull, "wb") as devnull, tempfile.TemporaryFile() as err, tempfile.TemporaryDirectory() as tmp:
        peak_file = Path(tmp) / "peak"
        proc = subprocess.Popen(
            [sys.executable, "-c", _CHILD, *map(str, args)], stdout=devnull, stderr=err,
            env={**os.environ, "CI": "1", "ROTAVAT_TEST_PEAK_FILE": str(peak_file)},
            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP)))
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        lines = err.read().decode(errors="replace").strip().splitlines()
        if peak_file.exists():
            peak_mb = int(peak_file.read_text()) / 1024
        else:  # no /proc (macOS), or the child died: its rusage (an over-estimate when pytest is large)
            peak_mb = usage.ru_maxrss / (1 << 20) if sys.platform == "darwin" else usage.ru_maxrss / 1024
    return proc.returncode, lines, peak_mb


def assert_refused(result: tuple[int, list[str], float], *needles: str) -> str:
    """Exit 2, exactly one stderr line holding every needle, peak memory bounded; returns the line."""
    code, lines, peak = result
    assert code == 2, (code, lines)
    assert len(lines) == 1, lines
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert "Traceback" not in lines[0]
    assert peak < PEAK_MB, f"peak RSS {peak:.0f} MB: {lines[0]}"
    return lines[0]


# ---- hostile files, built small ----------------------------------------------------------------
def npy_header(dtype: str, shape: tuple[int, ...], fortran: bool = False) -> bytes:
    """A version-1 .npy header declaring ``shape`` (whatever follows)."""
    text = f"{{'descr': '{np.dtype(dtype).str}', 'fortran_order': {fortran}, 'shape': {shape!r}, }}"
    pad = 64 - (10 + len(text) + 1) % 64
    text = text + " " * pad + "\n"
    return b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text.encode("latin1")


def deflated_zeros(prefix: bytes, n_zeros: int) -> tuple[bytes, int]:
    """Raw deflate of ``prefix`` + ``n_zeros`` zero bytes, built from one compressed 16 MiB block repeated
    (blocks after a full flush are independent), so a 4 GB member takes 4 MB and 50 ms. Returns
    (compressed bytes, uncompressed size)."""
    block_size = 1 << 24
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    head = comp.compress(prefix) + comp.flush(zlib.Z_FULL_FLUSH)
    block = comp.compress(bytes(block_size)) + comp.flush(zlib.Z_FULL_FLUSH)
    full, rest = divmod(n_zeros, block_size)
    tail = comp.compress(bytes(rest)) + comp.flush(zlib.Z_FINISH)
    return head + block * full + tail, len(prefix) + n_zeros


def write_zip(path: Path, members: list[tuple[str, bytes, int, int, int]]) -> Path:
    """A zip written field by field: (name, stored bytes, method, declared uncompressed size, crc).
    The declared sizes are whatever the caller says (a bomb's are true, a liar's are not)."""
    with open(path, "wb") as out:
        central = []
        for name, data, method, size, crc in members:
            offset = out.tell()
            raw_name = name.encode()
            out.write(struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, method, 0, 0x21, crc, len(data), size,
                                  len(raw_name), 0) + raw_name)
            out.write(data)
            central.append(struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, method, 0, 0x21, crc, len(data),
                                       size, len(raw_name), 0, 0, 0, 0, 0, offset) + raw_name)
        start = out.tell()
        out.write(b"".join(central))
        out.write(struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(central), len(central), out.tell() - start, start, 0))
    return path


def npy_member(name: str, array: np.ndarray) -> tuple[str, bytes, int, int, int]:
    """An honest stored member holding ``array``."""
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array)  # object arrays pickled in (the default)
    data = buf.getvalue()
    return name + ".npy", data, zipfile.ZIP_STORED, len(data), zlib.crc32(data)


def bomb_member(name: str, dtype: str, shape: tuple[int, ...]) -> tuple[str, bytes, int, int, int]:
    """A deflated member that truly inflates to the array it declares (zeros): a zip bomb. Its CRC is
    right when the member is small enough to be read (<= 64 MiB), else 0 (it must never be read)."""
    header = npy_header(dtype, shape)
    n_zeros = int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
    data, size = deflated_zeros(header, n_zeros)
    crc = zlib.crc32(bytes(n_zeros), zlib.crc32(header)) if n_zeros <= 64 << 20 else 0
    return name + ".npy", data, zipfile.ZIP_DEFLATED, size, crc


def liar_member(name: str, dtype: str, shape: tuple[int, ...], payload: bytes = bytes(64)) -> tuple[str, bytes, int, int, int]:
    """A stored member whose .npy header declares ``shape`` but which holds ``payload`` only."""
    data = npy_header(dtype, shape) + payload
    return name + ".npy", data, zipfile.ZIP_STORED, len(data), zlib.crc32(data)


def frame_members(seed: int = 0) -> list[tuple[str, bytes, int, int, int]]:
    return [npy_member(k, v) for k, v in tetra_frame(np.random.default_rng(seed), 2).items()]


def contract_sequence(root: Path, bad_members: list[tuple[str, bytes, int, int, int]]) -> Path:
    """A 4-frame npz sequence whose frame 000003 also holds ``bad_members``."""
    root.mkdir(parents=True)
    for i in range(3):
        write_zip(root / f"{i:06d}.npz", frame_members(i))
    write_zip(root / "000003.npz", frame_members(3) + bad_members)
    (root / "meta.yaml").write_text("image_size: [640, 480]\nfocal_length: 500.0\nsource: test\n")
    return root


class _Call:
    """Pickles as ``func(*args)`` (what a hostile file can ask for with the allowed callables)."""

    def __init__(self, func, *args):
        self.func, self.args = func, args

    def __reduce__(self):
        return self.func, self.args


def shared_nest(depth: int, fanout: int) -> list:
    """``[[...[[x, y], [x, y], ...]...]]`` where every level holds ``fanout`` references to ONE list."""
    level: list = [0.5, 1.5]
    for _ in range(depth):
        level = [level] * fanout
    return level


# ---- the campaign's cases, through the real commands --------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("command", ["info", "align"])
def test_npz_zip_bomb_in_a_frame(tmp_path, command):
    """3.9 MB of deflate that inflates to 3.7 GiB of vertices (the campaign's 3.2 MB -> 4 GB)."""
    seq = tmp_path / "seq"
    contract_sequence(seq, [])
    write_zip(seq / "000003.npz", [m for m in frame_members(3) if m[0] != "vertices.npy"]
              + [bomb_member("vertices", "<f4", (1, 333_000_000, 3))])
    assert (seq / "000003.npz").stat().st_size < 5 << 20
    args = ["info", seq] if command == "info" else ["align", "--in", seq, "--out", tmp_path / "out"]
    assert_refused(run(*args), "000003.npz: member 'vertices' declares 3.7 GiB", "limit 1.0 GiB: limits.max_array_mb")


@pytest.mark.slow
def test_frame_member_nobody_uses_is_still_refused_in_a_contract_frame(tmp_path):
    """Contract frames keep every key (align copies them through): a 3.5 GiB 'junk' member is refused by name."""
    seq = contract_sequence(tmp_path / "seq", [bomb_member("junk", "u1", ((3 << 30) + (1 << 29),))])
    assert_refused(run("info", seq), "000003.npz: member 'junk' declares 3.5 GiB", "limit 1.0 GiB: limits.max_array_mb")


@pytest.mark.slow
@pytest.mark.parametrize("shape, needle", [
    ((1, 1_600_000_000, 3), "member 'vertices' declares 17.9 GiB"),  # the campaign's 19 GB header
    ((4_000_000, 1000, 3), "member 'vertices' declares 44.7 GiB"),  # ... and its 48 GB one
])
def test_npz_member_header_declaring_gigabytes(tmp_path, shape, needle):
    members = [m for m in frame_members(3) if m[0] != "vertices.npy"] + [liar_member("vertices", "<f4", shape)]
    seq = contract_sequence(tmp_path / "seq", [])
    write_zip(seq / "000003.npz", members)
    assert_refused(run("info", seq), needle, "000003.npz", "limits.max_array_mb")


@pytest.mark.slow
def test_npz_header_lying_below_the_limit_is_caught_against_the_member_size(tmp_path):
    """12 MB declared, 64 bytes present: refused from the zip directory, before allocating 12 MB."""
    seq = contract_sequence(tmp_path / "seq", [liar_member("junk", "<f4", (1000, 1000, 3))])
    line = assert_refused(run("info", seq), "000003.npz ['junk']", "corrupt or truncated array")
    assert "12,000,000 bytes" in line and "the member holds 64" in line


@pytest.mark.slow
def test_inflating_beyond_the_declared_size_allocates_nothing_more(tmp_path):
    """A member declaring 400 bytes whose deflate stream inflates to 64 MiB: zipfile stops at the
    declared size, the CRC check fails, nothing beyond 400 bytes is kept."""
    arr_header = npy_header("<f4", (2, 4, 3))  # 96 bytes of data declared
    data, _ = deflated_zeros(arr_header, 64 << 20)
    members = [m for m in frame_members(3) if m[0] != "vertices.npy"]
    members.append(("vertices.npy", data, zipfile.ZIP_DEFLATED, len(arr_header) + 96, 0))
    seq = contract_sequence(tmp_path / "seq", [])
    write_zip(seq / "000003.npz", members)
    assert_refused(run("info", seq), "000003.npz: not a readable .npz file", "CRC")


@pytest.mark.slow
def test_multihmr_npy_header_declaring_48_gb(tmp_path):
    src = tmp_path / "mhmr"
    src.mkdir()
    (src / "img_0001.npy").write_bytes(npy_header("<f4", (1_145_000, 10475, 1)) + bytes(100))
    assert_refused(run("import", "--from", "multihmr", src, tmp_path / "out", "--image-size", 640, 480),
                   "img_0001.npy declares 44.7 GiB", "limits.max_array_mb")
    (src / "img_0001.npy").write_bytes(npy_header("<f4", (2, 10475, 3)) + bytes(100))  # 251 KB declared, 100 B there
    assert_refused(run("import", "--from", "multihmr", src, tmp_path / "out2", "--image-size", 640, 480),
                   "img_0001.npy", "corrupt or truncated array", "251,400 bytes", "100 follow")


@pytest.mark.slow
def test_pickle_list_of_a_range(tmp_path):
    """78 bytes asking for list(range(400_000_000)) (5.9 GB once built)."""
    src = tmp_path / "agora"
    src.mkdir()
    payload = pickle.dumps({"verts": _Call(list, range(400_000_000))}, protocol=2)
    assert len(payload) < 100
    (src / "ag_cam01_00000_personId_0.pkl").write_bytes(payload)
    assert_refused(run("import", "--from", "agora", src, tmp_path / "out"),
                   "ag_cam01_00000_personId_0.pkl: list() would build 400,000,000 items",
                   "limit 20,000,000: limits.max_pickle_items")


@pytest.mark.slow
def test_agora_pickle_of_shared_references(tmp_path):
    """Under 1 KB: one 2-float list referenced 8 times, that list 8 times, ... 10 levels deep. The
    unpickler builds 80 references; converting it to an array would make 2 billion floats (17 GB)."""
    src = tmp_path / "agora"
    src.mkdir()
    payload = pickle.dumps({"verts": shared_nest(10, 8), "joints": np.zeros((24, 2))}, protocol=2)
    assert len(payload) < 1000
    (src / "ag_cam01_00000_personId_0.pkl").write_bytes(payload)
    assert_refused(run("import", "--from", "agora", src, tmp_path / "out"),
                   "ag_cam01_00000_personId_0.pkl: shared references expand the pickle to 3,374,617,", "items",
                   "limits.max_pickle_items")


@pytest.mark.slow
def test_bev_npz_extra_member_is_never_read(tmp_path, scene):
    """A BEV result with an extra 3.5 GiB member: imported from 'results' alone, in bounded memory
    (the campaign saw exit 0 after 49 s at 7.45 GB)."""
    F.write_bev(tmp_path / "bev", scene[:1], (640, 480))
    good = next((tmp_path / "bev").glob("*.npz"))
    with zipfile.ZipFile(good) as archive:
        results = archive.read("results.npy")
    write_zip(good, [("results.npy", results, zipfile.ZIP_STORED, len(results), zlib.crc32(results)),
                     bomb_member("junk", "u1", ((3 << 30) + (1 << 29),))])
    code, lines, peak = run("import", "--from", "bev", tmp_path / "bev", tmp_path / "out", "--image-size", 640, 480)
    assert code == 0, lines
    assert peak < PEAK_MB
    assert len(list((tmp_path / "out").glob("*.npz"))) == 1


@pytest.mark.slow
def test_parameters_for_gigabytes_of_meshes_are_refused_before_posing(tmp_path):
    """A 0.1 MB CLIFF file naming 5,000 people in one image: posing them would need 754 MiB of
    float64 meshes (and 4 GiB of skinning transforms at once); refused, one line, bounded memory."""
    n = 5_000
    detections = np.zeros((n, 8))
    detections[:, 3:5] = 10.0  # boxes (0, 0) - (10, 10)
    src = tmp_path / "cliff.npz"
    np.savez_compressed(src, imgname=np.array(["/data/imgs/000000.png"] * n), pose=np.zeros((n, 72)),
                        shape=np.zeros((n, 10)), global_t=np.tile([0.0, 0.0, 10.0], (n, 1)),
                        pred_joints=np.zeros((n, 45, 3)), focal_l=np.full(n, 800.0), detection_all=detections)
    assert src.stat().st_size < 1 << 20
    model = B.write_synthetic_smpl(tmp_path / "SMPL.npz")  # named in the message
    for command in (("import", src, tmp_path / "out"), ("calibrate", src, "--out", tmp_path / "camera.yaml")):
        assert_refused(run(*command, "--from", "cliff", "--image-size", 640, 480, "--smpl-model", model),
                       "cliff.npz: posing 5000 people on SMPL.npz (6591 vertices) needs 754.3 MiB of meshes",
                       "limits.max_frame_mb (256.0 MiB)")
    assert not (tmp_path / "out").exists() and not (tmp_path / "camera.yaml").exists()


@pytest.mark.slow
def test_compressed_pickle_bomb(tmp_path):
    """A 2.3 MB zlib-compressed 'joblib' file inflating to 2.2 GiB: unpickled as it inflates, refused at
    its first byte that is no pickle's, never held; what follows a whole pickle is inflated (and
    counted) to the end, a chunk at a time, and refused past limits.max_file_mb."""
    data, _ = deflated_zeros(b"\x80\x04", (2 << 30) + (1 << 28))
    (tmp_path / "phalp.pkl").write_bytes(b"\x78\xda" + data + b"\0\0\0\0")
    assert_refused(run("import", "--from", "4dhumans", tmp_path / "phalp.pkl", tmp_path / "out"),
                   "phalp.pkl: not a readable pickle (invalid opcode)")
    data, _ = deflated_zeros(b"\x80\x04N.", 64 << 20)
    (tmp_path / "phalp.pkl").write_bytes(b"\x78\xda" + data + b"\0\0\0\0")
    with limits.applied(Limits(16 << 20, 1 << 20, 1 << 20, 10_000, 10_000)), pytest.raises(
            InputError, match=r"phalp\.pkl: decompresses to more than 16\.0 MiB \(limit: limits\.max_file_mb\)"):
        unpickle.load_file(tmp_path / "phalp.pkl")


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["wham", "gvhmr", "bev"])
def test_compressed_pickle_under_the_limit_is_refused_as_it_inflates(tmp_path, fmt):
    """A 1 MB file whose pickle inflates to 1 GiB of zeros, under limits.max_file_mb: WHAM's zlib
    joblib, a GVHMR torch archive whose data.pkl record is deflated, a BEV .npz whose object member
    is. Unpickled as it inflates, it is refused at its first zero (inflated whole first, it took 2.1 GB
    and 8-13 s). The checksums are right: the stream is sound to its end, only far too big."""
    if fmt == "wham":
        data, size = deflated_zeros(b"\x80\x02", 1 << 30)
        src = tmp_path / "wham_output.pkl"
        src.write_bytes(b"\x78\xda" + data + (0x5DC90083).to_bytes(4, "big"))  # zlib.adler32 of the whole
        needle = "wham_output.pkl: not a readable pickle (invalid opcode)"
    elif fmt == "gvhmr":
        data, size = deflated_zeros(b"\x80\x02", 1 << 30)
        src = write_zip(tmp_path / "hmr4d_results.pt", [("hmr4d_results/data.pkl", data, zipfile.ZIP_DEFLATED, size,
                                                          0x7E71F856)])  # zlib.crc32 of the whole
        needle = "hmr4d_results.pt: torch archive: not a readable pickle (invalid opcode)"
    else:
        data, size = deflated_zeros(npy_header("|O", ()) + b"\x80\x02", 1 << 30)
        (tmp_path / "bev").mkdir()
        src = write_zip(tmp_path / "bev" / "000000.npz", [("results.npy", data, zipfile.ZIP_DEFLATED, size,
                                                             0x4870C032)])  # zlib.crc32 of the whole
        needle = "000000.npz ['results']: not a readable pickle (invalid opcode)"
    assert src.stat().st_size < 2 << 20
    assert_refused(run("import", "--from", fmt, src, tmp_path / "out", "--image-size", 640, 480), needle)


@pytest.mark.slow
def test_grid_steps_from_config(tmp_path, npz_seq):
    (tmp_path / "grid.yaml").write_text("calibrate:\n  grid:\n    steps: [5000, 5000, 5000]\n")
    assert_refused(run("calibrate", npz_seq, "--config", tmp_path / "grid.yaml", "--out", tmp_path / "cam.yaml"),
                   "calibrate.grid.steps [5000, 5000, 5000] make 125,000,000,000 grid cells",
                   "limit 2,000,000: limits.max_grid_cells")


# ---- limits are configurable; normal files pass ---------------------------------------------------
def test_config_limits_decide_for_a_large_member(tmp_path, runner):
    """A 24 MiB extra member (a few KB on disk): refused under max_array_mb 16, read under 64."""
    seq = contract_sequence(tmp_path / "seq", [bomb_member("extra", "<f8", (3 << 20,))])
    (tmp_path / "low.yaml").write_text("limits:\n  max_array_mb: 16\n")
    (tmp_path / "high.yaml").write_text("limits:\n  max_array_mb: 64\n")
    camera = tmp_path / "camera.yaml"
    camera.write_text("image_size: [640, 480]\nfocal_px: 500.0\nprincipal_point: [320.0, 240.0]\n"
                      "pitch_deg: 20.0\nroll_deg: 0.0\nheight_m: 5.0\n")
    low = invoke(runner, "align", "--in", seq, "--camera", camera, "--out", tmp_path / "a", "--config", tmp_path / "low.yaml")
    assert low.exit_code == 2 and "member 'extra' declares 24.0 MiB" in low.stderr
    assert "limit 16.0 MiB: limits.max_array_mb" in low.stderr
    high = invoke(runner, "align", "--in", seq, "--camera", camera, "--out", tmp_path / "b", "--config", tmp_path / "high.yaml")
    assert high.exit_code == 0, high.stderr
    with np.load(tmp_path / "b" / "000003.npz") as npz:
        assert npz["extra"].shape == (3 << 20,) and not npz["extra"].any()


def test_raising_max_grid_cells_lets_a_finer_grid_through(tmp_path, runner):
    scene = tmp_path / "scene"
    assert invoke(runner, "synth", scene, "--seed", 1, "--frames", 2, "--people", 6).exit_code == 0
    (tmp_path / "fine.yaml").write_text("calibrate:\n  grid:\n    steps: [200, 50, 400]\n")
    (tmp_path / "raised.yaml").write_text("calibrate:\n  grid:\n    steps: [200, 50, 400]\nlimits:\n  max_grid_cells: 5000000\n")
    refused = invoke(runner, "calibrate", scene / "pred", "--config", tmp_path / "fine.yaml", "--out", tmp_path / "a.yaml")
    assert refused.exit_code == 2 and "4,000,000 grid cells (limit 2,000,000: limits.max_grid_cells)" in refused.stderr
    ok = invoke(runner, "calibrate", scene / "pred", "--config", tmp_path / "raised.yaml", "--out", tmp_path / "b.yaml")
    assert ok.exit_code == 0, ok.stderr
    assert (tmp_path / "b.yaml").exists()


def test_limits_from_config_and_errors():
    lim = Limits.from_config({"max_file_mb": 1, "max_array_mb": 0.5, "max_frame_mb": 2, "max_pickle_items": 10,
                              "max_grid_cells": 7})
    assert lim == Limits(1 << 20, 1 << 19, 2 << 20, 10, 7)
    assert pickle.loads(pickle.dumps(lim)) == lim
    assert Limits.from_config({}) == limits.current()  # missing keys: the packaged defaults
    assert limits.current() == Limits(2048 << 20, 1024 << 20, 256 << 20, 20_000_000, 2_000_000)
    for bad in (0, -1, "big", True, float("inf")):
        with pytest.raises(InputError, match=r"limits\.max_array_mb must be (> 0|a number|finite), got"):
            Limits.from_config({"max_array_mb": bad})
    with limits.applied(SMALL):
        assert limits.current() is SMALL
    assert limits.current() != SMALL


def test_batch_tasks_apply_the_plan_limits(tmp_path, npz_seq):
    from rotavat_cli.batch.tasks import _apply_limits
    from rotavat_cli.settings.config import default_config

    config = default_config()
    config["limits"]["max_array_mb"] = 0.0001  # 104 bytes: the fixture's vertices are larger
    _apply_limits({"config": config})
    with pytest.raises(InputError, match="limits.max_array_mb"):
        list(unpickle.load_npz(npz_seq / "000000.npz"))
    _apply_limits({"config": {}})  # an older plan without the section: the defaults
    assert unpickle.load_npz(npz_seq / "000000.npz")["vertices"].shape == (3, 4, 3)


# ---- the rules, in process -------------------------------------------------------------------------
_numpy_frombuffer = (getattr(np, "_core", None) or np.core).numeric._frombuffer


@pytest.mark.parametrize("obj, needle", [
    (_Call(list, range(50_000)), "list() would build 50,000 items"),
    (_Call(tuple, range(50_000)), "tuple() would build 50,000 items"),
    (_Call(set, range(50_000)), "set() would build 50,000 items"),
    (_Call(frozenset, range(50_000)), "frozenset() would build 50,000 items"),
    (_Call(dict, [(i, i) for i in range(10_000)]), "pickle builds more than 10,000 objects"),
    (_Call(bytes, 10**12), "bytes() of a int is not allowed"),
    (_Call(bytearray, 10**12), "bytearray() of a int is not allowed"),
    (_Call(str, shared_nest(20, 2)), "str() of a list is not allowed"),
    (_Call(np.ndarray, (10**6, 10**6)), "numpy.ndarray may not be called directly"),
    (_Call(numpy_multiarray()._reconstruct, np.ndarray, (10**6, 10**6), b"b"), "declares 931.3 GiB"),
    (_Call(_numpy_frombuffer, 10**12, np.dtype("u1"), (10**12,), "C"), "protocol-5 array buffer"),
    (list(range(20_000)), "more than 10,000 objects"),
    (shared_nest(12, 4), "shared references expand the pickle to"),
    ([np.zeros(1 << 17)] * 20, "shared references expand"),  # one 1 MiB array, np.asarray'ed 20 times
])
def test_refusals_are_made_before_building(obj, needle):
    payload = pickle.dumps({"x": obj}, protocol=4)
    with limits.applied(SMALL), pytest.raises(InputError, match=re.escape(needle)) as info:
        unpickle.loads(payload, "h.pkl")
    message = str(info.value)
    assert message.startswith("h.pkl: ") and "\n" not in message


def _hand_made_pickles():
    """Opcodes no Python object pickles to, written by hand."""
    # ndarray.__setstate__ of an object array of 10**8 elements with a one-item list: numpy would
    # allocate and zero 800 MB before noticing the list is short
    state = pickle.dumps((1, (10**8,), np.dtype(object), False, [0]), protocol=2)[2:-1]
    reconstruct = b"cnumpy.core.multiarray\n_reconstruct\ncnumpy\nndarray\nK\x00\x85C\x01b\x87R"
    yield "object array", b"\x80\x02" + reconstruct + state + b"b.", "object array data does not match its shape"
    yield "bytearray8", b"\x80\x05\x96" + struct.pack("<Q", 10**12) + b"xx.", "a bytearray of 1,000,000,000,000 bytes"
    # a FRAME is read whole before its opcodes run (pickle writes them of ~64 KiB): a 1 TB one is refused unread
    yield "frame", b"\x80\x04\x95" + struct.pack("<Q", 10**12) + b"N.", "a frame of 1,000,000,000,000 bytes"
    rng = b"c__builtin__\nrange\n(K\x00J\x00\xca\x9a;tR"  # range(0, 10**9), lazy
    yield "copyreg", b"ccopy_reg\n_reconstructor\n(c__builtin__\ntuple\nc__builtin__\ntuple\n" + rng + b"tR.", \
        "tuple() would build 1,000,000,000 items"
    yield "newobj", b"\x80\x02c__builtin__\ntuple\n" + rng + b"\x85\x81.", "tuple() would build 1,000,000,000 items"
    yield "obj", b"(c__builtin__\nlist\n" + rng + b"o.", "list() would build 1,000,000,000 items"
    yield "inst", b"(" + rng + b"i__builtin__\nlist\n.", "list() would build 1,000,000,000 items"
    yield "cycle", b"\x80\x02]q\x00h\x00a.", "reference cycle"
    yield "build on a global", b"\x80\x02cbuiltins\nlist\n}X\x01\x00\x00\x00aK\x01sb.", "BUILD on list"


@pytest.mark.parametrize("what, payload, needle", list(_hand_made_pickles()), ids=lambda v: v if isinstance(v, str) else "")
def test_hand_made_opcodes(what, payload, needle):
    with limits.applied(Limits(1 << 20, 1 << 30, 1 << 30, 10_000, 10_000)), pytest.raises(InputError, match=re.escape(needle)):
        unpickle.loads(payload, "h.pkl")


def test_legitimate_sharing_and_sizes_pass():
    """Modest sharing (one faces array in every person's dict), arrays near the limit, big strings."""
    faces = np.arange(3 * 1000).reshape(-1, 3)
    people = [{"faces": faces, "verts": np.zeros((6890, 3), np.float32)} for _ in range(20)]
    data = {"people": people, "names": ["x" * 1000] * 10, "big": np.zeros(1 << 17)}  # 1 MiB: exactly the limit
    with limits.applied(Limits(1 << 30, 1 << 20, 1 << 30, 100_000, 10_000)):
        back = unpickle.loads(pickle.dumps(data, protocol=4), "ok.pkl")
    assert back["people"][19]["faces"] is back["people"][0]["faces"]
    assert back["big"].nbytes == 1 << 20


def test_npz_reading_checks(tmp_path):
    path = write_zip(tmp_path / "x.npz", [npy_member("a", np.arange(6.0).reshape(2, 3)),
                                          npy_member("f", np.asfortranarray(np.arange(6).reshape(2, 3))),
                                          npy_member("o", np.array([{"k": 1}], dtype=object)),
                                          liar_member("big", "<f8", (10**6,))])
    data = unpickle.load_npz(path, keys=["a", "f", "o", "absent"])
    assert data["a"].tolist() == [[0, 1, 2], [3, 4, 5]] and data["f"].tolist() == [[0, 1, 2], [3, 4, 5]]
    assert data["o"][0] == {"k": 1} and set(data) == {"a", "f", "o"}
    with pytest.raises(InputError, match=r"member 'o' is an object array: cannot read without pickle"):
        unpickle.load_npz(path, keys=["o"], objects=False)
    with pytest.raises(InputError, match=r"x\.npz \['big'\]: corrupt or truncated array"):
        unpickle.load_npz(path)
    (tmp_path / "t.npz").write_text("just some text\n")
    with pytest.raises(InputError, match=r"t\.npz: not a valid \.npz file \(not a zip archive\)$"):
        unpickle.load_npz(tmp_path / "t.npz")
    members = [bomb_member(f"m{i}", "u1", (900 << 20,)) for i in range(3)]  # 3 x 900 MiB: each OK, 2.6 GiB in all
    with pytest.raises(InputError, match=r"members total 2\.6 GiB uncompressed \(limit 2\.0 GiB: limits\.max_file_mb\)"):
        unpickle.load_npz(write_zip(tmp_path / "many.npz", members))
    bz = npy_member("a", np.arange(3))
    with pytest.raises(InputError, match="unsupported compression method"):
        unpickle.load_npz(write_zip(tmp_path / "bz.npz", [(bz[0], bz[1], zipfile.ZIP_BZIP2, bz[3], bz[4])]))


def test_frame_reader_messages(tmp_path, runner):
    seq = tmp_path / "s"
    seq.mkdir()
    (seq / "meta.yaml").write_text("image_size: [640, 480]\n")
    (seq / "000000.npz").write_bytes(os.urandom(300))
    result = invoke(runner, "info", seq)
    assert result.exit_code == 2 and "000000.npz: not a valid .npz file" in result.stderr
    assert "allow_pickle" not in result.stderr
    write_zip(seq / "000000.npz", [npy_member("vertices", np.array([{"a": 1}], dtype=object))])
    result = invoke(runner, "info", seq)
    assert result.exit_code == 2 and "member 'vertices' is an object array: cannot read without pickle" in result.stderr
    assert "allow_pickle" not in result.stderr


def test_to_plain_is_bounded():
    assert to_plain({"a": [np.arange(3)] * 2}) == {"a": [[0, 1, 2], [0, 1, 2]]}
    with pytest.raises(InputError, match="more than 1,000 items"):
        to_plain(shared_nest(12, 2), max_items=1000)
    with pytest.raises(InputError, match="more than 1,000 items"):
        to_plain([np.zeros(600)] * 2, max_items=1000)


def test_grid_spec_validation():
    with limits.applied(SMALL):
        with pytest.raises(ValueError, match=r"calibrate\.grid\.steps \[30, 30, 30\] make 27,000 grid cells"):
            GridSpec(steps=(30, 30, 30))
        with pytest.raises(ValueError, match=r"refine method's seeding grid 12,000 cells"):
            GridSpec(steps=(1, 10, 1))
    assert GridSpec(steps=(30, 30, 30)).steps == (30, 30, 30)
