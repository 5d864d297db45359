"""The texture stage's cache-blocked and vectorised paths give the numbers of the straightforward forms, bit for
bit: each against a plain implementation kept here (whole-array NumPy/SciPy calls, the form the code had before),
on small fields with ties (quantised heights), plateaus, dropouts, odd shapes and, where a path works in blocks,
block sizes shrunk so that small fields cross many blocks."""

import importlib

import numpy as np
import pytest
from scipy import fft as sfft
from scipy import ndimage
from test_texture_speed import (  # the same pavement-like fields and plain forms as the texture speed tests
    pavement,
    ref_autocorrelation,
    ref_catchment_basins,
)

from skidsim.surface import Surface
from skidsim.texture import (
    TextureOptions,
    areal_parameters,
    basins,
    features,
    filters,
    furrows,
    height,
    hybrid,
    pairwise,
    pruning,
    quality,
    saddles,
    spatial,
)
from skidsim.texture import segmentation as seg
from skidsim.texture.features import feature_parameters, pruning_threshold

desp = importlib.import_module("skidsim.texture.despeckle")  # the package exports the function of that name


FIELDS = {
    "continuous": lambda: pavement(97, 131, 1, corr=3.0),
    "coded (ties, plateaus)": lambda: pavement(120, 150, 2, corr=3.0, quantum=0.01),
    "coarse codes": lambda: pavement(60, 85, 3, corr=3.0, quantum=0.1),
    "white noise": lambda: np.random.default_rng(4).standard_normal((53, 71)),
    "two columns": lambda: np.round(np.random.default_rng(7).standard_normal((40, 2)), 1),
    "two rows": lambda: np.round(np.random.default_rng(8).standard_normal((2, 40)), 1),
    "flat": lambda: np.zeros((12, 15)),
}


def same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    np.testing.assert_array_equal(a, b)


@pytest.fixture
def small_blocks(monkeypatch):
    """Blocks of a few points, so that every blocked path crosses many blocks on these small fields."""
    monkeypatch.setattr(desp, "_BLOCK_POINTS", 200)
    monkeypatch.setattr(filters, "_BLOCK_POINTS", 300)
    monkeypatch.setattr(furrows, "_BLOCK_POINTS", 400)
    monkeypatch.setattr(furrows, "_COLUMN_BLOCK_POINTS", 500)
    monkeypatch.setattr(pairwise, "LEAF_POINTS", 256)
    monkeypatch.setattr(basins, "_BLOCK_POINTS", 150)
    monkeypatch.setattr(saddles, "_SADDLE_STRIP_POINTS", 250)
    monkeypatch.setattr(basins, "_GATHER_BLOCK", 333)
    monkeypatch.setattr(seg, "_GATHER_BLOCK", 333)


# ---- despeckle: the 3 x 3 median and the 9 x 9 box mean ------------------------------------------------------


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("blocks", [False, True])
def test_median3x3_is_the_rank_filter(name, blocks, request):
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]()
    for f in (z, z[:1], z[:, :1], z[:1, :1], z[:3, :4]):
        same(desp._median3x3(f), ndimage.median_filter(f, size=3, mode="nearest"))


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("size", [3, 9])
def test_box_mean_is_uniform_filter(name, size):
    z = FIELDS[name]()
    valid = (np.random.default_rng(5).random(z.shape) < 0.9).astype(np.float64)
    for f in (np.abs(z), valid, valid[:1], valid[:, :1], z[:4, :5]):
        same(desp._box_mean(f, size), ndimage.uniform_filter(f, size=size, mode="constant"))


def ref_interp_rows(h):
    """Row by row with np.interp, as the filling was written first."""
    x = np.arange(h.shape[1])
    empty = 0
    for row in h:
        ok = ~np.isnan(row)
        if not ok.any():
            empty += 1
        elif not ok.all():
            row[~ok] = np.interp(x[~ok], x[ok], row[ok])
    return empty


