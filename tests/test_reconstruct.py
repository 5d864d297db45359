"""Tests of skidsim.reconstruct: C1 heightfield, area resampling, strip extraction, persistence."""

from __future__ import annotations

import numpy as np
import pytest

from skidsim.errors import InputError
from skidsim.reconstruct import (
    Heightfield,
    area_weights,
    gaussian_sigma_mm,
    pavement_strip,
    remove_mean_plane,
    resample_area,
    strip_length_mm,
)
from skidsim.surface import Surface


def _quad(x, y):
    """A full quadratic in x, y (m -> m)."""
    return 1e-3 * (0.3 + 2 * x - 3 * y + 40 * x * x - 25 * x * y + 60 * y * y)


def _quad_grad(x, y):
    return 1e-3 * (2 + 80 * x - 25 * y), 1e-3 * (-3 - 25 * x + 120 * y)


@pytest.fixture
def quad_hf():
    dx, dy = 0.5e-3, 0.4e-3
    x0, y0 = 0.01, -0.002
    x = x0 + dx * np.arange(30)
    y = y0 + dy * np.arange(20)
    X, Y = np.meshgrid(x, y)
    return Heightfield(_quad(X, Y), dx, dy, (x0, y0))


def test_quadratic_reproduced_exactly_including_edges(quad_hf):
    rng = np.random.default_rng(1)
    x0, x1, y0, y1 = quad_hf.extent
    px = np.concatenate([rng.uniform(x0, x1, 500), [x0, x1, x0, x1]])
    py = np.concatenate([rng.uniform(y0, y1, 500), [y0, y0, y1, y1]])
    z, zx, zy = quad_hf.evaluate(px, py)
    ex, ey = _quad_grad(px, py)
    np.testing.assert_allclose(z, _quad(px, py), rtol=0, atol=1e-15)
    # Slopes: exact in the interior and on the low edges; the high edges x = x1, y = y1 belong to the
    # constant extension (documented), so test them just inside.
    px[[-3, -1]] -= 1e-12
    py[[-2, -1]] -= 1e-12
    z, zx, zy = quad_hf.evaluate(px, py)
    ex, ey = _quad_grad(px, py)
    np.testing.assert_allclose(zx, ex, rtol=0, atol=1e-12)
    np.testing.assert_allclose(zy, ey, rtol=0, atol=1e-12)
    assert quad_hf.evaluate(x1, 0.5 * (y0 + y1))[1] == 0.0


def test_shapes_and_scalars(quad_hf):
    z, zx, zy = quad_hf.evaluate(0.0105, 0.0)
    assert np.shape(z) == () and np.isclose(float(z), _quad(0.0105, 0.0), atol=1e-15)
    X = np.full((3, 4), 0.012)
    Y = np.full((3, 4), 0.001)
    out = quad_hf.evaluate(X, Y)
    assert all(o.shape == (3, 4) for o in out)
    assert quad_hf.normal(X, Y).shape == (3, 4, 3)


def test_tilted_plane_normals_and_outside_extension():
    b, c = 0.12, -0.05  # slopes m/m
    x = 1e-3 * np.arange(11)
    y = 1e-3 * np.arange(7)
    X, Y = np.meshgrid(x, y)
    hf = Heightfield(0.002 + b * X + c * Y, 1e-3, 1e-3)
    rng = np.random.default_rng(2)
    px, py = rng.uniform(0, 0.01, 200), rng.uniform(0, 0.006, 200)
    n = hf.normal(px, py)
    expect = np.array([-b, -c, 1.0]) / np.sqrt(1 + b * b + c * c)
    np.testing.assert_allclose(n, np.broadcast_to(expect, n.shape), atol=1e-13)
    # Outside: constant extension across the edge passed, slope across it 0, slope along it kept.
    z, zx, zy = hf.evaluate(np.array([-0.003, 0.014, 0.004]), np.array([0.003, 0.003, 0.009]))
    np.testing.assert_allclose(
        z, [0.002 + c * 0.003, 0.002 + b * 0.010 + c * 0.003, 0.002 + b * 0.004 + c * 0.006], atol=1e-15
    )
    np.testing.assert_allclose(zx, [0.0, 0.0, b], atol=1e-13)
    np.testing.assert_allclose(zy, [c, c, 0.0], atol=1e-13)


