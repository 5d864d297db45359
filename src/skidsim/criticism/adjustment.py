"""Designs of the screening tests: a candidate's orthonormal basis, the texture nuisance design of the
texture-adjusted between-site tests (Frisch-Waugh, Freedman & Lane 1983) and the added-variable data of a cause
found that way (docs/model-criticism.md, section 2, "Texture-adjusted tests")."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .covariates import DEFAULT_EXCLUDE, scores_for, site_covariates
from .residuals import level_matrix


def basis(values: pd.Series, dtype: str) -> np.ndarray:
    """Orthonormal basis (n, q) of the centred design of one covariate."""
    if dtype == "numeric":
        z = values.to_numpy(float)[:, None]
    else:
        z = pd.get_dummies(values.astype(str)).to_numpy(float)
    z = z - z.mean(axis=0)
    q, r = np.linalg.qr(z)
    keep = np.abs(np.diag(r)) > 1e-9 * max(1.0, np.abs(r).max())
    return q[:, keep]


def residualise(A: np.ndarray, N: np.ndarray) -> np.ndarray:
    """A minus its least-squares projection on the columns of N."""
    beta, *_ = np.linalg.lstsq(N, A, rcond=None)
    return A - N @ beta


def adjusted_basis(B: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the part of a candidate's basis B orthogonal to the nuisance N (Frisch-Waugh); columns
    that the texture spans (relative norm < 1e-6) are dropped."""
    Bt = residualise(B, N)
    if Bt.shape[1] == 0:
        return Bt
    Qb, Rb = np.linalg.qr(Bt)
    ok = np.abs(np.diag(Rb)) > 1e-6 * max(1.0, float(np.linalg.norm(B, axis=0).max()))
    return Qb[:, ok]


def _loso_sse(M: np.ndarray, X: np.ndarray, folds: np.ndarray, n_sec: int) -> float:
    """Leave-one-section-out SSE of the least-squares fit of M on X."""
    sse = 0.0
    for f in range(n_sec):
        te = folds == f
        beta, *_ = np.linalg.lstsq(X[~te], M[~te], rcond=None)
        sse += float(((M[te] - X[te] @ beta) ** 2).sum())
    return sse


def texture_adjustment(
    M: np.ndarray, scores: np.ndarray, sections: np.ndarray, k_max: int | None = None, variance_share: float = 0.9
) -> tuple[int, np.ndarray, int]:
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
        sse = _loso_sse(M, np.c_[np.ones(n), scores[:, :k]], folds, n_sec)
        if sse < best * (1 - 1e-12):
            best_k, best = k, sse
    k = best_k
    var = scores.var(axis=0)
    if len(var) and var.sum() > 0:
        k_var = int(np.searchsorted(np.cumsum(var) / var.sum(), variance_share - 1e-12) + 1)
        k = max(best_k, min(k_var, max(top, 0)))
    return k, np.c_[np.ones(n), scores[:, :k]], best_k


def added_variable(
    residuals: pd.DataFrame,
    sites: pd.DataFrame,
    texture_wide: pd.DataFrame | None,
    cause,
    speed_bin_kmh: float = 10.0,
    exclude=DEFAULT_EXCLUDE,
    texture_pc_scores: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Added-variable (partial regression) data of a texture-adjusted cause: per site, the covariate and the
    measured site mean (``main``, mu) or speed slope (``x_speed``, mu per 10 km/h), both minus their least-squares
    fit on ``[1, first texture_pcs texture PCs]``. The slope of measured_adj on covariate_adj is the partial effect
    the test found (Frisch-Waugh). Empty for a cause without texture adjustment or a categorical covariate."""
    if cause.texture_pcs < 0 or cause.dtype != "numeric":
        return pd.DataFrame()
    ids, bins, M = level_matrix(residuals, "between-site", speed_bin_kmh, value="measured")
    cov, info = site_covariates(sites, texture_wide, exclude=exclude)
    C = cov.loc[ids]
    N = np.c_[np.ones(len(ids)), scores_for(ids, texture_pc_scores, cov, info)[:, : cause.texture_pcs]]
    sc = bins - bins.mean()
    y = M.mean(axis=1) if cause.kind == "main" else (M - M.mean(axis=1, keepdims=True)) @ sc / (sc @ sc) * 10.0
    return pd.DataFrame(
        {
            "site": ids,
            "covariate_adj": residualise(C[cause.variable].to_numpy(float), N),
            "measured_adj": residualise(y, N),
        }
    )
