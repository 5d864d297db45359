"""Designs of the screening tests: a candidate's orthonormal basis, the texture nuisance design of the
texture-adjusted between-site tests (Frisch-Waugh, Freedman & Lane 1983) and the added-variable data of a cause
found that way (docs/model-criticism.md, section 2, "Texture-adjusted tests")."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import InputError
from .covariates import DEFAULT_EXCLUDE, between_site_texture_scores, score_table, scores_for, site_covariates
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


def leverage_corrected(R: np.ndarray, N: np.ndarray, sections: np.ndarray, floor: float = 0.05) -> np.ndarray:
    """Residuals ``R = (I - H) Y`` (n, S) of a least-squares fit on ``N`` with each section's block scaled by
    ``(I - H_gg)^(-1/2)``: what the texture-adjusted tests permute.

    ``H = N N^+`` is the hat matrix, ``H_gg`` its block of one section's sites. For errors with covariance
    ``sigma^2 I`` the residuals have covariance ``sigma^2 (I - H)``: shrunk most where the nuisance columns vary
    between sections and few sections are left (12 sections, 7-9 texture columns), so permutations of the raw
    residuals understate the spread of the statistic, which sees the errors themselves (``Q~' (I - H) = Q~'``), and
    the Freedman-Lane test rejects too often. After the correction each section's block has covariance
    ``sigma^2 I`` again (the bias-reduced residuals of Bell & McCaffrey 2002, CR2). Eigenvalues of ``I - H_gg``
    below ``floor`` are raised to it (a section the nuisance fits almost exactly is not amplified beyond
    ``floor^(-1/2)``). docs/model-criticism.md, section 2, "Texture-adjusted tests"."""
    H = N @ np.linalg.pinv(N)
    out = np.array(R, dtype=float, copy=True)
    for g in np.unique(sections):
        idx = np.flatnonzero(sections == g)
        w, V = np.linalg.eigh(np.eye(idx.size) - H[np.ix_(idx, idx)])
        out[idx] = (V / np.sqrt(np.maximum(w, floor))) @ V.T @ R[idx]
    return out


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
    M: np.ndarray,
    scores: np.ndarray,
    sections: np.ndarray,
    k_max: int | None = None,
    variance_share: float = 0.9,
    n_lead: int = 0,
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

    ``n_lead``: the first ``n_lead`` columns of ``scores`` are the prediction model's texture columns
    (:func:`texture_model_scores`), always conditioned on (``k >= n_lead``, ``k_cv >= n_lead``), the PCs after
    them; (b) then counts PCs only, on top of the lead columns.
    """
    n = M.shape[0]
    folds = np.unique(sections, return_inverse=True)[1]
    n_sec = int(folds.max()) + 1
    top = min(n_sec - 2, n // 3, scores.shape[1]) if k_max is None else min(int(k_max), scores.shape[1])
    top = max(top, n_lead)
    best_k = n_lead + _best_loso(M, scores[:, :n_lead], scores[:, n_lead:], folds, n_sec, top)[1]
    k = best_k
    var = scores[:, n_lead:].var(axis=0)
    if len(var) and var.sum() > 0:
        k_var = n_lead + int(np.searchsorted(np.cumsum(var) / var.sum(), variance_share - 1e-12) + 1)
        k = max(best_k, min(k_var, top))
    return k, np.c_[np.ones(n), scores[:, :k]], best_k


def lead_design(cov: pd.DataFrame, terms) -> np.ndarray | None:
    """Columns (n_sites, len(terms)) of a prediction model's texture terms, ``column`` or ``log(column)`` (natural
    log), each standardised over the sites of ``cov``; None when a column is missing, has a NaN, is constant, or
    is not positive under a log."""
    cols = []
    for t in terms:
        is_log = t.startswith("log(") and t.endswith(")")
        name = t[4:-1] if is_log else t
        if name not in cov.columns:
            return None
        x = cov[name].to_numpy(float)
        if not np.isfinite(x).all() or (is_log and (x <= 0).any()):
            return None
        x = np.log(x) if is_log else x
        if x.std() == 0:
            return None
        cols.append((x - x.mean()) / x.std())
    return np.column_stack(cols) if cols else None


def _best_loso(M: np.ndarray, lead: np.ndarray, pcs: np.ndarray, folds: np.ndarray, n_sec: int, top: int):
    """Smallest leave-one-section-out SSE of ``M`` on ``[1, lead, first j PCs]`` over j (``lead`` may have no
    columns) with ``lead`` columns + j <= ``top``, and that j."""
    n = M.shape[0]
    best, best_j = np.inf, 0
    for j in range(max(top - lead.shape[1], 0) + 1):
        sse = _loso_sse(M, np.c_[np.ones(n), lead, pcs[:, :j]], folds, n_sec)
        if sse < best * (1 - 1e-12):
            best, best_j = sse, j
    return best, best_j


def texture_model_scores(
    residuals: pd.DataFrame,
    sites: pd.DataFrame,
    texture_wide: pd.DataFrame | None,
    speed_bin_kmh: float = 10.0,
    exclude=DEFAULT_EXCLUDE,
    lead=(),
) -> tuple[pd.DataFrame | None, dict]:
    """The texture model the between-site tests condition on, as the score table of
    :func:`~skidsim.criticism.covariates.between_site_texture_scores` (columns ``_tpc1, _tpc2, ...``), and its
    record (gain.json ``texture_model``).

    ``lead``: the texture terms of the regression model whose held-out predictions the between-site residuals
    use (``DiagnosisInputs.prediction_features``, e.g. ``("profile_MPD", "micro_Sq")`` for ``physics2@dft``).
    Two texture models of the measured curves (site x speed bin, mu) are compared by leave-one-section-out SSE,
    each with its best number j of leading PCs: ``[1, PCs 1..j]`` and ``[1, lead columns, PCs 1..j]``. When the
    second predicts unseen sections better, the lead columns (standardised, logs where the term is a log) come
    first in the table, ``table.attrs["n_lead"]`` says how many, and the tests always condition on them. No
    candidate enters the choice, so the permutation tests stay valid. The record holds the columns used, the
    number of PCs and the cross-validated R^2 of the measured curves (1 - SSE / sum of squares about the pooled
    mean) of the mean per speed bin, the PC model and the lead model."""
    table = between_site_texture_scores(residuals, sites, texture_wide, speed_bin_kmh, exclude)
    record = {"lead": [], "lead_chosen": False, "cv_r2_pcs": None, "cv_r2_lead": None, "cv_r2_mean_per_bin": None}
    if table is None:
        return None, record
    try:
        ids, _, M = level_matrix(residuals, "between-site", speed_bin_kmh, value="measured")
    except InputError:
        return table, record
    pos = {s: i for i, s in enumerate(ids)}
    M = M[[pos[s] for s in table.index]]
    cov, _ = site_covariates(sites, texture_wide, exclude=exclude)
    sec = sites.assign(site=sites["site"].astype(str)).set_index("site").loc[list(table.index), "section"]
    folds = np.unique(sec.astype(str).to_numpy(), return_inverse=True)[1]
    n_sec = int(folds.max()) + 1
    n, pcs = len(table), table.to_numpy(float)
    top = min(n_sec - 2, n // 3, pcs.shape[1])
    ss = float(((M - M.mean()) ** 2).sum())
    r2 = lambda sse: float(1 - sse / ss) if ss > 0 else None  # noqa: E731
    sse_mean = _loso_sse(M, np.ones((n, 1)), folds, n_sec)
    sse_pcs, j_pcs = _best_loso(M, np.zeros((n, 0)), pcs, folds, n_sec, top)
    record.update(cv_r2_mean_per_bin=r2(sse_mean), cv_r2_pcs=r2(sse_pcs), pcs=int(j_pcs))
    L = lead_design(cov.loc[list(table.index)], lead) if lead else None
    if L is None or L.shape[1] > top:
        return table, record
    sse_lead, j_lead = _best_loso(M, L, pcs, folds, n_sec, top)
    record.update(lead=list(lead), cv_r2_lead=r2(sse_lead), pcs_with_lead=int(j_lead))
    if sse_lead >= sse_pcs:
        return table, record
    record["lead_chosen"] = True
    out = score_table(np.c_[L, pcs], table.index)
    out.attrs["n_lead"] = L.shape[1]
    out.attrs["lead"] = list(lead)
    return out, record


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
