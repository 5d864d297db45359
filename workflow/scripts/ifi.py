"""Snakemake adapter: the IFI (ASTM E1960) of each site from its mpd.json and its DFT trace at 20 km/h."""

import json
from pathlib import Path

import pandas as pd

from skidsim import ifi
from skidsim.runlog import setup_logging, write_csv

log = setup_logging(snakemake.log[0])
mpd = {}
for path in snakemake.input.mpd:
    d = json.loads(Path(path).read_text())
    mpd[d.get("site") or Path(path).parent.name] = float("nan") if d["mpd_mm"] is None else float(d["mpd_mm"])
traces = pd.read_parquet(snakemake.input.traces)
traces = traces[traces["site"].isin(mpd)]
dft20 = ifi.dft20_of_traces(traces, snakemake.params.smooth_window_kmh)
table = ifi.ifi_table(mpd, dft20)
write_csv(snakemake.output.ifi, table)
n_na = int(table["f60"].isna().sum())
if n_na:
    log.warning(
        "IFI not available for %d site(s) without an MPD: %s", n_na, ", ".join(table.loc[table["f60"].isna(), "site"])
    )
log.info(
    "IFI of %d sites: F60 %.3f .. %.3f, Sp %.1f .. %.1f km/h",
    len(table),
    table["f60"].min(),
    table["f60"].max(),
    table["sp_kmh"].min(),
    table["sp_kmh"].max(),
)