@pytest.mark.parametrize("shape", [(1, 1), (1, 6), (6, 1), (3, 7), (40, 57), (4, 2)])
@pytest.mark.parametrize("share", [0.0, 0.05, 0.3, 0.7, 1.0])
def test_fill_by_runs_is_np_interp_row_by_row(shape, share):
    rng = np.random.default_rng(int(share * 100) + shape[0])
    h = np.round(rng.standard_normal(shape), 2)
    gaps = rng.random(shape) < share
    gaps |= np.roll(gaps, 1, axis=1) & (rng.random(shape) < 0.5)  # runs of several points
    h[gaps] = np.nan
    if shape[0] > 2:
        h[1] = np.nan  # a whole row
    got, ref = h.copy(), h.copy()
    assert filters._interp_rows(got, "linear") == ref_interp_rows(ref)
    np.testing.assert_array_equal(got, ref)


# ---- hybrid: the developed area summed in blocks -----------------------------------------------------------


def ref_developed_area(z, dx, dy):
    gx = (np.diff(z, axis=1) * dy) ** 2
    gy = (np.diff(z, axis=0) * dx) ** 2
    total = 0.0
    for xs in (gx[:-1, :], gx[1:, :]):
        for ys in (gy[:, :-1], gy[:, 1:]):
            t = xs + ys
            t += (dx * dy) ** 2
            total += float(np.sqrt(t).sum())
    return 0.25 * total


@pytest.mark.parametrize("n", [1, 7, 8, 9, 128, 129, 300, 1000, 4097, 65537])
@pytest.mark.parametrize("leaf", [16, 256, 1 << 15])
def test_pairwise_tree_sums_as_numpy(n, leaf):
    x = np.random.default_rng(n).random(n) * 1e3 + np.random.default_rng(n + 1).random(n)
    tree = pairwise.pairwise_tree(0, n, leaf)
    sums = {lf: x[lf[0] : lf[0] + lf[1]].sum() for lf in pairwise.leaves(tree)}
    assert pairwise.tree_sum(tree, sums) == x.sum()
    two_d = x[: (n // 7) * 7].reshape(7, -1)  # a contiguous 2-D array sums as its flat values
    tree = pairwise.pairwise_tree(0, two_d.size, leaf)
    flat = two_d.ravel()
    sums = {lf: flat[lf[0] : lf[0] + lf[1]].sum() for lf in pairwise.leaves(tree)}
    assert pairwise.tree_sum(tree, sums) == two_d.sum()


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("blocks", [False, True])
def test_developed_area_is_the_whole_array_sum(name, blocks, request):
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]()
    for dx, dy in ((0.05, 0.05), (0.05, 0.04)):
        assert hybrid.developed_area(z, dx, dy) == ref_developed_area(z, dx, dy)


def ref_height_parameters(z):
    c = np.ravel(z) - np.ravel(z).mean()
    c2 = c * c
    m2 = c2.sum() / c.size
    sq = float(np.sqrt(m2))
    sp, sv = float(c.max()), float(-c.min())
    return {
        "Sq": sq,
        "Ssk": float(np.dot(c2, c) / c.size) / sq**3 if sq > 0 else np.nan,
        "Sku": float((c2 * c2).sum() / c.size) / m2**2 if sq > 0 else np.nan,
        "Sp": sp,
        "Sv": sv,
        "Sz": sp + sv,
        "Sa": float(np.abs(c).sum() / c.size),
    }


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("blocks", [False, True])
def test_height_parameters_are_the_whole_array_sums(name, blocks, request):
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]() + 0.3
    got, ref = height.height_parameters(z), ref_height_parameters(z)
    assert got.keys() == ref.keys()
    for k, v in ref.items():
        assert got[k] == v or (np.isnan(v) and np.isnan(got[k])), k
    alone = height.sa_sq(z)  # Sa and Sq alone: the same bits
    assert alone == {"Sa": ref["Sa"], "Sq": ref["Sq"]}


# ---- furrows: sliding maxima by doubling, blocks of profiles ---------------------------------------------------


