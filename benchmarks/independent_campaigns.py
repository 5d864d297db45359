"""Issue 25's table on campaigns of each generator: generate, run the workflow, read its results.

    .venv/bin/python benchmarks/independent_campaigns.py WORKDIR [--generators chips spectral default]
        [--sites 36] [--shape 2048 2448] [--spacing-mm MM] [--config config/quick.yaml [MORE.yaml]] [--cores 2]

For each generator: ``skidsim synth WORKDIR/<gen>/campaign --generator <gen>`` (skipped when the campaign is
there), then ``snakemake --cores N --configfile config/config.yaml CONFIG... --config campaign=...`` in
``WORKDIR/<gen>/run`` (``--directory``; the checkout is not written to) for the calibration and regression
outputs only (no figure 11, mesh study or diagnosis). Then, per generator, from the run's results:

* back-calculation fit R^2 at the calibration / validation speeds (``results/calibration/fit_statistics.csv``,
  method ``ours``);
* sites not calibrated (``converged`` false) and sites with mu_s at the study's upper bound 0.85
  (``results/calibration/parameters.parquet``);
* the best model's section-grouped CV R^2 of the DFT pooled over the prediction speeds and the number of models
  with R^2 > 0 (``results/regression/cv_table.csv``, quantity ``dft``, speed NaN);
* the baseline: OLS of the DFT on at most two texture parameters (``results/texture/campaign.parquet``, columns
  ``raw_*``, ``macro_*``, ``micro_*``, ``profile_*``), the subset chosen by an inner leave-one-section-out CV among
  the empty subset, all singletons and all pairs, scored by leave-one-section-out CV of the measured DFT
  (``results/ingest/dft_points.parquet``) pooled over 20-70 km/h: ``R^2 = 1 - SSE / SS about the pooled mean``,
  as the workflow's CV table; and the fixed pair ``raw_Sq`` + ``micro_Vvc`` of the issue;
* the physics-prior pair: OLS of the DFT at each speed on ``profile_MPD`` and ``micro_Sq`` (the macrotexture depth
  that sets the speed gradient in the PIARC/IFI model, the microtexture amplitude that sets the low-speed level),
  the two columns taken as they are or as their logarithms, whichever has the smaller inner leave-one-section-out
  SSE on the training sections of each outer fold (2 candidates instead of the baseline's thousands of subsets).

Prints one markdown table (a column per generator) and writes ``WORKDIR/table.csv`` and ``WORKDIR/table.json``
(through :mod:`skidsim.atomic`).
The baseline is the library's ``ols2@dft`` (``skidsim.regression.fit_subset_ols``; the empty subset is a candidate
too), recomputed here from the run's tables so that runs made before it joined the workflow are scored the same
way; when the run has ``results/regression/prediction_skill.csv`` the table also reports whether the workflow's
chosen model beats the mean and the baseline.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.atomic import atomic_path, write_json
from skidsim.generators.campaign import COMMON

ROOT = Path(__file__).resolve().parents[1]
BANDS = ("raw_", "macro_", "micro_", "profile_")
SPEEDS_KMH = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
MU_S_BOUND = 0.85
TARGETS = [
    "results/calibration/fit_statistics.csv",
    "results/calibration/parameters.parquet",
    "results/regression/cv_table.csv",
    "results/regression/prediction_skill.csv",
    "results/texture/campaign.parquet",
    "results/ingest/dft_points.parquet",
]


# --------------------------------------------------------------------------------------------------------------
# Baseline: the library's ols2@dft (OLS of the DFT curve on at most two texture parameters, inner-CV choice)


def baseline_cv(X: pd.DataFrame, Y: np.ndarray, groups: np.ndarray, fixed: tuple[str, str] | None = None) -> dict:
    """Leave-one-section-out CV of the baseline :data:`skidsim.regression.BASELINE_MODEL` (one implementation:
    :func:`skidsim.regression.fit_subset_ols` in every outer fold). ``Y`` ``(n, len(SPEEDS_KMH))`` the DFT.
    Returns r2, rmse (pooled over sites and speeds), the subset chosen in each outer fold, and (``fixed``) the
    same scores of plain OLS on one fixed pair."""
    from skidsim import regression

    D = pd.DataFrame(Y, index=X.index, columns=[regression.dft_column(v) for v in SPEEDS_KMH])
    laws = pd.DataFrame({"mu_s": 0.5, "mu_k": 0.2, "alpha": 0.05}, index=X.index)  # unused by @dft models
    cvp = regression.cross_validated_predictions(
        X, laws, pd.Series(groups, index=X.index), [regression.BASELINE_MODEL], dft=D
    )
    cvp = cvp.set_index("site").loc[X.index]
    pred = cvp[list(D.columns)].to_numpy(float)
    chosen = cvp.drop_duplicates("section")["features"].tolist()
    out = {**_scores(pred, Y), "chosen": chosen}
    if fixed and all(f in X.columns for f in fixed):
        Xv = X.loc[:, list(fixed)].to_numpy(float)
        fp = np.full_like(Y, np.nan)
        for s in np.unique(groups):
            tr, te = groups != s, groups == s
            A = np.column_stack([np.ones(tr.sum()), Xv[tr]])
            beta, *_ = np.linalg.lstsq(A, Y[tr], rcond=None)
            fp[te] = np.column_stack([np.ones(te.sum()), Xv[te]]) @ beta
        out["fixed"] = {"features": list(fixed), **_scores(fp, Y)}
    return out


def _scores(pred: np.ndarray, Y: np.ndarray) -> dict:
    err = pred - Y
    sse = float((err**2).sum())
    sst = float(((Y - Y.mean()) ** 2).sum())
    return {"r2": 1.0 - sse / sst, "rmse": float(np.sqrt(np.mean(err**2)))}


PRIOR_PAIR = ("profile_MPD", "micro_Sq")


def _ols_fold(A_tr: np.ndarray, Y_tr: np.ndarray, A_te: np.ndarray) -> np.ndarray:
    beta, *_ = np.linalg.lstsq(np.column_stack([np.ones(len(A_tr)), A_tr]), Y_tr, rcond=None)
    return np.column_stack([np.ones(len(A_te)), A_te]) @ beta


def _loso_sse(A: np.ndarray, Y: np.ndarray, groups: np.ndarray) -> float:
    sse = 0.0
    for s in np.unique(groups):
        tr, te = groups != s, groups == s
        sse += float(((_ols_fold(A[tr], Y[tr], A[te]) - Y[te]) ** 2).sum())
    return sse


def physics_prior_cv(X: pd.DataFrame, Y: np.ndarray, groups: np.ndarray, pair=PRIOR_PAIR) -> dict | None:
    """Leave-one-section-out CV of OLS of ``Y`` (the DFT, one column per speed) on the columns ``pair``, taken as
    they are or as their logarithms (only when positive on every site), the form chosen in each outer fold by
    the inner leave-one-section-out SSE on its training sections. None when a column is missing."""
    if not all(c in X.columns for c in pair):
        return None
    raw = X.loc[:, list(pair)].to_numpy(float)
    forms = {"identity": raw}
    if (raw > 0).all():
        forms["log"] = np.log(raw)
    pred, chosen = np.full_like(Y, np.nan), []
    for s in np.unique(groups):
        tr, te = groups != s, groups == s
        form = min(forms, key=lambda f: _loso_sse(forms[f][tr], Y[tr], groups[tr]))
        pred[te] = _ols_fold(forms[form][tr], Y[tr], forms[form][te])
        chosen.append(form)
    return {"features": list(pair), **_scores(pred, Y), "chosen": chosen}


def baseline_from_results(results: Path) -> dict:
    """The baseline on a run's results directory (texture table + measured DFT at 20-70 km/h)."""
    wide = pd.read_parquet(results / "texture" / "campaign.parquet")
    dft = pd.read_parquet(results / "ingest" / "dft_points.parquet")
    dft = dft[dft["speed_kmh"].isin(SPEEDS_KMH)]
    Ymat = dft.pivot_table(index="site", columns="speed_kmh", values="mu").reindex(columns=list(SPEEDS_KMH))
    wide = wide.set_index(wide["site"].astype(str))
    feats = [c for c in wide.columns if isinstance(c, str) and c.startswith(BANDS)]
    X = wide[feats].apply(pd.to_numeric, errors="coerce")
    X = X.loc[:, X.notna().all() & (X.std() > 0)]
    sites = [s for s in X.index if s in Ymat.index and Ymat.loc[s].notna().all()]
    Y, groups = Ymat.loc[sites].to_numpy(float), wide.loc[sites, "section"].astype(str).to_numpy()
    res = baseline_cv(X.loc[sites], Y, groups, fixed=("raw_Sq", "micro_Vvc"))
    prior = physics_prior_cv(X.loc[sites], Y, groups)
    if prior is not None:
        res["prior"] = prior
    res["n_features"] = int(X.shape[1])
    res["n_sites"] = len(sites)
    return res


