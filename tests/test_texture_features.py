"""Feature, motif and furrow parameters: isolated Gaussian bumps (analytic), surfalize's Wolf pruning,
concentric furrows (Cauchy-Crofton length)."""

import numpy as np
import pytest
from scipy import ndimage

from skidsim.texture.features import feature_parameters, motif_parameters, pruning_threshold, ten_point_height
from skidsim.texture.furrows import furrow_parameters
from skidsim.texture.segmentation import segment

AMPS = [1.0, 0.9, 0.8, 0.7, 0.6, 0.55, -1.2, -1.0, -0.9, -0.8, -0.7, -0.65]  # mm: 6 hills, 6 pits
SIG = 1.0  # mm


def bump_field(dx=0.1):
    rows, cols = 300, 400  # 30 x 40 mm
    y, x = np.mgrid[0:rows, 0:cols] * dx
    z = np.zeros((rows, cols))
    centres = [(py, px) for py in (6.0, 15.0, 24.0) for px in (6.0, 15.0, 24.0, 33.0)]
    for a, (py, px) in zip(AMPS, centres):
        z += a * np.exp(-((x - px) ** 2 + (y - py) ** 2) / (2 * SIG**2))
    return z, dx


def test_bump_field_feature_parameters_analytic():
    z, dx = bump_field()
    rows, cols = z.shape
    mean = sum(AMPS) * 2 * np.pi * SIG**2 / (rows * dx * cols * dx)  # analytic mean plane (integral / area)
    zc = z - z.mean()
    fp = feature_parameters(zc, dx, dx)
    hills = sorted([a for a in AMPS if a > 0], reverse=True)
    pits = sorted([-a for a in AMPS if a < 0], reverse=True)
    s5p = np.mean(hills[:5]) - mean
    s5v = np.mean(pits[:5]) + mean
    assert fp["S5p"] == pytest.approx(s5p, rel=0.01)
    assert fp["S5v"] == pytest.approx(s5v, rel=0.01)
    assert fp["S10z"] == pytest.approx(s5p + s5v, rel=0.01)
    assert fp["Spd"] == pytest.approx(6 / ((cols - 1) * dx * (rows - 1) * dx), rel=0.01)
    # peak curvature of a Gaussian: -(z_xx + z_yy)/2 = A / sigma^2; the local quadric fit (the S-filter) reads
    # low by the quartic terms: ~2 % on 5 x 5 points at 0.1 mm, ~0.6 % on 3 x 3
    assert fp["Spc"] == pytest.approx(np.mean(hills) / SIG**2, rel=0.03)
    fp3 = feature_parameters(zc, dx, dx, spc_half_window=1)
    assert fp3["Spc"] == pytest.approx(np.mean(hills) / SIG**2, rel=0.01)
    assert fp3["Spc"] > fp["Spc"]


def test_edge_exclusion_drops_border_motifs():
    z, dx = bump_field()
    zc = z - z.mean()
    all_ = feature_parameters(zc, dx, dx, exclude_edge=False)
    excl = feature_parameters(zc, dx, dx, exclude_edge=True)
    # every hill basin of -z spreads over the flat background to the border: all are edge motifs
    assert all_["Spd"] > 0 and excl["Spd"] < all_["Spd"]


def test_motifs_on_bumps():
    z, dx = bump_field()
    zc = z - z.mean()
    mp = motif_parameters(zc, dx, dx)
    assert mp["motif_count"] == 6
    assert mp["motif_threshold"] == pytest.approx(0.05 * (zc.max() - zc.min()))
    assert mp["motif_mean_area"] == pytest.approx((z.shape[0] - 0) * (z.shape[1]) * dx * dx / 6, rel=0.01)


def test_hill_volume_of_single_bump():
    dx = 0.1
    y, x = np.mgrid[0:201, 0:201] * dx
    z = 0.5 * np.exp(-((x - 10) ** 2 + (y - 10) ** 2) / (2 * SIG**2))
    zc = z - z.mean()
    seg = segment(-zc, pruning_threshold(zc, 5.0, "Sz"), dx, dx)
    assert seg.critical.size == 1  # one hill covering the surface
    # lone motif: base = its lowest point, volume = sum(z - min) dx dy = 2 pi A sigma^2 (the tails are ~0)
    assert seg.volume_mm3[0] == pytest.approx(2 * np.pi * 0.5 * SIG**2, rel=1e-3)
    assert feature_parameters(zc, dx, dx)["Shv"] == pytest.approx(2 * np.pi * 0.5 * SIG**2, rel=1e-3)


