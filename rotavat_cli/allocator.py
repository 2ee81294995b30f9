"""How this process's memory allocator treats the arrays rotavat frees: kept for the next frame.

rotavat streams frames of a few MB each and frees every one of them before the next. With glibc's
defaults, an array above 128 KB is its own ``mmap`` and the free memory on top of the heap is given
back to the kernel as soon as a little of it gathers; the next frame's arrays then fault their pages
in again, one 4 KB page at a time. Aligning 300 frames of 10 SMPL meshes took 130,000 such page
faults, a quarter of the command's time in the kernel (docs/performance.md). Kept, the same memory is
reused: the faults drop to a few hundred.

The limits bound what is kept: an array of :data:`HEAP_ARRAYS_UP_TO_BYTES` or more is still mapped
on its own, and free memory above :data:`RETURN_ABOVE_BYTES` still goes back to the kernel, so
memory stays flat over a sequence of any length. Outside glibc (macOS, musl) nothing changes.
"""

from __future__ import annotations

import ctypes

HEAP_ARRAYS_UP_TO_BYTES = 32 << 20  # glibc's largest allowed M_MMAP_THRESHOLD on 64-bit
RETURN_ABOVE_BYTES = 64 << 20  # M_TRIM_THRESHOLD: free memory kept on top of the heap

_M_TRIM_THRESHOLD = -1  # glibc's mallopt parameter numbers (malloc.h)
_M_MMAP_THRESHOLD = -3


def keep_freed_memory() -> bool:
    """Have glibc's malloc keep freed frames' memory for reuse (see the module); True when it took.

    Process-wide and inherited by forked workers; idempotent. A no-op returning False where the C
    library has no ``mallopt`` or refuses the values.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, HEAP_ARRAYS_UP_TO_BYTES)) and bool(mallopt(_M_TRIM_THRESHOLD, RETURN_ABOVE_BYTES))
