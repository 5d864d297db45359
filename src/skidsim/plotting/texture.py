"""Texture figures: the study's Figure 7 panels, the despeckle comparisons, campaign distributions, scan quality."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from skidsim.surface import Surface

from .style import COLORS, figure

if TYPE_CHECKING:
    import pandas as pd


def _image(ax, s: Surface, title: str, max_px: int = 600, detail_mm: float | None = None):
    """Height image; colour limits at the 0.5 and 99.5 % quantiles so that a few outliers do not flatten it.

    ``detail_mm``: show only a ``detail_mm`` square at the centre at full resolution (microtexture would alias
    in a decimated full view)."""
    h = s.heights
    x0 = y0 = 0.0
    if detail_mm is not None:
        nx, ny = int(round(detail_mm / s.dx)), int(round(detail_mm / s.dy))
        i0, j0 = max(0, (h.shape[0] - ny) // 2), max(0, (h.shape[1] - nx) // 2)
        h = h[i0 : i0 + ny, j0 : j0 + nx]
        x0, y0 = j0 * s.dx, i0 * s.dy
    step = max(1, int(np.ceil(max(h.shape) / max_px)))  # decimate for the figure only
    img = h[::step, ::step]
    finite = img[np.isfinite(img)]
    lo, hi = np.quantile(finite, [0.005, 0.995]) if finite.size else (None, None)
    im = ax.imshow(
        img,
        origin="lower",
        aspect="equal",
        vmin=lo,
        vmax=hi,
        extent=(x0, x0 + (h.shape[1] - 1) * s.dx, y0, y0 + (h.shape[0] - 1) * s.dy),
    )
    ax.set_title(title)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.grid(False)
    ax.figure.colorbar(im, ax=ax, shrink=0.8, label="height (mm)", extend="both")


def plot_figure7(raw: Surface, despeckled: Surface, macro: Surface, micro: Surface, path: str | Path) -> None:
    """Four range images like the study's Figure 7: scan, despeckled, macrotexture, microtexture (mm)."""
    with figure(path, nrows=2, ncols=2, figsize=(10.0, 8.0)) as (fig, axes):
        for ax, s, t in zip(
            axes.ravel(),
            (raw, despeckled, macro, micro),
            (
                "range image (as scanned)",
                "despeckled",
                "macrotexture 0.5-50 mm",
                "microtexture < 0.5 mm (10 x 10 mm detail)",
            ),
        ):
            _image(ax, s, t, detail_mm=10.0 if s is micro else None)


def plot_despeckle_comparison(
    profile_mm: np.ndarray, dx_mm: float, results: dict[str, np.ndarray], path: str | Path, title: str = ""
) -> None:
    """One profile (mm) and its despeckled versions ``{rule: profile}`` on a common x axis (mm)."""
    x = np.arange(profile_mm.size) * dx_mm
    colors = ["#d95f02", "#1b9e77", "#7570b3", "#e7298a"]
    with figure(path, figsize=(9.0, 4.0)) as (fig, ax):
        ax.plot(x, profile_mm, color=COLORS["measured"], lw=0.8, label="profile")
        for (name, prof), c in zip(results.items(), colors):
            ax.plot(x, prof, color=c, lw=0.9, alpha=0.85, label=name)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("height (mm)")
        if title:
            ax.set_title(title)
        ax.legend(loc="best")


def plot_campaign_distributions(
    campaign_wide: pd.DataFrame,
    path: str | Path,
    parameters: tuple[str, ...] = ("Sq", "Ssk", "Sdr", "Sal", "Sk", "S10z", "Spd", "Vvv"),
    bands: tuple[str, ...] = ("macro", "micro"),
) -> None:
    """Histograms over sites of selected parameters, one panel per parameter, one colour per band."""
    import pandas as pd

    params = [p for p in parameters if any(f"{b}_{p}" in campaign_wide.columns for b in bands)]
    if not params:
        raise ValueError(f"plot_campaign_distributions: none of {parameters} found for bands {bands}")
    ncols = min(4, len(params))
    nrows = int(np.ceil(len(params) / ncols))
    with figure(path, nrows=nrows, ncols=ncols, figsize=(3.2 * ncols, 2.6 * nrows), squeeze=False) as (fig, axes):
        for ax, p in zip(axes.ravel(), params):
            for b in bands:
                col = f"{b}_{p}"
                if col in campaign_wide.columns:
                    v = pd.to_numeric(campaign_wide[col], errors="coerce").dropna()
                    ax.hist(v, bins=min(12, max(3, v.size)), alpha=0.6, color=COLORS.get(b), label=b)
            ax.set_title(p)
            ax.set_ylabel("sites")
        for ax in axes.ravel()[len(params) :]:
            ax.set_visible(False)
        axes.ravel()[0].legend()


