"""Speed of the explicit solver: internal-force kernel, whole steps, mass scaling, campaign vs reference.

Usage: ``python benchmarks/bench_solver.py [--quick] [--full] [--pavement PATH.npz [--speed 20] [--slide-mm 114.3]
[--element-mm 0.5]]``. Prints medians and ratios. BLAS is limited to one thread (threadpoolctl) so that the
figures are one-core figures. ``--full`` also runs the reference preset over the full 114.3 mm at 20 km/h (~2 min)
and the campaign-vs-reference SN comparison at 20/40/60 km/h. ``--pavement PATH`` times only the given real
pavement (a Heightfield ``.npz`` of skidsim.reconstruct, e.g. ``results/sites/E1-1/pavement.npz``): the kernel
against the naive gather/scatter in the same run, then one slide (default: the reference preset, 0.5 mm, 20 km/h,
the full 114.3 mm clamped to the strip) with wall time, element-steps/s and the share of each phase of the step.
``--campaign-cost [--repeat N]`` times only the campaign preset (full slide, RandomTexture) at 20/40/60 km/h with
each contact variant (``stick_limit``, ``penalty``, ``penalty`` + Rayleigh damping), the variants interleaved and
each run repeated N times (median CPU time), and prints the cost per FE run relative to ``stick_limit``.
``--batch [--repeat N] [--laws K] [--pavement-kind fine|heightfield|both]`` prints the old path (one ``simulate``
per run) and the new one (one ``simulate_batch`` of the same runs) in the same process, interleaved: median CPU s per
campaign FE run (full slide) of a calibration batch (20/40/60 km/h, one law) and of a validation batch (K laws x
20..70 km/h), the ratio and the largest relative SN difference; then element-steps per CPU second of the 0.5 mm
reference preset (8 mm slides at 20/40/60 km/h), old and new. Pavements (``PAVEMENT_KINDS``): ``fine`` (default, the
figures of the earlier reports) is RandomTexture on its default 200 x 60 mm extent sampled as a Heightfield at
0.1 mm; ``heightfield`` is a pavement like the workflow's: RandomTexture(seed 0) on a 122.4 x 100 mm strip sampled
at 0.5 mm; ``both`` runs the two in turn.
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
from skidsim.solver import RandomTexture, SolverConfig, simulate, simulate_batch
from skidsim.solver.kernel import NaiveKernel, StructuredKernel
from skidsim.solver.material import RubberMaterial, element_stiffness
from skidsim.solver.surfaces import to_heightfield

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
    for name, k in [
        ("structured (8 slabs + 1 dgemm)", StructuredKernel(mesh, ke)),
        ("naive gather + bincount scatter", NaiveKernel(mesh, ke, "bincount")),
        ("naive gather + np.add.at scatter", NaiveKernel(mesh, ke, "add_at")),
    ]:
        t = median_time(lambda k=k: k.force(u, out), repeat, 10)
        res[name] = t
        print(f"  {name:36s} {t * 1e3:7.3f} ms/eval  {mesh.n_elements / t / 1e6:6.2f} M element-steps/s")
    s = res["structured (8 slabs + 1 dgemm)"]
    for name, t in res.items():
        if not name.startswith("structured"):
            print(f"  speed-up of structured over {name}: {t / s:.2f}x")


def bench_run(cfg: SolverConfig, speed_kmh: float, label: str, pavement) -> object:
    r = simulate(pavement, speed_kmh, LAW, cfg)
    per_step = r.wall_s / r.n_steps
    print(
        f"  {label:34s} SN {r.sn:.4f}  {r.n_steps:6d} steps  dt {r.dt_s * 1e6:.3f} us  wall {r.wall_s:6.1f} s "
        f"({per_step * 1e3:.2f} ms/step, {r.element_steps_per_s / 1e6:.2f} M el-steps/s, "
        f"energy residual {100 * r.energy_residual_fraction():.3f} %)"
    )
    return r


def bench_pavement(path: str, speed_kmh: float, slide_mm: float, element_mm: float, repeat: int) -> None:
    """Kernel vs naive gather/scatter, then one timed slide on a real pavement with the per-phase shares."""
    from skidsim.reconstruct import Heightfield

    pav = Heightfield.from_npz(path)
    print(f"pavement {path}: {pav.shape[1]} x {pav.shape[0]} nodes, spacing {pav.dx_m * 1e3:.3f} mm")
    print(f"internal-force kernel, {element_mm} mm slider, median of {repeat}")
    bench_kernel(element_mm, repeat)
    cfg = SolverConfig.reference(element_mm=element_mm, slide_length_mm=slide_mm, progress_every_s=1e9)
    print(f"one slide: {element_mm} mm, {speed_kmh:g} km/h, {slide_mm} mm requested, no mass scaling")
    r = bench_run(cfg, speed_kmh, f"{element_mm} mm {speed_kmh:g} km/h", pav)
    print(
        f"  slide {r.slide_length_mm:.1f} mm (clamped {r.slide_clamped}), {r.n_steps} steps "
        f"({r.preload_steps} preload), dt {r.dt_s * 1e6:.4f} us (slope bound |grad z|^2 "
        f"{r.meta['slope_bound']:.1f}), wall {r.wall_s:.1f} s, {r.element_steps_per_s / 1e6:.2f} M element-steps/s"
    )
    ph = r.meta["phase_s"]
    for name, t in sorted(ph.items(), key=lambda kv: -kv[1]):
        print(f"    {name:16s} {t:7.1f} s  {100 * t / r.wall_s:5.1f} %  {1e3 * t / r.n_steps:.3f} ms/step")
    tr = r.trace
    print(f"  mean contact nodes {tr['contact_nodes'].mean():.1f}, SN {r.sn:.4f}")


#: Contact variants of the cost comparison: label -> SolverConfig overrides.
VARIANTS = {
    "stick_limit": dict(friction_model="stick_limit"),
    "penalty": dict(friction_model="penalty"),
    "penalty + rayleigh": dict(friction_model="penalty", slide_damping_model="rayleigh"),
}


def bench_campaign_cost(repeat: int, pav) -> None:
    """Median CPU time per FE run of the campaign preset with each contact variant (interleaved runs; CPU time of
    this process, which a busy or throttled host disturbs less than wall time)."""
    walls = {(k, v): [] for k in VARIANTS for v in (20, 40, 60)}
    sn = {}
    for _ in range(repeat):
        for v in (20, 40, 60):
            for k, over in VARIANTS.items():
                t0 = time.process_time()
                r = simulate(pav, v, LAW, SolverConfig.campaign(progress_every_s=1e9, **over))
                walls[(k, v)].append(time.process_time() - t0)
                sn[(k, v)] = (r.sn, r.n_steps, r.dt_s, r.mean_slip_speed_ms)
    base = {v: statistics.median(walls[("stick_limit", v)]) for v in (20, 40, 60)}
    print(f"campaign preset, RandomTexture, median CPU time of {repeat} interleaved runs, one BLAS thread")
    for k in VARIANTS:
        tot = sum(statistics.median(walls[(k, v)]) for v in (20, 40, 60))
        for v in (20, 40, 60):
            w = statistics.median(walls[(k, v)])
            s_, n, dt, slip = sn[(k, v)]
            print(
                f"  {k:20s} {v:3d} km/h: SN {s_:.4f}, {n:6d} steps, dt {dt * 1e6:.3f} us, CPU {w:6.2f} s "
                f"({100 * (w / base[v] - 1):+.1f} %), slip speed seen {slip:.2f} m/s (sliding {v / 3.6:.2f})"
            )
        print(f"  {k:20s} mean per run {tot / 3:.2f} s ({100 * (tot / sum(base.values()) - 1):+.1f} % vs stick_limit)")


#: Laws of the validation batch (the study's mesh-study law first).
BATCH_LAWS = (LAW, ExponentialDecay(0.45, 0.3, 0.5), ExponentialDecay(0.6, 0.35, 0.3), ExponentialDecay(0.5, 0.4, 0.8))


def _old_and_new(pav, speeds, laws, cfg, repeat: int):
    """CPU s of the runs one by one and as one batch (interleaved ``repeat`` times), the results of both."""
    old, new = [], []
    for _ in range(repeat):
        t0 = time.process_time()
        singles = [simulate(pav, v, law, cfg) for v, law in zip(speeds, laws)]
        old.append(time.process_time() - t0)
        t0 = time.process_time()
        batch = simulate_batch(pav, speeds, laws, cfg)
        new.append(time.process_time() - t0)
    return statistics.median(old), statistics.median(new), singles, batch


#: ``--pavement-kind`` of ``--batch``: label and pavement (the fine one: the figures of the earlier reports; the
#: heightfield: the workflow's 0.5 mm grid spacing on a strip of the DFT's extent)
PAVEMENT_KINDS = {
    "fine": ("RandomTexture, Heightfield at 0.1 mm", lambda: to_heightfield(RandomTexture(), 0.1e-3)),
    "heightfield": (
        "Heightfield at 0.5 mm of RandomTexture(seed 0) on 122.4 x 100 mm",
        lambda: to_heightfield(RandomTexture(seed=0, extent_m=(0, 0.1224, -0.05, 0.05)), spacing_m=0.5e-3),
    ),
}


def bench_batch(repeat: int, pav, n_laws: int, pav_label: str = "RandomTexture, Heightfield at 0.1 mm") -> None:
    """Old (one ``simulate`` per run) against new (``simulate_batch``): CPU s per campaign FE run, element-steps/s."""
    cfg = SolverConfig.campaign(progress_every_s=1e9)
    laws = BATCH_LAWS[:n_laws]
    cases = {
        "calibration batch, 20/40/60 km/h, one law": ([20.0, 40.0, 60.0], [LAW] * 3),
        f"validation batch, {n_laws} laws x 20..70 km/h": (
            [float(v) for _ in laws for v in (20, 30, 40, 50, 60, 70)],
            [law for law in laws for _ in range(6)],
        ),
    }
    print(f"campaign preset (full slide, {pav_label}), median CPU s of {repeat} interleaved repeats, one BLAS thread")
    for label, (speeds, ls) in cases.items():
        t_old, t_new, singles, batch = _old_and_new(pav, speeds, ls, cfg, repeat)
        n = len(speeds)
        d_sn = max(abs(b.sn / s.sn - 1.0) for s, b in zip(singles, batch))
        d_abs = max(abs(b.sn - s.sn) for s, b in zip(singles, batch))
        print(
            f"  {label}: {n} runs, {sum(r.n_steps for r in singles)} steps; old {t_old / n:.3f} s per run, "
            f"new {t_new / n:.3f} s per run, ratio {t_old / t_new:.2f}x; max |SN_batch / SN_single - 1| {d_sn:.1e}, "
            f"max |SN_batch - SN_single| {d_abs:.1e}"
        )
    ref = SolverConfig.reference(slide_length_mm=8.0, window_start_mm=3.0, progress_every_s=1e9)
    t_old, t_new, singles, batch = _old_and_new(pav, [20.0, 40.0, 60.0], [LAW] * 3, ref, max(1, repeat // 2))
    el_steps = singles[0].n_elements * sum(r.n_steps for r in singles)
    d_sn = max(abs(b.sn / s.sn - 1.0) for s, b in zip(singles, batch))
    print(
        f"reference preset 0.5 mm ({singles[0].n_elements} elements), 8 mm slides at 20/40/60 km/h: old "
        f"{el_steps / t_old / 1e6:.2f} M element-steps per CPU s, new {el_steps / t_new / 1e6:.2f} M "
        f"(ratio {t_old / t_new:.2f}x); max |SN_batch / SN_single - 1| {d_sn:.1e}"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--pavement", default=None, help="Heightfield .npz: time a slide on this real pavement only")
    ap.add_argument("--speed", type=float, default=20.0, help="km/h (with --pavement)")
    ap.add_argument("--slide-mm", type=float, default=114.3, help="mm (with --pavement)")
    ap.add_argument("--element-mm", type=float, default=0.5, help="mm (with --pavement)")
    ap.add_argument("--campaign-cost", action="store_true", help="cost per FE run of each contact variant only")
    ap.add_argument("--repeat", type=int, default=3, help="runs per variant and speed (with --campaign-cost)")
    ap.add_argument("--batch", action="store_true", help="old path (single runs) against simulate_batch only")
    ap.add_argument("--laws", type=int, default=2, help="laws of the validation batch (with --batch, 1-4)")
    ap.add_argument(
        "--pavement-kind",
        choices=(*PAVEMENT_KINDS, "both"),
        default="fine",
        help="pavement of --batch: fine (RandomTexture at 0.1 mm), heightfield (0.5 mm, like the workflow's), both",
    )
    a = ap.parse_args()
    rep = 3 if a.quick else 7
    if a.batch:
        kinds = list(PAVEMENT_KINDS) if a.pavement_kind == "both" else [a.pavement_kind]
        with threadpool_limits(1, user_api="blas"):
            for kind in kinds:
                label, make = PAVEMENT_KINDS[kind]
                bench_batch(a.repeat, make(), a.laws, label)
        return
    if a.campaign_cost:
        with threadpool_limits(1, user_api="blas"):
            bench_campaign_cost(a.repeat, to_heightfield(RandomTexture(), 0.1e-3))
        return
    if a.pavement:
        with threadpool_limits(1, user_api="blas"):
            bench_pavement(a.pavement, a.speed, a.slide_mm, a.element_mm, rep)
        return
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
        print(
            f"  -> extrapolated full 114.3 mm slide at 20 km/h: {n_full} steps, "
            f"{n_full * r.wall_s / r.n_steps:.0f} s (goal <= 100 s)"
        )

        print("mass scaling (1.0 mm mesh, 30 mm slide, 20 km/h): effect on SN")
        base = None
        for ms in (1.0, 4.0, 16.0, 64.0):
            cfg = SolverConfig(
                element_mm=1.0, slide_length_mm=30.0, window_start_mm=5.0, mass_scaling=ms, progress_every_s=1e9
            )
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
