"""Snakemake adapter: FE simulation of a held-out site with friction parameters predicted from its texture."""

import pandas as pd

from skidsim import calibration
from skidsim.calibration.cache import prefetch
from skidsim.calibration.site import site_simulator
from skidsim.friction import ExponentialDecay
from skidsim.runlog import setup_logging, write_parquet

log = setup_logging(snakemake.log[0])
site = snakemake.wildcards.site
simulate, cache, _ = site_simulator(snakemake.input.pavement, snakemake.params.solver, snakemake.params.cache, site)
pred = pd.read_csv(snakemake.input.predictions)
pred = pred[pred["site"].astype(str) == site]
if pred.empty:
    raise RuntimeError(f"{snakemake.input.predictions}: no predicted parameters for held-out site {site}")
speeds = [float(v) for v in snakemake.params.speeds]
laws = [ExponentialDecay(max(r.mu_s, 0.0), max(r.mu_k, 0.0), max(r.alpha, 0.0)) for r in pred.itertuples(index=False)]
prefetch(simulate, [(v, law) for law in laws for v in speeds])  # every model's runs in one FE batch (same SN)
parts = []
for row, law in zip(pred.itertuples(index=False), laws):
    df = calibration.simulate_speeds(simulate, law, speeds)
    df.insert(0, "model", row.model)
    df.insert(0, "site", site)
    df["mu_s"], df["mu_k"], df["alpha"] = law.mu_s, law.mu_k, law.alpha
    parts.append(df)
    log.info("%s %s: %s", site, row.model, df[["speed_kmh", "sn_sim"]].to_dict("list"))
write_parquet(snakemake.output.table, pd.concat(parts, ignore_index=True))
