"""Snakemake adapter: generate one synthetic site (scan X3P, DFT trace CSV, ground truth JSON)."""

import skidsim._lean  # noqa: F401  (first: SciPy imports without docstring parsing; start-up only)
from skidsim.allocator import scan_process_memory
from skidsim.config import synthetic_config
from skidsim.generators import default as synthetic
from skidsim.runlog import setup_logging

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
cfg = synthetic_config(snakemake.config)
design = synthetic.design_campaign(cfg).set_index("site")
row = design.loc[snakemake.wildcards.site].copy()
row["site"] = snakemake.wildcards.site
log.info("generating site %s (section %s)", row["site"], row["section"])
data = synthetic.generate_site(row, cfg)
synthetic.write_site(data, snakemake.output.scan, snakemake.output.dft, snakemake.output.truth)
log.info("done: %s", snakemake.output.scan)
