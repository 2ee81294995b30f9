"""Run one fuzz case and check every rule rotavat promises for hostile input.

Rules (issue 15; the labels are used in reports):

- ``R1 exit``: bad input of any kind exits 2 (never 1: that is a ``--fail-if`` gate's, or a failed
  ``batch`` sequence's); a clean input exits 0. ``R1 line``: a refusal is exactly ONE line on
  stderr, starting ``error:`` and naming the file or option. ``R1 traceback``: never a traceback.
  ``R1 result``: a success writes a correct result (the case's checks).
- ``R2 inputs``: no input file or folder changes (hashed before and after).
- ``R3 foreign``: nothing rotavat did not write is deleted or overwritten (sentinel files around the
  outputs, the whole case folder hashed). ``R3 stray``: nothing is created outside the declared
  outputs, and a refusal leaves nothing behind.
- ``R4 memory``: peak RSS under the bound (subprocess cases: ``wait4`` rusage of the command and
  its waited-for children, plus polling), and no attempt at a huge allocation (MemoryError).
- ``R5 payload``: no payload ran (no ``PWNED`` marker appeared).
- ``R6 procs`` / ``R6 time``: few processes at once, none left behind, finished in time.

A case runs in-process with click's ``CliRunner`` (fast) unless it measures memory or processes,
then as a real ``rotavat`` process.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from typer.testing import CliRunner

try:
    from . import corpus as C
except ImportError:  # run as a script from tests/fuzz
    import corpus as C  # type: ignore[no-redef]
from _cli import invoke  # noqa: E402 (tests/ is on sys.path once corpus is imported)

KILL_FACTOR = 1.1  # a case's command is killed at 1.1x its RSS bound: past the bound is a violation already
KILL_RSS_MB = 1100.0  # run_subprocess's default kill threshold (direct calls)
LEFTOVER_GRACE_S = 3.0  # processes of a finished command still alive after this are a violation
ADDRESS_SPACE_LIMIT = 8 << 30  # RLIMIT_AS of subprocess runs: a runaway allocation fails instead of swapping


@dataclass
class RunRecord:
    """What one run did, and which rules it broke."""

    case_id: str
    cls: str
    command: str
    expect: str
    mode: str
    exit_code: int | None = None
    stderr: str = ""
    stdout_tail: str = ""
    seconds: float = 0.0
    peak_rss_mb: float | None = None
    max_procs: int | None = None
    violations: list[tuple[str, str]] = field(default_factory=list)
    note: str = ""

    @property
    def ok(self) -> bool:
        return not self.violations

    def stderr_head(self, n: int = 3) -> list[str]:
        return [line[:300] for line in self.stderr.splitlines() if line.strip()][:n]

    def describe(self) -> str:
        lines = [f"case {self.case_id} ({self.mode}, expect {self.expect})", f"  $ {self.command}",
                 f"  exit {self.exit_code}, {self.seconds:.2f} s"
                 + (f", peak RSS {self.peak_rss_mb:.0f} MB" if self.peak_rss_mb is not None else "")
                 + (f", max processes {self.max_procs}" if self.max_procs is not None else "")]
        lines += [f"  stderr| {line}" for line in self.stderr_head()]
        lines += [f"  VIOLATION {rule}: {detail}" for rule, detail in self.violations]
        if self.note:
            lines.append(f"  note: {self.note}")
        return "\n".join(lines)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["stderr_head"] = self.stderr_head()
        d.pop("stderr")
        return d


# ---- the case folder -------------------------------------------------------------------------------
SENTINELS = {
    "FOREIGN.txt": b"a file rotavat did not write\n",
    "foreign/keep.txt": b"a folder rotavat did not write\n",
    "foreign/sub/keep.csv": b"frame,person_id\n0,0\n",
}


def _write(path: Path, content: Any, root: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if callable(content):
        content = content(root)
    if isinstance(content, str):
        content = content.encode()
    path.write_bytes(content)


def prepare(case: C.Case, root: Path) -> None:
    """Write the case's files, folders, links and pipes, plus sentinels next to every output."""
    root.mkdir(parents=True, exist_ok=True)
    for rel, content in case.resolve_files().items():
        _write(root / rel, content, root)
    for rel in case.dirs:
        (root / rel).mkdir(parents=True, exist_ok=True)
    for rel, target in case.symlinks.items():
        link = root / rel
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(target.replace("{root}", str(root)))
    for rel in case.fifos:
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        os.mkfifo(root / rel)
    for rel, content in SENTINELS.items():
        if not (root / rel).exists():
            _write(root / rel, content, root)
    for out in case.outputs:  # a foreign file beside each output, and one in its parent's parent
        parent = (root / out).parent
        for folder in (parent, parent.parent):
            if folder == root.parent or root not in [folder, *folder.parents]:
                continue
            sentinel = folder / "SENTINEL-beside-output.txt"
            if folder.exists() and not sentinel.exists():
                sentinel.write_bytes(b"not rotavat's\n")


