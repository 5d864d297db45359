"""Replay our calibration of every site of a finished run on its stored pavements and FE caches, with other options.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/calibration_replay.py RESULTS CONFIG OUT [--fit-gain-tol MU|none]
        [--set KEY=VALUE ...] [--study-steps N]

RESULTS: the ``results/`` folder of a finished ``make reproduce`` (pavements, ``ingest/`` tables, FE caches,
``calibration_study.json`` per site; a run of our calibration only takes the study's total FE steps from
``--study-steps``); CONFIG: its config file; ``--set`` replaces one more ``calibration.ours`` option (a YAML
value). The FE caches are copied to OUT first (the run's own stay as they are), so every FE run the old calibration
made is reused and only new laws cost FE time. The three reference sites are calibrated first without a prior, the
others from their prior, as the workflow does. Prints per site the FE runs and steps (old and new), the ratio of our
FE steps to the study's bisection (its stored summaries), and the fit R^2 / RMSE of the calibrated laws against the
measured DFT points at the calibration speeds (20, 40, 60 km/h) and the validation speeds (30, 50, 70 km/h), from FE
runs of each final law (cached in ``OUT/fit_cache.pkl`` by site and law); writes ``OUT/sites.csv`` and
``OUT/fit.csv``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pickle
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from skidsim.calibration import JointOptions
from skidsim.calibration.joint import calibrate_fast, prior_reference_sites, surrogate_prior
from skidsim.calibration.site import site_simulator
from skidsim.config import solver_config
from skidsim.reconstruct import Heightfield
from skidsim.solver import simulate_batch

SPEEDS = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)  # km/h
CALIBRATION, VALIDATION = (20.0, 40.0, 60.0), (30.0, 50.0, 70.0)


def calibrate_all(results: Path, cfg: dict, opt: JointOptions, out: Path) -> dict:
    """Our calibration of every site (references first, without a prior), on copies of the FE caches."""
    sites = pd.read_parquet(results / "ingest" / "sites.parquet")["site"].astype(str).tolist()
    traces = pd.read_parquet(results / "ingest" / "dft_traces.parquet")

    def run(site: str, prior):
        cache = out / "cache" / site / "fe.parquet"
        if not cache.exists():
            cache.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(results / "cache" / site / "fe.parquet", cache)
        sim, _, _ = site_simulator(results / "sites" / site / "pavement.npz", cfg["solver"], cache, site)
        trace = traces[traces["site"] == site][["speed_kmh", "mu"]].sort_values("speed_kmh")
        return calibrate_fast(sim, trace, opt, speeds_kmh=list(CALIBRATION), prior=prior)

    refs = prior_reference_sites(sites, int(opt.prior_sites))
    res = {s: run(s, None) for s in refs}
    prior = surrogate_prior([res[s] for s in refs]) if refs else None
    print("prior", prior, flush=True)
    for s in sites:
        if s not in res:
            res[s] = run(s, prior)
    return res


def fit_table(results: Path, cfg: dict, res: dict, out: Path) -> pd.DataFrame:
    """FE SN of every site's final law at 20-70 km/h against the measured DFT points (one batch per site)."""
    pts = pd.read_parquet(results / "ingest" / "dft_points.parquet")
    scfg = solver_config(cfg["solver"])
    path = out / "fit_cache.pkl"
    cache = pickle.loads(path.read_bytes()) if path.exists() else {}
    rows = []
    for site, r in res.items():
        law = r.params
        key = (site, law.mu_s, law.mu_k, law.alpha)
        if key not in cache:
            hf = Heightfield.from_npz(results / "sites" / site / "pavement.npz")
            cache[key] = [x.sn for x in simulate_batch(hf, list(SPEEDS), [law] * len(SPEEDS), scfg)]
            path.write_bytes(pickle.dumps(cache))
        mu = pts[pts["site"] == site].set_index("speed_kmh")["mu"]
        rows += [(site, v, float(mu.loc[v]), sn) for v, sn in zip(SPEEDS, cache[key])]
    return pd.DataFrame(rows, columns=["site", "speed_kmh", "mu_measured", "sn_sim"])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("config", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--fit-gain-tol", default=None, help="calibration.ours.fit_gain_tol (mu, or none); default: config")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=YAML", help="another calibration.ours option")
    ap.add_argument(
        "--study-steps", type=int, default=None, help="the study's FE steps of the campaign, where RESULTS has none"
    )
    a = ap.parse_args(argv)
    cfg = yaml.safe_load(a.config.read_text())
    opt = JointOptions.from_config(cfg["calibration"]["ours"])
    if a.fit_gain_tol is not None:
        opt = dataclasses.replace(opt, fit_gain_tol=None if a.fit_gain_tol == "none" else float(a.fit_gain_tol))
    for item in a.set:
        key, value = item.split("=", 1)
        opt = dataclasses.replace(opt, **{key: yaml.safe_load(value)})
    print(opt, flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    res = calibrate_all(a.results, cfg, opt, a.out)
    rows, study_steps = [], 0
    for site, r in res.items():
        old = json.loads((a.results / "sites" / site / "calibration_ours.json").read_text())["summary"]
        if a.study_steps is None:
            study = json.loads((a.results / "sites" / site / "calibration_study.json").read_text())["summary"]
            study_steps += int(study["n_steps"])
        rows.append(
            dict(site=site, n_fe=r.n_fe_runs, n_steps=r.n_steps, old_n_fe=old["n_fe_runs"], old_n_steps=old["n_steps"])
        )
    study_steps = a.study_steps if a.study_steps is not None else study_steps
    df = pd.DataFrame(rows)
    df.to_csv(a.out / "sites.csv", index=False)
    print(df.to_string(index=False))
    new, old = int(df["n_steps"].sum()), int(df["old_n_steps"].sum())
    print(
        f"FE steps: ours {new:,} (stored run {old:,}), study {study_steps:,}: ratio {new / study_steps:.4f} "
        f"(stored run {old / study_steps:.4f}); sites with one batch after the prior: {int((df['n_fe'] == 3).sum())}"
    )
    fit = fit_table(a.results, cfg, res, a.out)
    fit.to_csv(a.out / "fit.csv", index=False)
    for name, speeds in (("calibration", CALIBRATION), ("validation", VALIDATION)):
        d = fit[fit["speed_kmh"].isin(speeds)]
        e = d["sn_sim"] - d["mu_measured"]
        r2 = 1.0 - float((e**2).sum()) / float(((d["mu_measured"] - d["mu_measured"].mean()) ** 2).sum())
        print(f"{name} speeds: R2 {r2:.4f}, RMSE {float(np.sqrt((e**2).mean())):.4f} ({len(d)} points)")


if __name__ == "__main__":
    main()
