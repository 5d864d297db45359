"""Calibration figures: the study's Figure 10 (simulated vs measured) and fitted friction curves."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.calibration import CalibrationResult, fit_statistics, measured_arrays
from skidsim.plotting.style import COLORS, figure

_LABELS = {"study": "study (nested bisection)", "ours": "ours (fast fit)", "piarc_ifi": "PIARC/IFI model"}
_MARKERS = {"study": "s", "ours": "o", "piarc_ifi": "D"}
_COLORS = {**COLORS, "piarc_ifi": "#7570b3"}


def plot_figure10(df: pd.DataFrame, path: str | Path) -> None:
    """Two panels like the study's Figure 10: (a) calibration speeds, (b) validation speeds.

    df: :func:`skidsim.calibration.validation_table` output (columns method, kind, sn_sim, mu_measured).
    Each panel shows simulated SN vs measured DFT mu (dimensionless) for each method with a 1:1 line; the
    legend gives R^2 (about the 1:1 line) and RMSE per method. Rows of method ``piarc_ifi``
    (:func:`skidsim.ifi.model_validation_rows`) are drawn as one more method.
    """
    for col in ("method", "kind", "sn_sim", "mu_measured"):
        if col not in df.columns:
            raise ValueError(f"plot_figure10: column {col!r} missing; expected validation_table output")
    finite = df[["sn_sim", "mu_measured"]].to_numpy(float)
    finite = finite[np.isfinite(finite)]
    lo = float(finite.min()) if finite.size else 0.0
    hi = float(finite.max()) if finite.size else 1.0
    pad = 0.05 * max(hi - lo, 0.05)
    lim = (max(lo - pad, 0.0), hi + pad)
    with figure(path, ncols=2, figsize=(9.0, 4.2)) as (fig, axes):
        for ax, kind, title in zip(
            axes,
            ("calibration", "validation"),
            ("(a) calibration speeds 20/40/60 km/h", "(b) validation speeds 30/50/70 km/h"),
        ):
            sub = df[df["kind"] == kind]
            ax.plot(lim, lim, color="0.5", lw=1, ls="--", label="1:1")
            for method in sorted(sub["method"].unique()):
                g = sub[sub["method"] == method]
                st = fit_statistics(g["sn_sim"], g["mu_measured"])
                ax.scatter(
                    g["mu_measured"],
                    g["sn_sim"],
                    s=22,
                    alpha=0.8,
                    marker=_MARKERS.get(method, "^"),
                    color=_COLORS.get(method, None),
                    label=f"{_LABELS.get(method, method)}: R$^2$={st['r2']:.2f}, RMSE={st['rmse']:.3f}",
                )
            ax.set_xlim(lim)
            ax.set_ylim(lim)
            ax.set_aspect("equal")
            ax.set_xlabel("measured DFT friction coefficient (-)")
            ax.set_ylabel(
                "simulated SN or PIARC/IFI mu (-)" if "piarc_ifi" in set(df["method"]) else "simulated SN (-)"
            )
            ax.set_title(title)
            ax.legend(loc="upper left")


def plot_calibration_curves(
    results: Mapping[str, Mapping[str, CalibrationResult]],
    measured: Mapping[str, object],
    path: str | Path,
    *,
    runs: Mapping[str, Mapping[str, pd.DataFrame]] | None = None,
    ncols: int = 3,
    speed_range_kmh: tuple[float, float] = (0.0, 90.0),
) -> None:
    """Small multiples, one panel per site: measured DFT trace, both calibrated laws mu(v), and (if ``runs``
    is given, :func:`skidsim.calibration.simulate_speeds` output per site and method) the FE-simulated SN
    at the simulated speeds as markers. Speed axis in km/h.
    """
    sites = sorted(results)
    if not sites:
        raise ValueError("plot_calibration_curves: no sites")
    ncols = max(1, min(int(ncols), len(sites)))
    nrows = math.ceil(len(sites) / ncols)
    v = np.linspace(*speed_range_kmh, 181)
    with figure(path, nrows=nrows, ncols=ncols, figsize=(3.2 * ncols, 2.6 * nrows), squeeze=False) as (fig, axes):
        for k, site in enumerate(sites):
            ax = axes[k // ncols][k % ncols]
            if site in measured:
                mv, mmu = measured_arrays(measured[site])
                ax.plot(mv, mmu, ".", ms=2.5, color=COLORS["measured"], label="DFT")
            for method, res in results[site].items():
                c = COLORS.get(method, None)
                p = res.params
                ax.plot(v, p.mu_kmh(v), color=c, lw=1.4, label=f"{method}: {p.mu_s:.2f}/{p.mu_k:.2f}/{p.alpha:.3f}")
                if runs is not None and site in runs and method in runs[site]:
                    r = runs[site][method]
                    ax.plot(r["speed_kmh"], r["sn_sim"], _MARKERS.get(method, "^"), color=c, mfc="none", ms=5)
            ax.set_title(site)
            ax.set_xlabel("speed (km/h)")
            ax.set_ylabel("mu, SN (-)")
            ax.legend(fontsize=6, loc="upper right", title="mu_s/mu_k/alpha[s/m]", title_fontsize=6)
        fig.suptitle("lines: calibrated law mu(v); DFT: measured; open markers: FE-simulated SN", fontsize=8)
        for k in range(len(sites), nrows * ncols):
            axes[k // ncols][k % ncols].set_visible(False)


def plot_ifi_comparison(rows: pd.DataFrame, stats: pd.DataFrame, path: str | Path) -> None:
    """The PIARC/IFI speed model beside the FE-calibrated laws at the validation speeds: (a) predicted vs measured
    DFT mu (dimensionless) per model with R^2 (about the 1:1 line) and RMSE in the legend; (b) RMSE per validation
    speed and model.

    rows: validation-table rows of every model (columns method, kind, speed_kmh, sn_sim, mu_measured), the
    ``piarc_ifi`` rows from :func:`skidsim.ifi.model_validation_rows`; stats:
    :func:`skidsim.ifi.comparison_statistics` (columns speed_kmh, ``<model>_rmse``).
    """
    from skidsim.ifi import MODEL

    val = rows[rows["kind"] == "validation"]
    models = [c.removesuffix("_rmse") for c in stats.columns if c.endswith("_rmse")]
    labels = {**_LABELS, MODEL: "PIARC/IFI: DFT20 exp((20 - v)/Sp)"}
    colors, markers = _COLORS, _MARKERS
    vals = val[["sn_sim", "mu_measured"]].to_numpy(float)
    vals = vals[np.isfinite(vals)]
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    pad = 0.05 * max(hi - lo, 0.05)
    lim = (max(lo - pad, 0.0), hi + pad)
    with figure(path, ncols=2, figsize=(10.0, 4.4)) as (fig, axes):
        ax = axes[0]
        ax.plot(lim, lim, color="0.5", lw=1, ls="--", label="1:1")
        for m in models:
            g = val[val["method"] == m]
            st = fit_statistics(g["sn_sim"], g["mu_measured"])
            ax.scatter(
                g["mu_measured"],
                g["sn_sim"],
                s=22,
                alpha=0.8,
                marker=markers.get(m, "^"),
                color=colors.get(m),
                label=f"{labels.get(m, m)}: R$^2$={st['r2']:.2f}, RMSE={st['rmse']:.3f}",
            )
        ax.set_xlim(lim)
        ax.set_ylim(lim)
        ax.set_aspect("equal")
        ax.set_xlabel("measured DFT friction coefficient (-)")
        ax.set_ylabel("predicted (-)")
        ax.set_title("(a) validation speeds")
        ax.legend(loc="upper left", fontsize="small")
        ax = axes[1]
        per = stats[stats["speed_kmh"] != "all"]
        x = np.arange(len(per))
        width = 0.8 / max(len(models), 1)
        for i, m in enumerate(models):
            ax.bar(
                x + (i - (len(models) - 1) / 2) * width,
                per[f"{m}_rmse"].to_numpy(float),
                width,
                color=colors.get(m),
                label=labels.get(m, m),
            )
        ax.set_xticks(x, [f"{v} km/h" for v in per["speed_kmh"]])
        ax.set_ylabel("RMSE of mu (-)")
        ax.set_title("(b) RMSE per validation speed")
        ax.legend(loc="upper left", fontsize="small")
