"""The physically motivated two-parameter model ``physics2``: OLS with intercept of the targets on MPD and
micro-band Sq, taken as they are or as their natural logarithms, the form chosen by inner cross-validation.

Why these two: the friction-speed models users fit to DFT data split a curve into a level set by the
microtexture and a speed gradient set by the macrotexture (PIARC/IFI: ``F(S) = F60 exp((60 - S) / Sp)`` with
``Sp = 14.2 + 89.7 MPD`` km/h, ASTM E1960; Rado's and the Penn State model likewise), and the level grows with
the microtexture amplitude at a decreasing rate (hence the log form). Unlike ``ols2``, which searches thousands
of pairs, this model has no column choice to overfit: only the form (two candidates) is chosen by inner CV.

Conventions: one form for all target columns (the inner-CV test SSE pooled over the folds and the columns, as
:mod:`.subset`); exact ties go to ``identity``. ``log`` is a candidate only when both columns are positive on
every training row; at prediction a value below the smallest training value is raised to it before the log
(a non-positive MPD or Sq is a scan fault, not texture). NaN is imputed with the training median (of the
transformed column).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .splits import inner_splits
from .subset import _nanmedian, subset_test_sse

#: Base model name.
PHYSICS_OLS = "physics2"
#: Its columns: MPD (mm, ISO 13473-1 on the scan's profiles) and micro-band Sq (mm).
PHYSICS_COLUMNS = ("profile_MPD", "micro_Sq")
#: Candidate forms, simpler first (the tie order).
FORMS = ("identity", "log")
_PAIR = np.array([[0, 1]])


def _raw(X: pd.DataFrame) -> np.ndarray:
    missing = [c for c in PHYSICS_COLUMNS if c not in X.columns]
    if missing:
        raise InputError(None, f"the columns {list(PHYSICS_COLUMNS)} of model {PHYSICS_OLS!r}", column=missing[0])
    return X.loc[:, list(PHYSICS_COLUMNS)].to_numpy(dtype=float)


def _transform(A: np.ndarray, form: str, floor: np.ndarray | None) -> np.ndarray:
    if form == "identity":
        return A
    return np.log(np.maximum(A, floor) if floor is not None else A)


def _candidate_forms(A: np.ndarray) -> tuple[str, ...]:
    positive = bool(np.all(A[np.isfinite(A)] > 0)) and np.all(np.isfinite(A).any(axis=0))
    return FORMS if positive else FORMS[:1]


@dataclass(frozen=True)
class PhysicsOLS:
    """The fitted ``physics2`` model: ``form`` (identity | log), ``floor`` (smallest training value of each
    column, its unit mm; the log form's lower clip), ``medians`` (of the transformed columns), ``intercept``
    ``(k,)`` and ``coef`` ``(2, k)`` in target units (per mm, or per unit of ln mm), ``targets`` and
    ``inner_sse`` (pooled inner-CV SSE per candidate form, target units squared)."""

    form: str
    floor: np.ndarray
    medians: np.ndarray
    intercept: np.ndarray
    coef: np.ndarray
    targets: tuple[str, ...]
    inner_sse: pd.Series

    @property
    def label(self) -> str:
        """``"profile_MPD+micro_Sq"`` or ``"log(profile_MPD)+log(micro_Sq)"``."""
        names = PHYSICS_COLUMNS if self.form == "identity" else tuple(f"log({c})" for c in PHYSICS_COLUMNS)
        return "+".join(names)

    def predict(self, X: pd.DataFrame) -> pd.DataFrame:
        """Predicted targets ``(n, k)`` for the rows of ``X``, indexed like ``X``."""
        A = _transform(_raw(X), self.form, self.floor)
        A = np.where(np.isnan(A), self.medians, A)
        return pd.DataFrame(self.intercept[None, :] + A @ self.coef, index=X.index, columns=list(self.targets))


def fit_physics_ols(X: pd.DataFrame, Y: pd.DataFrame, *, groups=None, seed: int = 0, inner_folds: int = 5):
    """Fit ``physics2`` on these rows: the form with the smallest inner-CV test SSE pooled over the folds
    (:func:`~.splits.inner_splits`: leave-one-group-out with ``groups``) and the columns of ``Y``, then OLS with
    intercept of every column of ``Y`` on the two transformed columns."""
    if isinstance(Y, pd.Series):
        Y = Y.to_frame()
    Yv = Y.to_numpy(dtype=float)
    if len(Yv) != len(X) or not np.all(np.isfinite(Yv)):
        raise InputError(None, f"finite targets, one row per feature row ({len(X)})", got=len(Yv))
    A = _raw(X)
    if np.any(np.isnan(_nanmedian(A))):
        raise InputError(None, f"values of the columns {list(PHYSICS_COLUMNS)}", column="/".join(PHYSICS_COLUMNS))
    splits = inner_splits(len(Yv), groups, seed=seed, n_folds=inner_folds)
    forms = _candidate_forms(A)
    sse = {
        f: sum(
            float(subset_test_sse(_transform(A[tr], f, None), Yv[tr], _transform(A[te], f, None), Yv[te], _PAIR)[0])
            for tr, te in splits
        )
        for f in forms
    }
    form = min(forms, key=lambda f: sse[f])  # stable: ties keep the simpler form
    floor = np.nanmin(A, axis=0)
    B = _transform(A, form, floor)
    med = _nanmedian(B)
    B = np.where(np.isnan(B), med, B)
    beta, *_ = np.linalg.lstsq(np.column_stack([np.ones(len(B)), B]), Yv, rcond=None)
    return PhysicsOLS(
        form, floor, med, beta[0], beta[1:], tuple(str(c) for c in Y.columns), pd.Series(sse, name="inner_sse")
    )
