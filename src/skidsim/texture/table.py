"""Long-form texture tables, the campaign table and the study's Table 4 statistics; the whole stage in one call."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import pandas as pd

from skidsim.atomic import write_parquet
from skidsim.surface import Surface

from .despeckle import despeckle
from .filters import separate_bands
from .mpd import MPDResult, mean_profile_depth
from .parameters import UNITS, TextureOptions, areal_parameters, cross_band_parameters

LONG_COLUMNS = ["site", "band", "parameter", "value", "unit"]
BANDS = ("raw", "macro", "micro")


def texture_table(
    site: str, band_params: dict[str, dict[str, tuple[float, str]]], mpd: MPDResult | None = None
) -> pd.DataFrame:
    """Long form ``site, band, parameter, value, unit``; MPD, its SD, ETD and segment counts as band
    ``"profile"``."""
    rows = [
        (site, band, name, float(v), unit) for band, params in band_params.items() for name, (v, unit) in params.items()
    ]
    if mpd is not None:
        rows += [
            (site, "profile", "MPD", mpd.mpd_mm, "mm"),
            (site, "profile", "MPD_sd", mpd.sd_mm, "mm"),
            (site, "profile", "ETD", mpd.etd_mm, "mm"),
            (site, "profile", "MPD_n_segments", float(mpd.n_segments), "1"),
            (site, "profile", "MPD_n_invalid_segments", float(mpd.n_invalid_segments), "1"),
        ]
    df = pd.DataFrame(rows, columns=LONG_COLUMNS)
    return df.astype({"site": "string", "band": "string", "parameter": "string", "value": "float64", "unit": "string"})


def write_texture_table(df: pd.DataFrame, path: str | Path) -> None:
    """Write a long table to parquet atomically (:func:`skidsim.atomic.write_parquet`)."""
    write_parquet(path, df)


def campaign_table(
    long_tables: list[pd.DataFrame] | pd.DataFrame, sites_df: pd.DataFrame | None = None, site_column: str = "site"
) -> pd.DataFrame:
    """Wide campaign table: one row per site, columns ``<band>_<parameter>``, joined (left) onto the site
    metadata ``sites_df`` by ``site_column``. Raises ValueError on duplicated (site, band, parameter)."""
    long = pd.concat(long_tables, ignore_index=True) if isinstance(long_tables, list) else long_tables
    missing = [c for c in LONG_COLUMNS if c not in long.columns]
    if missing:
        raise ValueError(f"campaign_table: long tables lack column(s) {missing}; expected {LONG_COLUMNS}")
    key = long["band"].astype(str) + "_" + long["parameter"].astype(str)
    dup = long.assign(_k=key).duplicated(["site", "_k"])
    if dup.any():
        first = long[dup].iloc[0]
        raise ValueError(
            f"campaign_table: duplicated entry site={first['site']!r} band={first['band']!r} "
            f"parameter={first['parameter']!r}"
        )
    wide = long.assign(_k=key).pivot(index="site", columns="_k", values="value")
    wide.columns.name = None
    wide = wide.reset_index()
    wide["site"] = wide["site"].astype(str)
    if sites_df is None:
        return wide
    if site_column not in sites_df.columns:
        raise ValueError(f"campaign_table: sites table lacks the column {site_column!r}")
    meta = sites_df.copy()
    meta[site_column] = meta[site_column].astype(str)
    return meta.merge(wide, left_on=site_column, right_on="site", how="left", suffixes=("", "_texture")).drop(
        columns=[] if site_column == "site" else ["site"]
    )


def table4_statistics(
    campaign_wide: pd.DataFrame, bands: tuple[str, ...] = ("macro", "micro", "raw", "profile")
) -> pd.DataFrame:
    """The study's Table 4: per parameter (rows) and band, the mean, max, min and SD (ddof = 1) over sites.

    Columns are a MultiIndex ``(statistic, band)``, statistics in the study's order Average, Maximum, Minimum,
    Standard Deviation."""
    recs = {}
    for col in campaign_wide.columns:
        band, _, name = str(col).partition("_")
        if band not in bands or not name:
            continue
        v = pd.to_numeric(campaign_wide[col], errors="coerce")
        for stat, val in (
            ("Average", v.mean()),
            ("Maximum", v.max()),
            ("Minimum", v.min()),
            ("Standard Deviation", v.std(ddof=1)),
        ):
            recs.setdefault(name, {})[(stat, band)] = val
    out = pd.DataFrame.from_dict(recs, orient="index")
    if out.empty:
        return out
    order = [
        (s, b) for s in ("Average", "Maximum", "Minimum", "Standard Deviation") for b in bands if (s, b) in out.columns
    ]
    out = out[order]
    out.columns = pd.MultiIndex.from_tuples(out.columns, names=["statistic", "band"])
    out.index.name = "parameter"
    return out


def characterise(
    surface: Surface, options: TextureOptions | dict | None = None, site: str | None = None
) -> tuple[pd.DataFrame, dict[str, Surface]]:
    """The whole texture stage for one scan: despeckle -> fill -> form removal -> bands -> all parameters on
    raw/macro/micro -> MPD (on the despeckled scan). Returns ``(long table, {"despeckled", "raw", "macro",
    "micro"} surfaces)``; the number of replaced points is in ``surfaces["despeckled"].meta["n_despeckled"]``."""
    opt = options if isinstance(options, TextureOptions) else TextureOptions.from_dict(options)
    site = surface.name if site is None else site
    des, n_rep = despeckle(surface, opt.despeckle_method, opt.despeckle_k, opt.despeckle_axis)
    des = des.with_heights(des.heights, meta={**des.meta, "n_despeckled": n_rep})
    mpd = mean_profile_depth(des, **opt.mpd_kwargs())
    bands = separate_bands(
        des, macro=opt.macro_mm, order=opt.butterworth_order, form=opt.form, fill=opt.fill, workers=opt.workers
    )
    params = band_parameters(bands, opt)
    return texture_table(site, params, mpd), {"despeckled": des, **bands}


#: Work units of one band for the thread pool (features and motifs share the hill segmentation).
_TASKS = (("features", "motifs"), ("spatial",), ("height", "hybrid", "material_ratio"), ("furrows",))


def band_parameters(bands: dict[str, Surface], options: TextureOptions) -> dict[str, dict[str, tuple[float, str]]]:
    """Every parameter of the raw, macro and micro bands: :func:`areal_parameters` of each band and
    :func:`cross_band_parameters` (the contact zone). The one home of that set, for the workflow's rule, the scans
    of ``skidsim predict`` and :func:`characterise`. With ``options.workers > 1`` the (band, parameter group) work
    units run in a thread pool of that size (NumPy, SciPy release the GIL in their heavy loops); otherwise one
    call per band. Results do not depend on the number of workers."""
    out: dict[str, dict[str, tuple[float, str]]] = {b: {} for b in BANDS}
    if options.workers > 1:
        wanted = set(options.groups)
        units = [(b, tuple(g for g in task if g in wanted)) for b in BANDS for task in _TASKS]
        units = [(b, g) for b, g in units if g]

        def run(unit):
            b, g = unit
            return areal_parameters(bands[b], b, replace(options, groups=g, workers=1))

        with ThreadPoolExecutor(max_workers=options.workers) as pool:
            for (b, _), r in zip(units, pool.map(run, units)):
                out[b].update(r)
    else:
        out = {b: areal_parameters(bands[b], b, options) for b in BANDS}
    for b, r in cross_band_parameters(bands, options).items():
        out[b].update(r)
    return {b: {k: out[b][k] for k in UNITS if k in out[b]} for b in BANDS}


__all__ = [
    "texture_table",
    "write_texture_table",
    "campaign_table",
    "table4_statistics",
    "characterise",
    "band_parameters",
    "LONG_COLUMNS",
    "BANDS",
]
