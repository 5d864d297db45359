"""Despeckling: removing the points the instrument got wrong (spikes, reflections, dropout edges).

Four rules (``docs/texture.md`` has the argument and the figures):

* ``"local"`` (default): a 2-D detector of isolated outliers against their neighbourhood, right on bimodal
  (flat-binder) scans; see :func:`detect_spikes`. In short: the residual ``r = h - median3x3(h)``; a point is a
  *candidate* where ``|r| > k * s`` with ``s`` the local scale of the residuals (mean ``|r|`` over 9 x 9 points
  times sqrt(pi/2), floored at the height step of the scan); a small cluster of candidates (at most
  ``MAX_CLUSTER`` points) is a *spike* where it lies more than ``k * s`` above the highest (or below the lowest)
  point of its ring of neighbours: an instrument spike stands out from everything around it, while a genuine
  point (the edge of a stone, the corner of a chip, the bottom of a void) always has a neighbour at or beyond its
  height. The height step is the X3P Z increment of an integer-coded scan (``meta["z_increment_mm"]``), else
  detected from the data (:func:`height_step`). Spikes are re-interpolated along the frame (``axis``). k = 6.
* ``"study"``, literal as the study writes it: per frame the first quartile Q1 and third quartile Q3; a value
  above ``k * Q3`` is set to Q3, a value below ``k * Q1`` is set to Q1 (k = 1.5). The fences scale with the
  *value* of the quartiles, not with their spread, so the rule depends on where zero is: on heights that cross
  zero or sit far from it (range data), it replaces large shares of genuine points or none at all.
* ``"tukey"``: per-frame Tukey fences ``Q1 - k IQR`` and ``Q3 + k IQR`` (k = 1.5).
* ``"mad"``: per-frame fences ``median -+ k * 1.4826 * MAD`` (k = 3.5, the Iglewicz-Hoaglin modified z-score).

The per-frame fences (``study``, ``tukey``, ``mad``) treat the height distribution of a scan line as one
population with a tail of outliers. On a flat-binder scan (chip seal, flushed or bleeding asphalt, fine dense
mixes, heights stored as integer codes) more than half of a line can sit on one height code: the MAD or the IQR
is then 0 or one code, and every aggregate point becomes an "outlier" (docs/texture.md measures what this does to
the MPD). They stay available by name; ``local`` is the default.

A *profile frame* is one scan line: by default one row of the scan (a line along x), i.e. ``axis=1``.
Replacement: ``"study"`` replaces by Q1/Q3 as written; the other rules by default mark the outliers invalid and
re-interpolate them linearly along the frame (``replace="interpolate"``), so a spike does not become a plateau;
``replace="clip"`` sets them to the fence (per-frame rules only), ``replace="quartile"`` to Q1/Q3.
Quartiles use NumPy's default (linear) definition and ignore invalid points; invalid points stay invalid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skidsim._lazy import lazy_module
from skidsim.surface import Surface

from .filters import _interp_rows

ndimage = lazy_module("scipy.ndimage")  # imported on first use (skidsim._lazy)

METHODS = ("local", "tukey", "study", "mad")
FRAME_METHODS = ("tukey", "study", "mad")
REPLACE = ("interpolate", "clip", "quartile")
_DEFAULT_K = {"local": 6.0, "study": 1.5, "tukey": 1.5, "mad": 3.5}
_MAD_SCALE = 1.4826
#: mean absolute deviation -> standard deviation for normal residuals, sqrt(pi / 2)
_MEAN_ABS_SCALE = float(np.sqrt(np.pi / 2.0))
#: side (points) of the window of the local residual scale of ``local``
SCALE_WINDOW = 9
#: integer X3P types: their Z increment (``meta["z_increment_mm"]``) is the height step of the scan
_INTEGER_X3P = ("I", "L")
#: largest spike of ``local``, points: an 8-connected cluster of candidates of one sign larger than this is a
#: genuine feature (a stone rim, a crease between stones), not an instrument spike
MAX_CLUSTER = 9
#: at most this many valid heights (every n-th point) enter the height-step detection
_STEP_SAMPLE = 400_000
#: a height step below this share of the height range is not a quantisation step (continuous heights)
_MIN_STEP_SHARE = 1e-6
#: a height step above this share of the 0.5-99.5 % height range is no quantisation (a few distinct values)
_MAX_STEP_SHARE = 0.05
#: points of one block of rows of the 3 x 3 median (a few arrays of it stay in cache)
_BLOCK_POINTS = 1 << 13
#: floor of the local scale of ``local`` on continuous (unquantised) heights, mm: below the height resolution of
#: pavement laser scanners (LS-40: 0.01 mm), above the curvature residual of a smooth stone on a 0.05 mm grid
_CONTINUOUS_FLOOR_MM = 1e-3


@dataclass(frozen=True)
class SpikeDetection:
    """What :func:`detect_spikes` found. ``mask``: True at spike points; ``step_mm``: the height step of the scan
    (mm, 0.0 for continuous heights); ``step_source``: ``"x3p"`` (Z increment of an integer-coded file),
    ``"data"`` (detected) or ``"none"``; ``floor_mm``: the floor of the local scale (mm); ``k``."""

    mask: np.ndarray
    step_mm: float
    step_source: str
    floor_mm: float
    k: float


def height_step(surface: Surface) -> tuple[float, str]:
    """The height step (mm) of ``surface`` and where it comes from: ``(step_mm, "x3p" | "data" | "none")``.

    An integer-coded X3P (``meta["x3p_dtype"]`` I or L) gives its Z increment. Otherwise the step is detected from
    the data: the smallest difference between distinct valid heights (of at most 400,000 evenly strided points),
    accepted when every difference between distinct heights is a whole multiple of it (within 1 % of a step), it
    is above 1e-6 of the height range and at most 5 % of the 0.5-99.5 % percentile range (a scan of a few distinct
    heights is not quantised, it is flat); else 0.0 ("none", continuous heights).
    """
    meta = surface.meta or {}
    inc = meta.get("z_increment_mm")
    if meta.get("x3p_dtype") in _INTEGER_X3P and inc is not None and float(inc) > 0:
        return float(inc), "x3p"
    h = surface.heights.ravel()
    h = h[:: max(1, h.size // _STEP_SAMPLE)]
    u = np.unique(h[np.isfinite(h)])
    if u.size < 3:
        return 0.0, "none"
    d = np.diff(u)
    q = float(d.min())
    lo, hi = np.percentile(h[np.isfinite(h)], [0.5, 99.5])
    if not _MIN_STEP_SHARE * float(u[-1] - u[0]) < q <= _MAX_STEP_SHARE * float(hi - lo):
        return 0.0, "none"
    ratio = d / q
    if np.max(np.abs(ratio - np.round(ratio))) > 0.01:
        return 0.0, "none"
    return q, "data"


def _filled(h: np.ndarray, valid: np.ndarray) -> np.ndarray:
    if valid.all():
        return h
    out = np.array(h, dtype=np.float64)
    _interp_rows(out, "linear")
    if np.isnan(out).any():
        _interp_rows(out.T, "linear")
    if np.isnan(out).any():  # no valid point at all
        out[np.isnan(out)] = 0.0
    return out


def _median3x3(f: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.median_filter(f, size=3, mode="nearest")`` of a complete array, the same values: per point
    the three columns of its 3 x 3 window are sorted, and the median of the nine is the median of (the largest
    column minimum, the median column median, the smallest column maximum); every step is a min or max, so the
    result is one of the nine heights, as the rank filter's. Blocks of rows that stay in cache; every step runs on
    the flat padded block (the three columns of a window are the flat run shifted by 0, 1 and 2; the results that
    straddle two rows are dropped): one-dimensional loops."""
    rows, cols = f.shape
    out = np.empty(f.shape)
    width = cols + 2
    block = max(1, min(rows, _BLOCK_POINTS // width))
    pad = np.empty((block + 2, width))
    flat_pad = pad.ravel()
    res = np.empty(block * width)
    for r0 in range(0, rows, block):
        r1 = min(r0 + block, rows)
        h = r1 - r0
        pb = pad[: h + 2]
        pb[1 : h + 1, 1:-1] = f[r0:r1]
        pb[0, 1:-1] = f[max(r0 - 1, 0)]  # nearest: the edge rows and columns repeated
        pb[h + 1, 1:-1] = f[min(r1, rows - 1)]
        pb[:, 0] = pb[:, 1]
        pb[:, -1] = pb[:, -2]
        n = h * width  # padded rows 1 .. h, every column
        up, centre, down = flat_pad[0:n], flat_pad[width : width + n], flat_pad[2 * width : 2 * width + n]
        t1, t2 = np.minimum(up, centre), np.maximum(up, centre)
        lo, x = np.minimum(t1, down), np.maximum(t1, down)
        mid, hi = np.minimum(t2, x), np.maximum(t2, x)  # each column of three sorted: lo <= mid <= hi
        m = n - 2  # the window of the point in padded column j + 1 spans flat j, j + 1, j + 2
        lo_max = np.maximum(np.maximum(lo[:m], lo[1 : m + 1]), lo[2:])
        hi_min = np.minimum(np.minimum(hi[:m], hi[1 : m + 1]), hi[2:])
        a, b, c = mid[:m], mid[1 : m + 1], mid[2:]
        mid_med = np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))
        r = res[:m]
        np.maximum(np.minimum(lo_max, mid_med), np.minimum(np.maximum(lo_max, mid_med), hi_min), out=r)
        out[r0:r1] = res[:n].reshape(h, width)[:, :cols]
    return out