def snapshot(root: Path) -> dict[str, tuple]:
    """Every path under ``root`` (links not followed): kind, mode and content hash."""
    snap: dict[str, tuple] = {}
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in dirnames + filenames:
            path = Path(dirpath, name)
            rel = str(path.relative_to(root))
            try:
                st = path.lstat()
            except FileNotFoundError:
                continue
            mode = stat.S_IMODE(st.st_mode)
            if stat.S_ISLNK(st.st_mode):
                snap[rel] = ("link", os.readlink(path))
            elif stat.S_ISDIR(st.st_mode):
                snap[rel] = ("dir", mode)
            elif stat.S_ISREG(st.st_mode):
                h = hashlib.sha256()
                with open(path, "rb") as handle:
                    for chunk in iter(lambda: handle.read(1 << 20), b""):
                        h.update(chunk)
                snap[rel] = ("file", mode, h.hexdigest())
            else:
                snap[rel] = ("special", stat.S_IFMT(st.st_mode), mode)
    return snap


def _under(rel: str, prefixes: list[str]) -> bool:
    rel_p = Path(rel)
    for prefix in prefixes:
        p = Path(os.path.normpath(prefix))
        if rel_p == p or p in rel_p.parents:
            return True
    return False


# ---- running ------------------------------------------------------------------------------------
class CaseTimeout(BaseException):
    """Raised in the main thread when an in-process run exceeds its time (BaseException: the CLI
    runner must not swallow it)."""


@contextlib.contextmanager
def _alarm(seconds: float):
    if seconds <= 0 or not hasattr(signal, "setitimer"):
        yield
        return

    def fire(signum, frame):
        raise CaseTimeout()

    old = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def _cwd(path: Path):
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def run_inprocess(args: list[str], cwd: Path, timeout: float) -> dict:
    """The CLI in this process (click's CliRunner): exit code, stdout, stderr, traceback."""
    t0 = time.monotonic()
    tb, timed_out = "", False
    with _cwd(cwd), warnings.catch_warnings():
        # print warnings to (the captured) stderr, as a real run does, even under pytest's recorder
        warnings.resetwarnings()
        warnings.simplefilter("default")
        warnings.showwarning = _show_on_stderr
        try:
            with _alarm(timeout):
                result = invoke(CliRunner(), *args, catch_exceptions=True)
        except CaseTimeout:
            return {"exit_code": None, "stdout": "", "stderr": "", "traceback": "", "timed_out": True,
                    "seconds": time.monotonic() - t0}
    exc = result.exception
    if exc is not None and not isinstance(exc, SystemExit):
        tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return {"exit_code": result.exit_code, "stdout": result.stdout, "stderr": result.stderr, "traceback": tb,
            "timed_out": timed_out, "seconds": time.monotonic() - t0}


def _show_on_stderr(message, category, filename, lineno, file=None, line=None) -> None:
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def rotavat_command() -> list[str]:
    exe = Path(sys.executable).with_name("rotavat")
    if exe.exists():
        return [str(exe)]
    return [sys.executable, "-c", "import sys; sys.argv[0] = 'rotavat'; from rotavat_cli.cli import main; main()"]


