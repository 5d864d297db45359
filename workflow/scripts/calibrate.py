"""Snakemake adapter: back-calculate one site's friction law with one method (study | ours)."""
import pandas as pd

from skidsim import calibration
from skidsim.runlog import setup_logging, write_parquet
from skidsim.workflow_support import measured_points, site_simulator

log = setup_logging(snakemake.log[0])
site, method = snakemake.wildcards.site, snakemake.wildcards.method
cfg = snakemake.params.calibration
simulate, cache, scfg = site_simulator(snakemake.input.pavement, snakemake.params.solver, snakemake.params.cache,
                                       site)
log.info("%s: method %s, solver element %.2f mm, slide %.1f mm, %d cached FE evaluations", site, method,
         scfg.element_mm, scfg.slide_length_mm, len(cache))
points = pd.read_parquet(snakemake.input.dft)
measured = measured_points(points, site)
speeds = [float(v) for v in snakemake.params.speeds]
if method == "study":
    c = cfg["study"]
    intervals = {k: tuple(v) for k, v in c["intervals"].items()}
    start = (c["start"]["mu_s"], c["start"]["mu_k"], c["start"]["alpha"])
    order = (("mu_k", max(speeds)), ("mu_s", min(speeds)), ("alpha", sorted(speeds)[1]))
    result = calibration.calibrate_study(simulate, {v: measured[v] for v in speeds}, intervals=intervals,
                                         start=start, tol=c["tol"], max_iter=c["max_iter"], order=order,
                                         source=snakemake.input.dft)
else:
    c = cfg["ours"]
    traces = pd.read_parquet(snakemake.input.traces)
    trace = traces[traces["site"] == site][["speed_kmh", "mu"]].sort_values("speed_kmh")
    prior = None
    if snakemake.input.prior:
        refs = [calibration.CalibrationResult.from_json(p) for p in snakemake.input.prior]
        try:
            prior = calibration.surrogate_prior(refs)
        except ValueError as exc:  # e.g. no reference site converged: go on without a prior, say so
            log.warning("%s: no surrogate prior (%s); calibrating with a pilot run", site, exc)
        else:
            log.info("%s: surrogate prior from %d reference site(s): b %s, slip offsets %s km/h at %s km/h", site,
                     prior["n_sites"], [round(x, 4) for x in prior["b"]],
                     [round(x, 2) for x in prior["slip_offsets_kmh"]], prior["speeds_kmh"])
    fit_range = tuple(c["fit_range_kmh"]) if c.get("fit_range_kmh") else None
    result = calibration.calibrate_fast(simulate, trace, speeds_kmh=speeds, tol=c["tol"],
                                        max_fe_runs=c["max_fe_runs"], model=c["model"], fit_range_kmh=fit_range,
                                        source=snakemake.input.traces, prior=prior)
log.info("%s %s: %s; %d FE runs, %d steps, converged=%s %s", site, method, result.params, result.n_fe_runs,
         result.n_steps, result.converged, result.message)
write_parquet(snakemake.output.history, result.history.assign(site=site, method=method))
result.to_json(snakemake.output.result)
