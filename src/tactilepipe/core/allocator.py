"""Keep freed memory in the process for reuse, so training steps do not page-fault their tensors in.

glibc's malloc hands a block of 128 KiB or more straight to the kernel with ``mmap`` and gives it
back with ``munmap`` when freed (its threshold rises with use, but the heap top is trimmed too).
A training step frees and allocates the same few hundred tensors of 0.1–10 MB every time, so each
step faults every page of them in again: the kernel zeroes each 4 KiB page first. Measured on a
default-scale training step (width 32, one thread): about 4,300 page faults a step, and a 2.4 MB
``zeros_like`` taking 1.5 ms instead of a memset's 0.2 ms. Raising the mmap threshold to glibc's
maximum (32 MiB) and the trim threshold above any heap the tool models reach keeps those blocks
in the heap between steps: a fifth of the page faults, and the same bytes (only where memory
comes from changes, never what is computed). benchmarks/record.md, "Memory in a training step", has the measurements.
"""

from __future__ import annotations

import ctypes
import ctypes.util

# mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 << 20        # glibc's largest accepted value (HEAP_MAX_SIZE / 2 on 64-bit)
TRIM_THRESHOLD = 1 << 30


def keep_freed_memory() -> bool:
    """Tune glibc's malloc as described above; False where the C library is not glibc (nothing is
    changed there, and nothing else depends on it)."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