def _box_mean(x: np.ndarray, size: int) -> np.ndarray:
    """``scipy.ndimage.uniform_filter(x, size, mode="constant")`` of a float64 array, the same bits: along y the
    running sum of ``uniform_filter1d`` (the first window summed in order, then ``+ (entering - leaving)``, each
    sum divided by ``size``) as a cumulative sum, then SciPy's own pass along x. The cumulative sum runs row by
    row (each row the previous one plus its difference, as ``np.cumsum(axis=0)`` adds them, without its strided
    walk down the columns), each difference formed from the rows of ``x`` and a row of zeros for the constant
    extension."""
    rows, cols = x.shape
    s1 = size // 2
    zero = np.zeros(cols)

    def ext(j: int) -> np.ndarray:
        """Row ``j`` of ``x`` extended by ``s1`` rows of zeros above and ``size - 1 - s1`` below."""
        return x[j - s1] if 0 <= j - s1 < rows else zero

    acc = np.empty(x.shape)
    first = np.array(ext(0), dtype=np.float64)
    for k in range(1, size):
        first += ext(k)
    acc[0] = first
    diff = np.empty(cols)
    for i in range(1, rows):
        np.subtract(ext(i + size - 1), ext(i - 1), out=diff)  # entering - leaving
        np.add(acc[i - 1], diff, out=acc[i])
    acc /= size
    return ndimage.uniform_filter1d(acc, size, axis=1, mode="constant")


