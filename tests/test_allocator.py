"""rotavat_cli.allocator: freed frames' memory is reused instead of faulted in again page by page."""

from __future__ import annotations

import platform
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Frames of a few arrays of 0.5-3.2 MB, all freed before the next frame: align's pattern.
_FRAMES = """
import resource, sys
import numpy as np
from rotavat_cli.allocator import keep_freed_memory
if sys.argv[1] == "cli":
    import rotavat_cli.cli
print(keep_freed_memory() if sys.argv[1] == "keep" else sys.argv[1])
def frames(n):
    for _ in range(n):
        held = [np.ones(size) for size in (100_000, 200_000, 60_000, 60_000, 400_000, 60_000)]
        del held
frames(3)
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
frames(20)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""

glibc = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")


def _page_faults(mode: str) -> tuple[str, int]:
    out = subprocess.run([sys.executable, "-c", _FRAMES, mode], cwd=ROOT, check=True, capture_output=True,
                         text=True).stdout.split()
    return out[0], int(out[1])


@glibc
def test_kept_memory_is_reused_without_page_faults():
    took, kept = _page_faults("keep")
    _, default = _page_faults("default")
    assert took == "True"
    assert kept * 10 < default, (kept, default)  # measured: 0 against 33,720


@glibc
def test_the_command_line_keeps_freed_memory():
    took, faults = _page_faults("cli")  # importing the command line alone sets it
    _, default = _page_faults("default")
    assert faults * 10 < default, (faults, default)