def test_c1_continuity_across_cell_edges_and_fd_consistency():
    rng = np.random.default_rng(3)
    h = 0.5e-3
    hf = Heightfield(rng.normal(0, 1e-3, (9, 13)), h, h)
    eps = 1e-12  # m; slopes change by ~1e4 /m * 2 eps across the edge if C1
    y = np.linspace(0.0, hf.width_m, 41)
    for j in range(1, 12):  # interior vertical cell edges
        a = hf.evaluate(np.full_like(y, j * h - eps), y)
        b = hf.evaluate(np.full_like(y, j * h + eps), y)
        for k in range(3):
            np.testing.assert_allclose(a[k], b[k], atol=1e-6 if k else 1e-11)  # C0-only would jump O(1) in slope
    # Slopes are the derivatives of the height (central FD of the interpolant itself).
    px, py = rng.uniform(0.6e-3, 5.4e-3, 300), rng.uniform(0.6e-3, 3.4e-3, 300)
    d = 1e-8
    z, zx, zy = hf.evaluate(px, py)
    fdx = (hf.evaluate(px + d, py)[0] - hf.evaluate(px - d, py)[0]) / (2 * d)
    fdy = (hf.evaluate(px, py + d)[0] - hf.evaluate(px, py - d)[0]) / (2 * d)
    np.testing.assert_allclose(zx, fdx, atol=2e-6)
    np.testing.assert_allclose(zy, fdy, atol=2e-6)


def test_interpolates_nodes_and_catmull_rom_midpoint():
    rng = np.random.default_rng(4)
    h = 0.5e-3
    f = rng.normal(0, 1e-3, (6, 8))
    hf = Heightfield(f, h, h)
    X, Y = np.meshgrid(hf.x_m(), hf.y_m())
    np.testing.assert_allclose(hf.evaluate(X, Y)[0], f, atol=1e-18)
    # Along a node row the surface is 1-D Catmull-Rom: midpoint = (-f0 + 9 f1 + 9 f2 - f3) / 16.
    i, j = 3, 3
    z = hf.evaluate((j + 0.5) * h, i * h)[0]
    np.testing.assert_allclose(z, (-f[i, j - 1] + 9 * f[i, j] + 9 * f[i, j + 1] - f[i, j + 2]) / 16, atol=1e-18)


def test_third_order_convergence_on_smooth_function():
    def g(x, y):
        return 1e-3 * np.sin(2 * np.pi * x / 0.01) * np.cos(2 * np.pi * y / 0.008)

    errs = []
    rng = np.random.default_rng(5)
    px, py = rng.uniform(0.0, 0.02, 2000), rng.uniform(0.0, 0.016, 2000)
    for h in (1e-3, 0.5e-3, 0.25e-3):
        x = np.arange(0, 0.02 + h / 2, h)
        y = np.arange(0, 0.016 + h / 2, h)
        X, Y = np.meshgrid(x, y)
        hf = Heightfield(g(X, Y), h, h)
        errs.append(np.abs(hf.evaluate(px, py)[0] - g(px, py)).max())
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(rates > 2.7), rates


