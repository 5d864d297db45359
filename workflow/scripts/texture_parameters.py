"""Snakemake adapter: the study's Table 3 areal parameters for raw, macro and micro texture (long form)."""
import json

from skidsim import texture
from skidsim.runlog import setup_logging, write_parquet
from skidsim.texture import MPDResult
from skidsim.workflow_support import load_surfaces

log = setup_logging(snakemake.log[0])
site = snakemake.wildcards.site
bands = load_surfaces(snakemake.input.bands)
opts = snakemake.params.cfg
params = {}
for band in ("raw", "macro", "micro"):
    params[band] = texture.areal_parameters(bands[band], band, **opts)
    log.info("%s: %d parameters", band, len(params[band]))
mpd_dict = json.loads(open(snakemake.input.mpd).read())
mpd = MPDResult(**{k: v for k, v in mpd_dict.items() if k in MPDResult.__dataclass_fields__})
table = texture.texture_table(site, params, mpd)
write_parquet(snakemake.output.table, table)
