"""The study's PCA regression of one friction parameter (Tables 5 and 6): :func:`fit_pca_regression`.

* **PCA**: SVD of the standardised training matrix (:mod:`.standardiser`); components ordered by variance; the
  sign of each component is fixed so that its largest-magnitude loading is positive. Only components with a
  singular value above ``1e-10 * max(n, p) * s_max`` count (numerical rank).
* **Component retention** (``rule``), ``k_max = min(rank, n - 3)`` (at least 2 residual degrees of freedom):
  ``"cv"`` (default) the number 0..k_max chosen by an inner cross-validation (leave-one-group-out when groups
  are given, else seeded 5-fold; the standardisation and PCA are refitted in every inner fold) with the
  one-standard-error rule (:mod:`.paths`); ``"study"`` the largest k for which all k component coefficients
  have p < 0.05 (the study's reading: it kept 17 components for n = 27, an overfit that the in-sample adjusted
  R-squared cannot reveal); ``"kaiser"`` eigenvalues > 1; ``"variance:F"`` the fewest components whose
  cumulative share of variance reaches F (e.g. ``"variance:0.9"``). ``n_components=`` overrides the rule.
  ``"cv"`` is the default because it is the only rule that judges components by how well they predict sites the
  fit has not seen; ``"kaiser"``/``"variance"`` ignore the target and ``"study"`` uses in-sample p-values.
* **Back-transformation (Table 6)**: with loadings ``V_k`` and OLS coefficients ``b`` on the component scores,
  ``beta_per_sd = V_k b`` (friction per one training SD of each column) and ``beta = beta_per_sd / sd`` (friction
  per unit of the column), intercept ``b0 - sum(beta * mean)``. Standard errors are propagated exactly through
  this linear map from the OLS covariance.
* **Significance stars** as in the study's Table 5: ``*`` p < 0.05, ``**`` p < 0.01, ``***`` p < 0.001.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .design import split_band
from .paths import select_on_path
from .splits import inner_splits
from .standardiser import MAX_NAN_FRACTION, Standardiser


def significance_stars(p: float) -> str:
    """Stars of the study's Table 5: ``***`` p < 0.001, ``**`` p < 0.01, ``*`` p < 0.05, else ``""``."""
    if not np.isfinite(p):
        return ""
    return "***" if p < 0.001 else "**" if p < 0.01 else "*" if p < 0.05 else ""


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


def pcr_path_predictions(Ztr: np.ndarray, ytr: np.ndarray, Zte: np.ndarray, grid) -> np.ndarray:
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
        return {
            "target": self.target,
            "n": self.n,
            "n_components": self.n_components,
            "rule": self.rule,
            "r2": float(r.rsquared),
            "adj_r2": float(r.rsquared_adj),
            "rse": float(np.sqrt(r.scale)),
            "df_resid": float(r.df_resid),
            "f_pvalue": float(r.f_pvalue) if self.n_components else float("nan"),
        }

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
            rows.append(
                {
                    "target": self.target,
                    "component": "Intercept" if i == 0 else f"PC{i}",
                    "coefficient": params[i],
                    "std_error": bse[i],
                    "t_value": tv[i],
                    "p_value": pv[i],
                    "stars": significance_stars(pv[i]),
                    "explained_variance": float("nan") if i == 0 else float(share[i - 1]),
                }
            )
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
        return pd.DataFrame(
            {
                "target": self.target,
                "variable": names,
                "band": [b for b, _ in bands],
                "parameter": [q for _, q in bands],
                "coefficient": c,
                "std_error": se,
                "p_value": pv,
                "coefficient_per_sd": per_sd,
            }
        )


def parse_rule(rule: str) -> tuple[str, float | None]:
    """``(kind, F)`` of a retention rule: ``"cv"``, ``"study"``, ``"kaiser"`` (F None) or ``"variance:F"``."""
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


def _study_components(Z: np.ndarray, V: np.ndarray, yv: np.ndarray, k_max: int) -> int:
    """The study's rule: the largest k <= ``k_max`` for which all k component coefficients have p < 0.05."""
    k = 0
    for kk in range(1, k_max + 1):
        r = _ols(Z @ V[:, :kk], yv)
        if np.all(np.asarray(r.pvalues)[1:] < 0.05):
            k = kk
    return k


def _cv_components(
    X: pd.DataFrame,
    yv: np.ndarray,
    k_max: int,
    groups,
    seed: int,
    inner_folds: int,
    selection: str,
    max_nan_fraction: float,
) -> tuple[int, np.ndarray]:
    """The ``"cv"`` rule: the number of components chosen by inner CV, and the inner MSE per number."""
    splits = inner_splits(len(yv), groups, seed=seed, n_folds=inner_folds)
    n_inner = min(len(tr) for tr, _ in splits)
    k_cv = max(0, min(k_max, n_inner - 3))
    return select_on_path(
        X.to_numpy(dtype=float), yv, splits, pcr_path_predictions, np.arange(k_cv + 1), max_nan_fraction, selection
    )


def fit_pca_regression(
    X: pd.DataFrame,
    y: pd.Series,
    *,
    rule: str = "cv",
    n_components: int | None = None,
    groups=None,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
    max_nan_fraction: float = MAX_NAN_FRACTION,
) -> PCARegression:
    """PCA regression of ``y`` on the features ``X`` (rows aligned), with the retention ``rule``.

    ``groups`` (one label per row, e.g. section) makes the ``"cv"`` rule's inner CV leave-one-group-out;
    ``seed`` drives the shuffled K-fold otherwise. ``n_components`` (0..min(rank, n-2)) overrides the rule.
    """
    if len(X) != len(y):
        raise InputError(None, f"one target value per feature row ({len(X)})", column=str(y.name), got=len(y))
    yv = np.asarray(y, dtype=float)
    if not np.all(np.isfinite(yv)):
        raise InputError(None, "finite target values", column=str(y.name))
    kind, frac = parse_rule(rule)
    n = len(yv)
    st = Standardiser.fit(X, max_nan_fraction)
    Z = st.transform(X)
    V, s = _pca(Z)
    eig = s**2 / (n - 1)
    rank = V.shape[1]
    k_max = max(0, min(rank, n - 3))
    cv_mse = None
    if n_components is not None:
        if not (0 <= int(n_components) <= min(rank, n - 2)):
            raise InputError(
                None,
                f"n_components between 0 and {min(rank, n - 2)} (rank {rank}, n {n})",
                column="n_components",
                got=n_components,
            )
        k = int(n_components)
        rule = f"fixed:{k}"
    elif kind == "kaiser":
        k = min(int(np.sum(eig > 1.0)), k_max)
    elif kind == "variance":
        cum = np.cumsum(eig) / eig.sum()
        k = min(int(np.searchsorted(cum, frac - 1e-12) + 1), k_max)
    elif kind == "study":
        k = _study_components(Z, V, yv, k_max)
    else:
        k, cv_mse = _cv_components(X, yv, k_max, groups, seed, inner_folds, selection, max_nan_fraction)
    ols = _ols(Z @ V[:, :k], yv)
    return PCARegression(
        target=str(y.name), rule=rule, standardiser=st, loadings=V[:, :k], eigenvalues=eig, ols=ols, n=n, cv_mse=cv_mse
    )


def fit_pca_tables(
    X: pd.DataFrame, Y: pd.DataFrame, *, rule: str = "cv", groups=None, seed: int = 0, **kw
) -> dict[str, PCARegression]:
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
