"""skidsim.allocator: scan-sized arrays come from glibc's heap and without NumPy's huge-page advice once the
settings are made, and no number changes.

Each check runs in a fresh interpreter (the setting is for the whole process and cannot be undone)."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux") or not Path("/proc/self/maps").is_file(), reason="glibc on Linux only"
)

#: An array above glibc's largest mmap threshold (32 MB): a 2048 x 2448 float64 scan is 40 MB.
_WHERE = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from skidsim.allocator import retain_freed_memory
    ok = retain_freed_memory() if sys.argv[1] == "1" else None
    a = np.ones(2048 * 2448)
    heap = [l for l in open("/proc/self/maps") if l.rstrip().endswith("[heap]")]
    lo, hi = (int(x, 16) for x in heap[0].split()[0].split("-")) if heap else (0, 0)
    print(json.dumps({"set": ok, "on_heap": lo <= a.ctypes.data < hi}))
    """
)


def _run(code: str, *args: str, env: dict | None = None) -> dict:
    environ = {k: v for k, v in os.environ.items() if k != "SKIDSIM_MALLOC"} | (env or {})
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, check=True, env=environ)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_scan_sized_array_lives_on_the_heap_only_with_the_setting():
    default = _run(_WHERE, "0")
    retained = _run(_WHERE, "1")
    if not retained["set"]:
        pytest.skip("mallopt not available (not glibc)")
    assert default["on_heap"] is False  # glibc's default: a fresh memory map (the check can tell them apart)
    assert retained["on_heap"] is True
    switched_off = _run(_WHERE, "1", env={"SKIDSIM_MALLOC": "default"})  # the benchmark's side-by-side runs
    assert switched_off == {"set": False, "on_heap": False}


_SAME = textwrap.dedent(
    """
    import json
    import numpy as np
    from skidsim.allocator import scan_process_memory
    from skidsim.surface import Surface
    from skidsim.texture import TextureOptions, areal_parameters
    rng = np.random.default_rng(3)
    z = np.cumsum(rng.standard_normal((1800, 2448)), axis=1) * 0.002  # 35 MB of float64, rough
    z = np.round(z + 0.3 * np.sin(np.arange(2448) / 40.0), 2)  # 0.01 mm height codes: ties and plateaus
    s = Surface(z, 0.05, 0.05)
    opt = TextureOptions(workers=1)
    def params():
        return {k: v for k, (v, _) in areal_parameters(s, "raw", opt).items()}
    fresh = params()  # the defaults: every scan-sized array a fresh (zeroed) memory map
    scan_process_memory()
    first, second = params(), params()  # the second reuses the freed arrays (their old contents)
    same = all(
        (a == b == c) or (np.isnan(a) and np.isnan(b) and np.isnan(c))
        for a, b, c in zip(fresh.values(), first.values(), second.values())
    )
    print(json.dumps({"n": len(fresh), "same": bool(same), "keys": fresh.keys() == first.keys() == second.keys()}))
    """
)


def test_areal_parameters_of_a_scan_sized_band_are_the_same_with_the_setting():
    r = _run(_SAME)
    assert r["n"] > 30 and r["keys"]
    assert r["same"]


_ADVICE = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from skidsim.allocator import no_hugepage_advice
    ok = no_hugepage_advice() if sys.argv[1] == "1" else None
    a = np.ones(2048 * 2448)
    p, flags = a.ctypes.data + a.nbytes // 2, None  # the middle (the advice covers the aligned 2 MB blocks)
    lines = open("/proc/self/smaps").read().splitlines()
    inside = False
    for line in lines:
        head = line.split()[0] if line else ""
        if "-" in head and all(c in "0123456789abcdef-" for c in head):
            lo, hi = (int(x, 16) for x in head.split("-"))
            inside = lo <= p < hi
        elif inside and line.startswith("VmFlags:"):
            flags = line.split()[1:]
    print(json.dumps({"set": ok, "hugepage": "hg" in (flags or [])}))
    """
)


def test_numpy_huge_page_advice_is_off_only_with_the_setting():
    default = _run(_ADVICE, "0")
    if not default["hugepage"]:
        pytest.skip("NumPy does not advise huge pages here (kernel or NumPy build): nothing to turn off")
    off = _run(_ADVICE, "1")
    assert off == {"set": True, "hugepage": False}
    explicit = _run(_ADVICE, "1", env={"NUMPY_MADVISE_HUGEPAGE": "1"})  # the user's explicit choice stands
    assert explicit == {"set": False, "hugepage": True}
