"""Snakemake adapter: held-out-speed gain of the viscoelastic recalibration (results/diagnosis/fe_gain.json), or the
record that the FE extension was not applied (docs/model-criticism.md, "FE extension: viscoelastic slider")."""
import json

import pandas as pd

from skidsim.calibration import CalibrationResult
from skidsim.fe_extension import campaign_speed_gain, fe_extension_decision, site_speed_gain
from skidsim.runlog import atomic_path, setup_logging
from skidsim.workflow_support import measured_points

log = setup_logging(snakemake.log[0])
p = snakemake.params
inp = snakemake.input
causes = []
if "causes" in inp.keys():
    with open(inp.causes) as fh:
        causes = json.load(fh)
apply, reason = fe_extension_decision(p.mode, causes)
out = {"applied": bool(apply), "reason": reason, "mode": p.mode,
       "named_cause": ({k: causes[0].get(k) for k in ("variable", "level", "kind", "p_adjusted", "significant")}
                       if causes else None)}
if apply:
    if "visco" not in inp.keys():
        raise RuntimeError("fe_gain: the extension applies but the per-site viscoelastic runs are not inputs")
    dft = pd.read_parquet(inp.dft)
    per_site = {}
    for site, e_path, v_path, c_path in zip(p.sites, inp.elastic, inp.visco, inp.visco_calibrations):
        e = pd.read_parquet(e_path)
        e = e[e["method"] == "ours"]
        v = pd.read_parquet(v_path)
        g = site_speed_gain(measured_points(dft, site), dict(zip(e["speed_kmh"], e["sn_sim"])),
                            dict(zip(v["speed_kmh"], v["sn_sim"])), p.validation_speeds)
        res = CalibrationResult.from_json(c_path)
        g["params_viscoelastic"] = {"mu_s": res.params.mu_s, "mu_k": res.params.mu_k, "alpha": res.params.alpha}
        g["converged_viscoelastic"] = bool(res.converged)
        g["n_fe_runs_viscoelastic"] = int(res.n_fe_runs)
        per_site[site] = g
        log.info("%s: RMSE at validation speeds %.4f -> %.4f", site, g["rmse_before"], g["rmse_after"])
    agg = campaign_speed_gain(per_site, n_boot=int(p.n_boot), seed=int(p.seed), ci=float(p.ci))
    out.update({"held_out_speeds": agg, "per_site": per_site,
                "prony": {"prony_g": p.solver["overrides"]["prony_g"],
                          "prony_tau_s": p.solver["overrides"]["prony_tau_s"]},
                "validation_speeds_kmh": [float(x) for x in p.validation_speeds]})
    log.info("campaign: RMSE %.4f -> %.4f, gain %.4f CI %s", agg["rmse_before"], agg["rmse_after"],
             agg["rmse_gain"], agg["rmse_gain_ci"])
else:
    log.info("FE extension not applied: %s", reason)
with atomic_path(snakemake.output.gain) as tmp:
    with open(tmp, "w") as fh:
        json.dump(out, fh, indent=1)
