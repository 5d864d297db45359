"""CPU cost of the study's bisection with and without the batched look-ahead (``calibration.study.look_ahead``).

Usage: ``python benchmarks/bench_study_bisection.py [--sites 3] [--first 0] [--modes none,quarters,predicted]
[--baseline none] [--batch-repeat 2]``. Sites of the embedded default campaign (``config/config.yaml``: seed, solver
preset ``campaign``), each site's pavement cut from its generated clean surface with the config's mesh options (the
workflow cuts it from the despeckled, band-separated scan: close, not the same file), its DFT values at 20/40/60
km/h from the generated trace with the ingest's +-5 km/h local line. For every site each mode (``predicted:N``: with
``look_ahead_depth`` N) runs the whole study calibration with a fresh :func:`fe_simulator` (no cache) in this
process, the modes interleaved per site; CPU s are ``time.process_time`` with one BLAS thread. Prints per site and
mode: the evaluations per search, CPU s, speculative runs (announced, not evaluated), the check that history
(without wall times), parameters and message equal those of ``"none"`` (today's sequential bisection); then the
totals and the ratio ``none / mode``. First, the CPU s of a batch of 2-8 runs at 60 km/h on the first site relative
to one run (same speed, different mu_k; fastest of ``--batch-repeat``). Timings on a shared machine are disturbed by
other processes: report them with that caveat.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import yaml
from threadpoolctl import threadpool_limits

from skidsim.calibration import StudyOptions, calibrate_study
from skidsim.calibration.cache import fe_simulator
from skidsim.calibration.measured import measured_dict
from skidsim.config import solver_config
from skidsim.friction import ExponentialDecay
from skidsim.generators import default as synthetic
from skidsim.reconstruct import MeshOptions, pavement_strip
from skidsim.solver import simulate_batch

ROOT = Path(__file__).resolve().parents[1]
WALL_COLUMNS = ("wall_s_run", "fe_wall_s")
BATCH_SIZES = (1, 2, 3, 4, 6, 8)


def load_sites(first: int, n: int):
    """(site, Heightfield, {speed_kmh: mu}, SolverConfig, StudyOptions of the config) of ``n`` campaign sites."""
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    scfg = solver_config(cfg["solver"])
    scfg = replace(scfg, progress_every_s=1e9)
    syn = synthetic.resolve_config(cfg.get("synthetic") or {})
    design = synthetic.design_campaign(syn)
    mesh = MeshOptions.from_dict(cfg["mesh"])
    window = cfg["ingest"]["dft_smooth_window_kmh"]
    speeds = [float(v) for v in cfg["speeds"]["calibration_kmh"]]
    out = []
    for _, row in design.iloc[first : first + n].iterrows():
        data = synthetic.generate_site(row.to_dict(), syn)
        hf = pavement_strip(data.clean, **mesh.strip_kwargs())
        out.append((str(row["site"]), hf, measured_dict(data.dft, speeds, window, None), scfg))
    return out, StudyOptions.from_config(cfg["calibration"]["study"])


def batch_cost(hf, scfg, repeat: int) -> None:
    """CPU s of one run and of batches of 2-8 runs at 60 km/h (different mu_k), relative to one run."""
    best: dict[int, float] = {}
    for _ in range(repeat):
        for k in BATCH_SIZES:
            laws = [ExponentialDecay(0.4, 0.3 + 0.03 * i, 0.6) for i in range(k)]
            t0 = time.process_time()
            simulate_batch(hf, [60.0] * k, laws, scfg)
            best[k] = min(best.get(k, float("inf")), time.process_time() - t0)
    rel = ", ".join(f"{k} runs {best[k]:.2f} s ({best[k] / best[1]:.2f}x)" for k in BATCH_SIZES[1:])
    print(f"CPU s of one batch at 60 km/h (fastest of {repeat}): 1 run {best[1]:.2f} s; {rel}")


def history_key(res):
    """What must not depend on the look-ahead: history without wall times, parameters, flags, message."""
    h = res.history.drop(columns=list(WALL_COLUMNS))
    return h.fillna(-1.0).to_dict("records"), res.params, res.converged, res.message


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sites", type=int, default=3)
    ap.add_argument("--first", type=int, default=0, help="index of the first site in the campaign design")
    ap.add_argument("--baseline", default="none", help="the mode every other is compared with (history, CPU)")
    ap.add_argument("--modes", default="none,quarters,predicted", help="look_ahead values; predicted:N sets the depth")
    ap.add_argument("--batch-repeat", type=int, default=2, help="0: skip the batch-cost figures")
    a = ap.parse_args()
    base_mode = a.baseline
    modes = [base_mode] + [m for m in (m.strip() for m in a.modes.split(",")) if m != base_mode]
    sites, base = load_sites(a.first, a.sites)
    print(f"campaign preset: element {sites[0][3].element_mm} mm, slide {sites[0][3].slide_length_mm} mm; {base}")
    tot = dict.fromkeys(modes, 0.0)
    with threadpool_limits(1, user_api="blas"):
        if a.batch_repeat:
            batch_cost(sites[0][1], sites[0][3], a.batch_repeat)
        for site, hf, meas, scfg in sites:
            ref = None
            for m in modes:
                mode, _, depth = m.partition(":")
                opt = replace(base, look_ahead=mode, look_ahead_depth=int(depth or base.look_ahead_depth))
                t0 = time.process_time()
                res = calibrate_study(fe_simulator(hf, scfg), meas, opt)
                cpu = time.process_time() - t0
                tot[m] += cpu
                ref = history_key(res) if ref is None else ref
                same = history_key(res) == ref
                n_it = res.history.groupby("stage", sort=False).size().to_dict()
                st = res.settings
                print(
                    f"  {site} {m:9s}: evaluations {n_it}, {res.n_steps} steps, CPU {cpu:6.2f} s; speculative "
                    f"{st['speculative_fe_runs']} runs, {st['speculative_fe_steps']} steps; "
                    f"identical to {base_mode}: {same}"
                )
    for m in modes[1:]:
        print(
            f"total CPU s over {len(sites)} sites: {base_mode} {tot[base_mode]:.2f}, {m} {tot[m]:.2f}, "
            f"ratio {base_mode}/{m} {tot[base_mode] / tot[m]:.3f}"
        )


if __name__ == "__main__":
    main()
