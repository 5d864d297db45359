"""Fitting the exponential-decay law to data without FE: closed forms and the bounded least-squares fit.

Speeds in km/h at the interface, slip speed in m/s inside the law (``s = v / 3.6``), alpha in s/m. The surrogate
models the FE response per point as ``y = a + b mu(v)`` (a, b dimensionless); :func:`fit_exponential_decay` solves
the bounded problem over (mu_s, mu_k, alpha) exactly in (mu_k, mu_s) for each alpha (:func:`box_ls2_many`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from skidsim.calibration.brent import minimize_bounded
from skidsim.calibration.options import DEFAULT_BOUNDS, PARAMS
from skidsim.friction import KMH_PER_MS, ExponentialDecay


def aitken_three_point(speeds_kmh: Sequence[float], y: Sequence[float]) -> ExponentialDecay | None:
    """Exponential ``mu_k + (mu_s - mu_k) exp(-alpha s)`` through three equally spaced points (Aitken).

    ``r = (y2 - y3)/(y1 - y2)``, ``alpha = -ln(r)/dv`` (dv in m/s, alpha in s/m),
    ``mu_k = (y1 y3 - y2^2)/(y1 + y3 - 2 y2)``, ``mu_s = mu_k + (y1 - mu_k) exp(alpha s1)``.
    Needs ``y1 > y2 > y3`` and convexity (0 < r < 1); returns None otherwise. No bounds are applied.
    """
    v = np.asarray(speeds_kmh, dtype=float)
    y1, y2, y3 = (float(t) for t in y)
    if v.shape != (3,) or not np.isclose(v[1] - v[0], v[2] - v[1]) or v[1] <= v[0]:
        raise ValueError(f"aitken_three_point needs three increasing, equally spaced speeds (km/h), got {v}")
    if not (y1 > y2 > y3):
        return None
    r = (y2 - y3) / (y1 - y2)
    if not (0.0 < r < 1.0):
        return None
    dv_ms = float(v[1] - v[0]) / KMH_PER_MS
    alpha = -math.log(r) / dv_ms
    mu_k = (y1 * y3 - y2 * y2) / (y1 + y3 - 2.0 * y2)
    mu_s = mu_k + (y1 - mu_k) * math.exp(alpha * float(v[0]) / KMH_PER_MS)
    return ExponentialDecay(mu_s=mu_s, mu_k=mu_k, alpha=alpha)


def box_ls2_many(c1: np.ndarray, c2: np.ndarray, z: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Exact min ||c1 p1 + c2 p2 - z||^2 over the box lo <= p <= hi, for a batch of G problems.

    c1, c2: columns, shape (G, n); z: (n,). KKT enumeration (the interior solution when feasible, the four
    edges with the free unknown clipped); the problem is convex, so the best candidate is the optimum.
    Returns (p (G, 2), sse (G,)).
    """
    g11 = np.einsum("gn,gn->g", c1, c1)
    g22 = np.einsum("gn,gn->g", c2, c2)
    g12 = np.einsum("gn,gn->g", c1, c2)
    r1 = c1 @ z
    r2 = c2 @ z
    zz = float(z @ z)

    def sse_of(p1, p2):
        return zz - 2 * (p1 * r1 + p2 * r2) + p1 * p1 * g11 + 2 * p1 * p2 * g12 + p2 * p2 * g22

    G = c1.shape[0]
    best_sse = np.full(G, np.inf)
    best = np.zeros((G, 2))

    def consider(p1, p2, ok):
        val = np.where(ok, sse_of(p1, p2), np.inf)
        better = val < best_sse - 1e-18
        best_sse[better] = val[better]
        best[better, 0] = p1[better]
        best[better, 1] = p2[better]

    det = g11 * g22 - g12 * g12
    with np.errstate(divide="ignore", invalid="ignore"):
        u1 = (g22 * r1 - g12 * r2) / det
        u2 = (g11 * r2 - g12 * r1) / det
    ok = (np.abs(det) > 1e-14 * np.maximum(g11 * g22, 1e-300)) & np.isfinite(u1) & np.isfinite(u2)
    ok &= (u1 >= lo[0] - 1e-15) & (u1 <= hi[0] + 1e-15) & (u2 >= lo[1] - 1e-15) & (u2 <= hi[1] + 1e-15)
    consider(np.clip(np.nan_to_num(u1), lo[0], hi[0]), np.clip(np.nan_to_num(u2), lo[1], hi[1]), ok)
    every = np.ones(G, dtype=bool)
    for bnd1 in (lo[0], hi[0]):  # p1 at a bound, p2 free then clipped
        with np.errstate(divide="ignore", invalid="ignore"):
            p2 = np.where(g22 > 0, (r2 - bnd1 * g12) / g22, lo[1])
        consider(np.full(G, bnd1), np.clip(p2, lo[1], hi[1]), every)
    for bnd2 in (lo[1], hi[1]):
        with np.errstate(divide="ignore", invalid="ignore"):
            p1 = np.where(g11 > 0, (r1 - bnd2 * g12) / g11, lo[0])
        consider(np.clip(p1, lo[0], hi[0]), np.full(G, bnd2), every)
    return best, np.maximum(best_sse, 0.0)


