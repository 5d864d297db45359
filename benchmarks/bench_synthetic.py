"""Benchmark of the synthetic campaign generator: time per full-size site (surface + trace) and campaign ranges.

    .venv/bin/python benchmarks/bench_synthetic.py                # 5 full-size sites, median wall / CPU time
    .venv/bin/python benchmarks/bench_synthetic.py --sites all    # all 36 sites, plus the campaign's ranges
    .venv/bin/python benchmarks/bench_synthetic.py --rows 256     # reduced rows (faster look at the ranges)

Budget (task): one full-size site (2048 x 2448) in <= 6 s on one core. Prints medians; CPU time (process time)
is the figure to compare when the machine is shared (wall time then includes waiting for a core).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from skidsim.generators import default as S


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sites", default="5", help="number of sites (spread over the design) or 'all'")
    ap.add_argument("--rows", type=int, default=None, help="rows of the scan (default: full 2048)")
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
