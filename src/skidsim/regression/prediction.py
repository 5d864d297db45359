"""Predictions of held-out sites by a named model: :func:`predict_parameters` (friction parameters, the FE input)
and :func:`predict_targets` (any curve targets in one unit)."""

from __future__ import annotations

import pandas as pd

from skidsim.errors import InputError

from .design import PARAMETERS
from .models import CURVE_SUFFIX, DFT_SUFFIX, fit_model
from .physics import PHYSICS_OLS, fit_physics_ols
from .subset import SUBSET_OLS, fit_subset_ols
from .targets import curve_targets, dft_speeds, g_values, law_from_curve, law_from_dft


def predict_targets(
    base: str,
    X_train: pd.DataFrame,
    T_train: pd.DataFrame,
    X_test: pd.DataFrame,
    *,
    groups_train=None,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
) -> tuple[pd.DataFrame, str | None]:
    """Predict every column of ``T_train`` (curve values in one unit) at the test rows with model ``base``.

    ``"ols2"`` chooses one subset of at most two texture columns for all columns together (the pooled inner SSE,
    :func:`~.subset.fit_subset_ols`) and returns its label; any other model is fitted per column (its own
    hyper-parameters) and the label is None. Returns (predictions indexed like ``X_test`` with the columns of
    ``T_train``, label).
    """
    if base == SUBSET_OLS:
        m = fit_subset_ols(X_train, T_train, groups=groups_train, seed=seed, inner_folds=inner_folds)
        return m.predict(X_test), m.label
    if base == PHYSICS_OLS:
        m = fit_physics_ols(X_train, T_train, groups=groups_train, seed=seed, inner_folds=inner_folds)
        return m.predict(X_test), m.label
    out = {}
    for c in T_train.columns:
        m = fit_model(
            base, X_train, T_train[c], groups=groups_train, seed=seed, inner_folds=inner_folds, selection=selection
        )
        out[c] = m.predict(X_test).to_numpy()
    return pd.DataFrame(out, index=X_test.index), None


def _law_frame(laws, X_test: pd.DataFrame, Y_train: pd.DataFrame) -> pd.DataFrame:
    """The (mu_s, mu_k, alpha s/m) rows ``laws`` as a frame indexed like ``X_test``, columns those of ``Y_train``."""
    return pd.DataFrame(laws, index=X_test.index, columns=list(PARAMETERS))[
        [c for c in Y_train.columns if c in PARAMETERS]
    ]


def _predict_curve(base: str, X_train, Y_train, X_test, fit_kw: dict) -> pd.DataFrame:
    """``<base>@curve``: predict the laws' values at the curve anchors, then the law through them."""
    C, features = predict_targets(base, X_train, curve_targets(Y_train), X_test, **fit_kw)
    out = _law_frame([law_from_curve(row) for row in C.to_numpy(dtype=float)], X_test, Y_train)
    if features is not None:
        out["features"] = features
    return out


def _predict_dft(base: str, X_train, Y_train, X_test, dft_train: pd.DataFrame, g_test, fit_kw: dict) -> pd.DataFrame:
    """``<base>@dft``: predict the DFT at its speeds, then the bounded law whose ``g * mu(v)`` is closest."""
    D = dft_train.loc[X_train.index]
    C, features = predict_targets(base, X_train, D, X_test, **fit_kw)
    speeds = dft_speeds(D)
    laws = []
    for site, row in zip(X_test.index, C.to_numpy(dtype=float)):
        gv = None if g_test is None else g_values(g_test, str(site), speeds)
        laws.append(law_from_dft(row, speeds, gv))
    out = _law_frame(laws, X_test, Y_train)
    for c in C.columns:
        out[c] = C[c].to_numpy()
    if features is not None:
        out["features"] = features
    return out


def _predict_subset_parameters(base: str, X_train, Y_train, X_test, fit_kw: dict) -> pd.DataFrame:
    """``ols2`` or ``physics2`` on the parameters (each in its own unit): a column subset or form per parameter
    (:func:`predict_targets` shares one over columns in one unit)."""
    out, features = {}, {}
    for c in Y_train.columns:
        m = fit_model(
            base,
            X_train,
            Y_train[c],
            groups=fit_kw["groups_train"],
            seed=fit_kw["seed"],
            inner_folds=fit_kw["inner_folds"],
            selection=fit_kw["selection"],
        )
        out[c] = m.predict(X_test).to_numpy()
        features[c] = m.hyper["features"]
    out = pd.DataFrame(out, index=X_test.index)
    out["features"] = "; ".join(f"{c}: {f}" for c, f in features.items())
    return out


def predict_parameters(
    model_name: str,
    X_train: pd.DataFrame,
    Y_train: pd.DataFrame,
    X_test: pd.DataFrame,
    *,
    groups_train=None,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
    dft_train: pd.DataFrame | None = None,
    g_test: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Fit ``model_name`` on the training sites, one model per column of ``Y_train`` (``mu_s``, ``mu_k``,
    ``alpha`` s/m), and predict the test sites. Returns a frame indexed like ``X_test``, columns of ``Y_train``.

    ``<model>@curve`` (e.g. ``ridge@curve``): the targets are the laws' friction values at
    :data:`~.targets.CURVE_ANCHORS_KMH` (:func:`~.targets.curve_targets`), each predicted by ``<model>``; the
    predicted values are turned back into (mu_s, mu_k, alpha) by :func:`~.targets.law_from_curve`. Why: the
    back-calculated parameters are not identified by a DFT curve over 20-60 km/h (a nearly straight curve is
    fitted as well by a high mu_k with a fast decay as by mu_k = 0 with a slow one), so per-parameter regressions
    average incompatible parameter sets and the law of the averaged parameters is not the average curve
    (docs/regression.md, "Curve targets").

    ``<model>@dft`` (e.g. ``ridge@dft``, the baseline ``ols2@dft``): the targets are the DFT of the training
    sites at the prediction speeds, ``dft_train`` (:func:`~.targets.dft_targets`: the measured DFT, not the
    calibrated laws, so neither the back-calculation nor the FE stands between texture and target); the result
    also has the predicted ``dft@<v>`` columns, which the CV table scores directly, and parameters of the bounded
    law whose ``g * mu(v)`` is closest to them (:func:`~.targets.law_from_dft`, ``g_test`` the test sites' g, None
    for 1), the FE input of Figure 11. Models ``ols2``/``ols2@...`` add a column ``features`` naming the chosen
    columns.
    """
    if len(X_train) != len(Y_train):
        raise InputError(None, f"one friction row per training site ({len(X_train)})", got=len(Y_train))
    fit_kw = dict(groups_train=groups_train, seed=seed, inner_folds=inner_folds, selection=selection)
    if model_name.endswith(CURVE_SUFFIX):
        return _predict_curve(model_name[: -len(CURVE_SUFFIX)], X_train, Y_train, X_test, fit_kw)
    if model_name.endswith(DFT_SUFFIX):
        if dft_train is None:
            raise InputError(None, f"DFT targets of the training sites for model {model_name!r}", column="dft")
        return _predict_dft(model_name[: -len(DFT_SUFFIX)], X_train, Y_train, X_test, dft_train, g_test, fit_kw)
    if model_name not in (SUBSET_OLS, PHYSICS_OLS):
        return predict_targets(model_name, X_train, Y_train, X_test, **fit_kw)[0]
    return _predict_subset_parameters(model_name, X_train, Y_train, X_test, fit_kw)
