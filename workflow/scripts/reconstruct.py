"""Snakemake adapter: pavement strip -> rigid FE heightfield, STL/gmsh/VTU exports, CalculiX/ABAQUS decks, figures."""
from pathlib import Path

from skidsim.exports import write_model_bundle
from skidsim.friction import ExponentialDecay
from skidsim.plotting.mesh import plot_fe_model, plot_reconstruction
from skidsim.reconstruct import pavement_strip
from skidsim.runlog import setup_logging
from skidsim.slidermesh import SliderMesh
from skidsim.workflow_support import load_surfaces, solver_config

log = setup_logging(snakemake.log[0])
m = snakemake.params.mesh
clean = load_surfaces(snakemake.input.surfaces)["clean"]
hf = pavement_strip(clean, length_mm=m["length_mm"], width_mm=m["width_mm"], x0_mm=m.get("x0_mm"),
                    y0_mm=m.get("y0_mm"), resolution_mm=m["resolution_mm"], smoothing=m["smoothing"],
                    base_depth_mm=m["base_depth_mm"])
scfg = solver_config(snakemake.params.solver)
slider = SliderMesh.box(scfg.slider_length_mm, scfg.slider_width_mm, scfg.slider_thickness_mm, scfg.element_mm)
start = snakemake.params.friction_start
law = ExponentialDecay(start["mu_s"], start["mu_k"], start["alpha"])  # decks are re-written after calibration
paths = write_model_bundle(hf, slider, law, Path(snakemake.output.pavement).parent, load_n=scfg.load_n,
                           speed_kmh=m["inp_speed_kmh"], gmsh_layers=m["gmsh_layers"])
plot_reconstruction(clean, hf, snakemake.output.reconstruction)
plot_fe_model(hf, slider, snakemake.output.figure)
log.info("heightfield %s, exports %s", hf.shape, ", ".join(str(p) for p in paths.values()))
