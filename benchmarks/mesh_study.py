"""Mesh study like the study's Figure 9: SN vs element size at 20/40/60 km/h, error against the finest mesh.

Usage::

    python benchmarks/mesh_study.py OUT.csv OUT.png [--sizes 2 1.5 1 0.75 0.5 0.4 0.3] [--speeds 20 40 60]
        [--slide-mm 114.3] [--window-mm 5] [--mass-scaling 1] [--pavement random|sinusoid|PATH.npz]
        [--contact-gap vertical|normal] [--penalty-length-mm MM]

Friction law: the study's mesh-study parameters mu_s 0.4, mu_k 0.35, alpha 0.6 s/m. Pavement: the seeded
``RandomTexture`` sampled at 0.1 mm into a Heightfield (default), ``sinusoid`` (analytic, for smoke tests) or a
Heightfield ``.npz`` written by skidsim.reconstruct (``--pavement PATH``).
Long-running at full settings (on site E1-1 the 0.3 mm mesh at 20 km/h over a 50 mm slide alone takes ~8 min of
one core); the workflow may run it as an optional rule. Writes the CSV and the PNG atomically.
``--contact-gap`` and ``--penalty-length-mm`` set the contact options of :class:`SolverConfig` (defaults: the
vertical gap and the element-height penalty).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import pandas as pd

from skidsim.plotting.solver import plot_mesh_study
from skidsim.runlog import write_csv
from skidsim.solver import RandomTexture, SinusoidalSurface, SolverConfig
from skidsim.solver.mesh_study import mesh_study
from skidsim.solver.surfaces import to_heightfield


def load_pavement(spec: str):
    if spec == "sinusoid":  # cheap analytic texture (smoke tests)
        return SinusoidalSurface(amplitude_m=0.1e-3, wavelength_x_m=4e-3, wavelength_y_m=5e-3)
    if spec == "random":
        return to_heightfield(RandomTexture(), 0.1e-3, name="RandomTexture(seed=0)")
    from skidsim.reconstruct import Heightfield

    return Heightfield.from_npz(spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("png")
    ap.add_argument("--sizes", type=float, nargs="+", default=[2.0, 1.5, 1.0, 0.75, 0.5, 0.4, 0.3])
    ap.add_argument("--speeds", type=float, nargs="+", default=[20.0, 40.0, 60.0])
    ap.add_argument("--slide-mm", type=float, default=114.3)
    ap.add_argument("--window-mm", type=float, default=5.0)
    ap.add_argument("--mass-scaling", type=float, default=1.0)
    ap.add_argument("--pavement", default="random")
    ap.add_argument("--contact-gap", default="vertical", choices=["vertical", "normal"])
    ap.add_argument("--penalty-length-mm", type=float, default=None)
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    pav = load_pavement(a.pavement)
    base = SolverConfig(slide_length_mm=a.slide_mm, window_start_mm=a.window_mm, mass_scaling=a.mass_scaling,
                        contact_gap=a.contact_gap, penalty_length_mm=a.penalty_length_mm, progress_every_s=60)
    t = mesh_study(pav, a.sizes, a.speeds, base=base, log=logging.getLogger("mesh_study"))
    csv = Path(a.csv)
    csv.parent.mkdir(parents=True, exist_ok=True)
    write_csv(csv, t)
    plot_mesh_study(t, a.png)
    print(t.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
