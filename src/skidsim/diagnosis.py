"""Model criticism: where the simulation is systematically wrong, why, a model extension and its measured gain.

Two levels of error (``level``):

* ``"within-site"``: measured DFT mu vs the per-site calibrated simulation ``SN_sim(v)`` (calibration, validation
  and trace points). The per-site calibration absorbs level shifts, so only the *shape* (the residual profile
  over speed after removing the site's mean residual) is screened here.
* ``"between-site"``: measured mu vs texture-based predictions ``sn_pred(v)`` for held-out sites. Level (site
  mean residual) and shape are screened.

Candidate causes: every column of sites.csv except identifiers and file paths (``exclude``), section included,
every numeric column of the texture table (all bands), each as a ``"main"`` effect (site-mean residual, between
level only) and interacting with speed (``"x_speed"``: a free speed profile times the covariate), plus the
``"functional_form"`` of mu(v) (a residual shape shared by all sites) at each level. For each: the statistic
(sum of squares of the residual explained by the candidate), its permutation p-value (whole sites permuted; whole
sections, among sections of equal size, for covariates constant within sections; random sign flips of whole
sections' profiles for the functional form, which between sites is the shape the texture model adds to the
within-site residual, ``sn_sim - sn_pred``), false-discovery control over *testing units* in two families, and the
cross-validated gain (leave-one-section-out) of adding the candidate to a residual model. Units: correlated
texture parameters (complete-linkage clusters, every pair |Spearman rho| >= ``cluster_rho``) are one unit per
level and kind, tested by the max-statistic over their members under the same permutations; every other candidate
is its own unit. Families: *primary* (functional form; temperature columns between sites; MPD x speed) and
*secondary* (the rest), each with Benjamini-Hochberg (or -Yekutieli) at its share of ``fdr``; FDR being
subadditive over a partition, the FDR over units is <= ``fdr``. See ``docs/model-criticism.md`` for every convention. Units: speeds km/h, residuals in friction
units (mu, dimensionless), temperatures deg C, MPD mm.

The analysis reads only campaign-level tables (never a truth file).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import minimize, minimize_scalar

from .errors import ConfigError, InputError
from .runlog import atomic_path, write_parquet
from .extensions import (DRAINAGE_FORMS, CovariateTerm, DrainageIFI, SharedShape, TemperatureShift,
                         ViscoelasticFE, exp_curve, fit_exp_curves, ifi_speed_constant_kmh)

LEVELS = ("within-site", "between-site")
KINDS = ("calibration", "validation", "trace")
#: sites.csv columns never treated as candidate causes (identifiers and file paths).
DEFAULT_EXCLUDE = ("site", "scan", "dft", "scan_path", "dft_path", "path", "file")


# ----------------------------------------------------------------------------------------------------------------
# residuals
# ----------------------------------------------------------------------------------------------------------------

def _require(df, columns, name):
    if not isinstance(df, pd.DataFrame):
        raise InputError(name, "a pandas DataFrame", got=type(df).__name__)
    for c in columns:
        if c not in df.columns:
            raise InputError(name, f"column '{c}' (have {list(df.columns)})", column=c)


def _numeric(df, column, name):
    v = pd.to_numeric(df[column], errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(v)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputError(name, "finite numbers", row=row, column=column, got=df[column].iloc[row])
    return v


def _interp_site(target: pd.DataFrame, model: pd.DataFrame, value: str) -> np.ndarray:
    """Linear interpolation in speed (km/h) of ``model[value]`` per site at ``target`` speeds; NaN outside range."""
    out = np.full(len(target), np.nan)
    groups = {s: g for s, g in model.groupby("site", sort=False)}
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


def build_residuals(sites: pd.DataFrame, measured: pd.DataFrame, simulated: pd.DataFrame,
                    predicted: pd.DataFrame | None = None) -> pd.DataFrame:
    """Residuals ``measured - model`` in long form, one row per measured point and level.

    ``sites``: (site, section, ...); ``measured``: (site, speed_kmh, mu, kind in {calibration, validation, trace});
    ``simulated``: (site, speed_kmh, sn) the calibrated simulation; ``predicted``: (site, speed_kmh, sn_pred)
    texture-based predictions of held-out sites, or None. Model values are interpolated linearly in speed within
    each site's simulated/predicted speeds; measured points outside that range are dropped (no extrapolation).
    Returns columns site, section, level, kind, speed_kmh (km/h), measured, model, residual (mu, dimensionless).
    """
    _require(sites, ("site", "section"), "sites table")
    _require(measured, ("site", "speed_kmh", "mu", "kind"), "measured table")
    _require(simulated, ("site", "speed_kmh", "sn"), "simulated table")
    m = measured[["site", "speed_kmh", "mu", "kind"]].copy()
    m["site"] = m["site"].astype(str)
    m["speed_kmh"] = _numeric(m, "speed_kmh", "measured table")
    m["mu"] = _numeric(m, "mu", "measured table")
    badk = ~m["kind"].isin(KINDS)
    if badk.any():
        row = int(np.flatnonzero(badk.to_numpy())[0])
        raise InputError("measured table", f"kind in {KINDS}", row=row, column="kind", got=m["kind"].iloc[row])
    sec = sites.assign(site=sites["site"].astype(str)).set_index("site")["section"].astype(str)
    unknown = sorted(set(m["site"]) - set(sec.index))
    if unknown:
        raise InputError("measured table", "sites listed in the sites table", column="site", got=unknown[:5])
    frames = []
    sim = simulated.assign(site=simulated["site"].astype(str))
    sim = sim.assign(speed_kmh=_numeric(sim, "speed_kmh", "simulated table"), sn=_numeric(sim, "sn", "simulated table"))
    for level, model_df, col in (("within-site", sim, "sn"), ("between-site", predicted, "sn_pred")):
        if model_df is None:
            continue
        if level == "between-site":
            _require(model_df, ("site", "speed_kmh", "sn_pred"), "predicted table")
            model_df = model_df.assign(site=model_df["site"].astype(str))
            model_df = model_df.assign(speed_kmh=_numeric(model_df, "speed_kmh", "predicted table"),
                                       sn_pred=_numeric(model_df, "sn_pred", "predicted table"))
        t = m[m["site"].isin(set(model_df["site"]))].reset_index(drop=True)
        if t.empty:
            continue
        t["model"] = _interp_site(t, model_df, col)
        t = t[np.isfinite(t["model"])]
        t = t.assign(level=level, section=t["site"].map(sec).to_numpy(), residual=t["mu"] - t["model"])
        frames.append(t.rename(columns={"mu": "measured"}))
    if not frames:
        raise InputError("simulated table", "model values for at least one measured site and speed")
    out = pd.concat(frames, ignore_index=True)
    return out[["site", "section", "level", "kind", "speed_kmh", "measured", "model", "residual"]]


# ----------------------------------------------------------------------------------------------------------------
# candidates
# ----------------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Cause:
    """One candidate cause and its evidence.

    ``effect``: RMS (over sites and speed bins) of the residual part the candidate explains, in friction units (mu);
    ``direction``: sign of the association (+1: residual, or its slope over speed for ``x_speed``, grows with the
    covariate; 0 for categorical / functional form); ``cv_gain``: 1 - MSE_with / MSE_without of the cross-validated
    residual model (fraction of held-out residual variance explained; <= 0 means no predictive value);
    ``cv_msr``: cross-validated reduction of the mean squared residual per (site, speed bin) cell, mu^2 (a level
    term acts on every bin of a site), used to rank significant causes: comparable across kinds and levels;
    ``z``: (T - mean T_perm) / sd T_perm (standardised statistic); ``group``: numeric candidates with
    |Pearson r| >= corr_group across sites (itself included), or for texture parameters the members of its
    texture cluster; ``significant``: p_adjusted <= fdr and cv_gain > 0. ``family``: "primary" (functional form
    and the physical hypotheses: temperature, MPD x speed) or "secondary" (every other candidate); ``unit``: the
    tested unit (the variable itself, or ``cluster:<representative>`` for a texture cluster tested by its
    max-statistic); ``unit_p``: the unit's permutation p-value (max-statistic p for a cluster);
    ``texture_pcs``: for a between-site sites.csv covariate that varies within sections, the number of texture
    principal components its test is conditioned on (the texture-adjusted test, :func:`texture_adjustment`);
    -1 for the residual test; ``texture_pcs_cv``: the leading PCs of the best predictive texture model (leave-one-
    section-out), against which ``cv_gain`` and the texture-refit extension are computed.
    """

    variable: str
    level: str
    kind: str
    effect: float
    cv_gain: float
    p_value: float
    p_adjusted: float
    significant: bool
    group: tuple[str, ...] = ()
    cv_msr: float = 0.0
    statistic: float = 0.0
    z: float = 0.0
    direction: int = 0
    source: str = ""
    dtype: str = ""
    section_level: bool = False
    n_sites: int = 0
    n_permutations: int = 0
    family: str = ""
    unit: str = ""
    unit_p: float = float("nan")
    texture_pcs: int = -1
    texture_pcs_cv: int = -1

    def as_dict(self) -> dict:
        d = asdict(self)
        d["group"] = list(self.group)
        return d


def site_covariates(sites: pd.DataFrame, texture_wide: pd.DataFrame | None = None, *,
                    exclude=DEFAULT_EXCLUDE) -> tuple[pd.DataFrame, dict]:
    """All candidate covariates per site (index = site) and their source/dtype: {name: (source, dtype)}.

    sites.csv: every column but ``exclude``; booleans and numbers are numeric, anything else categorical;
    constant columns and categoricals with one level per site (identifiers) are dropped; missing numeric values are
    replaced by the column mean. Texture table (index = site or a 'site' column): every numeric column.
    """
    _require(sites, ("site", "section"), "sites table")
    s = sites.assign(site=sites["site"].astype(str)).set_index("site")
    if s.index.duplicated().any():
        raise InputError("sites table", "unique site names", column="site",
                         got=list(s.index[s.index.duplicated()][:3]))
    out, info = {}, {}
    n = len(s)
    excl = {e.lower() for e in exclude}
    for c in s.columns:
        if str(c).lower() in excl:
            continue
        col = s[c]
        num = pd.to_numeric(col, errors="coerce")
        is_num = col.dtype == bool or (num.notna().sum() == col.notna().sum() and col.notna().any())
        if is_num and str(c) != "section":
            v = num.astype(float)
            if v.isna().all() or np.nanstd(v.to_numpy()) == 0:
                continue
            out[str(c)] = v.fillna(v.mean())
            info[str(c)] = ("sites", "numeric")
        else:
            v = col.astype(str).where(col.notna(), "NA")
            k = v.nunique()
            if k < 2 or k >= n:
                continue
            out[str(c)] = v
            info[str(c)] = ("sites", "categorical")
    if texture_wide is not None:
        t = texture_wide.copy()
        if "site" in t.columns:
            t = t.assign(site=t["site"].astype(str)).set_index("site")
        t.index = t.index.astype(str)
        for c in t.columns:
            v = pd.to_numeric(t[c], errors="coerce")
            if v.notna().sum() == 0 or str(c) in out:
                continue
            v = v.reindex(s.index)
            if v.isna().all() or np.nanstd(v.to_numpy()) == 0:
                continue
            out[str(c)] = v.fillna(v.mean()).astype(float)
            info[str(c)] = ("texture", "numeric")
    return pd.DataFrame(out, index=s.index), info


def _residual_matrix(res: pd.DataFrame, speed_bin_kmh: float) -> tuple[list, np.ndarray, np.ndarray]:
    """(sites, bin centres km/h, R (n_sites, n_bins)) of mean residual per site and speed bin; bins not observed at
    every site are dropped."""
    b = np.round(res["speed_kmh"].to_numpy(float) / speed_bin_kmh) * speed_bin_kmh
    tab = res.assign(bin=b).pivot_table(index="site", columns="bin", values="residual", aggfunc="mean")
    tab = tab.loc[:, tab.notna().all(axis=0)]
    if tab.shape[1] == 0:
        raise InputError("residuals", f"speed bins ({speed_bin_kmh} km/h) observed at every site")
    return list(tab.index), tab.columns.to_numpy(float), tab.to_numpy(float)


def _texture_model_shape(residuals: pd.DataFrame, speed_bin_kmh: float) -> pd.DataFrame | None:
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
        ids, bins, R = _residual_matrix(m, speed_bin_kmh)
    except InputError:
        return None
    return pd.DataFrame(R, index=ids, columns=bins)


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


def between_site_texture_scores(residuals: pd.DataFrame, sites: pd.DataFrame, texture_wide: pd.DataFrame | None,
                                speed_bin_kmh: float = 10.0, exclude=DEFAULT_EXCLUDE) -> pd.DataFrame | None:
    """Texture PC scores (:func:`texture_scores`) standardised over the sites the between-site tests use (every
    speed bin observed), as a table indexed by site with columns ``_tpc1, _tpc2, ...``; None without between-site
    residuals at 4 sites or without texture columns. :func:`diagnose` computes it once and hands it to the
    screening, the added-variable data and the texture-refit extensions, so that all three condition on the same
    PCs."""
    res = residuals[residuals["level"] == "between-site"]
    if res["site"].nunique() < 4:
        return None
    try:
        ids, _, _ = _residual_matrix(res.assign(site=res["site"].astype(str)), speed_bin_kmh)
    except InputError:
        return None
    cov, info = site_covariates(sites, texture_wide, exclude=exclude)
    ids = [s for s in ids if s in cov.index]
    sc = texture_scores(cov.loc[ids], info)
    if sc.shape[1] == 0:
        return None
    return pd.DataFrame(sc, index=ids, columns=[f"_tpc{j}" for j in range(1, sc.shape[1] + 1)])


def _scores_for(ids, table: pd.DataFrame | None, cov: pd.DataFrame, info: dict) -> np.ndarray:
    """The PC scores of ``ids`` from ``table`` when it holds exactly those sites, else computed over ``ids``."""
    if table is not None and set(table.index) == set(ids):
        return table.loc[list(ids)].to_numpy(float)
    return texture_scores(cov.loc[list(ids)], info)


def texture_adjustment(M: np.ndarray, scores: np.ndarray, sections: np.ndarray, k_max: int | None = None,
                       variance_share: float = 0.9) -> tuple[int, np.ndarray, int]:
    """Nuisance design of the texture-adjusted between-site tests: ``(k, N, k_cv)`` with ``N = [1, scores[:, :k]]``.

    ``M`` (n_sites, n_bins): measured friction (mu) per site and speed bin. ``k`` is the larger of (a) the number of
    leading PCs that minimises the leave-one-section-out SSE of the least-squares fit of ``M`` on
    ``[1, first k texture PCs]`` and (b) the number of PCs that explain ``variance_share`` of the texture variance,
    capped at ``k_max`` (default ``min(n_sections - 2, n_sites // 3, available PCs)``). (b) guards against
    under-adjustment: a covariate's effect inflates the CV error of the texture-only fit, so (a) alone can stop
    before a texture direction the covariate correlates with, and the test would credit the covariate with that
    texture's effect; over-adjustment only costs power. No candidate enters the choice, so the permutation test
    stays valid (docs/model-criticism.md, section 2, "Texture-adjusted tests"). ``k_cv`` (a) alone is the best
    predictive texture model: the candidates' ``cv_gain`` and the texture-refit extensions use it (a predictive
    comparison is made against the best texture predictor, not an over-fitted one).
    """
    n = M.shape[0]
    folds = np.unique(sections, return_inverse=True)[1]
    n_sec = int(folds.max()) + 1
    top = min(n_sec - 2, n // 3, scores.shape[1]) if k_max is None else min(int(k_max), scores.shape[1])
    best_k, best = 0, np.inf
    for k in range(max(top, 0) + 1):
        X = np.c_[np.ones(n), scores[:, :k]]
        sse = 0.0
        for f in range(n_sec):
            te = folds == f
            beta, *_ = np.linalg.lstsq(X[~te], M[~te], rcond=None)
            sse += float(((M[te] - X[te] @ beta) ** 2).sum())
        if sse < best * (1 - 1e-12):
            best_k, best = k, sse
    k = best_k
    var = scores.var(axis=0)
    if len(var) and var.sum() > 0:
        k_var = int(np.searchsorted(np.cumsum(var) / var.sum(), variance_share - 1e-12) + 1)
        k = max(best_k, min(k_var, max(top, 0)))
    return k, np.c_[np.ones(n), scores[:, :k]], best_k


def _residualise(A: np.ndarray, N: np.ndarray) -> np.ndarray:
    """A minus its least-squares projection on the columns of N."""
    beta, *_ = np.linalg.lstsq(N, A, rcond=None)
    return A - N @ beta


def _adjusted_basis(B: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the part of a candidate's basis B orthogonal to the nuisance N (Frisch-Waugh); columns
    that the texture spans (relative norm < 1e-6) are dropped."""
    Bt = _residualise(B, N)
    if Bt.shape[1] == 0:
        return Bt
    Qb, Rb = np.linalg.qr(Bt)
    ok = np.abs(np.diag(Rb)) > 1e-6 * max(1.0, float(np.linalg.norm(B, axis=0).max()))
    return Qb[:, ok]


def _basis(values: pd.Series, dtype: str) -> np.ndarray:
    """Orthonormal basis (n, q) of the centred design of one covariate."""
    if dtype == "numeric":
        z = values.to_numpy(float)[:, None]
    else:
        z = pd.get_dummies(values.astype(str)).to_numpy(float)
    z = z - z.mean(axis=0)
    q, r = np.linalg.qr(z)
    keep = np.abs(np.diag(r)) > 1e-9 * max(1.0, np.abs(r).max())
    return q[:, keep]


def _section_permutations(sections: np.ndarray, n_perm: int, rng) -> np.ndarray:
    """(n_perm, n) site index permutations that move whole sections among sections of the same size."""
    secs, inv = np.unique(sections, return_inverse=True)
    members = [np.flatnonzero(inv == k) for k in range(len(secs))]
    sizes = np.array([len(m) for m in members])
    out = np.tile(np.arange(len(sections)), (n_perm, 1))
    for size in np.unique(sizes):
        ks = np.flatnonzero(sizes == size)
        if len(ks) < 2:
            continue
        src = np.stack([members[k] for k in ks])  # (m, size)
        perm = rng.permuted(np.tile(np.arange(len(ks)), (n_perm, 1)), axis=1)  # (P, m)
        out[:, src.reshape(-1)] = src[perm].reshape(n_perm, -1)
    return out


def _nested_permutations(sections: np.ndarray, n_perm: int, rng) -> np.ndarray:
    """(n_perm, n) permutations in the nested exchangeability structure of the campaign (Winkler et al. 2015,
    multi-level exchangeability blocks): whole sections move among sections of the same size, and sites are
    shuffled within their section. Valid when residuals share a section effect."""
    out = _section_permutations(sections, n_perm, rng)
    secs, inv = np.unique(sections, return_inverse=True)
    for k in range(len(secs)):
        pos = np.flatnonzero(inv == k)
        if len(pos) < 2:
            continue
        out[:, pos] = np.take_along_axis(out[:, pos], rng.permuted(np.tile(np.arange(len(pos)), (n_perm, 1)),
                                                                    axis=1), axis=1)
    return out


def _perm_stats(Y: np.ndarray, Q: np.ndarray, owner: np.ndarray, n_cand: int, perms: np.ndarray,
                chunk: int = 512) -> np.ndarray:
    """Permutation statistics (P, n_cand): T = sum over a candidate's basis columns and Y's columns of (Q^T Y_perm)^2."""
    P = perms.shape[0]
    out = np.empty((P, n_cand))
    order = np.argsort(owner, kind="stable")
    Qs, ow = Q[:, order], owner[order]
    starts = np.flatnonzero(np.r_[True, ow[1:] != ow[:-1]])
    ids = ow[starts]
    for a in range(0, P, chunk):
        Yp = Y[perms[a:a + chunk]]  # (c, n, S)
        A = np.einsum("pns,nq->pqs", Yp, Qs, optimize=True)
        sq = (A * A).sum(axis=2)  # (c, q)
        out[a:a + chunk][:, ids] = np.add.reduceat(sq, starts, axis=1)
    return out


def _folds(sections: np.ndarray, nested: bool) -> np.ndarray:
    """Fold id per site: the section (leave-one-section-out), or for section-nested categoricals the site's rank
    within its section (each fold holds out one site of every section)."""
    if not nested:
        return np.unique(sections, return_inverse=True)[1]
    rank = pd.Series(np.arange(len(sections))).groupby(sections).cumcount().to_numpy()
    return rank


def _cv_sse(Y: np.ndarray, values: pd.Series | None, dtype: str, folds: np.ndarray,
            nuisance: np.ndarray | None = None) -> tuple[float, float]:
    """Cross-validated SSE of the residual model without and with the candidate.

    Without: training column means. With: numeric -> per-column OLS on [1, z]; categorical -> training group
    means (a level unseen in training -> training mean). ``values=None`` is the functional-form test: without = 0,
    with = training column means. ``nuisance`` (n, k) columns (texture PC scores of the texture-adjusted test)
    enter both models: without = OLS on [1, nuisance], with = OLS on [1, nuisance, candidate] (categorical:
    indicators of the training levels but the first; an unseen level gets none).
    """
    if nuisance is not None and values is not None:
        if dtype == "numeric":
            Z = values.to_numpy(float)[:, None]
        else:
            lab = values.to_numpy(str)
            Z = np.stack([lab == g for g in np.unique(lab)[1:]], axis=1).astype(float)
        X0 = np.c_[np.ones(len(Y)), nuisance]
        sse = [0.0, 0.0]
        for f in np.unique(folds):
            te, tr = folds == f, folds != f
            for j, X in enumerate((X0, np.c_[X0, Z])):
                cols = np.abs(X[tr]).sum(axis=0) > 0  # a categorical level absent from training drops out
                beta, *_ = np.linalg.lstsq(X[tr][:, cols], Y[tr], rcond=None)
                sse[j] += float(((Y[te] - X[te][:, cols] @ beta) ** 2).sum())
        return sse[0], sse[1]
    sse0 = sse1 = 0.0
    for f in np.unique(folds):
        te, tr = folds == f, folds != f
        mean_tr = Y[tr].mean(axis=0)
        if values is None:
            sse0 += float((Y[te] ** 2).sum())
            sse1 += float(((Y[te] - mean_tr) ** 2).sum())
            continue
        sse0 += float(((Y[te] - mean_tr) ** 2).sum())
        if dtype == "numeric":
            z = values.to_numpy(float)
            X = np.c_[np.ones(tr.sum()), z[tr]]
            beta, *_ = np.linalg.lstsq(X, Y[tr], rcond=None)
            pred = np.c_[np.ones(te.sum()), z[te]] @ beta
        else:
            lab = values.to_numpy(str)
            pred = np.tile(mean_tr, (te.sum(), 1))
            for j, l in enumerate(lab[te]):
                m = tr & (lab == l)
                if m.any():
                    pred[j] = Y[m].mean(axis=0)
        sse1 += float(((Y[te] - pred) ** 2).sum())
    return sse0, sse1


def adjust_pvalues(p, method: str = "bh") -> np.ndarray:
    """Benjamini-Hochberg (``"bh"``) or Benjamini-Yekutieli (``"by"``) adjusted p-values (step-up, monotone)."""
    p = np.asarray(p, dtype=float)
    m = len(p)
    if m == 0:
        return p
    if method not in ("bh", "by"):
        raise ConfigError(f"fdr method must be 'bh' or 'by', got {method!r}")
    cm = np.sum(1.0 / np.arange(1, m + 1)) if method == "by" else 1.0
    order = np.argsort(p)
    adj = p[order] * m * cm / np.arange(1, m + 1)
    adj = np.minimum.accumulate(adj[::-1])[::-1]
    out = np.empty(m)
    out[order] = np.minimum(adj, 1.0)
    return out


def temperature_columns(cov: pd.DataFrame, info: dict) -> list[str]:
    """Numeric sites.csv columns whose name contains 'temp' (deg C): the temperature hypotheses (primary family)."""
    return [c for c in cov.columns if info[c] == ("sites", "numeric") and "temp" in str(c).lower()]


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
    for c, l in zip(tex, lab):
        out.setdefault(l, []).append(c)
    return list(out.values())


def auto_permutations(n_candidates: int, fdr: float) -> int:
    """Default permutation count: with m candidates, BH can only declare a cause if its p-value <= fdr/m, and the
    smallest permutation p-value is 1/(P+1); we use P = max(999, ceil(4 m / fdr) - 1)."""
    return int(max(999, math.ceil(4 * n_candidates / fdr) - 1))


def screen_candidates(residuals: pd.DataFrame, sites: pd.DataFrame, texture_wide: pd.DataFrame | None = None, *,
                      n_permutations: int | None = None, seed: int = 0, fdr: float = 0.05,
                      corr_group: float = 0.9, speed_bin_kmh: float = 10.0, fdr_method: str = "bh",
                      min_cv_gain: float = 0.0, exclude=DEFAULT_EXCLUDE, cluster_rho: float = 0.8,
                      primary_share: float = 0.5, temperature_column: str | None = None,
                      mpd_column: str | None = None, adjust_texture: bool = True,
                      texture_pc_scores: pd.DataFrame | None = None) -> list[Cause]:
    """Screen every candidate cause at every level; returns causes ranked by evidence.

    Ranking: significant causes first (statistical evidence decides whether a cause is named), among them by
    ``cv_msr`` (cross-validated explained residual mean square, mu^2: predictive evidence); a significant MPD x
    speed (the drainage hypothesis on the MPD column) ranks above every significant texture cluster that holds the
    MPD column (the same variable's footprint without a mechanism); a section-level grouping (section identity,
    a free-text comment) goes below a significant coarser section-level grouping of the same level and kind whose
    partition it refines (parsimony); the within-site
    functional form goes below a significant within-site covariate x speed (the covariate explains how the shared
    shape varies between sites, and its model nests the shared shape); the rest by
    ``p_adjusted`` and ``z``. ``n_permutations=None`` uses :func:`auto_permutations` for the larger family size
    divided by its share of ``fdr``. Residuals are averaged per site and speed bin (``speed_bin_kmh``); only bins
    observed at every site of a level are used. The between-site functional form tests the mean over sites of
    the binned, per-site centred ``between residual - within residual`` of the same points (= ``sn_sim - sn_pred``,
    :func:`_texture_model_shape`; falls back to the between-site residual when points lack a within-site
    residual): the between-site residuals share the texture model's estimated shape, so sign flips of their
    section profiles were anti-conservative (docs/model-criticism.md, section 2).

    Multiple testing (docs/model-criticism.md, section 2): texture columns are clustered
    (:func:`texture_clusters`, ``cluster_rho``) and a cluster is tested per level and kind by its max-statistic;
    the primary family (functional form, temperature columns between sites -- :func:`temperature_columns` or
    ``temperature_column`` --, MPD x speed -- :func:`find_mpd_column` or ``mpd_column``) gets BH at
    ``primary_share * fdr``, the secondary family (everything else) at ``(1 - primary_share) * fdr``.
    ``p_adjusted`` is on the fdr scale (family-adjusted unit p / share; for a cluster member at least its
    within-cluster single-step maxT p).

    ``adjust_texture`` (default): between sites, every sites.csv covariate that varies within sections is tested
    conditional on the texture: the measured curve (site x speed bin; main: site mean, x_speed: centred shape) is
    regressed on ``[1, first k texture PCs]`` (:func:`texture_adjustment`), and the candidate's part orthogonal to
    those PCs is tested against the residuals with the same nested permutations (Freedman & Lane 1983); its
    ``cv_gain`` compares ``[1, PCs]`` with ``[1, PCs, candidate]`` out of section. Section-level covariates and
    section identity keep the residual test (12 sections leave too few units to condition on k PCs). Needs the
    ``measured`` column of the residual table. ``texture_pc_scores`` (:func:`between_site_texture_scores`) supplies
    the PC scores; without it they are computed here, identically.
    """
    _require(residuals, ("site", "level", "speed_kmh", "residual"), "residuals")
    if not 0 < fdr < 1:
        raise ConfigError(f"fdr must be in (0, 1), got {fdr}")
    cov, info = site_covariates(sites, texture_wide, exclude=exclude)
    section_of = sites.assign(site=sites["site"].astype(str)).set_index("site")["section"].astype(str)
    rng = np.random.default_rng(seed)
    tests = []  # dicts with level, kind, name, T, Tperm, cv, effect, direction, ...
    level_data = {}
    measured_between = None
    for level in LEVELS:
        res = residuals[residuals["level"] == level]
        if res["site"].nunique() < 4:
            continue
        site_ids, bins, R = _residual_matrix(res.assign(site=res["site"].astype(str)), speed_bin_kmh)
        level_data[level] = (site_ids, bins, R)
        if level == "between-site" and adjust_texture and "measured" in res.columns:
            ids_m, bins_m, M = _residual_matrix(res.assign(site=res["site"].astype(str), residual=res["measured"]),
                                                speed_bin_kmh)
            measured_between = M if (ids_m == site_ids and np.array_equal(bins_m, bins)) else None
    if not level_data:
        raise InputError("residuals", "at least 4 sites with residuals at one level")
    ff_delta = _texture_model_shape(residuals, speed_bin_kmh) if "between-site" in level_data else None
    if ff_delta is not None and set(ff_delta.index) != set(level_data["between-site"][0]):
        ff_delta = None
    if not 0 < primary_share < 1:
        raise ConfigError(f"primary_share must be in (0, 1), got {primary_share}")
    temp_cols = temperature_columns(cov, info) if temperature_column is None else [temperature_column]
    mpd_col = find_mpd_column(cov, info) if mpd_column is None else mpd_column
    for c, what in ((temperature_column, "temperature_column"), (mpd_column, "mpd_column")):
        if c is not None and c not in cov.columns:
            raise InputError("sites table / texture table", f"the {what} '{c}' as a numeric column", column=c)
    clusters = texture_clusters(cov, info, cluster_rho)
    kinds_per_level = {lv: (("x_speed",) if lv == "within-site" else ("main", "x_speed")) for lv in level_data}
    m_fam = {"primary": 0, "secondary": 0}
    for lv, kinds in kinds_per_level.items():
        m_fam["primary"] += 1  # functional form
        for kind in kinds:
            n_temp = len(temp_cols) if lv == "between-site" else 0
            m_fam["primary"] += n_temp + (1 if (mpd_col is not None and kind == "x_speed") else 0)
            meta = [c for c in cov.columns if info[c][0] != "texture"]
            m_fam["secondary"] += len(meta) - n_temp + len(clusters)
    share = {"primary": primary_share, "secondary": 1.0 - primary_share}
    m_eff = max(m_fam[f] / share[f] for f in m_fam if m_fam[f] > 0)
    n_tests = int(math.ceil(m_eff))
    P = auto_permutations(n_tests, fdr) if n_permutations is None else int(n_permutations)
    if P < 1:
        raise ConfigError(f"n_permutations must be >= 1, got {P}")
    if (P + 1) * fdr < n_tests:
        warnings.warn(f"n_permutations={P} with {n_tests} effective units: the smallest permutation p-value "
                      f"1/{P + 1} exceeds share * fdr / m = {fdr / n_tests:.2g}, so a single cause can never be "
                      f"significant; use n_permutations=None (auto: {auto_permutations(n_tests, fdr)})",
                      RuntimeWarning, stacklevel=2)
    for level, (site_ids, bins, R) in level_data.items():
        missing = [s for s in site_ids if s not in cov.index]
        if missing:
            raise InputError("sites table", "a row for every site with residuals", column="site", got=missing[:5])
        C = cov.loc[site_ids]
        sec = section_of.loc[site_ids].to_numpy()
        n, S = R.shape
        amp_col = mpd_col if (level == "within-site" and mpd_col is not None and mpd_col in C.columns
                              and info[mpd_col][1] == "numeric") else None
        m = R.mean(axis=1)
        D = R - m[:, None]
        Ys = {"x_speed": D - D.mean(axis=0)}
        if level == "between-site":
            Ys["main"] = (m - m.mean())[:, None]
        speed_c = bins - bins.mean()
        # one permutation set for site-level covariates, one for section-level ones
        perm_site = rng.permuted(np.tile(np.arange(n), (P, 1)), axis=1)
        perm_nested = _nested_permutations(sec, P, rng)
        # every covariate is permuted in the nested structure (sections as blocks + sites within sections), which
        # stays valid when residuals share a section effect; section identity (and any relabelling of it) is
        # invariant to that, so it is tested against free site permutations (its null: no section clustering)
        n_sec = len(np.unique(sec))
        section_level = {c: bool((C[c].groupby(sec).nunique() == 1).all()) for c in C.columns}
        is_section_id = {c: section_level[c] and C[c].nunique() == n_sec for c in C.columns}
        bases = {c: _basis(C[c], info[c][1]) for c in C.columns}
        # texture-adjusted tests (between sites, sites.csv covariates that vary within sections): the measured
        # curve is regressed on [1, k texture PCs] (texture_adjustment, no candidate involved) and the
        # candidate's part orthogonal to the texture is tested against the residuals (Freedman & Lane 1983
        # permutations: the reduced model's residuals move in the nested structure). A covariate that correlates
        # with texture by chance is thus neither credited with texture's effect nor absorbed by the texture model
        # (docs/model-criticism.md, section 2)
        adj_k, adj_kcv, N_adj, Ys_adj, Ys_cv = -1, -1, None, {}, {}
        adjusted = {c: False for c in C.columns}
        if level == "between-site" and measured_between is not None:
            scores = _scores_for(site_ids, texture_pc_scores, cov, info)
            if scores.shape[1] > 0:
                M = measured_between
                adj_k, N_adj, adj_kcv = texture_adjustment(M, scores, sec)
            if adj_k < 1:  # too few sections to condition on any texture PC: keep the residual test
                adj_k, adj_kcv, N_adj = -1, -1, None
            else:
                DM = M - M.mean(axis=1, keepdims=True)
                Ys_cv = {"main": (M.mean(axis=1) - M.mean())[:, None], "x_speed": DM - DM.mean(axis=0)}
                Ys_adj = {kind: _residualise(Yc, N_adj) for kind, Yc in Ys_cv.items()}
                adjusted = {c: info[c][0] == "sites" and not section_level[c] and not is_section_id[c]
                            for c in C.columns}
        for kind, Y0 in Ys.items():
            for is_id, perms, adj in ((True, perm_site, False), (False, perm_nested, False),
                                      (False, perm_nested, True)):
                if adj and N_adj is None:
                    continue
                Y = Ys_adj[kind] if adj else Y0
                bk = {c: (_adjusted_basis(bases[c], N_adj) if adj else bases[c]) for c in C.columns
                      if is_section_id[c] == is_id and adjusted[c] == adj and bases[c].shape[1] > 0
                      and not (c == amp_col and kind == "x_speed")}
                names = [c for c in bk if bk[c].shape[1] > 0]
                if not names:
                    continue
                Q = np.concatenate([bk[c] for c in names], axis=1)
                owner = np.concatenate([np.full(bk[c].shape[1], k) for k, c in enumerate(names)])
                A = Q.T @ Y
                T = np.bincount(owner, weights=(A * A).sum(axis=1), minlength=len(names))
                Tp = _perm_stats(Y, Q, owner, len(names), perms)
                for k, c in enumerate(names):
                    dtype = info[c][1]
                    nested = dtype == "categorical" and \
                        bool((pd.Series(sec).groupby(C[c].to_numpy()).nunique() == 1).all())
                    if adj:
                        sse0, sse1 = _cv_sse(Ys_cv[kind], C[c], dtype, _folds(sec, nested),
                                             nuisance=scores[:, :adj_kcv])
                    else:
                        sse0, sse1 = _cv_sse(Y, C[c], dtype, _folds(sec, nested))
                    direction = 0
                    if dtype == "numeric":
                        z = bk[c][:, 0] * np.sign(bk[c][:, 0] @ (C[c].to_numpy(float) - C[c].mean())) if adj \
                            else C[c].to_numpy(float) - C[c].mean()
                        target = Y[:, 0] if kind == "main" else (Y if adj else D) @ speed_c
                        direction = int(np.sign(z @ target))
                    tests.append(dict(variable=c, level=level, kind=kind, T=T[k], Tp=Tp[:, k], sse0=sse0,
                                      sse1=sse1, n=n, S=Y.shape[1], direction=direction, source=info[c][0],
                                      dtype=dtype, section_level=section_level[c],
                                      texture_pcs=adj_k if adj else -1,
                                      texture_pcs_cv=adj_kcv if adj else -1))
        # MPD x speed within sites: the amplitude of the shared residual shape against the IFI's 1/Sp(MPD)
        # (drainage changes how strongly the law's shape is wrong, not its form, in proportion to 1/Sp,
        # Sp = 14.2 + 89.7 MPD km/h): Y projected on the unit mean shape, one degree of freedom instead of a free
        # profile; the mean shape is invariant to permuting sites, so the nested permutations stay exact
        # (docs/model-criticism.md, section 2)
        if amp_col is not None:
            f = D.mean(axis=0)
            fn = float(np.linalg.norm(f))
            Ya = (Ys["x_speed"] @ (f / fn))[:, None] if fn > 0 else np.zeros((n, 1))
            inv_sp = pd.Series(1.0 / ifi_speed_constant_kmh(np.maximum(C[amp_col].to_numpy(float), 0.0)),
                               index=C.index)
            q = _basis(inv_sp, "numeric")
            A = q.T @ Ya
            Tp = _perm_stats(Ya, q, np.zeros(q.shape[1], dtype=int), 1, perm_nested)
            sse0, sse1 = _cv_sse(Ya, inv_sp, "numeric", _folds(sec, False))
            zc = C[amp_col].to_numpy(float) - C[amp_col].mean()
            tests.append(dict(variable=amp_col, level=level, kind="x_speed", T=float((A * A).sum()), Tp=Tp[:, 0],
                              sse0=sse0, sse1=sse1, n=n, S=1, direction=int(np.sign(zc @ Ya[:, 0])),
                              source=info[amp_col][0], dtype="numeric", section_level=section_level[amp_col],
                              texture_pcs=-1, texture_pcs_cv=-1))
        # functional form: mean residual shape over sites, random sign flips of whole sections' profiles.
        # Between sites the shape tested is the part the texture model adds to the within-site residual
        # (sim - pred per point, :func:`_texture_model_shape`): the rest is the within-site residual of the same
        # points, tested there; the between-site residuals of all held-out sites share the texture model's
        # estimate of the simulated shape (its calibration errors), so their section profiles are not
        # independent and flipping them is anti-conservative (docs/model-criticism.md, section 2)
        Dff = D
        if level == "between-site" and ff_delta is not None:
            Dff = ff_delta.loc[site_ids].to_numpy(float)
            Dff = Dff - Dff.mean(axis=1, keepdims=True)
        flips = rng.choice(np.array([-1.0, 1.0]), size=(P, n_sec))[:, np.unique(sec, return_inverse=True)[1]]
        Tff = n * float((Dff.mean(axis=0) ** 2).sum())
        Tffp = ((flips @ Dff) ** 2).sum(axis=1) / n
        sse0, sse1 = _cv_sse(Dff, None, "", _folds(sec, False))
        tests.append(dict(variable="functional_form", level=level, kind="functional_form", T=Tff, Tp=Tffp,
                          sse0=sse0, sse1=sse1, n=n, S=Dff.shape[1], direction=0, source="residual", dtype="",
                          section_level=False, texture_pcs=-1, texture_pcs_cv=-1))
    # p-values; testing units (single candidates, or texture clusters tested by their max-statistic) in two
    # families, each with its own step-up FDR procedure at its share of fdr (FDR is subadditive over a partition
    # of the hypotheses, so the overall FDR over units is <= fdr); see docs/model-criticism.md
    pvals = np.array([(1 + np.sum(t["Tp"] >= t["T"] * (1 - 1e-12))) / (P + 1) for t in tests])
    cluster_of = {c: k for k, members in enumerate(clusters) for c in members}
    units = {}  # key -> dict(family, name, members=[test index])
    for j, t in enumerate(tests):
        v = t["variable"]
        if t["kind"] == "functional_form" or (v in temp_cols and t["level"] == "between-site") or \
                (v == mpd_col and t["kind"] == "x_speed"):
            key, fam, name = ("single", j), "primary", v
        elif v in cluster_of and len(clusters[cluster_of[v]]) > 1:
            key, fam, name = ("cluster", t["level"], t["kind"], cluster_of[v]), "secondary", None
        else:
            key, fam, name = ("single", j), "secondary", v
        units.setdefault(key, dict(family=fam, name=name, members=[]))["members"].append(j)
    unit_p, wy_p = {}, np.ones(len(tests))
    for key, u in units.items():
        mem = u["members"]
        if len(mem) == 1:
            unit_p[key] = pvals[mem[0]]
            wy_p[mem[0]] = pvals[mem[0]]
            continue
        Tmax_perm = np.max(np.stack([tests[j]["Tp"] for j in mem]), axis=0)
        Tobs = np.array([tests[j]["T"] for j in mem])
        rep = mem[int(np.argmax(Tobs))]
        u["name"] = f"cluster:{tests[rep]['variable']}"
        unit_p[key] = (1 + np.sum(Tmax_perm >= Tobs.max() * (1 - 1e-12))) / (P + 1)
        for j, tj in zip(mem, Tobs):  # single-step maxT (Westfall & Young 1993) within the cluster
            wy_p[j] = (1 + np.sum(Tmax_perm >= tj * (1 - 1e-12))) / (P + 1)
    unit_adj = {}
    for fam in ("primary", "secondary"):
        keys = [k for k, u in units.items() if u["family"] == fam]
        if keys:
            a = adjust_pvalues(np.array([unit_p[k] for k in keys]), fdr_method) / share[fam]
            unit_adj.update({k: float(min(x, 1.0)) for k, x in zip(keys, a)})
    padj = np.ones(len(tests))
    unit_of = np.empty(len(tests), dtype=object)
    for key, u in units.items():
        for j in u["members"]:
            padj[j] = max(unit_adj[key], wy_p[j])
            unit_of[j] = key
    # hierarchical (gatekeeper) step, Yekutieli (2008): where section identity is significant at a level and kind,
    # the section-level covariates of that level and kind (coarser groupings such as mix, section-constant
    # numbers) are the candidate explanations of the section effect and form a child family adjusted on its own.
    sec_name = [t["variable"] for t in tests if t["dtype"] == "categorical" and t["section_level"]
                and cov[t["variable"]].nunique() == section_of.nunique()]
    for k, t in enumerate(tests):
        if t["variable"] in sec_name and padj[k] <= fdr:
            fam = [j for j, u in enumerate(tests) if u["section_level"] and u["variable"] not in sec_name
                   and u["level"] == t["level"] and u["kind"] == t["kind"]]
            if fam:
                child = adjust_pvalues(pvals[fam], fdr_method)
                for j, pc in zip(fam, child):
                    padj[j] = min(padj[j], max(pc, padj[k]))
    num = [c for c in cov.columns if info[c][1] == "numeric"]
    corr = cov[num].corr().abs() if num else pd.DataFrame()
    causes = []
    for j, (t, p, pa) in enumerate(zip(tests, pvals, padj)):
        sd = float(np.std(t["Tp"]))
        z = (t["T"] - float(np.mean(t["Tp"]))) / sd if sd > 0 else 0.0
        cvg = 1.0 - t["sse1"] / t["sse0"] if t["sse0"] > 0 else 0.0
        grp = ()
        if t["variable"] in cluster_of and len(clusters[cluster_of[t["variable"]]]) > 1:
            grp = tuple(sorted(clusters[cluster_of[t["variable"]]]))
        elif t["variable"] in corr.columns:
            row = corr[t["variable"]]
            grp = tuple(sorted(row.index[row >= corr_group]))
        u = units[unit_of[j]]
        causes.append(Cause(variable=t["variable"], level=t["level"], kind=t["kind"],
                            effect=float(math.sqrt(max(t["T"], 0.0) / (t["n"] * t["S"]))), cv_gain=float(cvg),
                            p_value=float(p), p_adjusted=float(pa),
                            significant=bool(pa <= fdr and cvg > min_cv_gain), group=grp,
                            cv_msr=float((t["sse0"] - t["sse1"]) / (t["n"] * t["S"])), statistic=float(t["T"]),
                            z=float(z), direction=t["direction"], source=t["source"], dtype=t["dtype"],
                            section_level=t["section_level"], n_sites=t["n"], n_permutations=P,
                            family=u["family"], unit=u["name"], unit_p=float(unit_p[unit_of[j]]),
                            texture_pcs=int(t["texture_pcs"]), texture_pcs_cv=int(t["texture_pcs_cv"])))
    causes.sort(key=lambda c: (not c.significant, -c.cv_msr if c.significant else c.p_adjusted, -c.z))
    causes = order_by_refinement(causes, cov)
    # the physical hypothesis on the MPD column ranks above the texture clusters that hold MPD (e.g. drainage makes the
    # texture model misfit the level of shallow-texture sites: the macrotexture height cluster is significant
    # between sites; MPD x speed names the mechanism)
    if mpd_col is not None:
        mp = [k for k, c in enumerate(causes) if c.significant and c.variable == mpd_col and c.kind == "x_speed"]
        above = [k for k, c in enumerate(causes) if c.significant and mp and k < mp[0] and mpd_col in c.group
                 and c.unit is not None and str(c.unit).startswith("cluster:")]
        if mp and above:
            causes.insert(above[0], causes.pop(mp[0]))
    # hierarchy of within-site shapes: where the functional form and a covariate x speed are both significant within
    # sites, the shape's amplitude follows the covariate and the shared shape is its mean over the sites; the
    # covariate names the mechanism (its model, shared profile + covariate x profile, nests the functional form's),
    # so the functional form ranks right below the first such cause
    ff = [k for k, c in enumerate(causes) if c.significant and c.kind == "functional_form" and c.level == "within-site"]
    xs = [k for k, c in enumerate(causes) if c.significant and c.kind == "x_speed" and c.level == "within-site"]
    if ff and xs and ff[0] < xs[0]:
        causes.insert(xs[0], causes.pop(ff[0]))
    return causes


def refines(fine: Cause, coarse: Cause, cov: pd.DataFrame) -> bool:
    """Whether ``fine`` (a significant categorical section-level cause) refines ``coarse`` (a significant
    section-level cause of the same level and kind): each level of ``fine`` lies within one value of ``coarse``,
    and ``coarse`` has fewer distinct values, or as many and is a number (a section-constant number names a
    quantity, section identity only the sections). ``cov``: one row per site, the candidate columns."""
    if not (fine.significant and coarse.significant and fine.section_level and coarse.section_level
            and fine.dtype == "categorical" and fine.level == coarse.level and fine.kind == coarse.kind
            and fine.variable in cov.columns and coarse.variable in cov.columns):
        return False
    pair = pd.DataFrame({"f": cov[fine.variable], "c": cov[coarse.variable]}).dropna()
    if not len(pair) or int(pair.groupby("f")["c"].nunique().max()) != 1:
        return False
    n_fine, n_coarse = pair["f"].nunique(), pair["c"].nunique()
    return n_coarse < n_fine or (n_coarse == n_fine and coarse.dtype != "categorical")


def order_by_refinement(causes: list[Cause], cov: pd.DataFrame) -> list[Cause]:
    """Parsimony between section-level groupings: a cause moves right below the first significant coarser one of
    the same level and kind whose partition it refines (:func:`refines`): section identity below mix, a free-text
    comment that splits the mixes below mix. The finer one holds the coarser one's evidence; the coarser names the
    effect with fewer levels. Other causes keep their order."""
    causes = list(causes)
    moved = True
    while moved:  # terminates: a cause moves only below a number or a grouping with strictly fewer levels
        moved = False
        for k, c in enumerate(causes):
            below = [j for j in range(k + 1, len(causes)) if refines(c, causes[j], cov)]
            if below:
                causes.insert(below[0], causes.pop(k))
                moved = True
                break
    return causes


def named_cause(causes: list[Cause]) -> Cause | None:
    """The top significant cause, or None."""
    return causes[0] if causes and causes[0].significant else None


# ----------------------------------------------------------------------------------------------------------------
# extensions: choice, recalibration, cross-fitting
# ----------------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ExtendedModel:
    """The extension chosen for a named cause: ``extension`` (physical where one applies), ``fallback`` (generic
    term, also evaluated), ``fe_hook`` (solver flags for an FE-level extension, not evaluated here)."""

    cause: Cause
    extension: object
    fallback: object | None = None
    fe_hook: ViscoelasticFE | None = None


def apply_extension(cause: Cause, sites: pd.DataFrame, texture_wide: pd.DataFrame | None = None, *,
                    speed_bin_kmh: float = 10.0) -> ExtendedModel:
    """Choose the extension for a named cause.

    temperature (name contains 'temp') -> :class:`TemperatureShift`; MPD, or a macrotexture cause whose correlated
    group holds the MPD column, interacting with speed -> :class:`DrainageIFI`; functional form ->
    :class:`SharedShape` plus the :class:`ViscoelasticFE` hook; anything else -> :class:`CovariateTerm` (on the
    level for ``main``, on the speed slope for ``x_speed``). Physical extensions carry the generic term as
    ``fallback``.
    """
    if cause.kind == "functional_form":
        return ExtendedModel(cause, SharedShape(speed_bin_kmh=speed_bin_kmh), None, ViscoelasticFE())
    pcs = cause.texture_pcs_cv if cause.dtype == "numeric" else -1
    generic = CovariateTerm(cause.variable, on="level" if cause.kind == "main" else "slope", texture_pcs=pcs)
    cov, _ = site_covariates(sites, texture_wide)
    name = cause.variable.lower()
    if "temp" in name and cause.dtype == "numeric":
        return ExtendedModel(cause, TemperatureShift(column=cause.variable, texture_pcs=pcs), generic)
    mpd = find_mpd_column(cov)
    if mpd is not None and cause.kind == "x_speed" and (
            cause.variable == mpd or mpd in cause.group or "macro" in name):
        return ExtendedModel(cause, DrainageIFI(mpd_column=mpd), generic, ViscoelasticFE())
    return ExtendedModel(cause, generic, None)


@dataclass
class _Scope:
    """Rows to evaluate (held out) and per-site points to refit the law."""

    name: str
    rows: pd.DataFrame  # site, section, speed_kmh, kind, measured, before
    sites: list
    fit_v: np.ndarray  # (n_sites, J) km/h, NaN padded
    fit_y: np.ndarray
    row_site: np.ndarray  # index into sites per row
    base: tuple = ()  # (b, c, alpha) of the plain exponential fit to (fit_v, fit_y), per site


def _make_scope(residuals: pd.DataFrame, level: str) -> _Scope | None:
    r = residuals[residuals["level"] == level].copy()
    if r.empty:
        return None
    r["site"] = r["site"].astype(str)
    if level == "within-site":
        fit = r[r["kind"] == "calibration"]
        rows = r[r["kind"] != "calibration"]
        fit = fit.assign(y=fit["measured"])
        name = "held_out_speeds"
    else:
        rows = r
        fit = r.assign(y=r["model"])
        name = "held_out_sites"
    sites = sorted(set(rows["site"]) & set(fit["site"]))
    if len(sites) < 4:
        return None
    rows = rows[rows["site"].isin(sites)].rename(columns={"model": "before"}).reset_index(drop=True)
    fit = fit[fit["site"].isin(sites)]
    counts = fit.groupby("site").size()
    J = int(counts.max())
    fv = np.full((len(sites), J), np.nan)
    fy = np.full((len(sites), J), np.nan)
    pos = {s: k for k, s in enumerate(sites)}
    for s, g in fit.groupby("site"):
        g = g.groupby("speed_kmh", as_index=False)["y"].mean()
        fv[pos[s], :len(g)] = g["speed_kmh"].to_numpy(float)
        fy[pos[s], :len(g)] = g["y"].to_numpy(float)
    ok = np.isfinite(fy).sum(axis=1) >= 3
    keep = [s for s, k in zip(sites, ok) if k]
    if len(keep) < 4:
        return None
    if not ok.all():
        return _make_scope(residuals[~residuals["site"].astype(str).isin(set(sites) - set(keep))], level)
    return _Scope(name, rows, sites, fv, fy, rows["site"].map(pos).to_numpy(), fit_exp_curves(fv, fy))


def _site_values(cov: pd.DataFrame, column: str, sites: list) -> np.ndarray:
    if column not in cov.columns:
        raise InputError("sites table / texture table", f"a numeric column '{column}'", column=column)
    return cov.loc[sites, column].to_numpy(float)


def _site_mean(x: np.ndarray, i: np.ndarray, n_sites: int) -> np.ndarray:
    """Per-row mean of ``x`` over the rows of the same site."""
    return (np.bincount(i, weights=x, minlength=n_sites) / np.maximum(np.bincount(i, minlength=n_sites), 1))[i]


def _site_target(on: str, scope: _Scope, values: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Per site of the scope: the mean of ``values`` over its rows (``on="level"``, mu) or their least-squares
    slope on the centred speed ``dv`` (``on="slope"``, mu per km/h)."""
    i, n_s = scope.row_site, len(scope.sites)
    if on == "level":
        return np.bincount(i, weights=values, minlength=n_s) / np.bincount(i, minlength=n_s)
    return np.bincount(i, weights=dv * values, minlength=n_s) / np.bincount(i, weights=dv * dv, minlength=n_s)


def _refit_design(scope: _Scope, cov: pd.DataFrame, k: int, column: str | None) -> np.ndarray:
    """Site design ``[1, PC_1..k]`` of the texture refit, plus the covariate ``column`` unless None (the PC scores
    are the ``_tpc<j>`` columns that :func:`evaluate_extension` adds to the covariates)."""
    S = cov.loc[scope.sites, [f"_tpc{j}" for j in range(1, k + 1)]].to_numpy(float)
    cols = [np.ones(len(scope.sites)), S] + ([cov.loc[scope.sites, column].to_numpy(float)] if column else [])
    return np.column_stack(cols)


def _refit_correction(on: str, beta, X: np.ndarray, scope: _Scope, before: np.ndarray,
                      dv: np.ndarray) -> np.ndarray:
    """Per-row correction of a texture refit: the site's level (``on="level"``) or speed slope of the prediction
    is replaced by the linear model's ``X_i beta`` (fitted on the training sites' measured site means or slopes):
    ``after = before + (X_i beta - mean_i before)`` or ``+ (X_i beta - slope_i before) (v - mean_i v)``; the
    texture model's speed profile (level) is kept."""
    d = (X @ np.asarray(beta) - _site_target(on, scope, before, dv))[scope.row_site]
    return d if on == "level" else d * dv


def _texture_partial(scope: _Scope, cov: pd.DataFrame, z: np.ndarray, train: np.ndarray, k: int) -> np.ndarray:
    """``z`` (per site of the scope) minus its least-squares prediction from ``[1, PC_1..k]`` fitted on the
    training sites."""
    X = _refit_design(scope, cov, k, None)
    c, *_ = np.linalg.lstsq(X[train], z[train], rcond=None)
    return z - X @ c


def texture_refit_reference(ext, scope: _Scope, cov: pd.DataFrame) -> np.ndarray:
    """Cross-fitted reference for a texture-adjusted :class:`CovariateTerm`: the same refit without the covariate
    (``[1, PC_1..k]`` only, same folds). Comparing the extension against it isolates what the named variable adds
    beyond refitting the level (slope) on the texture PCs (gain.json ``over_texture_refit``)."""
    folds = _ext_folds(ext, scope, cov)
    before = scope.rows["before"].to_numpy(float)
    y = scope.rows["measured"].to_numpy(float)
    v = scope.rows["speed_kmh"].to_numpy(float)
    dv = v - _site_mean(v, scope.row_site, len(scope.sites))
    X = _refit_design(scope, cov, ext.texture_pcs, None)
    out = np.full(len(before), np.nan)
    for f in np.unique(folds):
        train = folds != f
        beta, *_ = np.linalg.lstsq(X[train], _site_target(ext.on, scope, y, dv)[train], rcond=None)
        te = ~train[scope.row_site]
        out[te] = (before + _refit_correction(ext.on, beta, X, scope, before, dv))[te]
    return out


def _physical_params(ext, scope: _Scope, cov: pd.DataFrame, train: np.ndarray) -> tuple[list, list]:
    """Names and bounds of the fitted parameters of a physical extension in a scope."""
    if isinstance(ext, TemperatureShift):
        tb = ext.t_ref_bounds_c(_site_values(cov, ext.column, scope.sites))
        if ext.fit_level:
            return ["t_ref_c", "level_per_c"], [tb, ext.level_bounds_per_c]
        return ["t_ref_c"], [tb]
    if isinstance(ext, DrainageIFI):
        return ["kappa"], [ext.kappa_bounds]
    raise ConfigError(f"not a physical extension: {type(ext).__name__}")


def _training_offset(scope: _Scope, train: np.ndarray, after: np.ndarray) -> float:
    """Campaign-wide level offset (mu) of an extended between-site prediction: the mean training residual
    ``measured - after`` over the training sites' rows (closed-form least squares of a constant)."""
    rtr = train[scope.row_site]
    return float(np.mean(scope.rows["measured"].to_numpy(float)[rtr] - after[rtr]))


def _after_physical(ext, scope: _Scope, cov: pd.DataFrame, train: np.ndarray, theta) -> np.ndarray:
    """'after' values of every row of ``scope`` for parameters ``theta`` (anchors from the training sites).

    Within a site (held-out speeds) the law is refitted through the calibration points with the extension
    included and the change is added to the calibrated simulation: ``after = before + f_ext(v) - f_plain(v)``.
    Between sites the prediction is transformed: TemperatureShift evaluates the exponential fitted to the
    prediction at the shifted speed; DrainageIFI multiplies by ``m_i(v) / mean_site(m_i)`` with
    ``m_i(v) = exp(-kappa v (1/Sp_i - mean_train 1/Sp))``: a pure shape correction that keeps each site's mean
    predicted level over its evaluated speeds (the texture model already carries the level, and the IFI anchor
    speed then drops out). Between sites an extension that acts on the level (TemperatureShift) also refits the
    campaign-wide level offset of the texture model (:func:`_training_offset`, the mean training residual after
    the extension), as the generic level term does with its intercept b0; shape extensions (DrainageIFI, slope
    terms) keep each site's level. gain.json ``over_shared_level`` separates that offset from the cause.
    """
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    v = scope.rows["speed_kmh"].to_numpy(float)
    before = scope.rows["before"].to_numpy(float)
    i = scope.row_site
    within = scope.name == "held_out_speeds"
    b0, c0, a0 = scope.base
    if isinstance(ext, TemperatureShift):
        T = _site_values(cov, ext.column, scope.sites)
        if ext.texture_pcs >= 0 and not within:
            T = float(T[train].mean()) + _texture_partial(scope, cov, T, train, ext.texture_pcs)
        anchor = float(T[train].mean())
        k = ext.speed_factor(T, anchor, float(theta[0]))
        bt = ext.vertical_factor(T, anchor, float(theta[1]) if len(theta) > 1 else None)
        if within:
            # refitting the law through the calibration points at effective speeds k v gives
            # f(k v; b, c, alpha / k) = f(v; b, c, alpha): the exponential family is closed under speed scaling,
            # so a per-site calibration absorbs a temperature shift exactly and 'after' equals 'before' (the
            # vertical factor b_T scales b and c and is absorbed likewise)
            return before.copy()
        a = before + bt[i] * exp_curve(v * k[i], b0[i], c0[i], a0[i]) - exp_curve(v, b0[i], c0[i], a0[i])
        return a + _training_offset(scope, train, a)
    if isinstance(ext, DrainageIFI):
        inv_sp = ext.inverse_speed_constant(_site_values(cov, ext.mpd_column, scope.sites))
        if within:
            M = ext.multiplier(scope.fit_v, inv_sp[:, None], float(theta[0]))
            b1, c1, a1 = fit_exp_curves(scope.fit_v, scope.fit_y / M)
            return before + exp_curve(v, b1[i], c1[i], a1[i]) * ext.multiplier(v, inv_sp[i], float(theta[0])) \
                - exp_curve(v, b0[i], c0[i], a0[i])
        if ext.form == "squeeze":  # relative to the training sites' mean 1/Sp^2 (the texture model carries it)
            d2 = inv_sp ** 2 - (inv_sp[train] ** 2).mean()
            m = np.maximum(ext.floor, 1.0 - theta[0] * v * v * d2[i])
        else:
            d = inv_sp - inv_sp[train].mean()
            m = np.exp(-theta[0] * v * d[i])
        return before * m / _site_mean(m, i, len(scope.sites))
    raise ConfigError(f"not a physical extension: {type(ext).__name__}")


def recalibrate(ext, scope: _Scope, cov: pd.DataFrame, train: np.ndarray) -> dict:
    """Fit the extension's parameters on the training sites (boolean mask over ``scope.sites``).

    Physical extensions: TemperatureShift T_r (deg C); DrainageIFI kappa (and, for ``form="auto"``, the curve form
    with the smaller training error); minimising the training rows' squared error (one parameter: a 41-point grid
    over the bounds, then a bounded scalar search between the best point's neighbours; two: a coarse grid +
    bounded Powell);
    within a site the law is refitted through the calibration points with the extension included. Generic terms:
    least squares / group means on the training residuals. Returns the fitted parameters (JSON-ready)."""
    rows_tr = train[scope.row_site]
    y = scope.rows["measured"].to_numpy(float)
    if getattr(ext, "physical", False) and not isinstance(ext, ViscoelasticFE):
        names, bounds = _physical_params(ext, scope, cov, train)
        if isinstance(ext, TemperatureShift) and scope.name == "held_out_speeds":
            return {"t_ref_c": float(ext.t_ref_c), "level_per_c": float(ext.level_per_c), "identifiable": False}
        if isinstance(ext, DrainageIFI) and ext.form == "auto":
            # each curve form fitted on the training data; the smaller training error wins (no held-out data)
            fits = [dict(recalibrate(replace(ext, form=f), scope, cov, train), form=f) for f in DRAINAGE_FORMS]
            for fit in fits:
                fit["train_sse"] = _train_sse(replace(ext, form=fit["form"]), fit, scope, cov, train)
            return min(fits, key=lambda fit: fit["train_sse"])

        def obj(th):
            a = _after_physical(ext, scope, cov, train, th)
            return float(np.sum((a[rows_tr] - y[rows_tr]) ** 2))

        if len(names) == 1:
            # a grid over the bounds first (the squeeze form's objective is multimodal where the multiplier reaches
            # its floor), then a bounded search between the best grid value's neighbours
            lo, hi = bounds[0]
            grid = np.linspace(lo, hi, 41)
            vals = [obj([g]) for g in grid]
            j = int(np.argmin(vals))
            a, b = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
            r = minimize_scalar(obj, bounds=(a, b), method="bounded", options={"xatol": 1e-4 * (hi - lo)})
            th = [float(r.x)] if r.fun <= vals[j] else [float(grid[j])]
        else:
            grids = np.meshgrid(*[np.linspace(lo, hi, 9) for lo, hi in bounds], indexing="ij")
            cand = np.stack([g.ravel() for g in grids], axis=1)
            th0 = cand[int(np.argmin([obj(c) for c in cand]))]
            r = minimize(obj, th0, method="Powell", bounds=bounds, options={"xtol": 1e-4, "ftol": 1e-12})
            th = [float(x) for x in (r.x if r.fun <= obj(th0) else th0)]
        return dict(zip(names, th))
    resid = (y - scope.rows["before"].to_numpy(float))
    v = scope.rows["speed_kmh"].to_numpy(float)
    if isinstance(ext, SharedShape):
        b = np.round(v[rows_tr] / ext.speed_bin_kmh) * ext.speed_bin_kmh
        prof = pd.Series(resid[rows_tr]).groupby(b).mean()
        return {"speed_kmh": prof.index.to_list(), "h": prof.to_list()}
    if isinstance(ext, CovariateTerm):
        dv = v - _site_mean(v, scope.row_site, len(scope.sites))
        if ext.name not in cov.columns:
            raise InputError("sites table / texture table", f"column '{ext.name}'", column=ext.name)
        col = cov.loc[scope.sites, ext.name]
        if pd.api.types.is_numeric_dtype(col) and ext.texture_pcs >= 0 and scope.name == "held_out_sites":
            # texture refit: [1, PCs, z] fitted to the training sites' measured site means (speed slopes)
            X = _refit_design(scope, cov, ext.texture_pcs, ext.name)
            beta, *_ = np.linalg.lstsq(X[train], _site_target(ext.on, scope, y, dv)[train], rcond=None)
            return {"numeric": True, "texture_pcs": ext.texture_pcs, "beta": beta.tolist()}
        if pd.api.types.is_numeric_dtype(col):
            z = col.to_numpy(float)
            zc = z - z[train].mean()
            zr = zc[scope.row_site]
            X = np.c_[np.ones(len(v)), zr] if ext.on == "level" else np.c_[dv, zr * dv]
            beta, *_ = np.linalg.lstsq(X[rows_tr], resid[rows_tr], rcond=None)
            return {"numeric": True, "z_mean": float(z[train].mean()), "beta": beta.tolist()}
        lab = col.astype(str).to_numpy()[scope.row_site]
        groups = {}
        for g in np.unique(lab[rows_tr]):
            m = rows_tr & (lab == g)
            X = np.ones((m.sum(), 1)) if ext.on == "level" else dv[m][:, None]
            groups[str(g)] = np.linalg.lstsq(X, resid[m], rcond=None)[0].tolist()
        X = np.ones((rows_tr.sum(), 1)) if ext.on == "level" else dv[rows_tr][:, None]
        return {"numeric": False, "groups": groups,
                "overall": np.linalg.lstsq(X, resid[rows_tr], rcond=None)[0].tolist()}
    raise ConfigError(f"cannot recalibrate extension {type(ext).__name__}")


def _train_sse(ext, params: dict, scope: _Scope, cov: pd.DataFrame, train: np.ndarray) -> float:
    """Squared error (mu^2) of the fitted extension over the training sites' rows."""
    rows_tr = train[scope.row_site]
    a = predict_extended(ext, params, scope, cov, train)
    return float(np.sum((a[rows_tr] - scope.rows["measured"].to_numpy(float)[rows_tr]) ** 2))


def predict_extended(ext, params: dict, scope: _Scope, cov: pd.DataFrame, train: np.ndarray) -> np.ndarray:
    """'after' values for every row of the scope with fitted ``params`` (use the rows of held-out sites)."""
    if isinstance(ext, DrainageIFI) and "form" in params:
        ext = replace(ext, form=params["form"])
    v = scope.rows["speed_kmh"].to_numpy(float)
    before = scope.rows["before"].to_numpy(float)
    if getattr(ext, "physical", False):
        return _after_physical(ext, scope, cov, train, [params[k] for k in _physical_params(ext, scope, cov,
                                                                                              train)[0]])
    if isinstance(ext, SharedShape):
        return before + np.interp(v, params["speed_kmh"], params["h"])
    col = cov.loc[scope.sites, ext.name]
    dv = v - _site_mean(v, scope.row_site, len(scope.sites))
    if params.get("texture_pcs", -1) >= 0:
        X = _refit_design(scope, cov, params["texture_pcs"], ext.name)
        return before + _refit_correction(ext.on, params["beta"], X, scope, before, dv)
    if params["numeric"]:
        zr = (col.to_numpy(float) - params["z_mean"])[scope.row_site]
        X = np.c_[np.ones(len(v)), zr] if ext.on == "level" else np.c_[dv, zr * dv]
        return before + X @ np.asarray(params["beta"])
    lab = col.astype(str).to_numpy()[scope.row_site]
    out = before.copy()
    for j in range(len(v)):
        c = params["groups"].get(lab[j], params["overall"])
        out[j] += c[0] * (1.0 if ext.on == "level" else dv[j])
    return out


def _ext_folds(ext, scope: _Scope, cov: pd.DataFrame) -> np.ndarray:
    sec = scope.rows.groupby("site")["section"].first().reindex(scope.sites).astype(str).to_numpy()
    nested = False
    if isinstance(ext, CovariateTerm) and not pd.api.types.is_numeric_dtype(cov[ext.name]):
        lab = cov.loc[scope.sites, ext.name].astype(str).to_numpy()
        nested = bool((pd.Series(sec).groupby(lab).nunique() == 1).all())
    return _folds(sec, nested)


def cross_fit(ext, scope: _Scope, cov: pd.DataFrame) -> tuple[pd.DataFrame, list]:
    """Out-of-sample 'after' for every site: the extension is recalibrated without the site's fold
    (leave-one-section-out; one site per section for section-nested categorical terms). Returns the rows with
    columns before/after and the per-fold parameters."""
    folds = _ext_folds(ext, scope, cov)
    after = np.full(len(scope.rows), np.nan)
    params = []
    for f in np.unique(folds):
        train = folds != f
        p = recalibrate(ext, scope, cov, train)
        a = predict_extended(ext, p, scope, cov, train)
        te = ~train[scope.row_site]
        after[te] = a[te]
        params.append(p)
    return scope.rows.assign(after=after), params


def shared_level_reference(ext, scope: _Scope, cov: pd.DataFrame) -> np.ndarray:
    """Cross-fitted reference 'before + shared offset' for every row of the scope: the mean training residual
    (mu) of the same folds as the extension. Comparing an extension against it isolates what the named variable
    adds beyond a campaign-wide level correction of the texture model (gain.json ``over_shared_level``)."""
    folds = _ext_folds(ext, scope, cov)
    before = scope.rows["before"].to_numpy(float)
    resid = scope.rows["measured"].to_numpy(float) - before
    out = np.full(len(before), np.nan)
    for f in np.unique(folds):
        tr = (folds != f)[scope.row_site]
        out[~tr] = before[~tr] + resid[tr].mean()
    return out


# ----------------------------------------------------------------------------------------------------------------
# gain
# ----------------------------------------------------------------------------------------------------------------

def measure_gain(predictions: pd.DataFrame, *, n_boot: int = 2000, seed: int = 0, ci: float = 0.95) -> dict:
    """RMSE and R^2 before/after on held-out rows, with percentile bootstrap intervals resampling whole sites.

    ``predictions``: columns site, measured, before, after (mu). ``rmse_gain = rmse_before - rmse_after`` and
    ``r2_gain = r2_after - r2_before`` (positive = the extension helps). R^2 = 1 - SSE/SST with SST about the mean
    of the (resampled) measured values. ``shape_rmse_*``: RMSE of the residuals about each site's mean residual
    (what a per-site level shift cannot fix), with its gain and interval. Bootstrap: ``n_boot`` multinomial
    resamples of the sites (seeded), percentile intervals at level ``ci``; ``gain_excludes_zero``: lower bound of
    the RMSE gain > 0; ``shape_gain_excludes_zero`` likewise for the shape RMSE.
    """
    _require(predictions, ("site", "measured", "before", "after"), "predictions")
    p = predictions.dropna(subset=["measured", "before", "after"])
    if p["site"].nunique() < 2:
        raise InputError("predictions", "held-out rows from at least 2 sites", got=int(p["site"].nunique()))
    rb, ra = p["measured"] - p["before"], p["measured"] - p["after"]
    g = p.assign(eb=rb ** 2, ea=ra ** 2, rb=rb, ra=ra, y2=p["measured"] ** 2).groupby("site")
    n_i = g.size().to_numpy(float)
    s1 = g["measured"].sum().to_numpy(float)
    s2 = g["y2"].sum().to_numpy(float)
    eb = g["eb"].sum().to_numpy(float)
    ea = g["ea"].sum().to_numpy(float)
    # shape part: squared residual about each site's own mean residual
    sb = eb - g["rb"].sum().to_numpy(float) ** 2 / n_i
    sa = ea - g["ra"].sum().to_numpy(float) ** 2 / n_i
    k = len(n_i)
    rng = np.random.default_rng(seed)
    W = np.vstack([np.ones(k), rng.multinomial(k, np.full(k, 1.0 / k), size=n_boot).astype(float)])
    N = W @ n_i
    sst = W @ s2 - (W @ s1) ** 2 / N
    with np.errstate(divide="ignore", invalid="ignore"):
        stats = {"rmse_before": np.sqrt(W @ eb / N), "rmse_after": np.sqrt(W @ ea / N),
                 "r2_before": 1 - (W @ eb) / sst, "r2_after": 1 - (W @ ea) / sst}
        stats["shape_rmse_before"] = np.sqrt(W @ sb / N)
        stats["shape_rmse_after"] = np.sqrt(W @ sa / N)
    stats["rmse_gain"] = stats["rmse_before"] - stats["rmse_after"]
    stats["shape_rmse_gain"] = stats["shape_rmse_before"] - stats["shape_rmse_after"]
    stats["r2_gain"] = stats["r2_after"] - stats["r2_before"]
    q = [(1 - ci) / 2 * 100, (1 + ci) / 2 * 100]
    out = {"n_sites": int(k), "n_points": int(n_i.sum()), "n_boot": int(n_boot), "seed": int(seed), "ci": ci}
    for name, arr in stats.items():
        out[name] = float(arr[0])
        boot = arr[1:][np.isfinite(arr[1:])]
        out[name + "_ci"] = [float(x) for x in np.percentile(boot, q)] if len(boot) else [float("nan")] * 2
    out["gain_excludes_zero"] = bool(out["rmse_gain_ci"][0] > 0)
    out["shape_gain_excludes_zero"] = bool(out["shape_rmse_gain_ci"][0] > 0)
    return out


def _ext_describe(ext, params) -> dict:
    d = {"name": type(ext).__name__, "physical": bool(getattr(ext, "physical", False))}
    d["settings"] = {k: v for k, v in asdict(ext).items()} if hasattr(ext, "__dataclass_fields__") else {}
    d["params_per_fold"] = params
    return d


@dataclass
class DiagnosisResult:
    """Everything :func:`diagnose` found: residual table, ranked causes, the named cause (or None), the gain dict
    (gain.json), held-out predictions before/after per scope, and the candidate covariates per site."""

    residuals: pd.DataFrame
    causes: list
    named: Cause | None
    gain: dict
    predictions: pd.DataFrame  # held-out rows: scope, site, speed_kmh, kind, measured, before, after
    covariates: pd.DataFrame = field(default_factory=pd.DataFrame)
    added_variable: pd.DataFrame = field(default_factory=pd.DataFrame)  # site, covariate_adj, measured_adj


def added_variable(residuals: pd.DataFrame, sites: pd.DataFrame, texture_wide: pd.DataFrame | None, cause: Cause,
                   speed_bin_kmh: float = 10.0, exclude=DEFAULT_EXCLUDE,
                   texture_pc_scores: pd.DataFrame | None = None) -> pd.DataFrame:
    """Added-variable (partial regression) data of a texture-adjusted cause: per site, the covariate and the
    measured site mean (``main``, mu) or speed slope (``x_speed``, mu per 10 km/h), both minus their least-squares
    fit on ``[1, first texture_pcs texture PCs]``. The slope of measured_adj on covariate_adj is the partial effect
    the test found (Frisch-Waugh). Empty for a cause without texture adjustment or a categorical covariate."""
    if cause.texture_pcs < 0 or cause.dtype != "numeric":
        return pd.DataFrame()
    res = residuals[residuals["level"] == "between-site"]
    ids, bins, M = _residual_matrix(res.assign(site=res["site"].astype(str), residual=res["measured"]),
                                    speed_bin_kmh)
    cov, info = site_covariates(sites, texture_wide, exclude=exclude)
    C = cov.loc[ids]
    N = np.c_[np.ones(len(ids)), _scores_for(ids, texture_pc_scores, cov, info)[:, :cause.texture_pcs]]
    sc = bins - bins.mean()
    y = M.mean(axis=1) if cause.kind == "main" else (M - M.mean(axis=1, keepdims=True)) @ sc / (sc @ sc) * 10.0
    return pd.DataFrame({"site": ids, "covariate_adj": _residualise(C[cause.variable].to_numpy(float), N),
                         "measured_adj": _residualise(y, N)})


def evaluate_extension(model: ExtendedModel, residuals: pd.DataFrame, sites: pd.DataFrame,
                       texture_wide: pd.DataFrame | None = None, *, n_boot: int = 2000, seed: int = 0,
                       ci: float = 0.95, texture_pc_scores: pd.DataFrame | None = None) -> tuple[dict, pd.DataFrame]:
    """Cross-fit the extension (and its generic fallback) on held-out speeds and held-out sites, measure the gain.

    The primary extension is the physical one unless its RMSE-gain interval at the cause's level does not exclude 0
    while the fallback's lower bound is higher ("no physical model fits"). ``texture_pc_scores``: the PC scores of
    the texture-adjusted test (:func:`between_site_texture_scores`) for the texture-refit terms. Returns (gain dict,
    predictions)."""
    cov, info = site_covariates(sites, texture_wide)
    # the texture-refit terms use the PCs the test conditioned on (texture_pc_scores, standardised over the
    # between-site test's sites) where those cover every site of the held-out-site scope; else PCs over all sites
    level_scopes = {level: _make_scope(residuals, level) for level in LEVELS}  # built once, used by every extension
    between = level_scopes["between-site"]
    pcs = texture_pc_scores
    if pcs is None or between is None or not set(between.sites) <= set(pcs.index):
        sc = texture_scores(cov, info)
        pcs = pd.DataFrame(sc, index=cov.index, columns=[f"_tpc{j}" for j in range(1, sc.shape[1] + 1)])
    cov = cov.join(pcs)
    own = "held_out_speeds" if model.cause.level == "within-site" else "held_out_sites"
    results = []
    for ext in [model.extension] + ([model.fallback] if model.fallback is not None else []):
        scopes, preds = {}, []
        for sc in level_scopes.values():
            if sc is None:
                continue
            rows, params = cross_fit(ext, sc, cov)
            scopes[sc.name] = measure_gain(rows, n_boot=n_boot, seed=seed, ci=ci)
            scopes[sc.name]["extension"] = _ext_describe(ext, params)
            if sc.name == "held_out_sites" and isinstance(ext, CovariateTerm) and ext.texture_pcs >= 0:
                g3 = measure_gain(rows.assign(before=texture_refit_reference(ext, sc, cov)), n_boot=n_boot,
                                  seed=seed, ci=ci)
                scopes[sc.name]["over_texture_refit"] = {
                    k: g3[k] for k in ("rmse_before", "rmse_before_ci", "rmse_after", "rmse_after_ci", "rmse_gain",
                                       "rmse_gain_ci", "r2_gain", "r2_gain_ci", "gain_excludes_zero")}
            if sc.name == "held_out_sites":
                ref = shared_level_reference(ext, sc, cov)
                g2 = measure_gain(rows.assign(before=ref), n_boot=n_boot, seed=seed, ci=ci)
                scopes[sc.name]["over_shared_level"] = {
                    k: g2[k] for k in ("rmse_before", "rmse_before_ci", "rmse_after", "rmse_after_ci", "rmse_gain",
                                       "rmse_gain_ci", "r2_before", "r2_before_ci", "r2_gain", "r2_gain_ci",
                                       "gain_excludes_zero")}
            preds.append(rows.assign(scope=sc.name))
        results.append((ext, scopes, pd.concat(preds, ignore_index=True) if preds else pd.DataFrame()))
    best = results[0]
    if len(results) > 1 and own in best[1] and not best[1][own]["gain_excludes_zero"]:
        alt = results[1]
        if alt[1][own]["rmse_gain_ci"][0] > best[1][own]["rmse_gain_ci"][0]:
            best = alt
    gain = {"cause": model.cause.as_dict(), "extension": type(best[0]).__name__, "level": model.cause.level,
            "scope": own, "scopes": best[1],
            "fe_hook": None if model.fe_hook is None else {"name": "ViscoelasticFE",
                                                           "solver_flags": model.fe_hook.solver_flags},
            "alternatives": [{"extension": type(e).__name__, "scopes": s} for e, s, _ in results if e is not best[0]]}
    gain["gain_excludes_zero"] = bool(own in best[1] and best[1][own]["gain_excludes_zero"])
    return gain, best[2]


def diagnose(sites: pd.DataFrame, measured: pd.DataFrame, simulated: pd.DataFrame,
             predicted: pd.DataFrame | None = None, texture_wide: pd.DataFrame | None = None, *,
             n_permutations: int | None = None, seed: int = 0, fdr: float = 0.05, corr_group: float = 0.9,
             speed_bin_kmh: float = 10.0, fdr_method: str = "bh", n_boot: int = 2000, ci: float = 0.95,
             exclude=DEFAULT_EXCLUDE, cluster_rho: float = 0.8, primary_share: float = 0.5,
             temperature_column: str | None = None, mpd_column: str | None = None,
             adjust_texture: bool = True) -> DiagnosisResult:
    """The whole diagnosis on campaign-level tables: residuals, screening, extension for the named cause,
    cross-fitted gain. With no named cause, ``gain`` holds the baseline RMSE/R^2 (after = before)."""
    res = build_residuals(sites, measured, simulated, predicted)
    pcs = between_site_texture_scores(res, sites, texture_wide, speed_bin_kmh, exclude)  # one set of PCs for all
    causes = screen_candidates(res, sites, texture_wide, n_permutations=n_permutations, seed=seed, fdr=fdr,
                               corr_group=corr_group, speed_bin_kmh=speed_bin_kmh, fdr_method=fdr_method,
                               exclude=exclude, cluster_rho=cluster_rho, primary_share=primary_share,
                               temperature_column=temperature_column, mpd_column=mpd_column,
                               adjust_texture=adjust_texture, texture_pc_scores=pcs)
    top = named_cause(causes)
    cov, _ = site_covariates(sites, texture_wide, exclude=exclude)
    if top is not None:
        model = apply_extension(top, sites, texture_wide, speed_bin_kmh=speed_bin_kmh)
        gain, preds = evaluate_extension(model, res, sites, texture_wide, n_boot=n_boot, seed=seed, ci=ci,
                                         texture_pc_scores=pcs)
    else:
        scopes, frames = {}, []
        for level in LEVELS:
            sc = _make_scope(res, level)
            if sc is None:
                continue
            rows = sc.rows.assign(after=sc.rows["before"])
            scopes[sc.name] = measure_gain(rows, n_boot=n_boot, seed=seed, ci=ci)
            frames.append(rows.assign(scope=sc.name))
        gain = {"cause": None, "extension": None, "level": None, "scope": None, "scopes": scopes,
                "fe_hook": None, "alternatives": [], "gain_excludes_zero": False}
        preds = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    av = pd.DataFrame() if top is None else added_variable(res, sites, texture_wide, top, speed_bin_kmh, exclude,
                                                           texture_pc_scores=pcs)
    return DiagnosisResult(res, causes, top, gain, preds, cov, av)


# ----------------------------------------------------------------------------------------------------------------
# outputs
# ----------------------------------------------------------------------------------------------------------------

def _atomic_write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _json_safe(o):
    if isinstance(o, dict):
        return {str(k): _json_safe(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_json_safe(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def _fmt_ci(d, key):
    lo, hi = d[key + "_ci"]
    return f"{d[key]:.4f} [{lo:.4f}, {hi:.4f}]"


def _fmt_group(group, n_show: int = 6) -> str:
    """A correlated group for report.md: up to ``n_show`` names and the count of the rest (causes.json has all)."""
    g = list(group)
    if len(g) <= 1:
        return ""
    return ", ".join(g[:n_show]) + (f" (+{len(g) - n_show} more)" if len(g) > n_show else "")


def write_outputs(out_dir, residuals: pd.DataFrame, causes: list, gain: dict, figures: dict | None = None,
                  *, top_n: int = 15) -> dict:
    """Write residuals.parquet, causes.json, gain.json and report.md to ``out_dir`` (each atomically).

    ``figures``: {caption: path of an existing PNG}; embedded in report.md with paths relative to ``out_dir``.
    Returns {name: path}."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    p = out / "residuals.parquet"
    write_parquet(p, residuals)
    paths["residuals"] = p
    clist = [c.as_dict() if isinstance(c, Cause) else dict(c) for c in causes]
    for rank, c in enumerate(clist, 1):
        c["rank"] = rank
    _atomic_write_text(out / "causes.json", json.dumps(_json_safe(clist), indent=2) + "\n")
    paths["causes"] = out / "causes.json"
    _atomic_write_text(out / "gain.json", json.dumps(_json_safe(gain), indent=2) + "\n")
    paths["gain"] = out / "gain.json"
    lines = ["# Model criticism", ""]
    top = clist[0] if clist and clist[0]["significant"] else None
    if top is None:
        lines += ["**No cause named**: no candidate is significant after false-discovery control "
                  "(and with positive cross-validated gain).", ""]
    else:
        grp = _fmt_group(top["group"]) or "-"
        lines += [f"**Named cause: `{top['variable']}`** ({top['level']}, {top['kind']}); correlated group: {grp}; "
                  f"effect {top['effect']:.4f} mu, cv gain {top['cv_gain']:.3f}, p = {top['p_value']:.2g}, "
                  f"p_adj = {top['p_adjusted']:.2g}"
                  + (f"; tested beyond the texture (conditional on {top['texture_pcs']} texture principal "
                     "components)" if top.get("texture_pcs", -1) >= 0 else "") + ".", "",
                  f"Extension applied: **{gain.get('extension')}**"
                  + (f"; FE hook: {gain['fe_hook']['solver_flags']}" if gain.get("fe_hook") else "") + ".", ""]
        own = gain.get("scopes", {}).get(gain.get("scope") or "", {})
        folds = own.get("extension", {}).get("params_per_fold", [])
        if folds and all("form" in f for f in folds):  # DrainageIFI form "auto": the curve form chosen per fold
            forms = sorted({f["form"] for f in folds})
            lines += ["Drainage curve form chosen on the training data, per fold: " + ", ".join(
                f"{fm} {sum(f['form'] == fm for f in folds)} of {len(folds)} (kappa median "
                f"{float(np.median([f['kappa'] for f in folds if f['form'] == fm])):.3g})" for fm in forms) + ".", ""]
    lines += ["## Gain on held-out data (bootstrap over sites)", "",
              "| scope | sites | points | RMSE before | RMSE after | RMSE gain | R2 before | R2 after |",
              "|---|---|---|---|---|---|---|---|"]
    for name, d in gain.get("scopes", {}).items():
        lines.append(f"| {name} | {d['n_sites']} | {d['n_points']} | {_fmt_ci(d, 'rmse_before')} | "
                     f"{_fmt_ci(d, 'rmse_after')} | {_fmt_ci(d, 'rmse_gain')} | {_fmt_ci(d, 'r2_before')} | "
                     f"{_fmt_ci(d, 'r2_after')} |")
    for name, d in gain.get("scopes", {}).items():
        o = d.get("over_shared_level")
        if o is not None and gain.get("extension"):
            lines += ["", f"{name}: against a campaign-wide level offset of the texture model alone (RMSE "
                          f"{o['rmse_before']:.4f}), the extension's RMSE gain is {_fmt_ci(o, 'rmse_gain')} "
                          "(what the named variable itself adds)."]
        o = d.get("over_texture_refit")
        if o is not None and gain.get("extension"):
            lines += ["", f"{name}: against the same refit on the texture PCs without the named variable (RMSE "
                          f"{o['rmse_before']:.4f}), the RMSE gain is {_fmt_ci(o, 'rmse_gain')}."]
    lines += ["", f"## Candidates (top {top_n} of {len(clist)}, ranked by evidence)", "",
              "Kind `main*` / `x_speed*`: tested beyond the texture (texture-adjusted test).", "",
              "| rank | variable | level | kind | effect (mu) | cv gain | p | p adj | significant | group |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for c in clist[:top_n]:
        kind = c["kind"] + ("*" if c.get("texture_pcs", -1) >= 0 else "")
        lines.append(f"| {c['rank']} | {c['variable']} | {c['level']} | {kind} | {c['effect']:.4f} | "
                     f"{c['cv_gain']:.3f} | {c['p_value']:.2g} | {c['p_adjusted']:.2g} | {c['significant']} | "
                     f"{_fmt_group(c['group'])} |")
    if figures:
        lines += ["", "## Figures", ""]
        for cap, fp in figures.items():
            rel = os.path.relpath(Path(fp), out)
            lines += [f"![{cap}]({rel})", "", f"*{cap}*", ""]
    _atomic_write_text(out / "report.md", "\n".join(lines) + "\n")
    paths["report"] = out / "report.md"
    return paths
