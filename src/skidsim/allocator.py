"""Memory settings of a process that works on whole scans: speed settings, never a number.

The scan steps (synthetic sites, the campaign check, despeckle, bands, MPD, texture parameters, reconstruction,
figures, predictions from scans) allocate and free many arrays the size of a scan (2048 x 2448 float64 = 40 MB).
Two defaults make each new array cost system time:

* glibc serves every array above its mmap threshold (128 kB, rising to at most 32 MB as maps are freed) from a
  fresh memory map: each page is faulted in and zeroed by the kernel on first touch, and the map is returned when
  the array is freed, so the next array pays again. :func:`retain_freed_memory` asks glibc to serve every
  allocation from its heap, of any size (``M_MMAP_MAX`` 0; the 32 MB that ``M_MMAP_THRESHOLD`` accepts at most is
  below a 40 MB scan array, so the threshold alone left those mapped), to grow the heap in 512 MB steps of address
  space (``M_TOP_PAD``; only touched pages count) and never to give freed heap back (``M_TRIM_THRESHOLD``): later
  arrays reuse pages that are already mapped. Where the heap cannot grow, glibc still falls back to a map.
* NumPy advises the kernel to back every array of 4 MB or more with transparent huge pages
  (``madvise(MADV_HUGEPAGE)``). Where the kernel's huge pages are ``madvise`` with defrag ``madvise`` (the
  development host: ``/sys/kernel/mm/transparent_hugepage``), each huge-page fault may compact memory first;
  there the generation of one synthetic site spent 2.0-2.5 s of system time on 22,000 faults with the advice and
  0.24-0.28 s on 95,000 small-page faults without it (3 runs each, 2026-12-04, on top of commit c0f6da3; the
  workflow's jobs both ways: benchmarks/bench_allocator.py, docs/performance.md).
  :func:`no_hugepage_advice` turns the advice off for arrays allocated afterwards (NumPy's
  ``NUMPY_MADVISE_HUGEPAGE=0``, which NumPy reads only at import); an explicit ``NUMPY_MADVISE_HUGEPAGE`` in the
  environment is left to decide.

:func:`scan_process_memory` makes both settings; the workflow's scan scripts call it first. In isolation their jobs
take 1.23-1.37x less CPU with them (four runs); a whole default run did not show it (the scan stages 507 against
505 CPU s on another day's host), and the texture stage's peak RSS was 974 MB against 923-933 MB
(docs/performance.md). The arithmetic is the same (an array's values never depend on where it lives;
tests/test_allocator.py). With the environment variable ``SKIDSIM_MALLOC=default`` (benchmarks/bench_allocator.py's
side-by-side runs) nothing is set; elsewhere than glibc on Linux only NumPy's advice is.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

#: mallopt parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD, _M_MMAP_MAX = -1, -2, -3, -4


def _switched_off() -> bool:
    return os.environ.get("SKIDSIM_MALLOC", "") == "default"


def retain_freed_memory() -> bool:
    """Set glibc's malloc to serve every array from its heap and keep freed memory for reuse (module docstring);
    True when it was set."""
    if _switched_off():
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    ok = mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)
    ok &= mallopt(_M_TOP_PAD, 512 << 20)
    ok &= mallopt(_M_MMAP_THRESHOLD, 32 << 20)
    ok &= mallopt(_M_MMAP_MAX, 0)
    return bool(ok)


def no_hugepage_advice() -> bool:
    """Turn off NumPy's transparent-huge-page advice for the arrays allocated from now on (module docstring);
    True when it was turned off (False: ``NUMPY_MADVISE_HUGEPAGE`` set in the environment, switched off, or a
    NumPy without the switch)."""
    if _switched_off() or "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        return False
    try:
        from numpy._core.multiarray import _set_madvise_hugepage
    except ImportError:
        return False
    _set_madvise_hugepage(False)
    return True


def scan_process_memory() -> dict[str, bool]:
    """Both settings of the module docstring; which were made (``{"heap": ..., "no_hugepage_advice": ...}``)."""
    return {"heap": retain_freed_memory(), "no_hugepage_advice": no_hugepage_advice()}
