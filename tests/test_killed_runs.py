"""What a killed run leaves behind (issue 24, point 8): staging folders and temporary files whose
writer was SIGKILLed are removed by the next write of the same output, even while the dead writer
is a zombie nobody has reaped (its pid still answers ``kill(pid, 0)``); a live writer's are never
touched; worker processes exit when the process that started them is killed.

Every child here is a real process killed with SIGKILL (those tests are marked ``slow``: ``make
test-slow``); nothing waits on a fixed delay: states are polled with generous timeouts (the tests must
hold on a loaded 2-core machine).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rotavat_cli.files.atomic import atomic_open, atomic_write_text, staged_directory
from rotavat_cli.files.outputs import STAGING_OWNER

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads process states from /proc")

_STAGING_CHILD = """
import sys, time
from rotavat_cli.files.atomic import staged_directory
with staged_directory(sys.argv[1], "test") as stage:
    (stage / "half.txt").write_text("half")
    print(stage, flush=True)
    time.sleep(120)
"""

_WRITER_CHILD = """
import sys, time
from rotavat_cli.files.atomic import atomic_open
with atomic_open(sys.argv[1], "w") as handle:
    handle.write("half")
    handle.flush()
    print("writing", flush=True)
    time.sleep(120)
"""


def _state(pid: int) -> str:
    """The one-letter state of process ``pid`` ('Z' zombie, 'R', 'S', ...), '' once it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return ""
    return stat.rsplit(")", 1)[1].split()[0]


def _poll(condition, timeout_s: float = 30.0, what: str = "") -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def _start(code: str, *args: str) -> tuple[subprocess.Popen, str]:
    """A Python child running ``code``; its first line of output (it says when it is ready)."""
    child = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE, text=True)
    line = child.stdout.readline().strip()
    assert line, "the child ended before it was ready"
    return child, line


def _dead_unreaped(pid: int) -> bool:
    """A zombie whose every thread has ended (numpy's BLAS threads outlive the main one by a moment,
    and the open files, their locks with them, go with the last thread)."""
    try:
        return _state(pid) == "Z" and os.listdir(f"/proc/{pid}/task") == [str(pid)]
    except FileNotFoundError:
        return False


def _kill_unreaped(child: subprocess.Popen) -> None:
    """SIGKILL ``child`` and wait until it is a zombie: dead, but not reaped, so its pid still answers."""
    os.kill(child.pid, signal.SIGKILL)
    _poll(lambda: _dead_unreaped(child.pid), what="the killed child to become a zombie")
    os.kill(child.pid, 0)  # a zombie still answers kill(pid, 0): a pid check would call it alive


@pytest.mark.slow
def test_staging_of_a_killed_unreaped_run_is_removed_by_the_next_run(tmp_path):
    out = tmp_path / "aligned"
    child, stage = _start(_STAGING_CHILD, str(out))
    stage = Path(stage)
    try:
        assert (stage / STAGING_OWNER).is_file() and (stage / "half.txt").is_file()
        _kill_unreaped(child)
        with staged_directory(out, "test") as new:
            (new / "done.txt").write_text("whole")
        assert not stage.exists(), "the dead run's staging folder is still there"
        assert (out / "done.txt").read_text() == "whole"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["aligned"]
    finally:
        child.kill()
        child.wait()


@pytest.mark.slow
def test_staging_of_a_live_run_is_kept(tmp_path):
    out = tmp_path / "aligned"
    child, stage = _start(_STAGING_CHILD, str(out))
    try:
        with staged_directory(out, "test") as new:
            (new / "done.txt").write_text("whole")
        assert Path(stage, "half.txt").is_file(), "a live run's staging folder was removed"
    finally:
        child.kill()
        child.wait()


