"""Compare two finished runs of the workflow on the same campaign (e.g. config/quick.yaml against the default):
what a cheaper configuration costs in accuracy, stage by stage.

    .venv/bin/python benchmarks/compare_runs.py RESULTS_CHEAP RESULTS_REFERENCE [--method ours]

Prints, for sites present in both: MPD and a few texture parameters (should agree exactly when the texture
settings are equal); the calibrated law of each site as mu(v) at 20-70 km/h (RMSE and max |difference| of the
two laws, dimensionless mu); each run's fit statistics (Figure 10: R^2 and RMSE vs measured at calibration and
validation speeds); the cost of each method (FE runs, steps, FE wall s); the regression's cross-validated best
model and its score; the diagnosis's top cause. Wall times of the runs themselves come from `time` around
snakemake and from benchmarks/out/ (see docs/quick.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.friction import ExponentialDecay

SPEEDS_KMH = np.arange(20.0, 71.0, 5.0)


def laws(results: Path, method: str) -> dict[str, ExponentialDecay]:
    out = {}
    for p in sorted(results.glob(f"sites/*/calibration_{method}.json")):
        d = json.loads(p.read_text())["params"]
        out[p.parent.name] = ExponentialDecay(mu_s=d["mu_s"], mu_k=d["mu_k"], alpha=d["alpha"])
    return out


#: mu_k below this: the slow branch of docs/regression.md (mu_k = 0 with a slow decay); above: the fast branch.
SLOW_BRANCH_MU_K = 0.05


def print_parameter_moves(method: str, sites: list[str], cheap: dict, reference: dict) -> None:
    """Per parameter of the law (mu_s, mu_k dimensionless; alpha s/m): each run's median and the median and
    largest change per site (cheap - reference), and how many sites lie on each branch."""
    for name in ("mu_s", "mu_k", "alpha"):
        a = np.array([getattr(cheap[s], name) for s in sites])
        b = np.array([getattr(reference[s], name) for s in sites])
        d = a - b
        print(
            f"  {method} {name}: median {np.median(a):.4f} vs {np.median(b):.4f}; change per site median "
            f"{np.median(d):+.4f}, median |change| {np.median(np.abs(d)):.4f}, largest {d[np.argmax(np.abs(d))]:+.4f}"
        )
    for label, laws_ in (("cheap", cheap), ("reference", reference)):
        slow = sum(laws_[s].mu_k < SLOW_BRANCH_MU_K for s in sites)
        print(f"  {method} {label}: {slow} of {len(sites)} sites on the slow branch (mu_k < {SLOW_BRANCH_MU_K})")
    d = np.array([cheap[s].mu_kmh(SPEEDS_KMH) - reference[s].mu_kmh(SPEEDS_KMH) for s in sites])
    print(
        f"  {method} mu(v) change per speed (km/h: mean): "
        + ", ".join(f"{v:.0f}: {x:+.4f}" for v, x in zip(SPEEDS_KMH, d.mean(axis=0)) if v % 10 == 0)
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cheap", type=Path)
    ap.add_argument("reference", type=Path)
    ap.add_argument("--method", default="ours")
    a = ap.parse_args()
    c, r = a.cheap, a.reference

    mc = {p.parent.name: json.loads(p.read_text()) for p in c.glob("sites/*/mpd.json")}
    mr = {p.parent.name: json.loads(p.read_text()) for p in r.glob("sites/*/mpd.json")}
    both = sorted(set(mc) & set(mr))
    if both:
        key = next(k for k in mc[both[0]] if "mpd" in k.lower() and isinstance(mc[both[0]][k], (int, float)))
        dm = np.array([mc[s][key] - mr[s][key] for s in both])
        print(f"texture: {key} on {len(both)} common sites, max |difference| {np.max(np.abs(dm)):.3g} mm")

    for method in dict.fromkeys([a.method, "study", "ours"]):
        lc, lr = laws(c, method), laws(r, method)
        common = sorted(set(lc) & set(lr))
        if not common:
            continue
        diff = np.array([lc[s].mu_kmh(SPEEDS_KMH) - lr[s].mu_kmh(SPEEDS_KMH) for s in common])
        per_site = np.sqrt(np.mean(diff**2, axis=1))
        print(
            f"calibrated law ({method}), {len(common)} sites, mu(v) at 20-70 km/h: RMSE of the difference "
            f"{np.sqrt(np.mean(diff**2)):.4f}, mean difference {diff.mean():+.4f}, worst site "
            f"{common[int(np.argmax(per_site))]} {per_site.max():.4f}"
        )
        print_parameter_moves(method, common, lc, lr)

    for name, res in (("cheap", c), ("reference", r)):
        f = res / "calibration" / "fit_statistics.csv"
        if f.exists():
            st = pd.read_csv(f)
            for _, row in st.iterrows():
                print(
                    f"{name}: {row['method']} {row['kind']}: R2 {row['r2']:.3f}, RMSE {row['rmse']:.4f} (n {row['n']})"
                )
        f = res / "calibration" / "comparison.csv"
        if f.exists():
            tot = pd.read_csv(f).set_index("site").loc["TOTAL"]
            for m in ("study", "ours"):
                if f"{m}_steps" in tot:
                    print(
                        f"{name}: {m} cost: {int(tot[f'{m}_fe_runs'])} FE runs, {int(tot[f'{m}_steps']):,} steps, "
                        f"FE wall {tot[f'{m}_wall_s']:.0f} s"
                    )
            if "steps_ratio" in tot:
                print(f"{name}: steps ratio ours/study {tot['steps_ratio']:.3f}")
            for m in ("study", "ours"):
                if f"{m}_converged" in tot:
                    print(f"{name}: {m} converged {tot[f'{m}_converged']}")
        f = res / "regression" / "prediction_skill.csv"
        if f.exists():
            sk = pd.read_csv(f)
            for _, row in sk.iterrows():
                if isinstance(row["role"], str) and row["role"]:
                    print(
                        f"{name}: skill {row['model']} ({row['role']}): CV R2 {row['r2']:.3f}, RMSE {row['rmse']:.4f}"
                    )
        f = res / "regression" / "cv_ranking.csv"
        if f.exists():
            rk = pd.read_csv(f)
            print(f"{name}: regression CV best {rk.iloc[0]['model']} (score {rk.iloc[0]['score']:.4f})")
        f = res / "diagnosis" / "causes.json"
        if f.exists():
            causes = json.loads(f.read_text())
            top = causes[0] if causes else None
            named = [x["variable"] for x in causes if x.get("significant")]
            if top:
                print(
                    f"{name}: diagnosis top {top['variable']} ({top['level']}), p_adj {top['p_adjusted']:.3g}; "
                    f"named: {named[:5]}"
                )


if __name__ == "__main__":
    main()