def ref_furrow_parameters(zc, dx, dy, window_mm=2.0, min_depth_pct=5.0):
    sz = float(zc.max() - zc.min())
    tmin = min_depth_pct / 100.0 * sz
    depths, p = [], []
    for axis, step in ((1, dx), (0, dy)):
        w = max(1, int(round(window_mm / step)))
        z = zc.T if axis == 0 else zc
        n = z.shape[1]
        size = 2 * (w // 2) + 1
        half = (size + 1) // 2
        if n <= 2 * half + 2:
            depth, tested = np.empty(0), 0
        else:
            m = ndimage.maximum_filter1d(z, size=size, axis=1, mode="nearest")
            c = z[:, half : n - half]
            is_min = (c < z[:, half - 1 : n - half - 1]) & (c < z[:, half + 1 : n - half + 1])
            depth = np.minimum(m[:, : n - 2 * half], m[:, 2 * half :])[is_min] - c[is_min]
            tested = c.size
        depth = depth[depth >= tmin]
        depths.append(depth)
        p.append(depth.size / (tested * step) if tested else 0.0)
    d = np.concatenate(depths)
    return {
        "Fdmax": float(d.max()) if d.size else 0.0,
        "Fdmean": float(d.mean()) if d.size else 0.0,
        "Fden": 10.0 * (np.pi / 4.0 * (p[0] + p[1])),
    }


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("blocks", [False, True])
def test_furrows_are_those_of_the_maximum_filter(name, blocks, request):
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]()
    for window_mm, pct in ((2.0, 5.0), (0.3, 0.0), (0.05, 20.0), (0.42, 1.0)):
        for dx, dy in ((0.05, 0.05), (0.05, 0.04)):
            got = furrows.furrow_parameters(z, dx, dy, window_mm=window_mm, min_depth_pct=pct)
            assert got == ref_furrow_parameters(z, dx, dy, window_mm, pct)


@pytest.mark.parametrize("size", [1, 2, 3, 5, 8, 9, 31, 41, 64])
def test_sliding_max_is_the_window_maximum(size):
    f = np.round(np.random.default_rng(size).standard_normal(200), 1)
    ref = np.array([f[j : j + size].max() for j in range(f.size - size + 1)])
    same(furrows._sliding_max(f, size), ref)


# ---- segmentation: pruning rounds on the active edges, the deepest pits without the dales ----------------------


def ref_contract_leaves(a, b, pour, minv, threshold):
    """The pruning rounds on the whole edge list, as they were."""
    n = minv.size
    unit = np.arange(n)
    while a.size:
        lowest = np.full(n, np.inf)
        np.minimum.at(lowest, a, pour)
        np.minimum.at(lowest, b, pour)
        nb = np.full(n, -1, dtype=np.int64)
        m = pour == lowest[a]
        nb[a[m]] = b[m]
        m = pour == lowest[b]
        nb[b[m]] = a[m]
        cand = np.flatnonzero((nb >= 0) & (lowest - minv < threshold))
        deeper = (minv[nb[cand]] < minv[cand]) | ((minv[nb[cand]] == minv[cand]) & (nb[cand] < cand))
        cand = cand[deeper]
        if cand.size == 0:
            break
        parent = np.arange(n)
        parent[cand] = nb[cand]
        while not np.array_equal(parent[parent], parent):
            parent = parent[parent]
        unit = parent[unit]
        a, b = parent[a], parent[b]
        keep = a != b
        a, b, pour = a[keep], b[keep], pour[keep]
    return unit, a, b, pour


