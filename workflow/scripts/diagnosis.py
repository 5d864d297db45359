"""Snakemake adapter: model criticism (residuals, candidate causes, extension for the named cause, gain).

Within-site residuals: measured DFT (points at calibration/validation speeds and the trace between them) minus the
calibrated FE simulation. Between-site residuals: measured minus texture-based predictions of sites the model never
saw: leave-one-section-out predicted friction parameters (the best regression model) times the site's FE geometric
factor g(v) = SN_sim(v) / mu_cal(v). The analysis reads only campaign-derived tables, never results/truth/.
"""
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim import diagnosis
from skidsim.friction import ExponentialDecay
from skidsim.plotting.diagnosis import diagnosis_figures
from skidsim.runlog import setup_logging

log = setup_logging(snakemake.log[0])
cfg = snakemake.params.cfg
method = snakemake.params.calibration_method
sites = pd.read_parquet(snakemake.input.ingest)
wide = pd.read_parquet(snakemake.input.wide)

cal = {float(v) for v in snakemake.params.calibration_speeds}
val = {float(v) for v in snakemake.params.validation_speeds}
points = pd.read_parquet(snakemake.input.dft)[["site", "speed_kmh", "mu"]]
points["kind"] = np.where(points["speed_kmh"].isin(cal), "calibration",
                          np.where(points["speed_kmh"].isin(val), "validation", "trace"))
traces = pd.read_parquet(snakemake.input.traces)[["site", "speed_kmh", "mu"]].assign(kind="trace")
measured = pd.concat([points, traces], ignore_index=True)

vt = pd.read_parquet(snakemake.input.validation)
vt = vt[vt["method"] == method]
simulated = vt[["site", "speed_kmh", "sn_sim"]].rename(columns={"sn_sim": "sn"})

params = pd.read_parquet(snakemake.input.params)
params = params[params["method"] == method].set_index("site")
g = vt.assign(mu_cal=[ExponentialDecay(*params.loc[r.site, ["mu_s", "mu_k", "alpha"]]).mu_kmh(r.speed_kmh)
                      for r in vt.itertuples()])
g = g.assign(g=g["sn_sim"] / g["mu_cal"])[["site", "speed_kmh", "g"]]
best = Path(snakemake.input.best_model).read_text().strip()
cvp = pd.read_csv(snakemake.input.cv_predictions)
cvp = cvp[cvp["model"] == best]
pred = g.merge(cvp[["site", "mu_s", "mu_k", "alpha"]].astype({"site": str}), on="site")
pred["sn_pred"] = [r.g * ExponentialDecay(max(r.mu_s, 0), max(r.mu_k, 0), max(r.alpha, 0)).mu_kmh(r.speed_kmh)
                   for r in pred.itertuples()]
log.info("diagnosis: %d measured points, %d sites, between-site predictions from model %s", len(measured),
         len(sites), best)

result = diagnosis.diagnose(sites, measured, simulated, pred[["site", "speed_kmh", "sn_pred"]], wide,
                            n_permutations=cfg.get("n_permutations"), seed=cfg["seed"], fdr=cfg["fdr"],
                            corr_group=cfg["corr_group"], speed_bin_kmh=cfg["speed_bin_kmh"],
                            fdr_method=cfg["fdr_method"], n_boot=cfg["n_boot"], ci=cfg["ci"],
                            cluster_rho=cfg["cluster_rho"], primary_share=cfg["primary_share"],
                            adjust_texture=cfg.get("adjust_texture", True))
out = Path(snakemake.output.causes).parent
figs = diagnosis_figures(result, snakemake.output.figures)
diagnosis.write_outputs(out, result.residuals, result.causes, result.gain, figs)
top = result.named
log.info("named cause: %s", None if top is None else f"{top.variable} ({top.level}, p_adj={top.p_adjusted:.3g})")