def test_area_weights_block_mean_and_brute_force():
    rng = np.random.default_rng(6)
    H = rng.normal(size=(40, 60))
    d = 0.05
    # Boxes of 10 pixels aligned with pixel edges: block mean.
    xc = (np.arange(6) * 10 + 4.5) * d
    yc = (np.arange(4) * 10 + 4.5) * d
    Z = resample_area(H, d, d, xc, yc, 10 * d, 10 * d)
    np.testing.assert_allclose(Z, H.reshape(4, 10, 6, 10).mean(axis=(1, 3)), atol=1e-14)
    # Non-integer ratio (2.5 px boxes at arbitrary offsets): compare with 4x sub-pixel brute force.
    xc = np.array([3.0, 7.3, 20.125, 41.0]) * d
    yc = np.array([5.0, 11.6, 30.2]) * d
    Z = resample_area(H, d, d, xc, yc, 2.5 * d, 2.5 * d)
    fine = np.repeat(np.repeat(H, 40, axis=0), 40, axis=1)  # sub-pixel size d/40
    fx = (np.arange(fine.shape[1]) + 0.5) * d / 40 - 0.5 * d
    fy = (np.arange(fine.shape[0]) + 0.5) * d / 40 - 0.5 * d
    for a, yy in enumerate(yc):
        for b, xx in enumerate(xc):
            mx = np.abs(fx - xx) < 1.25 * d
            my = np.abs(fy - yy) < 1.25 * d
            np.testing.assert_allclose(Z[a, b], fine[np.ix_(my, mx)].mean(), rtol=0, atol=0.02)
    # Exact version of the same check: weights integrate each pixel's overlap.
    w = area_weights(60, d, [1.25 * d], 2.5 * d)[0]  # box [0, 2.5 d]: half of pixel 0, pixels 1 and 2
    np.testing.assert_allclose(w[:4], [0.2, 0.4, 0.4, 0.0], atol=1e-12)
    np.testing.assert_allclose(w.sum(), 1.0)


def _scan(fun, W=124.0, H=60.0, d=0.05, name="synthetic"):
    x = np.arange(int(round(W / d)) + 1) * d
    y = np.arange(int(round(H / d)) + 1) * d
    X, Y = np.meshgrid(x, y)
    return Surface(fun(X, Y), d, d, name)


def test_pavement_strip_geometry_levelling_and_transfer():
    lam = 2.0  # mm, wavelength along x
    A = 0.4  # mm
    s = _scan(lambda X, Y: 3.0 + 0.01 * X - 0.02 * Y + A * np.sin(2 * np.pi * X / lam))
    hf = pavement_strip(s, smoothing=2.0)
    assert hf.shape == (81, 230)
    assert np.isclose(hf.length_m, 0.1143, rtol=0, atol=1e-12) and np.isclose(hf.width_m, 0.040, atol=1e-12)
    assert np.isclose(hf.dx_m, 0.1143 / 229)
    assert np.isclose(hf.meta["x0_mm"], (124.0 - 114.3) / 2) and np.isclose(hf.meta["y0_mm"], 10.0)
    assert np.isclose(hf.z_bottom_m, hf.min_height_m - 8e-3)
    # Removed plane: the scan's tilt (the sinusoid has near-zero projection on the plane).
    assert abs(hf.meta["removed_plane_mm"]["b_mm_per_mm"] - 0.01) < 2e-4
    assert abs(hf.meta["removed_plane_mm"]["c_mm_per_mm"] + 0.02) < 1e-6
    # Transfer: ISO Gaussian 50 % at its cutoff, times the box average sinc(h / lambda).
    hmm = hf.dx_m * 1e3
    gain = 0.5 * np.sinc(hmm / lam)
    x_scan = hf.meta["x0_mm"] + hmm * np.arange(hf.shape[1])
    row = hf.z_m[40] * 1e3
    B = np.column_stack(
        [np.sin(2 * np.pi * x_scan / lam), np.cos(2 * np.pi * x_scan / lam), np.ones_like(x_scan), x_scan]
    )
    coef = np.linalg.lstsq(B, row, rcond=None)[0]
    assert np.isclose(np.hypot(coef[0], coef[1]), A * gain, rtol=0.01)
    # No smoothing: long-wave content passes untouched (box average only).
    hf2 = pavement_strip(s, smoothing=None, x0_mm=1.0, y0_mm=2.0)
    x_scan = 1.0 + hmm * np.arange(hf2.shape[1])
    B = np.column_stack(
        [np.sin(2 * np.pi * x_scan / lam), np.cos(2 * np.pi * x_scan / lam), np.ones_like(x_scan), x_scan]
    )
    coef = np.linalg.lstsq(B, hf2.z_m[10] * 1e3, rcond=None)[0]
    assert np.isclose(np.hypot(coef[0], coef[1]), A * np.sinc(hmm / lam), rtol=0.01)
    # Levelled: mean zero, no tilt left.
    _, plane = remove_mean_plane(hf.z_m, hf.x_m(), hf.y_m())
    assert np.all(np.abs(plane) < 1e-12)


