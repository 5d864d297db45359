"""Snakemake adapter: predicted vs measured DFT of held-out sites at six speeds (study Figure 11) + error tables."""

import pandas as pd

from skidsim import regression
from skidsim.plotting.regression import plot_figure11
from skidsim.runlog import setup_logging, write_csv

log = setup_logging(snakemake.log[0])
fe = pd.concat([pd.read_parquet(p) for p in snakemake.input.tables], ignore_index=True)
measured = pd.read_parquet(snakemake.input.dft)[["site", "speed_kmh", "mu"]]
best = open(snakemake.input.best_model).read().strip()
tables, summaries = [], []
for model, g in fe.groupby("model", sort=False):
    t = regression.figure11_table(
        g[["site", "speed_kmh", "sn_sim"]].rename(columns={"sn_sim": "predicted"}),
        measured,
        pred_file=f"FE predictions ({model})",
        measured_file=snakemake.input.dft,
    )
    s = regression.figure11_summary(t)
    t.insert(0, "model", model)
    s.insert(0, "model", model)
    tables.append(t)
    summaries.append(s)
    if model == best:
        plot_figure11(t, snakemake.output.figure)
table = pd.concat(tables, ignore_index=True)
summary = pd.concat(summaries, ignore_index=True)
if best not in set(table["model"]):
    raise RuntimeError(f"no FE predictions for the best model {best!r}; models: {sorted(set(table['model']))}")
write_csv(snakemake.output.table, table)
write_csv(snakemake.output.summary, summary)
log.info("\n%s", summary.to_string())
