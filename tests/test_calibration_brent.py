"""The calibration's scipy stand-ins give scipy's numbers, bit for bit: the bounded Brent step
(skidsim.calibration.brent, as scipy.optimize.minimize_scalar(method="bounded")) and the chi-square quantile of the
identifiability record (as scipy.stats.chi2.ppf). Both exist so that the calibrate and identifiability jobs need not
import scipy.optimize / scipy.stats (docs/workflow.md, "Per-job fixed cost")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skidsim.calibration.brent import minimize_bounded
from skidsim.calibration.identifiability.profile import _CHI2_PPF, chi2_ppf


def _cases():
    rng = np.random.default_rng(20261129)
    s = np.array([20.0, 30.0, 40.0, 50.0, 60.0, 70.0]) / 3.6
    y = 0.35 + 0.4 * np.exp(-0.05 * s) + 0.01 * rng.standard_normal(s.size)
    yield "exp_sse", lambda al: float(np.sum((0.35 + 0.4 * np.exp(-al * s) - y) ** 2)), 0.0, 0.3, 1e-12, 200
    yield "exp_sse_narrow", lambda al: float(np.sum((0.35 + 0.4 * np.exp(-al * s) - y) ** 2)), 0.04, 0.06, 1e-10, 500
    yield "quadratic", lambda x: (x - 0.3) ** 2, -1.0, 2.0, 1e-5, 500
    yield "min_at_bound", lambda x: x, 1.0, 3.0, 1e-8, 500
    yield "flat", lambda x: 1.0, 0.0, 1.0, 1e-10, 500
    yield "wiggly", lambda x: math.sin(5 * x) + 0.1 * x * x, -3.0, 3.0, 1e-9, 500
    yield "few_iterations", lambda x: math.cos(x), 0.0, 6.0, 1e-14, 5  # maxiter reached: not a success
    yield "nan", lambda x: math.nan, 0.0, 1.0, 1e-5, 500
    yield "point", lambda x: (x - 1.0) ** 2, 0.5, 0.5, 1e-5, 500


@pytest.mark.parametrize("name,func,lo,hi,xatol,maxiter", list(_cases()), ids=[c[0] for c in _cases()])
def test_minimize_bounded_is_scipys_bounded_brent(name, func, lo, hi, xatol, maxiter):
    from scipy.optimize import minimize_scalar

    ref = minimize_scalar(func, bounds=(lo, hi), method="bounded", options={"xatol": xatol, "maxiter": maxiter})
    x, fun, ok = minimize_bounded(func, lo, hi, xatol=xatol, maxiter=maxiter)
    assert ok == bool(ref.success)
    np.testing.assert_array_equal([x, fun], [float(ref.x), float(ref.fun)])  # bit for bit (NaN equals NaN)


def test_minimize_bounded_rejects_bad_bounds():
    with pytest.raises(ValueError, match="lower bound exceeds"):
        minimize_bounded(lambda x: x, 1.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        minimize_bounded(lambda x: x, 0.0, math.inf)


def test_chi2_ppf_is_scipys():
    from scipy.stats import chi2

    qs = [*np.linspace(0.0, 1.0, 2001), 0.6827, 0.9, 0.95, 0.99, 1e-300, 1.0 - 1e-16, -0.1, 1.1]
    for df in (1, 2, 3):
        np.testing.assert_array_equal([chi2_ppf(q, df) for q in qs], [float(chi2.ppf(q, df)) for q in qs])
    for (q, df), value in _CHI2_PPF.items():  # the table of common levels
        assert value == float(chi2.ppf(q, df))
