"""Invalid-point filling, form removal and the areal Butterworth band separation.

Conventions that change numbers (also in ``docs/texture.md``):

* **Filling** (:func:`fill_invalid`): invalid (NaN) points are filled before any FFT/DCT step. Default
  ``"linear"``: along each row (x), linear interpolation between the nearest valid neighbours, the ends held
  at the nearest valid value; rows with no valid point are then filled the same way along the columns (y).
* **Form** (:func:`remove_form`): least-squares polynomial in x and y of total degree ``d`` (``"plane"`` = 1),
  fitted to the valid points and subtracted; the result has zero mean over the valid points.
* **Butterworth** (:func:`butterworth_gain`): the areal (isotropic, radial frequency ``f = sqrt(fx^2 + fy^2)``)
  Butterworth low-pass of order ``n`` and cut-off wavelength ``lc`` (mm) has magnitude
  ``|H| = 1 / sqrt(1 + (f lc)^(2n))``. It is applied **zero-phase** (as forward-backward filtering would), so the
  transmitted gain is ``|H|^2 = 1 / (1 + (f lc)^(2n))``: exactly 50 % at the cut-off, as ISO 16610 filters.
  The high-pass is the complement ``1 - |H|^2``; the band-pass is the product of a low-pass and a high-pass.
* **Edges**: the spectrum is taken with the type-II DCT, i.e. the surface is mirror-extended (half-sample
  symmetric) in x and y. The extension is continuous, so no wrap-around step enters the filter; the DCT
  frequency of index ``k`` on ``N`` points of spacing ``d`` is ``k / (2 N d)``.
"""

from __future__ import annotations

import numpy as np

from skidsim._lazy import lazy_module
from skidsim.surface import Surface

sfft = lazy_module("scipy.fft")  # imported on first use (skidsim._lazy)

FILL_METHODS = ("linear", "nearest", "mean")


def _interp_runs_linear(h: np.ndarray) -> int:
    """:func:`_interp_rows` ``"linear"`` on a C-contiguous array, by runs of NaN instead of row by row: a run is
    filled from the valid points either side of it in its row, with ``np.interp``'s arithmetic
    (``slope * (x - x0) + z0``, ``slope = (z1 - z0) / (x1 - x0)`` on float distances), or held at the one valid
    end; the same values. Returns the number of rows without a valid point (left NaN)."""
    rows, cols = h.shape
    flat = h.ravel()
    pos = np.flatnonzero(np.isnan(flat))
    if pos.size == 0:
        return 0
    row_of = pos // cols
    brk = np.flatnonzero((np.diff(pos) != 1) | (np.diff(row_of) != 0)) + 1
    start = pos[np.r_[0, brk]]  # first NaN of each run
    stop = pos[np.r_[brk - 1, pos.size - 1]]  # last NaN of each run
    col0, col1 = start % cols, stop % cols
    has_left, has_right = col0 > 0, col1 < cols - 1
    run_of = np.repeat(np.arange(start.size), np.diff(np.r_[0, brk, pos.size]))
    left = start - 1  # the valid neighbours (where they exist in the row)
    right = stop + 1
    both = (has_left & has_right).take(run_of)
    only_right = (~has_left & has_right).take(run_of)
    only_left = (has_left & ~has_right).take(run_of)
    vals = np.empty(pos.size)
    r = run_of[both]
    z0, z1 = flat.take(left.take(r)), flat.take(right.take(r))
    x0 = (col0.take(r) - 1).astype(np.float64)
    slope = (z1 - z0) / ((col1.take(r) + 1).astype(np.float64) - x0)
    vals[both] = slope * ((pos[both] % cols).astype(np.float64) - x0) + z0
    vals[only_right] = flat.take(right.take(run_of[only_right]))
    vals[only_left] = flat.take(left.take(run_of[only_left]))
    empty = ~(has_left | has_right)  # a whole row
    fill = ~empty.take(run_of)
    flat[pos[fill]] = vals[fill]
    return int(empty.sum())