def test_gaussian_sigma_iso():
    assert np.isclose(gaussian_sigma_mm(1.0), np.sqrt(np.log(2) / np.pi) / np.sqrt(2 * np.pi))
    # transmission exp(-pi (alpha lc / lambda)^2) = 0.5 at lambda = lc  <=> exp(-2 pi^2 sigma^2 / lc^2) = 0.5
    assert np.isclose(np.exp(-2 * np.pi**2 * gaussian_sigma_mm(3.0) ** 2 / 9.0), 0.5)


def test_pavement_strip_bad_input():
    s = _scan(lambda X, Y: 0.0 * X, W=60.0, H=50.0, d=0.1)
    with pytest.raises(InputError) as e:
        pavement_strip(s)  # 114.3 mm does not fit in 60 mm
    assert e.value.column == "x0_mm"
    h = s.heights.copy()
    h[250, 300] = np.nan
    with pytest.raises(InputError) as e:
        pavement_strip(s.with_heights(h), length_mm=40.0, width_mm=20.0)
    assert e.value.column == "heights"
    with pytest.raises(InputError):
        pavement_strip(s, length_mm=40.0, width_mm=20.0, resolution_mm=-1)


def test_scan_shorter_than_strip_early_error_or_auto_length():
    """A scan 0.3 mm shorter than the study's 114.3 mm strip: a clear error naming the shortfall and the remedy,
    or with length_mm='auto' a strip of the scan's whole length."""
    s = _scan(lambda X, Y: 0.2 * np.sin(2 * np.pi * X / 7.0) + 0.01 * Y, W=114.0, H=50.0, d=0.05, name="short")
    assert s.width_mm == pytest.approx(114.0)
    with pytest.raises(
        InputError,
        match=r"short: column 'x0_mm'.*the scan is 0\.3 mm shorter than the 114\.3 mm "
        r"strip: give a longer scan, or length_mm='auto'",
    ):
        pavement_strip(s)
    hf = pavement_strip(s, length_mm="auto")
    assert hf.meta["length_mm"] == pytest.approx(114.0) and hf.meta["x0_mm"] == pytest.approx(0.0, abs=1e-12)
    assert hf.shape == (81, 229) and hf.length_m == pytest.approx(0.114)  # 228 cells of 0.5 mm
    assert strip_length_mm(s, "auto", x0_mm=4.0) == pytest.approx(110.0)
    long = _scan(lambda X, Y: 0.0 * X, W=124.0, H=50.0, d=0.1)
    assert pavement_strip(long, length_mm="auto").meta["length_mm"] == 114.3  # capped at the study's strip
    with pytest.raises(InputError, match="a strip length in mm or 'auto'"):
        pavement_strip(s, length_mm="fit")


