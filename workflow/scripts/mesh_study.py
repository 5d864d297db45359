"""Snakemake adapter: the mesh study (study Figure 9) on one site's pavement, the study's friction law."""

from skidsim.config import mesh_study_solver_config
from skidsim.plotting.solver import plot_mesh_study
from skidsim.reconstruct import Heightfield
from skidsim.runlog import setup_logging, write_csv
from skidsim.solver.mesh_study import MeshStudyOptions, mesh_study

log = setup_logging(snakemake.log[0])
cfg = MeshStudyOptions.from_dict(snakemake.params.cfg)
pav = Heightfield.from_npz(snakemake.input.pavement)
base = mesh_study_solver_config(snakemake.params.solver)  # reference preset, the campaign's load and contact gap
log.info("mesh study on site %s: sizes %s mm, speeds %s km/h", snakemake.params.site, cfg.sizes_mm, cfg.speeds_kmh)
table = mesh_study(pav, cfg.sizes_mm, cfg.speeds_kmh, base=base, log=log)
table.insert(0, "site", snakemake.params.site)
write_csv(snakemake.output.table, table)
plot_mesh_study(table, snakemake.output.figure)
log.info("\n%s", table[["speed_kmh", "element_mm", "sn", "error_pct", "wall_s"]].to_string(index=False))
