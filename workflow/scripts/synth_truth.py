"""Snakemake adapter: gather the per-site ground truth of the synthetic campaign into one JSON."""

import json
from pathlib import Path

from skidsim.config import synthetic_config
from skidsim.runlog import setup_logging, write_json

log = setup_logging(snakemake.log[0])
truth = {
    "config": synthetic_config(snakemake.config),
    "sites": {Path(p).stem: json.loads(Path(p).read_text()) for p in snakemake.input.truths},
}
write_json(snakemake.output.truth, truth)
log.info("wrote %s", snakemake.output.truth)
