"""Mesh study like the study's Figure 9: SN vs element size at 20/40/60 km/h, error against the finest mesh.

Usage::

    python benchmarks/mesh_study.py OUT.csv OUT.png [--sizes 2 1.5 1 0.75 0.5 0.4 0.3] [--speeds 20 40 60]
        [--slide-mm 114.3] [--window-mm 5] [--mass-scaling 1] [--pavement random|sinusoid|PATH.npz]

Friction law: the study's mesh-study parameters mu_s 0.4, mu_k 0.35, alpha 0.6 s/m. Pavement: the seeded
``RandomTexture`` sampled at 0.1 mm into a Heightfield (default), ``sinusoid`` (analytic, for smoke tests) or a
Heightfield ``.npz`` written by skidsim.reconstruct (``--pavement PATH``).
Long-running at full settings (the 0.3 mm mesh at 20 km/h alone is ~10 min on one core); the workflow may run
it as an optional rule. Writes the CSV and the PNG atomically.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

import pandas as pd

from skidsim.friction import ExponentialDecay
from skidsim.plotting.solver import plot_mesh_study
from skidsim.solver import RandomTexture, SinusoidalSurface, SolverConfig, simulate
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
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    pav = load_pavement(a.pavement)
    law = ExponentialDecay(0.4, 0.35, 0.6)
    rows = []
    for v in a.speeds:
        for h in sorted(a.sizes, reverse=True):
            cfg = SolverConfig(element_mm=h, slide_length_mm=a.slide_mm, window_start_mm=a.window_mm,
                               mass_scaling=a.mass_scaling, progress_every_s=60)
            r = simulate(pav, v, law, cfg)
            rows.append(dict(speed_kmh=v, element_mm=h, sn=r.sn, wall_s=r.wall_s, n_steps=r.n_steps,
                             n_elements=r.n_elements, dt_s=r.dt_s, element_steps_per_s=r.element_steps_per_s,
                             slide_mm=r.slide_length_mm, energy_residual_frac=r.energy_residual_fraction(),
                             mean_contact_area_mm2=r.mean_contact_area_mm2, max_penetration_um=r.max_penetration_um,
                             mu_at_speed=float(law.mu_kmh(v))))
            print(f"{v:5.0f} km/h {h:5.2f} mm: SN {r.sn:.4f}  {r.wall_s:7.1f} s  {r.n_steps} steps", flush=True)
    t = pd.DataFrame(rows)
    finest = t.loc[t.groupby("speed_kmh")["element_mm"].idxmin(), ["speed_kmh", "sn"]].set_index("speed_kmh")["sn"]
    t["sn_finest"] = t["speed_kmh"].map(finest)
    t["error_pct"] = 100.0 * (t["sn"] - t["sn_finest"]).abs() / t["sn_finest"]
    csv = Path(a.csv)
    csv.parent.mkdir(parents=True, exist_ok=True)
    tmp = csv.with_name(csv.name + ".tmp")
    t.to_csv(tmp, index=False)
    os.replace(tmp, csv)
    plot_mesh_study(t, a.png)
    print(t.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
