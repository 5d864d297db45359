"""The simple baseline ``ols2``: OLS with intercept on at most two texture columns chosen by inner CV.

* Candidates are the empty subset, every texture column (``raw_*``, ``macro_*``, ``micro_*``, ``profile_*``; not
  temperature) and every pair; the one with the smallest inner-CV SSE pooled over all targets (one subset for
  the whole curve) wins, exact ties to the smaller subset; NaN imputed with training medians. Always the
  minimum, not the one-SE rule.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .design import texture_columns
from .splits import inner_splits
from .standardiser import MAX_NAN_FRACTION, standardiser_arrays

#: Base model name: OLS with intercept on at most :data:`SUBSET_MAX_FEATURES` texture columns chosen by inner CV.
SUBSET_OLS = "ols2"
SUBSET_MAX_FEATURES = 2


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


def subset_test_sse(
    Atr: np.ndarray, Ytr: np.ndarray, Ate: np.ndarray, Yte: np.ndarray, subsets: np.ndarray
) -> np.ndarray:
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
    det = sii * sjj - sij**2
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


def fit_subset_ols(
    X: pd.DataFrame,
    Y: pd.DataFrame,
    *,
    groups=None,
    seed: int = 0,
    inner_folds: int = 5,
    max_features: int = SUBSET_MAX_FEATURES,
    max_nan_fraction: float = MAX_NAN_FRACTION,
) -> SubsetOLS:
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
        raise InputError(
            None, "texture columns (raw_*, macro_*, micro_*, profile_*) for the baseline", got=list(X.columns)[:8]
        )
    A = X.loc[:, cols].to_numpy(dtype=float)
    keep, _, _, _, _ = standardiser_arrays(A, max_nan_fraction)
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
    return SubsetOLS(
        columns=tuple(names[c] for c in chosen),
        targets=tuple(str(c) for c in Y.columns),
        medians=med[chosen],
        intercept=beta[0],
        coef=beta[1:],
        inner_sse=pd.Series(sse, index=labels, name="inner_sse"),
    )
