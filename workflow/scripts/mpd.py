"""Snakemake adapter: mean profile depth (ISO 13473-1:2019) and ETD of one scan."""
import dataclasses

from skidsim import texture
from skidsim.runlog import setup_logging, write_json
from skidsim.texture import TextureOptions
from skidsim.workflow_support import load_surfaces

log = setup_logging(snakemake.log[0])
o = TextureOptions(**snakemake.params.cfg)
clean = load_surfaces(snakemake.input.surfaces)["clean"]
res = texture.mean_profile_depth(clean, axis=o.mpd_axis)
out = dataclasses.asdict(res)
out["site"] = snakemake.wildcards.site
write_json(snakemake.output.mpd, out)
log.info("MPD %.3f mm", res.mpd_mm)