def _interp_rows(h: np.ndarray, method: str) -> int:
    """Fill NaNs in place along axis 1 of ``h``; returns the number of rows that had no valid point."""
    if method == "linear" and h.flags.c_contiguous:
        return _interp_runs_linear(h)
    n_cols = h.shape[1]
    x = np.arange(n_cols)
    bad_rows = np.flatnonzero(np.isnan(h).any(axis=1))
    empty = 0
    for i in bad_rows:
        row = h[i]
        ok = ~np.isnan(row)
        if not ok.any():
            empty += 1
            continue
        if method == "linear":
            row[~ok] = np.interp(x[~ok], x[ok], row[ok])
        else:  # nearest
            xo = x[ok]
            pos = np.clip(np.searchsorted(xo, x[~ok]), 1, len(xo) - 1) if len(xo) > 1 else np.zeros((~ok).sum(), int)
            if len(xo) > 1:
                left = xo[pos - 1]
                right = xo[pos]
                pick = np.where(np.abs(x[~ok] - left) <= np.abs(right - x[~ok]), left, right)
            else:
                pick = np.full((~ok).sum(), xo[0])
            row[~ok] = row[pick]
    return empty


def fill_invalid(surface: Surface, method: str = "linear") -> Surface:
    """Fill invalid (NaN) points; returns a new Surface without NaN (the input is not modified).

    Parameters
    ----------
    surface:
        Heights in mm, NaN = invalid.
    method:
        ``"linear"`` (default): linear interpolation along each row (x) between the nearest valid points, ends
        held constant; then along columns (y) for rows that were entirely invalid. ``"nearest"``: the nearest
        valid point along the row (then column). ``"mean"``: the mean height of the valid points.

    Raises
    ------
    ValueError
        Unknown method, or a surface without any valid point.
    """
    if method not in FILL_METHODS:
        raise ValueError(f"fill_invalid: method must be one of {FILL_METHODS}, got {method!r}")
    h = surface.heights
    if not np.isnan(h).any():
        return surface
    if not np.isfinite(h).any():
        raise ValueError(f"fill_invalid: surface {surface.name!r} has no valid point to fill from")
    out = np.array(h, dtype=np.float64)  # one copy
    out[np.isinf(out)] = np.nan
    if method == "mean":
        out[np.isnan(out)] = np.nanmean(out)
        return surface.with_heights(out)
    empty = _interp_rows(out, method)
    if empty:
        t = out.T  # view: fill the remaining (wholly invalid) rows along y
        _interp_rows(t, method)
    return surface.with_heights(out)


def _poly_terms(degree: int) -> list[tuple[int, int]]:
    return [(i, t - i) for t in range(degree + 1) for i in range(t, -1, -1)]


def form_degree(form: str | int) -> int:
    """Polynomial degree for a ``form`` option: ``"plane"`` -> 1, ``"none"`` -> 0 (mean only), or an int >= 0."""
    if isinstance(form, str):
        if form == "plane":
            return 1
        if form == "none":
            return 0
        raise ValueError(f"form must be 'plane', 'none' or a polynomial degree (int >= 0), got {form!r}")
    deg = int(form)
    if deg < 0 or deg != form:
        raise ValueError(f"form degree must be an int >= 0, got {form!r}")
    return deg


