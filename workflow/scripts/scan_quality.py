"""Snakemake adapter: the campaign's scan-quality table (one row per site, the limits applied) and its figure."""

import json
from dataclasses import asdict, fields

from skidsim.plotting.texture import plot_scan_quality
from skidsim.runlog import setup_logging, write_csv
from skidsim.texture.quality import QualityOptions, ScanQuality, quality_table

log = setup_logging(snakemake.log[0])
opt = QualityOptions.from_dict(snakemake.params.quality, strip_length_mm=snakemake.params.strip_length_mm)
names = {f.name for f in fields(ScanQuality)}
measures, methods = [], []
for path in snakemake.input.quality:
    with open(path, encoding="utf-8") as fh:
        d = json.load(fh)
    measures.append(ScanQuality(**{k: v for k, v in d.items() if k in names}))
    methods.append(d.get("method"))
table = quality_table(measures, opt, log)  # action stop: raises naming every flagged site, measure, value, limit
table.insert(len(table.columns) - 2, "despeckle_method", methods)
write_csv(snakemake.output.table, table)
plot_scan_quality(table, asdict(opt), snakemake.output.figure)
log.info("scan quality: %d sites, %d flagged", len(table), int((table["status"] != "ok").sum()))