def fit_exponential_decay(
    speeds_kmh, y, *, a=None, b=None, bounds: Mapping[str, tuple[float, float]] | None = None, n_alpha_grid: int = 401
) -> tuple[ExponentialDecay, float]:
    """Bounded least squares of ``y_j ~ a_j + b_j mu(v_j)`` over (mu_s, mu_k, alpha); returns (law, SSE).

    speeds_kmh: km/h; ``a`` (default 0) and ``b`` (default 1) per point model the FE response
    ``SN = a + b mu``. Variable projection: for fixed alpha the model is linear in (mu_k, mu_s) and the
    box-constrained 2-unknown problem is solved exactly (KKT enumeration: interior, four edges); alpha (s/m)
    is searched on a grid of ``n_alpha_grid`` values over its bounds and refined with bounded Brent
    (:func:`skidsim.calibration.brent.minimize_bounded`, scipy's ``minimize_scalar(method="bounded")``) between
    the neighbours of the best grid value. Handles non-convex or non-monotone data (the best law within the
    bounds). Where the data do not identify all three parameters (a flat curve), the first best grid value
    wins: the fitted curve is unique, the parameters are not.
    """
    bnd = dict(DEFAULT_BOUNDS if bounds is None else bounds)
    v = np.asarray(speeds_kmh, dtype=float)
    y = np.asarray(y, dtype=float)
    a = np.zeros_like(y) if a is None else np.broadcast_to(np.asarray(a, dtype=float), y.shape)
    b = np.ones_like(y) if b is None else np.broadcast_to(np.asarray(b, dtype=float), y.shape)
    if v.shape != y.shape or v.ndim != 1 or v.size < 3:
        raise ValueError(f"need >= 3 points with matching speeds and values, got {v.shape} and {y.shape}")
    for name in PARAMS:
        lo_, hi_ = bnd[name]
        if not (hi_ >= lo_):
            raise ValueError(f"bounds for {name} must satisfy lo <= hi, got {bnd[name]}")
    s = v / KMH_PER_MS
    z = y - a
    lo = np.array([bnd["mu_k"][0], bnd["mu_s"][0]], dtype=float)
    hi = np.array([bnd["mu_k"][1], bnd["mu_s"][1]], dtype=float)

    def solve(alphas):
        e = np.exp(-np.outer(np.atleast_1d(alphas), s))
        return box_ls2_many(b * (1.0 - e), b * e, z, lo, hi)

    alo, ahi = (float(x) for x in bnd["alpha"])
    grid = np.linspace(alo, ahi, max(int(n_alpha_grid), 2))
    _, sse = solve(grid)
    i = int(np.argmin(sse))
    best_alpha, best_sse = float(grid[i]), float(sse[i])
    left, right = float(grid[max(i - 1, 0)]), float(grid[min(i + 1, len(grid) - 1)])
    if right > left:
        x, fun, ok = minimize_bounded(lambda al: float(solve(al)[1][0]), left, right, xatol=1e-12, maxiter=200)
        if ok and fun < best_sse:
            best_alpha, best_sse = x, fun
    p, sse1 = solve(best_alpha)
    return ExponentialDecay(mu_s=float(p[0, 1]), mu_k=float(p[0, 0]), alpha=best_alpha), float(sse1[0])


def invert_law_kmh(law: ExponentialDecay, mu_target: float) -> float | None:
    """Speed (km/h) at which ``law`` gives ``mu_target``; None when the law is flat or the value is out of range."""
    span = law.mu_s - law.mu_k
    if not (law.alpha > 1e-9 and abs(span) > 1e-9 and math.isfinite(mu_target)):
        return None
    r = (mu_target - law.mu_k) / span
    if not (0.0 < r <= 1.0):
        return None
    return -math.log(r) / law.alpha * KMH_PER_MS
