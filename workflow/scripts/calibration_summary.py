"""Snakemake adapter: Table 2, the method comparison (FE runs, steps, wall time, fit), Figure 10, curves.

With an input named ``ifi`` (results/ifi/ifi.csv), the PIARC/IFI speed model (method ``piarc_ifi``) is added to
fit_statistics.csv and Figure 10 beside the FE-calibrated methods; validation.parquet stays FE-only.

The per-site identifiability records (written by rule validate_speeds) become identifiability.csv and its figure;
each flagged site gets a WARNING line here and the log ends with the count of flagged sites per flag."""

import json
from pathlib import Path

import pandas as pd

from skidsim import calibration
from skidsim.calibration import identifiability
from skidsim.plotting.calibration import plot_calibration_curves, plot_figure10
from skidsim.plotting.identifiability import plot_identifiability
from skidsim.runlog import setup_logging, write_csv, write_parquet

log = setup_logging(snakemake.log[0])
methods = snakemake.params.methods
results = {}
for path in snakemake.input.calibrations:
    site = Path(path).parent.name
    method = Path(path).stem.removeprefix("calibration_")
    results.setdefault(site, {})[method] = calibration.CalibrationResult.from_json(path)
vtable = pd.concat([pd.read_parquet(p) for p in snakemake.input.validations], ignore_index=True)
comparison = calibration.comparison_table(results, vtable, methods=methods)
t2 = calibration.table2(results, methods=methods)
ifi_csv = getattr(snakemake.input, "ifi", None)
vfig = vtable
if ifi_csv:
    from skidsim import ifi

    model = ifi.model_validation_rows(pd.read_csv(ifi_csv), vtable)
    vfig = pd.concat([vtable[model.columns], model], ignore_index=True)
stats = calibration.figure10_statistics(vfig)
params = pd.DataFrame(
    [
        {
            "site": s,
            "method": m,
            "mu_s": r.params.mu_s,
            "mu_k": r.params.mu_k,
            "alpha": r.params.alpha,
            "converged": r.converged,
        }
        for s, per in results.items()
        for m, r in per.items()
    ]
)
traces = pd.read_parquet(snakemake.input.traces)
measured = {s: g[["speed_kmh", "mu"]].sort_values("speed_kmh") for s, g in traces.groupby("site")}
runs = {s: {m: g[["speed_kmh", "sn_sim"]] for m, g in gs.groupby("method")} for s, gs in vtable.groupby("site")}
# the identifiability records (rule validate_speeds); a caller without them gets the other tables only
records = [json.loads(Path(p).read_text()) for p in (getattr(snakemake.input, "identifiability", None) or [])]
ident = pd.DataFrame([identifiability.table_row(r) for r in records])
if len(ident):
    ident = ident.sort_values(["method", "site"]).reset_index(drop=True)
write_csv(snakemake.output.table2, t2)
write_csv(snakemake.output.comparison, comparison)
write_csv(snakemake.output.stats, stats)
write_parquet(snakemake.output.validation, vtable)
write_parquet(snakemake.output.params, params)
plot_figure10(vfig, snakemake.output.figure10)
plot_calibration_curves(results, measured, snakemake.output.curves, runs=runs)
if records:
    write_csv(snakemake.output.identifiability, ident)
    plot_identifiability(ident, snakemake.output.identifiability_figure, bounds=records[0]["bounds"])
elif hasattr(snakemake.output, "identifiability"):
    raise ValueError(
        "calibration_summary: outputs identifiability.csv/.png declared but no identifiability records "
        "given (input 'identifiability')"
    )
log.info("\n%s", stats.to_string())
for r in records:
    if r["flags"]:
        log.warning(
            "%s %s flagged: %s", r["site"], r["method"], " | ".join(f"{f}: {r['reasons'][f]}" for f in r["flags"])
        )
for m, g in ident.groupby("method") if len(ident) else []:
    counts = ", ".join(f"{f} {int(g[f].sum())}" for f in identifiability.FLAGS)
    log.info(
        "identifiability (%s): %d of %d sites flagged (%s); fit within the trace's noise at %d; mu_s / mu_k / "
        "alpha identified at %d / %d / %d",
        m,
        int((g["n_flags"] > 0).sum()),
        len(g),
        counts,
        int(g["within_noise"].sum()),
        int(g["mu_s_identified"].sum()),
        int(g["mu_k_identified"].sum()),
        int(g["alpha_identified"].sum()),
    )
