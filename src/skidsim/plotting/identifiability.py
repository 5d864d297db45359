"""Identifiability figure: per site and parameter, the calibrated value and its profile-likelihood interval."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.plotting.style import COLORS, figure

_PANELS = (("mu_s", "mu_s (-)"), ("mu_k", "mu_k (-)"), ("alpha", "alpha (s/m)"))


def plot_identifiability(table: pd.DataFrame, path: str | Path, *, bounds: dict | None = None) -> None:
    """Three panels (mu_s, mu_k, alpha): per site (rows) and method the calibrated value (marker) and the 95 %
    profile-likelihood interval (bar; dotted where it runs to a bound, i.e. not bounded within the bounds); a
    red marker for a site with a flag. ``table``: rows of :func:`skidsim.calibration.identifiability.table_row`."""
    for col in ("site", "method", "flags", *(f"{p}_{s}" for p, _ in _PANELS for s in ("lower", "upper", "open"))):
        if col not in table.columns:
            raise ValueError(f"plot_identifiability: column {col!r} missing; expected identifiability.csv rows")
    sites = sorted(table["site"].unique())
    methods = sorted(table["method"].unique())
    ypos = {s: i for i, s in enumerate(sites)}
    offs = {m: (k - (len(methods) - 1) / 2) * 0.3 for k, m in enumerate(methods)}
    value_col = {"mu_s": "mu_s", "mu_k": "mu_k", "alpha": "alpha_s_per_m"}
    height = max(3.0, 0.22 * len(sites) + 1.2)
    with figure(path, ncols=3, figsize=(10.0, height), sharey=True) as (fig, axes):
        for ax, (p, label) in zip(axes, _PANELS):
            for m in methods:
                g = table[table["method"] == m]
                y = np.array([ypos[s] + offs[m] for s in g["site"]])
                lo = g[f"{p}_lower"].to_numpy(float)
                hi = g[f"{p}_upper"].to_numpy(float)
                opened = g[f"{p}_open"].fillna("").astype(str).to_numpy()
                for yi, a, b, o in zip(y, lo, hi, opened):
                    if np.isfinite(a) and np.isfinite(b):
                        ax.plot([a, b], [yi, yi], color=COLORS.get(m, "0.3"), lw=2.0, ls=":" if o else "-", alpha=0.85)
                flagged = g["flags"].fillna("").astype(str).str.len().to_numpy() > 0
                val = g[value_col[p]].to_numpy(float)
                ax.scatter(
                    val[~flagged],
                    y[~flagged],
                    s=16,
                    color=COLORS.get(m, "0.3"),
                    zorder=3,
                    label=f"{m}" if p == "mu_s" else None,
                )
                ax.scatter(
                    val[flagged],
                    y[flagged],
                    s=16,
                    color="#e7298a",
                    marker="x",
                    zorder=3,
                    label=f"{m}, flagged" if p == "mu_s" and flagged.any() else None,
                )
            if bounds and p in bounds:
                for b in bounds[p]:
                    ax.axvline(float(b), color="0.6", lw=0.8, ls="--")
            ax.set_xlabel(label)
            ax.set_title(f"{label.split()[0]}: value and 95 % profile interval", fontsize=9)
        axes[0].set_yticks(range(len(sites)))
        axes[0].set_yticklabels(sites)
        axes[0].invert_yaxis()
        handles, labels = axes[0].get_legend_handles_labels()
        axes[2].legend(handles, labels, loc="center right", fontsize=7)  # alpha values sit far left of 1 s/m
