"""Evaluation scopes of an extension: held-out speeds (within sites: the law refitted through the calibration
points, evaluated at the other speeds) and held-out sites (between sites: the texture model's predictions).
Speeds km/h, friction mu (dimensionless)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError
from .extensions import fit_exp_curves


@dataclass
class Scope:
    """Rows to evaluate (held out) and per-site points to refit the law."""

    name: str
    rows: pd.DataFrame  # site, section, speed_kmh, kind, measured, before
    sites: list
    fit_v: np.ndarray  # (n_sites, J) km/h, NaN padded
    fit_y: np.ndarray
    row_site: np.ndarray  # index into sites per row
    base: tuple = ()  # (b, c, alpha) of the plain exponential fit to (fit_v, fit_y), per site
    curves: tuple | None = None  # (V km/h, Y mu) of the sites' whole measured DFT curves (measured_curves), or None


def _rows_and_fit(residuals: pd.DataFrame, level: str):
    """(scope name, rows to evaluate, points to fit the law with column y) of a level; None without rows."""
    r = residuals[residuals["level"] == level].copy()
    if r.empty:
        return None
    r["site"] = r["site"].astype(str)
    if level == "within-site":
        fit = r[r["kind"] == "calibration"]
        return "held_out_speeds", r[r["kind"] != "calibration"], fit.assign(y=fit["measured"])
    return "held_out_sites", r, r.assign(y=r["model"])


def _padded_points(fit: pd.DataFrame, sites: list) -> tuple[np.ndarray, np.ndarray]:
    """(speeds km/h, values) per site, NaN padded: the mean value per speed."""
    J = int(fit.groupby("site").size().max())
    fv = np.full((len(sites), J), np.nan)
    fy = np.full((len(sites), J), np.nan)
    pos = {s: k for k, s in enumerate(sites)}
    for s, g in fit.groupby("site"):
        g = g.groupby("speed_kmh", as_index=False)["y"].mean()
        fv[pos[s], : len(g)] = g["speed_kmh"].to_numpy(float)
        fy[pos[s], : len(g)] = g["y"].to_numpy(float)
    return fv, fy


#: Lowest speed (km/h) of the measured DFT points in :func:`measured_curves`: below it the disc is stopping.
CURVE_MIN_SPEED_KMH = 5.0


def measured_curves(measured: pd.DataFrame, sites: list, min_speed_kmh: float = CURVE_MIN_SPEED_KMH):
    """The whole measured DFT curve of each site of ``sites`` (every point of ``measured``: site, speed_kmh, mu,
    at or above ``min_speed_kmh``, equal speeds averaged), as ``(V km/h, Y mu)`` (n_sites, J), NaN padded; None
    when a site has no point or none has 4 speeds (as :func:`skidsim.criticism.wlf.site_curves`). Unlike the
    residual rows, which stop where the simulation does (20-70 km/h by default), the curve keeps the trace's low
    speeds, where the decay of friction with slip speed shows."""
    m = measured[["site", "speed_kmh", "mu"]].assign(site=measured["site"].astype(str))
    m = m[(m["speed_kmh"] >= min_speed_kmh) & np.isfinite(m["mu"]) & m["site"].isin(set(sites))]
    if m.empty or m["site"].nunique() < len(sites):
        return None
    V, Y = _padded_points(m.rename(columns={"mu": "y"}), sites)
    return (V, Y) if np.isfinite(V).sum(axis=1).max() >= 4 else None


def make_scope(residuals: pd.DataFrame, level: str, measured: pd.DataFrame | None = None) -> Scope | None:
    """The scope of a level; sites with fewer than 3 points to fit the law are left out; None below 4 sites.
    ``measured`` (site, speed_kmh, mu): the DFT points, for the between-site scope's whole measured curves
    (:func:`measured_curves`; None: the scope holds none)."""
    parts = _rows_and_fit(residuals, level)
    if parts is None:
        return None
    name, rows, fit = parts
    sites = sorted(set(rows["site"]) & set(fit["site"]))
    if len(sites) < 4:
        return None
    rows = rows[rows["site"].isin(sites)].rename(columns={"model": "before"}).reset_index(drop=True)
    fv, fy = _padded_points(fit[fit["site"].isin(sites)], sites)
    ok = np.isfinite(fy).sum(axis=1) >= 3
    keep = [s for s, k in zip(sites, ok) if k]
    if len(keep) < 4:
        return None
    if not ok.all():
        return make_scope(residuals[~residuals["site"].astype(str).isin(set(sites) - set(keep))], level, measured)
    pos = {s: k for k, s in enumerate(sites)}
    curves = measured_curves(measured, sites) if measured is not None and name == "held_out_sites" else None
    return Scope(name, rows, sites, fv, fy, rows["site"].map(pos).to_numpy(), fit_exp_curves(fv, fy), curves)


def site_values(cov: pd.DataFrame, column: str, sites: list) -> np.ndarray:
    """``cov[column]`` at ``sites`` as floats; :class:`InputError` naming a missing column."""
    if column not in cov.columns:
        raise InputError("sites table / texture table", f"a numeric column '{column}'", column=column)
    return cov.loc[sites, column].to_numpy(float)


def site_mean(x: np.ndarray, i: np.ndarray, n_sites: int) -> np.ndarray:
    """Per-row mean of ``x`` over the rows of the same site."""
    return (np.bincount(i, weights=x, minlength=n_sites) / np.maximum(np.bincount(i, minlength=n_sites), 1))[i]


def centred_speed(scope: Scope) -> np.ndarray:
    """Per row, the speed minus the mean of its site's evaluated speeds (km/h)."""
    v = scope.rows["speed_kmh"].to_numpy(float)
    return v - site_mean(v, scope.row_site, len(scope.sites))


def site_target(on: str, scope: Scope, values: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Per site of the scope: the mean of ``values`` over its rows (``on="level"``, mu) or their least-squares
    slope on the centred speed ``dv`` (``on="slope"``, mu per km/h)."""
    i, n_s = scope.row_site, len(scope.sites)
    if on == "level":
        return np.bincount(i, weights=values, minlength=n_s) / np.bincount(i, minlength=n_s)
    return np.bincount(i, weights=dv * values, minlength=n_s) / np.bincount(i, weights=dv * dv, minlength=n_s)
