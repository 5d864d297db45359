"""Keep freed memory in the process for the next array (glibc only): a speed setting, never a number.

The texture steps allocate and free many arrays the size of a scan (2048 x 2448 float64 = 40 MB). With glibc's
defaults most of them are fresh memory maps: every one is page-faulted in (and zeroed by the kernel) on first
touch and unmapped when freed. On the texture stage of one LS-40 scan that was 2-4 s of system time of about
10 s of CPU (measured 2026-11-28, benchmarks/bench_texture.py). :func:`retain_freed_memory` asks glibc to serve
arrays up to 32 MB from its heap (the largest mmap threshold it accepts), to grow the heap in 512 MB steps of
address space (only touched pages count) and never to give freed heap back: later arrays reuse pages that are
already mapped. Peak RSS stays that of the largest working set (measured +2 %). Call it once at the start of
a process that does texture work (the workflow's texture scripts do); elsewhere (not glibc) it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util

_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3


def retain_freed_memory() -> bool:
    """Set glibc's malloc to keep and reuse freed memory (see the module docstring); True when it was set."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    ok = mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)
    ok &= mallopt(_M_TOP_PAD, 512 << 20)
    ok &= mallopt(_M_MMAP_THRESHOLD, 32 << 20)
    return bool(ok)