@pytest.mark.slow
def test_temporary_of_a_killed_writer_is_removed_by_the_next_write_of_that_file(tmp_path):
    """calibrate's SEQ/camera.yaml: a SIGKILL during its atomic write left '.camera.yaml.*.tmp' in SEQ."""
    seq = tmp_path / "seq"
    seq.mkdir()
    target = seq / "camera.yaml"
    (seq / ".camera.yaml.notes.tmp").write_text("someone's file")  # not rotavat's temporary: never removed
    (seq / ".meta.yaml.rotavat-abcdefgh.tmp").write_text("x")  # a temporary of another file: not this write's
    dead, _ = _start(_WRITER_CHILD, str(target))
    try:
        _kill_unreaped(dead)
        left = [p for p in seq.glob(".camera.yaml.*.tmp") if p.name != ".camera.yaml.notes.tmp"]
        assert len(left) == 1 and left[0].read_text() == "half"
        live, _ = _start(_WRITER_CHILD, str(target))  # a writer still at work: its temporary stays
        try:
            live_tmp = [p for p in seq.glob(".camera.yaml.*.tmp") if p not in left and "notes" not in p.name]
            atomic_write_text(target, "# written by rotavat\nnew\n")
            assert not left[0].exists(), "the killed writer's temporary is still there"
            assert len(live_tmp) == 1 and live_tmp[0].read_text() == "half", "a live writer's temporary was removed"
        finally:
            live.kill()
            live.wait()
        assert target.read_text().endswith("new\n")
        assert (seq / ".camera.yaml.notes.tmp").read_text() == "someone's file"
        assert (seq / ".meta.yaml.rotavat-abcdefgh.tmp").exists()
    finally:
        dead.kill()
        dead.wait()


def test_files_written_inside_a_staging_folder_and_beside_it(tmp_path):
    """Temporaries are renamed over their target and leave nothing behind, in a staging folder or not."""
    with staged_directory(tmp_path / "out", "test") as stage:
        for i in range(3):
            with atomic_open(stage / f"{i}.txt", "w") as handle:
                handle.write(str(i))
    atomic_write_text(tmp_path / "x.yaml", "x\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "x.yaml"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [".rotavat-output", "0.txt", "1.txt", "2.txt"]


# ---- worker processes die with their parent ------------------------------------------------------
def _children(pid: int) -> list[int]:
    """Live processes whose parent is ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            fields = stat.rsplit(")", 1)[1].split()
            if int(fields[1]) == pid and fields[0] not in "ZX":
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    return _state(pid) not in ("", "Z", "X")


def _assert_workers_die_with_their_parent(args: list[str], n_workers: int, cwd: Path | None = None) -> None:
    parent = subprocess.Popen(args, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        workers: list[int] = []
        while len(workers) < n_workers:
            assert parent.poll() is None, f"the run ended before its workers were seen: {parent.stderr.read()}"
            assert time.monotonic() < deadline, "the workers never started"
            time.sleep(0.05)
            workers = _children(parent.pid)
        time.sleep(0.3)  # every worker started (a pool may also start a helper process: it must go too)
        workers = sorted(set(workers) | set(_children(parent.pid)))
        os.kill(parent.pid, signal.SIGKILL)  # as the OOM killer would
        parent.wait()
        deadline = time.monotonic() + 10
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        survivors = [w for w in workers if _alive(w)]
        assert not survivors, f"workers {survivors} outlived their killed parent"
    finally:
        for w in _children(parent.pid) + (workers if "workers" in locals() else []):
            if _alive(w):
                os.kill(w, signal.SIGKILL)
        if parent.poll() is None:
            parent.kill()
            parent.wait()


# align's frames are slowed down (so the run is mid-way when killed) by patching the per-chunk function
# before the CLI starts: the forked workers inherit the patch.
_SLOW_ALIGN = """
import sys, time
import rotavat_cli.alignment.align as A
_real = A._align_chunk
def slow_chunk(task):
    time.sleep(2.0)  # 10 chunks on 2 workers: the pool lives 10 s, the test kills it as soon as it is seen
    return _real(task)
A._align_chunk = slow_chunk
from rotavat_cli.cli import main
sys.argv = ["rotavat", *sys.argv[1:]]
main()
"""


@pytest.mark.slow
def test_align_workers_exit_when_align_is_killed(tmp_path):
    from rotavat_cli.synth import SynthOptions, write_synth_scene

    write_synth_scene(tmp_path / "s", SynthOptions(seed=3, frames=80, people=2))
    _assert_workers_die_with_their_parent(
        [sys.executable, "-c", _SLOW_ALIGN, "align", str(tmp_path / "s" / "pred"), "--camera",
         str(tmp_path / "s" / "gt" / "camera.yaml"), "--out", str(tmp_path / "al"), "--jobs", "2", "-q"], 2)


_POOL = """
import time
from rotavat_cli.batch.executors import _PoolExecutor
pool = _PoolExecutor(2)
futures = [pool.submit(time.sleep, 60) for _ in range(2)]
time.sleep(120)
"""


@pytest.mark.slow
def test_batch_pool_workers_exit_when_the_driver_is_killed(tmp_path):
    _assert_workers_die_with_their_parent([sys.executable, "-c", _POOL], 2)
