"""Height parameters, Sdq and Sdr against analytic sinusoids, independent formulas and surfalize."""

import numpy as np
import pytest
from scipy import integrate, stats

from skidsim.texture.height import height_parameters
from skidsim.texture.hybrid import developed_area, sdq, sdr


def _sine_x(rows=60, cols=400, dx=0.05, dy=0.05, amp=0.3, periods=4):
    lam = cols * dx / periods
    x = np.arange(cols) * dx
    return np.tile(amp * np.sin(2 * np.pi * x / lam), (rows, 1)), lam


def test_height_parameters_sinusoid_exact():
    z, _ = _sine_x()
    hp = height_parameters(z)
    # integer number of periods with >= 5 points per period: discrete sums of sin^2, sin^3, sin^4 are exact
    assert hp["Sq"] == pytest.approx(0.3 / np.sqrt(2), rel=1e-12)
    assert abs(hp["Ssk"]) < 1e-10
    assert hp["Sku"] == pytest.approx(1.5, rel=1e-10)
    assert hp["Sp"] == pytest.approx(0.3, rel=1e-9) and hp["Sv"] == pytest.approx(0.3, rel=1e-9)
    assert hp["Sz"] == pytest.approx(hp["Sp"] + hp["Sv"], rel=1e-15)


def test_height_parameters_match_independent_formulas():
    rng = np.random.default_rng(11)
    z = rng.gamma(2.0, 0.1, size=(50, 70)) - 3.0  # skewed, offset
    hp = height_parameters(z)
    c = z - z.mean()
    assert hp["Sq"] == pytest.approx(np.std(z), rel=1e-9)
    assert hp["Sa"] == pytest.approx(np.mean(np.abs(c)), rel=1e-9)
    assert hp["Ssk"] == pytest.approx(stats.skew(z.ravel()), rel=1e-9)
    assert hp["Sku"] == pytest.approx(stats.kurtosis(z.ravel(), fisher=False), rel=1e-9)
    assert hp["Sp"] == pytest.approx(c.max(), rel=1e-9) and hp["Sv"] == pytest.approx(-c.min(), rel=1e-9)


def test_sdq_sinusoid_analytic_and_discrete():
    rows, cols, dx, dy = 40, 800, 0.05, 0.04
    lam = 8.0  # mm, 10 periods along x
    x = np.arange(cols) * dx
    z = np.tile(0.2 * np.sin(2 * np.pi * x / lam), (rows, 1))
    # continuous: rms slope = A (2 pi / lam) / sqrt(2)
    assert sdq(z, dx, dy) == pytest.approx(0.2 * 2 * np.pi / lam / np.sqrt(2), rel=1e-3)
    # discretisation convention: forward differences, each direction averaged over its own differences
    d = np.diff(z[0])
    assert sdq(z, dx, dy) == pytest.approx(np.sqrt(np.mean(d * d)) / dx, rel=1e-9)


def test_sdr_one_dimensional_sinusoid_equals_arc_length():
    rows, cols, dx, dy = 30, 801, 0.05, 0.05
    lam, amp = 4.0, 0.4
    x = np.arange(cols) * dx
    z = np.tile(amp * np.sin(2 * np.pi * x / lam), (rows, 1))
    # a surface constant along y: D.15 gives the polyline length exactly; the continuous arc length differs by
    # the discretisation only (O((dx/lam)^2))
    length = integrate.quad(
        lambda t: np.sqrt(1 + (amp * 2 * np.pi / lam * np.cos(2 * np.pi * t / lam)) ** 2), 0, (cols - 1) * dx, limit=400
    )[0]
    expected = (length / ((cols - 1) * dx) - 1) * 100
    assert sdr(z, dx, dy) == pytest.approx(expected, rel=2e-3)
    poly = np.sum(np.sqrt(dx**2 + np.diff(z[0]) ** 2))
    assert developed_area(z, dx, dy) == pytest.approx(poly * (rows - 1) * dy, rel=1e-12)


@pytest.mark.peer
def test_height_sdq_sdr_against_surfalize():
    surfalize = pytest.importorskip("surfalize")
    rng = np.random.default_rng(3)
    from scipy import ndimage

    for sigma in (0.7, 3.0):  # rough (near Nyquist) and smooth
        z = ndimage.gaussian_filter(rng.standard_normal((90, 120)), sigma)
        s = surfalize.Surface(z, 0.05, 0.04)
        hp = height_parameters(z)
        for k in ("Sq", "Ssk", "Sku", "Sp", "Sv", "Sz", "Sa"):
            assert hp[k] == pytest.approx(getattr(s, k)(), rel=1e-9), k
        assert sdq(z, 0.05, 0.04) == pytest.approx(s.Sdq(), rel=1e-9)
        assert sdr(z, 0.05, 0.04) == pytest.approx(s.Sdr(), rel=1e-6)