def test_npz_round_trip_and_errors(tmp_path, quad_hf):
    hf = Heightfield(
        quad_hf.z_m, quad_hf.dx_m, quad_hf.dy_m, quad_hf.origin_m, -0.01, "site-A", {"x0_mm": 4.85, "nested": {"a": 1}}
    )
    p = hf.to_npz(tmp_path / "sub" / "pavement.npz")
    back = Heightfield.from_npz(p)
    assert np.array_equal(back.z_m, hf.z_m) and back.dx_m == hf.dx_m and back.dy_m == hf.dy_m
    assert back.origin_m == hf.origin_m and back.z_bottom_m == -0.01 and back.name == "site-A"
    assert back.meta == hf.meta
    assert list(tmp_path.joinpath("sub").iterdir()) == [p]  # no temporary left behind
    bad = tmp_path / "bad.npz"
    np.savez(bad, z_m=np.zeros((3, 3)), dx_m=1.0)
    with pytest.raises(InputError) as e:
        Heightfield.from_npz(bad)
    assert "bad.npz" in str(e.value) and e.value.column == "dy_m"
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(InputError):
        Heightfield.from_npz(tmp_path / "junk.npz")


def test_volume_bilinear_and_crop():
    x = 1e-3 * np.arange(5)
    y = 1e-3 * np.arange(4)
    X, Y = np.meshgrid(x, y)
    hf = Heightfield(1e-3 + 0.1 * X + 0.2 * Y, 1e-3, 1e-3, z_bottom_m=-2e-3)
    # plane over [0,4]x[0,3] mm: mean height at the centre (2, 1.5) mm
    mean_h = 1e-3 + 0.1 * 2e-3 + 0.2 * 1.5e-3 + 2e-3
    assert np.isclose(hf.volume_m3(), 12e-6 * mean_h, rtol=1e-12)
    assert np.isclose(hf.bilinear(1.5e-3, 2.25e-3), 1e-3 + 0.1 * 1.5e-3 + 0.2 * 2.25e-3)
    c = hf.crop((1e-3, 3e-3), (1e-3, 2e-3))
    assert c.shape == (2, 3) and c.origin_m == (1e-3, 1e-3)
    np.testing.assert_allclose(c.evaluate(2e-3, 1.5e-3)[0], hf.evaluate(2e-3, 1.5e-3)[0], atol=1e-15)
    with pytest.raises(InputError):
        Heightfield(np.full((3, 3), np.nan), 1e-3, 1e-3)


def test_simulate_command_takes_auto_strip_length(capsys):
    from skidsim.cli import build_parser

    base = ["simulate", "s.x3p", "--speed", "20", "--mu-s", "0.5", "--mu-k", "0.4", "--alpha", "0.1"]
    assert build_parser().parse_args(base).length_mm == 114.3
    assert build_parser().parse_args(base + ["--length-mm", "auto"]).length_mm == "auto"
    assert build_parser().parse_args(base + ["--length-mm", "100"]).length_mm == 100.0
    with pytest.raises(SystemExit):
        build_parser().parse_args(base + ["--length-mm", "fit"])
    assert "expected a length in mm or 'auto', got 'fit'" in capsys.readouterr().err


@pytest.mark.parametrize("shape", [(50, 60), (7, 300), (200, 9), (120, 150)])
@pytest.mark.parametrize("sigmas", [(0.3, 0.4), (1.0, 2.0), (2.7, 3.3), (5.5, 1.1), (12.0, 12.0)])
def test_gaussian_reflect_is_scipy_bit_for_bit(shape, sigmas):
    """The SciPy-free smoothing of pavement_strip gives SciPy's gaussian_filter bits (kernels longer than an
    axis go to SciPy itself)."""
    from scipy import ndimage

    from skidsim.reconstruct.resample import _gaussian_reflect

    a = np.random.default_rng(7).standard_normal(shape) * 3.0 + 1.0
    ref = ndimage.gaussian_filter(a, sigma=sigmas, mode="reflect", truncate=4.0)
    got = _gaussian_reflect(a, sigmas)
    assert got.dtype == ref.dtype and got.shape == ref.shape
    assert np.array_equal(got.view(np.int64), ref.view(np.int64))
