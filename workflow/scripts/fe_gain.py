"""Snakemake adapter: held-out-speed gain of the viscoelastic recalibration (results/diagnosis/fe_gain.json), or the
record that the FE extension was not applied (docs/model-criticism.md, "FE extension: viscoelastic slider")."""

import json

import pandas as pd

from skidsim.atomic import write_json
from skidsim.calibration import CalibrationResult
from skidsim.calibration.site import measured_points
from skidsim.criticism import DiagnosisOptions
from skidsim.criticism.fe_extension import fe_extension_decision, fe_gain_record, site_fe_gain
from skidsim.runlog import setup_logging

log = setup_logging(snakemake.log[0])
p = snakemake.params
inp = snakemake.input
causes = []
if "causes" in inp.keys():
    with open(inp.causes) as fh:
        causes = json.load(fh)
per_site = None
if fe_extension_decision(p.mode, causes)[0] and "visco" in inp.keys():
    dft = pd.read_parquet(inp.dft)
    per_site = {}
    for site, e_path, v_path, c_path in zip(p.sites, inp.elastic, inp.visco, inp.visco_calibrations):
        e = pd.read_parquet(e_path)
        e = e[e["method"] == "ours"]
        v = pd.read_parquet(v_path)
        per_site[site] = g = site_fe_gain(
            measured_points(dft, site),
            dict(zip(e["speed_kmh"], e["sn_sim"])),
            dict(zip(v["speed_kmh"], v["sn_sim"])),
            p.validation_speeds,
            CalibrationResult.from_json(c_path),
        )
        log.info("%s: RMSE at validation speeds %.4f -> %.4f", site, g["rmse_before"], g["rmse_after"])
out = fe_gain_record(
    p.mode,
    causes,
    per_site,
    prony=p.solver["overrides"],
    validation_speeds_kmh=p.validation_speeds,
    options=DiagnosisOptions(n_boot=int(p.n_boot), seed=int(p.seed), ci=float(p.ci)),
)
if out["applied"]:
    agg = out["held_out_speeds"]
    log.info(
        "campaign: RMSE %.4f -> %.4f, gain %.4f CI %s",
        agg["rmse_before"],
        agg["rmse_after"],
        agg["rmse_gain"],
        agg["rmse_gain_ci"],
    )
else:
    log.info("FE extension not applied: %s", out["reason"])
write_json(snakemake.output.gain, out, indent=1)
