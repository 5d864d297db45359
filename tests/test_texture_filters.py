"""Despeckle rules, invalid-point filling, form removal and the Butterworth band separation."""

import numpy as np
import pytest

from skidsim.surface import Surface
from skidsim.texture import despeckle, fill_invalid, remove_form, separate_bands
from skidsim.texture.filters import butterworth_gain, dct_radial_frequency, fit_form


def dct_cosine(n, k, d):
    """cos(pi k (j + 1/2) / n): an exact type-II DCT basis vector, wavelength 2 n d / k (mm)."""
    return np.cos(np.pi * k * (np.arange(n) + 0.5) / n), 2 * n * d / k


def test_bands_transmit_exact_butterworth_gains():
    rows, cols, d = 64, 480, 0.05
    cx, lam_x = dct_cosine(cols, 24, d)  # wavelength 2 mm: macro
    cy, lam_y = dct_cosine(rows, 30, d)  # wavelength 0.2133 mm: micro
    z = 0.3 * cx[None, :] + 0.01 * cy[:, None]
    bands = separate_bands(Surface(z, d, d), form="none")
    g_macro = lambda lam: butterworth_gain(1 / lam, 0.5, 2, "low") * butterworth_gain(1 / lam, 50, 2, "high")  # noqa: E731
    g_micro = lambda lam: butterworth_gain(1 / lam, 0.5, 2, "high")  # noqa: E731
    expected_macro = 0.3 * g_macro(lam_x) * cx[None, :] + 0.01 * g_macro(lam_y) * cy[:, None]
    expected_micro = 0.3 * g_micro(lam_x) * cx[None, :] + 0.01 * g_micro(lam_y) * cy[:, None]
    assert np.allclose(bands["macro"].heights, expected_macro, atol=1e-12)  # zero phase: pure scaling
    assert np.allclose(bands["micro"].heights, expected_micro, atol=1e-12)
    assert np.allclose(bands["raw"].heights, z, atol=1e-12)


def test_gain_is_half_at_cutoff_and_bands_are_complementary():
    assert butterworth_gain(np.array([2.0]), 0.5, 2)[0] == pytest.approx(0.5)
    assert butterworth_gain(np.array([1 / 50]), 50.0, 3, "high")[0] == pytest.approx(0.5)
    rng = np.random.default_rng(0)
    z = rng.standard_normal((40, 50))
    b = separate_bands(Surface(z, 0.05, 0.05), macro=(0.5, 50.0), form="none")
    # macro + micro = raw minus what the 50 mm high-pass removes from the long waves
    from scipy import fft

    f = dct_radial_frequency(z.shape, 0.05, 0.05)
    raw = b["raw"].heights  # form "none": the mean removed
    waviness = fft.idctn(
        fft.dctn(raw, norm="ortho") * butterworth_gain(f, 0.5, 2) * butterworth_gain(f, 50, 2), norm="ortho"
    )
    assert np.allclose(b["macro"].heights + b["micro"].heights + waviness, raw, atol=1e-12)
    assert np.allclose(raw, z - z.mean(), atol=1e-14)


def test_form_removal_recovers_polynomial():
    rows, cols = 30, 40
    y, x = np.mgrid[0:rows, 0:cols] * 0.1
    plane = 0.5 + 0.02 * x - 0.03 * y
    quad = plane + 0.004 * x * x - 0.002 * x * y
    rng = np.random.default_rng(1)
    noise = rng.standard_normal((rows, cols)) * 1e-3
    s = Surface(plane + noise, 0.1, 0.1)
    out = remove_form(s, "plane").heights
    # the residual of a plane fit equals the residual of the noise alone (linearity of least squares)
    assert np.allclose(out, remove_form(Surface(noise, 0.1, 0.1), "plane").heights, atol=1e-12)
    assert np.allclose(fit_form(Surface(quad, 0.1, 0.1), 2), quad, atol=1e-12)
    holes = quad.copy()
    holes[5:9, 10:20] = np.nan  # the valid-point path gives the same fit
    assert np.allclose(fit_form(Surface(holes, 0.1, 0.1), 2), quad, atol=1e-10)
    with pytest.raises(ValueError, match="form"):
        fit_form(s, "cubic")


def test_fill_invalid_linear_is_exact_on_a_plane():
    y, x = np.mgrid[0:20, 0:30].astype(float)
    z = 0.1 * x + 0.2 * y
    holes = z.copy()
    holes[3, 4:9] = np.nan
    holes[7, :] = np.nan  # a wholly invalid row: filled along y
    out = fill_invalid(Surface(holes, 0.05, 0.05)).heights
    assert np.allclose(out, z)
    assert not np.isnan(fill_invalid(Surface(holes, 0.05, 0.05), "nearest").heights).any()
    with pytest.raises(ValueError, match="method"):
        fill_invalid(Surface(holes, 0.05, 0.05), "spline")