def pair_saddles(a, b, p):
    """The lowest saddle of every unordered pair of units (what the segmentation reads from the edges)."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.lexsort((p, hi, lo))
    lo, hi, p = lo[order], hi[order], p[order]
    first = np.r_[True, (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])][: lo.size]
    return lo[first], hi[first], p[first]


@pytest.mark.parametrize("name", [k for k in FIELDS if k != "two rows"])
@pytest.mark.parametrize("pct", [1.0, 5.0, 20.0])
@pytest.mark.parametrize("share", [0.0, 0.7, 2.0])  # dominated parallel edges dropped every round, some, never
def test_contract_leaves_same_units_and_saddles(name, pct, share, monkeypatch):
    monkeypatch.setattr(pruning, "_PARALLEL_EDGES_SHARE", share)
    z = FIELDS[name]()
    t = pct / 100 * float(z.max() - z.min())
    for d in (z, -z):
        labels, n, sink = seg.catchment_basins(d)
        a, b, sad = saddles._saddles(labels, d, n)
        got = pruning._contract_leaves(a, b, sad, d.ravel()[sink], t)
        ref = ref_contract_leaves(a, b, sad, d.ravel()[sink], t)
        same(got[0], ref[0])
        for x, y in zip(pair_saddles(*got[1:]), pair_saddles(*ref[1:])):
            same(x, y)
        for x, y in zip(seg._roots_and_ranks(got[0]), np.unique(got[0], return_inverse=True)):
            same(x, y)  # the motifs and the motif of every basin without a sort


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("pct", [0.0, 1.0, 5.0, 20.0, 60.0])
@pytest.mark.parametrize("blocks", [False, True])
def test_saddles_at_which_the_pruning_can_merge(name, pct, blocks, request):
    """``_saddles(..., merging=(minima, t))``: the edges of the whole set with at least one pair of points below
    ``max(min_x, min_y) + t`` (as a rounded difference), each with its exact saddle, and every edge left out has
    its saddle at or above that; the segmentation without bases has the same motifs, critical points and edge
    flags as the whole one."""
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]()
    t = pct / 100 * float(z.max() - z.min())
    for d in (z, -z):
        labels, n, sink = seg.catchment_basins(d)
        low = d.ravel()[sink]
        a, b, sad = saddles._saddles(labels, d, n)
        fa, fb, fs = saddles._saddles(labels, d, n, merging=(low, t))
        kept = sad - np.maximum(low[a], low[b]) < t
        same(fa, a[kept])
        same(fb, b[kept])
        same(fs, sad[kept])
        whole = seg.segment(d, t, 0.05, 0.05, measure=False)
        bare = seg.segment(d, t, 0.05, 0.05, measure=False, bases=False)
        for field in ("critical_index", "critical", "touches_edge", "motif_of_basin"):
            same(getattr(bare, field), getattr(whole, field))
        assert np.isnan(bare.base).all() and np.isnan(bare.volume_mm3).all()
    with pytest.raises(ValueError, match="bases=False needs measure=False"):
        seg.segment(z, t, 0.05, 0.05, bases=False)


def test_saddles_at_which_the_pruning_can_merge_leave_out_most_of_a_microtexture():
    """On white noise at 5 % of Sz most basins are deeper than the threshold: most edges are left out (the
    filter does something), and the ten-point height is that of the whole segmentation."""
    d = np.random.default_rng(11).standard_normal((120, 150))
    t = 0.05 * float(d.max() - d.min())
    labels, n, sink = seg.catchment_basins(d)
    low = d.ravel()[sink]
    whole = saddles._saddles(labels, d, n)[0].size
    kept = saddles._saddles(labels, d, n, merging=(low, t))[0].size
    assert 0 < kept < 0.5 * whole
    zc = d - d.mean()
    full = feature_parameters(zc, 0.05, 0.05, exclude_edge=True)
    assert features.ten_point_height(zc, 0.05, 0.05, exclude_edge=True)["S10z"] == full["S10z"]


@pytest.mark.parametrize("size", [1, 2, 7, 1000])
def test_run_starts_are_the_concatenated_comparison(size):
    v = np.random.default_rng(size).integers(0, 3, size)
    same(saddles.run_starts(v), np.flatnonzero(np.r_[True, v[1:] != v[:-1]]))


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("pct", [0.0, 1.0, 5.0, 20.0, 60.0])
@pytest.mark.parametrize("blocks", [False, True])
def test_deepest_motifs_are_the_first_critical_values(name, pct, blocks, request):
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]()
    t = pct / 100 * float(z.max() - z.min())
    for d in (z, -z):
        critical = seg.segment(d, t, 0.05, 0.05).critical
        peaks = seg.segment(-d, t, 0.05, 0.05, keep_peaks=True).peaks  # the sinks of d, from the other pass
        same(peaks, ndimage.minimum_filter(d, footprint=np.ones((3, 3)), mode="nearest") == d)
        for count in (1, 5, 40):
            same(seg.deepest_motifs(d, t, count), critical[:count])
            same(seg.deepest_motifs(d, t, count, sinks=peaks), critical[:count])
        same(seg.deepest_motifs(d, t, 5, flood_budget=0.0), critical[:5])  # the whole segmentation instead


def test_deepest_motifs_on_a_coded_scan_with_plateaus_and_a_grown_window():
    """Long plateaus of one code and basins wider than the first window (16 points either side)."""
    z = pavement(160, 220, 11, corr=12.0, quantum=0.05)
    for pct in (2.0, 5.0, 10.0):
        t = pct / 100 * float(z.max() - z.min())
        for d in (z, -z):
            same(seg.deepest_motifs(d, t, 5), seg.segment(d, t, 0.05, 0.05).critical[:5])


@pytest.mark.parametrize("name", list(FIELDS))
@pytest.mark.parametrize("blocks", [False, True])
def test_catchment_basins_of_the_flat_blocked_descent(name, blocks, request):
    """The descent on flat padded blocks of rows (blocks of 8 rows; shrunk: a few points) and the sink labels
    without ndimage.label where no two sinks touch: the basins of the whole-array form, and its peaks."""
    if blocks:
        request.getfixturevalue("small_blocks")
    z = FIELDS[name]()
    for d in (z, -z, z[:1], z[:, :1], z[:3, :4]):
        labels, n, sink = seg.catchment_basins(d)
        rl, rn, rs = ref_catchment_basins(d)
        assert n == rn
        same(labels, rl)
        same(sink, rs)
        peaks = basins._descent(d, peaks=True)[2]
        same(peaks, ndimage.maximum_filter(d, footprint=np.ones((3, 3)), mode="nearest") == d)


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (2, 2), (5, 7), (40, 57), (97, 131)])
@pytest.mark.parametrize("share", [0.0, 0.01, 0.05, 0.3, 1.0])
def test_sink_labels_are_ndimage_labels(shape, share):
    """Isolated sinks (the fast path: labels in raster order) and touching ones (ndimage.label)."""
    rng = np.random.default_rng(int(share * 1000) + shape[1])
    for _ in range(5):
        mask = rng.random(shape) < share
        markers, n, idx, first = basins._sink_labels(mask)
        ref, rn = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
        assert n == rn
        same(markers, ref)
        same(idx, np.flatnonzero(mask))
        same(first, basins._first_sinks(idx, ref.ravel()[idx], rn))


@pytest.mark.parametrize("rows_per_call", [1, 3, 7, 64])
@pytest.mark.parametrize("max_lag_fraction", [1.0, 0.5])
def test_padded_spectrum_without_the_padding_rows(rows_per_call, max_lag_fraction, monkeypatch):
    """rfft2 of the zero-padded heights from the rows of heights only, a few rows per transform (remainders
    included), and |F|^2 formed in the spectrum's array: the bits of the whole-array form."""
    monkeypatch.setattr(spatial, "_FFT_ROWS", rows_per_call)
    for z in (FIELDS["coded (ties, plateaus)"](), FIELDS["white noise"](), FIELDS["two columns"]()):
        acf, power, shape = spatial.autocorrelation(z, return_spectrum=True, max_lag_fraction=max_lag_fraction)
        racf, rpower, rshape = ref_autocorrelation(z, max_lag_fraction)
        assert tuple(shape) == tuple(rshape)
        same(power, rpower)
        same(acf, racf)
        spec = sfft.rfft2(z - z.mean(), s=shape)
        same(spatial._padded_spectrum(z, 1, shape), spec)


