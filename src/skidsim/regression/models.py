"""The models of the comparison, each fitted on one target: :func:`fit_model`.

``"mean"`` (training mean), ``"pca"``/``"pca:<rule>"`` (:mod:`.pca`), ``"ridge"``, ``"lasso"``, ``"pls"``
(hyper-parameters by inner CV, :mod:`.paths`), ``"two_variable"`` (OLS on ``profile_MPD`` and ``micro_Sq`` in their
own units, NaN imputed with the training medians) and ``"ols2"`` (:mod:`.subset`). A name may carry the suffix
``@curve`` or ``@dft`` (:func:`skidsim.regression.predict_parameters`): the same model fitted on other targets.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .paths import (
    LASSO_ALPHA_RATIOS,
    LASSO_MAX_ITER,
    LASSO_TOL,
    PLS_MAX_COMPONENTS,
    RIDGE_ALPHAS,
    lasso_path_predictions,
    pls_path_predictions,
    ridge_path_predictions,
    select_on_path,
)
from .pca import _ols, fit_pca_regression, parse_rule
from .physics import PHYSICS_OLS, fit_physics_ols
from .splits import inner_splits
from .standardiser import MAX_NAN_FRACTION, Standardiser
from .subset import SUBSET_OLS, fit_subset_ols

#: The two-variable model's columns: MPD (mm) and micro-band Sq (mm).
TWO_VARIABLES = ("profile_MPD", "micro_Sq")
#: Models compared by :func:`skidsim.regression.cross_validate_models` by default ("pca" uses the "cv" rule,
#: "pca:study" the study's).
DEFAULT_MODELS = ("mean", "pca", "pca:study", "ridge", "pls", "lasso", "two_variable")
#: Suffix of a model fitted on curve targets (see :func:`skidsim.regression.predict_parameters`), e.g.
#: ``"ridge@curve"``.
CURVE_SUFFIX = "@curve"
#: Suffix of a model fitted on the DFT itself (see :func:`skidsim.regression.predict_parameters`), e.g.
#: ``"ridge@dft"``: the targets are each training site's DFT reference (the measured DFT when given) at the
#: prediction speeds.
DFT_SUFFIX = "@dft"
#: Base model names besides ``pca:<rule>``.
BASE_MODELS = ("mean", SUBSET_OLS, PHYSICS_OLS, "pca", "ridge", "lasso", "pls", "two_variable")
_PENALISED = ("ridge", "lasso", "pls")
_NAMES = (
    "a model name: mean, ols2, physics2, pca, pca:<rule>, ridge, lasso, pls, two_variable (optionally with @curve or"
    " @dft)"
)


def check_model_name(name: str, file=None, column: str = "models") -> str:
    """``name`` if it names a model (a base model, optionally ``@curve``/``@dft``), else InputError naming
    ``file`` and ``column``."""
    base = str(name)
    for suffix in (CURVE_SUFFIX, DFT_SUFFIX):
        base = base.removesuffix(suffix)
    if base.startswith("pca:"):
        try:
            parse_rule(base[4:])
        except InputError:
            raise InputError(
                file, _NAMES + " with a retention rule cv, study, kaiser or variance:F", column=column, got=name
            ) from None
    elif base not in BASE_MODELS:
        raise InputError(file, _NAMES, column=column, got=name)
    return str(name)


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
        elif self.name in (SUBSET_OLS, PHYSICS_OLS):
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


def _fit_two_variable(X: pd.DataFrame, yv: np.ndarray, target: str) -> FittedModel:
    """OLS on :data:`TWO_VARIABLES` in their own units, NaN imputed with the training medians."""
    missing = [c for c in TWO_VARIABLES if c not in X.columns]
    if missing:
        raise InputError(None, "the two-variable model's columns " + ", ".join(TWO_VARIABLES), column=missing[0])
    A = X.loc[:, list(TWO_VARIABLES)].to_numpy(dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(A, axis=0)
    if np.any(np.isnan(med)):
        raise InputError(None, "values of the two-variable model's columns", column="profile_MPD/micro_Sq")
    A = np.where(np.isnan(A), med, A)
    return FittedModel("two_variable", target, None, _ols(A, yv), {"medians": med})


def _path_grid(name: str, Z: np.ndarray, yv: np.ndarray, splits):
    """The hyper-parameter grid of a penalised model (most regularised first) and its path function."""
    if name == "ridge":
        return RIDGE_ALPHAS[::-1], ridge_path_predictions
    if name == "lasso":
        amax = np.max(np.abs(Z.T @ (yv - yv.mean()))) / len(yv)
        return max(amax, 1e-12) * LASSO_ALPHA_RATIOS, lasso_path_predictions
    n_inner = min(len(tr) for tr, _ in splits)
    return np.arange(1, max(1, min(PLS_MAX_COMPONENTS, Z.shape[1], n_inner - 2)) + 1), pls_path_predictions


def _fit_estimator(name: str, best, Z: np.ndarray, yv: np.ndarray) -> tuple[object, dict]:
    """The sklearn estimator of a penalised model at the chosen hyper-parameter ``best``."""
    from sklearn.cross_decomposition import PLSRegression
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.linear_model import Lasso, Ridge

    if name == "ridge":
        return Ridge(alpha=float(best)).fit(Z, yv), {"alpha": float(best)}
    if name == "lasso":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            est = Lasso(alpha=float(best), max_iter=LASSO_MAX_ITER, tol=LASSO_TOL).fit(Z, yv)
        return est, {"alpha": float(best), "n_nonzero": int(np.sum(est.coef_ != 0))}
    return PLSRegression(n_components=int(best), scale=False).fit(Z, yv), {"n_components": int(best)}


def _fit_penalised(
    name: str,
    X: pd.DataFrame,
    yv: np.ndarray,
    target: str,
    groups,
    seed: int,
    inner_folds: int,
    selection: str,
    max_nan_fraction: float,
) -> FittedModel:
    """Ridge, lasso or PLS on the standardised features, the hyper-parameter by inner CV on these rows."""
    st = Standardiser.fit(X, max_nan_fraction)
    Z = st.transform(X)
    splits = inner_splits(len(yv), groups, seed=seed, n_folds=inner_folds)
    grid, fn = _path_grid(name, Z, yv, splits)
    i, mse = select_on_path(X.to_numpy(dtype=float), yv, splits, fn, grid, max_nan_fraction, selection)
    est, hyper = _fit_estimator(name, grid[i], Z, yv)
    hyper["grid"] = np.asarray(grid)
    hyper["inner_mse"] = mse
    return FittedModel(name, target, st, est, hyper)


def fit_model(
    name: str,
    X: pd.DataFrame,
    y: pd.Series,
    *,
    groups=None,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
    max_nan_fraction: float = MAX_NAN_FRACTION,
):
    """Fit model ``name`` on one target; hyper-parameters by inner CV on these rows only.

    ``name``: ``"mean"`` (training mean), ``"pca"`` (rule ``"cv"``), ``"pca:<rule>"`` (e.g. ``"pca:study"``,
    ``"pca:kaiser"``, ``"pca:variance:0.9"``), ``"ridge"``, ``"lasso"``, ``"pls"``, ``"two_variable"`` (OLS on
    ``profile_MPD`` and ``micro_Sq``, NaN imputed with training medians), ``"ols2"`` (OLS on at most two texture
    columns chosen by inner CV, :func:`fit_subset_ols`). ``groups`` (one label per row) makes the
    inner CV leave-one-group-out; ``selection`` ``"one_se"`` or ``"min"`` (:mod:`.paths`). Returns an
    object with ``predict(X) -> Series`` (:class:`~.pca.PCARegression` or :class:`FittedModel`).
    """
    yv = np.asarray(y, dtype=float)
    if len(yv) != len(X):
        raise InputError(None, f"one target value per feature row ({len(X)})", column=str(y.name), got=len(yv))
    if not np.all(np.isfinite(yv)):
        raise InputError(None, "finite target values", column=str(y.name))
    target = str(y.name)
    if name == "pca" or name.startswith("pca:"):
        rule = "cv" if name == "pca" else name[4:]
        return fit_pca_regression(
            X,
            y,
            rule=rule,
            groups=groups,
            seed=seed,
            inner_folds=inner_folds,
            selection=selection,
            max_nan_fraction=max_nan_fraction,
        )
    if name == "mean":
        return FittedModel(name, target, None, float(yv.mean()), {})
    if name == SUBSET_OLS:
        est = fit_subset_ols(
            X,
            pd.DataFrame({target: yv}, index=X.index),
            groups=groups,
            seed=seed,
            inner_folds=inner_folds,
            max_nan_fraction=max_nan_fraction,
        )
        return FittedModel(name, target, None, est, {"features": est.label})
    if name == PHYSICS_OLS:
        est = fit_physics_ols(
            X, pd.DataFrame({target: yv}, index=X.index), groups=groups, seed=seed, inner_folds=inner_folds
        )
        return FittedModel(name, target, None, est, {"features": est.label})
    if name == "two_variable":
        return _fit_two_variable(X, yv, target)
    if name not in _PENALISED:
        raise InputError(None, _NAMES, column="models", got=name)
    return _fit_penalised(name, X, yv, target, groups, seed, inner_folds, selection, max_nan_fraction)
