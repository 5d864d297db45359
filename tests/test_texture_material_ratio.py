"""Sk family and volume parameters against the analytic normal distribution and surfalize."""

import math

import numpy as np
import pytest
from scipy import integrate, stats

from skidsim.texture.material_ratio import MaterialRatio, core_height, material_ratio_parameters

SIGMA = 0.3  # mm


def normal_heights(rows=300, cols=400, seed=1):
    """Heights at the exact normal quantiles (k + 0.5)/N, shuffled onto the grid: no sampling scatter."""
    n = rows * cols
    q = stats.norm.ppf((np.arange(n) + 0.5) / n) * SIGMA
    return np.random.default_rng(seed).permutation(q).reshape(rows, cols)


def vm(c):  # E[max(Z - c, 0)], Z ~ N(0, SIGMA^2)
    u = c / SIGMA
    return SIGMA * (stats.norm.pdf(u) - u * stats.norm.sf(u))


def vv(c):  # E[max(c - Z, 0)]
    u = c / SIGMA
    return SIGMA * (stats.norm.pdf(u) + u * stats.norm.cdf(u))


def analytic():
    h = lambda m: SIGMA * stats.norm.ppf(1 - m / 100)  # noqa: E731  material ratio curve, m in %
    # equivalent line: least-squares fit over the central 40 % window, which is [30, 70] % for a symmetric curve
    num = integrate.quad(lambda m: (m - 50) * h(m), 30, 70)[0]
    den = integrate.quad(lambda m: (m - 50) ** 2, 30, 70)[0]
    slope = num / den
    upper, lower = -50 * slope, 50 * slope
    cp, cq = h(10.0), h(80.0)
    smr1 = 100 * stats.norm.sf(upper / SIGMA)
    smr2 = 100 * stats.norm.sf(lower / SIGMA)
    sa1, sa2 = vm(upper), vv(lower)
    return {
        "Vm": vm(cp),
        "Vv": vv(cp),
        "Vmp": vm(cp),
        "Vmc": vm(cq) - vm(cp),
        "Vvc": vv(cp) - vv(cq),
        "Vvv": vv(cq),
        "Sk": upper - lower,
        "Smr1": smr1,
        "Smr2": smr2,
        "Sa1": sa1,
        "Sa2": sa2,
        "Spk": 2 * sa1 * 100 / smr1,
        "Svk": 2 * sa2 * 100 / (100 - smr2),
    }


def test_normal_heights_against_analytic():
    got = material_ratio_parameters(normal_heights())
    for k, v in analytic().items():
        assert got[k] == pytest.approx(v, rel=0.01), k
    assert core_height(normal_heights()) == pytest.approx(analytic()["Sk"], rel=0.01)  # Sk alone


def test_exact_volumes_on_small_set():
    z = np.array([[3.0, 1.0], [0.0, -2.0]])
    mrc = MaterialRatio(z)
    assert mrc.volume_above(0.5) == pytest.approx((2.5 + 0.5) / 4)
    assert mrc.volume_below(0.5) == pytest.approx((0.5 + 2.5) / 4)
    assert mrc.smr(1.0) == pytest.approx(50.0)
    assert mrc.smc(0.0) == 3.0 and mrc.smc(100.0) == -2.0


@pytest.mark.peer
def test_against_surfalize():
    surfalize = pytest.importorskip("surfalize")
    z = normal_heights(200, 250, seed=4) ** 3 / SIGMA**2  # skewed, heavy tails
    z -= z.mean()
    s = surfalize.Surface(z, 0.05, 0.05)
    got = material_ratio_parameters(z)
    for k in ("Vmp", "Vmc", "Vvc", "Vvv", "Sk", "Spk", "Svk", "Smr1", "Smr2"):
        assert got[k] == pytest.approx(getattr(s, k)(), rel=0.01), k


def _select_fields():
    """Heights the selection must order exactly: 0.01 mm codes (ties) with a tilt, an LS-40-like flat binder
    (most points on a few codes), spikes far outside the body (most bins empty) and a continuous field."""
    rng = np.random.default_rng(11)
    rows, cols = 1000, 1200  # 1.2 million points: bins of 5 points, few of them read by the 10,001 classes
    yy, xx = np.mgrid[0:rows, 0:cols]
    codes = np.round(rng.normal(0, 0.4, (rows, cols)) / 0.01) * 0.01
    binder = np.where(rng.random((rows, cols)) < 0.9, 0.0, np.round(rng.gamma(2, 0.3, (rows, cols)) / 0.01) * 0.01)
    spiky = rng.normal(0, 0.2, (rows, cols))
    spiky.flat[rng.choice(spiky.size, 30, replace=False)] = rng.choice([-50.0, 60.0], 30)
    top = rng.standard_normal((rows, cols))
    top.flat[rng.choice(top.size, 40, replace=False)] = top.max()  # ties at the maximum: the range's last bin
    top.flat[rng.choice(top.size, 40, replace=False)] = np.nextafter(top.max(), -np.inf)
    return {
        "ties at the top": top,
        "codes with tilt": codes + 2.618034e-4 * xx - 1.414214e-4 * yy,  # about 0.3 deg of tilt at 0.05 mm
        "codes": codes,
        "flat binder": binder + 1e-6 * xx,
        "spikes": spiky,
        "continuous": rng.standard_normal((rows, cols)),
    }


@pytest.mark.parametrize("name", list(_select_fields()))
def test_selected_order_statistics_are_the_sorted_heights(name):
    """The curve's heights by value bins are those of one whole sort, bit for bit, on ties, spikes and flat binder.
    Where many points share the bins the classes fall in (codes without tilt, flat binder, spikes that stretch
    the bins' range) the curve is read from one whole sort instead."""
    z = _select_fields()[name]
    desc = np.sort(z.ravel())[::-1]
    mrc = MaterialRatio(z)
    mr = np.linspace(0.0, 100.0, 10001)
    pos = mr / 100.0 * (z.size - 1)
    i0 = np.floor(pos).astype(int)
    i1 = np.minimum(i0 + 1, z.size - 1)
    w = pos - i0
    np.testing.assert_array_equal(mrc.smc(mr), desc[i0] * (1 - w) + desc[i1] * w)
    assert mrc.smc(0.0) == desc[0] and mrc.smc(100.0) == desc[-1]
    binned = mrc._binning.sorted_all is None
    assert binned == (name in ("codes with tilt", "continuous", "ties at the top")), "which path ran"
    if name == "ties at the top":  # the 80 highest heights: read from the bin the maximum is counted with
        np.testing.assert_array_equal(mrc.smc(np.arange(81) / (z.size - 1) * 100.0), desc[:81])
    c = float(np.median(z))
    assert mrc.smr(c) == 100.0 * np.count_nonzero(z >= c) / z.size
    assert mrc.volume_above(c) == pytest.approx(math.fsum(np.maximum(z - c, 0).ravel().tolist()) / z.size, rel=1e-13)
    assert mrc.volume_below(c) == pytest.approx(math.fsum(np.maximum(c - z, 0).ravel().tolist()) / z.size, rel=1e-13)


@pytest.mark.parametrize("name", list(_select_fields()))
def test_sk_alone_is_the_sk_of_the_whole_group(name):
    """``core_height`` (Sk without the volumes and ratios) gives the bits of ``material_ratio_parameters``' Sk on
    height codes with and without tilt, flat binder, spikes and continuous heights (the analytic Sk of the normal
    distribution: :func:`test_normal_heights_against_analytic`)."""
    z = _select_fields()[name]
    assert core_height(z) == material_ratio_parameters(z)["Sk"]