@pytest.mark.peer
@pytest.mark.parametrize("sigma", [1.0, 3.0])
def test_wolf_pruning_matches_surfalize(sigma):
    surfalize = pytest.importorskip("surfalize")
    rng = np.random.default_rng(5)
    z = ndimage.gaussian_filter(rng.standard_normal((160, 200)), sigma)
    zc = z - z.mean()
    fp_ref = surfalize.Surface(zc, 0.05, 0.05).get_feature_parameters()
    t = pruning_threshold(zc, 5.0, "Sz")
    for invert in (True, False):
        ref = fp_ref._segment(invert=invert, pruning=5, exclude_edge=False)
        ours = segment(-zc if invert else zc, t, 0.05, 0.05)
        got = {tuple(p) for p in np.column_stack(np.divmod(ours.critical_index, 200)).tolist()}
        assert got == {tuple(p) for p in ref.extrema.tolist()}
    s = surfalize.Surface(zc, 0.05, 0.05)
    fp = feature_parameters(zc, 0.05, 0.05, exclude_edge=True)
    assert fp["S5p"] == pytest.approx(s.S5p(), rel=1e-9)
    assert fp["S5v"] == pytest.approx(s.S5v(), rel=1e-9)
    assert fp["Spd"] == pytest.approx(s.Spd(), rel=1e-9)


def test_furrows_concentric_rings_crofton():
    d, n, lam = 0.05, 600, 1.5  # 30 x 30 mm, ring furrows every 1.5 mm
    y, x = np.mgrid[0:n, 0:n] * d
    r = np.hypot(x - 15.0, y - 15.0)
    z = 0.2 * (1 - np.cos(2 * np.pi * r / lam))  # minima (furrows) on circles r = k lam, depth 0.4 mm
    fp = furrow_parameters(z, d, d, window_mm=1.0, min_depth_pct=5.0)
    # true length per area: full circles inside the tested square (margin ~ window) over its area
    margin = 1.05
    side = (n - 1) * d - 2 * margin
    th = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    length = 0.0
    for k in range(1, 20):
        px, py = 15 + k * lam * np.cos(th), 15 + k * lam * np.sin(th)
        inside = (np.abs(px - 15) <= side / 2) & (np.abs(py - 15) <= side / 2)
        length += 2 * np.pi * k * lam * inside.mean()
    la_true = length / side**2 * 10  # cm/cm^2
    assert fp["Fden"] == pytest.approx(la_true, rel=0.05)
    assert fp["Fdmax"] == pytest.approx(0.4, rel=0.02)
    assert 0.2 < fp["Fdmean"] <= fp["Fdmax"]


def _coded_pavement(seed=3, rows=180, cols=220):
    """Correlated heights on 0.01 mm codes (ties, plateaus), mean removed."""
    rng = np.random.default_rng(seed)
    z = ndimage.gaussian_filter(rng.standard_normal((rows, cols)), 3.0)
    z = np.round(0.6 * z / z.std() / 0.01) * 0.01
    return z - z.mean()


@pytest.mark.parametrize("exclude_edge", [False, True])
@pytest.mark.parametrize("field", ["coded", "bumps"])
def test_ten_point_height_alone_equals_feature_parameters(field, exclude_edge):
    """S10z, S5p and S5v without areas, volumes and curvature: the same bits as feature_parameters'; the
    segmentation without measures keeps the critical points, edge flags and bases (a lone motif's base aside)."""
    if field == "coded":
        zc, dx = _coded_pavement(), 0.05
    else:
        z, dx = bump_field()
        zc = z - z.mean()
    full = feature_parameters(zc, dx, dx, exclude_edge=exclude_edge)
    alone = ten_point_height(zc, dx, dx, exclude_edge=exclude_edge)
    assert alone.keys() == {"S10z", "S5p", "S5v"}
    for k, v in alone.items():
        assert v == full[k], k
    t = pruning_threshold(zc, 5.0, "Sz")
    for d in (zc, -zc):
        a, b = segment(d, t, dx, dx), segment(d, t, dx, dx, measure=False)
        np.testing.assert_array_equal(a.critical_index, b.critical_index)
        np.testing.assert_array_equal(a.touches_edge, b.touches_edge)
        assert np.isnan(b.volume_mm3).all() and np.isnan(b.area_mm2).all()
        shared = np.isfinite(b.base)
        np.testing.assert_array_equal(a.base[shared], b.base[shared])
        assert (~shared).sum() <= 1  # only a lone motif (no saddle to another) has no base without the points
