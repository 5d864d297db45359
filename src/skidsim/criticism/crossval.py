"""Cross-validated evidence of a candidate: the out-of-section SSE of the residual model without and with it
(leave-one-section-out folds; one site of every section held out for section-nested categoricals)."""

from __future__ import annotations

import numpy as np
import pandas as pd


def folds(sections: np.ndarray, nested: bool) -> np.ndarray:
    """Fold id per site: the section (leave-one-section-out), or for section-nested categoricals the site's rank
    within its section (each fold holds out one site of every section)."""
    if not nested:
        return np.unique(sections, return_inverse=True)[1]
    rank = pd.Series(np.arange(len(sections))).groupby(sections).cumcount().to_numpy()
    return rank


def is_section_nested(values: pd.Series | np.ndarray, sections: np.ndarray) -> bool:
    """Whether every level of the categorical ``values`` lies within one section."""
    return bool((pd.Series(sections).groupby(np.asarray(values)).nunique() == 1).all())


def _candidate_design(values: pd.Series, dtype: str) -> np.ndarray:
    """Numeric: the column itself; categorical: indicators of the levels but the first."""
    if dtype == "numeric":
        return values.to_numpy(float)[:, None]
    lab = values.to_numpy(str)
    return np.stack([lab == g for g in np.unique(lab)[1:]], axis=1).astype(float)


def _cv_sse_nuisance(Y, values, dtype, fold, nuisance) -> tuple[float, float]:
    Z = _candidate_design(values, dtype)
    X0 = np.c_[np.ones(len(Y)), nuisance]
    sse = [0.0, 0.0]
    for f in np.unique(fold):
        te, tr = fold == f, fold != f
        for j, X in enumerate((X0, np.c_[X0, Z])):
            cols = np.abs(X[tr]).sum(axis=0) > 0  # a categorical level absent from training drops out
            beta, *_ = np.linalg.lstsq(X[tr][:, cols], Y[tr], rcond=None)
            sse[j] += float(((Y[te] - X[te][:, cols] @ beta) ** 2).sum())
    return sse[0], sse[1]


def _fold_prediction(Y, values, dtype, te, tr, mean_tr) -> np.ndarray:
    """Held-out prediction of the residual model with the candidate: OLS on [1, z] or training group means."""
    if dtype == "numeric":
        z = values.to_numpy(float)
        beta, *_ = np.linalg.lstsq(np.c_[np.ones(tr.sum()), z[tr]], Y[tr], rcond=None)
        return np.c_[np.ones(te.sum()), z[te]] @ beta
    lab = values.to_numpy(str)
    pred = np.tile(mean_tr, (te.sum(), 1))
    for j, level in enumerate(lab[te]):
        m = tr & (lab == level)
        if m.any():
            pred[j] = Y[m].mean(axis=0)
    return pred


def cv_sse(
    Y: np.ndarray, values: pd.Series | None, dtype: str, fold: np.ndarray, nuisance: np.ndarray | None = None
) -> tuple[float, float]:
    """Cross-validated SSE of the residual model without and with the candidate.

    Without: training column means. With: numeric -> per-column OLS on [1, z]; categorical -> training group
    means (a level unseen in training -> training mean). ``values=None`` is the functional-form test: without = 0,
    with = training column means. ``nuisance`` (n, k) columns (texture PC scores of the texture-adjusted test)
    enter both models: without = OLS on [1, nuisance], with = OLS on [1, nuisance, candidate] (categorical:
    indicators of the training levels but the first; an unseen level gets none).
    """
    if nuisance is not None and values is not None:
        return _cv_sse_nuisance(Y, values, dtype, fold, nuisance)
    sse0 = sse1 = 0.0
    for f in np.unique(fold):
        te, tr = fold == f, fold != f
        mean_tr = Y[tr].mean(axis=0)
        if values is None:
            sse0 += float((Y[te] ** 2).sum())
            sse1 += float(((Y[te] - mean_tr) ** 2).sum())
            continue
        sse0 += float(((Y[te] - mean_tr) ** 2).sum())
        sse1 += float(((Y[te] - _fold_prediction(Y, values, dtype, te, tr, mean_tr)) ** 2).sum())
    return sse0, sse1


def cv_sse_design(Y: np.ndarray, Z: np.ndarray, fold: np.ndarray) -> tuple[float, float]:
    """Cross-validated SSE (mu^2) of the residual model without (training column means) and with a multi-column
    design ``Z`` (n, q) (OLS on ``[1, Z]`` fitted on the training folds): the texture-model candidate."""
    sse0 = sse1 = 0.0
    for f in np.unique(fold):
        te, tr = fold == f, fold != f
        sse0 += float(((Y[te] - Y[tr].mean(axis=0)) ** 2).sum())
        X = np.c_[np.ones(len(Y)), Z]
        beta, *_ = np.linalg.lstsq(X[tr], Y[tr], rcond=None)
        sse1 += float(((Y[te] - X[te] @ beta) ** 2).sum())
    return sse0, sse1
