"""The regression's inputs: feature columns of the campaign table and the friction targets (:class:`Design`).

* **Features**: every column named ``raw_*``, ``macro_*``, ``micro_*`` or ``profile_*`` plus ``temperature_c``
  (deg C). Other columns (site, section, metadata) are never features.
* **Targets**: the exponential-decay parameters ``mu_s``, ``mu_k`` (dimensionless) and ``alpha`` (s/m, see
  :mod:`skidsim.friction`) of every site.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

#: Column prefixes that mark texture features (bands).
BANDS = ("raw", "macro", "micro", "profile")
#: The friction parameters (alpha in s/m).
PARAMETERS = ("mu_s", "mu_k", "alpha")
#: The one non-texture feature: the site's temperature (deg C).
TEMPERATURE_COLUMN = "temperature_c"


def split_band(column: str) -> tuple[str, str]:
    """``"macro_Sq" -> ("macro", "Sq")``; ``"temperature_c" -> ("temperature", "temperature_c")``."""
    for band in BANDS:
        if column.startswith(band + "_"):
            return band, column[len(band) + 1 :]
    if column == TEMPERATURE_COLUMN:
        return "temperature", column
    return "other", column


def texture_columns(X: pd.DataFrame) -> list[str]:
    """The texture columns of a feature table (``raw_*``, ``macro_*``, ``micro_*``, ``profile_*``; no temperature)."""
    return [c for c in X.columns if isinstance(c, str) and any(c.startswith(b + "_") for b in BANDS)]


def feature_columns(table: pd.DataFrame) -> list[str]:
    """Texture columns (``raw_*``, ``macro_*``, ``micro_*``, ``profile_*``) plus ``temperature_c`` if present."""
    cols = texture_columns(table)
    if TEMPERATURE_COLUMN in table.columns:
        cols.append(TEMPERATURE_COLUMN)
    return cols


def _numeric_frame(df: pd.DataFrame, columns: Sequence[str], file) -> pd.DataFrame:
    out = {}
    for c in columns:
        s = df[c]
        v = pd.to_numeric(s, errors="coerce")
        bad = v.isna() & s.notna()
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise InputError(file, "a number", row=row, column=c, got=s.iloc[row])
        out[c] = v.astype(float)
    return pd.DataFrame(out, index=df.index)


@dataclass(frozen=True)
class Design:
    """The regression's inputs, all indexed by site id.

    ``X``: features (texture in their own units, mm, %, 1/mm ..., temperature in deg C); ``Y``: ``mu_s``, ``mu_k``
    (dimensionless) and ``alpha`` (s/m), or ``None``; ``groups``: the section of each site.
    """

    X: pd.DataFrame
    Y: pd.DataFrame | None
    groups: pd.Series


def _feature_frame(campaign: pd.DataFrame, campaign_file) -> tuple[pd.DataFrame, pd.Series]:
    """The features (indexed by site) and the section of every site of the wide campaign table."""
    for col in ("site", "section"):
        if col not in campaign.columns:
            raise InputError(campaign_file, f"a '{col}' column", column=col, got=list(campaign.columns)[:8])
    sites = campaign["site"].astype(str)
    dup = sites[sites.duplicated()]
    if len(dup):
        raise InputError(campaign_file, "one row per site", column="site", got=dup.iloc[0])
    feats = feature_columns(campaign)
    if not feats:
        raise InputError(
            campaign_file,
            "texture columns named <band>_<parameter> (bands raw, macro, micro, profile)",
            got=list(campaign.columns)[:8],
        )
    X = _numeric_frame(campaign, feats, campaign_file)
    X.index = pd.Index(sites, name="site")
    groups = pd.Series(campaign["section"].astype(str).to_numpy(), index=X.index, name="section")
    return X, groups


def _friction_frame(friction: pd.DataFrame, sites: pd.Index, campaign_file, friction_file) -> pd.DataFrame:
    """The friction parameters of the friction table, one finite value per site, in the order of ``sites``."""
    for col in ("site",) + PARAMETERS:
        if col not in friction.columns:
            raise InputError(friction_file, f"a '{col}' column", column=col, got=list(friction.columns))
    fs = friction["site"].astype(str)
    if fs.duplicated().any():
        raise InputError(friction_file, "one row per site", column="site", got=fs[fs.duplicated()].iloc[0])
    Y = _numeric_frame(friction, PARAMETERS, friction_file)
    Y.index = pd.Index(fs, name="site")
    for col in PARAMETERS:
        if Y[col].isna().any():
            raise InputError(friction_file, "a finite value for every site", column=col, got=Y.index[Y[col].isna()][0])
    missing = sorted(set(Y.index) - set(sites))
    if missing:
        raise InputError(campaign_file, "a row for every site of the friction table", column="site", got=missing[0])
    missing = sorted(set(sites) - set(Y.index))
    if missing:
        raise InputError(friction_file, "a row for every site of the campaign table", column="site", got=missing[0])
    return Y.loc[sites]


def assemble_design(
    campaign: pd.DataFrame,
    friction: pd.DataFrame | None = None,
    *,
    campaign_file="campaign table",
    friction_file="friction table",
) -> Design:
    """Build :class:`Design` from the wide campaign table (one row per site) and the friction table.

    Raises :class:`~skidsim.errors.InputError` naming the table and column for a missing ``site``/``section``
    column, duplicate sites, no feature columns, non-numeric values, a missing friction column or a site of the
    friction table that the campaign table lacks (and vice versa).
    """
    X, groups = _feature_frame(campaign, campaign_file)
    Y = None if friction is None else _friction_frame(friction, X.index, campaign_file, friction_file)
    return Design(X=X, Y=Y, groups=groups)
