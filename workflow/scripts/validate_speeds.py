"""Snakemake adapter: simulate a site at calibration and validation speeds with each method's parameters."""

import pandas as pd

from skidsim import calibration
from skidsim.calibration.cache import prefetch
from skidsim.calibration.site import measured_points, site_simulator
from skidsim.runlog import setup_logging, write_parquet

log = setup_logging(snakemake.log[0])
site = snakemake.wildcards.site
simulate, cache, _ = site_simulator(snakemake.input.pavement, snakemake.params.solver, snakemake.params.cache, site)
speeds = sorted(
    set(map(float, snakemake.params.calibration_speeds)) | set(map(float, snakemake.params.validation_speeds))
)
results = {
    method: calibration.CalibrationResult.from_json(path)
    for method, path in zip(snakemake.params.methods, snakemake.input.calibrations)
}
# every method's runs are independent: the cache misses run as one batch (the same SN as single runs)
prefetch(simulate, [(v, res.params) for res in results.values() for v in speeds])
runs = {}
for method, res in results.items():
    runs[method] = calibration.simulate_speeds(simulate, res.params, speeds)
    log.info("%s %s: %s", site, method, runs[method][["speed_kmh", "sn_sim"]].to_dict("list"))
measured = {site: measured_points(pd.read_parquet(snakemake.input.dft), site)}
table = calibration.validation_table(
    {site: runs},
    measured,
    calibration_speeds_kmh=snakemake.params.calibration_speeds,
    validation_speeds_kmh=snakemake.params.validation_speeds,
)
write_parquet(snakemake.output.table, table)
