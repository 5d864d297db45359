"""How smooth is the FE's SN as a function of the friction law? (issue 25, item 2)

One site of an independent campaign (skidsim.generators: chips or spectral), its clean surface cut into the FE
pavement strip as the workflow does (config/config.yaml ``mesh``), the campaign solver preset (or ``--element-mm``
for a coarser slider mesh). At each speed the FE runs the law ``(mu_s, mu_k, alpha)`` and the law with each
parameter moved by ``+-delta`` (mu: ``--dmu``, alpha: ``--dalpha`` s/m). Printed per run: SN, the change of SN
against the base law, the change the law itself makes at the sliding speed (``d mu``) and their ratio; a smooth
response has ratios near the geometric factor SN / mu (about 1) and equal for +delta and -delta. The base law is
run twice (the FE is deterministic: the repeat must give the same SN).

    .venv/bin/python benchmarks/fe_response_smoothness.py --generator chips --site-index 0 --speeds 40 60
        [--friction-model penalty --slide-damping-model rayleigh]   # the contact of docs/solver.md

Units: speeds km/h, alpha s/m, mu and SN dimensionless. Output also as CSV with ``--csv``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from skidsim.friction import ExponentialDecay  # noqa: E402
from skidsim.generators.campaign import design_campaign, generate_site, generator_config  # noqa: E402
from skidsim.reconstruct import pavement_strip  # noqa: E402
from skidsim.solver import SolverConfig  # noqa: E402
from skidsim.solver import simulate as fe_simulate  # noqa: E402
from skidsim.surface import Surface  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generator", choices=["chips", "spectral"], default="chips")
    ap.add_argument(
        "--site-index",
        type=int,
        default=None,
        help="row of the campaign design (default: the site with the largest MPD of the first --sites)",
    )
    ap.add_argument("--sites", type=int, default=12, help="sites of the design to choose from")
    ap.add_argument("--shape", type=int, nargs=2, default=[300, 600], help="scan rows, cols")
    ap.add_argument("--spacing-mm", type=float, default=0.2)
    ap.add_argument("--speeds", type=float, nargs="+", default=[60.0], help="km/h")
    ap.add_argument(
        "--law",
        type=float,
        nargs=3,
        default=[0.85, 0.0, 0.05],
        metavar=("MU_S", "MU_K", "ALPHA"),
        help="base law (default: the independent campaigns' typical calibration, mu_s at its bound)",
    )
    ap.add_argument("--dmu", type=float, default=0.01, help="step of mu_s and mu_k")
    ap.add_argument("--dalpha", type=float, default=0.005, help="step of alpha, s/m")
    ap.add_argument("--element-mm", type=float, default=None, help="slider element size (default: campaign preset)")
    ap.add_argument("--friction-model", choices=["stick_limit", "penalty"], default=None, help="default: the preset's")
    ap.add_argument("--slide-damping-model", choices=["mass", "rayleigh"], default=None, help="default: the preset's")
    ap.add_argument("--csv", type=Path, default=None)
    args = ap.parse_args(argv)

    cfg = generator_config(
        args.generator, {"n_sites": args.sites, "shape": list(args.shape), "spacing_mm": args.spacing_mm}
    )
    design = design_campaign(cfg)
    sites = (
        [generate_site(row, cfg) for _, row in design.iterrows()]
        if args.site_index is None
        else [generate_site(design.iloc[args.site_index], cfg)]
    )
    site = max(sites, key=lambda s: s.truth["texture_measures"]["mpd_mm"])
    mesh = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["mesh"]
    surf = Surface(site.clean, args.spacing_mm, args.spacing_mm, name=site.truth["site"])
    hf = pavement_strip(
        surf,
        length_mm=mesh["length_mm"],
        width_mm=mesh["width_mm"],
        x0_mm=mesh["x0_mm"],
        y0_mm=mesh["y0_mm"],
        resolution_mm=mesh["resolution_mm"],
        smoothing=mesh["smoothing"],
        base_depth_mm=mesh["base_depth_mm"],
    )
    over = {} if args.element_mm is None else {"element_mm": args.element_mm}
    if args.friction_model:
        over["friction_model"] = args.friction_model
    if args.slide_damping_model:
        over["slide_damping_model"] = args.slide_damping_model
    scfg = SolverConfig.campaign(**over)
    tm = site.truth["texture_measures"]
    print(
        f"site {site.truth['site']} ({args.generator}): MPD {tm['mpd_mm']:.2f} mm, "
        f"micro Sq {tm['micro_sq_mm']:.4f} mm; solver element {scfg.element_mm} mm, slide {scfg.slide_length_mm} mm, "
        f"friction {scfg.friction_model}, slide damping {scfg.slide_damping_model}"
    )
    base = ExponentialDecay(*args.law)
    laws = [("base", base), ("base (repeat)", base)]
    for p, d in (("mu_s", args.dmu), ("mu_k", args.dmu), ("alpha", args.dalpha)):
        for sgn in (+1, -1):
            vals = base.as_dict()
            vals[p] = max(vals[p] + sgn * d, 0.0)
            if vals[p] == getattr(base, p):  # clipped at 0: nothing to compare
                continue
            laws.append((f"{p} {'+' if sgn > 0 else '-'}{d:g}", ExponentialDecay(**vals)))
    rows = []
    for v in args.speeds:
        sn0 = None
        for name, law in laws:
            t0 = time.perf_counter()
            r = fe_simulate(hf, v, law, scfg)
            wall = time.perf_counter() - t0
            sn = float(r.sn)
            if sn0 is None:
                sn0 = sn
            dmu = float(law.mu_kmh(v) - base.mu_kmh(v))
            dsn = sn - sn0
            rows.append(
                {
                    "site": site.truth["site"],
                    "speed_kmh": v,
                    "run": name,
                    "mu_s": law.mu_s,
                    "mu_k": law.mu_k,
                    "alpha_s_per_m": law.alpha,
                    "mu_at_v": float(law.mu_kmh(v)),
                    "sn": sn,
                    "d_sn": dsn,
                    "d_mu_at_v": dmu,
                    "ratio_dsn_dmu": dsn / dmu if abs(dmu) > 1e-12 else np.nan,
                    "sn_over_mu_at_v": sn / float(law.mu_kmh(v)),
                    "mean_slip_speed_ms": float(r.mean_slip_speed_ms),
                    "n_steps": int(r.n_steps),
                    "wall_s": wall,
                }
            )
            print(
                f"{v:5.1f} km/h  {name:16s} SN {sn:.4f}  dSN {dsn:+.4f}  d mu(v) {dmu:+.4f}  "
                f"ratio {rows[-1]['ratio_dsn_dmu']:+.2f}  SN/mu(v) {sn / float(law.mu_kmh(v)):.3f}  "
                f"slip speed {r.mean_slip_speed_ms:.2f} m/s  ({int(r.n_steps)} steps, {wall:.1f} s)",
                flush=True,
            )
    df = pd.DataFrame(rows)
    if args.csv:
        df.to_csv(args.csv, index=False)
    g = df[~df["run"].str.startswith("base")]
    b = df[df["run"] == "base"]
    print(
        "SN / mu of the base law: "
        + ", ".join(f"{s:.3f} at {v:g} km/h" for v, s in zip(b["speed_kmh"], b["sn"] / b["mu_at_v"]))
    )
    print(
        f"ratio dSN / d mu(v) over the perturbed runs: median {g.ratio_dsn_dmu.median():.2f}, "
        f"min {g.ratio_dsn_dmu.min():.2f}, max {g.ratio_dsn_dmu.max():.2f}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