# --------------------------------------------------------------------------------------------------------------
# Workflow figures


def workflow_figures(results: Path, method: str = "ours") -> dict:
    stats = pd.read_csv(results / "calibration" / "fit_statistics.csv")
    st = stats[stats["method"] == method].set_index("kind")
    params = pd.read_parquet(results / "calibration" / "parameters.parquet")
    pm = params[params["method"] == method]
    cv = pd.read_csv(results / "regression" / "cv_table.csv")
    d = cv[(cv["quantity"] == "dft") & cv["speed_kmh"].isna()].sort_values("r2", ascending=False)
    return {
        "fit_r2_cal": float(st.loc["calibration", "r2"]),
        "fit_r2_val": float(st.loc["validation", "r2"]),
        "fit_rmse_cal": float(st.loc["calibration", "rmse"]),
        "fit_rmse_val": float(st.loc["validation", "rmse"]),
        "n_sites": int(len(pm)),
        "not_converged": int((~pm["converged"].astype(bool)).sum()),
        "at_mu_s_bound": int((pm["mu_s"] >= MU_S_BOUND - 1e-9).sum()),
        "best_model": str(d["model"].iloc[0]),
        "best_r2": float(d["r2"].iloc[0]),
        "best_rmse": float(d["rmse"].iloc[0]),
        "models_r2_above_0": int((d["r2"] > 0).sum()),
        "n_models": int(len(d)),
        **skill_figures(results),
    }


