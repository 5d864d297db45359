"""Where a model was trained: the texture domain of its training sites and a scan's distance to it (:class:`Domain`).

* **Space**: the model's own feature columns, transformed as the model does (:meth:`LinearMap.transformed`: logs
  for ``physics2``'s log form, NaN imputed with the training medians), then standardised with the training mean
  and sample SD of each column.
* **Distance**: Mahalanobis distance to the training centre in the principal components of that standardised
  space (SVD of the training rows) that carry at least :data:`MIN_COMPONENT_SHARE` of its variance, at most
  ``n // 3`` of them (``n`` training sites), so that no component estimated from a handful of sites weighs in:
  ``d(x)^2 = sum_c score_c(x)^2 / lambda_c``. For a two-column model (``physics2``, ``ols2``) it is the ordinary
  Mahalanobis distance of the two columns unless they are nearly collinear.
* **Threshold** (from the training sections): every section is held out in turn, the domain refitted on the
  others, and the held-out sites' distances taken; the threshold is the ``ceil((1 - alpha)(n + 1))``-th smallest
  of these (``alpha`` :data:`DOMAIN_ALPHA`, config ``predict.domain_alpha``; the largest when there are fewer
  than ``1 / alpha - 1`` sites). A new site exchangeable with the training sites lies beyond it with probability
  at most ``alpha`` (conformal outlier detection); beyond it the prediction is an ``extrapolation``. A quantile
  rather than the largest distance: one unusual training site (a held-out distance of 117 against a median of 2.5
  in a spectral campaign, measured 2026-11-28) would otherwise open the domain to everything.
* **Features out of range**: a column whose value lies outside the training range widened by
  :data:`RANGE_MARGIN` of that range on each side (in the column's own unit), or that is missing. These are named
  in the warning; when none is, the three columns farthest from the training mean (in training SDs) are named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .linear import LinearMap

#: Smallest share of the standardised variance a principal component needs to enter the distance.
MIN_COMPONENT_SHARE = 0.01
#: Default share of sites like the training sites that may be flagged as extrapolation.
DOMAIN_ALPHA = 0.1
#: Most out-of-range features named in one warning (the farthest out first).
MAX_NAMED = 5
#: Widening of each column's training range (share of the range, each side) before a value counts as out of range.
RANGE_MARGIN = 0.1


@dataclass(frozen=True)
class Domain:
    """The training domain of a model (module docstring). ``features``; ``mean``/``sd`` of the transformed
    columns; ``components`` ``(p, c)`` unit loadings and ``variances`` ``(c,)`` of the kept components;
    ``raw_min``/``raw_max`` (each column's unit) of the training sites; ``threshold`` (the distance beyond which a
    scan is an extrapolation), ``heldout_distance`` of each training site (its section held out) and ``alpha``
    (the threshold's level)."""

    features: tuple[str, ...]
    mean: np.ndarray
    sd: np.ndarray
    components: np.ndarray
    variances: np.ndarray
    raw_min: np.ndarray
    raw_max: np.ndarray
    threshold: float
    heldout_distance: np.ndarray
    alpha: float = DOMAIN_ALPHA

    def distance(self, T: np.ndarray) -> np.ndarray:
        """Distance of rows ``T`` ``(m, p)`` of transformed, imputed features (:meth:`LinearMap.transformed`)."""
        if not self.features:
            return np.zeros(len(T))
        S = ((T - self.mean) / self.sd) @ self.components
        return np.sqrt(np.sum(S * S / self.variances, axis=1))

    def out_of_range(self, X: pd.DataFrame, T: np.ndarray) -> list[list[str]]:
        """For each row: the features outside their widened training range (``"micro_Sq 0.081 mm > 0.052"``-like
        strings, in the column's unit), or missing."""
        out = []
        if not self.features:
            return [[] for _ in range(len(X))]
        A = X.loc[:, list(self.features)].to_numpy(dtype=float)
        span = self.raw_max - self.raw_min
        lo, hi = self.raw_min - RANGE_MARGIN * span, self.raw_max + RANGE_MARGIN * span
        for a in A:
            names, how_far = [], []
            for j, c in enumerate(self.features):
                far = max(lo[j] - a[j], a[j] - hi[j]) / span[j] if span[j] > 0 else np.inf
                how_far.append(np.inf if np.isnan(a[j]) else far)
                if np.isnan(a[j]):
                    names.append(f"{c} missing")
                elif a[j] < lo[j]:
                    names.append(
                        f"{c} {a[j]:.4g} below the training range [{self.raw_min[j]:.4g}, {self.raw_max[j]:.4g}]"
                    )
                elif a[j] > hi[j]:
                    names.append(
                        f"{c} {a[j]:.4g} above the training range [{self.raw_min[j]:.4g}, {self.raw_max[j]:.4g}]"
                    )
            out.append(names)
        return out

    def farthest(self, T: np.ndarray, n: int = 3) -> list[list[str]]:
        """For each row: the ``n`` features farthest from the training mean, as ``"<name> (z SD)"``."""
        if not self.features:
            return [[] for _ in range(len(T))]
        z = (T - self.mean) / self.sd
        return [[f"{self.features[j]} ({r[j]:+.1f} SD)" for j in np.argsort(-np.abs(r))[:n]] for r in z]

    def to_dict(self) -> dict:
        return {
            "features": list(self.features),
            "mean": [float(v) for v in self.mean],
            "sd": [float(v) for v in self.sd],
            "components": [[float(v) for v in row] for row in self.components],
            "variances": [float(v) for v in self.variances],
            "raw_min": [float(v) for v in self.raw_min],
            "raw_max": [float(v) for v in self.raw_max],
            "threshold": float(self.threshold),
            "heldout_distance": [float(v) for v in self.heldout_distance],
            "alpha": float(self.alpha),
        }

    @classmethod
    def from_dict(cls, d: dict, source="model file", field="domain") -> Domain:
        try:
            features = tuple(str(c) for c in d["features"])
            p = len(features)
            vec = {n: np.asarray(d[n], dtype=float) for n in ("mean", "sd", "raw_min", "raw_max")}
            variances = np.asarray(d["variances"], dtype=float)
            comps = np.asarray(d["components"], dtype=float).reshape(p, len(variances))
            threshold = float(d["threshold"])
            held = np.asarray(d["heldout_distance"], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(
                source,
                "a training domain: features, mean, sd, components, variances, raw_min, raw_max,"
                " threshold, heldout_distance",
                column=field,
                got=str(e),
            ) from None
        if any(v.shape != (p,) for v in vec.values()) or not np.all(vec["sd"] > 0) or not np.all(variances > 0):
            raise InputError(
                source, f"one mean, positive sd, min and max per feature ({p}); positive variances", column=field
            )
        if not np.isfinite(threshold) or threshold < 0:
            raise InputError(
                source, "a finite non-negative distance threshold", column=f"{field}.threshold", got=threshold
            )
        return cls(features, vec["mean"], vec["sd"], comps, variances, vec["raw_min"], vec["raw_max"], threshold, held)


def _fit(T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, sd, kept components and their variances of the transformed training rows ``T``."""
    n, p = T.shape
    mean = T.mean(axis=0)
    sd = T.std(axis=0, ddof=1) if n > 1 else np.ones(p)
    sd = np.where(sd > 1e-12 * (1.0 + np.abs(mean)), sd, np.inf)  # a constant column carries no distance
    Z = (T - mean) / sd
    _, s, vt = np.linalg.svd(Z, full_matrices=False)
    var = s**2 / max(n - 1, 1)
    total = var.sum()
    keep = np.flatnonzero(var >= MIN_COMPONENT_SHARE * total)[: max(1, n // 3)] if total > 0 else np.array([], int)
    return mean, sd, vt[keep].T, var[keep]


def heldout_threshold(held: np.ndarray, alpha: float) -> float:
    """The ``ceil((1 - alpha)(n + 1))``-th smallest of the held-out distances ``held`` (the largest if fewer)."""
    n = len(held)
    r = min(int(np.ceil((1.0 - alpha) * (n + 1))), n)
    return float(np.sort(held)[r - 1])


def fit_domain(lin: LinearMap, X: pd.DataFrame, groups, alpha: float = DOMAIN_ALPHA) -> Domain:
    """The training domain of the model ``lin`` on its training rows ``X`` with their sections ``groups``; the
    threshold from the held-out sections at level ``alpha`` (module docstring)."""
    if not 0.0 < float(alpha) < 1.0:
        raise InputError(None, "a domain level alpha between 0 and 1", column="domain_alpha", got=alpha)
    groups = np.asarray(groups).astype(str)
    if len(pd.unique(groups)) < 2:
        raise InputError(None, "at least 2 sections for the domain threshold", column="section")
    T = lin.transformed(X)
    mean, sd, comps, var = _fit(T)
    keep = np.isfinite(sd)
    features = tuple(c for c, k in zip(lin.features, keep) if k)
    held = np.zeros(len(X))
    for s in pd.unique(groups):
        te = groups == s
        m, d, c, v = _fit(T[~te][:, keep])
        d = np.where(np.isfinite(d), d, np.inf)
        S = ((T[te][:, keep] - m) / d) @ c
        held[te] = np.sqrt(np.sum(S * S / v, axis=1)) if len(v) else 0.0
    A = X.loc[:, list(features)].to_numpy(dtype=float)
    with np.errstate(invalid="ignore"):
        rmin, rmax = np.nanmin(A, axis=0), np.nanmax(A, axis=0)
    thr = heldout_threshold(held, float(alpha))
    return Domain(features, mean[keep], sd[keep], comps[keep], var, rmin, rmax, thr, held, float(alpha))
