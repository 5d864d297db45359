"""Snakemake adapter: mean profile depth (ISO 13473-1:2019) and ETD of one scan."""
import dataclasses

from skidsim import texture
from skidsim.runlog import setup_logging, write_json
from skidsim.workflow_support import load_surfaces

log = setup_logging(snakemake.log[0])
clean = load_surfaces(snakemake.input.surfaces)["clean"]
res = texture.mean_profile_depth(clean, **snakemake.params.cfg)
out = dataclasses.asdict(res) if dataclasses.is_dataclass(res) else dict(res)
out["site"] = snakemake.wildcards.site
write_json(snakemake.output.mpd, out)
log.info("MPD %.3f mm", res.mpd_mm)
