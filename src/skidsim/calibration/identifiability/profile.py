"""Profile-likelihood intervals of the law's parameters through the mapping (:func:`profile_intervals`): the
profiled sum of squares over each calibration bound, its chi-square cut, open ends at a bound.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from skidsim.calibration.brent import minimize_bounded
from skidsim.calibration.identifiability.mapping import SurrogateMap
from skidsim.calibration.law_fit import box_ls2_many, fit_exponential_decay
from skidsim.calibration.options import PARAMS
from skidsim.friction import KMH_PER_MS

#: chi2_ppf at the levels a record uses, as scipy gives them (tests/test_calibration_brent.py checks them against
#: scipy.stats.chi2.ppf): the default confidence needs no scipy at all
_CHI2_PPF = {
    (0.9, 1): 2.705543454095404,
    (0.9, 3): 6.251388631170325,
    (0.95, 1): 3.841458820694124,
    (0.95, 3): 7.814727903251179,
    (0.99, 1): 6.6348966010212145,
    (0.99, 3): 11.344866730144373,
}


def chi2_ppf(q: float, df: int) -> float:
    """Quantile at ``q`` of the chi-squared distribution with ``df`` degrees of freedom: the number
    ``scipy.stats.chi2.ppf(q, df)`` gives, computed as it does (``2 gammaincinv(df / 2, q)``; 0 at q = 0, inf at
    q = 1, NaN outside [0, 1]) without importing scipy.stats (0.6 s, the largest import of an identifiability job);
    the common levels come from a table (:data:`_CHI2_PPF`) without importing scipy.special either."""
    q = float(q)
    if (q, df) in _CHI2_PPF:
        return _CHI2_PPF[(q, df)]
    if q == 0.0:
        return 0.0
    if q == 1.0:
        return math.inf
    if not 0.0 < q < 1.0:
        return math.nan
    from scipy.special import gammaincinv

    return float(2 * gammaincinv(df / 2, q))


def _profile_sse(
    param: str,
    values: np.ndarray,
    s: np.ndarray,
    b: np.ndarray,
    z: np.ndarray,
    bounds: Mapping[str, tuple[float, float]],
    alphas: np.ndarray,
) -> np.ndarray:
    """min SSE over the other two parameters (box-bounded) with ``param`` fixed at each of ``values``.

    Model ``z = b (mu_k (1 - e) + mu_s e)``, ``e = exp(-alpha s)``. For fixed alpha the model is linear in
    (mu_k, mu_s): alpha fixed -> the exact 2-unknown box problem; mu_k or mu_s fixed -> the exact 1-unknown box
    problem on every alpha of the grid ``alphas``, minimum over the grid refined by bounded Brent between the
    best grid value's neighbours.
    """
    lo2 = np.array([bounds["mu_k"][0], bounds["mu_s"][0]], dtype=float)
    hi2 = np.array([bounds["mu_k"][1], bounds["mu_s"][1]], dtype=float)
    if param == "alpha":
        e = np.exp(-np.outer(values, s))
        _, sse = box_ls2_many(b * (1.0 - e), b * e, z, lo2, hi2)
        return sse
    e = np.exp(-np.outer(alphas, s))  # (A, n)
    if param == "mu_k":
        fixed_col, free_col, free = b * (1.0 - e), b * e, "mu_s"
    elif param == "mu_s":
        fixed_col, free_col, free = b * e, b * (1.0 - e), "mu_k"
    else:
        raise ValueError(f"unknown parameter {param!r}")
    flo, fhi = (float(x) for x in bounds[free])

    def sse_at(c: float, fixed, freec) -> np.ndarray:
        r = z[None, :] - c * fixed  # (A, n)
        ff = np.einsum("an,an->a", freec, freec)
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.where(ff > 0, np.einsum("an,an->a", freec, r) / ff, flo)
        res = r - np.clip(p, flo, fhi)[:, None] * freec
        return np.einsum("an,an->a", res, res)

    def cols(al: float):
        e1 = np.exp(-al * s)[None, :]
        return (b * (1.0 - e1), b * e1) if param == "mu_k" else (b * e1, b * (1.0 - e1))

    out = np.empty(values.size)
    for k, c in enumerate(values):
        sse = sse_at(float(c), fixed_col, free_col)
        i = int(np.argmin(sse))
        best = float(sse[i])
        left, right = float(alphas[max(i - 1, 0)]), float(alphas[min(i + 1, alphas.size - 1)])
        if right > left:  # refine alpha between the grid neighbours (the profile is sharp when the rest is pinned)
            _, fun, ok = minimize_bounded(
                lambda al, c=c: float(sse_at(float(c), *cols(al))[0]), left, right, xatol=1e-10
            )
            if ok and fun < best:
                best = fun
        out[k] = best
    return out


def _interval_from_profile(grid: np.ndarray, dev: np.ndarray, crit: float, lo: float, hi: float) -> dict:
    """The confidence set {dev <= crit} on ``grid``: its hull (ends interpolated), whether each end is open at a
    bound, and the number of disjoint pieces (two branches give 2)."""
    inside = dev <= crit
    if not inside.any():  # numerical: the minimum lies between grid points
        k = int(np.argmin(dev))
        return {
            "lower": float(grid[k]),
            "upper": float(grid[k]),
            "lower_open": False,
            "upper_open": False,
            "n_pieces": 1,
        }
    ks = np.flatnonzero(inside)
    i0, i1 = int(ks[0]), int(ks[-1])
    pieces = 1 + int(np.sum(np.diff(ks) > 1))

    def cross(i_out, i_in):
        d0, d1 = dev[i_out], dev[i_in]
        t = (crit - d0) / (d1 - d0) if d1 != d0 else 0.5
        return float(grid[i_out] + t * (grid[i_in] - grid[i_out]))

    lower = float(grid[0]) if i0 == 0 else cross(i0 - 1, i0)
    upper = float(grid[-1]) if i1 == grid.size - 1 else cross(i1 + 1, i1)
    return {
        "lower": lower,
        "upper": upper,
        "lower_open": i0 == 0 and lo == grid[0],
        "upper_open": i1 == grid.size - 1 and hi == grid[-1],
        "n_pieces": pieces,
    }


def profile_intervals(
    v_kmh,
    y,
    mapping: SurrogateMap,
    bounds: Mapping[str, tuple[float, float]],
    sigma_eff: float,
    *,
    confidence: float = 0.95,
    points: int = 121,
    alpha_points: int = 801,
) -> dict:
    """Profile-likelihood intervals of (mu_s, mu_k, alpha) within ``bounds`` for data ``y`` at ``v_kmh`` (km/h)
    through ``mapping``, noise sd ``sigma_eff`` (mu). Each profile is evaluated on ``points`` values over the
    bounds, and again on ``points`` values around the confidence set when fewer than 5 of them fall inside it (a
    parameter pinned by the data or by the other parameters' bounds). Returns ``{"sse_min", "params": {name:
    {lower, upper, lower_open, upper_open, n_pieces, grid, deviance}}}`` (deviance = (SSE_profile - SSE_min) /
    sigma_eff^2)."""
    v = np.asarray(v_kmh, dtype=float)
    a, b, s = mapping.terms(v)
    z = np.asarray(y, dtype=float) - a
    crit = chi2_ppf(confidence, 1)
    alphas = np.linspace(float(bounds["alpha"][0]), float(bounds["alpha"][1]), int(alpha_points))
    profiles = {}
    for p in PARAMS:
        lo, hi = (float(x) for x in bounds[p])
        grid = np.linspace(lo, hi, int(points))
        profiles[p] = (grid, _profile_sse(p, grid, s, b, z, bounds, alphas))
    _, sse_fit = fit_exponential_decay(s * KMH_PER_MS, y, a=a, b=b, bounds=bounds)
    sse_min = min(float(sse_fit), *(float(np.min(pr[1])) for pr in profiles.values()))
    # a sharp profile (fewer than 5 grid values inside the set) is profiled again on a fine grid around the set
    for p, (grid, sse) in list(profiles.items()):
        ks = np.flatnonzero((sse - sse_min) / sigma_eff**2 <= crit)
        if ks.size >= 5:
            continue
        k0, k1 = (int(ks[0]), int(ks[-1])) if ks.size else (int(np.argmin(sse)),) * 2
        i0, i1 = max(k0 - 1, 0), min(k1 + 1, grid.size - 1)
        fine = np.linspace(grid[i0], grid[i1], int(points))
        both = np.concatenate([grid, fine])
        order = np.argsort(both, kind="stable")
        vals = np.concatenate([sse, _profile_sse(p, fine, s, b, z, bounds, alphas)])[order]
        both = both[order]
        keep = np.concatenate([[True], np.diff(both) > 0])
        profiles[p] = (both[keep], vals[keep])
    sse_min = min(sse_min, *(float(np.min(pr[1])) for pr in profiles.values()))
    out = {"sse_min": sse_min, "critical_deviance": crit, "params": {}}
    for p, (grid, sse) in profiles.items():
        lo, hi = (float(x) for x in bounds[p])
        dev = (sse - sse_min) / sigma_eff**2
        rec = _interval_from_profile(grid, dev, crit, lo, hi)
        rec.update(grid=grid.tolist(), deviance=dev.tolist())
        out["params"][p] = rec
    return out
