"""Snakemake adapter: despeckle a scan (limiting filter or robust variant) and fill invalid points."""
from skidsim import texture
from skidsim.runlog import setup_logging, write_json
from skidsim.scans import read_scan
from skidsim.texture import TextureOptions
from skidsim.workflow_support import save_surfaces

log = setup_logging(snakemake.log[0])
o = TextureOptions(**snakemake.params.cfg)
surface = read_scan(snakemake.input.scan)
if o.crop_y_mm:  # quick configuration: a centred band of rows (every later texture and FE step sees only it)
    full_shape = surface.shape
    surface = surface.crop_y_centred(o.crop_y_mm)
    log.info("cropped to the centred %.1f mm band of rows: %s of %s points", o.crop_y_mm, surface.shape, full_shape)
invalid = surface.invalid_fraction
clean, n_replaced = texture.despeckle(surface, method=o.despeckle_method, k=o.despeckle_k, axis=o.despeckle_axis)
filled = texture.fill_invalid(clean, method=o.fill)
save_surfaces(snakemake.output.surfaces, {"clean": filled})
write_json(snakemake.output.stats, {"site": snakemake.wildcards.site, "method": o.despeckle_method,
                                    "k": o.despeckle_k, "n_points": int(surface.heights.size),
                                    "n_replaced": int(n_replaced), "invalid_fraction": invalid,
                                    "dx_mm": surface.dx, "dy_mm": surface.dy})
log.info("%s: %d points replaced, %.3f %% invalid filled", snakemake.wildcards.site, n_replaced, 100 * invalid)
