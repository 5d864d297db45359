"""Snakemake adapter: validate the campaign against the data contract; write the site table and DFT points."""
import pandas as pd

from skidsim.campaign import load_campaign
from skidsim.runlog import setup_logging, write_parquet

log = setup_logging(snakemake.log[0])
check = snakemake.params.check_scans
camp = load_campaign(snakemake.params.campaign, speeds_kmh=snakemake.params.speeds,
                     check_scans=check if check else False)
sites = camp.sites.copy()
sites["scan"] = sites["scan"].astype(str)
sites["dft"] = sites["dft"].astype(str)
points = camp.dft_points(snakemake.params.speeds, smooth_window_kmh=snakemake.params.smooth_window_kmh)
traces = pd.concat([pd.DataFrame({"site": site, "speed_kmh": tr.speeds_kmh, "mu": tr.mu})
                    for site, tr in camp.traces.items()], ignore_index=True)
write_parquet(snakemake.output.traces, traces)
write_parquet(snakemake.output.dft, points)
write_parquet(snakemake.output.sites, sites)
log.info("campaign %s: %d sites, metadata columns %s", snakemake.params.campaign, len(sites), camp.metadata_columns)
