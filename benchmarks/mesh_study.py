"""Mesh study like the study's Figure 9: SN vs element size at 20/40/60 km/h, error against the finest mesh.

Usage::

    python benchmarks/mesh_study.py OUT.csv OUT.png [--sizes MM ...] [--speeds KMH ...] [--slide-mm MM]
        [--window-mm MM] [--mass-scaling S] [--pavement random|sinusoid|PATH.npz] [--contact-gap vertical|normal]
        [--penalty-length-mm MM] [--friction-models stick_limit penalty] [--slide-damping-model mass|rayleigh]
        [--slide-damping-per-s 1/S] [--loss-factor ETA] [--loss-band-hz LOW HIGH] [--friction-stiffness-pa-per-m C_T]

Every default is the library's: the sizes and speeds of :class:`~skidsim.solver.mesh_study.MeshStudyOptions`
(the workflow's ``mesh_study`` section), the contact, friction and damping of :class:`SolverConfig`; the study's
Figure 9 went down to 0.3 mm (``--sizes 2 1.5 1 0.75 0.5 0.4 0.3``).

Friction law: the study's mesh-study parameters mu_s 0.4, mu_k 0.35, alpha 0.6 s/m. Pavement: the seeded
``RandomTexture`` sampled at 0.1 mm into a Heightfield (default), ``sinusoid`` (analytic, for smoke tests) or a
Heightfield ``.npz`` written by skidsim.reconstruct (``--pavement PATH``).
Long-running at full settings (on site E1-1 the 0.3 mm mesh at 20 km/h over a 50 mm slide alone takes ~8 min of
one core); the workflow may run it as an optional rule. Writes the CSV and the PNG atomically.
``--contact-gap`` and ``--penalty-length-mm`` set the contact options of :class:`SolverConfig`.
``--friction-models`` runs the whole study once per friction model (``friction_model`` of :class:`SolverConfig`; the
CSV has a ``friction_model`` column, the PNG gets one file per model: ``OUT_<model>.png``); the damping options set
the slide damping of every run. With exactly three element sizes the Richardson estimate of the converged SN per
(model, speed) and the error of each size against it are printed and written next to the CSV as
``OUT_richardson.csv`` (columns friction_model, slide_damping_model, speed_kmh, sn_converged, order, monotone,
sn_<h>mm, error_pct_<h>mm, change_pct_<coarse>_to_<fine>mm = SN change between consecutive sizes in %).
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
from skidsim.solver.mesh_study import MeshStudyOptions, mesh_study, richardson
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
    cfg, study = SolverConfig(), MeshStudyOptions()  # every default below is the library's
    ap.add_argument("--sizes", type=float, nargs="+", default=list(study.sizes_mm), help="element sizes, mm")
    ap.add_argument("--speeds", type=float, nargs="+", default=list(study.speeds_kmh), help="km/h")
    ap.add_argument("--slide-mm", type=float, default=cfg.slide_length_mm)
    ap.add_argument("--window-mm", type=float, default=cfg.window_start_mm)
    ap.add_argument("--mass-scaling", type=float, default=cfg.mass_scaling)
    ap.add_argument("--pavement", default="random")
    ap.add_argument("--contact-gap", default=cfg.contact_gap, choices=["vertical", "normal"])
    ap.add_argument("--penalty-length-mm", type=float, default=cfg.penalty_length_mm)
    ap.add_argument("--friction-models", nargs="+", default=[cfg.friction_model], choices=["stick_limit", "penalty"])
    ap.add_argument("--slide-damping-model", default=cfg.slide_damping_model, choices=["mass", "rayleigh"])
    ap.add_argument("--slide-damping-per-s", type=float, default=cfg.slide_damping_per_s)
    ap.add_argument("--loss-factor", type=float, default=cfg.loss_factor)
    ap.add_argument("--loss-band-hz", type=float, nargs=2, default=list(cfg.loss_band_hz))
    ap.add_argument("--friction-stiffness-pa-per-m", type=float, default=cfg.friction_stiffness_pa_per_m)
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    pav = load_pavement(a.pavement)
    base = SolverConfig(
        slide_length_mm=a.slide_mm,
        window_start_mm=a.window_mm,
        mass_scaling=a.mass_scaling,
        contact_gap=a.contact_gap,
        penalty_length_mm=a.penalty_length_mm,
        progress_every_s=60,
        slide_damping_model=a.slide_damping_model,
        slide_damping_per_s=a.slide_damping_per_s,
        loss_factor=a.loss_factor,
        loss_band_hz=tuple(a.loss_band_hz),
        friction_stiffness_pa_per_m=a.friction_stiffness_pa_per_m,
    )
    csv = Path(a.csv)
    tables = []
    for model in a.friction_models:
        t = mesh_study(
            pav, a.sizes, a.speeds, base=base.replace(friction_model=model), log=logging.getLogger("mesh_study")
        )
        tables.append(t)
        write_csv(csv, pd.concat(tables, ignore_index=True))  # after every model: partial results survive
        png = Path(a.png)
        plot_mesh_study(t, png if len(a.friction_models) == 1 else png.with_name(f"{png.stem}_{model}{png.suffix}"))
    t = pd.concat(tables, ignore_index=True)
    print(t.to_string(index=False))
    if len(set(a.sizes)) == 3:
        rt = richardson_table(t)
        write_csv(csv.with_name(f"{csv.stem}_richardson.csv"), rt)
        print(rt.to_string(index=False))
    return 0


def richardson_table(t: pd.DataFrame) -> pd.DataFrame:
    """Richardson estimate per (friction model, speed) of a three-size mesh study table (see the module doc)."""
    rows = []
    for (model, v), g in t.groupby(["friction_model", "speed_kmh"], sort=False):
        g = g.sort_values("element_mm", ascending=False)
        h, sn = g["element_mm"].to_list(), g["sn"].to_list()
        est = richardson(h, sn)
        row = dict(
            friction_model=model,
            slide_damping_model=g["slide_damping_model"].iloc[0],
            speed_kmh=v,
            sn_converged=est["value"],
            order=est["order"],
            monotone=est["monotone"],
        )
        row.update({f"sn_{hi:g}mm": s for hi, s in zip(h, sn)})
        row.update({f"error_pct_{hi:g}mm": e for hi, e in zip(h, est["error_pct"])})
        row.update({f"change_pct_{h[i]:g}_to_{h[i + 1]:g}mm": 100.0 * (sn[i + 1] / sn[i] - 1.0) for i in range(2)})
        rows.append(row)
    return pd.DataFrame(rows)


if __name__ == "__main__":
    sys.exit(main())