def test_tukey_despeckle_removes_exactly_the_spikes():
    rng = np.random.default_rng(2)
    x = np.arange(500) * 0.05
    base = np.sin(2 * np.pi * x / 3.0) * 0.3 + rng.standard_normal(500) * 0.001
    z = np.tile(base, (4, 1))
    z[1, 100] += 5.0
    z[2, 300] -= 4.0
    out, n = despeckle(Surface(z, 0.05, 0.05), "tukey")
    assert n == 2
    assert out.heights[1, 100] == pytest.approx(0.5 * (z[1, 99] + z[1, 101]))  # re-interpolated
    assert np.array_equal(out.heights[0], z[0])
    # offset invariance of Tukey fences
    out2, n2 = despeckle(Surface(z + 100.0, 0.05, 0.05), "tukey")
    assert n2 == 2 and np.allclose(out2.heights - 100.0, out.heights)


def test_study_rule_as_written_and_its_offset_dependence():
    row = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 100.0, 0.5, 3.0])
    q1, q3 = np.percentile(row, [25, 75])
    out, n = despeckle(Surface(row[None, :], 1.0, 1.0), "study")
    expected = np.where(row > 1.5 * q3, q3, np.where(row < 1.5 * q1, q1, row))
    assert np.array_equal(out.heights[0], expected)
    assert n == int(np.sum(row > 1.5 * q3) + np.sum(row < 1.5 * q1))
    # the same profile shifted by +1000 mm: the literal fences replace nothing (misbehaviour documented)
    _, n_shift = despeckle(Surface(row[None, :] + 1000.0, 1.0, 1.0), "study")
    assert n_shift != n


def test_despeckle_axis_and_mad_and_errors():
    z = np.zeros((50, 6))
    z[:, 3] = np.linspace(0, 1, 50)
    z[25, 3] = 40.0
    s = Surface(z, 0.05, 0.05)
    out, n = despeckle(s, "mad", axis=0)
    assert n == 1 and out.heights[25, 3] == pytest.approx(0.5 * (z[24, 3] + z[26, 3]))
    with pytest.raises(ValueError, match="method"):
        despeckle(s, "median")
    with pytest.raises(ValueError, match="axis"):
        despeckle(s, axis=2)


def test_mad_and_local_keep_genuine_voids_that_tukey_clips():
    from scipy import ndimage

    rng = np.random.default_rng(4)
    f = ndimage.gaussian_filter1d(rng.standard_normal(1200), 25)
    f /= f.std()
    prof = 0.6 * np.minimum(f, 0.7) + 0.01 * rng.standard_normal(1200)  # flat tops, deep voids
    prof[[150, 420, 800]] += [4.0, -3.5, 5.0]
    s = Surface(prof[None, :], 0.05, 0.05)
    keep = np.ones(1200, bool)
    keep[[150, 420, 800]] = False
    for method in ("mad", "local"):  # mad: k = 3.5 robust sigma per row; local (default): isolated 2-D outliers
        out, n = despeckle(s, method)
        assert n == 3, method
        assert np.array_equal(out.heights[0][keep], prof[keep]), method
    assert despeckle(s, "tukey")[1] > 3  # Tukey's lower fence cuts into the void bottoms


def test_crop_y_centred_keeps_the_middle_band_and_the_grid():
    """The quick configuration's crop: the centred rows spanning the extent, every column, the same spacings."""
    from skidsim.errors import ConfigError
    from skidsim.texture import TextureOptions

    h = np.arange(101 * 7, dtype=float).reshape(101, 7)  # row i holds 7 i .. 7 i + 6
    s = Surface(h, dx=0.05, dy=0.1)
    c = s.crop_y_centred(4.0)  # 4 mm / 0.1 mm = 40 intervals -> 41 rows, first row (101 - 41) // 2 = 30
    assert c.shape == (41, 7) and c.dx == 0.05 and c.dy == 0.1
    assert c.heights[0, 0] == 7 * 30 and c.heights[-1, -1] == 7 * 70 + 6
    assert abs(c.height_mm - 4.0) < 1e-12
    assert s.crop_y_centred(1e3).shape == s.shape  # capped at the scan
    with pytest.raises(ValueError, match="positive number of mm"):
        s.crop_y_centred(0.0)
    assert TextureOptions(crop_y_mm=50.0).crop_y_mm == 50.0
    with pytest.raises(ConfigError, match="texture.crop_y_mm"):
        TextureOptions(crop_y_mm=-1.0)
