"""Residuals ``measured - model`` at the two levels of error, and their site x speed-bin matrices.

``"within-site"``: measured DFT mu against the per-site calibrated simulation ``SN_sim(v)``; ``"between-site"``:
against the texture-based predictions ``sn_pred(v)`` of held-out sites. Speeds km/h, friction mu (dimensionless).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import InputError

LEVELS = ("within-site", "between-site")
KINDS = ("calibration", "validation", "trace")
COLUMNS = ["site", "section", "level", "kind", "speed_kmh", "measured", "model", "residual"]


def require_columns(df, columns, name):
    """Raise :class:`InputError` unless ``df`` is a DataFrame holding ``columns`` (``name``: the table's name)."""
    if not isinstance(df, pd.DataFrame):
        raise InputError(name, "a pandas DataFrame", got=type(df).__name__)
    for c in columns:
        if c not in df.columns:
            raise InputError(name, f"column '{c}' (have {list(df.columns)})", column=c)


def finite_column(df, column, name) -> np.ndarray:
    """``df[column]`` as finite floats; :class:`InputError` naming the first bad row otherwise."""
    v = pd.to_numeric(df[column], errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(v)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputError(name, "finite numbers", row=row, column=column, got=df[column].iloc[row])
    return v


def interpolate_per_site(target: pd.DataFrame, model: pd.DataFrame, value: str) -> np.ndarray:
    """Linear interpolation in speed (km/h) of ``model[value]`` per site at ``target`` speeds; NaN outside range."""
    out = np.full(len(target), np.nan)
    groups = dict(iter(model.groupby("site", sort=False)))
    for site, idx in target.groupby("site", sort=False).indices.items():
        g = groups.get(site)
        if g is None:
            continue
        g = g.groupby("speed_kmh", as_index=False)[value].mean().sort_values("speed_kmh")
        xs, ys = g["speed_kmh"].to_numpy(float), g[value].to_numpy(float)
        v = target["speed_kmh"].to_numpy(float)[idx]
        res = np.interp(v, xs, ys) if len(xs) > 1 else np.where(np.isclose(v, xs[0]), ys[0], np.nan)
        res[(v < xs[0] - 1e-9) | (v > xs[-1] + 1e-9)] = np.nan
        out[idx] = res
    return out


def _measured_points(measured: pd.DataFrame, section_of: pd.Series) -> pd.DataFrame:
    require_columns(measured, ("site", "speed_kmh", "mu", "kind"), "measured table")
    m = measured[["site", "speed_kmh", "mu", "kind"]].copy()
    m["site"] = m["site"].astype(str)
    m["speed_kmh"] = finite_column(m, "speed_kmh", "measured table")
    m["mu"] = finite_column(m, "mu", "measured table")
    badk = ~m["kind"].isin(KINDS)
    if badk.any():
        row = int(np.flatnonzero(badk.to_numpy())[0])
        raise InputError("measured table", f"kind in {KINDS}", row=row, column="kind", got=m["kind"].iloc[row])
    unknown = sorted(set(m["site"]) - set(section_of.index))
    if unknown:
        raise InputError("measured table", "sites listed in the sites table", column="site", got=unknown[:5])
    return m


def _model_table(df: pd.DataFrame, column: str, name: str) -> pd.DataFrame:
    require_columns(df, ("site", "speed_kmh", column), name)
    df = df.assign(site=df["site"].astype(str))
    return df.assign(speed_kmh=finite_column(df, "speed_kmh", name), **{column: finite_column(df, column, name)})


def _level_rows(
    m: pd.DataFrame, model_df: pd.DataFrame, column: str, level: str, section_of: pd.Series
) -> pd.DataFrame | None:
    t = m[m["site"].isin(set(model_df["site"]))].reset_index(drop=True)
    if t.empty:
        return None
    t["model"] = interpolate_per_site(t, model_df, column)
    t = t[np.isfinite(t["model"])]
    t = t.assign(level=level, section=t["site"].map(section_of).to_numpy(), residual=t["mu"] - t["model"])
    return t.rename(columns={"mu": "measured"})


def build_residuals(
    sites: pd.DataFrame, measured: pd.DataFrame, simulated: pd.DataFrame, predicted: pd.DataFrame | None = None
) -> pd.DataFrame:
    """Residuals ``measured - model`` in long form, one row per measured point and level.

    ``sites``: (site, section, ...); ``measured``: (site, speed_kmh, mu, kind in {calibration, validation, trace});
    ``simulated``: (site, speed_kmh, sn) the calibrated simulation; ``predicted``: (site, speed_kmh, sn_pred)
    texture-based predictions of held-out sites, or None. Model values are interpolated linearly in speed within
    each site's simulated/predicted speeds; measured points outside that range are dropped (no extrapolation).
    Returns columns site, section, level, kind, speed_kmh (km/h), measured, model, residual (mu, dimensionless).
    """
    require_columns(sites, ("site", "section"), "sites table")
    section_of = sites.assign(site=sites["site"].astype(str)).set_index("site")["section"].astype(str)
    m = _measured_points(measured, section_of)
    models = [("within-site", _model_table(simulated, "sn", "simulated table"), "sn")]
    if predicted is not None:
        models.append(("between-site", _model_table(predicted, "sn_pred", "predicted table"), "sn_pred"))
    frames = [f for level, df, col in models if (f := _level_rows(m, df, col, level, section_of)) is not None]
    if not frames:
        raise InputError("simulated table", "model values for at least one measured site and speed")
    return pd.concat(frames, ignore_index=True)[COLUMNS]


def speed_bin_centres(speed_kmh, speed_bin_kmh: float) -> np.ndarray:
    """The speed bin (its centre, km/h) of each speed: the nearest multiple of ``speed_bin_kmh``, a speed halfway
    between two going to the even multiple (``np.round``). The bins of every residual profile of the diagnosis."""
    return np.round(np.asarray(speed_kmh, dtype=float) / speed_bin_kmh) * speed_bin_kmh


def residual_matrix(res: pd.DataFrame, speed_bin_kmh: float) -> tuple[list, np.ndarray, np.ndarray]:
    """(sites, bin centres km/h, R (n_sites, n_bins)) of mean residual per site and speed bin
    (:func:`speed_bin_centres`); bins not observed at every site are dropped."""
    b = speed_bin_centres(res["speed_kmh"], speed_bin_kmh)
    tab = res.assign(bin=b).pivot_table(index="site", columns="bin", values="residual", aggfunc="mean")
    tab = tab.loc[:, tab.notna().all(axis=0)]
    if tab.shape[1] == 0:
        raise InputError("residuals", f"speed bins ({speed_bin_kmh} km/h) observed at every site")
    return list(tab.index), tab.columns.to_numpy(float), tab.to_numpy(float)


def level_matrix(residuals: pd.DataFrame, level: str, speed_bin_kmh: float, value: str = "residual"):
    """:func:`residual_matrix` of one level's rows, of ``value`` (``"residual"`` or ``"measured"``)."""
    res = residuals[residuals["level"] == level]
    return residual_matrix(res.assign(site=res["site"].astype(str), residual=res[value]), speed_bin_kmh)


def texture_model_shape(residuals: pd.DataFrame, speed_bin_kmh: float) -> pd.DataFrame | None:
    """Per site and speed bin (index site, columns bin centres km/h) the mean of ``between-site residual -
    within-site residual`` of the same measured points, i.e. ``sn_sim - sn_pred`` (mu): what the texture model
    adds to the calibrated simulation's residual. None where some between-site point has no within-site residual
    (the between-site functional form then falls back to the between-site residual itself)."""
    cols = ["site", "kind", "speed_kmh", "measured"]
    if "measured" not in residuals.columns or "kind" not in residuals.columns:
        return None
    parts = []
    for level in LEVELS:
        r = residuals.loc[residuals["level"] == level, cols + ["residual"]]
        r = r.assign(site=r["site"].astype(str))
        parts.append(r.assign(_k=r.groupby(cols).cumcount()))
    w, b = parts
    m = b.merge(w, on=cols + ["_k"], how="left", suffixes=("", "_w"))
    if m.empty or m["residual_w"].isna().any():
        return None
    m = m.assign(residual=m["residual"] - m["residual_w"])
    try:
        ids, bins, R = residual_matrix(m, speed_bin_kmh)
    except InputError:
        return None
    return pd.DataFrame(R, index=ids, columns=bins)
