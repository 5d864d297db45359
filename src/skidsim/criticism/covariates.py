"""Candidate causes: the per-site covariates (sites.csv columns and texture parameters), their roles (temperature,
MPD), the texture clusters tested as one unit, and the texture principal components the between-site tests
condition on. Temperatures deg C, MPD mm."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError
from .residuals import level_matrix, require_columns

#: sites.csv columns never treated as candidate causes (identifiers and file paths).
DEFAULT_EXCLUDE = ("site", "scan", "dft", "scan_path", "dft_path", "path", "file")


@dataclass(frozen=True)
class CandidateRoles:
    """Which columns are candidates and which carry the physical hypotheses: ``exclude`` (sites.csv columns that
    are identifiers or paths), ``temperature_column`` (deg C; None: every numeric sites.csv column named like
    'temp', :func:`temperature_columns`) and ``mpd_column`` (mm; None: :func:`find_mpd_column`)."""

    exclude: tuple = DEFAULT_EXCLUDE
    temperature_column: str | None = None
    mpd_column: str | None = None


#: A column (sites.csv or texture table) with values at fewer than this share of the sites is not a candidate: its
#: mean-filled rest would be tested as if it were measured (docs/model-criticism.md, section 2).
MIN_PRESENT_SHARE = 0.5


def _constant(v: pd.Series) -> bool:
    """One value at every site with a value, up to rounding (a mean of equal floats is not always that float)."""
    a = v.to_numpy(dtype=float)
    return bool(np.nanstd(a) <= 1e-12 * max(1.0, float(np.nanmax(np.abs(a)))))


def _sites_column(col: pd.Series, name: str, n: int) -> tuple[pd.Series | None, str]:
    """One sites.csv column as a candidate: (values, "numeric" | "categorical"), or (None, why it is not one)."""
    present = int(col.notna().sum())
    if present < MIN_PRESENT_SHARE * n:
        return None, f"values at {present} of {n} sites (fewer than {MIN_PRESENT_SHARE:.0%})"
    num = pd.to_numeric(col, errors="coerce")
    is_num = col.dtype == bool or (num.notna().sum() == present and present > 0)
    if is_num and name != "section":
        v = num.astype(float)
        if _constant(v):
            return None, "one value at every site"
        return v.fillna(v.mean()), "numeric"
    v = col.astype(str).where(col.notna(), "NA")
    k = v.nunique()
    if k < 2:
        return None, "one value at every site"
    if k >= n:
        return None, "a different value at every site (an identifier, not a grouping)"
    return v, "categorical"


def _texture_table(texture_wide: pd.DataFrame, index: pd.Index) -> dict[str, pd.Series]:
    """The numeric columns of the texture table on the sites ``index`` (NaN where a site has no value)."""
    t = texture_wide.copy()
    if "site" in t.columns:
        t = t.assign(site=t["site"].astype(str)).set_index("site")
    t.index = t.index.astype(str)
    out = {}
    for c in t.columns:
        v = pd.to_numeric(t[c], errors="coerce")
        if v.notna().sum():  # a text column (a method's name, a flag) is not a texture parameter
            out[str(c)] = v.reindex(index)
    return out


def _texture_why(v: pd.Series) -> str | None:
    """Why a texture column (values per site, NaN: none) is not a candidate, or None."""
    present, n = int(v.notna().sum()), len(v)
    if present < MIN_PRESENT_SHARE * n:
        return f"texture table: values at {present} of {n} sites (fewer than {MIN_PRESENT_SHARE:.0%})"
    if _constant(v):
        return "texture table: one value at every site"
    return None


def _sorted_columns(sites: pd.DataFrame, texture_wide, exclude) -> tuple[pd.Index, dict, dict, dict]:
    """Both tables' columns sorted into candidates and the rest: (site index, {name: values}, {name: (source,
    dtype)}, {name: why not a candidate})."""
    require_columns(sites, ("site", "section"), "sites table")
    s = sites.assign(site=sites["site"].astype(str)).set_index("site")
    if s.index.duplicated().any():
        raise InputError("sites table", "unique site names", column="site", got=list(s.index[s.index.duplicated()][:3]))
    out, info, why = {}, {}, {}
    excl = {e.lower() for e in exclude}
    for c in s.columns:
        if str(c).lower() in excl:
            continue
        v, dtype = _sites_column(s[c], str(c), len(s))
        if v is None:
            why[str(c)] = dtype
        else:
            out[str(c)] = v
            info[str(c)] = ("sites", dtype)
    for c, v in (_texture_table(texture_wide, s.index) if texture_wide is not None else {}).items():
        if c in out:  # a sites.csv column of that name is the candidate
            continue
        reason = _texture_why(v)
        if reason is None:
            out[c] = v.fillna(v.mean()).astype(float)
            info[c] = ("texture", "numeric")
        else:
            why.setdefault(c, reason)
    return s.index, out, info, why


def untested_columns(
    sites: pd.DataFrame, texture_wide: pd.DataFrame | None = None, *, exclude=DEFAULT_EXCLUDE
) -> dict[str, str]:
    """The sites.csv columns (but ``exclude``, identifiers and paths) and numeric texture-table columns that are
    not candidate causes of :func:`site_covariates`, each with why: values at fewer than half the sites, one value
    at every site, or (sites.csv) a different value at every site."""
    return _sorted_columns(sites, texture_wide, exclude)[3]


def site_covariates(
    sites: pd.DataFrame, texture_wide: pd.DataFrame | None = None, *, exclude=DEFAULT_EXCLUDE
) -> tuple[pd.DataFrame, dict]:
    """All candidate covariates per site (index = site) and their source/dtype: {name: (source, dtype)}.

    sites.csv: every column but ``exclude``; booleans and numbers are numeric, anything else categorical;
    constant columns, categoricals with one level per site (identifiers) and columns with values at fewer than
    half the sites (``MIN_PRESENT_SHARE``) are dropped (:func:`untested_columns` says which and why); missing
    numeric values are replaced by the column mean, missing categories are the level "NA". Texture table (index =
    site or a 'site' column): every numeric column, under the same rules.
    """
    index, out, info, _ = _sorted_columns(sites, texture_wide, exclude)
    return pd.DataFrame(out, index=index), info


def names_temperature(name: str, dtype: str) -> bool:
    """Whether a numeric column called ``name`` is a temperature (deg C): its name contains 'temp'."""
    return dtype == "numeric" and "temp" in str(name).lower()


def temperature_columns(cov: pd.DataFrame, info: dict) -> list[str]:
    """Numeric sites.csv columns whose name contains 'temp' (deg C): the temperature hypotheses (primary family)."""
    return [c for c in cov.columns if info[c][0] == "sites" and names_temperature(c, info[c][1])]


def find_mpd_column(cov: pd.DataFrame, info: dict | None = None) -> str | None:
    """The mean profile depth column (mm): a numeric column named like MPD (``mpd``, ``mpd_mm``, ``profile_MPD``,
    case-insensitive); companion statistics (``*_sd``, ``*_n_*``, ``*segments*``) are not MPD. None if absent."""

    def ok(c):
        lc = str(c).lower()
        return "mpd" in lc and not lc.endswith("_sd") and "_n_" not in lc and "segment" not in lc

    names = [c for c in cov.columns if ok(c) and (info is None or info[c][1] == "numeric")]
    if not names:
        return None
    exact = [c for c in names if str(c).lower() in ("mpd", "mpd_mm", "profile_mpd", "profile_mpd_mm")]
    return str((exact or sorted(names, key=len))[0])


def texture_clusters(cov: pd.DataFrame, info: dict, rho: float = 0.8) -> list[list[str]]:
    """Clusters of the numeric texture columns: complete-linkage hierarchical clustering on 1 - |Spearman rho|
    across sites, cut at 1 - ``rho``: every pair of members of a cluster has |rho| >= ``rho``. Deterministic:
    clusters ordered by their first member in column order."""
    tex = [c for c in cov.columns if info[c][0] == "texture" and info[c][1] == "numeric"]
    if len(tex) < 2:
        return [[c] for c in tex]
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    r = cov[tex].rank().corr().abs().to_numpy()
    r = np.nan_to_num(r, nan=0.0)
    d = np.clip(1.0 - r, 0.0, None)
    np.fill_diagonal(d, 0.0)
    lab = fcluster(linkage(squareform((d + d.T) / 2, checks=False), "complete"), 1.0 - rho, "distance")
    out = {}
    for c, k in zip(tex, lab):
        out.setdefault(k, []).append(c)
    return list(out.values())


@dataclass(frozen=True)
class CandidateSet:
    """Every candidate of one campaign: ``covariates`` (one row per site), ``info`` ({name: (source, dtype)}),
    ``section_of`` (site -> section), texture ``clusters``, the ``temperature`` columns (deg C) and the ``mpd``
    column (mm, or None) of the primary hypotheses."""

    covariates: pd.DataFrame
    info: dict
    section_of: pd.Series
    clusters: list
    temperature: list
    mpd: str | None

    def cluster_of(self, name: str) -> list | None:
        """The texture cluster (of more than one member) holding ``name``, else None."""
        for members in self.clusters:
            if name in members:
                return members if len(members) > 1 else None
        return None


def candidate_set(
    sites: pd.DataFrame, texture_wide: pd.DataFrame | None, roles: CandidateRoles, cluster_rho: float
) -> CandidateSet:
    """The :class:`CandidateSet` of a campaign; raises :class:`InputError` for a named role column that is not a
    candidate."""
    cov, info = site_covariates(sites, texture_wide, exclude=roles.exclude)
    section_of = sites.assign(site=sites["site"].astype(str)).set_index("site")["section"].astype(str)
    for c, what in ((roles.temperature_column, "temperature_column"), (roles.mpd_column, "mpd_column")):
        if c is not None and c not in cov.columns:
            raise InputError("sites table / texture table", f"the {what} '{c}' as a numeric column", column=c)
    temps = temperature_columns(cov, info) if roles.temperature_column is None else [roles.temperature_column]
    mpd = find_mpd_column(cov, info) if roles.mpd_column is None else roles.mpd_column
    return CandidateSet(cov, info, section_of, texture_clusters(cov, info, cluster_rho), temps, mpd)


# ----------------------------------------------------------------------------------------------------------------
# texture principal components
# ----------------------------------------------------------------------------------------------------------------


def texture_scores(cov: pd.DataFrame, info: dict) -> np.ndarray:
    """Principal-component scores (n_sites, m) of the campaign's texture columns (``info`` source "texture"), each
    standardised over the sites of ``cov``; columns ordered by explained variance. Unsupervised (no friction
    enters), so the scores can be used inside any cross-validation fold. Empty (n, 0) without texture columns."""
    cols = [c for c in cov.columns if info[c][0] == "texture"]
    if not cols:
        return np.zeros((len(cov), 0))
    X = cov[cols].to_numpy(float)
    sd = X.std(axis=0)
    X = (X[:, sd > 0] - X[:, sd > 0].mean(axis=0)) / sd[sd > 0]
    U, S, _ = np.linalg.svd(X, full_matrices=False)
    keep = S > S[0] * 1e-10 if len(S) else S > 0
    return U[:, keep] * S[keep]


def score_table(scores: np.ndarray, index) -> pd.DataFrame:
    """PC scores as a table indexed by site with columns ``_tpc1, _tpc2, ...``."""
    return pd.DataFrame(scores, index=index, columns=[f"_tpc{j}" for j in range(1, scores.shape[1] + 1)])


def between_site_texture_scores(
    residuals: pd.DataFrame,
    sites: pd.DataFrame,
    texture_wide: pd.DataFrame | None,
    speed_bin_kmh: float = 10.0,
    exclude=DEFAULT_EXCLUDE,
) -> pd.DataFrame | None:
    """Texture PC scores (:func:`texture_scores`) standardised over the sites the between-site tests use (every
    speed bin observed), as a :func:`score_table`; None without between-site residuals at 4 sites or without
    texture columns. :func:`skidsim.criticism.diagnose` computes it once and hands it to the screening, the
    added-variable data and the texture-refit extensions, so that all three condition on the same PCs."""
    res = residuals[residuals["level"] == "between-site"]
    if res["site"].nunique() < 4:
        return None
    try:
        ids, _, _ = level_matrix(residuals, "between-site", speed_bin_kmh)
    except InputError:
        return None
    cov, info = site_covariates(sites, texture_wide, exclude=exclude)
    ids = [s for s in ids if s in cov.index]
    sc = texture_scores(cov.loc[ids], info)
    if sc.shape[1] == 0:
        return None
    return score_table(sc, ids)


def _holds_exactly(table: pd.DataFrame | None, ids) -> bool:
    """Whether the score table ``table`` is given and holds exactly the sites ``ids`` (then its scores are used)."""
    return table is not None and set(table.index) == set(ids)


def scores_for(ids, table: pd.DataFrame | None, cov: pd.DataFrame, info: dict) -> np.ndarray:
    """The PC scores of ``ids`` from ``table`` when it holds exactly those sites, else computed over ``ids``."""
    if _holds_exactly(table, ids):
        return table.loc[list(ids)].to_numpy(float)
    return texture_scores(cov.loc[list(ids)], info)


def lead_count(ids, table: pd.DataFrame | None) -> int:
    """How many of the leading columns of :func:`scores_for`'s scores of ``ids`` are the prediction model's own
    (``table.attrs["n_lead"]``): 0 when the scores are computed over ``ids`` (``table`` None or of other sites)."""
    return int(table.attrs.get("n_lead", 0)) if _holds_exactly(table, ids) else 0
