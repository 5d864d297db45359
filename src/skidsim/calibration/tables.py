"""Validation runs and the campaign's result tables: FE runs of a law at given speeds, agreement statistics,
the long validation table, Figure 10's statistics, the method comparison and Table 2.

SN and mu are dimensionless (DFT scale); speeds in km/h; wall times in s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from skidsim.calibration.cache import Simulator, prefetch
from skidsim.calibration.measured import measured_at
from skidsim.calibration.options import CALIBRATION_SPEEDS_KMH, VALIDATION_SPEEDS_KMH
from skidsim.calibration.result import CalibrationResult
from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay


def simulate_speeds(
    simulate: Simulator, law: ExponentialDecay, speeds_kmh: Sequence[float] = VALIDATION_SPEEDS_KMH
) -> pd.DataFrame:
    """FE runs of ``law`` at ``speeds_kmh`` (km/h): DataFrame speed_kmh, sn_sim, n_steps, wall_s (s), cached.

    ``n_steps``/``wall_s`` are the cost of the FE run behind each value (also for cache hits). The runs are
    independent: a simulator that can batch runs them together (:func:`skidsim.calibration.cache.prefetch`).
    """
    prefetch(simulate, [(float(v), law) for v in speeds_kmh])
    rows = []
    for v in speeds_kmh:
        out = simulate(float(v), law)
        rows.append(
            {
                "speed_kmh": float(v),
                "sn_sim": float(out.sn),
                "n_steps": out.cost_steps,
                "wall_s": out.cost_wall_s,
                "cached": bool(out.cached),
            }
        )
    return pd.DataFrame(rows, columns=["speed_kmh", "sn_sim", "n_steps", "wall_s", "cached"])


def fit_statistics(sim, meas) -> dict:
    """Agreement of simulated with measured values (both dimensionless SN / mu).

    r2: coefficient of determination about the 1:1 line, ``1 - sum (sim - meas)^2 / sum (meas - mean)^2``
    (can be negative); r2_pearson: squared Pearson correlation (the R^2 of a fitted trend line, as in
    spreadsheet plots); rmse, mae; max_rel_err: max |sim/meas - 1|; n.
    """
    s = np.asarray(sim, dtype=float).ravel()
    m = np.asarray(meas, dtype=float).ravel()
    if s.shape != m.shape:
        raise ValueError(f"sim and meas must have the same length, got {s.size} and {m.size}")
    ok = np.isfinite(s) & np.isfinite(m)
    s, m = s[ok], m[ok]
    n = int(s.size)
    if n == 0:
        return {
            "n": 0,
            "r2": float("nan"),
            "r2_pearson": float("nan"),
            "rmse": float("nan"),
            "mae": float("nan"),
            "max_rel_err": float("nan"),
        }
    d = s - m
    sst = float(np.sum((m - m.mean()) ** 2))
    r2 = 1.0 - float(d @ d) / sst if sst > 0 else float("nan")
    if n >= 2 and s.std() > 0 and m.std() > 0:
        r2p = float(np.corrcoef(s, m)[0, 1] ** 2)
    else:
        r2p = float("nan")
    return {
        "n": n,
        "r2": r2,
        "r2_pearson": r2p,
        "rmse": float(np.sqrt(np.mean(d * d))),
        "mae": float(np.mean(np.abs(d))),
        "max_rel_err": float(np.max(np.abs(d / m))),
    }


def validation_table(
    runs: Mapping[str, Mapping[str, pd.DataFrame]],
    measured: Mapping[str, Any],
    *,
    calibration_speeds_kmh: Sequence[float] = CALIBRATION_SPEEDS_KMH,
    validation_speeds_kmh: Sequence[float] = VALIDATION_SPEEDS_KMH,
    window_kmh: float | None = None,
) -> pd.DataFrame:
    """Long table of simulated vs measured per site, method and speed.

    runs: ``{site: {method: DataFrame(speed_kmh, sn_sim, ...)}}`` as returned by :func:`simulate_speeds`
    for the final params (calibration and validation speeds). measured: ``{site: curve}``. Columns: site,
    method, speed_kmh, kind (``calibration`` / ``validation`` / ``other``), sn_sim, mu_measured, err
    (sn_sim - mu_measured), rel_err, n_steps, wall_s (s).
    """
    cal = {float(v) for v in calibration_speeds_kmh}
    val = {float(v) for v in validation_speeds_kmh}
    rows = []
    for site, per_method in runs.items():
        if site not in measured:
            raise InputError(None, f"a measured curve for site {site!r}", column="site", got=sorted(measured))
        for method, df in per_method.items():
            for col in ("speed_kmh", "sn_sim"):
                if col not in df.columns:
                    raise InputError(None, f"column in the runs of {site}/{method}", column=col, got="missing")
            mu = measured_at(
                measured[site],
                df["speed_kmh"].to_numpy(float),
                window_kmh=window_kmh,
                source=getattr(measured[site], "path", site),
            )
            for r, m in zip(df.itertuples(index=False), mu):
                v = float(r.speed_kmh)
                kind = "calibration" if v in cal else ("validation" if v in val else "other")
                rows.append(
                    {
                        "site": site,
                        "method": method,
                        "speed_kmh": v,
                        "kind": kind,
                        "sn_sim": float(r.sn_sim),
                        "mu_measured": float(m),
                        "err": float(r.sn_sim) - float(m),
                        "rel_err": float(r.sn_sim) / float(m) - 1.0,
                        "n_steps": int(getattr(r, "n_steps", 0) or 0),
                        "wall_s": float(getattr(r, "wall_s", 0.0) or 0.0),
                    }
                )
    return pd.DataFrame(
        rows,
        columns=["site", "method", "speed_kmh", "kind", "sn_sim", "mu_measured", "err", "rel_err", "n_steps", "wall_s"],
    )


def figure10_statistics(vtable: pd.DataFrame) -> pd.DataFrame:
    """R^2, RMSE, MAE, max relative error per method and kind (calibration / validation) over all sites."""
    rows = []
    for (method, kind), g in vtable.groupby(["method", "kind"], sort=True):
        rows.append({"method": method, "kind": kind, **fit_statistics(g["sn_sim"], g["mu_measured"])})
    return pd.DataFrame(rows, columns=["method", "kind", "n", "r2", "r2_pearson", "rmse", "mae", "max_rel_err"])


def _rmse_by(vtable: pd.DataFrame | None, site: str, method: str, kind: str) -> float:
    if vtable is None or not len(vtable):
        return float("nan")
    g = vtable[(vtable["site"] == site) & (vtable["method"] == method) & (vtable["kind"] == kind)]
    return float(np.sqrt(np.mean(g["err"] ** 2))) if len(g) else float("nan")


def comparison_table(
    results: Mapping[str, Mapping[str, CalibrationResult]],
    vtable: pd.DataFrame | None = None,
    *,
    methods: Sequence[str] = ("study", "ours"),
) -> pd.DataFrame:
    """One row per site plus ``TOTAL``: FE runs, FE time steps, wall time (s), fit error, per method.

    Columns ``<method>_fe_runs, _steps, _wall_s, _converged, _rmse_cal, _rmse_val`` (RMSE of SN vs measured
    at calibration / validation speeds from ``vtable``; without it ``_rmse_cal`` is the result's own
    ``fit_rmse``), and ``steps_ratio`` = steps of the second method / steps of the first. ``_converged`` is
    1/0 per site. In ``TOTAL`` counts and times are sums, ``_converged`` the number of converged sites, the
    RMSEs are over all points. Plain int/float/str columns (parquet- and CSV-safe).
    """
    rows = []
    for site in sorted(results):
        row: dict[str, Any] = {"site": site}
        for m in methods:
            r = results[site].get(m)
            if r is None:
                continue
            row[f"{m}_fe_runs"] = r.n_fe_runs
            row[f"{m}_steps"] = r.n_steps
            row[f"{m}_wall_s"] = r.wall_s
            row[f"{m}_converged"] = int(bool(r.converged))
            row[f"{m}_rmse_cal"] = _rmse_by(vtable, site, m, "calibration") if vtable is not None else r.fit_rmse
            row[f"{m}_rmse_val"] = _rmse_by(vtable, site, m, "validation")
        rows.append(row)
    df = pd.DataFrame(rows)
    if df.empty:
        return df
    tot: dict[str, Any] = {"site": "TOTAL"}
    for m in methods:
        if f"{m}_steps" not in df:
            continue
        for c in ("fe_runs", "steps", "wall_s"):
            tot[f"{m}_{c}"] = df[f"{m}_{c}"].sum()
        tot[f"{m}_converged"] = int(df[f"{m}_converged"].sum())
        for kind, c in (("calibration", "rmse_cal"), ("validation", "rmse_val")):
            if vtable is not None and len(vtable):
                g = vtable[(vtable["method"] == m) & (vtable["kind"] == kind)]
                tot[f"{m}_{c}"] = float(np.sqrt(np.mean(g["err"] ** 2))) if len(g) else float("nan")
            else:
                tot[f"{m}_{c}"] = float(np.sqrt(np.nanmean(df[f"{m}_{c}"] ** 2)))
    df = pd.concat([df, pd.DataFrame([tot])], ignore_index=True)
    if len(methods) >= 2 and f"{methods[0]}_steps" in df and f"{methods[1]}_steps" in df:
        df["steps_ratio"] = df[f"{methods[1]}_steps"] / df[f"{methods[0]}_steps"]
    for m in methods:
        if f"{m}_converged" in df:
            df[f"{m}_converged"] = df[f"{m}_converged"].astype("int64")
    return df


def table2(
    results: Mapping[str, Mapping[str, CalibrationResult]], *, methods: Sequence[str] = ("study", "ours")
) -> pd.DataFrame:
    """Parameters per site (like the study's Table 2): ``<method>_mu_s, _mu_k, _alpha_s_per_m, _converged``."""
    rows = []
    for site in sorted(results):
        row: dict[str, Any] = {"site": site}
        for m in methods:
            r = results[site].get(m)
            if r is None:
                continue
            row[f"{m}_mu_s"] = r.params.mu_s
            row[f"{m}_mu_k"] = r.params.mu_k
            row[f"{m}_alpha_s_per_m"] = r.params.alpha
            row[f"{m}_converged"] = bool(r.converged)
        rows.append(row)
    return pd.DataFrame(rows)


def _require_columns(df: pd.DataFrame, columns, name: str) -> None:
    """Raise :class:`InputError` unless ``df`` is a DataFrame holding ``columns`` (``name``: the table's name)."""
    if not isinstance(df, pd.DataFrame):
        raise InputError(name, "a pandas DataFrame", got=type(df).__name__)
    for c in columns:
        if c not in df.columns:
            raise InputError(name, f"column '{c}' (have {list(df.columns)})", column=c)


def geometric_factors(validation: pd.DataFrame, parameters: pd.DataFrame) -> pd.DataFrame:
    """The FE geometric factor ``g(v) = SN_sim(v) / mu_cal(v)`` (site, speed_kmh, g) of every simulated point of one
    calibration method: ``validation`` (site, speed_kmh, sn_sim), ``parameters`` (site, mu_s, mu_k, alpha s/m) the
    calibrated law of each site."""
    _require_columns(validation, ("site", "speed_kmh", "sn_sim"), "validation table")
    _require_columns(parameters, ("site", "mu_s", "mu_k", "alpha"), "calibration parameters table")
    p = parameters.set_index("site")
    missing = sorted(set(validation["site"]) - set(p.index))
    if missing:
        raise InputError(
            "calibration parameters table", "a calibrated law for every simulated site", column="site", got=missing[:5]
        )
    v = validation.assign(
        mu_cal=[
            ExponentialDecay(*p.loc[r.site, ["mu_s", "mu_k", "alpha"]]).mu_kmh(r.speed_kmh)
            for r in validation.itertuples()
        ]
    )
    return v.assign(g=v["sn_sim"] / v["mu_cal"])[["site", "speed_kmh", "g"]]
