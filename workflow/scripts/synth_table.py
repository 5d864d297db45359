"""Snakemake adapter: write the synthetic campaign's sites.csv (the data contract)."""

from pathlib import Path

from skidsim.config import synthetic_config
from skidsim.generators import default as synthetic
from skidsim.runlog import setup_logging

log = setup_logging(snakemake.log[0])
design = synthetic.design_campaign(synthetic_config(snakemake.config))
synthetic.write_sites_csv(design, Path(snakemake.output.sites).parent, snakemake.output.sites)
log.info("wrote %s (%d sites)", snakemake.output.sites, len(design))
