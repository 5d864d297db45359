"""Snakemake adapter: despeckle a scan, measure its quality and check it against the configured limits, fill
invalid points. The limits come from the config (not the rule's params): changing one re-runs only the campaign's
scan_quality rule, which applies the limits again to every site's measures."""

import skidsim._lean  # noqa: F401  (first: SciPy imports without docstring parsing; start-up only)
from skidsim.allocator import scan_process_memory
from skidsim.runlog import setup_logging, write_json
from skidsim.scans import read_scan, save_surfaces
from skidsim.texture import TextureOptions, despeckle_detail, fill_invalid
from skidsim.texture.quality import QualityOptions, check_quality, scan_quality

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
site = snakemake.wildcards.site
o = TextureOptions(**snakemake.params.cfg)
qo = QualityOptions.from_dict(snakemake.config.get("quality"), strip_length_mm=snakemake.config["mesh"]["length_mm"])
surface = read_scan(snakemake.input.scan)
if o.crop_y_mm:  # quick configuration: a centred band of rows (every later texture and FE step sees only it)
    full_shape = surface.shape
    surface = surface.crop_y_centred(o.crop_y_mm)
    log.info("cropped to the centred %.1f mm band of rows: %s of %s points", o.crop_y_mm, surface.shape, full_shape)
invalid = surface.invalid_fraction
res = despeckle_detail(surface, method=o.despeckle_method, k=o.despeckle_k, axis=o.despeckle_axis)
q = scan_quality(site, surface, res.mask, res.step_mm, res.step_source, qo.min_column_valid_pct)
write_json(snakemake.output.quality, {**q.to_dict(), "method": o.despeckle_method})
check_quality(q, qo, log)  # action stop: raises ScanQualityError naming the site, measure, value and limit
filled = fill_invalid(res.surface, method=o.fill)
save_surfaces(snakemake.output.surfaces, {"clean": filled})
write_json(
    snakemake.output.stats,
    {
        "site": site,
        "method": o.despeckle_method,
        "k": o.despeckle_k,
        "n_points": int(surface.heights.size),
        "n_replaced": res.n_replaced,
        "invalid_fraction": invalid,
        "height_step_mm": res.step_mm,
        "height_step_source": res.step_source,
        "dx_mm": surface.dx,
        "dy_mm": surface.dy,
    },
)
log.info(
    "%s: %d points replaced (%s), %.3f %% invalid filled; height step %.4g mm (%s)",
    site,
    res.n_replaced,
    o.despeckle_method,
    100 * invalid,
    res.step_mm,
    res.step_source,
)
