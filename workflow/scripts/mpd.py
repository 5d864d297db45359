"""Snakemake adapter: mean profile depth (ISO 13473-1:2019) and ETD of one scan; the texture.mpd_* keys set the
procedure (segment length, spike factor, reference plates, dropout limit). A scan shorter than one segment gives
MPD null and one warning in the log."""

import dataclasses

import skidsim._lean  # noqa: F401  (first: SciPy imports without docstring parsing; start-up only)
from skidsim import texture
from skidsim.allocator import scan_process_memory
from skidsim.runlog import setup_logging, write_json
from skidsim.scans import load_surfaces
from skidsim.texture import TextureOptions

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
o = TextureOptions(**snakemake.params.cfg)
clean = load_surfaces(snakemake.input.surfaces)["clean"]
res = texture.mean_profile_depth(clean, **o.mpd_kwargs())
out = dataclasses.asdict(res)
out["site"] = snakemake.wildcards.site
write_json(snakemake.output.mpd, out)
log.info("MPD %.3f mm (%d of %d segments valid)", res.mpd_mm, res.n_segments - res.n_invalid_segments, res.n_segments)
