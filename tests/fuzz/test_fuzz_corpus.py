"""The fixed fuzz corpus (issue 15): every hostile-input class, every rule (see harness.py).

Run with ``make test`` (marked ``fuzz``: ``pytest -m fuzz`` selects it, ``-m "not fuzz"`` skips it; the
cases run as real processes are marked ``slow`` too: ``make test-slow``); ``make fuzz`` runs the longer randomized campaign (run_fuzz.py). Set ``ROTAVAT_FUZZ_REPORT=FILE``
to append one JSON line per case (command, exit, stderr, peak RSS, violations).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from pathlib import Path

import pytest

from . import corpus as C
from . import harness as H

pytestmark = pytest.mark.fuzz

CASES = C.all_cases()


def _report(rec: H.RunRecord) -> None:
    path = os.environ.get("ROTAVAT_FUZZ_REPORT")
    if path:
        with open(path, "a", encoding="utf-8") as handle:
            handle.write(json.dumps(rec.as_dict()) + "\n")


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id, marks=[pytest.mark.slow] if c.subprocess else [])
                                  for c in CASES])
def test_case_keeps_every_rule(case: C.Case, tmp_path: Path) -> None:
    """A case that measures memory or processes runs as a real ``rotavat`` process (marked slow)."""
    rec = H.run_case(case, tmp_path / "case")
    _report(rec)
    assert rec.ok, "\n" + rec.describe()


def test_corpus_is_deterministic_and_small(tmp_path: Path, monkeypatch) -> None:
    """Two builds of every generator give the same bytes, the second as if a day later (a zip member
    stamped with the clock differs, every time); no case writes more than 2 MB."""
    root = tmp_path / "r"
    for name, generate in C.GENERATORS.items():
        first = generate()
        with _a_day_later(monkeypatch):
            second = generate()
        assert [c.id for c in first] == [c.id for c in second], name
        for a, b in zip(first, second):
            fa = _files(a, root)
            with _a_day_later(monkeypatch):
                fb = _files(b, root)
            assert sorted(fa) == sorted(fb), a.id
            for rel in fa:
                assert fa[rel] == fb[rel], f"{a.id}: {rel} differs between two builds"
            total = sum(len(content) for content in fa.values())
            assert total < 2_000_000, f"{a.id} writes {total} bytes"


_CLOCK = time.time


@contextlib.contextmanager
def _a_day_later(monkeypatch):
    """``time.time()`` a day ahead while inside."""
    with monkeypatch.context() as later:
        later.setattr(time, "time", lambda: _CLOCK() + 86_400.0)
        yield


def _files(case: C.Case, root: Path) -> dict[str, bytes]:
    """The bytes of every file ``case`` writes."""
    return {rel: _bytes(content, root) for rel, content in case.resolve_files().items()}


def _bytes(content, root: Path) -> bytes:
    if callable(content):
        content = content(root)
    return content.encode() if isinstance(content, str) else content


def test_every_class_has_cases_and_every_case_a_rule_to_keep() -> None:
    classes = {c.cls for c in CASES}
    assert {"npz-frame", "importer", "pickle-gadget", "yaml", "paths", "obj", "degenerate", "process",
            "bomb"} <= classes
    for case in CASES:
        assert case.expect in ("ok", "refuse", "either", "gate"), case.id
        assert case.expect != "ok" or case.checks or case.args[0] == "info", f"{case.id}: an ok case checks its result"
    assert sum(c.subprocess for c in CASES) <= 22
    assert {c.id for c in CASES if c.payload} >= {c.id for c in CASES if c.cls == "pickle-gadget"}


# ---- the harness itself: it must see each kind of rule break -------------------------------------
def test_harness_sees_each_rule_break(tmp_path: Path) -> None:
    case = C.Case("self/test", "self", ["info", "seq"], {}, "refuse", inputs=["seq"], outputs=["out"], names=["x.npz"])
    before = {"seq": ("dir", 0o755), "seq/a.npz": ("file", 0o644, "1"), "FOREIGN.txt": ("file", 0o644, "2")}
    after = {"seq": ("dir", 0o755), "seq/a.npz": ("file", 0o644, "changed"), "new": ("dir", 0o755),
             "new/f": ("file", 0o644, "3"), C.MARKER: ("file", 0o644, "4")}
    run = {"exit_code": 1, "stderr": "Traceback (most recent call last):\n  x\nValueError: boom\n", "traceback": ""}
    rules = {rule for rule, _ in H.evaluate(case, tmp_path, run, before, after)}
    assert rules == {"R1 traceback", "R1 exit", "R2 inputs", "R3 foreign", "R3 stray", "R5 payload"}
    run = {"exit_code": 2, "stderr": "warning: something\nerror: seq/y.npz: bad\n", "traceback": ""}
    assert [r for r, _ in H.evaluate(case, tmp_path, run, before, before)] == ["R1 line"]
    run = {"exit_code": 2, "stderr": "error: seq/y.npz: bad\n", "traceback": ""}
    assert [r for r, _ in H.evaluate(case, tmp_path, run, before, before)] == ["R1 line"]  # names y, not x
    run = {"exit_code": 2, "stderr": "error: seq/x.npz: out of memory\n", "traceback": ""}
    assert [r for r, _ in H.evaluate(case, tmp_path, run, before, before)] == ["R4 memory"]


@pytest.mark.slow
def test_harness_measures_memory_and_processes(tmp_path: Path, monkeypatch) -> None:
    import sys

    code = ("import subprocess, sys, time; b = bytearray(300 << 20); "
            "ps = [subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(1)']) for _ in range(4)]; "
            "[p.wait() for p in ps]; sys.exit(2)")
    monkeypatch.setattr(H, "rotavat_command", lambda: [sys.executable, "-c", code])
    run = H.run_subprocess([], tmp_path, timeout=30)
    assert run["exit_code"] == 2 and run["peak_rss_mb"] >= 300 and run["max_procs"] >= 5, run
    monkeypatch.setattr(H, "rotavat_command", lambda: [sys.executable, "-c", "b = bytearray(3 << 30)"])
    run = H.run_subprocess([], tmp_path, timeout=30, kill_rss_mb=500)
    assert run["killed"] and run["exit_code"] == -9
