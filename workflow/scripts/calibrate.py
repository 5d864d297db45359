"""Snakemake adapter: back-calculate one site's friction law with one method (study | ours)."""

import pandas as pd

from skidsim.calibration import JointOptions, StudyOptions, calibrate_study
from skidsim.calibration.site import calibrate_ours_site, measured_points, site_simulator
from skidsim.runlog import setup_logging, write_parquet

log = setup_logging(snakemake.log[0])
site, method = snakemake.wildcards.site, snakemake.wildcards.method
cfg = snakemake.params.calibration
simulate, cache, scfg = site_simulator(snakemake.input.pavement, snakemake.params.solver, snakemake.params.cache, site)
log.info(
    "%s: method %s, solver element %.2f mm, slide %.1f mm, %d cached FE evaluations",
    site,
    method,
    scfg.element_mm,
    scfg.slide_length_mm,
    len(cache),
)
points = pd.read_parquet(snakemake.input.dft)
measured = measured_points(points, site)
speeds = [float(v) for v in snakemake.params.speeds]
if method == "study":
    order = (("mu_k", max(speeds)), ("mu_s", min(speeds)), ("alpha", sorted(speeds)[1]))
    result = calibrate_study(
        simulate,
        {v: measured[v] for v in speeds},
        StudyOptions.from_config(cfg["study"]),
        order=order,
        source=snakemake.input.dft,
    )
else:
    result = calibrate_ours_site(
        simulate,
        snakemake.input.traces,
        site,
        JointOptions.from_config(cfg["ours"]),
        speeds,
        snakemake.input.prior,
        log,
    )
log.info(
    "%s %s: %s; %d FE runs, %d steps, converged=%s %s",
    site,
    method,
    result.params,
    result.n_fe_runs,
    result.n_steps,
    result.converged,
    result.message,
)
if result.settings.get("speculative_fe_runs"):
    st = result.settings
    log.info(
        "%s %s look-ahead: %d announced FE runs not used (%d steps, %d run now, %.2f s), not counted above",
        site,
        method,
        st["speculative_fe_runs"],
        st["speculative_fe_steps"],
        st["speculative_fe_steps_run"],
        st["speculative_fe_wall_s"],
    )
write_parquet(snakemake.output.history, result.history.assign(site=site, method=method))
result.to_json(snakemake.output.result)
