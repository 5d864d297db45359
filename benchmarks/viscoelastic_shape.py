"""How much a viscoelastic slider bulk (Prony series) changes SN and its speed dependence, on a real pavement.

Usage::

    OMP_NUM_THREADS=1 nice -n 19 python benchmarks/viscoelastic_shape.py PAVEMENT.npz CALIBRATION.json
        [--speeds 20 30 40 50 60 70] [--preset campaign|quick] [--prony-g ...] [--prony-tau-s ...] [--csv OUT.csv]

The friction law is the site's calibrated law (``params`` of a ``calibration_*.json``); the solver is the
workflow's preset (``campaign`` by default) once elastic and once with the Prony series added (default:
:data:`skidsim.criticism.fe_extension.DEFAULT_PRONY`, docs/model-criticism.md "FE extension: viscoelastic slider").
Prints one row per speed: SN elastic, SN viscoelastic, their difference (absolute and %), the viscous
dissipation's share of the friction work, and the wall time of each run (s, one core), then the speed slope of SN
(least squares, per 10 km/h) for both and the wall-time ratio. Writes the table as CSV with ``--csv``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import pandas as pd

from skidsim.config import solver_config
from skidsim.criticism.fe_extension import DEFAULT_PRONY
from skidsim.friction import ExponentialDecay
from skidsim.reconstruct import Heightfield
from skidsim.solver import simulate
from skidsim.solver.config import SolverOptions


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pavement")
    ap.add_argument("calibration")
    ap.add_argument("--speeds", type=float, nargs="+", default=[20, 30, 40, 50, 60, 70])
    ap.add_argument("--preset", default=SolverOptions().preset, choices=["campaign", "reference", "quick"])
    ap.add_argument("--prony-g", type=float, nargs="+", default=list(DEFAULT_PRONY["prony_g"]))
    ap.add_argument("--prony-tau-s", type=float, nargs="+", default=list(DEFAULT_PRONY["prony_tau_s"]))
    ap.add_argument("--csv")
    a = ap.parse_args(argv)

    hf = Heightfield.from_npz(a.pavement)
    with open(a.calibration) as fh:
        p = json.load(fh)["params"]
    law = ExponentialDecay(p["mu_s"], p["mu_k"], p["alpha"])
    elastic = solver_config({"preset": a.preset})
    visco = elastic.replace(prony_g=tuple(a.prony_g), prony_tau_s=tuple(a.prony_tau_s))
    print(
        f"pavement {a.pavement}; law mu_s {law.mu_s:.4f}, mu_k {law.mu_k:.4f}, alpha {law.alpha:.4f} s/m; "
        f"preset {a.preset} (element {elastic.element_mm} mm, slide {elastic.slide_length_mm} mm)"
    )
    print(f"Prony g {tuple(a.prony_g)}, tau {tuple(a.prony_tau_s)} s", flush=True)
    rows = []
    for v in a.speeds:
        row = {"speed_kmh": v}
        for tag, cfg in (("elastic", elastic), ("visco", visco)):
            t0 = time.perf_counter()
            r = simulate(hf, v, law, cfg)
            row[f"sn_{tag}"] = float(r.sn)
            row[f"wall_s_{tag}"] = time.perf_counter() - t0
            row[f"steps_{tag}"] = int(r.n_steps)
            if tag == "visco":
                en = r.energies if hasattr(r, "energies") else {}
                fr = float(en.get("friction", np.nan)) if en else np.nan
                vi = float(en.get("viscous", np.nan)) if en else np.nan
                row["viscous_over_friction"] = vi / fr if fr else np.nan
        row["d_sn"] = row["sn_visco"] - row["sn_elastic"]
        row["d_sn_pct"] = 100 * row["d_sn"] / row["sn_elastic"]
        rows.append(row)
        print(
            f"{v:5.0f} km/h  SN elastic {row['sn_elastic']:.4f}  visco {row['sn_visco']:.4f}  "
            f"d {row['d_sn']:+.4f} ({row['d_sn_pct']:+.2f} %)  viscous/friction {row['viscous_over_friction']:.3f}"
            f"  wall {row['wall_s_elastic']:.1f} / {row['wall_s_visco']:.1f} s",
            flush=True,
        )
    df = pd.DataFrame(rows)
    print()
    print(df.to_string(index=False, float_format=lambda x: f"{x:.4f}"))
    sl_e = np.polyfit(df["speed_kmh"], df["sn_elastic"], 1)[0] * 10
    sl_v = np.polyfit(df["speed_kmh"], df["sn_visco"], 1)[0] * 10
    print(
        f"\nSN slope (least squares): elastic {sl_e:+.5f}, viscoelastic {sl_v:+.5f} per 10 km/h "
        f"(change {sl_v - sl_e:+.5f}); mean |d SN| {df['d_sn'].abs().mean():.4f}; "
        f"range of d SN over speeds {df['d_sn'].max() - df['d_sn'].min():.4f}"
    )
    print(
        f"wall time: elastic {df['wall_s_elastic'].sum():.1f} s, viscoelastic {df['wall_s_visco'].sum():.1f} s, "
        f"ratio {df['wall_s_visco'].sum() / df['wall_s_elastic'].sum():.2f}; steps ratio "
        f"{df['steps_visco'].sum() / df['steps_elastic'].sum():.2f}"
    )
    if a.csv:
        df.to_csv(a.csv, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
