"""Model paths: predictions of a whole grid of hyper-parameters from one fit, and their choice by inner CV.

* **Hyper-parameters** of ridge (penalty), lasso (penalty), PLS (number of components) and the PCA regression's
  ``"cv"`` rule (number of components) are chosen by inner cross-validation on the training rows of each fit
  (nested in a cross-validation: the outer test section is never seen, not even by the scaler, which is refitted
  in every inner fold). ``selection="one_se"`` (default, Hastie et al. ESL 7.10): the most regularised grid
  value whose pooled inner MSE is within one standard error (SD of the per-fold MSEs at the minimum over
  sqrt(folds)) of the minimum; ``"min"``: the minimum. Exact ties go to the more regularised model.
* **Lasso path iterations**: the inner-CV lasso path stops each grid value's coordinate descent after
  :data:`LASSO_PATH_MAX_ITER` (1,000, scikit-learn's default for ``Lasso``) sweeps at ``tol`` 1e-4 (warm start along
  the path); the final fit at the chosen penalty keeps :data:`LASSO_MAX_ITER` (5,000). Only the least regularised
  grid values (ratios below about 1e-1.5 of ``alpha_max``, 30 rows x 121 collinear texture columns) reach the cap;
  on the default campaign the inner-CV choice, every CV prediction and every table are identical to 5,000 sweeps
  (0.0 difference; 2026-11-29, commit after 80089eb) and the regression rule costs 36 CPU s instead of 90.
* **Grids**: ridge penalty 1e-2..1e4 (31, log, :data:`RIDGE_ALPHAS`), lasso ``alpha_max * 10**(0..-2.5)`` (26,
  :data:`LASSO_ALPHA_RATIOS`), PLS 1..min(10, p, n_inner-2) components (:data:`PLS_MAX_COMPONENTS`).
"""

from __future__ import annotations

import warnings

import numpy as np

from skidsim.errors import InputError

from .standardiser import standardise_split

RIDGE_ALPHAS = np.logspace(-2, 4, 31)
LASSO_ALPHA_RATIOS = np.logspace(0, -2.5, 26)
LASSO_MAX_ITER = 5000
#: Coordinate-descent sweeps per grid value of the inner-CV lasso path (scikit-learn's ``Lasso`` default).
LASSO_PATH_MAX_ITER = 1000
LASSO_TOL = 1e-4
PLS_MAX_COMPONENTS = 10
#: Relative tie-break of the inner-CV minimum: exact ties go to the grid value listed first (simpler).
_TIE = 1e-12


def ridge_path_predictions(Ztr: np.ndarray, ytr: np.ndarray, Zte: np.ndarray, alphas) -> np.ndarray:
    """Ridge predictions ``(n_te, n_alphas)`` for standardised (centred) ``Ztr``; objective of sklearn ``Ridge``
    (``||y - ym - Z w||^2 + alpha ||w||^2``, intercept unpenalised), all penalties from one SVD."""
    ym = ytr.mean()
    U, s, vt = np.linalg.svd(Ztr, full_matrices=False)
    uty = U.T @ (ytr - ym)
    d = s[:, None] / (s[:, None] ** 2 + np.asarray(alphas, float)[None, :])
    W = vt.T @ (d * uty[:, None])
    return ym + Zte @ W


def lasso_path_predictions(Ztr: np.ndarray, ytr: np.ndarray, Zte: np.ndarray, alphas) -> np.ndarray:
    """Lasso predictions ``(n_te, n_alphas)`` (sklearn objective ``||y - Zw||^2 / (2n) + alpha |w|_1``)."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.linear_model import lasso_path

    ym = ytr.mean()
    zm = Ztr.mean(axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        _, coefs, _ = lasso_path(
            Ztr - zm, ytr - ym, alphas=np.asarray(alphas), max_iter=LASSO_PATH_MAX_ITER, tol=LASSO_TOL
        )
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


def select_on_path(A: np.ndarray, y: np.ndarray, splits, fn, grid, max_nan_fraction: float, selection: str):
    """Inner CV of a model path: index into ``grid`` (ordered simplest / most regularised first) and the pooled
    MSE per grid value. ``selection="one_se"``: the first grid value whose pooled MSE is within one standard
    error (SD of the per-fold MSEs at the minimum / sqrt(folds)) of the minimum; ``"min"``: the minimum."""
    if selection not in ("one_se", "min"):
        raise InputError(None, "selection 'one_se' or 'min'", column="selection", got=selection)
    fold_sse = np.zeros((len(splits), len(grid)))
    fold_n = np.zeros(len(splits))
    for i, (tr, te) in enumerate(splits):
        Ztr, Zte = standardise_split(A, tr, te, max_nan_fraction)
        pred = fn(Ztr, y[tr], Zte, grid)
        fold_sse[i] = ((pred - y[te, None]) ** 2).sum(axis=0)
        fold_n[i] = len(te)
    mse = fold_sse.sum(axis=0) / fold_n.sum()
    i_min = int(np.argmin(mse + _TIE * np.arange(len(grid)) * max(float(np.max(mse)), 1e-300)))
    if selection == "min" or len(splits) < 2:
        return i_min, mse
    se = float(np.std(fold_sse[:, i_min] / fold_n, ddof=1) / np.sqrt(len(splits)))
    return int(np.flatnonzero(mse <= mse[i_min] + se)[0]), mse
