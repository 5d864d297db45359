"""Prediction intervals that hold at unseen sections: CV+ with sections as folds (:class:`SectionCVPlus`).

Why CV+ (Barber, Candes, Ramdas and Tibshirani 2021, "Predictive inference with the jackknife+", Ann. Statist.
49(1), section 3): the workflow already fits the model once per held-out section (its leave-one-section-out
cross-validation), so every training site ``i`` has an out-of-section residual ``R_i = |D_i - mu_{-S(i)}(x_i)|``
(friction) made by the model fitted without its section ``S(i)``. CV+ turns exactly these into an interval for a
new scan ``x``: with ``n`` training sites and ``alpha = 1 - level``,

``lo = the floor(alpha (n + 1))-th smallest of mu_{-S(i)}(x) - R_i``,
``hi = the ceil((1 - alpha)(n + 1))-th smallest of mu_{-S(i)}(x) + R_i``,

separately at each speed. Folds are whole sections, so the residuals are those of sites whose section the model
had not seen: the situation of a new road. Unlike split conformal it spends no sites on calibration (36 sites
are few), and unlike the plain "full model +- residual quantile" it carries the fold-to-fold variability of the
fitted model into the interval. Its worst-case guarantee for exchangeable sites and K folds of n / K sites is
``1 - 2 alpha - min(2 (1 - 1/K) / (n/K + 1), (1 - K/n) / (K + 1))`` (their Theorem 4); in practice its coverage
is close to ``level``. Sites within a section are not exchangeable with each other, so the measured coverage at
unseen sections (:mod:`.coverage`, docs/prediction.md) is the claim, not the theorem. Where ``(1 - alpha)(n + 1) > n``
(fewer than ``1 / alpha - 1`` sites) the interval is unbounded and returned as NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .linear import LinearMap


def check_level(level: float, source="--level") -> float:
    """``level`` as a float in (0, 1), else InputError naming ``source``."""
    try:
        v = float(level)
    except (TypeError, ValueError):
        v = float("nan")
    if not 0.0 < v < 1.0:
        raise InputError(source, "a nominal coverage level between 0 and 1 (e.g. 0.9)", got=level)
    return v


@dataclass(frozen=True)
class SectionCVPlus:
    """The CV+ ingredients: ``sections`` (one fold per training section), ``folds`` (the model fitted without
    each section, :class:`~.linear.LinearMap`), ``sites`` (training sites), ``site_fold`` (index of each site's
    section in ``sections``) and ``residuals`` ``(n, k)``: ``|D_i - mu_{-S(i)}(x_i)|`` (friction)."""

    sections: tuple[str, ...]
    folds: tuple[LinearMap, ...]
    sites: tuple[str, ...]
    site_fold: np.ndarray
    residuals: np.ndarray

    def interval(self, X: pd.DataFrame, level: float) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds ``(m, k)`` (friction) at ``level`` for the rows of ``X``; NaN where the
        training sites are too few for the level."""
        alpha = 1.0 - check_level(level, "level")
        n = len(self.sites)
        P = np.stack([f.predict(X).to_numpy(dtype=float) for f in self.folds])  # (folds, m, k)
        mu = P[self.site_fold]  # (n, m, k): each training site's fold model at the new rows
        R = self.residuals[:, None, :]
        r_lo, r_hi = math.floor(alpha * (n + 1)), math.ceil((1.0 - alpha) * (n + 1))
        m, k = P.shape[1], P.shape[2]
        if r_lo < 1 or r_hi > n:
            return np.full((m, k), np.nan), np.full((m, k), np.nan)
        lo = np.sort(mu - R, axis=0)[r_lo - 1]
        hi = np.sort(mu + R, axis=0)[r_hi - 1]
        return lo, hi

    def to_dict(self) -> dict:
        return {
            "method": "cv+ (folds: sections)",
            "sections": list(self.sections),
            "folds": [f.to_dict() for f in self.folds],
            "sites": list(self.sites),
            "site_section": [self.sections[j] for j in self.site_fold],
            "residuals": [[float(v) for v in row] for row in self.residuals],
        }

    @classmethod
    def from_dict(cls, d: dict, source="model file", field="intervals") -> SectionCVPlus:
        try:
            sections = tuple(str(s) for s in d["sections"])
            folds = tuple(LinearMap.from_dict(f, source, f"{field}.folds") for f in d["folds"])
            sites = tuple(str(s) for s in d["sites"])
            index = {s: j for j, s in enumerate(sections)}
            site_fold = np.asarray([index[str(s)] for s in d["site_section"]], dtype=int)
            residuals = np.asarray(d["residuals"], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(
                source, "CV+ intervals: sections, folds, sites, site_section, residuals", column=field, got=str(e)
            ) from None
        k = len(folds[0].targets) if folds else 0
        if len(folds) != len(sections) or residuals.shape != (len(sites), k) or len(site_fold) != len(sites):
            raise InputError(source, "one fold per section and one residual per site and speed", column=field)
        if not np.all(np.isfinite(residuals)) or np.any(residuals < 0):
            raise InputError(source, "finite non-negative residuals", column=f"{field}.residuals")
        return cls(sections, folds, sites, site_fold, residuals)


def fit_cvplus(X: pd.DataFrame, D: pd.DataFrame, groups, fit) -> tuple[SectionCVPlus, pd.DataFrame]:
    """The section folds of a model: ``fit(X_train, D_train, groups_train) -> LinearMap`` on all sections but
    one, for each section; returns the CV+ ingredients and the out-of-section predictions of the training sites
    (friction, indexed like ``D``)."""
    groups = np.asarray(groups).astype(str)
    sections = tuple(sorted(pd.unique(groups)))
    if len(sections) < 3:
        raise InputError(None, "at least 3 sections for section-grouped intervals", column="section", got=len(sections))
    folds, oof = [], pd.DataFrame(np.nan, index=D.index, columns=D.columns)
    for s in sections:
        te = groups == s
        f = fit(X[~te], D[~te], groups[~te])
        folds.append(f)
        oof.loc[te] = f.predict(X[te]).to_numpy(dtype=float)
    index = {s: j for j, s in enumerate(sections)}
    res = np.abs(D.to_numpy(dtype=float) - oof.to_numpy(dtype=float))
    site_fold = np.asarray([index[g] for g in groups], dtype=int)
    return SectionCVPlus(sections, tuple(folds), tuple(str(s) for s in D.index), site_fold, res), oof
