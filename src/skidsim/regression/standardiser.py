"""Column selection, median imputation and standardisation, learnt on the training rows only.

* **Missing values and constant columns**: a column with more than ``max_nan_fraction`` (default
  :data:`MAX_NAN_FRACTION`, 0.2) NaN is dropped; remaining NaN are replaced by the training median of the column;
  a column whose (imputed) training standard deviation is zero (``<= 1e-12 * (1 + |mean|)``) is dropped.
* **Standardisation** uses the sample standard deviation (``ddof=1``), so the eigenvalues of the PCA are those of
  the training correlation matrix (they sum to the number of kept columns).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from skidsim.errors import InputError

#: Largest share of NaN a feature column may have on the training rows and still be used.
MAX_NAN_FRACTION = 0.2


def _impute_medians(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A`` with NaN replaced by the column medians, and the medians."""
    nan = np.isnan(A)
    if not nan.any():
        return A, np.median(A, axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(A, axis=0)
    return np.where(nan, med, A), med


def standardiser_arrays(A: np.ndarray, max_nan_fraction: float):
    """Kept column indices, medians, means, sds (ddof=1) and {index: reason} of dropped columns of ``A``."""
    if A.shape[0] < 3:
        raise InputError(None, "at least 3 training sites", got=A.shape[0])
    nan_frac = np.isnan(A).mean(axis=0)
    A, med = _impute_medians(A)
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
        raise InputError(
            None,
            "at least one feature column that is neither constant nor mostly NaN",
            got=sorted(set(dropped.values())),
        )
    k = np.asarray(keep)
    return k, med[k], mean[k], sd[k], dropped


def standardise_split(A: np.ndarray, tr: np.ndarray, te: np.ndarray, max_nan_fraction: float):
    """Standardised training and test rows of the array ``A``, the scaler learnt on the training rows only."""
    k, med, mean, sd, _ = standardiser_arrays(A[tr], max_nan_fraction)
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
    def fit(cls, X: pd.DataFrame, max_nan_fraction: float = MAX_NAN_FRACTION) -> Standardiser:
        keep, med, mean, sd, dropped = standardiser_arrays(X.to_numpy(dtype=float), max_nan_fraction)
        names = list(X.columns)
        return cls(tuple(names[j] for j in keep), med, mean, sd, {names[j]: why for j, why in dropped.items()})

    def transform(self, X: pd.DataFrame) -> np.ndarray:
        """Standardised ``(n, p)`` array of the kept columns (NaN imputed with the training medians)."""
        missing = [c for c in self.columns if c not in X.columns]
        if missing:
            raise InputError(None, "every feature column the model was fitted with", column=missing[0])
        A = X.loc[:, list(self.columns)].to_numpy(dtype=float)
        A = np.where(np.isnan(A), self.medians, A)
        return (A - self.means) / self.sds
