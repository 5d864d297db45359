"""Texture-to-friction regression: the study's PCA regression (Tables 5, 6, Figure 11) and honest alternatives.

The study (section 7) regressed each exponential-decay parameter (``mu_s``, ``mu_k`` dimensionless; ``alpha`` in
s/m, see :mod:`skidsim.friction`) on principal components of the standardised texture parameters (all bands) and
temperature, on 27 randomly chosen sites, and judged the fit on those same 27 sites. This module reproduces that
analysis and adds what it lacked: leave-one-section-out cross-validation of PCA regression against ridge,
partial least squares, lasso, a two-variable model (``profile_MPD``, ``micro_Sq``) and an intercept-only baseline,
on each parameter and on the DFT curves they imply; models of what the data identify (``<model>@curve``: the
calibrated laws' values at 20/40/60 km/h; ``<model>@dft``: the measured DFT at the prediction speeds); the simple
baseline ``ols2@dft`` (OLS of the DFT curve on at most two texture columns chosen by inner CV,
:func:`fit_subset_ols`); and the prediction-skill table (:func:`prediction_skill`) that sets every model beside
the intercept-only ``mean@dft`` and that baseline, with a WARNING when the chosen model does not beat both.

Conventions that change numbers (also in ``docs/regression.md``):

* **Features**: every column named ``raw_*``, ``macro_*``, ``micro_*`` or ``profile_*`` plus ``temperature_c``
  (deg C). Other columns (site, section, metadata) are never features.
* **Missing values and constant columns** (:class:`Standardiser`, fitted on the *training* rows only): a column
  with more than ``max_nan_fraction`` (default 0.2) NaN is dropped; remaining NaN are replaced by the training
  median of the column; a column whose (imputed) training standard deviation is zero (``<= 1e-12 * (1 + |mean|)``)
  is dropped. Standardisation uses the sample standard deviation (``ddof=1``), so the eigenvalues of the PCA are
  those of the training correlation matrix (they sum to the number of kept columns).
* **PCA**: SVD of the standardised training matrix; components ordered by variance; the sign of each component is
  fixed so that its largest-magnitude loading is positive. Only components with a singular value above
  ``1e-10 * max(n, p) * s_max`` count (numerical rank).
* **Component retention** (``rule``), ``k_max = min(rank, n - 3)`` (at least 2 residual degrees of freedom):
  ``"cv"`` (default) the number 0..k_max chosen by an inner cross-validation (leave-one-group-out when groups
  are given, else seeded 5-fold; the standardisation and PCA are refitted in every inner fold) with the
  one-standard-error rule (below); ``"study"`` the largest k for which all k component
  coefficients have p < 0.05 (the study's reading: it kept 17 components for n = 27, an overfit that the in-sample
  adjusted R-squared cannot reveal); ``"kaiser"`` eigenvalues > 1; ``"variance:F"`` the fewest components whose
  cumulative share of variance reaches F (e.g. ``"variance:0.9"``). ``n_components=`` overrides the rule.
  ``"cv"`` is the default because it is the only rule that judges components by how well they predict sites the
  fit has not seen; ``"kaiser"``/``"variance"`` ignore the target and ``"study"`` uses in-sample p-values.
* **Back-transformation (Table 6)**: with loadings ``V_k`` and OLS coefficients ``b`` on the component scores,
  ``beta_per_sd = V_k b`` (friction per one training SD of each column) and ``beta = beta_per_sd / sd`` (friction
  per unit of the column), intercept ``b0 - sum(beta * mean)``. Standard errors are propagated exactly through
  this linear map from the OLS covariance.
* **Significance stars** as in the study's Table 5: ``*`` p < 0.05, ``**`` p < 0.01, ``***`` p < 0.001.
* **Hyper-parameters** of ridge (penalty), lasso (penalty) and PLS (number of components) are chosen by the same
  inner cross-validation as the ``"cv"`` rule, inside each outer fold (nested: the outer test section is never
  seen, not even by the scaler). ``selection="one_se"`` (default, Hastie et al. ESL 7.10): the most regularised
  grid value whose pooled inner MSE is within one standard error (SD of the per-fold MSEs at the minimum over
  sqrt(folds)) of the minimum; ``"min"``: the minimum. Exact ties go to the more regularised model. Grids:
  ridge penalty 1e-2..1e4 (31, log), lasso ``alpha_max * 10**(0..-2.5)`` (26), PLS 1..min(10, p, n_inner-2).
* **Best model** (:func:`rank_models`): pooled DFT RMSE over speeds when the CV has DFT rows, else the mean
  over parameters of ``1 - R2`` (out of sample); lower is better; exact ties go to the simpler model.
* **Predicted DFT**: ``DFT(v) = g(site, v) * mu(v)`` with the exponential-decay law of the *predicted*
  parameters (speed in km/h converted to m/s), ``g`` the FE geometric factor (default 1). Predicted parameters are
  clipped to be physical (``mu_s, mu_k, alpha >= 0``) before the law is evaluated.
* **Relative error** ``(predicted - measured) / measured``; "within 10 %" means ``|relative error| <= 0.10``.
* **Baseline** (``ols2``): candidates are the empty subset, every texture column (``raw_*``, ``macro_*``,
  ``micro_*``, ``profile_*``; not temperature) and every pair; the one with the smallest inner-CV SSE pooled over
  all targets (one subset for the whole curve) wins, exact ties to the smaller subset; NaN imputed with training
  medians. Always the minimum, not the one-SE rule.
* **Skill** (:func:`prediction_skill`): pooled DFT R^2 and RMSE per model; a model "beats" a reference when its
  RMSE is lower by more than a relative 1e-9 (a model never beats itself).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay

#: Column prefixes that mark texture features (bands).
BANDS = ("raw", "macro", "micro", "profile")
#: The friction parameters (alpha in s/m).
PARAMETERS = ("mu_s", "mu_k", "alpha")
#: DFT speeds of Figure 11, km/h.
DEFAULT_SPEEDS_KMH = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
#: The two-variable model's columns: MPD (mm) and micro-band Sq (mm).
TWO_VARIABLES = ("profile_MPD", "micro_Sq")
#: Models compared by :func:`cross_validate_models` by default ("pca" uses the "cv" rule, "pca:study" the study's).
DEFAULT_MODELS = ("mean", "pca", "pca:study", "ridge", "pls", "lasso", "two_variable")
#: Suffix of a model fitted on curve targets (see :func:`predict_parameters`), e.g. ``"ridge@curve"``.
CURVE_SUFFIX = "@curve"
#: Speeds (km/h) at which the ``@curve`` models' targets are the law's friction values: the DFT's standard
#: calibration speeds (the study's DFT20, DFT40, DFT60).
CURVE_ANCHORS_KMH = (20.0, 40.0, 60.0)
#: Suffix of a model fitted on the DFT itself (see :func:`predict_parameters`), e.g. ``"ridge@dft"``: the targets
#: are each training site's DFT reference (the measured DFT when given) at the prediction speeds.
DFT_SUFFIX = "@dft"
#: Base model: OLS with intercept on at most :data:`SUBSET_MAX_FEATURES` texture columns chosen by inner CV.
SUBSET_OLS = "ols2"
SUBSET_MAX_FEATURES = 2
#: The simple baseline of the prediction-skill table: OLS of the DFT curve on <= 2 texture columns (inner CV).
BASELINE_MODEL = SUBSET_OLS + DFT_SUFFIX
#: The intercept-only reference of the prediction-skill table: the training sections' mean DFT at each speed.
MEAN_MODEL = "mean" + DFT_SUFFIX
#: Order used to break exact ties (simpler first; suffixes ``@curve``/``@dft`` and ``:<rule>`` ignored).
_SIMPLICITY = ("mean", SUBSET_OLS, "two_variable", "pca", "pls", "ridge", "lasso")
TEMPERATURE_COLUMN = "temperature_c"
MAX_NAN_FRACTION = 0.2
RIDGE_ALPHAS = np.logspace(-2, 4, 31)
LASSO_ALPHA_RATIOS = np.logspace(0, -2.5, 26)
LASSO_MAX_ITER = 5000
LASSO_TOL = 1e-4
PLS_MAX_COMPONENTS = 10
_TIE = 1e-12


def _stars(p: float) -> str:
    if not np.isfinite(p):
        return ""
    return "***" if p < 0.001 else "**" if p < 0.01 else "*" if p < 0.05 else ""


def split_band(column: str) -> tuple[str, str]:
    """``"macro_Sq" -> ("macro", "Sq")``; ``"temperature_c" -> ("temperature", "temperature_c")``."""
    for band in BANDS:
        if column.startswith(band + "_"):
            return band, column[len(band) + 1:]
    if column == TEMPERATURE_COLUMN:
        return "temperature", column
    return "other", column


def feature_columns(table: pd.DataFrame) -> list[str]:
    """Texture columns (``raw_*``, ``macro_*``, ``micro_*``, ``profile_*``) plus ``temperature_c`` if present."""
    cols = [c for c in table.columns if isinstance(c, str) and any(c.startswith(b + "_") for b in BANDS)]
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


def assemble_design(campaign: pd.DataFrame, friction: pd.DataFrame | None = None, *,
                    campaign_file="campaign table", friction_file="friction table") -> Design:
    """Build :class:`Design` from the wide campaign table (one row per site) and the friction table.

    Raises :class:`~skidsim.errors.InputError` naming the table and column for a missing ``site``/``section``
    column, duplicate sites, no feature columns, non-numeric values, a missing friction column or a site of the
    friction table that the campaign table lacks (and vice versa).
    """
    for col in ("site", "section"):
        if col not in campaign.columns:
            raise InputError(campaign_file, f"a '{col}' column", column=col, got=list(campaign.columns)[:8])
    sites = campaign["site"].astype(str)
    dup = sites[sites.duplicated()]
    if len(dup):
        raise InputError(campaign_file, "one row per site", column="site", got=dup.iloc[0])
    feats = feature_columns(campaign)
    if not feats:
        raise InputError(campaign_file, "texture columns named <band>_<parameter> (bands raw, macro, micro, "
                         "profile)", got=list(campaign.columns)[:8])
    X = _numeric_frame(campaign, feats, campaign_file)
    X.index = pd.Index(sites, name="site")
    groups = pd.Series(campaign["section"].astype(str).to_numpy(), index=X.index, name="section")
    Y = None
    if friction is not None:
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
                raise InputError(friction_file, "a finite value for every site", column=col,
                                 got=Y.index[Y[col].isna()][0])
        missing = sorted(set(Y.index) - set(X.index))
        if missing:
            raise InputError(campaign_file, "a row for every site of the friction table", column="site",
                             got=missing[0])
        missing = sorted(set(X.index) - set(Y.index))
        if missing:
            raise InputError(friction_file, "a row for every site of the campaign table", column="site",
                             got=missing[0])
        Y = Y.loc[X.index]
    return Design(X=X, Y=Y, groups=groups)


# ---------------------------------------------------------------------------------------------------------
# Standardisation
# ---------------------------------------------------------------------------------------------------------

def _standardiser_arrays(A: np.ndarray, max_nan_fraction: float):
    """Kept column indices, medians, means, sds (ddof=1) and {index: reason} of dropped columns of ``A``."""
    if A.shape[0] < 3:
        raise InputError(None, "at least 3 training sites", got=A.shape[0])
    nan = np.isnan(A)
    nan_frac = nan.mean(axis=0)
    if nan.any():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(A, axis=0)
        A = np.where(nan, med, A)
    else:
        med = np.median(A, axis=0)
    mean = A.mean(axis=0)
    sd = A.std(axis=0, ddof=1)
    keep, dropped = [], {}
    for j in range(A.shape[1]):
        if nan_frac[j] > max_nan_fraction:
            dropped[j] = f"NaN in {nan_frac[j]:.0%} of training sites (> {max_nan_fraction:.0%})"
        elif not (sd[j] > 1e-12 * (1.0 + abs(mean[j]))):
            dropped[j] = "constant over the training sites"
        else:
            keep.append(j)
    if not keep:
        raise InputError(None, "at least one feature column that is neither constant nor mostly NaN",
                         got=sorted(set(dropped.values())))
    k = np.asarray(keep)
    return k, med[k], mean[k], sd[k], dropped


def _standardise_split(A: np.ndarray, tr: np.ndarray, te: np.ndarray, max_nan_fraction: float):
    """Standardised training and test rows of the array ``A``, the scaler learnt on the training rows only."""
    k, med, mean, sd, _ = _standardiser_arrays(A[tr], max_nan_fraction)
    out = []
    for rows in (tr, te):
        B = A[np.ix_(rows, k)]
        B = np.where(np.isnan(B), med, B)
        out.append((B - mean) / sd)
    return out


@dataclass(frozen=True)
class Standardiser:
    """Column selection, median imputation and standardisation learnt on training rows (see module docstring).

    ``columns`` kept, with their training ``medians``, ``means`` and ``sds`` (ddof=1, after imputation), in the
    columns' own units; ``dropped`` maps each dropped column to the reason.
    """

    columns: tuple[str, ...]
    medians: np.ndarray
    means: np.ndarray
    sds: np.ndarray
    dropped: dict = field(default_factory=dict)

    @classmethod
    def fit(cls, X: pd.DataFrame, max_nan_fraction: float = MAX_NAN_FRACTION) -> "Standardiser":
        keep, med, mean, sd, dropped = _standardiser_arrays(X.to_numpy(dtype=float), max_nan_fraction)
        names = list(X.columns)
        return cls(tuple(names[j] for j in keep), med, mean, sd,
                   {names[j]: why for j, why in dropped.items()})

    def transform(self, X: pd.DataFrame) -> np.ndarray:
        """Standardised ``(n, p)`` array of the kept columns (NaN imputed with the training medians)."""
        missing = [c for c in self.columns if c not in X.columns]
        if missing:
            raise InputError(None, "every feature column the model was fitted with", column=missing[0])
        A = X.loc[:, list(self.columns)].to_numpy(dtype=float)
        A = np.where(np.isnan(A), self.medians, A)
        return (A - self.means) / self.sds


# ---------------------------------------------------------------------------------------------------------
# Cross-validation splits
# ---------------------------------------------------------------------------------------------------------

def inner_splits(n: int, groups=None, *, seed: int = 0, n_folds: int = 5) -> list[tuple[np.ndarray, np.ndarray]]:
    """Index splits used to choose hyper-parameters on ``n`` training rows.

    Leave-one-group-out when ``groups`` has at least 3 distinct values, else ``min(n_folds, n)``-fold with rows
    shuffled by ``numpy.random.default_rng(seed)``.
    """
    if groups is not None:
        g = np.asarray(groups)
        uniq = sorted(set(g.tolist()))
        if len(uniq) >= 3:
            return [(np.flatnonzero(g != u), np.flatnonzero(g == u)) for u in uniq]
    k = int(min(n_folds, n))
    if k < 2:
        raise InputError(None, "at least 2 rows for an inner cross-validation", got=n)
    perm = np.random.default_rng(seed).permutation(n)
    folds = np.array_split(perm, k)
    return [(np.sort(np.concatenate([f for j, f in enumerate(folds) if j != i])), np.sort(folds[i]))
            for i in range(k)]


def split_sites(sites_df: pd.DataFrame, n_train: int = 27, seed: int = 0, grouped_by: str | None = None,
                *, file="campaign table") -> tuple[list[str], list[str]]:
    """Split sites into training and test ids (the study: 27/9 at random).

    Random split: the sorted site ids are permuted with ``numpy.random.default_rng(seed)``; the first ``n_train``
    train. Grouped split (``grouped_by="section"``): the sorted group names are permuted with the same generator
    and whole groups go to training, in that order, while they fit into ``n_train`` sites (a group that would
    overflow is skipped); all other groups are test. No group is then on both sides; the training size is
    ``n_train`` whenever group sizes allow it, else the largest total not above it. Returned lists are sorted.
    """
    if "site" not in sites_df.columns:
        raise InputError(file, "a 'site' column", column="site", got=list(sites_df.columns)[:8])
    sites = sites_df["site"].astype(str)
    if sites.duplicated().any():
        raise InputError(file, "one row per site", column="site", got=sites[sites.duplicated()].iloc[0])
    n = len(sites)
    if not (1 <= n_train < n):
        raise InputError(file, f"n_train between 1 and {n - 1} (there are {n} sites)", column="site", got=n_train)
    rng = np.random.default_rng(seed)
    if grouped_by is None:
        order = sorted(sites)
        perm = rng.permutation(n)
        train = [order[i] for i in perm[:n_train]]
    else:
        if grouped_by not in sites_df.columns:
            raise InputError(file, f"a '{grouped_by}' column to group the split by", column=grouped_by)
        grp = sites_df[grouped_by].astype(str).to_numpy()
        names = sorted(set(grp.tolist()))
        train, size = [], 0
        for gi in rng.permutation(len(names)):
            members = sites[grp == names[gi]].tolist()
            if size + len(members) <= n_train:
                train += members
                size += len(members)
        if size == 0 or size == n:
            raise InputError(file, f"groups ('{grouped_by}') small enough to put {n_train} sites in training",
                             column=grouped_by, got=size)
    train_set = set(train)
    test = sorted(s for s in sites if s not in train_set)
    return sorted(train), test


# ---------------------------------------------------------------------------------------------------------
# PCA regression
# ---------------------------------------------------------------------------------------------------------

def _pca(Z: np.ndarray):
    """Loadings ``(p, r)``, singular values ``(r,)`` of a centred ``Z``; sign: largest |loading| positive."""
    _, s, vt = np.linalg.svd(Z, full_matrices=False)
    tol = 1e-10 * max(Z.shape) * (s[0] if s.size else 0.0)
    r = int(np.sum(s > tol))
    V = vt[:r].T.copy()
    idx = np.argmax(np.abs(V), axis=0)
    sign = np.sign(V[idx, np.arange(r)])
    sign[sign == 0] = 1.0
    return V * sign, s[:r]


def _ols(T: np.ndarray, y: np.ndarray):
    import statsmodels.api as sm

    exog = sm.add_constant(T, has_constant="add") if T.shape[1] else np.ones((len(y), 1))
    return sm.OLS(y, exog).fit()


def _pcr_path_predictions(Ztr: np.ndarray, ytr: np.ndarray, Zte: np.ndarray, grid) -> np.ndarray:
    """PCA-regression predictions ``(n_te, len(grid))`` for 0..k components (``grid = arange(k_max + 1)``).

    The training scores are centred and mutually orthogonal, so the OLS coefficient of a component does not
    depend on the other components in the model: all k follow from one cumulative sum. A fold whose rank is
    below k repeats its largest model.
    """
    V, _ = _pca(Ztr)
    k_max = int(grid[-1])
    kk = min(k_max, V.shape[1], len(ytr) - 3)
    kk = max(kk, 0)
    Ttr, Tte = Ztr @ V[:, :kk], Zte @ V[:, :kk]
    ym = ytr.mean()
    b = (Ttr.T @ (ytr - ym)) / np.einsum("ij,ij->j", Ttr, Ttr)
    pred = ym + np.concatenate([np.zeros((len(Zte), 1)), np.cumsum(Tte * b, axis=1)], axis=1)
    if kk < k_max:
        pred = np.concatenate([pred, np.repeat(pred[:, -1:], k_max - kk, axis=1)], axis=1)
    return pred


def _select(A: np.ndarray, y: np.ndarray, splits, fn, grid, max_nan_fraction: float, selection: str):
    """Inner CV of a model path: index into ``grid`` (ordered simplest / most regularised first) and the pooled
    MSE per grid value. ``selection="one_se"``: the first grid value whose pooled MSE is within one standard
    error (SD of the per-fold MSEs at the minimum / sqrt(folds)) of the minimum; ``"min"``: the minimum."""
    if selection not in ("one_se", "min"):
        raise InputError(None, "selection 'one_se' or 'min'", column="selection", got=selection)
    fold_sse = np.zeros((len(splits), len(grid)))
    fold_n = np.zeros(len(splits))
    for i, (tr, te) in enumerate(splits):
        Ztr, Zte = _standardise_split(A, tr, te, max_nan_fraction)
        pred = fn(Ztr, y[tr], Zte, grid)
        fold_sse[i] = ((pred - y[te, None]) ** 2).sum(axis=0)
        fold_n[i] = len(te)
    mse = fold_sse.sum(axis=0) / fold_n.sum()
    i_min = int(np.argmin(mse + _TIE * np.arange(len(grid)) * max(float(np.max(mse)), 1e-300)))
    if selection == "min" or len(splits) < 2:
        return i_min, mse
    se = float(np.std(fold_sse[:, i_min] / fold_n, ddof=1) / np.sqrt(len(splits)))
    return int(np.flatnonzero(mse <= mse[i_min] + se)[0]), mse


@dataclass
class PCARegression:
    """A fitted PCA regression of one friction parameter (see module docstring for conventions).

    ``loadings`` ``(p, k)`` unit vectors in standardised feature space (kept components); ``eigenvalues``
    of the training correlation matrix (all components of the numerical rank); ``ols`` the statsmodels results
    on ``[1, scores]``; ``cv_mse`` the inner-CV error per number of components (rule ``"cv"`` only), in
    squared units of the target.
    """

    target: str
    rule: str
    standardiser: Standardiser
    loadings: np.ndarray
    eigenvalues: np.ndarray
    ols: object
    n: int
    cv_mse: np.ndarray | None = None

    @property
    def n_components(self) -> int:
        return int(self.loadings.shape[1])

    def scores(self, X: pd.DataFrame) -> np.ndarray:
        """Principal-component scores ``(n, k)`` of feature rows ``X``."""
        return self.standardiser.transform(X) @ self.loadings

    def predict(self, X: pd.DataFrame) -> pd.Series:
        """Predicted target for the rows of ``X`` (same units as the target)."""
        T = self.scores(X)
        params = np.asarray(self.ols.params)
        return pd.Series(params[0] + T @ params[1:], index=X.index, name=self.target)

    def statistics(self) -> dict:
        """n, number of components, rule, R-squared, adjusted R-squared, residual standard error (target units)."""
        r = self.ols
        return {"target": self.target, "n": self.n, "n_components": self.n_components, "rule": self.rule,
                "r2": float(r.rsquared), "adj_r2": float(r.rsquared_adj), "rse": float(np.sqrt(r.scale)),
                "df_resid": float(r.df_resid),
                "f_pvalue": float(r.f_pvalue) if self.n_components else float("nan")}

    def table5(self) -> pd.DataFrame:
        """Study's Table 5 for this target: intercept and component coefficients, std errors, p-values, stars.

        ``explained_variance`` is the share of the standardised feature variance carried by the component. The
        fit statistics (:meth:`statistics`) are also in ``DataFrame.attrs``.
        """
        r = self.ols
        params, bse = np.asarray(r.params), np.asarray(r.bse)
        tv, pv = np.asarray(r.tvalues), np.asarray(r.pvalues)
        share = self.eigenvalues / self.eigenvalues.sum()
        rows = []
        for i in range(self.n_components + 1):
            rows.append({"target": self.target, "component": "Intercept" if i == 0 else f"PC{i}",
                         "coefficient": params[i], "std_error": bse[i], "t_value": tv[i], "p_value": pv[i],
                         "stars": _stars(pv[i]),
                         "explained_variance": float("nan") if i == 0 else float(share[i - 1])})
        out = pd.DataFrame(rows)
        out.attrs.update(self.statistics())
        return out

    def _linear_map(self) -> np.ndarray:
        """``L`` with ``[intercept, beta (original units)] = L @ [b0, b]``."""
        st, V = self.standardiser, self.loadings
        p, k = V.shape
        L = np.zeros((p + 1, k + 1))
        L[0, 0] = 1.0
        L[0, 1:] = -(st.means / st.sds) @ V
        L[1:, 1:] = V / st.sds[:, None]
        return L

    @property
    def coefficients_per_sd(self) -> pd.Series:
        """Target change per one training SD of each kept feature (``V_k b``)."""
        b = np.asarray(self.ols.params)[1:]
        return pd.Series(self.loadings @ b, index=list(self.standardiser.columns))

    @property
    def coefficients(self) -> pd.Series:
        """Intercept and one coefficient per kept feature, target units per feature unit (Table 6)."""
        L = self._linear_map()
        c = L @ np.asarray(self.ols.params)
        return pd.Series(c, index=["Intercept"] + list(self.standardiser.columns))

    def table6(self) -> pd.DataFrame:
        """Study's Table 6: intercept + one coefficient per feature in original units, with propagated SE.

        Columns: target, variable, band, parameter, coefficient (target units per feature unit), std_error,
        p_value (two-sided t with the OLS residual dof), coefficient_per_sd (target units per feature SD).
        """
        from scipy import stats

        L = self._linear_map()
        c = L @ np.asarray(self.ols.params)
        cov = L @ np.asarray(self.ols.cov_params()) @ L.T
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            pv = 2 * stats.t.sf(np.abs(c / se), self.ols.df_resid)
        per_sd = np.concatenate([[np.nan], self.coefficients_per_sd.to_numpy()])
        names = ["Intercept"] + list(self.standardiser.columns)
        bands = [("intercept", "Intercept")] + [split_band(c_) for c_ in self.standardiser.columns]
        return pd.DataFrame({"target": self.target, "variable": names, "band": [b for b, _ in bands],
                             "parameter": [q for _, q in bands], "coefficient": c, "std_error": se,
                             "p_value": pv, "coefficient_per_sd": per_sd})


def _parse_rule(rule: str):
    if rule in ("cv", "study", "kaiser"):
        return rule, None
    if rule.startswith("variance:"):
        try:
            f = float(rule.split(":", 1)[1])
        except ValueError:
            f = float("nan")
        if not (0 < f <= 1):
            raise InputError(None, "'variance:F' with 0 < F <= 1", column="rule", got=rule)
        return "variance", f
    raise InputError(None, "a retention rule: 'cv', 'study', 'kaiser' or 'variance:F'", column="rule", got=rule)


def fit_pca_regression(X: pd.DataFrame, y: pd.Series, *, rule: str = "cv", n_components: int | None = None,
                       groups=None, seed: int = 0, inner_folds: int = 5, selection: str = "one_se",
                       max_nan_fraction: float = MAX_NAN_FRACTION) -> PCARegression:
    """PCA regression of ``y`` on the features ``X`` (rows aligned), with the retention ``rule``.

    ``groups`` (one label per row, e.g. section) makes the ``"cv"`` rule's inner CV leave-one-group-out;
    ``seed`` drives the shuffled K-fold otherwise. ``n_components`` (0..min(rank, n-2)) overrides the rule.
    """
    if len(X) != len(y):
        raise InputError(None, f"one target value per feature row ({len(X)})", column=str(y.name), got=len(y))
    yv = np.asarray(y, dtype=float)
    if not np.all(np.isfinite(yv)):
        raise InputError(None, "finite target values", column=str(y.name))
    kind, frac = _parse_rule(rule)
    n = len(yv)
    st = Standardiser.fit(X, max_nan_fraction)
    Z = st.transform(X)
    V, s = _pca(Z)
    eig = s ** 2 / (n - 1)
    rank = V.shape[1]
    k_max = max(0, min(rank, n - 3))
    cv_mse = None
    if n_components is not None:
        if not (0 <= int(n_components) <= min(rank, n - 2)):
            raise InputError(None, f"n_components between 0 and {min(rank, n - 2)} (rank {rank}, n {n})",
                             column="n_components", got=n_components)
        k = int(n_components)
        rule = f"fixed:{k}"
    elif kind == "kaiser":
        k = min(int(np.sum(eig > 1.0)), k_max)
    elif kind == "variance":
        cum = np.cumsum(eig) / eig.sum()
        k = min(int(np.searchsorted(cum, frac - 1e-12) + 1), k_max)
    elif kind == "study":
        k = 0
        for kk in range(1, k_max + 1):
            r = _ols(Z @ V[:, :kk], yv)
            if np.all(np.asarray(r.pvalues)[1:] < 0.05):
                k = kk
    else:  # cv
        splits = inner_splits(n, groups, seed=seed, n_folds=inner_folds)
        n_inner = min(len(tr) for tr, _ in splits)
        k_cv = max(0, min(k_max, n_inner - 3))
        k, cv_mse = _select(X.to_numpy(dtype=float), yv, splits, _pcr_path_predictions, np.arange(k_cv + 1),
                            max_nan_fraction, selection)
    ols = _ols(Z @ V[:, :k], yv)
    return PCARegression(target=str(y.name), rule=rule, standardiser=st, loadings=V[:, :k], eigenvalues=eig,
                         ols=ols, n=n, cv_mse=cv_mse)


def fit_pca_tables(X: pd.DataFrame, Y: pd.DataFrame, *, rule: str = "cv", groups=None, seed: int = 0,
                   **kw) -> dict[str, PCARegression]:
    """One :class:`PCARegression` per friction parameter (columns of ``Y``)."""
    return {c: fit_pca_regression(X, Y[c], rule=rule, groups=groups, seed=seed, **kw) for c in Y.columns}


def table5(fits: Mapping[str, PCARegression]) -> pd.DataFrame:
    """Table 5 for several targets, long form (target, component, coefficient, ..., stars)."""
    return pd.concat([f.table5() for f in fits.values()], ignore_index=True)


def table5_statistics(fits: Mapping[str, PCARegression]) -> pd.DataFrame:
    """The bottom of Table 5: per target n, components, rule, R-squared, adjusted R-squared, RSE."""
    return pd.DataFrame([f.statistics() for f in fits.values()])


def table6(fits: Mapping[str, PCARegression]) -> pd.DataFrame:
    """Table 6 for several targets, long form (target, variable, band, parameter, coefficient, ...)."""
    return pd.concat([f.table6() for f in fits.values()], ignore_index=True)


# ---------------------------------------------------------------------------------------------------------
# Alternatives: ridge, lasso, PLS, two-variable OLS, intercept only
# ---------------------------------------------------------------------------------------------------------

def ridge_path_predictions(Ztr: np.ndarray, ytr: np.ndarray, Zte: np.ndarray, alphas) -> np.ndarray:
    """Ridge predictions ``(n_te, n_alphas)`` for standardised (centred) ``Ztr``; objective of sklearn ``Ridge``
    (``||y - ym - Z w||^2 + alpha ||w||^2``, intercept unpenalised), all penalties from one SVD."""
    ym = ytr.mean()
    U, s, vt = np.linalg.svd(Ztr, full_matrices=False)
    uty = U.T @ (ytr - ym)
    d = s[:, None] / (s[:, None] ** 2 + np.asarray(alphas, float)[None, :])
    W = vt.T @ (d * uty[:, None])
    return ym + Zte @ W


def _lasso_path_predictions(Ztr, ytr, Zte, alphas) -> np.ndarray:
    """Lasso predictions ``(n_te, n_alphas)`` (sklearn objective ``||y - Zw||^2 / (2n) + alpha |w|_1``)."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.linear_model import lasso_path

    ym = ytr.mean()
    zm = Ztr.mean(axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        _, coefs, _ = lasso_path(Ztr - zm, ytr - ym, alphas=np.asarray(alphas), max_iter=LASSO_MAX_ITER,
                                 tol=LASSO_TOL)
    return ym + (Zte - zm) @ coefs


def pls_path_predictions(Ztr: np.ndarray, ytr: np.ndarray, Zte: np.ndarray, ncomps) -> np.ndarray:
    """PLS1 (NIPALS, single target, no scaling: as sklearn ``PLSRegression(scale=False)``) predictions
    ``(n_te, len(ncomps))`` for each number of components, all from one pass of deflation."""
    zm, ym = Ztr.mean(axis=0), ytr.mean()
    Xk, yk = Ztr - zm, ytr - ym
    kmax = int(np.max(ncomps))
    W, P, Q = [], [], []
    for _ in range(kmax):
        w = Xk.T @ yk
        nw = np.linalg.norm(w)
        if nw < 1e-14:
            break
        w /= nw
        t = Xk @ w
        tt = t @ t
        p_ = Xk.T @ t / tt
        q = (yk @ t) / tt
        Xk = Xk - np.outer(t, p_)
        yk = yk - q * t
        W.append(w), P.append(p_), Q.append(q)
    W, P, Q = np.array(W).T, np.array(P).T, np.array(Q)
    out = np.empty((len(Zte), len(ncomps)))
    for j, nc in enumerate(ncomps):
        k = min(int(nc), W.shape[1] if W.size else 0)
        if k == 0:
            out[:, j] = ym
            continue
        B = W[:, :k] @ np.linalg.solve(P[:, :k].T @ W[:, :k], Q[:k])
        out[:, j] = ym + (Zte - zm) @ B
    return out


@dataclass
class FittedModel:
    """A fitted model of one target: ``predict(X) -> Series``; ``hyper`` holds the chosen hyper-parameter and
    the inner-CV error per grid value (``inner_mse``, squared target units)."""

    name: str
    target: str
    standardiser: Standardiser | None
    estimator: object
    hyper: dict

    def predict(self, X: pd.DataFrame) -> pd.Series:
        if self.name == "mean":
            v = np.full(len(X), self.estimator)
        elif self.name == SUBSET_OLS:
            v = self.estimator.predict(X).iloc[:, 0].to_numpy()
        elif self.name == "two_variable":
            missing = [c for c in TWO_VARIABLES if c not in X.columns]
            if missing:
                raise InputError(None, "the two-variable model's columns", column=missing[0])
            A = X.loc[:, list(TWO_VARIABLES)].to_numpy(dtype=float)
            A = np.where(np.isnan(A), self.hyper["medians"], A)
            v = self.estimator.params[0] + A @ np.asarray(self.estimator.params[1:])
        else:
            v = np.asarray(self.estimator.predict(self.standardiser.transform(X))).ravel()
        return pd.Series(v, index=X.index, name=self.target)


def fit_model(name: str, X: pd.DataFrame, y: pd.Series, *, groups=None, seed: int = 0, inner_folds: int = 5,
              selection: str = "one_se", max_nan_fraction: float = MAX_NAN_FRACTION):
    """Fit model ``name`` on one target; hyper-parameters by inner CV on these rows only.

    ``name``: ``"mean"`` (training mean), ``"pca"`` (rule ``"cv"``), ``"pca:<rule>"`` (e.g. ``"pca:study"``,
    ``"pca:kaiser"``, ``"pca:variance:0.9"``), ``"ridge"``, ``"lasso"``, ``"pls"``, ``"two_variable"`` (OLS on
    ``profile_MPD`` and ``micro_Sq``, NaN imputed with training medians), ``"ols2"`` (OLS on at most two texture
    columns chosen by inner CV, :func:`fit_subset_ols`). ``groups`` (one label per row) makes the
    inner CV leave-one-group-out; ``selection`` ``"one_se"`` or ``"min"`` (see module docstring). Returns an
    object with ``predict(X) -> Series`` (:class:`PCARegression` or :class:`FittedModel`).
    """
    yv = np.asarray(y, dtype=float)
    if len(yv) != len(X):
        raise InputError(None, f"one target value per feature row ({len(X)})", column=str(y.name), got=len(yv))
    if not np.all(np.isfinite(yv)):
        raise InputError(None, "finite target values", column=str(y.name))
    target = str(y.name)
    if name == "pca" or name.startswith("pca:"):
        rule = "cv" if name == "pca" else name[4:]
        return fit_pca_regression(X, y, rule=rule, groups=groups, seed=seed, inner_folds=inner_folds,
                                  selection=selection, max_nan_fraction=max_nan_fraction)
    if name == "mean":
        return FittedModel(name, target, None, float(yv.mean()), {})
    if name == SUBSET_OLS:
        est = fit_subset_ols(X, pd.DataFrame({target: yv}, index=X.index), groups=groups, seed=seed,
                             inner_folds=inner_folds, max_nan_fraction=max_nan_fraction)
        return FittedModel(name, target, None, est, {"features": est.label})
    if name == "two_variable":
        missing = [c for c in TWO_VARIABLES if c not in X.columns]
        if missing:
            raise InputError(None, "the two-variable model's columns " + ", ".join(TWO_VARIABLES),
                             column=missing[0])
        A = X.loc[:, list(TWO_VARIABLES)].to_numpy(dtype=float)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(A, axis=0)
        if np.any(np.isnan(med)):
            raise InputError(None, "values of the two-variable model's columns", column="profile_MPD/micro_Sq")
        A = np.where(np.isnan(A), med, A)
        return FittedModel(name, target, None, _ols(A, yv), {"medians": med})
    if name not in ("ridge", "lasso", "pls"):
        raise InputError(None, "a model name: mean, ols2, pca, pca:<rule>, ridge, lasso, pls, two_variable "
                         "(optionally with @curve or @dft)", column="models", got=name)
    from sklearn.cross_decomposition import PLSRegression
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.linear_model import Lasso, Ridge

    st = Standardiser.fit(X, max_nan_fraction)
    Z = st.transform(X)
    A = X.to_numpy(dtype=float)
    splits = inner_splits(len(yv), groups, seed=seed, n_folds=inner_folds)
    if name == "ridge":
        grid = RIDGE_ALPHAS[::-1]  # most regularised first
        fn = ridge_path_predictions
    elif name == "lasso":
        amax = np.max(np.abs(Z.T @ (yv - yv.mean()))) / len(yv)
        grid = max(amax, 1e-12) * LASSO_ALPHA_RATIOS  # most regularised first
        fn = _lasso_path_predictions
    else:
        n_inner = min(len(tr) for tr, _ in splits)
        grid = np.arange(1, max(1, min(PLS_MAX_COMPONENTS, Z.shape[1], n_inner - 2)) + 1)
        fn = pls_path_predictions
    i, mse = _select(A, yv, splits, fn, grid, max_nan_fraction, selection)
    best = grid[i]
    if name == "ridge":
        est = Ridge(alpha=float(best)).fit(Z, yv)
        hyper = {"alpha": float(best)}
    elif name == "lasso":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            est = Lasso(alpha=float(best), max_iter=LASSO_MAX_ITER, tol=LASSO_TOL).fit(Z, yv)
        hyper = {"alpha": float(best), "n_nonzero": int(np.sum(est.coef_ != 0))}
    else:
        est = PLSRegression(n_components=int(best), scale=False).fit(Z, yv)
        hyper = {"n_components": int(best)}
    hyper["grid"] = np.asarray(grid)
    hyper["inner_mse"] = mse
    return FittedModel(name, target, st, est, hyper)


# ---------------------------------------------------------------------------------------------------------
# The simple baseline: OLS on at most two texture columns, the subset chosen by inner cross-validation
# ---------------------------------------------------------------------------------------------------------

def texture_columns(X: pd.DataFrame) -> list[str]:
    """The texture columns of a feature table (``raw_*``, ``macro_*``, ``micro_*``, ``profile_*``; no temperature)."""
    return [c for c in X.columns if isinstance(c, str) and any(c.startswith(b + "_") for b in BANDS)]


def candidate_subsets(p: int, max_features: int = SUBSET_MAX_FEATURES) -> np.ndarray:
    """Candidate column subsets of size 0..``max_features`` (at most 2) of ``p`` columns, as an ``(m, 2)`` index
    array: ``(-1, -1)`` the empty subset (intercept only), ``(i, i)`` the column i alone, ``(i, j)`` with
    ``i < j`` the pair. Ordered by size, then lexicographically (the tie order: simpler first)."""
    if max_features not in (0, 1, 2):
        raise InputError(None, "at most 2 features in the subset OLS", column="max_features", got=max_features)
    rows = [np.array([[-1, -1]])]
    if max_features >= 1 and p:
        rows.append(np.column_stack([np.arange(p), np.arange(p)]))
    if max_features >= 2 and p > 1:
        rows.append(np.column_stack(np.triu_indices(p, k=1)))
    return np.concatenate(rows).astype(int)


def _impute(A: np.ndarray, medians: np.ndarray) -> np.ndarray:
    return np.where(np.isnan(A), medians, A)


def _nanmedian(A: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(A, axis=0)


def subset_test_sse(Atr: np.ndarray, Ytr: np.ndarray, Ate: np.ndarray, Yte: np.ndarray,
                    subsets: np.ndarray) -> np.ndarray:
    """Test SSE, summed over the test rows and the target columns, of OLS with intercept fitted on the training
    rows with each subset of :func:`candidate_subsets` (closed forms, all subsets at once).

    ``Atr``/``Ate`` feature rows (NaN imputed with the training medians here); ``Ytr``/``Yte`` ``(n, k)`` targets
    in one unit. A subset whose columns are constant or collinear on the training rows (``1 - r^2 <= 1e-10``)
    gets ``+inf``, so it is never chosen.
    """
    med = _nanmedian(Atr)
    med = np.where(np.isnan(med), 0.0, med)
    Atr, Ate = _impute(Atr, med), _impute(Ate, med)
    mx, sx = Atr.mean(axis=0), Atr.std(axis=0)
    const = ~(sx > 1e-12 * (1.0 + np.abs(mx)))
    sx = np.where(const, 1.0, sx)
    A, At = (Atr - mx) / sx, (Ate - mx) / sx
    A[:, const] = 0.0
    At[:, const] = 0.0
    Ytr, Yte = np.atleast_2d(Ytr.T).T, np.atleast_2d(Yte.T).T
    my = Ytr.mean(axis=0)
    S = A.T @ A
    C = A.T @ (Ytr - my)
    empty = subsets[:, 0] < 0
    i = np.where(empty, 0, subsets[:, 0])
    j = np.where(empty, 0, subsets[:, 1])
    single = (i == j) & ~empty
    sii, sjj, sij = S[i, i], S[j, j], S[i, j]
    tol = 1e-12 * len(A)
    det = sii * sjj - sij ** 2
    ok = empty | np.where(single, sii > tol, (sii > tol) & (sjj > tol) & (det > 1e-10 * sii * sjj))
    sii_s = np.where(sii > tol, sii, 1.0)
    det_s = np.where(ok & ~single & ~empty, det, 1.0)
    bi = np.where(single[:, None], C[i] / sii_s[:, None], (sjj[:, None] * C[i] - sij[:, None] * C[j]) / det_s[:, None])
    bj = np.where(single[:, None], 0.0, (sii[:, None] * C[j] - sij[:, None] * C[i]) / det_s[:, None])
    bi = np.where(empty[:, None], 0.0, bi)
    bj = np.where(empty[:, None], 0.0, bj)
    pred = my[None, None, :] + At[:, i][:, :, None] * bi[None] + At[:, j][:, :, None] * bj[None]  # (n_te, m, k)
    sse = ((pred - Yte[:, None, :]) ** 2).sum(axis=(0, 2))
    return np.where(ok, sse, np.inf)


@dataclass(frozen=True)
class SubsetOLS:
    """OLS with intercept on at most two texture columns, the subset chosen by inner cross-validation.

    ``columns``: the chosen texture columns (0, 1 or 2; empty = intercept only); ``targets``: the target
    columns, fitted jointly with the same subset (one unit, e.g. DFT friction at several speeds, dimensionless);
    ``medians``: training medians of ``columns`` (NaN imputation), in the columns' units; ``intercept`` ``(k,)``
    in target units; ``coef`` ``(len(columns), k)`` in target units per unit of the column; ``inner_sse``: the
    pooled inner-CV squared error (target units squared) of every candidate subset, named ``"a+b"`` (``""`` for
    the intercept only), ``inf`` for a constant or collinear subset.
    """

    columns: tuple[str, ...]
    targets: tuple[str, ...]
    medians: np.ndarray
    intercept: np.ndarray
    coef: np.ndarray
    inner_sse: pd.Series

    @property
    def label(self) -> str:
        """``"a+b"`` (or ``"(intercept only)"``)."""
        return "+".join(self.columns) if self.columns else "(intercept only)"

    def predict(self, X: pd.DataFrame) -> pd.DataFrame:
        """Predicted targets ``(n, k)`` for the rows of ``X``, indexed like ``X``."""
        missing = [c for c in self.columns if c not in X.columns]
        if missing:
            raise InputError(None, "the baseline's chosen texture columns", column=missing[0])
        A = _impute(X.loc[:, list(self.columns)].to_numpy(dtype=float), self.medians)
        P = self.intercept[None, :] + A @ self.coef
        return pd.DataFrame(P, index=X.index, columns=list(self.targets))


def fit_subset_ols(X: pd.DataFrame, Y: pd.DataFrame, *, groups=None, seed: int = 0, inner_folds: int = 5,
                   max_features: int = SUBSET_MAX_FEATURES,
                   max_nan_fraction: float = MAX_NAN_FRACTION) -> SubsetOLS:
    """The simple baseline: choose at most ``max_features`` texture columns of ``X`` by inner cross-validation
    on these rows, then fit OLS with intercept of all columns of ``Y`` on them.

    Candidates: the empty subset, every texture column (:func:`texture_columns`; columns with more than
    ``max_nan_fraction`` NaN or constant on these rows are left out) and every pair. The inner CV is
    :func:`inner_splits` (leave-one-group-out with ``groups``, else seeded K-fold); in each fold the medians
    (NaN imputation) are learnt on the fold's training rows. The subset with the smallest test SSE pooled over
    the folds and the columns of ``Y`` wins (one unit, so one subset for the whole curve); exact ties go to the
    smaller subset. Only the rows given are used: in a cross-validation the held-out section never enters the
    choice.
    """
    if isinstance(Y, pd.Series):
        Y = Y.to_frame()
    if len(X) != len(Y):
        raise InputError(None, f"one target row per feature row ({len(X)})", got=len(Y))
    Yv = Y.to_numpy(dtype=float)
    if not np.all(np.isfinite(Yv)):
        raise InputError(None, "finite target values", column=str(list(Y.columns)))
    cols = texture_columns(X)
    if not cols:
        raise InputError(None, "texture columns (raw_*, macro_*, micro_*, profile_*) for the baseline",
                         got=list(X.columns)[:8])
    A = X.loc[:, cols].to_numpy(dtype=float)
    keep, _, _, _, _ = _standardiser_arrays(A, max_nan_fraction)
    names = [cols[k] for k in keep]
    A = A[:, keep]
    subsets = candidate_subsets(len(names), max_features)
    splits = inner_splits(len(Yv), groups, seed=seed, n_folds=inner_folds)
    sse = np.zeros(len(subsets))
    for tr, te in splits:
        sse += subset_test_sse(A[tr], Yv[tr], A[te], Yv[te], subsets)
    best = subsets[int(np.argmin(sse))]
    chosen = sorted({int(c) for c in best if c >= 0})
    med = _nanmedian(A)
    B = _impute(A[:, chosen], med[chosen])
    design = np.column_stack([np.ones(len(B)), B])
    beta, *_ = np.linalg.lstsq(design, Yv, rcond=None)
    labels = ["" if a < 0 else names[a] if a == b else f"{names[a]}+{names[b]}" for a, b in subsets]
    return SubsetOLS(columns=tuple(names[c] for c in chosen), targets=tuple(str(c) for c in Y.columns),
                     medians=med[chosen], intercept=beta[0], coef=beta[1:],
                     inner_sse=pd.Series(sse, index=labels, name="inner_sse"))


def curve_targets(Y: pd.DataFrame, anchors_kmh: Sequence[float] = CURVE_ANCHORS_KMH) -> pd.DataFrame:
    """The friction law of each row of ``Y`` (``mu_s``, ``mu_k``, ``alpha`` s/m) evaluated at ``anchors_kmh``
    (km/h): columns ``mu@<v>`` (dimensionless), indexed like ``Y``. The targets of the ``<model>@curve`` models."""
    for c in PARAMETERS:
        if c not in Y.columns:
            raise InputError(None, f"a '{c}' column in the friction table", column=c)
    out = {f"mu@{v:g}": [ExponentialDecay(r.mu_s, r.mu_k, r.alpha).mu_kmh(float(v)) for r in Y.itertuples()]
           for v in anchors_kmh}
    return pd.DataFrame(out, index=Y.index)


def law_from_curve(values, anchors_kmh: Sequence[float] = CURVE_ANCHORS_KMH) -> tuple[float, float, float]:
    """(mu_s, mu_k, alpha s/m) of the law closest to friction ``values`` at ``anchors_kmh`` (km/h), within the
    study's bounds (bounded least squares, :func:`skidsim.calibration.fit_exponential_decay`): exact wherever a
    bounded law passes through the values (three anchors: three equations, three unknowns), else the nearest."""
    from skidsim.calibration import fit_exponential_decay

    law, _ = fit_exponential_decay(np.asarray(anchors_kmh, dtype=float), np.asarray(values, dtype=float))
    return law.mu_s, law.mu_k, law.alpha


def predict_parameters(model_name: str, X_train: pd.DataFrame, Y_train: pd.DataFrame, X_test: pd.DataFrame, *,
                       groups_train=None, seed: int = 0, inner_folds: int = 5, selection: str = "one_se",
                       dft_train: pd.DataFrame | None = None, g_test: pd.DataFrame | None = None) -> pd.DataFrame:
    """Fit ``model_name`` on the training sites, one model per column of ``Y_train`` (``mu_s``, ``mu_k``,
    ``alpha`` s/m), and predict the test sites. Returns a frame indexed like ``X_test``, columns of ``Y_train``.

    ``<model>@curve`` (e.g. ``ridge@curve``): the targets are the laws' friction values at
    :data:`CURVE_ANCHORS_KMH` (:func:`curve_targets`), each predicted by ``<model>``; the predicted values are
    turned back into (mu_s, mu_k, alpha) by :func:`law_from_curve`. Why: the back-calculated parameters are
    not identified by a DFT curve over 20-60 km/h (a nearly straight curve is fitted as well by a high mu_k with
    a fast decay as by mu_k = 0 with a slow one), so per-parameter regressions average incompatible parameter
    sets and the law of the averaged parameters is not the average curve (docs/regression.md, "Curve targets").

    ``<model>@dft`` (e.g. ``ridge@dft``, the baseline ``ols2@dft``): the targets are the DFT of the training
    sites at the prediction speeds, ``dft_train`` (:func:`dft_targets`: the measured DFT, not the calibrated
    laws, so neither the back-calculation nor the FE stands between texture and target); the result also has
    the predicted ``dft@<v>`` columns, which the CV table scores directly, and parameters of the bounded law
    whose ``g * mu(v)`` is closest to them (:func:`law_from_dft`, ``g_test`` the test sites' g, None for 1), the
    FE input of Figure 11. Models ``ols2``/``ols2@...`` add a column ``features`` naming the chosen columns.
    """
    if len(X_train) != len(Y_train):
        raise InputError(None, f"one friction row per training site ({len(X_train)})", got=len(Y_train))
    if model_name.endswith(CURVE_SUFFIX):
        base = model_name[:-len(CURVE_SUFFIX)]
        C, features = predict_targets(base, X_train, curve_targets(Y_train), X_test, groups_train=groups_train,
                                      seed=seed, inner_folds=inner_folds, selection=selection)
        laws = [law_from_curve(row) for row in C.to_numpy(dtype=float)]
        out = pd.DataFrame(laws, index=X_test.index, columns=list(PARAMETERS))[
            [c for c in Y_train.columns if c in PARAMETERS]]
        if features is not None:
            out["features"] = features
        return out
    if model_name.endswith(DFT_SUFFIX):
        if dft_train is None:
            raise InputError(None, f"DFT targets of the training sites for model {model_name!r}", column="dft")
        base = model_name[:-len(DFT_SUFFIX)]
        D = dft_train.loc[X_train.index]
        C, features = predict_targets(base, X_train, D, X_test, groups_train=groups_train, seed=seed,
                                      inner_folds=inner_folds, selection=selection)
        speeds = dft_speeds(D)
        laws = []
        for site, row in zip(X_test.index, C.to_numpy(dtype=float)):
            gv = None if g_test is None else _g_values(g_test, str(site), speeds)
            laws.append(law_from_dft(row, speeds, gv))
        out = pd.DataFrame(laws, index=X_test.index, columns=list(PARAMETERS))[
            [c for c in Y_train.columns if c in PARAMETERS]]
        for c in C.columns:
            out[c] = C[c].to_numpy()
        if features is not None:
            out["features"] = features
        return out
    if model_name != SUBSET_OLS:
        return predict_targets(model_name, X_train, Y_train, X_test, groups_train=groups_train, seed=seed,
                               inner_folds=inner_folds, selection=selection)[0]
    out, features = {}, {}  # ols2 on the parameters: a subset per parameter (predict_targets shares one)
    for c in Y_train.columns:
        m = fit_model(model_name, X_train, Y_train[c], groups=groups_train, seed=seed, inner_folds=inner_folds,
                      selection=selection)
        out[c] = m.predict(X_test).to_numpy()
        features[c] = m.hyper["features"]
    out = pd.DataFrame(out, index=X_test.index)
    out["features"] = "; ".join(f"{c}: {f}" for c, f in features.items())
    return out


def predict_targets(base: str, X_train: pd.DataFrame, T_train: pd.DataFrame, X_test: pd.DataFrame, *,
                    groups_train=None, seed: int = 0, inner_folds: int = 5,
                    selection: str = "one_se") -> tuple[pd.DataFrame, str | None]:
    """Predict every column of ``T_train`` (curve values in one unit) at the test rows with model ``base``.

    ``"ols2"`` chooses one subset of at most two texture columns for all columns together (the pooled inner SSE,
    :func:`fit_subset_ols`) and returns its label; any other model is fitted per column (its own hyper-parameters)
    and the label is None. Returns (predictions indexed like ``X_test`` with the columns of ``T_train``, label).
    """
    if base == SUBSET_OLS:
        m = fit_subset_ols(X_train, T_train, groups=groups_train, seed=seed, inner_folds=inner_folds)
        return m.predict(X_test), m.label
    out = {}
    for c in T_train.columns:
        m = fit_model(base, X_train, T_train[c], groups=groups_train, seed=seed, inner_folds=inner_folds,
                      selection=selection)
        out[c] = m.predict(X_test).to_numpy()
    return pd.DataFrame(out, index=X_test.index), None


def dft_column(speed_kmh: float) -> str:
    """Name of the DFT target column at ``speed_kmh`` (km/h): ``"dft@20"``."""
    return f"dft@{float(speed_kmh):g}"


def dft_speeds(D: pd.DataFrame) -> list[float]:
    """Speeds (km/h) of the ``dft@<v>`` columns of ``D``, in column order."""
    out = []
    for c in D.columns:
        if not (isinstance(c, str) and c.startswith("dft@")):
            raise InputError(None, "DFT target columns named dft@<speed km/h>", column=str(c))
        out.append(float(c[4:]))
    return out


def dft_targets(Y: pd.DataFrame | None, *, measured_dft: pd.DataFrame | None = None, g: pd.DataFrame | None = None,
                speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH, sites=None,
                measured_file="measured DFT") -> pd.DataFrame:
    """The targets of the ``<model>@dft`` models: one row per site, columns ``dft@<v>`` (friction, dimensionless)
    at ``speeds_kmh`` (km/h). The measured DFT (long form site, speed_kmh, mu) when given, else ``g * mu(v)`` of
    the calibrated laws ``Y`` (the same reference as :func:`score_predictions`). ``sites``: the rows wanted
    (default: the index of ``Y``); every site needs a value at every speed, else InputError."""
    if sites is None:
        if Y is None:
            raise InputError(None, "the sites of the DFT targets", column="site")
        sites = list(Y.index.astype(str))
    sites = [str(s) for s in sites]
    if measured_dft is None:
        if Y is None:
            raise InputError(None, "a measured DFT or calibrated laws for the DFT targets", column="mu")
        long = predict_dft(Y.loc[sites], g, speeds_kmh)
    else:
        long = measured_dft
    t, mc = _keyed_values(long, ("measured", "mu", "sn"), measured_file, "v", unique=True)
    wide = t.pivot(index="site", columns="key", values="v")
    out = {}
    for v in speeds_kmh:
        k = float(_speed_key(v))
        col = wide[k] if k in wide.columns else pd.Series(dtype=float)
        vals = col.reindex(sites)
        if vals.isna().any():
            raise InputError(measured_file, f"a DFT value for site {vals.index[vals.isna()][0]} at {v:g} km/h",
                             column=mc)
        out[dft_column(v)] = vals.to_numpy(dtype=float)
    return pd.DataFrame(out, index=pd.Index(sites, name="site"))


def _g_values(g: pd.DataFrame, site: str, speeds: Sequence[float]) -> np.ndarray:
    t = g[g["site"].astype(str) == site]
    m = dict(zip(_speed_key(t["speed_kmh"]).tolist(), t["g"].astype(float)))
    out = []
    for v in speeds:
        k = float(_speed_key(v))
        if k not in m:
            raise InputError("g table", f"a geometric factor for site {site} at {v:g} km/h", column="g")
        out.append(m[k])
    return np.asarray(out, dtype=float)


def law_from_dft(values, speeds_kmh: Sequence[float], g=None) -> tuple[float, float, float]:
    """(mu_s, mu_k, alpha s/m) of the bounded law whose FE response ``g(v) * mu(v)`` is closest (least squares)
    to the DFT ``values`` at ``speeds_kmh`` (km/h); ``g`` None for g = 1. The law a ``<model>@dft`` model hands
    to the FE (Figure 11) and to the parameter rows of the CV table; its DFT score uses the predicted values
    themselves, not this law."""
    from skidsim.calibration import fit_exponential_decay

    law, _ = fit_exponential_decay(np.asarray(speeds_kmh, dtype=float), np.asarray(values, dtype=float),
                                   b=None if g is None else np.asarray(g, dtype=float))
    return law.mu_s, law.mu_k, law.alpha


# ---------------------------------------------------------------------------------------------------------
# DFT predictions and error tables
# ---------------------------------------------------------------------------------------------------------

def _speed_key(v) -> np.ndarray:
    return np.round(np.asarray(v, dtype=float), 6)


def predict_dft(params: pd.DataFrame, g: pd.DataFrame | None = None,
                speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH, *, clip_physical: bool = True,
                g_file="g table") -> pd.DataFrame:
    """DFT predicted from friction parameters: ``g(site, v) * mu(v)``, long form (site, speed_kmh, mu, g).

    ``params`` is indexed by site (or has a ``site`` column) with ``mu_s``, ``mu_k``, ``alpha`` (s/m); ``g`` a
    table (site, speed_kmh, g) covering every site and speed (km/h), ``None`` for g = 1.
    """
    p = params.set_index(params["site"].astype(str)) if "site" in params.columns else params
    for c in PARAMETERS:
        if c not in p.columns:
            raise InputError(None, f"a '{c}' column in the parameter table", column=c)
    gmap = None
    if g is not None:
        for c in ("site", "speed_kmh", "g"):
            if c not in g.columns:
                raise InputError(g_file, f"a '{c}' column", column=c, got=list(g.columns))
        gmap = {(str(s), float(v)): float(x)
                for s, v, x in zip(g["site"], _speed_key(g["speed_kmh"]), g["g"].astype(float))}
    speeds = np.asarray(speeds_kmh, dtype=float)
    rows = []
    for site, r in p.iterrows():
        ms, mk, a = float(r["mu_s"]), float(r["mu_k"]), float(r["alpha"])
        if clip_physical:
            ms, mk, a = max(ms, 0.0), max(mk, 0.0), max(a, 0.0)
        mu = ExponentialDecay(ms, mk, a).mu_kmh(speeds)
        for v, m in zip(speeds, mu):
            gv = 1.0
            if gmap is not None:
                key = (str(site), float(_speed_key(v)))
                if key not in gmap:
                    raise InputError(g_file, f"a geometric factor for site {site} at {v:g} km/h", column="g")
                gv = gmap[key]
            rows.append({"site": str(site), "speed_kmh": float(v), "mu": gv * float(m), "g": gv})
    return pd.DataFrame(rows, columns=["site", "speed_kmh", "mu", "g"])


def _value_col(df: pd.DataFrame, candidates, file) -> str:
    for c in candidates:
        if c in df.columns:
            return c
    raise InputError(file, "a value column named " + " or ".join(f"'{c}'" for c in candidates),
                     column=candidates[0], got=list(df.columns))


def _keyed_values(df: pd.DataFrame, candidates, file, name: str, *, unique: bool) -> tuple[pd.DataFrame, str]:
    """A long table (``site``, ``speed_kmh`` km/h, a value column among ``candidates``) as columns ``site``,
    ``key`` (:func:`_speed_key`), ``speed_kmh`` and ``name``; ``unique``: one value per site and speed, else
    InputError naming ``file``. Returns the table and the value column's name in ``df``."""
    for c in ("site", "speed_kmh"):
        if c not in df.columns:
            raise InputError(file, f"a '{c}' column", column=c, got=list(df.columns))
    vc = _value_col(df, candidates, file)
    t = pd.DataFrame({"site": df["site"].astype(str), "key": _speed_key(df["speed_kmh"]),
                      "speed_kmh": df["speed_kmh"].astype(float), name: df[vc].astype(float)})
    if unique and t.duplicated(["site", "key"]).any():
        d = t[t.duplicated(["site", "key"])].iloc[0]
        raise InputError(file, "one value per site and speed", column="speed_kmh",
                         got=f"{d['site']} at {d['key']:g} km/h")
    return t, vc


def figure11_table(pred_dft: pd.DataFrame, measured_dft: pd.DataFrame, *,
                   pred_file="predicted DFT", measured_file="measured DFT") -> pd.DataFrame:
    """Per site and speed: predicted, measured, relative error ``(pred - meas)/meas``, ``within_10pct``.

    Both tables are long form with ``site``, ``speed_kmh`` (km/h) and a value column (``mu``, or ``predicted``
    / ``measured``, or ``sn``). Every predicted (site, speed) must have a measurement, else InputError.
    """
    a, _ = _keyed_values(pred_dft, ("predicted", "mu", "sn"), pred_file, "predicted", unique=False)
    b, mc = _keyed_values(measured_dft, ("measured", "mu", "sn"), measured_file, "measured", unique=True)
    t = a.merge(b.drop(columns="speed_kmh"), on=["site", "key"], how="left")
    miss = t[t["measured"].isna()]
    if len(miss):
        raise InputError(measured_file, f"a measurement for site {miss['site'].iloc[0]} at "
                         f"{miss['speed_kmh'].iloc[0]:g} km/h", column=mc)
    t["relative_error"] = (t["predicted"] - t["measured"]) / t["measured"]
    t["within_10pct"] = np.abs(t["relative_error"]) <= 0.10
    return t.drop(columns="key").sort_values(["speed_kmh", "site"]).reset_index(drop=True)


def figure11_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per speed (and ``speed_kmh`` NaN = all speeds): n, share within 10 %, mean |relative error|, RMSE."""
    def agg(t):
        e = t["predicted"] - t["measured"]
        return {"n": int(len(t)), "share_within_10pct": float(t["within_10pct"].mean()),
                "mean_abs_rel_error": float(np.abs(t["relative_error"]).mean()),
                "rmse": float(np.sqrt(np.mean(e ** 2)))}
    rows = [{"speed_kmh": float(v), **agg(t)} for v, t in table.groupby("speed_kmh", sort=True)]
    rows.append({"speed_kmh": float("nan"), **agg(table)})
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------------------------------------
# Cross-validation (leave one section out)
# ---------------------------------------------------------------------------------------------------------

def cross_validated_predictions(X: pd.DataFrame, Y: pd.DataFrame, groups, models: Sequence[str] = DEFAULT_MODELS,
                                *, seed: int = 0, inner_folds: int = 5, selection: str = "one_se",
                                workers: int = 1, dft: pd.DataFrame | None = None,
                                g: pd.DataFrame | None = None) -> pd.DataFrame:
    """Out-of-section predictions: for every section, each model is fitted on all other sections (hyper-
    parameters by inner leave-one-section-out CV on those) and predicts the held-out section's parameters.

    ``workers`` > 1 fits the (model, section) pairs in a thread pool: the fits are independent and seeded, the
    rows are assembled in the same order, so the result is identical to ``workers=1``; the time goes into
    scikit-learn's lasso coordinate descent (90 % of a default run's regression), which releases the GIL.
    ``dft``: the DFT targets of the ``<model>@dft`` models (:func:`dft_targets`, one row per site; default
    ``g * mu(v)`` of ``Y`` at :data:`DEFAULT_SPEEDS_KMH`), ``g`` the geometric factors (None: 1) for their laws.
    Returns long form: site, section, model, and one predicted column per column of ``Y``; ``<model>@dft``
    rows also fill the ``dft@<v>`` columns, ``ols2`` models the ``features`` column (NaN elsewhere).
    """
    grp = pd.Series(np.asarray(groups).astype(str), index=X.index) if not isinstance(groups, pd.Series) \
        else groups.astype(str).reindex(X.index)
    if grp.isna().any() or len(grp) != len(X):
        raise InputError(None, "a section for every site", column="section")
    if not X.index.equals(Y.index):
        raise InputError(None, "feature and friction tables indexed by the same sites in the same order",
                         column="site")
    uniq = sorted(grp.unique())
    if len(uniq) < 3:
        raise InputError(None, "at least 3 sections for leave-one-section-out", column="section", got=len(uniq))
    if dft is None and any(m.endswith(DFT_SUFFIX) for m in models):
        dft = dft_targets(Y, g=g)
    if dft is not None:
        missing = sorted(set(X.index.astype(str)) - set(dft.index.astype(str)))
        if missing:
            raise InputError(None, "DFT targets for every site", column="site", got=missing[0])
        dft = dft.set_axis(dft.index.astype(str)).loc[X.index.astype(str)].set_axis(X.index)

    def one(model, sec):
        te = (grp == sec).to_numpy()
        tr = ~te
        pred = predict_parameters(model, X[tr], Y[tr], X[te], groups_train=grp[tr].to_numpy(), seed=seed,
                                  inner_folds=inner_folds, selection=selection,
                                  dft_train=None if dft is None else dft[tr], g_test=g)
        pred.insert(0, "model", model)
        pred.insert(0, "section", sec)
        pred.insert(0, "site", pred.index.astype(str))
        return pred.reset_index(drop=True)

    pairs = [(model, sec) for model in models for sec in uniq]
    if int(workers) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=int(workers)) as pool:
            rows = list(pool.map(lambda ms: one(*ms), pairs))
    else:
        rows = [one(*ms) for ms in pairs]
    return pd.concat(rows, ignore_index=True)


def _scores(pred: np.ndarray, ref: np.ndarray, ref_all: np.ndarray) -> dict:
    e = pred - ref
    sst = np.sum((ref_all - ref_all.mean()) ** 2) if len(ref_all) > 1 else np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = e / ref
    return {"n": int(len(e)), "rmse": float(np.sqrt(np.mean(e ** 2))), "mae": float(np.mean(np.abs(e))),
            "bias": float(np.mean(e)), "r2": float(1 - np.sum(e ** 2) / sst) if sst > 0 else float("nan"),
            "mean_abs_rel_error": float(np.mean(np.abs(rel))),
            "share_within_10pct": float(np.mean(np.abs(rel) <= 0.10))}


def score_predictions(predictions: pd.DataFrame, Y: pd.DataFrame, *, g: pd.DataFrame | None = None,
                      measured_dft: pd.DataFrame | None = None,
                      speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH) -> pd.DataFrame:
    """Score out-of-sample predictions (from :func:`cross_validated_predictions`) per model.

    Rows: ``quantity`` in the parameters (``speed_kmh`` NaN) and ``"dft"`` at each speed plus pooled over speeds
    (``speed_kmh`` NaN). Columns n, rmse, mae, bias, r2 (out-of-sample, ``1 - SSE / sum((ref - mean ref)^2)``),
    mean_abs_rel_error, share_within_10pct. The DFT is ``g * mu(v)`` of the predicted parameters; the reference is
    ``measured_dft`` (site, speed_kmh, mu) or, if None, ``g * mu(v)`` of the calibrated parameters ``Y``.
    A model whose rows fill the ``dft@<v>`` columns of every speed (``<model>@dft``) is scored on those
    predicted values directly.
    """
    out = []
    params = [c for c in Y.columns if c in predictions.columns]
    for model, p in predictions.groupby("model", sort=False):
        ref = Y.loc[p["site"].astype(str)]
        for c in params:
            out.append({"model": model, "quantity": c, "speed_kmh": float("nan"),
                        **_scores(p[c].to_numpy(float), ref[c].to_numpy(float), ref[c].to_numpy(float))})
        direct = [dft_column(v) for v in speeds_kmh]
        if all(c in p.columns for c in direct) and p[direct].notna().all().all():
            # a <model>@dft model: its DFT predictions are scored as they are (not through a law)
            pd_ = pd.DataFrame({"site": np.repeat(p["site"].astype(str).to_numpy(), len(direct)),
                                "speed_kmh": np.tile(np.asarray(speeds_kmh, dtype=float), len(p)),
                                "mu": p[direct].to_numpy(dtype=float).ravel()})
        elif all(c in params for c in PARAMETERS):
            pd_ = predict_dft(p.set_index(p["site"].astype(str)), g, speeds_kmh)
        else:
            pd_ = None
        if pd_ is not None:
            if measured_dft is None:
                meas = predict_dft(ref, g, speeds_kmh)
            else:
                meas = measured_dft
            t = figure11_table(pd_, meas, pred_file=f"predicted DFT ({model})")
            for v, tv in t.groupby("speed_kmh", sort=True):
                out.append({"model": model, "quantity": "dft", "speed_kmh": float(v),
                            **_scores(tv["predicted"].to_numpy(), tv["measured"].to_numpy(),
                                      tv["measured"].to_numpy())})
            out.append({"model": model, "quantity": "dft", "speed_kmh": float("nan"),
                        **_scores(t["predicted"].to_numpy(), t["measured"].to_numpy(), t["measured"].to_numpy())})
    return pd.DataFrame(out)


def cross_validate_models(X: pd.DataFrame, Y: pd.DataFrame, groups, models: Sequence[str] = DEFAULT_MODELS, *,
                          g: pd.DataFrame | None = None, measured_dft: pd.DataFrame | None = None,
                          speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH, seed: int = 0,
                          inner_folds: int = 5, selection: str = "one_se") -> pd.DataFrame:
    """Leave-one-section-out comparison of ``models`` (see :func:`score_predictions` for the table); the
    ``<model>@dft`` targets are the same DFT reference the table scores against (:func:`dft_targets`)."""
    dft = None
    if any(m.endswith(DFT_SUFFIX) for m in models):
        dft = dft_targets(Y, measured_dft=measured_dft, g=g, speeds_kmh=speeds_kmh)
    pred = cross_validated_predictions(X, Y, groups, models, seed=seed, inner_folds=inner_folds,
                                      selection=selection, dft=dft, g=g)
    return score_predictions(pred, Y, g=g, measured_dft=measured_dft, speeds_kmh=speeds_kmh)


def rank_models(cv_table: pd.DataFrame, criterion: str = "auto") -> pd.DataFrame:
    """Rank models by ``criterion`` (lower score is better), with the gap to the best.

    ``"dft_rmse"``: RMSE of the DFT pooled over all speeds (what the FE input is for); ``"param_r2"``: the mean
    over the friction parameters of ``1 - R2`` (out-of-sample relative squared error; each parameter weighs the
    same whatever its unit); ``"auto"``: ``"dft_rmse"`` when the table has DFT rows, else ``"param_r2"``.
    Columns: model, score, gap (score - best score), ratio (score / best score).
    """
    has_dft = ((cv_table["quantity"] == "dft") & cv_table["speed_kmh"].isna()).any()
    if criterion == "auto":
        criterion = "dft_rmse" if has_dft else "param_r2"
    if criterion == "dft_rmse":
        if not has_dft:
            raise InputError(None, "pooled DFT rows in the CV table for criterion 'dft_rmse'", column="quantity")
        s = cv_table[(cv_table["quantity"] == "dft") & cv_table["speed_kmh"].isna()].set_index("model")["rmse"]
    elif criterion == "param_r2":
        t = cv_table[cv_table["quantity"].isin(PARAMETERS)]
        if t.empty:
            raise InputError(None, "parameter rows in the CV table", column="quantity")
        s = (1 - t.groupby("model", sort=False)["r2"].mean())
    else:
        raise InputError(None, "criterion 'auto', 'dft_rmse' or 'param_r2'", column="criterion", got=criterion)
    order = {m: i for i, m in enumerate(_SIMPLICITY)}
    r = pd.DataFrame({"model": s.index, "score": s.to_numpy(float)})
    r["simplicity"] = [order.get(m.split("@")[0].split(":")[0], len(order)) for m in r["model"]]
    r = r.sort_values(["score", "simplicity"], kind="stable").drop(columns="simplicity").reset_index(drop=True)
    r["gap"] = r["score"] - r["score"].iloc[0]
    r["ratio"] = r["score"] / r["score"].iloc[0] if r["score"].iloc[0] > 0 else np.nan
    r.attrs["criterion"] = criterion
    return r


def best_model(cv_table: pd.DataFrame, criterion: str = "auto") -> str:
    """The winner of :func:`rank_models` (lowest score; exact ties go to the simpler model)."""
    return str(rank_models(cv_table, criterion)["model"].iloc[0])


def prediction_skill(cv_table: pd.DataFrame, chosen: str, *, mean_model: str = MEAN_MODEL,
                     baseline_model: str = BASELINE_MODEL, notes: Mapping[str, str] | None = None) -> pd.DataFrame:
    """The prediction-skill table: per model, the section-grouped CV R^2 and RMSE of the DFT pooled over the
    prediction speeds (the ``quantity == "dft"``, ``speed_kmh`` NaN rows of ``cv_table``), beside the
    intercept-only ``mean_model`` and the simple ``baseline_model``.

    Columns: rank (by RMSE), model, role (``chosen``, ``mean``, ``baseline``, joined by ``+``), n, r2, rmse
    (friction, dimensionless), r2_minus_mean, r2_minus_baseline, beats_mean / beats_baseline (RMSE lower than
    the reference's by more than a relative 1e-9; a model never beats itself), beats_both, warning (the text
    below on the chosen model's row when it does not beat both, else empty), note (``notes[model]``, e.g. the
    baseline's chosen columns). ``attrs["warning"]`` holds the same text (empty when the chosen model beats both):
    callers must show it (the workflow logs it as a WARNING and the report flags the row).
    """
    pooled = cv_table[(cv_table["quantity"] == "dft") & cv_table["speed_kmh"].isna()]
    if pooled.empty:
        raise InputError(None, "pooled DFT rows (quantity 'dft', speed NaN) in the CV table", column="quantity")
    t = pooled.drop_duplicates("model").set_index("model")
    for m, what in ((chosen, "the chosen model"), (mean_model, "the mean model"),
                    (baseline_model, "the baseline model")):
        if m not in t.index:
            raise InputError(None, f"{what} {m!r} in the CV table's pooled DFT rows", column="model",
                             got=sorted(t.index)[:12])
    ref = {"mean": t.loc[mean_model], "baseline": t.loc[baseline_model]}
    out = pd.DataFrame({"model": t.index, "n": t["n"].astype(int).to_numpy(), "r2": t["r2"].to_numpy(float),
                        "rmse": t["rmse"].to_numpy(float)})
    roles = []
    for m in out["model"]:
        r = [name for name, mm in (("chosen", chosen), ("mean", mean_model), ("baseline", baseline_model))
             if m == mm]
        roles.append("+".join(r))
    out.insert(1, "role", roles)
    for name in ("mean", "baseline"):
        out[f"r2_minus_{name}"] = out["r2"] - float(ref[name]["r2"])
        out[f"beats_{name}"] = (out["rmse"] < float(ref[name]["rmse"]) * (1 - 1e-9)) & \
            (out["model"] != (mean_model if name == "mean" else baseline_model))
    out["beats_both"] = out["beats_mean"] & out["beats_baseline"]
    out = out.sort_values(["rmse", "model"], kind="stable").reset_index(drop=True)
    out.insert(0, "rank", np.arange(1, len(out) + 1))
    c = out[out["model"] == chosen].iloc[0]
    warning = ""
    if not bool(c["beats_both"]):
        lost = []
        for name, mm in (("mean", mean_model), ("baseline", baseline_model)):
            if not bool(c[f"beats_{name}"]):
                rr = ref[name]
                lost.append(f"the {'intercept-only mean' if name == 'mean' else 'simple baseline'} {mm} "
                            f"(R^2 {float(rr['r2']):.3f}, RMSE {float(rr['rmse']):.4f})")
        score = (f"section-grouped CV R^2 {float(c['r2']):.3f}, RMSE {float(c['rmse']):.4f} of the DFT pooled "
                 "over the prediction speeds")
        if chosen in (mean_model, baseline_model):
            what = "the intercept-only mean" if chosen == mean_model else \
                "the simple baseline (OLS on at most two texture parameters)"
            better = int((out["rmse"] < float(c["rmse"]) * (1 - 1e-9)).sum())
            others = [t_ for t_, mm in zip(lost, (mean_model, baseline_model)) if mm != chosen] \
                if len(lost) == 2 else []
            warning = (f"WARNING: the chosen model is {what} {chosen} itself ({score}): "
                       + (f"{better} model(s) of the comparison have a lower RMSE" if better else
                          "no other model of the comparison beats it")
                       + ("; it does not beat " + others[0] if others else ""))
        else:
            warning = (f"WARNING: the chosen model {chosen} ({score}) does not beat " + " nor ".join(lost)
                       + ": its predictions of friction at unseen sections are no better than that reference")
    out["warning"] = np.where(out["model"] == chosen, warning, "")
    out["note"] = [str((notes or {}).get(m, "")) for m in out["model"]]
    out.attrs["warning"] = warning
    return out


def baseline_notes(cv_predictions: pd.DataFrame) -> dict[str, str]:
    """For each model with a ``features`` column in ``cv_predictions`` (the ``ols2`` models): the columns chosen
    in the outer folds and in how many sections, e.g. ``"raw_Sq+micro_Vvc in 10 of 12 folds; ..."``."""
    if "features" not in cv_predictions.columns:
        return {}
    out = {}
    for m, t in cv_predictions.groupby("model", sort=False):
        f = t.drop_duplicates("section")["features"].dropna()
        if f.empty:
            continue
        counts = f.value_counts()
        out[str(m)] = "; ".join(f"{k} in {v} of {len(f)} folds" for k, v in counts.items())
    return out


# ---------------------------------------------------------------------------------------------------------
# The whole analysis, for the workflow
# ---------------------------------------------------------------------------------------------------------

@dataclass
class RegressionAnalysis:
    """Everything the regression rule writes (see :func:`run_analysis` and :func:`write_analysis`).

    ``table5``/``table6``/``statistics`` hold the PCA regressions fitted on the training sites with the
    configured rule and with the study's rule (column ``rule``); ``cv_predictions``/``cv_table``/``ranking``
    the leave-one-section-out comparison on all sites; ``best`` its winner; ``test_parameters`` the predicted
    friction parameters of the test sites (column ``model``) that the FE runs of Figure 11 take as input.
    """

    train_ids: list
    test_ids: list
    fits: dict
    study_fits: dict
    table5: pd.DataFrame
    table6: pd.DataFrame
    statistics: pd.DataFrame
    cv_predictions: pd.DataFrame
    cv_table: pd.DataFrame
    ranking: pd.DataFrame
    best: str
    test_parameters: pd.DataFrame
    skill: pd.DataFrame | None = None


def run_analysis(design: Design, *, n_train: int = 27, seed: int = 0, grouped_by: str | None = None,
                 rule: str = "cv", models: Sequence[str] = DEFAULT_MODELS, figure11_models: Sequence[str] = ("best",),
                 g: pd.DataFrame | None = None, measured_dft: pd.DataFrame | None = None,
                 speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH, criterion: str = "auto", inner_folds: int = 5,
                 selection: str = "one_se", workers: int = 1) -> RegressionAnalysis:
    """The study's analysis plus the honest comparison, on a :class:`Design` with friction.

    Split (:func:`split_sites`, ``grouped_by`` None or ``"section"``), PCA regression Tables 5 and 6 on the
    training sites (``rule`` and ``"study"``), leave-one-section-out CV of ``models`` on all sites, the best
    model by ``criterion`` (:func:`rank_models`) and, for each of ``figure11_models`` (``"best"`` = the
    winner, or any model name such as ``"pca:study"``), the predicted parameters of the test sites, fitted on
    the training sites. ``g``/``measured_dft`` as in :func:`score_predictions`. ``workers``: threads of the
    cross-validation (:func:`cross_validated_predictions`; same numbers for any value). The intercept-only
    :data:`MEAN_MODEL` and the baseline :data:`BASELINE_MODEL` are always cross-validated (appended to the CV
    when ``models`` lacks them): they are the references of the prediction-skill table (:func:`prediction_skill`,
    ``skill``). The best model is chosen among ``models`` only, so the references compete for it only when
    listed (the default configuration lists both).
    """
    if design.Y is None:
        raise InputError(None, "a friction table (mu_s, mu_k, alpha per site)", column="mu_s")
    sites = pd.DataFrame({"site": design.X.index.astype(str), "section": design.groups.to_numpy()})
    train, test = split_sites(sites, n_train, seed, grouped_by)
    Xtr, Ytr, gtr = design.X.loc[train], design.Y.loc[train], design.groups.loc[train]
    fits = fit_pca_tables(Xtr, Ytr, rule=rule, groups=gtr.to_numpy(), seed=seed, inner_folds=inner_folds,
                          selection=selection)
    study = fits if rule == "study" else fit_pca_tables(Xtr, Ytr, rule="study")
    parts5, parts6, stats = [], [], []
    for r, f in ((rule, fits), ("study", study)) if rule != "study" else (("study", study),):
        t5, t6, st = table5(f), table6(f), table5_statistics(f)
        t5.insert(0, "rule", r), t6.insert(0, "rule", r), st.insert(0, "rule_config", r)
        parts5.append(t5), parts6.append(t6), stats.append(st)
    listed = list(dict.fromkeys(models))
    compared = list(dict.fromkeys(listed + [MEAN_MODEL, BASELINE_MODEL]))
    dft = dft_targets(design.Y, measured_dft=measured_dft, g=g, speeds_kmh=speeds_kmh)
    cvp = cross_validated_predictions(design.X, design.Y, design.groups, compared, seed=seed,
                                      inner_folds=inner_folds, selection=selection, workers=workers, dft=dft, g=g)
    cvt = score_predictions(cvp, design.Y, g=g, measured_dft=measured_dft, speeds_kmh=speeds_kmh)
    ranking = rank_models(cvt[cvt["model"].isin(listed)], criterion)
    best = str(ranking["model"].iloc[0])
    skill = prediction_skill(cvt, best, notes=baseline_notes(cvp))
    preds = []
    for m in dict.fromkeys(best if m == "best" else m for m in figure11_models):
        p = predict_parameters(m, Xtr, Ytr, design.X.loc[test], groups_train=gtr.to_numpy(), seed=seed,
                               inner_folds=inner_folds, selection=selection, dft_train=dft.loc[train], g_test=g)
        p.insert(0, "model", m)
        p.insert(0, "site", p.index.astype(str))
        preds.append(p.reset_index(drop=True))
    return RegressionAnalysis(train, test, fits, study, pd.concat(parts5, ignore_index=True),
                              pd.concat(parts6, ignore_index=True), pd.concat(stats, ignore_index=True), cvp, cvt,
                              ranking, best, pd.concat(preds, ignore_index=True), skill)


def _write_csv(df: pd.DataFrame, path) -> None:
    from pathlib import Path

    from skidsim.runlog import write_csv

    write_csv(path, df)


def write_analysis(analysis: RegressionAnalysis, directory) -> dict:
    """Write the analysis as CSV files (atomically: temporary name, then rename) into ``directory``.

    Files: split.csv, table5.csv, table5_statistics.csv, table6.csv, cv_predictions.csv, cv_table.csv,
    cv_ranking.csv, test_parameters.csv, prediction_skill.csv (when ``analysis.skill`` is set),
    best_model.txt. Returns {name: path}.
    """
    from pathlib import Path

    d = Path(directory)
    split = pd.DataFrame({"site": analysis.train_ids + analysis.test_ids,
                          "set": ["train"] * len(analysis.train_ids) + ["test"] * len(analysis.test_ids)})
    out = {"split": split, "table5": analysis.table5, "table5_statistics": analysis.statistics,
           "table6": analysis.table6, "cv_predictions": analysis.cv_predictions, "cv_table": analysis.cv_table,
           "cv_ranking": analysis.ranking, "test_parameters": analysis.test_parameters}
    if analysis.skill is not None:
        out["prediction_skill"] = analysis.skill
    paths = {}
    for name, df in out.items():
        paths[name] = d / f"{name}.csv"
        _write_csv(df, paths[name])
    p = d / "best_model.txt"
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(analysis.best + "\n")
    tmp.replace(p)
    paths["best_model"] = p
    return paths