def test_areal_parameters_reject_invalid_points_and_share_the_range():
    """The finite-mean test lets no NaN or infinity through; the range of the heights read once (pruning
    threshold, furrows) gives the values of the functions that compute it themselves."""
    z = pavement(60, 70, 5, corr=3.0, quantum=0.01)
    for bad in (np.nan, np.inf, -np.inf):
        h = z.copy()
        h[7, 9] = bad
        with pytest.raises(ValueError, match="invalid points"):
            areal_parameters(Surface(h, 0.05, 0.05), "raw", TextureOptions())
    huge = np.full((10, 10), 1e308)
    huge[::2] = -1e308  # finite heights whose sum overflows (NaN mean): the full check, which passes
    with np.errstate(over="ignore", invalid="ignore"):
        areal_parameters(Surface(huge, 0.05, 0.05), "raw", TextureOptions(groups=("height",)))
    got = areal_parameters(Surface(z, 0.05, 0.05), "raw", TextureOptions())
    zc = z - z.mean()
    t = pruning_threshold(zc, 5.0, "Sz")
    hills = seg.segment(-zc, t, 0.05, 0.05, keep_peaks=True)
    ref = {
        **feature_parameters(zc, 0.05, 0.05, hills=hills),
        **furrows.furrow_parameters(zc, 0.05, 0.05),
        **features.motif_parameters(zc, 0.05, 0.05, hills=hills),
    }
    for k, v in ref.items():
        assert got[k][0] == v or (np.isnan(v) and np.isnan(got[k][0])), k


