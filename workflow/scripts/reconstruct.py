"""Snakemake adapter: pavement strip -> rigid FE heightfield, STL/gmsh/VTU exports, CalculiX/ABAQUS decks, figures."""

from pathlib import Path

from skidsim.allocator import scan_process_memory
from skidsim.config import solver_config
from skidsim.exports import write_model_bundle
from skidsim.friction import ExponentialDecay
from skidsim.plotting.mesh import plot_fe_model, plot_reconstruction
from skidsim.reconstruct import MeshOptions, pavement_strip
from skidsim.runlog import setup_logging
from skidsim.scans import load_surfaces
from skidsim.slidermesh import SliderMesh

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
m = MeshOptions.from_dict(snakemake.params.mesh)
clean = load_surfaces(snakemake.input.surfaces)["clean"]
hf = pavement_strip(clean, **m.strip_kwargs())
scfg = solver_config(snakemake.params.solver)
slider = SliderMesh.box(scfg.slider_length_mm, scfg.slider_width_mm, scfg.slider_thickness_mm, scfg.element_mm)
start = snakemake.params.friction_start
law = ExponentialDecay(start["mu_s"], start["mu_k"], start["alpha"])  # decks are re-written after calibration
paths = write_model_bundle(
    hf,
    slider,
    law,
    Path(snakemake.output.pavement).parent,
    load_n=scfg.load_n,
    speed_kmh=m.inp_speed_kmh,
    gmsh_layers=m.gmsh_layers,
)
plot_reconstruction(clean, hf, snakemake.output.reconstruction)
plot_fe_model(hf, slider, snakemake.output.figure)
log.info("heightfield %s, exports %s", hf.shape, ", ".join(str(p) for p in paths.values()))
