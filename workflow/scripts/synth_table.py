"""Snakemake adapter: write the synthetic campaign's sites.csv and the campaign-level truth."""
import json
from pathlib import Path

from skidsim import synthetic
from skidsim.runlog import setup_logging, write_json
from skidsim.workflow_support import synthetic_config

log = setup_logging(snakemake.log[0])
cfg = synthetic_config(snakemake.config)
design = synthetic.design_campaign(cfg)
synthetic.write_sites_csv(design, Path(snakemake.output.sites).parent, snakemake.output.sites)
truth = {"config": cfg, "sites": {Path(p).stem: json.loads(Path(p).read_text()) for p in snakemake.input.truths}}
write_json(snakemake.output.truth, truth)
log.info("wrote %s (%d sites)", snakemake.output.sites, len(design))