def _per_label(ufunc: np.ufunc, labels: np.ndarray, values: np.ndarray, m: int, empty: float) -> np.ndarray:
    """``ufunc.reduce`` of ``values`` per label 0..m (``empty`` where a label has no value); by one sort."""
    out = np.full(m + 1, empty)
    if labels.size == 0:
        return out
    order = np.argsort(labels, kind="stable")
    lab, val = labels[order], values[order]
    starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
    out[lab[starts]] = ufunc.reduceat(val, starts)
    return out


def _isolated(h: np.ndarray, valid: np.ndarray, cand: np.ndarray, thr: np.ndarray, sign: int) -> np.ndarray:
    """Points of the clusters of ``cand`` (8-connected, at most ``MAX_CLUSTER`` points) that stand out from their
    whole ring (every valid point 8-adjacent to a member and not in the cluster): for ``sign`` +1 the lowest
    member lies above the highest ring point by more than the members' mean threshold ``thr`` (mm); for -1
    mirrored."""
    eight = np.ones((3, 3), dtype=bool)
    labels, n = ndimage.label(cand, structure=eight)
    out = np.zeros(cand.shape, dtype=bool)
    if n == 0:
        return out
    ii, jj = np.nonzero(labels)  # work on the candidates' coordinates only
    lm = labels[ii, jj]
    small = np.bincount(lm, minlength=n + 1) <= MAX_CLUSTER
    keep = small[lm]
    ii, jj, lm = ii[keep], jj[keep], lm[keep]
    if lm.size == 0:
        return out
    ny, nx = h.shape
    hs = sign * h
    member_low = _per_label(np.minimum, lm, hs[ii, jj], n, np.inf)
    limit = np.bincount(lm, weights=thr[ii, jj], minlength=n + 1) / np.maximum(np.bincount(lm, minlength=n + 1), 1)
    ring_lab, ring_h = [], []
    for di in (-1, 0, 1):  # the ring: every valid point 8-adjacent to a member and not in its cluster
        for dj in (-1, 0, 1):
            if di == 0 and dj == 0:
                continue
            ni, nj = ii + di, jj + dj
            ok = (ni >= 0) & (ni < ny) & (nj >= 0) & (nj < nx)
            ni, nj, lo = ni[ok], nj[ok], lm[ok]
            ok = valid[ni, nj] & (labels[ni, nj] != lo)
            ring_lab.append(lo[ok])
            ring_h.append(hs[ni[ok], nj[ok]])
    lr = np.concatenate(ring_lab)
    ring_high = _per_label(np.maximum, lr, np.concatenate(ring_h), n, -np.inf)
    has_ring = np.bincount(lr, minlength=n + 1) > 0
    spike = has_ring & (member_low - ring_high > limit)
    sel = spike[lm]
    out[ii[sel], jj[sel]] = True
    return out


