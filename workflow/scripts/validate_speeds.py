"""Snakemake adapter: simulate a site at calibration and validation speeds with each method's parameters; from
those runs and the site's DFT trace, the identifiability record of each method's calibration (no further FE runs;
skidsim.calibration.identifiability.site_record)."""

import pandas as pd

from skidsim import calibration
from skidsim.calibration.cache import prefetch
from skidsim.calibration.site import measured_points, site_simulator
from skidsim.runlog import setup_logging, write_json, write_parquet

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
opts = calibration.IdentifiabilityOptions.from_config(snakemake.params.identifiability)
traces = pd.read_parquet(snakemake.input.traces)
records = {
    method: calibration.site_record(
        res,
        traces,
        table,
        site=site,
        method=method,
        options=opts,
        calibration_speeds_kmh=[float(v) for v in snakemake.params.calibration_speeds],
        validation_speeds_kmh=[float(v) for v in snakemake.params.validation_speeds],
        source=snakemake.input.traces,
        log=log,
    )
    for method, res in results.items()
}
write_parquet(snakemake.output.table, table)
for method, path in zip(snakemake.params.methods, snakemake.output.records):
    write_json(path, records[method])
