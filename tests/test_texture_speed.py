"""The texture stage's speed changes of 2026-11-28 give the same numbers, bit for bit: each optimised function
against the form it had at commit 64ab885 (kept here: the same operations, names and `del`s aside), on fields
with ties (quantised heights), plateaus, long correlation, grooves and odd shapes."""

import math

import numpy as np
import pytest
from scipy import fft as sfft
from scipy import ndimage
from test_texture_despeckle import flat_binder_scan  # the flushed scans of the despeckle tests, one builder

from skidsim.texture import basins, pruning, saddles, spatial
from skidsim.texture import segmentation as seg
from skidsim.texture.hybrid import developed_area, hybrid_parameters, sdq, sdr
from skidsim.texture.material_ratio import MaterialRatio, material_ratio_parameters

# ---- the replaced implementations (skidsim.texture before 2026-11-28) ----------------------------------------

_OFFSETS = basins._OFFSETS
_EIGHT = np.ones((3, 3), dtype=bool)


def ref_catchment_basins(d):
    rows, cols = d.shape
    pad = np.full((rows + 2, cols + 2), np.inf)
    pad[1:-1, 1:-1] = d
    low = np.array(d, copy=True)
    code = np.full(d.shape, -1, dtype=np.int8)
    better = np.empty(d.shape, dtype=bool)
    for k, (oy, ox) in enumerate(_OFFSETS):
        nb = pad[1 + oy : 1 + oy + rows, 1 + ox : 1 + ox + cols]
        np.less(nb, low, out=better)
        np.minimum(low, nb, out=low)
        np.copyto(code, np.int8(k), where=better)
    markers, n = ndimage.label(code < 0, structure=_EIGHT)
    delta = np.array([oy * cols + ox for oy, ox in _OFFSETS] + [0], dtype=np.int32)
    ptr = np.arange(rows * cols, dtype=np.int32)
    ptr += delta[code.ravel()]
    for it in range(64):
        nxt = ptr[ptr]
        if it % 3 == 2 and np.array_equal(nxt, ptr):
            break
        ptr = nxt
    flat_markers = markers.ravel()
    labels = flat_markers[ptr].reshape(d.shape)
    if labels.dtype != np.int32:
        labels = labels.astype(np.int32)
    sink_idx = np.flatnonzero(flat_markers)
    _, first = np.unique(flat_markers[sink_idx], return_index=True)
    return labels, n, sink_idx[first]