def detect_spikes(surface: Surface, k: float | None = None) -> SpikeDetection:
    """Spikes of ``surface`` by the ``local`` rule (module docstring); heights in mm, NaN = invalid.

    1. ``r = h - median3x3(h)`` on the heights with invalid points filled linearly (rows, then columns); r is
       only evaluated at valid points.
    2. Local scale ``s = max(sqrt(pi/2) * mean(|r|) over the 9 x 9 valid points around, floor)``; the floor is
       the height step (:func:`height_step`), or 1e-3 mm for continuous heights.
    3. Candidates: ``|r| > k s``, split by the sign of r into 8-connected clusters. A cluster of more than
       ``MAX_CLUSTER`` (9) points is a genuine feature (a stone rim, a crease between stones). A small positive
       cluster is a spike where its lowest point lies above the highest point of its *ring* (the valid points
       8-adjacent to it) by more than ``k s`` (s averaged over the cluster); negative clusters mirrored. A
       genuine point always has a ring point at or beyond its height (along a rim, a crease, a slope); an
       instrument spike stands out from all of them. A cluster without a valid ring point is kept.
    """
    k = _DEFAULT_K["local"] if k is None else float(k)
    if not k > 0:
        raise ValueError(f"despeckle: k must be > 0, got {k}")
    h = surface.heights
    valid = np.isfinite(h)
    step, source = height_step(surface)
    floor = step if step > 0 else _CONTINUOUS_FLOOR_MM
    f = _filled(h, valid)
    r = np.where(valid, h - _median3x3(f), 0.0)
    del f
    a = np.abs(r)
    w = SCALE_WINDOW
    n_valid = _box_mean(valid.astype(np.float64), w)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = _MEAN_ABS_SCALE * _box_mean(a, w) / n_valid
    thr = k * np.fmax(s, floor)  # fmax: no valid point in the window (s NaN) -> the floor
    cand = valid & (a > thr)
    mask = _isolated(h, valid, cand & (r > 0), thr, +1) | _isolated(h, valid, cand & (r < 0), thr, -1)
    return SpikeDetection(mask=mask, step_mm=step, step_source=source, floor_mm=floor, k=k)


