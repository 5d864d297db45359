"""Snakemake adapter: the study's Table 3 areal parameters for raw, macro and micro texture (long form)."""

import json

import numpy as np

import skidsim._lean  # noqa: F401  (first: SciPy imports without docstring parsing; start-up only)
from skidsim import texture
from skidsim.allocator import scan_process_memory
from skidsim.runlog import setup_logging, write_parquet
from skidsim.scans import load_surfaces
from skidsim.texture import MPDResult, TextureOptions

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
site = snakemake.wildcards.site
o = TextureOptions(**snakemake.params.cfg)
bands = load_surfaces(snakemake.input.bands)
params = texture.band_parameters(bands, o)
mpd_dict = json.loads(open(snakemake.input.mpd).read())
mpd_dict["msd_mm"] = np.asarray(mpd_dict.get("msd_mm") or [], dtype=float)
mpd = MPDResult(**{k: v for k, v in mpd_dict.items() if k in MPDResult.__dataclass_fields__})
table = texture.texture_table(site, params, mpd)
write_parquet(snakemake.output.table, table)
log.info("%s: %d values", site, len(table))
