"""Snakemake adapter: validate the campaign (skidsim.validate at config ingest.check_scans); write the site table
and DFT points. Problems: one line each in the log and on stderr, exit status 1, no traceback."""

import pandas as pd

from skidsim import validate
from skidsim.allocator import scan_process_memory
from skidsim.runlog import setup_logging, write_parquet

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
level = validate.IngestOptions.from_dict(snakemake.config.get("ingest")).level
req = validate.Requirements.from_config(snakemake.config)
camp = validate.check_campaign(snakemake.params.campaign, req, level=level, workers=snakemake.threads)
sites = camp.sites.copy()
sites["scan"] = sites["scan"].astype(str)
sites["dft"] = sites["dft"].astype(str)
points = camp.dft_points(snakemake.params.speeds, smooth_window_kmh=snakemake.params.smooth_window_kmh)
traces = pd.concat(
    [pd.DataFrame({"site": site, "speed_kmh": tr.speeds_kmh, "mu": tr.mu}) for site, tr in camp.traces.items()],
    ignore_index=True,
)
write_parquet(snakemake.output.traces, traces)
write_parquet(snakemake.output.dft, points)
write_parquet(snakemake.output.sites, sites)
log.info(
    "campaign %s: %d sites, metadata columns %s (validated at level %s)",
    snakemake.params.campaign,
    len(sites),
    camp.metadata_columns,
    level,
)
