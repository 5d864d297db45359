"""Benchmark of the synthetic campaign generator: time per full-size site (surface + trace) and campaign ranges.

    .venv/bin/python benchmarks/bench_synthetic.py                # 5 full-size sites, median wall / CPU time
    .venv/bin/python benchmarks/bench_synthetic.py --sites all    # all 36 sites, plus the campaign's ranges
    .venv/bin/python benchmarks/bench_synthetic.py --rows 256     # reduced rows (faster look at the ranges)
    .venv/bin/python benchmarks/bench_synthetic.py --old ../skidsim-OLD [--sites 12 --repeats 2]
        # an older checkout's generate_site against this one's, in one process, alternating site by site; CPU s
        # per site of each and of the surface rendering (_render), and whether every array is the same bits

Budget (task): one full-size site (2048 x 2448) in <= 6 s on one core. Prints medians; CPU time (process time)
is the figure to compare when the machine is shared (wall time then includes waiting for a core).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from skidsim.generators import default as S


def _old_module(root: Path):
    """``skidsim.generators.default`` of another checkout (its ``src``), loaded beside this one's: the module
    ``default.py`` of older checkouts or the package ``default/`` (its modules load from that checkout too)."""
    name = "skidsim.generators._bench_old_default"
    where = root / "src" / "skidsim" / "generators"
    if (where / "default.py").exists():
        spec = importlib.util.spec_from_file_location(name, where / "default.py")
    else:
        pkg = where / "default"
        spec = importlib.util.spec_from_file_location(name, pkg / "__init__.py", submodule_search_locations=[str(pkg)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _timed_render(mod, calls: list):
    """``mod.generate_site`` with ``_render`` timed (CPU s appended to ``calls``), patched in the module that calls
    it (the one that holds ``synthesize_surface``: ``mod`` itself, or its ``surface`` module)."""
    home = sys.modules[mod.synthesize_surface.__module__]
    inner = home._render

    def render(*args, **kwargs):
        c0 = time.process_time()
        out = inner(*args, **kwargs)
        calls.append(time.process_time() - c0)
        return out

    home._render = render
    return mod


def compare_old(root: Path, cfg: dict, idx: list, repeats: int) -> None:
    """Old and new generate_site on the same sites, alternating (the first of each pair switches every repeat)."""
    from skidsim.allocator import scan_process_memory

    scan_process_memory()
    design = S.design_campaign(cfg)
    render = {"old": [], "new": []}
    mods = {"old": _timed_render(_old_module(root), render["old"]), "new": _timed_render(S, render["new"])}
    total = {"old": [], "new": []}
    differ = []
    for rep in range(repeats):
        for i in idx:
            row = design.iloc[i].to_dict()
            out = {}
            for name in ("old", "new") if (rep + i) % 2 == 0 else ("new", "old"):
                c0 = time.process_time()
                out[name] = mods[name].generate_site(row, cfg)
                total[name].append(time.process_time() - c0)
            o, n = out["old"], out["new"]
            same = (
                np.array_equal(o.surface.heights, n.surface.heights, equal_nan=True)
                and np.array_equal(o.clean.heights, n.clean.heights, equal_nan=True)
                and o.dft.equals(n.dft)
                and o.truth == n.truth
            )
            if not same:
                differ.append(row["site"])
    for name in ("old", "new"):
        print(
            f"{name}: generate_site median CPU {np.median(total[name]):.3f} s, sum {sum(total[name]):.2f} s; "
            f"_render median {np.median(render[name]):.3f} s, sum {sum(render[name]):.2f} s ({len(total[name])} sites)"
        )
    print(
        f"old / new: generate_site {sum(total['old']) / sum(total['new']):.2f}x, "
        f"_render {sum(render['old']) / sum(render['new']):.2f}x; "
        + ("every surface, trace and truth identical" if not differ else f"DIFFERENT at {sorted(set(differ))}")
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sites", default="5", help="number of sites (spread over the design) or 'all'")
    ap.add_argument("--rows", type=int, default=None, help="rows of the scan (default: full 2048)")
    ap.add_argument("--old", type=Path, help="another checkout: its generate_site against this one's")
    ap.add_argument("--repeats", type=int, default=2, help="with --old: passes over the sites")
    args = ap.parse_args()
    cfg = S.default_config()
    if args.rows:
        cfg["shape"] = [args.rows, cfg["shape"][1]]
    t0 = time.perf_counter()
    design = S.design_campaign(cfg)
    t_design = time.perf_counter() - t0
    if args.sites == "all":
        idx = list(range(len(design)))
    else:
        idx = list(np.linspace(0, len(design) - 1, int(args.sites)).round().astype(int))
    if args.old:
        compare_old(args.old, cfg, idx, args.repeats)
        return
    wall, cpu, rows = [], [], []
    for i in idx:
        row = design.iloc[i].to_dict()
        w0, c0 = time.perf_counter(), time.process_time()
        sd = S.generate_site(row, cfg)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
        tr = sd.truth
        curve = dict(zip(tr["curve"]["speeds_kmh"], tr["curve"]["total"]))
        rows.append(
            (
                row["site"],
                tr["descriptors"]["mpd_mm"],
                tr["descriptors"]["ssk"],
                tr["descriptors"]["micro_sq_mm"],
                curve[20.0],
                curve[60.0],
                len(sd.dft),
                float(np.isnan(sd.surface.heights).mean()),
            )
        )
        print(
            f"{row['site']:6s} wall {wall[-1]:5.2f} s  cpu {cpu[-1]:5.2f} s  MPD {rows[-1][1]:.3f} mm  "
            f"Ssk {rows[-1][2]:+.2f}  microSq {rows[-1][3]:.4f} mm  DFT20 {rows[-1][4]:.3f}  "
            f"DFT60 {rows[-1][5]:.3f}  points {rows[-1][6]}  NaN {rows[-1][7]:.4f}",
            flush=True,
        )
    shape = tuple(cfg["shape"])
    print(f"\nshape {shape}, {len(idx)} sites; design_campaign {t_design * 1000:.1f} ms")
    print(
        f"generate_site median wall {np.median(wall):.2f} s (min {min(wall):.2f}, max {max(wall):.2f}); "
        f"median CPU {np.median(cpu):.2f} s (min {min(cpu):.2f}, max {max(cpu):.2f})"
    )
    a = np.array([r[1:] for r in rows], dtype=float)
    for k, name in enumerate(["MPD mm", "Ssk", "micro Sq mm", "DFT20", "DFT60", "trace points", "NaN share"]):
        print(f"  {name:12s} min {a[:, k].min():8.4f}  median {np.median(a[:, k]):8.4f}  max {a[:, k].max():8.4f}")


if __name__ == "__main__":
    main()
