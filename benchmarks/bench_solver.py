"""Speed of the explicit solver: internal-force kernel, whole steps, mass scaling, campaign vs reference.

Usage: ``python benchmarks/bench_solver.py [--quick] [--full]``. Prints medians and ratios. BLAS is limited to
one thread (threadpoolctl) so that the figures are one-core figures. ``--full`` also runs the reference preset
over the full 114.3 mm at 20 km/h (~2 min) and the campaign-vs-reference SN comparison at 20/40/60 km/h.
Timings on a shared machine are disturbed by other processes: report them with that caveat.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from threadpoolctl import threadpool_limits

from skidsim.friction import ExponentialDecay
from skidsim.slidermesh import SliderMesh
from skidsim.solver import RandomTexture, SolverConfig, simulate
from skidsim.solver.surfaces import to_heightfield
from skidsim.solver.kernel import NaiveKernel, StructuredKernel
from skidsim.solver.material import RubberMaterial, element_stiffness

LAW = ExponentialDecay(0.4, 0.35, 0.6)  # the study's mesh-study parameters


def median_time(fn, repeat: int, inner: int) -> float:
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(inner):
            fn()
        ts.append((time.perf_counter() - t) / inner)
    return statistics.median(ts)


def bench_kernel(element_mm: float, repeat: int) -> None:
    mat = RubberMaterial()
    mesh = SliderMesh.box(element_mm=element_mm)
    ke = element_stiffness(mat, mesh.hx, mesh.hy, mesh.hz)
    u = np.random.default_rng(0).standard_normal((3, mesh.nz + 1, mesh.ny + 1, mesh.nx + 1))
    out = np.empty_like(u)
    res = {}
    for name, k in [("structured (8 slices + 1 dgemm)", StructuredKernel(mesh, ke)),
                    ("naive gather + bincount scatter", NaiveKernel(mesh, ke, "bincount")),
                    ("naive gather + np.add.at scatter", NaiveKernel(mesh, ke, "add_at"))]:
        t = median_time(lambda: k.force(u, out), repeat, 10)
        res[name] = t
        print(f"  {name:36s} {t * 1e3:7.3f} ms/eval  {mesh.n_elements / t / 1e6:6.2f} M element-steps/s")
    s = res["structured (8 slices + 1 dgemm)"]
    for name, t in res.items():
        if not name.startswith("structured"):
            print(f"  speed-up of structured over {name}: {t / s:.2f}x")


def bench_run(cfg: SolverConfig, speed_kmh: float, label: str, pavement) -> object:
    r = simulate(pavement, speed_kmh, LAW, cfg)
    per_step = r.wall_s / r.n_steps
    print(f"  {label:34s} SN {r.sn:.4f}  {r.n_steps:6d} steps  dt {r.dt_s * 1e6:.3f} us  wall {r.wall_s:6.1f} s "
          f"({per_step * 1e3:.2f} ms/step, {r.element_steps_per_s / 1e6:.2f} M el-steps/s, "
          f"energy residual {100 * r.energy_residual_fraction():.3f} %)")
    return r


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--full", action="store_true")
    a = ap.parse_args()
    rep = 3 if a.quick else 7
    pav = to_heightfield(RandomTexture(), 0.1e-3)  # the scanned-pavement code path (C1 Heightfield)
    with threadpool_limits(1, user_api="blas"):
        print("internal-force kernel, 0.5 mm slider (15,360 hexahedra), median of", rep)
        bench_kernel(0.5, rep)
        print("internal-force kernel, 1.0 mm slider (1,920 hexahedra)")
        bench_kernel(1.0, rep)

        print("whole steps, reference preset (0.5 mm, no mass scaling), RandomTexture, 20 km/h, 8 mm slide:")
        ref = SolverConfig.reference(slide_length_mm=8.0, window_start_mm=3.0, progress_every_s=1e9)
        r = bench_run(ref, 20, "reference 0.5 mm, 8 mm", pav)
        n_full = int(np.ceil(114.3e-3 / (20 / 3.6 * r.dt_s))) + r.preload_steps
        print(f"  -> extrapolated full 114.3 mm slide at 20 km/h: {n_full} steps, "
              f"{n_full * r.wall_s / r.n_steps:.0f} s (goal <= 100 s)")

        print("mass scaling (1.0 mm mesh, 30 mm slide, 20 km/h): effect on SN")
        base = None
        for ms in (1.0, 4.0, 16.0, 64.0):
            cfg = SolverConfig(element_mm=1.0, slide_length_mm=30.0, window_start_mm=5.0, mass_scaling=ms,
                               progress_every_s=1e9)
            r = bench_run(cfg, 20, f"mass scaling {ms:g}", pav)
            base = r.sn if base is None else base
            print(f"    SN change vs no mass scaling: {100 * (r.sn / base - 1):+.2f} %")

        print("campaign preset:", SolverConfig.campaign())
        camp = {}
        for v in (20, 40, 60):
            camp[v] = bench_run(SolverConfig.campaign(progress_every_s=1e9), v, f"campaign {v} km/h", pav)
        if a.full:
            print("reference preset, full 114.3 mm slides (clamped to the strip if needed):")
            for v in (20, 40, 60):
                r = bench_run(SolverConfig.reference(progress_every_s=1e9), v, f"reference {v} km/h", pav)
                print(f"    campaign SN error vs reference at {v} km/h: {100 * (camp[v].sn / r.sn - 1):+.2f} %")


if __name__ == "__main__":
    main()