def skill_figures(results: Path) -> dict:
    """From the workflow's prediction-skill table (absent in runs made before it existed): the chosen model, its
    R^2, the mean's and the baseline's, and whether the chosen model beats both."""
    path = results / "regression" / "prediction_skill.csv"
    if not path.exists():
        return {}
    sk = pd.read_csv(path, keep_default_na=False)
    role = sk["role"].astype(str)

    def row(r: str) -> pd.Series:
        return sk[role.str.contains(r)].iloc[0]

    c, m, b = row("chosen"), row("mean"), row("baseline")
    return {
        "skill_chosen": str(c["model"]),
        "skill_chosen_r2": float(c["r2"]),
        "skill_mean_r2": float(m["r2"]),
        "skill_baseline_r2": float(b["r2"]),
        "skill_beats_both": str(c["beats_both"]) == "True",
    }


# --------------------------------------------------------------------------------------------------------------
# Running


def run(cmd: list[str], log: Path, env: dict | None = None) -> None:
    t0 = time.time()
    with open(log, "w") as fh:
        r = subprocess.run(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)
    if r.returncode != 0:
        tail = log.read_text()[-3000:]
        raise SystemExit(f"failed ({r.returncode}) after {time.time() - t0:.0f} s: {' '.join(cmd)}\n{tail}")


def generate(gen: str, campaign: Path, a) -> None:
    if (campaign / "sites.csv").exists():
        return
    cmd = [
        str(ROOT / ".venv" / "bin" / "skidsim"),
        "synth",
        str(campaign),
        "--sites",
        str(a.sites),
        "--seed",
        str(a.seed),
        "--shape",
        *map(str, a.shape),
    ]
    if gen != "default":
        cmd += ["--generator", gen]
    if a.spacing_mm:
        cmd += ["--spacing-mm", str(a.spacing_mm)]
    run(cmd, campaign.parent / "synth.log")


def workflow(campaign: Path, rundir: Path, a, targets=None) -> float:
    """``snakemake`` on ``campaign`` in ``rundir`` (``--directory``) with ``a.config`` on top of the default
    config, ``a.cores`` cores, up to ``targets`` (default :data:`TARGETS`). Returns the wall time in s."""
    rundir.mkdir(parents=True, exist_ok=True)
    cmd = [
        sys.executable,
        "-m",
        "snakemake",
        "-s",
        str(ROOT / "Snakefile"),
        "--directory",
        str(rundir),
        "--configfile",
        str(ROOT / "config" / "config.yaml"),
        *(str(Path(c).resolve()) for c in a.config),
        "--config",
        f"campaign={campaign}",
        "--cores",
        str(a.cores),
        "--rerun-triggers",
        "mtime",
        "params",
        "input",
        "--",
        *(TARGETS if targets is None else targets),
    ]
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    t0 = time.time()
    run(cmd, rundir / "snakemake.log", env)
    return time.time() - t0