# A small process between the harness and the command. A forked child's ru_maxrss starts at its
# parent's RSS (Linux keeps the old mm's high-water mark across exec), so forking rotavat straight
# from a large pytest process would report pytest's size; forked from this ~10 MB trampoline, the
# command's own peak (with its waited-for workers) comes back through a pipe.
_TRAMPOLINE = r"""
import os, resource, signal, sys
fd, limit, cmd = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:]
try:
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
except (ValueError, OSError):
    pass
pid = os.fork()
if pid == 0:
    os.close(fd)
    try:
        os.execv(cmd[0], cmd)
    finally:
        os._exit(127)
while True:
    try:
        _, status, usage = os.wait4(pid, 0)
        break
    except InterruptedError:
        continue
os.write(fd, str(usage.ru_maxrss).encode())
os.close(fd)
code = os.waitstatus_to_exitcode(status)
if code < 0:
    signal.signal(-code, signal.SIG_DFL)
    os.kill(os.getpid(), -code)
os._exit(code)
"""


def _tree(pid: int) -> list[Any]:
    try:
        import psutil
    except ImportError:  # pragma: no cover
        return []
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.Error:
        return []


def _rss_mb(procs: list[Any]) -> float:
    best = 0.0
    for p in procs:
        with contextlib.suppress(Exception):
            best = max(best, p.memory_info().rss / 2**20)
    return best


