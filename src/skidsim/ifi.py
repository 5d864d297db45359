"""The International Friction Index (IFI, ASTM E1960) and the PIARC/IFI speed model.

From the DFT friction coefficient at 20 km/h (DFT20, dimensionless) and the mean profile depth (MPD, mm):

* speed constant ``Sp = 14.2 + 89.7 MPD`` (km/h);
* friction at 60 km/h adjusted to the DFT: ``FR60 = DFT20 exp(-40 / Sp)`` (the PIARC model from 20 to 60 km/h);
* ``F60 = 0.081 + 0.732 FR60`` (ASTM E1960 calibration constants of the DFT, A = 0.081, B = 0.732).

The IFI is the pair (F60, Sp). The PIARC/IFI speed model predicts friction at any speed v (km/h) from DFT20 and
MPD alone: ``mu(v) = DFT20 exp((20 - v) / Sp)``. :func:`model_validation_rows` sets it beside the FE-calibrated
laws at the validation speeds (same measured values, same statistics).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from .errors import InputError

SP_INTERCEPT_KMH = 14.2
SP_SLOPE_KMH_PER_MM = 89.7
F60_A = 0.081
F60_B = 0.732
DFT_REFERENCE_SPEED_KMH = 20.0
IFI_SPEED_KMH = 60.0
#: name of the PIARC/IFI model in validation tables (beside the calibration methods "study", "ours")
MODEL = "piarc_ifi"
COLUMNS = ["site", "mpd_mm", "dft20", "sp_kmh", "fr60", "f60"]


def speed_constant_kmh(mpd_mm):
    """Sp (km/h) = 14.2 + 89.7 MPD (mm)."""
    return SP_INTERCEPT_KMH + SP_SLOPE_KMH_PER_MM * np.asarray(mpd_mm, dtype=float)


def piarc_mu(speed_kmh, dft20, sp_kmh):
    """PIARC/IFI friction at ``speed_kmh`` (km/h): DFT20 exp((20 - v) / Sp), Sp in km/h."""
    v = np.asarray(speed_kmh, dtype=float)
    return np.asarray(dft20, dtype=float) * np.exp((DFT_REFERENCE_SPEED_KMH - v) / np.asarray(sp_kmh, dtype=float))


def fr60(dft20, sp_kmh):
    """FR60 = DFT20 exp(-40 / Sp) (dimensionless; Sp in km/h)."""
    return piarc_mu(IFI_SPEED_KMH, dft20, sp_kmh)


def f60(fr60_value):
    """F60 = 0.081 + 0.732 FR60 (dimensionless)."""
    return F60_A + F60_B * np.asarray(fr60_value, dtype=float)


def ifi(mpd_mm: float, dft20: float) -> dict:
    """``{"sp_kmh", "fr60", "f60"}`` of one site (MPD in mm, DFT20 dimensionless); NaN where an input is NaN."""
    sp = float(speed_constant_kmh(mpd_mm))
    r = float(fr60(dft20, sp))
    return {"sp_kmh": sp, "fr60": r, "f60": float(f60(r))}


def dft20_of_traces(traces: pd.DataFrame, window_kmh: float | None = 5.0) -> dict:
    """DFT20 of each site of a long trace table (site, speed_kmh, mu), as the campaign's DFT value at a speed
    (config ``ingest.dft_smooth_window_kmh``): local linear fit within +-``window_kmh`` km/h of 20 km/h, or linear
    interpolation when None (:class:`skidsim.dft.DftTrace`)."""
    from .dft import DftTrace

    out = {}
    for site, g in traces.groupby("site", sort=True):
        tr = DftTrace.from_samples(g["speed_kmh"], g["mu"], path=f"DFT trace of {site}")
        v = [DFT_REFERENCE_SPEED_KMH]
        out[site] = float((tr.at(v) if window_kmh is None else tr.smooth_at(v, window_kmh))[0])
    return out


def ifi_table(mpd_mm: dict, dft20: dict) -> pd.DataFrame:
    """One row per site (sorted): site, mpd_mm, dft20, sp_kmh (km/h), fr60, f60. ``mpd_mm`` and ``dft20``: dicts
    site -> value with the same sites; a site whose MPD is not available (NaN) gets NaN IFI values."""
    if set(mpd_mm) != set(dft20):
        raise InputError(
            None, "an MPD and a DFT20 for the same sites", column="site", got=sorted(set(mpd_mm) ^ set(dft20))
        )
    rows = [
        {"site": s, "mpd_mm": float(mpd_mm[s]), "dft20": float(dft20[s]), **ifi(mpd_mm[s], dft20[s])}
        for s in sorted(mpd_mm)
    ]
    return pd.DataFrame(rows, columns=COLUMNS)


def model_validation_rows(table: pd.DataFrame, vtable: pd.DataFrame) -> pd.DataFrame:
    """Rows of the validation table (:func:`skidsim.calibration.validation_table`) for the PIARC/IFI model: for each
    site and speed of ``vtable`` (every kind), ``sn_sim`` = the model's mu(v) from the site's DFT20 and Sp, against
    the same ``mu_measured``. Columns: site, method (``piarc_ifi``), speed_kmh, kind, sn_sim, mu_measured, err,
    rel_err."""
    missing = sorted(set(vtable["site"]) - set(table["site"]))
    if missing:
        raise InputError(None, "an IFI row for every site of the validation table", column="site", got=missing)
    pts = vtable.drop_duplicates(["site", "speed_kmh"])[["site", "speed_kmh", "kind", "mu_measured"]]
    pts = pts.merge(table[["site", "dft20", "sp_kmh"]], on="site", how="left")
    sim = piarc_mu(pts["speed_kmh"], pts["dft20"], pts["sp_kmh"])
    out = pd.DataFrame(
        {
            "site": pts["site"],
            "method": MODEL,
            "speed_kmh": pts["speed_kmh"].astype(float),
            "kind": pts["kind"],
            "sn_sim": sim,
            "mu_measured": pts["mu_measured"].astype(float),
        }
    )
    out["err"] = out["sn_sim"] - out["mu_measured"]
    out["rel_err"] = out["sn_sim"] / out["mu_measured"] - 1.0
    return out.reset_index(drop=True)


def comparison_statistics(rows: pd.DataFrame, speeds_kmh: Sequence[float]) -> pd.DataFrame:
    """RMSE and R^2 (about the 1:1 line; :func:`skidsim.calibration.fit_statistics`) of each model (FE methods and
    ``piarc_ifi``) at the given speeds, all together (``speed_kmh`` = ``"all"``) and per speed, side by side:
    columns speed_kmh, n, ``<model>_rmse``, ``<model>_r2`` for each model, and ``best_model`` (the model with the
    lowest RMSE there)."""
    from .calibration import fit_statistics

    speeds = [float(v) for v in speeds_kmh]
    sub = rows[rows["speed_kmh"].astype(float).isin(speeds)]
    models = list(dict.fromkeys(m for m in sub["method"] if m != MODEL)) + [MODEL]
    out = []
    for label, g in [("all", sub)] + [(f"{v:g}", sub[sub["speed_kmh"].astype(float) == v]) for v in speeds]:
        row = {"speed_kmh": label, "n": int(g[g["method"] == MODEL]["mu_measured"].notna().sum())}
        for m in models:
            gm = g[g["method"] == m]
            st = fit_statistics(gm["sn_sim"], gm["mu_measured"])
            row[f"{m}_rmse"], row[f"{m}_r2"] = st["rmse"], st["r2"]
        rmse = {m: row[f"{m}_rmse"] for m in models if np.isfinite(row[f"{m}_rmse"])}
        row["best_model"] = min(rmse, key=rmse.get) if rmse else ""
        out.append(row)
    return pd.DataFrame(out)


def wins(stats: pd.DataFrame) -> list[str]:
    """Sentences naming where the PIARC/IFI model has a lower RMSE than an FE-calibrated method."""
    models = [c.removesuffix("_rmse") for c in stats.columns if c.endswith("_rmse") and c != f"{MODEL}_rmse"]
    out = []
    for _, r in stats.iterrows():
        beaten = [m for m in models if r[f"{MODEL}_rmse"] < r[f"{m}_rmse"]]
        if beaten:
            where = "over all validation speeds" if r["speed_kmh"] == "all" else f"at {r['speed_kmh']} km/h"
            out.append(
                f"PIARC/IFI model beats {', '.join(beaten)} {where}: RMSE {r[f'{MODEL}_rmse']:.4f} vs "
                + ", ".join(f"{r[f'{m}_rmse']:.4f}" for m in beaten)
            )
    return out
