"""Snakemake adapter: the study's Figure 7 (a-b) for one site."""

from skidsim.allocator import scan_process_memory
from skidsim.plotting.texture import plot_figure7
from skidsim.runlog import setup_logging
from skidsim.scans import load_surfaces, read_scan

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
raw = read_scan(snakemake.input.scan)
clean = load_surfaces(snakemake.input.surfaces)["clean"]
bands = load_surfaces(snakemake.input.bands, names=["macro", "micro"])  # not the raw band: the figure shows the scan
plot_figure7(raw, clean, bands["macro"], bands["micro"], snakemake.output.figure)