def table(rows: dict[str, dict]) -> str:
    gens = list(rows)
    lines = ["| measure | " + " | ".join(gens) + " |", "|---|" + "---|" * len(gens)]

    def line(label, fmt):
        lines.append(f"| {label} | " + " | ".join(fmt(rows[g]) for g in gens) + " |")

    line(
        "back-calculation fit R^2, calibration / validation speeds",
        lambda r: f"{r['fit_r2_cal']:.3f} / {r['fit_r2_val']:.3f}",
    )
    line(
        "sites not converged; at mu_s = 0.85 (of n)",
        lambda r: f"{r['not_converged']}; {r['at_mu_s_bound']} (of {r['n_sites']})",
    )
    line(
        "DFT at unseen sections, best model (section-grouped CV R^2)", lambda r: f"{r['best_model']} {r['best_r2']:.2f}"
    )
    line("models with CV R^2 of DFT above 0", lambda r: f"{r['models_r2_above_0']} of {r['n_models']}")
    line(
        "baseline: OLS on <= 2 texture parameters (inner CV), CV R^2 / RMSE",
        lambda r: f"{r['baseline']['r2']:.2f} / {r['baseline']['rmse']:.3f}",
    )
    line(
        "OLS on raw_Sq + micro_Vvc, CV R^2",
        lambda r: f"{r['baseline']['fixed']['r2']:.2f}" if "fixed" in r["baseline"] else "n/a",
    )
    line(
        "physics prior: OLS on profile_MPD + micro_Sq (as they are or logs, inner CV), CV R^2 / RMSE",
        lambda r: (
            (
                f"{r['baseline']['prior']['r2']:.2f} / {r['baseline']['prior']['rmse']:.3f} (logs in "
                f"{r['baseline']['prior']['chosen'].count('log')} of {len(r['baseline']['prior']['chosen'])} "
                "folds)"
            )
            if "prior" in r["baseline"]
            else "n/a"
        ),
    )
    line(
        "workflow's prediction-skill table: chosen (R^2) / mean / baseline; beats both",
        lambda r: (
            (
                f"{r['skill_chosen']} ({r['skill_chosen_r2']:.2f}) / {r['skill_mean_r2']:.2f} / "
                f"{r['skill_baseline_r2']:.2f}; {'yes' if r['skill_beats_both'] else 'NO'}"
            )
            if "skill_chosen" in r
            else "n/a"
        ),
    )
    line("workflow wall time (s)", lambda r: f"{r['wall_s']:.0f}")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("workdir")
    p.add_argument(
        "--generators", nargs="+", default=["chips", "spectral", "default"], choices=["chips", "spectral", "default"]
    )
    p.add_argument("--sites", type=int, default=COMMON["n_sites"])
    p.add_argument("--shape", type=int, nargs=2, default=list(COMMON["shape"]), metavar=("ROWS", "COLS"))
    p.add_argument("--spacing-mm", type=float, help="scan spacing (default: each generator's own)")
    p.add_argument("--seed", type=int, default=COMMON["seed"])
    p.add_argument(
        "--config",
        nargs="+",
        default=[str(ROOT / "config" / "quick.yaml")],
        help="config file(s) given after config/config.yaml (later ones override)",
    )
    p.add_argument("--cores", type=int, default=2)
    p.add_argument("--tables-only", action="store_true", help="only read existing results")
    a = p.parse_args(argv)
    work = Path(a.workdir).resolve()
    rows = {}
    for gen in a.generators:
        base = work / gen
        base.mkdir(parents=True, exist_ok=True)
        campaign = base / "campaign"
        wall = float("nan")
        if not a.tables_only:
            generate(gen, campaign, a)
            wall = workflow(campaign, base / "run", a)
        results = base / "run" / "results"
        rows[gen] = {**workflow_figures(results), "baseline": baseline_from_results(results), "wall_s": wall}
        print(f"{gen}: done", file=sys.stderr, flush=True)
    text = table(rows)
    print(text)
    write_json(work / "table.json", rows)
    flat = {
        g: {k: v for k, v in r.items() if k != "baseline"}
        | {"baseline_r2": r["baseline"]["r2"], "baseline_rmse": r["baseline"]["rmse"]}
        | (
            {"prior_r2": r["baseline"]["prior"]["r2"], "prior_rmse": r["baseline"]["prior"]["rmse"]}
            if "prior" in r["baseline"]
            else {}
        )
        for g, r in rows.items()
    }
    with atomic_path(work / "table.csv") as tmp:
        pd.DataFrame(flat).to_csv(tmp)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
