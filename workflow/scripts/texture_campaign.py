"""Snakemake adapter: campaign texture table with metadata, Table 4 statistics, distributions figure."""

import pandas as pd

from skidsim import texture
from skidsim.plotting.texture import plot_campaign_distributions
from skidsim.runlog import setup_logging, write_csv, write_parquet

log = setup_logging(snakemake.log[0])
sites = pd.read_parquet(snakemake.input.ingest)
long = pd.concat([pd.read_parquet(p) for p in snakemake.input.tables], ignore_index=True)
wide = texture.campaign_table(long, sites)
table4 = texture.table4_statistics(wide)
write_parquet(snakemake.output.long, long)
write_parquet(snakemake.output.wide, wide)
write_csv(snakemake.output.table4, table4)
plot_campaign_distributions(wide, snakemake.output.figure)
log.info("campaign texture table: %d sites x %d columns", *wide.shape)
