"""Bounded scalar minimisation: Brent's method on an interval, as ``scipy.optimize.minimize_scalar`` with
``method="bounded"`` computes it.

The algorithm is scipy's ``_minimize_scalar_bounded`` (scipy/optimize/_optimize.py, BSD-3-Clause), statement for
statement, so that every number is the one scipy gives (tests/test_calibration_brent.py compares them). It is here
because ``import scipy.optimize`` costs about 0.3 s (it loads scipy.linalg, scipy.spatial, scipy.fft and
scipy.special) in every job that fits a law (calibrate with method ours, validate_speeds for its identifiability
records), and those jobs need nothing else of it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np


def minimize_bounded(
    func: Callable[[float], float], lo: float, hi: float, *, xatol: float = 1e-5, maxiter: int = 500
) -> tuple[float, float, bool]:
    """Minimise ``func`` over ``[lo, hi]``; returns ``(x, fun, success)`` as ``minimize_scalar(func, bounds=(lo,
    hi), method="bounded", options={"xatol": xatol, "maxiter": maxiter})`` gives ``res.x``, ``res.fun`` and
    ``res.success`` (False when ``maxiter`` evaluations were reached or a value is NaN)."""
    x1, x2 = lo, hi
    if not (np.size(x1) == 1 and np.isfinite(x1) and np.size(x2) == 1 and np.isfinite(x2)):
        raise ValueError("Optimization bounds must be finite scalars.")
    if x1 > x2:
        raise ValueError("The lower bound exceeds the upper bound.")
    maxfun = maxiter
    flag = 0
    sqrt_eps = math.sqrt(2.2e-16)
    golden_mean = 0.5 * (3.0 - math.sqrt(5.0))
    a, b = x1, x2
    fulc = a + golden_mean * (b - a)
    nfc, xf = fulc, fulc
    rat = e = 0.0
    x = xf
    fx = func(x)
    num = 1
    fu = np.inf
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * np.abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while np.abs(xf - xm) > (tol2 - 0.5 * (b - a)):
        golden = 1
        if np.abs(e) > tol1:  # parabolic fit
            golden = 0
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = np.abs(q)
            r = e
            e = rat
            if (np.abs(p) < np.abs(0.5 * q * r)) and (p > q * (a - xf)) and (p < q * (b - xf)):  # acceptable
                rat = (p + 0.0) / q
                x = xf + rat
                if ((x - a) < tol2) or ((b - x) < tol2):
                    si = np.sign(xm - xf) + ((xm - xf) == 0)
                    rat = tol1 * si
            else:
                golden = 1
        if golden:  # golden-section step
            if xf >= xm:
                e = a - xf
            else:
                e = b - xf
            rat = golden_mean * e
        si = np.sign(rat) + (rat == 0)
        x = xf + si * np.maximum(np.abs(rat), tol1)
        fu = func(x)
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if (fu <= fnfc) or (nfc == xf):
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif (fu <= ffulc) or (fulc == xf) or (fulc == nfc):
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = sqrt_eps * np.abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxfun:
            flag = 1
            break
    if np.isnan(xf) or np.isnan(fx) or np.isnan(fu):
        flag = 2
    return float(xf), float(fx), flag == 0