def _form_coefficients(surface: Surface, form: str | int):
    """Least-squares coefficients of :func:`fit_form`: ``(coef, terms, upow, vpow)``."""
    deg = form_degree(form)
    h = surface.heights
    rows, cols = h.shape
    u = np.linspace(-1.0, 1.0, cols) if cols > 1 else np.zeros(1)
    v = np.linspace(-1.0, 1.0, rows) if rows > 1 else np.zeros(1)
    terms = _poly_terms(deg)
    upow = np.vander(u, deg + 1, increasing=True)  # (cols, deg+1)
    vpow = np.vander(v, deg + 1, increasing=True)  # (rows, deg+1)
    valid = np.isfinite(h)
    if valid.all():
        su = upow.T @ upow  # sums of u^(a+b)
        sv = vpow.T @ vpow
        zu = h @ upow  # (rows, deg+1): sum_j z_ij u_j^a
        rhs_full = vpow.T @ zu  # (deg+1 [v power], deg+1 [u power])
        a = np.array([[su[i, k] * sv[j, m] for (k, m) in terms] for (i, j) in terms])
        b = np.array([rhs_full[j, i] for (i, j) in terms])
    else:
        ii, jj = np.nonzero(valid)
        zv = h[ii, jj]
        design = np.stack([upow[jj, i] * vpow[ii, j] for (i, j) in terms], axis=1)
        a = design.T @ design
        b = design.T @ zv
    coef = np.linalg.lstsq(a, b, rcond=None)[0]
    return coef, terms, upow, vpow


def _form_rows(fit, r0: int, r1: int) -> np.ndarray:
    """Rows ``r0:r1`` of the form of :func:`fit_form` (the same sum of terms, in the same order)."""
    coef, terms, upow, vpow = fit
    out = np.zeros((r1 - r0, upow.shape[0]))
    for c, (i, j) in zip(coef, terms):
        out += c * np.outer(vpow[r0:r1, j], upow[:, i])
    return out


def fit_form(surface: Surface, form: str | int = "plane") -> np.ndarray:
    """Least-squares polynomial form of total degree ``form`` (mm), evaluated on the grid (rows, cols).

    Coordinates are scaled to [-1, 1] for conditioning. Complete grids use separable sums (no design
    matrix the size of the scan); grids with NaN use the valid points only.
    """
    return _form_rows(_form_coefficients(surface, form), 0, surface.heights.shape[0])


#: points of one block of rows of the form removal and of the band gains (a few arrays of it stay in cache)
_BLOCK_POINTS = 1 << 16


