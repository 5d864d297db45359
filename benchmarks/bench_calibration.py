"""Benchmark: the study's nested bisection vs our fast calibration on a synthetic campaign of surrogate sites.

No FE: each site's "FE solver" is a surrogate ``SN = g(v, mu) * mu(v) + noise`` with a site geometric factor
that depends weakly on speed and on the friction level (field notes: SN_sim ~ g * mu(v)). Step counts follow
the real solver's schedule (114.3 mm slide at dt = 0.8 us: 25.7k steps at 20 km/h, 12.9k at 40, 8.6k at 60);
FE wall time is *modelled* from the field notes' linear-elastic throughput (15,360 hex at 5e6 element-steps/s,
3.1 ms per step), so the FE columns are counts, not measurements. The calibration overhead (everything but the
FE calls: bisection bookkeeping, least-squares fits) *is* measured on this machine.

DFT traces: the exponential-decay base times a drainage-like factor exp(-k (v - 20)/Sp) (as in
``skidsim.generators.truth``, so the
law cannot represent them exactly) plus white noise 0.005, 1 km/h spacing 5..85 km/h.

Usage: ``python benchmarks/bench_calibration.py [--sites 12] [--seed 2026] [--scenario realistic|flat]``
(``flat``: nearly speed-independent sites, the case where the study's bisection converges at once). Prints the
comparison table (per site and total: FE runs, steps, wall, fit RMSE at calibration and validation speeds for
both methods), Figure-10 statistics, Table 2 and medians of the measured overhead.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import pandas as pd

from skidsim.calibration import (
    FEOutcome,
    JointOptions,
    StudyOptions,
    calibrate_fast,
    calibrate_study,
    comparison_table,
    figure10_statistics,
    fit_exponential_decay,
    simulate_speeds,
    table2,
    validation_table,
)
from skidsim.friction import ExponentialDecay

ELEMENTS = 15_360
ELEMENT_STEPS_PER_S = 5e6
#: FE budgets of the tables in docs/calibration.md ("Measured (benchmarks/bench_calibration.py)"): 15 evaluations
#: per bisection search and 15 FE runs for ours (the workflow's config/config.yaml uses 8 and 12)
STUDY_MAX_ITER = 15
OURS_MAX_FE_RUNS = 15


def steps_for(speed_kmh: float) -> int:
    return int(round(0.1143 / (speed_kmh / 3.6) / 0.8e-6))


class SurrogateFE:
    def __init__(self, g0, g1, g2, noise_sd, seed):
        self.g0, self.g1, self.g2 = g0, g1, g2
        self.noise_sd = noise_sd
        self.seed = seed

    def __call__(self, speed_kmh, law):
        mu = float(law.mu_kmh(speed_kmh))
        g = self.g0 * (1 + self.g1 * (speed_kmh - 40) / 40) * (1 + self.g2 * (mu - 0.45))
        # deterministic noise per (speed, law), like a deterministic solver's discretisation noise
        key = hash((round(speed_kmh, 9), round(law.mu_s, 12), round(law.mu_k, 12), round(law.alpha, 12))) % 2**32
        sn = g * mu + np.random.default_rng([self.seed, key]).normal(0, self.noise_sd)
        n = steps_for(speed_kmh)
        return FEOutcome(sn=sn, n_steps=n, wall_s=n * ELEMENTS / ELEMENT_STEPS_PER_S)


def make_site(rng, scenario="realistic"):
    mu_k = rng.uniform(0.25, 0.5)
    mpd = rng.uniform(0.4, 1.6)
    v = np.arange(5.0, 86.0, 1.0)
    if scenario == "flat":  # nearly speed-independent friction: what the study's start values can fit
        law = ExponentialDecay(mu_s=mu_k + 0.05, mu_k=mu_k, alpha=rng.uniform(0.4, 1.0))
        base = law.mu_kmh(v)
    else:
        law = ExponentialDecay(mu_s=mu_k + 0.10 + 0.12 * mpd, mu_k=mu_k, alpha=0.10 * (0.8 / mpd) ** 0.5)
        sp = 14.2 + 89.7 * mpd
        base = law.mu_kmh(v) * np.exp(-0.5 * (v - 20) / sp)
    g = dict(g0=rng.uniform(0.95, 1.10), g1=rng.uniform(-0.03, 0.03), g2=rng.uniform(-0.3, 0.3))
    g0v = g["g0"] * (1 + g["g1"] * (v - 40) / 40)
    mu_meas = g0v * base + rng.normal(0, 0.005, v.size)  # what the DFT shows: the FE's g included
    return law, pd.DataFrame({"speed_kmh": v, "mu": mu_meas}), g


def real_simulator(i, site, cache_dir):
    """The real explicit solver on a seeded random texture (campaign preset), behind an FECache."""
    import tempfile

    from skidsim.calibration import FECache, fe_simulator
    from skidsim.solver import RandomTexture, SolverConfig

    cfg = SolverConfig.campaign(progress_every_s=1e9)
    cache_dir = cache_dir or tempfile.mkdtemp(prefix="bench_calibration_")
    cache = FECache(
        f"{cache_dir}/{site}.parquet", site=site, pavement=f"RandomTexture(seed={i})", solver=repr(cfg.as_dict())
    )
    return cache.wrap(fe_simulator(RandomTexture(seed=i), cfg))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sites", type=int, default=12)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument(
        "--scenario",
        choices=("realistic", "flat"),
        default="realistic",
        help="realistic: truth-like decay + drainage; flat: nearly speed-independent friction",
    )
    ap.add_argument(
        "--real-solver",
        action="store_true",
        help="use skidsim.solver.simulate (campaign preset, RandomTexture pavements) instead of the "
        "surrogate; minutes per site",
    )
    ap.add_argument(
        "--model", choices=("ratio", "slip"), default=JointOptions().model, help="calibrate_fast surrogate model"
    )
    ap.add_argument("--cache-dir", default=None, help="FECache directory for --real-solver (default: a temp dir)")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    results, runs, meas, over = {}, {}, {}, {"study": [], "ours": []}
    for i in range(args.sites):
        site = f"S{i + 1:02d}"
        _, curve, g = make_site(rng, args.scenario)
        sim = SurrogateFE(**g, noise_sd=0.002, seed=i)
        if args.real_solver:
            sim = real_simulator(i, site, args.cache_dir)
        meas[site] = curve
        study_opt = StudyOptions(max_iter=STUDY_MAX_ITER)
        ours_opt = JointOptions(model=args.model, max_fe_runs=OURS_MAX_FE_RUNS)
        results[site] = {"study": calibrate_study(sim, curve, study_opt), "ours": calibrate_fast(sim, curve, ours_opt)}
        runs[site] = {m: simulate_speeds(sim, r.params, (20, 30, 40, 50, 60, 70)) for m, r in results[site].items()}
        for m, r in results[site].items():
            over[m].append(r.overhead_s)
    vt = validation_table(runs, meas)
    cmp = comparison_table(results, vt)
    pd.set_option("display.width", 200)
    pd.set_option("display.max_columns", 30)
    print(
        "== comparison ("
        + (
            "real solver, campaign preset, measured wall s"
            if args.real_solver
            else "surrogate FE, wall modelled at 3.1 ms/step"
        )
        + "; rmse in SN units) =="
    )
    cols = [
        "site",
        "study_fe_runs",
        "study_steps",
        "study_wall_s",
        "study_converged",
        "study_rmse_cal",
        "study_rmse_val",
        "ours_fe_runs",
        "ours_steps",
        "ours_wall_s",
        "ours_converged",
        "ours_rmse_cal",
        "ours_rmse_val",
        "steps_ratio",
    ]
    print(cmp[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print("\n== Figure 10 statistics ==")
    print(figure10_statistics(vt).to_string(index=False, float_format=lambda x: f"{x:.4f}"))
    print("\n== Table 2 ==")
    print(table2(results).to_string(index=False, float_format=lambda x: f"{x:.4f}"))
    tot = cmp.set_index("site").loc["TOTAL"]
    print(
        f"\ntotal steps: study {int(tot.study_steps)}, ours {int(tot.ours_steps)}, ratio {tot.steps_ratio:.3f} "
        f"(target <= 0.333); validation RMSE study {tot.study_rmse_val:.4f}, ours {tot.ours_rmse_val:.4f}"
    )
    print(
        f"median measured overhead per site (s, no FE): study {statistics.median(over['study']):.4f}, "
        f"ours {statistics.median(over['ours']):.4f}  (2 shared cores, disturbed by other jobs)"
    )
    v = np.arange(20.0, 61.0)
    y = meas["S01"].set_index("speed_kmh").loc[v, "mu"].to_numpy()
    ts = []
    for _ in range(15):
        t0 = time.perf_counter()
        fit_exponential_decay(v, y)
        ts.append(time.perf_counter() - t0)
    print(f"fit_exponential_decay on 41 points: median {statistics.median(ts) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