def ref_boundary_pairs(labels, d):
    las, lbs, pours = [], [], []
    for sa, sb in (
        ((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
        ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
        ((slice(None, -1), slice(None, -1)), (slice(1, None), slice(1, None))),
        ((slice(None, -1), slice(1, None)), (slice(1, None), slice(None, -1))),
    ):
        la, lb = labels[sa], labels[sb]
        m = la != lb
        x, y = la[m], lb[m]
        p = np.maximum(d[sa][m], d[sb][m])
        if x.size:
            starts = np.flatnonzero(np.r_[True, (x[1:] != x[:-1]) | (y[1:] != y[:-1])])
            x, y, p = x[starts], y[starts], np.minimum.reduceat(p, starts)
        las.append(x)
        lbs.append(y)
        pours.append(p)
    return (np.concatenate(las).astype(np.int64) - 1, np.concatenate(lbs).astype(np.int64) - 1, np.concatenate(pours))


def ref_dedupe_edges(a, b, pour, n):
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    if lo.size == 0:
        return lo, hi, pour
    key = lo * (n + 1) + hi
    order = np.argsort(key)
    key = key[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    saddle = np.minimum.reduceat(pour[order], starts)
    first = order[starts]
    return lo[first], hi[first], saddle


def ref_segment(d, threshold_mm, dx, dy):
    labels, n, sink = ref_catchment_basins(d)
    flat = d.ravel()
    crit_val = flat[sink]
    t = float(threshold_mm)
    a, b, sad = ref_dedupe_edges(*ref_boundary_pairs(labels, d), n)
    motif_root, a, b, sad = pruning._contract_leaves(a, b, sad, crit_val, t)
    roots, motif_of_basin = np.unique(motif_root, return_inverse=True)
    m = roots.size
    crit = crit_val[roots]
    ma, mb = motif_of_basin[a], motif_of_basin[b]
    diff = ma != mb
    base = np.full(m, np.inf)
    np.minimum.at(base, ma[diff], sad[diff])
    np.minimum.at(base, mb[diff], sad[diff])
    pix_motif = motif_of_basin[labels.ravel() - 1]
    area = np.bincount(pix_motif, minlength=m).astype(float) * dx * dy
    lone = ~np.isfinite(base)
    if lone.any():
        mx = np.full(m, -np.inf)
        np.maximum.at(mx, pix_motif, flat)
        base[lone] = mx[lone]
    w = base[pix_motif] - flat
    np.maximum(w, 0.0, out=w)
    vol = np.bincount(pix_motif, weights=w, minlength=m) * dx * dy
    border = np.unique(np.concatenate([labels[0, :], labels[-1, :], labels[:, 0], labels[:, -1]]))
    edge = np.zeros(m, dtype=bool)
    edge[motif_of_basin[border - 1]] = True
    srt = np.argsort(crit, kind="stable")
    inv = np.empty(m, dtype=np.int64)
    inv[srt] = np.arange(m)
    return dict(
        critical_index=sink[roots][srt],
        critical=crit[srt],
        base=base[srt],
        area_mm2=area[srt],
        volume_mm3=vol[srt],
        touches_edge=edge[srt],
        motif_of_basin=inv[motif_of_basin],
        labels=labels,
    )


def ref_autocorrelation(z, max_lag_fraction=1.0):
    rows, cols = z.shape
    ly = int(np.floor(max_lag_fraction * (rows - 1)))
    lx = int(np.floor(max_lag_fraction * (cols - 1)))
    c = z - z.mean()
    shape = (sfft.next_fast_len(rows + ly, real=True), sfft.next_fast_len(cols + lx, real=True))
    spec = sfft.rfft2(c, s=shape)
    power = spec.real**2
    power += spec.imag**2
    full = sfft.irfft2(power, s=shape)
    acf = full[np.ix_(np.r_[shape[0] - ly : shape[0], 0 : ly + 1], np.r_[shape[1] - lx : shape[1], 0 : lx + 1])]
    acf /= (rows - np.abs(np.arange(-ly, ly + 1)))[:, None]
    acf /= (cols - np.abs(np.arange(-lx, lx + 1)))[None, :]
    acf /= acf[ly, lx]
    return acf, power, shape


def ref_spatial_parameters(z, dx, dy, s=0.2, on_border="nan"):
    acf, power, shape = ref_autocorrelation(z, max_lag_fraction=0.5)
    std = spatial.texture_direction(power, shape, dx, dy, 0.5)
    ang, lengths = spatial.decay_lengths(acf, dx, dy, s=s)  # unchanged but for the crop's helper
    within = bool(np.isfinite(lengths).all())
    if not np.isfinite(lengths).any():
        return np.nan, np.nan, std, lengths
    sal = float(np.nanmin(lengths))
    stri = sal / float(np.nanmax(lengths)) if within or on_border == "bound" else np.nan
    return sal, stri, std, lengths


def ref_sdq(z, dx, dy):
    gx = np.diff(z, axis=1)
    gy = np.diff(z, axis=0)
    mx = float(np.einsum("ij,ij->", gx, gx)) / gx.size / dx**2
    my = float(np.einsum("ij,ij->", gy, gy)) / gy.size / dy**2
    return float(np.sqrt(mx + my))


def ref_developed_area(z, dx, dy):
    gx = np.diff(z, axis=1)
    gx *= dy
    np.square(gx, out=gx)
    gy = np.diff(z, axis=0)
    gy *= dx
    np.square(gy, out=gy)
    cz = (dx * dy) ** 2
    total = 0.0
    for xs in (gx[:-1, :], gx[1:, :]):
        for ys in (gy[:, :-1], gy[:, 1:]):
            t = xs + ys
            t += cz
            np.sqrt(t, out=t)
            total += float(t.sum())
    return 0.25 * total


class RefMaterialRatio(MaterialRatio):
    """The curve read from one whole sort of the heights, the volumes as exact sums (``math.fsum``)."""

    def __init__(self, z, n_classes=10001):
        super().__init__(z, n_classes)
        self.desc = np.sort(self.z)[::-1]

    def smc(self, mr_pct):
        pos = np.asarray(mr_pct, dtype=float) / 100.0 * (self.n - 1)
        i0 = np.clip(np.floor(pos).astype(int), 0, self.n - 1)
        i1 = np.clip(i0 + 1, 0, self.n - 1)
        w = pos - i0
        return self.desc[i0] * (1 - w) + self.desc[i1] * w

    def smr(self, c):
        return 100.0 * np.searchsorted(-self.desc, -c, side="right") / self.n

    def volume_above(self, c):
        return math.fsum(np.maximum(self.z - c, 0.0).tolist()) / self.n

    def volume_below(self, c):
        return math.fsum(np.maximum(c - self.z, 0.0).tolist()) / self.n


# ---- fields --------------------------------------------------------------------------------------------------


def pavement(rows, cols, seed, corr=6.0, quantum=0.0):
    """Negatively skewed aggregate-like heights (mm) with microtexture; ``quantum`` rounds them to codes (ties,
    plateaus)."""
    rng = np.random.default_rng(seed)
    f = ndimage.gaussian_filter(rng.standard_normal((rows, cols)), corr)
    f /= f.std()
    z = 0.6 * np.minimum(f, 0.7)
    m = ndimage.gaussian_filter(rng.standard_normal((rows, cols)), 1.0)
    z += 0.02 * m / m.std()
    if quantum:
        z = np.round(z / quantum) * quantum
    return z - z.mean()


FIELDS = {
    "continuous": lambda: pavement(257, 311, 1),
    "coded (ties, plateaus)": lambda: pavement(240, 300, 2, quantum=0.01),
    "coarse codes": lambda: pavement(120, 170, 3, quantum=0.1),
    "white noise": lambda: np.random.default_rng(4).standard_normal((97, 131)),
    "one row": lambda: np.random.default_rng(5).standard_normal((1, 50)),
    "one column": lambda: np.random.default_rng(6).standard_normal((40, 1)),
    "two columns": lambda: np.round(np.random.default_rng(7).standard_normal((40, 2)), 1),
    "flat": lambda: np.zeros((12, 15)),
}


def assert_same(a, b):
    assert a.dtype == b.dtype and a.shape == b.shape
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", list(FIELDS))
def test_segmentation_steps_identical(name):
    z = FIELDS[name]()
    for d in (z, -z):
        labels, n, sink = seg.catchment_basins(d)
        rl, rn, rs = ref_catchment_basins(d)
        assert n == rn
        assert_same(labels, rl)
        assert_same(sink, rs)
        pairs = seg.boundary_pairs(labels, d)
        for x, y in zip(pairs, ref_boundary_pairs(labels, d)):
            assert_same(x, y)
        ref_edges = ref_dedupe_edges(*ref_boundary_pairs(labels, d), n)
        for x, y, z2 in zip(seg.dedupe_edges(*pairs, n), saddles._saddles(labels, d, n), ref_edges):
            assert_same(x, z2)
            assert_same(y, z2)


def test_dedupe_edges_argsort_fallback_identical():
    """More basins than the packed sort holds (key and position over 63 bits): the argsort path."""
    rng = np.random.default_rng(8)
    n = 3_000_000_000  # key ~ 2^63 / 2^1: no room for the position
    a = rng.integers(0, n, 2000)
    b = rng.integers(0, n, 2000)
    b[::3] = a[::3] + 1
    a = np.r_[a, b[:500]]
    b = np.r_[b, a[:500]]  # repeated pairs, both orders
    pour = rng.random(a.size)
    for x, y in zip(seg.dedupe_edges(a, b, pour, n), ref_dedupe_edges(a, b, pour, n)):
        assert_same(x, y)


@pytest.mark.parametrize("name", [k for k in FIELDS if k not in ("one row", "one column")])
@pytest.mark.parametrize("pct", [1.0, 5.0, 20.0])
def test_segment_identical(name, pct):
    z = FIELDS[name]()
    t = pct / 100 * float(z.max() - z.min())
    for d in (z, -z):
        new = seg.segment(d, t, 0.05, 0.04, keep_labels=True)
        ref = ref_segment(d, t, 0.05, 0.04)
        for key, val in ref.items():
            assert_same(getattr(new, key), val)


@pytest.mark.parametrize("name", [k for k in FIELDS if k not in ("one row", "one column")])
def test_hybrid_identical(name):
    z = FIELDS[name]()
    h = hybrid_parameters(z, 0.05, 0.04)
    assert h["Sdq"] == ref_sdq(z, 0.05, 0.04) == sdq(z, 0.05, 0.04)
    rows, cols = z.shape
    area = ref_developed_area(z, 0.05, 0.04)
    assert developed_area(z, 0.05, 0.04) == area
    assert h["Sdr"] == sdr(z, 0.05, 0.04) == (area / ((cols - 1) * 0.05 * (rows - 1) * 0.04) - 1.0) * 100.0


@pytest.mark.parametrize("name", list(FIELDS))
def test_material_ratio_identical(name):
    z = FIELDS[name]()
    new = material_ratio_parameters(z)
    ref = material_ratio_parameters(curve=RefMaterialRatio(z))
    assert new.keys() == ref.keys()
    for k, v in ref.items():  # the curve's heights and ratios: the same bits; the volumes: summed, to 1e-13
        if k in ("Sk", "Smr1", "Smr2"):
            assert new[k] == v or (np.isnan(v) and np.isnan(new[k])), k
        else:
            assert new[k] == pytest.approx(v, rel=1e-13, abs=1e-300, nan_ok=True), k


@pytest.mark.parametrize("max_lag_fraction", [1.0, 0.5, 0.3])
def test_autocorrelation_identical(max_lag_fraction):
    z = FIELDS["coded (ties, plateaus)"]()
    acf, power, shape = spatial.autocorrelation(z, return_spectrum=True, max_lag_fraction=max_lag_fraction)
    racf, rpower, rshape = ref_autocorrelation(z, max_lag_fraction)
    assert tuple(shape) == tuple(rshape)
    assert_same(acf, racf)
    assert_same(power, rpower)


def grooves(rows, cols):
    x = np.arange(cols) * 0.05
    return np.tile(0.3 * np.sin(2 * np.pi * x / 1.7), (rows, 1)) + 0.01 * np.random.default_rng(9).standard_normal(
        (rows, cols)
    )


@pytest.mark.parametrize(
    "field,first_window",
    [
        (lambda: pavement(300, 280, 10, corr=4.0), 128),  # the window holds the region at once
        (lambda: pavement(300, 280, 10, corr=4.0), 3),  # the window grows (3 -> 12 -> 48 ...)
        (lambda: pavement(400, 360, 11, corr=25.0), 2),  # long correlation: grows to the whole domain
        (lambda: grooves(200, 260), 2),  # no crossing along the grooves: the region spans every row
        (lambda: pavement(240, 300, 2, quantum=0.01), 5),
    ],
)
@pytest.mark.parametrize("on_border", ["nan", "bound"])
def test_spatial_parameters_identical(field, first_window, on_border, monkeypatch):
    monkeypatch.setattr(spatial, "_FIRST_WINDOW_LAGS", first_window)
    z = field()
    sp = spatial.spatial_parameters(z, 0.05, 0.04, on_border=on_border)
    sal, stri, std, lengths = ref_spatial_parameters(z, 0.05, 0.04, on_border=on_border)
    assert_same(sp.decay_mm, lengths)
    for new, ref in ((sp.Sal, sal), (sp.Str, stri), (sp.Std, std)):
        assert new == ref or (np.isnan(new) and np.isnan(ref))
    alone = spatial.spatial_parameters(z, 0.05, 0.04, on_border=on_border, direction=False)  # Sal and Str only
    assert_close_decays(alone, sal, stri, lengths)
    assert np.isnan(alone.Std)


def assert_close_decays(got, sal, stri, lengths, rtol=1e-12):
    """``direction=False`` against the reference: the same NaN pattern, values within the FFT's rounding."""
    np.testing.assert_array_equal(np.isnan(got.decay_mm), np.isnan(lengths))
    np.testing.assert_allclose(got.decay_mm, lengths, rtol=rtol, equal_nan=True)
    for new, ref in ((got.Sal, sal), (got.Str, stri)):
        assert (np.isnan(new) and np.isnan(ref)) or new == pytest.approx(ref, rel=rtol)


def flat_binder(rows, cols):
    """The flushed scan of tests/test_texture_despeckle.py: stones on 67 % flat binder, 0.01 mm codes, a tilt of
    about 0.3 deg along x and 0.16 deg along y; complete (no dropouts: the ACF needs every point)."""
    h = flat_binder_scan(0.67, seed=12, shape=(rows, cols), tilt=(5.236e-3, -2.828e-3))
    return h - h.mean()


def along_y(rows, cols):
    """Grooves across the rows (heights vary along y only, plus a little noise): the ACF stays above 0.2 along x."""
    return np.ascontiguousarray(grooves(cols, rows).T)


@pytest.mark.parametrize(
    "field,window,taken",
    [
        (lambda: pavement(300, 280, 10, corr=4.0), 128, True),  # the region well inside 128 lags
        (lambda: pavement(300, 280, 10, corr=4.0), 24, True),  # ... and inside 24 (rounded up to a fast length)
        (lambda: pavement(400, 360, 11, corr=25.0), 8, False),  # long correlation: reaches the window's border
        (lambda: pavement(400, 360, 11, corr=25.0), 200, True),  # the window is the whole domain (max_lag 0.5)
        (lambda: grooves(200, 260), 16, False),  # no crossing along the grooves (y): the region spans every row
        (lambda: along_y(200, 260), 16, False),  # ... along x: every column of the window
        (lambda: pavement(240, 300, 2, quantum=0.01), 40, True),  # 0.01 mm codes
        (lambda: flat_binder(240, 300), 64, True),  # 67 % flat binder, tilt, codes
        (lambda: flat_binder(240, 300), 24, False),  # ... its stones' ACF reaches past 24 lags
    ],
)
@pytest.mark.parametrize("on_border", ["nan", "bound"])
def test_sal_str_from_the_small_padding(field, window, taken, on_border, monkeypatch):
    """``direction=False`` pads by ``_FIRST_WINDOW_LAGS`` only where the region above s lies inside those lags
    (else the domain's padding): Sal, Str and every decay length as the reference's up to the FFT's rounding;
    the small padding is used exactly where the region fits it."""
    monkeypatch.setattr(spatial, "_FIRST_WINDOW_LAGS", window)
    z = field()
    sal, stri, _, lengths = ref_spatial_parameters(z, 0.05, 0.04, on_border=on_border)
    pads = []
    real = spatial._padded_power

    def spy(*args, **kw):
        out = real(*args, **kw)
        pads.append((kw.get("pad"), out[2]))
        return out

    monkeypatch.setattr(spatial, "_padded_power", spy)
    got = spatial.spatial_parameters(z, 0.05, 0.04, on_border=on_border, direction=False)
    assert_close_decays(got, sal, stri, lengths)
    rows, cols = z.shape
    small = pads[0][1]
    assert pads[0][0] == (window, window) and small[0] >= rows + min(window, (rows - 1) // 2)
    assert len(pads) == (1 if taken else 2)  # the domain's padding only where the small one is not enough
    if taken and window < (rows - 1) // 2:
        assert small[0] < rows + (rows - 1) // 2  # a smaller transform than the domain's