@pytest.mark.parametrize("exclude_edge", [False, True])
def test_feature_parameters_without_the_dales_segmentation(exclude_edge):
    zc = pavement(120, 150, 2, corr=3.0, quantum=0.01)
    t = pruning_threshold(zc, 5.0, "Sz")
    dales = seg.segment(zc, t, 0.05, 0.05)
    fast = feature_parameters(zc, 0.05, 0.05, exclude_edge=exclude_edge)
    assert fast == feature_parameters(zc, 0.05, 0.05, exclude_edge=exclude_edge, dales=dales)
    assert features.deepest_motifs is seg.deepest_motifs


# ---- bands and scan quality ------------------------------------------------------------------------------------


def ref_separate_bands(surface, macro=(0.5, 50.0), order=2):
    raw = surface.heights - filters.fit_form(surface, "plane")
    coeff = sfft.dctn(raw, type=2, norm="ortho")
    f = filters.dct_radial_frequency(raw.shape, surface.dx, surface.dy)
    g = filters.band_gains(f, macro, order)
    return {
        "raw": raw,
        "macro": sfft.idctn(g["macro"] * coeff, type=2, norm="ortho"),
        "micro": sfft.idctn(g["micro"] * coeff, type=2, norm="ortho"),
    }


@pytest.mark.parametrize("name", [k for k in FIELDS if k != "flat"])
@pytest.mark.parametrize("blocks", [False, True])
def test_separate_bands_in_blocks(name, blocks, request):
    if blocks:
        request.getfixturevalue("small_blocks")
    s = Surface(FIELDS[name]() + 0.01 * np.arange(FIELDS[name]().shape[1]), 0.05, 0.04)
    for macro, order in (((0.5, 50.0), 2), ((0.3, 20.0), 3)):
        got = filters.separate_bands(s, macro=macro, order=order)
        for band, ref in ref_separate_bands(s, macro, order).items():
            same(got[band].heights, ref)
    holes = s.heights.copy()
    holes[::3, ::4] = np.nan
    sh = Surface(holes, 0.05, 0.04)
    for form in ("plane", "none", 2):
        same(filters.remove_form(sh, form).heights, holes - filters.fit_form(sh, form))


def ref_plane_slopes(surface):
    h = surface.heights
    ok = np.isfinite(h)
    yy, xx = np.nonzero(ok)
    x, y, z = xx * surface.dx, yy * surface.dy, h[ok]
    x, y, z = x - x.mean(), y - y.mean(), z - z.mean()
    sx, sy = np.linalg.solve(np.array([[x @ x, x @ y], [x @ y, y @ y]]), np.array([x @ z, y @ z]))
    return float(sx), float(sy)


@pytest.mark.parametrize("name", [k for k in FIELDS if k not in ("flat", "two rows", "two columns")])
def test_plane_slopes_of_the_valid_points(name):
    h = FIELDS[name]() + 0.002 * np.arange(FIELDS[name]().shape[1])
    h[np.random.default_rng(3).random(h.shape) < 0.1] = np.nan
    s = Surface(h, 0.05, 0.04)
    assert quality.plane_slopes(s) == ref_plane_slopes(s)
