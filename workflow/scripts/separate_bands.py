"""Snakemake adapter: form removal and Butterworth separation into raw, macro and micro texture."""

import skidsim._lean  # noqa: F401  (first: SciPy imports without docstring parsing; start-up only)
from skidsim import texture
from skidsim.allocator import scan_process_memory
from skidsim.runlog import setup_logging
from skidsim.scans import load_surfaces, save_surfaces
from skidsim.texture import TextureOptions

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
o = TextureOptions(**snakemake.params.cfg)
clean = load_surfaces(snakemake.input.surfaces)["clean"]
bands = texture.separate_bands(clean, macro=tuple(o.macro_mm), order=o.butterworth_order, form=o.form, fill=o.fill)
save_surfaces(snakemake.output.bands, bands)
log.info("bands written: %s", ", ".join(bands))
