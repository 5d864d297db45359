"""Figures of the explicit solver: mesh study (discretisation error and compute time vs element size), trace."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.plotting.style import figure


def plot_mesh_study(table: pd.DataFrame, path: str | Path) -> Path:
    """Like the study's Figure 9: one panel per speed, discretisation error (%) against the finest mesh and
    compute time (s) against element size (mm). ``table`` columns: speed_kmh, element_mm, error_pct, wall_s."""
    speeds = sorted(table["speed_kmh"].unique())
    with figure(path, ncols=len(speeds), figsize=(3.6 * len(speeds), 3.4)) as (fig, axes):
        axes = np.atleast_1d(axes)
        for ax, v in zip(axes, speeds):
            t = table[table["speed_kmh"] == v].sort_values("element_mm")
            ax.plot(t["element_mm"], t["error_pct"], "x-", color="#1b9e77", label="discretisation error")
            ax.set_xlabel("element size (mm)")
            ax.set_ylabel("SN error vs finest mesh (%)")
            ax.set_title(f"DFT {v:g} km/h")
            ax2 = ax.twinx()
            ax2.plot(t["element_mm"], t["wall_s"], "^--", color="#d95f02", label="computing time")
            ax2.set_ylabel("computing time (s)")
            ax2.set_yscale("log")
            ax2.grid(False)
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = ax2.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, loc="best")
    return Path(path)


def plot_trace(trace: pd.DataFrame, path: str | Path, *, window_mm: tuple[float, float] | None = None) -> Path:
    """Tangential and normal pavement force (N) and their ratio against the slide position (mm)."""
    with figure(path, nrows=2, figsize=(6.5, 5.0), sharex=True) as (fig, (a1, a2)):
        a1.plot(trace["position_mm"], trace["normal_n"], lw=0.6, label="normal (N)")
        a1.plot(trace["position_mm"], trace["tangential_n"], lw=0.6, label="tangential (N)")
        a1.set_ylabel("force (N)")
        a1.legend()
        ratio = trace["tangential_n"] / trace["normal_n"].where(trace["normal_n"].abs() > 1e-9)
        a2.plot(trace["position_mm"], ratio, lw=0.6, color="#333333")
        a2.set_ylabel("tangential / normal")
        a2.set_xlabel("slide position (mm)")
        if window_mm is not None:
            for a in (a1, a2):
                a.axvspan(*window_mm, color="#1b9e77", alpha=0.1)
    return Path(path)