def despeckle_fences(
    heights: np.ndarray, method: str = "mad", k: float | None = None, axis: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame ``(low_fence, high_fence, low_replacement, high_replacement)`` (mm), shaped to broadcast
    against ``heights`` along ``axis``. Replacements are the quartiles Q1, Q3."""
    if method not in FRAME_METHODS:
        raise ValueError(f"despeckle: per-frame fences need a method of {FRAME_METHODS}, got {method!r}")
    k = _DEFAULT_K[method] if k is None else float(k)
    if not k > 0:
        raise ValueError(f"despeckle: k must be > 0, got {k}")
    has_nan = np.isnan(heights).any()
    pct = np.nanpercentile if has_nan else np.percentile
    q1, med, q3 = pct(heights, [25.0, 50.0, 75.0], axis=axis, keepdims=True)  # one partition pass
    if method == "study":
        lo, hi = k * q1, k * q3
    elif method == "tukey":
        iqr = q3 - q1
        lo, hi = q1 - k * iqr, q3 + k * iqr
    else:
        med_fn = np.nanmedian if has_nan else np.median
        mad = med_fn(np.abs(heights - med), axis=axis, keepdims=True)
        lo, hi = med - k * _MAD_SCALE * mad, med + k * _MAD_SCALE * mad
    return lo, hi, q1, q3


@dataclass(frozen=True)
class DespeckleResult:
    """:func:`despeckle_detail`'s answer: the despeckled ``surface``; ``mask`` True at the replaced points;
    ``step_mm`` / ``step_source`` the height step of the scan (mm; see :func:`height_step`, computed for every
    method)."""

    surface: Surface
    mask: np.ndarray
    step_mm: float
    step_source: str

    @property
    def n_replaced(self) -> int:
        """Number of replaced points."""
        return int(self.mask.sum())


def despeckle_detail(
    surface: Surface, method: str = "local", k: float | None = None, axis: int = 1, replace: str | None = None
) -> DespeckleResult:
    """Despeckle ``surface`` and say which points were replaced; parameters as :func:`despeckle`."""
    if method not in METHODS:
        raise ValueError(f"despeckle: method must be one of {METHODS}, got {method!r}")
    if axis not in (0, 1):
        raise ValueError(f"despeckle: axis must be 0 or 1, got {axis!r}")
    replace = ("quartile" if method == "study" else "interpolate") if replace is None else replace
    if replace not in REPLACE:
        raise ValueError(f"despeckle: replace must be one of {REPLACE}, got {replace!r}")
    h = surface.heights
    if method == "local":
        if replace != "interpolate":
            raise ValueError(f"despeckle: method 'local' replaces by interpolation only, got replace={replace!r}")
        det = detect_spikes(surface, k)
        high, low = det.mask, np.zeros_like(det.mask)
        step, source = det.step_mm, det.step_source
    else:
        lo, hi, q1, q3 = despeckle_fences(h, method, k, axis)
        with np.errstate(invalid="ignore"):
            high = h > hi
            low = h < lo
        step, source = height_step(surface)
    mask = high | low
    if not mask.any():
        return DespeckleResult(surface, mask, step, source)
    out = np.array(h, dtype=np.float64)
    if replace == "quartile":
        np.copyto(out, np.broadcast_to(q3, h.shape), where=high)
        np.copyto(out, np.broadcast_to(q1, h.shape), where=low)
    elif replace == "clip":
        np.copyto(out, np.broadcast_to(hi, h.shape), where=high)
        np.copyto(out, np.broadcast_to(lo, h.shape), where=low)
    else:
        was_nan = np.isnan(out)
        out[mask] = np.nan
        view = out if axis == 1 else out.T
        _interp_rows(view, "linear")
        out[was_nan] = np.nan
    return DespeckleResult(surface.with_heights(out), mask, step, source)


def despeckle(
    surface: Surface, method: str = "local", k: float | None = None, axis: int = 1, replace: str | None = None
) -> tuple[Surface, int]:
    """Despeckle ``surface``; returns ``(new Surface, number of replaced points)``.

    Parameters
    ----------
    surface:
        Heights in mm, NaN = invalid (left invalid).
    method:
        ``"local"`` (default: isolated 2-D outliers, right on flat-binder scans), per-frame ``"mad"``,
        ``"tukey"`` or ``"study"`` (literal limiting filter); see the module docstring.
    k:
        Threshold factor; default 6 for ``local`` (times the local residual scale), 1.5 for ``study`` and
        ``tukey``, 3.5 for ``mad``.
    axis:
        Axis along which a frame runs: 1 = rows are frames (lines along x, default), 0 = columns. For ``local``
        the direction of the re-interpolation of the replaced points.
    replace:
        ``"interpolate"`` (default, the only choice for ``local``), ``"quartile"`` (default for study: above ->
        Q3, below -> Q1), or ``"clip"`` (to the fence).
    """
    res = despeckle_detail(surface, method, k, axis, replace)
    return res.surface, res.n_replaced