def _row_blocks(rows: int, cols: int):
    step = max(1, _BLOCK_POINTS // max(cols, 1))
    return ((r0, min(r0 + step, rows)) for r0 in range(0, rows, step))


def remove_form(surface: Surface, form: str | int = "plane") -> Surface:
    """Subtract the least-squares polynomial form (see :func:`fit_form`); NaN stay NaN. The form is evaluated
    and subtracted block by block of rows (the same values as ``heights - fit_form(...)``)."""
    h = surface.heights
    fit = _form_coefficients(surface, form)
    out = np.empty(h.shape)
    for r0, r1 in _row_blocks(*h.shape):
        np.subtract(h[r0:r1], _form_rows(fit, r0, r1), out=out[r0:r1])
    return surface.with_heights(out)


def butterworth_gain(f_per_mm: np.ndarray, cutoff_mm: float, order: int, kind: str = "low") -> np.ndarray:
    """Zero-phase Butterworth gain ``|H|^2`` at spatial frequency ``f_per_mm`` (1/mm) for cut-off wavelength
    ``cutoff_mm`` (mm) and order ``order``: low ``1/(1+(f lc)^(2n))``, high ``1 - low``."""
    if cutoff_mm <= 0 or order < 1:
        raise ValueError(f"butterworth_gain: cutoff_mm > 0 and order >= 1 expected, got {cutoff_mm}, {order}")
    u = np.array(f_per_mm, dtype=np.float64)  # a copy, also for scalars (0-d)
    u *= cutoff_mm
    u *= u  # (f lc)^2
    low = u.copy() if order > 1 else u
    for _ in range(order - 1):
        low *= u  # (f lc)^(2n) by integer products
    low += 1.0
    np.reciprocal(low, out=low)
    if kind == "low":
        return low
    if kind == "high":
        return 1.0 - low
    raise ValueError(f"butterworth_gain: kind must be 'low' or 'high', got {kind!r}")


def dct_radial_frequency(shape: tuple[int, int], dx: float, dy: float) -> np.ndarray:
    """Radial spatial frequency (1/mm) of each type-II DCT coefficient of a (rows, cols) grid."""
    rows, cols = shape
    fx = np.arange(cols) / (2.0 * cols * dx)
    fy = np.arange(rows) / (2.0 * rows * dy)
    return np.sqrt(fy[:, None] ** 2 + fx[None, :] ** 2)


def band_gains(f: np.ndarray, macro: tuple[float, float], order: int) -> dict[str, np.ndarray]:
    """Gains of the macro band-pass (``macro = (short_mm, long_mm)``) and of the micro high-pass (< short_mm)."""
    short_mm, long_mm = macro
    if not (0 < short_mm < long_mm):
        raise ValueError(f"macro band must be (short_mm, long_mm) with 0 < short < long, got {macro}")
    low_short = butterworth_gain(f, short_mm, order, "low")
    high_long = butterworth_gain(f, long_mm, order, "high")
    return {"macro": low_short * high_long, "micro": 1.0 - low_short}


def separate_bands(
    surface: Surface,
    macro: tuple[float, float] = (0.5, 50.0),
    order: int = 2,
    form: str | int = "plane",
    fill: str = "linear",
    workers: int = 1,
) -> dict[str, Surface]:
    """Form removal, then areal Butterworth band separation.

    Order of operations: fill invalid points (:func:`fill_invalid`, method ``fill``) -> subtract the
    least-squares form (``form``) -> type-II DCT (mirror edges) -> multiply by the zero-phase gains -> inverse.

    Parameters
    ----------
    surface:
        Heights in mm (NaN allowed; filled first).
    macro:
        ``(short_mm, long_mm)``: the macrotexture band keeps wavelengths between them (default 0.5-50 mm);
        microtexture keeps wavelengths below ``short_mm``.
    order:
        Butterworth order ``n`` of each low/high-pass (applied zero-phase, so the gain is ``|H|^2``).
    form:
        ``"plane"``, ``"none"`` or a polynomial degree.
    workers:
        Threads for scipy.fft.

    Returns
    -------
    dict with keys ``raw`` (filled, form removed, all wavelengths), ``macro``, ``micro``; all in mm.
    """
    filled = fill_invalid(surface, fill)
    raw = remove_form(filled, form)
    h = raw.heights
    coeff = sfft.dctn(h, type=2, norm="ortho", workers=workers)
    short_mm, long_mm = macro
    if not (0 < short_mm < long_mm):
        raise ValueError(f"macro band must be (short_mm, long_mm) with 0 < short < long, got {macro}")
    rows, cols = h.shape
    # band_gains(dct_radial_frequency(...)) times the coefficients, block by block of rows (the same values)
    fx = np.arange(cols) / (2.0 * cols * surface.dx)
    fy = np.arange(rows) / (2.0 * rows * surface.dy)
    fx2, fy2 = fx[None, :] ** 2, fy[:, None] ** 2
    g_macro, g_micro = np.empty(h.shape), np.empty(h.shape)
    for r0, r1 in _row_blocks(rows, cols):
        f = np.sqrt(fy2[r0:r1] + fx2)
        low_short = butterworth_gain(f, short_mm, order, "low")
        m = np.multiply(low_short, butterworth_gain(f, long_mm, order, "high"), out=g_macro[r0:r1])
        m *= coeff[r0:r1]
        m = np.subtract(1.0, low_short, out=g_micro[r0:r1])
        m *= coeff[r0:r1]
    del coeff
    out = {"raw": raw.with_heights(h, name=surface.name)}
    for band, g in (("macro", g_macro), ("micro", g_micro)):
        out[band] = raw.with_heights(
            sfft.idctn(g, type=2, norm="ortho", workers=workers, overwrite_x=True), name=surface.name
        )
    return out
