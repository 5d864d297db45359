"""Figures of the texture-to-friction regression: the study's Figure 11, the CV comparison, Table 6 as bars,
the prediction-skill table.

Inputs are the tables of :mod:`skidsim.regression` (``figure11_table``, ``cross_validate_models``, ``table6``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.ticker import MaxNLocator

from skidsim.errors import InputError
from skidsim.plotting.style import COLORS, figure

_MODEL_COLORS = [
    "#1b9e77",
    "#d95f02",
    "#7570b3",
    "#e7298a",
    "#66a61e",
    "#e6ab02",
    "#a6761d",
    "#666666",
    "#1f78b4",
    "#b15928",
    "#6a3d9a",
    "#b2df8a",
    "#fb9a99",
    "#000000",
]


def _need(df: pd.DataFrame, cols, what: str) -> None:
    for c in cols:
        if c not in df.columns:
            raise InputError(what, f"a '{c}' column", column=c, got=list(df.columns))


def plot_figure11(table: pd.DataFrame, path: str | Path) -> Path:
    """The study's Figure 11: one panel per speed (20..70 km/h), measured and predicted DFT per test site.

    ``table`` from :func:`skidsim.regression.figure11_table` (site, speed_kmh, predicted, measured,
    within_10pct). Measured values carry a +-10 % bar; predictions inside it are filled, outside hollow.
    """
    _need(table, ("site", "speed_kmh", "predicted", "measured"), "figure 11 table")
    speeds = sorted(table["speed_kmh"].unique())
    if not speeds:
        raise InputError("figure 11 table", "at least one row", column="speed_kmh", got=0)
    ncols = 3 if len(speeds) > 2 else len(speeds)
    nrows = math.ceil(len(speeds) / ncols)
    sites = sorted(table["site"].astype(str).unique())
    pos = {s: i for i, s in enumerate(sites)}
    lo = float(min(table["predicted"].min(), table["measured"].min() * 0.9))
    hi = float(max(table["predicted"].max(), table["measured"].max() * 1.1))
    pad = 0.05 * (hi - lo if hi > lo else 1.0)
    with figure(path, nrows=nrows, ncols=ncols, figsize=(3.4 * ncols, 2.9 * nrows), squeeze=False) as (fig, axes):
        for ax, v in zip(axes.ravel(), speeds):
            t = table[table["speed_kmh"] == v]
            x = np.array([pos[str(s)] for s in t["site"]])
            m, p = t["measured"].to_numpy(float), t["predicted"].to_numpy(float)
            inside = np.abs(p - m) <= 0.10 * np.abs(m)
            ax.errorbar(
                x - 0.1,
                m,
                yerr=0.10 * np.abs(m),
                fmt="s",
                color=COLORS["measured"],
                ms=4,
                capsize=2,
                label="measured DFT (+-10 %)",
            )
            ax.plot(x[inside] + 0.1, p[inside], "o", color=COLORS["ours"], ms=5, label="predicted, within 10 %")
            ax.plot(
                x[~inside] + 0.1,
                p[~inside],
                "o",
                mfc="none",
                color=COLORS["study"],
                ms=5,
                label="predicted, outside 10 %",
            )
            ax.set_title(f"{v:g} km/h: {int(inside.sum())}/{len(t)} within 10 %")
            ax.set_xticks(range(len(sites)))
            ax.set_xticklabels(sites, rotation=60, fontsize=7)
            ax.set_ylim(lo - pad, hi + pad)
            ax.set_ylabel("DFT friction coefficient (-)")
        for ax in axes.ravel()[len(speeds) :]:
            ax.set_visible(False)
        axes.ravel()[0].legend(loc="best", fontsize=7)
    return Path(path)


def plot_cv_comparison(cv_table: pd.DataFrame, path: str | Path) -> Path:
    """Leave-one-section-out comparison: out-of-sample R-squared per friction parameter and model (left), and
    the DFT RMSE per speed and model (right, when the table has DFT rows)."""
    _need(cv_table, ("model", "quantity", "speed_kmh", "rmse", "r2"), "cross-validation table")
    models = list(dict.fromkeys(cv_table["model"]))
    params = [q for q in ("mu_s", "mu_k", "alpha") if q in set(cv_table["quantity"])]
    dft = cv_table[(cv_table["quantity"] == "dft") & cv_table["speed_kmh"].notna()]
    ncols = 2 if len(dft) else 1
    with figure(path, nrows=1, ncols=ncols, figsize=(5.2 * ncols, 3.8), squeeze=False) as (fig, axes):
        ax = axes[0, 0]
        w = 0.8 / max(len(models), 1)
        for i, m in enumerate(models):
            t = cv_table[(cv_table["model"] == m) & cv_table["quantity"].isin(params)].set_index("quantity")
            r2 = [float(t.loc[q, "r2"]) if q in t.index else np.nan for q in params]
            ax.bar(
                np.arange(len(params)) + (i - (len(models) - 1) / 2) * w,
                r2,
                width=w,
                label=m,
                color=_MODEL_COLORS[i % len(_MODEL_COLORS)],
            )
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xticks(range(len(params)))
        ax.set_xticklabels([{"mu_s": "mu_s (-)", "mu_k": "mu_k (-)", "alpha": "alpha (s/m)"}[q] for q in params])
        ax.set_ylabel("out-of-section R-squared (-)")
        ax.set_title("Friction parameters, leave one section out")
        ax.legend(fontsize=7, ncol=2)
        if len(dft):
            ax = axes[0, 1]
            for i, m in enumerate(models):
                t = dft[dft["model"] == m].sort_values("speed_kmh")
                ax.plot(t["speed_kmh"], t["rmse"], "o-", label=m, color=_MODEL_COLORS[i % len(_MODEL_COLORS)])
            ax.set_xlabel("speed (km/h)")
            ax.set_ylabel("DFT RMSE (-)")
            ax.set_title("Predicted DFT, leave one section out")
            ax.legend(fontsize=7, ncol=2)
    return Path(path)


def plot_table6(coeffs: pd.DataFrame, path: str | Path) -> Path:
    """Table 6 as bars: one row of panels per target, one panel per band; bar length is the coefficient per
    one training standard deviation of the feature (``coefficient_per_sd``, target units), comparable across
    features of different units. ``coeffs`` from :func:`skidsim.regression.table6` (or one fit's ``table6()``)."""
    _need(coeffs, ("variable", "band", "parameter", "coefficient_per_sd"), "table 6")
    t = coeffs[coeffs["variable"] != "Intercept"].copy()
    if "target" not in t.columns:
        t["target"] = "target"
    targets = list(dict.fromkeys(t["target"]))
    bands = [b for b in ("raw", "macro", "micro", "profile", "temperature", "other") if b in set(t["band"])]
    if not targets or not bands:
        raise InputError("table 6", "at least one feature coefficient", column="variable", got=0)
    nper = max(int((t["band"] == b).groupby(t["target"]).sum().max()) for b in bands)
    with figure(
        path,
        nrows=len(targets),
        ncols=len(bands),
        squeeze=False,
        figsize=(2.6 * len(bands), max(2.2, 0.16 * nper + 1.0) * len(targets)),
    ) as (fig, axes):
        for i, tg in enumerate(targets):
            for j, b in enumerate(bands):
                ax = axes[i, j]
                s = t[(t["target"] == tg) & (t["band"] == b)]
                y = np.arange(len(s))
                ax.barh(y, s["coefficient_per_sd"].to_numpy(float), color=COLORS.get(b, "#666666"))
                ax.set_yticks(y)
                ax.set_yticklabels(s["parameter"].astype(str), fontsize=6)
                ax.axvline(0.0, color="k", lw=0.6)
                ax.set_ylim(-0.6, max(len(s), 3) - 0.4)
                ax.xaxis.set_major_locator(MaxNLocator(4))
                ax.set_title(f"{tg}: {b}", fontsize=8)
                if i == len(targets) - 1:
                    ax.set_xlabel("coefficient per 1 SD")
    return Path(path)


#: Lowest R-squared drawn by :func:`plot_prediction_skill` (bars below it are cut and labelled with the value).
SKILL_R2_FLOOR = -1.0


def plot_prediction_skill(skill: pd.DataFrame, path: str | Path) -> Path:
    """The prediction-skill table as bars: section-grouped CV R-squared of the DFT pooled over the prediction
    speeds, one bar per model (best first), the chosen model filled dark, the intercept-only mean and the
    baseline as dashed lines. When the chosen model does not beat both (``skill.attrs["warning"]`` or a
    non-empty ``warning`` column), the title is a red WARNING and the chosen bar is red.

    ``skill`` from :func:`skidsim.regression.prediction_skill`. Bars below ``SKILL_R2_FLOOR`` are cut there and
    carry their value.
    """
    _need(skill, ("model", "role", "r2", "rmse", "warning"), "prediction-skill table")
    if skill.empty:
        raise InputError("prediction-skill table", "at least one model", column="model", got=0)
    t = skill.sort_values("rmse", kind="stable").reset_index(drop=True)
    warning = str(skill.attrs.get("warning") or "") or next((w for w in t["warning"].astype(str) if w), "")
    roles = t["role"].fillna("").astype(str)
    chosen = roles.str.contains("chosen")
    r2 = t["r2"].to_numpy(float)
    shown = np.maximum(r2, SKILL_R2_FLOOR)
    colors = ["#b2182b" if (c and warning) else "#1b9e77" if c else "#bdbdbd" for c in chosen]
    with figure(path, figsize=(7.0, 0.32 * len(t) + 1.8)) as (fig, ax):
        y = np.arange(len(t))[::-1]
        ax.barh(y, shown, color=colors)
        for yy, v, s in zip(y, r2, shown):
            ax.text(s + 0.01 if s >= 0 else 0.01, yy, f"{v:.3f}", va="center", fontsize=7)
        for role, style in (("mean", ":"), ("baseline", "--")):
            ref = t[roles.str.contains(role)]
            if len(ref):
                ax.axvline(
                    float(ref["r2"].iloc[0]),
                    color="k",
                    ls=style,
                    lw=1.0,
                    label=f"{role}: {ref['model'].iloc[0]} ({float(ref['r2'].iloc[0]):.3f})",
                )
        ax.axvline(0.0, color="k", lw=0.6)
        ax.set_yticks(y)
        ax.set_yticklabels([f"{m} [{r}]" if r else m for m, r in zip(t["model"], roles)], fontsize=7)
        ax.set_xlim(SKILL_R2_FLOOR - 0.05, 1.05)
        ax.set_xlabel("section-grouped CV R-squared of the DFT, pooled over speeds (-)")
        ax.legend(fontsize=7, loc="lower right")
        if warning:
            ax.set_title(
                "WARNING: the chosen model does not beat the mean and the baseline",
                color="#b2182b",
                fontsize=9,
                fontweight="bold",
            )
        else:
            ax.set_title(
                "Prediction skill at unseen sections: the chosen model beats the mean and the baseline", fontsize=9
            )
    return Path(path)
