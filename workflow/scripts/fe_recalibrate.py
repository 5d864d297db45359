"""Snakemake adapter: recalibrate one site with the viscoelastic slider (our method) and simulate it at the
calibration and validation speeds (docs/model-criticism.md, "FE extension: viscoelastic slider")."""

import pandas as pd

from skidsim import calibration
from skidsim.calibration.site import calibrate_ours_site, measured_points, site_simulator
from skidsim.runlog import setup_logging, write_parquet

log = setup_logging(snakemake.log[0])
site = snakemake.wildcards.site
# the solver section carries the Prony terms: the cache key (every solver field) differs from the elastic runs',
# and the viscoelastic evaluations live in their own cache file
simulate, cache, scfg = site_simulator(snakemake.input.pavement, snakemake.params.solver, snakemake.params.cache, site)
log.info(
    "%s: viscoelastic recalibration, Prony g %s, tau %s s, element %.2f mm, %d cached FE evaluations",
    site,
    scfg.prony_g,
    scfg.prony_tau_s,
    scfg.element_mm,
    len(cache),
)
result = calibrate_ours_site(
    simulate,
    snakemake.input.traces,
    site,
    snakemake.params.calibration["ours"],
    snakemake.params.calibration_speeds,
    snakemake.input.prior,
    log,
)
log.info(
    "%s viscoelastic: %s; %d FE runs, %d steps, converged=%s %s",
    site,
    result.params,
    result.n_fe_runs,
    result.n_steps,
    result.converged,
    result.message,
)
write_parquet(snakemake.output.history, result.history.assign(site=site, method="ours_viscoelastic"))
result.to_json(snakemake.output.result)

all_speeds = sorted(
    set(map(float, snakemake.params.calibration_speeds)) | set(map(float, snakemake.params.validation_speeds))
)
runs = {"ours_viscoelastic": calibration.simulate_speeds(simulate, result.params, all_speeds)}
measured = {site: measured_points(pd.read_parquet(snakemake.input.dft), site)}
table = calibration.validation_table(
    {site: runs},
    measured,
    calibration_speeds_kmh=snakemake.params.calibration_speeds,
    validation_speeds_kmh=snakemake.params.validation_speeds,
)
write_parquet(snakemake.output.validation, table)
