"""Snakemake adapter: the PIARC/IFI speed model beside the FE-calibrated laws at the validation speeds."""

import pandas as pd

from skidsim import ifi
from skidsim.plotting.calibration import plot_ifi_comparison
from skidsim.runlog import setup_logging, write_csv, write_parquet

log = setup_logging(snakemake.log[0])
table = pd.read_csv(snakemake.input.ifi)
vtable = pd.read_parquet(snakemake.input.validation)
model = ifi.model_validation_rows(table, vtable)
rows = pd.concat([vtable[model.columns], model], ignore_index=True)
stats = ifi.comparison_statistics(rows, snakemake.params.validation_speeds)
write_csv(snakemake.output.table, stats)
write_parquet(snakemake.output.rows, rows)
plot_ifi_comparison(rows, stats, snakemake.output.figure)
log.info("\n%s", stats.to_string())
for line in ifi.wins(stats) or ["the PIARC/IFI model has a higher RMSE than every FE-calibrated method everywhere"]:
    log.info("%s", line)
