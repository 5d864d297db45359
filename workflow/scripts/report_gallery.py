"""Snakemake adapter: reduced JPEG copies of every site's Figure 7, reconstruction and FE model for the report."""

from skidsim.plotting.gallery import ThumbnailOptions, write_gallery
from skidsim.runlog import setup_logging

log = setup_logging(snakemake.log[0])
options = ThumbnailOptions()
for kind in ("figure7", "reconstruction", "fe_model"):
    sources = dict(zip(snakemake.params.sites, snakemake.input[kind], strict=True))
    written = write_gallery(sources, snakemake.output[kind], options)
    log.info("report gallery %s: %d figures, %.1f MB", kind, len(written), sum(p.stat().st_size for p in written) / 1e6)
