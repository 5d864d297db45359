"""Snakemake adapter: the quality and identifiability record of one site's calibration with one method.

Reads the calibration result (the law, the surrogate state it was fitted under, the verification history), the
site's DFT trace and the FE runs of the final law at the calibration and validation speeds (validation.parquet);
runs no FE. Writes ``identifiability_<method>.json`` (skidsim.calibration.identifiability.assess; docs/calibration.md,
"Quality and identifiability") and logs a WARNING per raised flag."""

import pandas as pd

from skidsim.calibration import CalibrationResult, IdentifiabilityOptions
from skidsim.calibration.identifiability import assess
from skidsim.runlog import setup_logging, write_json

log = setup_logging(snakemake.log[0])
site, method = snakemake.wildcards.site, snakemake.wildcards.method
opts = IdentifiabilityOptions.from_config(snakemake.params.options)
result = CalibrationResult.from_json(snakemake.input.calibration)
traces = pd.read_parquet(snakemake.input.traces)
trace = traces[traces["site"] == site][["speed_kmh", "mu"]].sort_values("speed_kmh")
vt = pd.read_parquet(snakemake.input.validation)
vt = vt[vt["method"] == method]
rec = assess(
    result,
    trace,
    vt,
    options=opts,
    calibration_speeds_kmh=[float(v) for v in snakemake.params.calibration_speeds],
    validation_speeds_kmh=[float(v) for v in snakemake.params.validation_speeds],
    site=site,
    source=snakemake.input.traces,
)
log.info(
    "%s %s: noise sigma %.4g (%d points), FE RMSE %.4g / %.4g at calibration / validation speeds, within noise: %s",
    site,
    method,
    rec["noise"]["sigma"],
    rec["noise"]["n"],
    rec["fit"]["rmse_fe_calibration"],
    rec["fit"]["rmse_fe_validation"],
    rec["within_noise"],
)
log.info("%s %s: %s", site, method, rec["statement"])
for flag in rec["flags"]:
    log.warning("%s %s: %s: %s", site, method, flag, rec["reasons"][flag])
write_json(snakemake.output.record, rec)