def run_subprocess(args: list[str], cwd: Path, timeout: float, kill_rss_mb: float = KILL_RSS_MB) -> dict:
    """A real ``rotavat`` process: exit, output, peak RSS (its wait4 rusage, through the trampoline, and
    polling), processes at once (the command and its descendants)."""
    try:
        import psutil
    except ImportError:  # pragma: no cover
        psutil = None
    env = dict(os.environ)
    env.pop("FORCE_COLOR", None)
    read_fd, write_fd = os.pipe()
    with tempfile.TemporaryFile() as out_f, tempfile.TemporaryFile() as err_f:
        t0 = time.monotonic()
        command = [sys.executable, "-S", "-c", _TRAMPOLINE, str(write_fd), str(ADDRESS_SPACE_LIMIT),
                   *rotavat_command(), *args]
        proc = subprocess.Popen(command, cwd=cwd, stdout=out_f, stderr=err_f, stdin=subprocess.DEVNULL,
                                pass_fds=(write_fd,), start_new_session=True, env=env)
        os.close(write_fd)
        killed, max_procs, polled_rss = None, 0, 0.0
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            procs = _tree(proc.pid) if psutil is not None else []  # the command and its workers
            max_procs = max(max_procs, len(procs))
            polled_rss = max(polled_rss, _rss_mb(procs))
            elapsed = time.monotonic() - t0
            if killed is None and polled_rss > kill_rss_mb:
                killed = f"killed by the harness at {polled_rss:.0f} MB RSS"
            elif killed is None and elapsed > timeout:
                killed = f"killed by the harness after {timeout:.0f} s"
            if killed:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(proc.pid, signal.SIGKILL)
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.02)
        seconds = time.monotonic() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        leftover = []
        deadline = time.monotonic() + LEFTOVER_GRACE_S  # workers may take a moment to exit on their own
        while _group_alive(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        if _group_alive(proc.pid):
            leftover = [f"processes of the command still running {LEFTOVER_GRACE_S:.0f} s after it exited"]
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(proc.pid, signal.SIGKILL)
        out_f.seek(0)
        err_f.seek(0)
        stdout = out_f.read().decode("utf-8", "replace")
        stderr = err_f.read().decode("utf-8", "replace")
    os.set_blocking(read_fd, False)
    try:
        reported = os.read(read_fd, 64)
    except BlockingIOError:
        reported = b""
    finally:
        os.close(read_fd)
    maxrss_mb = int(reported) / 1024.0 if reported.strip().isdigit() else 0.0  # none when killed
    return {"exit_code": proc.returncode, "stdout": stdout, "stderr": stderr, "traceback": "",
            "timed_out": bool(killed and "after" in killed), "killed": killed, "seconds": seconds,
            "peak_rss_mb": max(maxrss_mb, polled_rss), "max_procs": max_procs, "leftover": leftover}


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
        return True
    except (ProcessLookupError, PermissionError):
        return False


# ---- the rules --------------------------------------------------------------------------------------
_MEMORY_WORDS = ("MemoryError", "Unable to allocate", "Cannot allocate memory", "ArrayMemoryError", "out of memory")


def evaluate(case: C.Case, root: Path, run: dict, before: dict, after: dict) -> list[tuple[str, str]]:
    """Every rule broken by this run."""
    v: list[tuple[str, str]] = []
    code = run.get("exit_code")
    stderr = run.get("stderr") or ""
    tb = run.get("traceback") or ""
    if "Traceback (most recent call last)" in stderr and not tb:
        tb = stderr[stderr.index("Traceback"):]
    if run.get("timed_out"):
        v.append(("R6 time", f"no result within {case.timeout_s:.0f} s (killed)"))
    elif run.get("killed"):
        v.append(("R4 memory", f"peak RSS over {case.max_rss_mb:.0f} MB ({run['killed']})"))
    if tb:
        last = [line for line in tb.strip().splitlines() if line.strip()][-1]
        v.append(("R1 traceback", last[:240]))
    if any(word in stderr or word in tb for word in _MEMORY_WORDS):
        v.append(("R4 memory", "tried a huge allocation: " + next(
            line for line in (stderr + "\n" + tb).splitlines() if any(w in line for w in _MEMORY_WORDS))[:200]))
    if not run.get("timed_out") and not run.get("killed"):
        expect = case.expect
        if expect == "ok" and code != 0:
            v.append(("R1 exit", f"a clean input gave exit {code} (expected 0)"))
        elif expect == "refuse" and code != 2:
            v.append(("R1 exit", {0: "bad input accepted (exit 0, expected 2)",
                                  1: "exit 1 for bad input (1 is only a --fail-if gate's)"}.get(
                                      code, f"exit {code} (expected 2)")))
        elif expect == "either" and code not in (0, 2):
            v.append(("R1 exit", f"exit {code} (expected 0 with a correct result, or 2 with one error line)"))
        elif expect == "gate" and code != 1:
            v.append(("R1 exit", f"a tripped --fail-if gate gave exit {code} (expected 1)"))
        if code == 2:
            lines = [line for line in stderr.splitlines() if line.strip()]
            if len(lines) != 1 or not lines[0].startswith("error:"):
                v.append(("R1 line", f"refusal wrote {len(lines)} stderr lines"
                          + ("" if lines and lines[0].startswith("error:") else " not starting 'error:'")))
            elif case.names and not any(n in lines[0] for n in case.names):
                v.append(("R1 line", f"the error does not name {' or '.join(repr(n) for n in case.names)}"))
        if code == 0 and expect in ("ok", "either"):
            for check in case.checks:
                try:
                    problems = check(root, run)
                except Exception as exc:  # noqa: BLE001
                    problems = [f"result check failed: {type(exc).__name__}: {exc}"]
                v += [("R1 result", p) for p in problems]
    # files: inputs, foreign files, strays, payload
    allowed = case.outputs if (code == 0 or (code == 1 and case.expect == "gate")) else []
    inputs = case.inputs
    created, changed, deleted = [], [], []
    for rel in sorted(set(before) | set(after)):
        if _under(rel, allowed):
            continue
        if rel not in before:
            created.append(rel)
        elif rel not in after:
            deleted.append(rel)
        elif before[rel] != after[rel]:
            changed.append(rel)
    payload = [r for r in created if Path(r).name.startswith(C.MARKER)]
    if payload:
        v.append(("R5 payload", f"the payload ran: {payload[0]} was created"))
    created = [r for r in created if r not in payload]
    for kind, rels in (("deleted", deleted), ("modified", changed)):
        in_inputs = [r for r in rels if _under(r, inputs)]
        foreign = [r for r in rels if not _under(r, inputs)]
        if in_inputs:
            v.append(("R2 inputs", f"{len(in_inputs)} input paths {kind}: {_few(in_inputs)}"))
        if foreign:
            v.append(("R3 foreign", f"{len(foreign)} foreign paths {kind}: {_few(foreign)}"))
    created = _top_level(created)
    if created:
        where = "a refusal left" if code != 0 else "wrote outside its outputs:"
        v.append(("R3 stray", f"{where} {len(created)} new paths: {_few(created)}"))
    # measured limits
    if run.get("peak_rss_mb") is not None and run["peak_rss_mb"] > case.max_rss_mb and not run.get("killed"):
        v.append(("R4 memory", f"peak RSS {run['peak_rss_mb']:.0f} MB > {case.max_rss_mb:.0f} MB"))
    if case.max_children is not None and run.get("max_procs") is not None and run["max_procs"] - 1 > case.max_children:
        # max_procs counts the command itself and every descendant alive at once
        v.append(("R6 procs", f"{run['max_procs'] - 1} child processes at once (cap {case.max_children})"))
    if run.get("leftover"):
        v.append(("R6 procs", run["leftover"][0]))
    if case.max_seconds is not None and run.get("seconds", 0) > case.max_seconds and not run.get("timed_out"):
        v.append(("R6 time", f"took {run['seconds']:.1f} s (limit {case.max_seconds:.0f} s)"))
    return v


def _few(rels: list[str], n: int = 3) -> str:
    return ", ".join(rels[:n]) + (f", ... (+{len(rels) - n})" if len(rels) > n else "")


def _top_level(rels: list[str]) -> list[str]:
    """Drop paths inside another listed path (a new folder counts once)."""
    chosen: list[str] = []
    for rel in sorted(rels, key=lambda r: (r.count(os.sep), r)):
        if not any(Path(c) in Path(rel).parents for c in chosen):
            chosen.append(rel)
    return chosen


def _unlock(root: Path) -> None:
    for dirpath, dirnames, _ in os.walk(root, followlinks=False):
        for name in dirnames:
            with contextlib.suppress(OSError):
                p = Path(dirpath, name)
                if not p.is_symlink():
                    p.chmod(0o755)


def run_case(case: C.Case, root: Path, subprocess_mode: bool | None = None) -> RunRecord:
    """Prepare ``case`` in the empty folder ``root``, run it, check every rule."""
    use_sub = case.subprocess if subprocess_mode is None else subprocess_mode
    rec = RunRecord(case.id, case.cls, case.command(), case.expect, "subprocess" if use_sub else "in-process",
                    note=case.note)
    prepare(case, root)
    cwd = root / case.cwd
    for pre in case.pre:
        res = run_inprocess(pre, cwd, 60)
        if res["exit_code"] != 0:
            rec.violations.append(("R1 exit", f"setup command 'rotavat {' '.join(pre)}' gave exit "
                                   f"{res['exit_code']}: {(res['stderr'] or res['traceback']).strip()[:200]}"))
            return rec
    for rel in case.readonly:
        (root / rel).chmod(0o555)
    before = snapshot(root)
    try:
        run = (run_subprocess(case.args, cwd, case.timeout_s, KILL_FACTOR * case.max_rss_mb) if use_sub
               else run_inprocess(case.args, cwd, case.timeout_s))
        after = snapshot(root)
    finally:
        _unlock(root)
    rec.exit_code = run.get("exit_code")
    rec.stderr = (run.get("stderr") or "") + (("\n" + run["traceback"]) if run.get("traceback") else "")
    rec.stdout_tail = (run.get("stdout") or "")[-300:]
    rec.seconds = run.get("seconds", 0.0)
    rec.peak_rss_mb = run.get("peak_rss_mb")
    rec.max_procs = run.get("max_procs")
    rec.violations += evaluate(case, root, run, before, after)
    return rec


def run_case_in_tmp(case: C.Case, subprocess_mode: bool | None = None) -> RunRecord:
    """``run_case`` in a fresh temporary folder, removed afterwards."""
    tmp = Path(tempfile.mkdtemp(prefix="rotavat-fuzz-"))
    try:
        return run_case(case, tmp / "case", subprocess_mode)
    finally:
        _unlock(tmp)
        shutil.rmtree(tmp, ignore_errors=True)