#: (column of the quality table, axis label, key of the limit in QualityOptions, "max" | "min")
_QUALITY_PANELS = (
    ("dropout_pct", "dropouts (% of points)", "max_dropout_pct", "max"),
    ("replaced_pct", "replaced by despeckle (% of points)", "max_replaced_pct", "max"),
    ("height_step_mm", "height step (mm)", None, None),
    ("spikes_found", "spikes found (clusters)", None, None),
    ("tilt_deg", "tilt of the plane (deg)", "max_tilt_deg", "max"),
    ("usable_length_mm", "usable strip length along x (mm)", "min_usable_length_mm", "min"),
)


def plot_scan_quality(table: pd.DataFrame, limits: dict, path: str | Path) -> None:
    """Six panels, one bar per site: the scan-quality measures of ``table`` (skidsim.texture.quality), the
    limits of ``limits`` (QualityOptions fields) as dashed lines; a bar beyond its limit in red, the names of
    flagged sites (``status`` not ok) in red."""
    sites = table["site"].astype(str).tolist()
    flagged = (table["status"] != "ok").to_numpy() if "status" in table else np.zeros(len(table), bool)
    n = max(len(sites), 1)
    with figure(path, nrows=3, ncols=2, figsize=(max(8.0, 0.28 * n + 4.0), 8.5)) as (fig, axes):
        for ax, (col, label, lim_key, kind) in zip(axes.ravel(), _QUALITY_PANELS):
            values = table[col].to_numpy(dtype=float)
            lim = limits.get(lim_key) if lim_key else None
            beyond = np.zeros(values.size, bool)
            if lim is not None:
                beyond = values > float(lim) if kind == "max" else values < float(lim)
            ax.bar(np.arange(len(sites)), values, color=np.where(beyond, "#d62728", COLORS["ours"]))
            if lim is not None:
                ax.axhline(
                    float(lim),
                    color="#333333",
                    ls="--",
                    lw=0.9,
                    label=f"{'most' if kind == 'max' else 'least'} allowed: {float(lim):g}",
                )
                ax.legend(loc="best")
            ax.set_ylabel(label)
            ax.set_xticks(np.arange(len(sites)))
            ax.set_xticklabels(sites, rotation=90, fontsize=6 if n > 20 else 8)
            for tick, bad in zip(ax.get_xticklabels(), flagged):
                if bad:
                    tick.set_color("#d62728")
        n_flag = int(flagged.sum())
        fig.suptitle(
            f"Scan quality, {len(sites)} sites: {n_flag} flagged (red names; red bars beyond a limit)"
            if n_flag
            else f"Scan quality, {len(sites)} sites: none beyond the limits"
        )


def plot_despeckle_flat_binder(cases: list[dict], path: str | Path) -> None:
    """Before/after figure of the despeckle rules on flat-binder scans: per case (dict with ``label``, ``dx_mm``,
    ``row`` (one profile, mm, as scanned), ``rules`` {rule: despeckled profile}, ``replaced_pct`` {rule: %},
    ``mpd_err_pct`` {rule: %} and optionally ``x0_mm``, the start of the shown window), 30 mm of the profile and
    each rule's result, the replaced shares and MPD errors in the legend."""
    colors = {"mad": "#d95f02", "tukey": "#7570b3", "local": "#1b9e77", "study": "#e7298a"}
    with figure(path, nrows=len(cases), ncols=1, figsize=(9.0, 2.6 * len(cases))) as (fig, axes):
        for ax, c in zip(np.atleast_1d(axes), cases):
            j0 = int(round(c.get("x0_mm", 0.0) / c["dx_mm"]))
            j1 = min(c["row"].size, j0 + int(round(30.0 / c["dx_mm"])) + 1)
            x = np.arange(j0, j1) * c["dx_mm"]
            ax.plot(x, c["row"][j0:j1], color=COLORS["measured"], lw=1.6, label="as scanned (with spikes)")
            for name, prof in c["rules"].items():
                ax.plot(
                    x,
                    prof[j0:j1],
                    color=colors.get(name, "#666666"),
                    lw=0.9,
                    label=f"{name}: {c['replaced_pct'][name]:.2f} % replaced, MPD {c['mpd_err_pct'][name]:+.1f} %",
                )
            ax.set_title(c["label"])
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("height (mm)")
            ax.legend(loc="upper right", fontsize=7)
