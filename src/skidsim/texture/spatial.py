"""ISO 25178-2 spatial parameters Sal, Str (autocorrelation) and Std (texture direction).

Conventions (docs/texture.md):

* **ACF estimator**: the linear (non-circular) autocorrelation of the mean-subtracted heights by a zero-padded
  real FFT, *unbiased*: each lag is divided by the number of overlapping point pairs, then normalised by its
  zero-lag value (so ACF(0) = 1).
* **Decay lengths**: along ``n_angles`` directions over 0..180 deg (the ACF is point-symmetric) the ACF is
  sampled by cubic-spline interpolation at steps of ``ray_step`` grid lags from the origin; the decay length in a
  direction is the linearly interpolated distance (mm) of its first crossing below ``s`` (0.2). Sal = the
  shortest decay length; Str = Sal / longest decay length.
* **Border**: a direction that does not cross ``s`` before leaving the lag domain (half the scan extent by
  default, ``max_lag_fraction = 0.5``: beyond it fewer than half the points overlap and the unbiased estimator
  is noisy; the zero padding is sized to that domain; Sal and Str alone, ``direction=False``, pad by fewer lags
  where the region above ``s`` fits them: :func:`_decays_in_window`) has no decay length. If no direction
  crosses, Sal is NaN; if some direction does not cross, Str is NaN (``on_border="nan"``, default) or the bound
  Sal / (longest measured length) (``on_border="bound"``).
* **Std** (deg): the direction, counter-clockwise from +x with +y along increasing row index, of the maximum of
  the angular power spectrum: the sum of |F|^2 (power spectrum of the zero-padded heights) over radial
  frequencies in angular bins of ``std_step_deg`` over [0, 180). Its resolution is limited by the frequency
  grid (``1 / padded extent``) relative to the dominant frequency. It points along the frequency vector,
  i.e. across the lay (grooves along y give Std = 0).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from skidsim._lazy import lazy_module

sfft = lazy_module("scipy.fft")  # imported on first use (skidsim._lazy)
ndimage = lazy_module("scipy.ndimage")


@dataclass(frozen=True)
class SpatialResult:
    """Sal (mm), Str (1), Std (deg), whether every direction decayed inside the domain, decay lengths (mm)."""

    Sal: float
    Str: float
    Std: float
    decays_within: bool
    angles_deg: np.ndarray
    decay_mm: np.ndarray


_FFT_ROWS = 64  # rows of the zero-padded heights transformed along x at a time (the chunk stays in cache)


def _padded_spectrum(z: np.ndarray, workers: int, shape: tuple[int, int]) -> np.ndarray:
    """``scipy.fft.rfft2`` of the mean-subtracted heights zero-padded to ``shape``, bit for bit, without the padding
    rows: pocketfft's ``rfft2`` is the real transform along x of every row, then the complex transform along y of
    every column (in place). The rows of the padding transform to zeros, so only the ``rows`` rows of heights are
    transformed along x, ``_FFT_ROWS`` at a time (each row's transform is the same whatever rows share the call),
    each chunk padded in a small buffer; the padding rows of the result are set to zero, then the y transform runs
    on the whole array."""
    rows, cols = z.shape
    spec = np.empty((shape[0], shape[1] // 2 + 1), dtype=complex)
    spec[rows:] = 0.0
    mean = z.mean()
    buf = np.zeros((min(rows, _FFT_ROWS), shape[1]))  # its columns from cols on stay zero (the padding)
    for r0 in range(0, rows, _FFT_ROWS):
        r1 = min(r0 + _FFT_ROWS, rows)
        b = buf[: r1 - r0]
        np.subtract(z[r0:r1], mean, out=b[:, :cols])
        spec[r0:r1] = sfft.rfft(b, axis=1, workers=workers)
    return sfft.fft(spec, axis=0, workers=workers, overwrite_x=True)


def _lag_domain(shape: tuple[int, int], max_lag_fraction: float) -> tuple[int, int]:
    """``(Ly, Lx)``: the largest lags (points) of the ACF's domain, ``floor(f (n - 1))`` per axis."""
    return int(np.floor(max_lag_fraction * (shape[0] - 1))), int(np.floor(max_lag_fraction * (shape[1] - 1)))


def _padded_power(
    z: np.ndarray, workers: int, max_lag_fraction: float, keep_power: bool = True, pad: tuple[int, int] | None = None
):
    """|F|^2 of the zero-padded rfft2 of the mean-subtracted heights, the same values as a complex array (imaginary
    parts zero; the input of :class:`_AcfRows`, which overwrites it), the padded shape and the lag limits
    ``(Ly, Lx)`` (see :func:`autocorrelation`). ``|F|^2 = re^2 + im^2`` (each square rounded, then the sum) is
    formed in chunks of rows in the spectrum's own array and written back into it. Without ``keep_power`` the
    real array of |F|^2 is not kept (None; the complex one holds the same values).

    ``pad = (py, px)``: at least ``py`` rows and ``px`` columns of zeros instead of ``(Ly, Lx)``; the lag limits
    returned are then the lags free of wrap-around, ``min(Ly, padded rows - rows)`` and the same along x."""
    rows, cols = z.shape
    ly, lx = _lag_domain(z.shape, max_lag_fraction)
    py, px = (ly, lx) if pad is None else (min(ly, pad[0]), min(lx, pad[1]))
    shape = (sfft.next_fast_len(rows + py, real=True), sfft.next_fast_len(cols + px, real=True))
    ly, lx = min(ly, shape[0] - rows), min(lx, shape[1] - cols)
    spec = _padded_spectrum(z, workers, shape)
    power = np.empty(spec.shape) if keep_power else np.empty((min(_FFT_ROWS, spec.shape[0]), spec.shape[1]))
    for r0 in range(0, spec.shape[0], _FFT_ROWS):
        r1 = min(r0 + _FFT_ROWS, spec.shape[0])
        p, sp = (power[r0:r1] if keep_power else power[: r1 - r0]), spec[r0:r1]
        parts = sp.view(np.float64)  # re, im, re, im, ... of each row
        np.square(parts, out=parts)
        np.add(parts[:, 0::2], parts[:, 1::2], out=p)
        np.copyto(sp, p)  # real part p, imaginary part 0
    return (power if keep_power else None), spec, shape, ly, lx


class _AcfRows:
    """Rows of the unbiased ACF for lags ``|ky| <= k`` (every x lag up to ``Lx``), on demand.

    ``irfft2`` of the power spectrum is a complex inverse transform along y followed by a real one along x; the
    first is done once, the second only for the rows asked for. Every value is bit-identical to the same entry
    of the whole ACF (``scipy.fft.irfft2``, then the unbiased and ACF(0) normalisations): the same pocketfft
    transforms on the same data and the same scale factor applied to their output (tested).
    """

    def __init__(self, cpower: np.ndarray, shape, rows: int, cols: int, ly: int, lx: int, workers: int = 1):
        # the power as a complex array (irfft2 converts its input so; a real input would take pocketfft's
        # symmetric path: other roundings), from _padded_power; overwritten
        self.half = sfft.ifft(cpower, axis=0, norm="forward", workers=workers, overwrite_x=True)
        self.shape, self.rows, self.cols, self.ly, self.lx, self.workers = tuple(shape), rows, cols, ly, lx, workers
        # irfft2's scale factor 1 / (ny nx), computed as pocketfft does (long double, rounded once)
        self.fct = np.float64(1 / np.longdouble(self.shape[0] * self.shape[1]))

    def __call__(self, k: int) -> np.ndarray:
        """``(2 k + 1, 2 Lx + 1)`` ACF rows for lags ``-k..k`` (``k <= Ly``), zero lag at ``(k, Lx)``."""
        ny, nx = self.shape
        lx = self.lx
        part = sfft.irfft(self.half[np.r_[ny - k : ny, 0 : k + 1]], n=nx, axis=1, norm="forward", workers=self.workers)
        part *= self.fct
        acf = part[:, np.r_[nx - lx : nx, 0 : lx + 1]]
        del part
        acf /= (self.rows - np.abs(np.arange(-k, k + 1)))[:, None]
        acf /= (self.cols - np.abs(np.arange(-lx, lx + 1)))[None, :]
        acf /= acf[k, lx]
        return acf


def autocorrelation(z: np.ndarray, workers: int = 1, return_spectrum: bool = False, max_lag_fraction: float = 1.0):
    """Unbiased linear ACF (normalised, ACF(0)=1) of a complete height array for lags up to
    ``max_lag_fraction`` of the extent (``L = floor(f (n - 1))`` points per axis); the zero lag sits at index
    ``(Ly, Lx)`` of the returned ``(2 Ly + 1, 2 Lx + 1)`` array. The zero padding is ``L`` points per axis,
    enough to keep every returned lag free of wrap-around.

    With ``return_spectrum`` also returns the power |F|^2 of the zero-padded rfft2 (for Std) and the padded
    shape.
    """
    rows, cols = z.shape
    power, cpower, shape, ly, lx = _padded_power(z, workers, max_lag_fraction)
    acf = _AcfRows(cpower, shape, rows, cols, ly, lx, workers)(ly)
    if return_spectrum:
        return acf, power, shape
    return acf


_CROP_MARGIN = 4  # lags kept around the region above s for the spline of decay_lengths
_FIRST_WINDOW_LAGS = 128  # rows of the ACF either side of the zero lag tried first by spatial_parameters


def _central_crop(acf: np.ndarray, r0: int, c0: int, s: float) -> tuple[int, int, int, int]:
    """``(ra, rb, ca, cb)``: rows ``ra:rb`` and columns ``ca:cb`` of ``acf`` (zero lag at ``(r0, c0)``), the
    bounding box of the 4-connected region above ``s`` that holds the origin, widened by ``_CROP_MARGIN`` lags
    (clipped to the array)."""
    lab, _ = ndimage.label(acf > s)
    sl = ndimage.find_objects(lab)[lab[r0, c0] - 1] if lab[r0, c0] else (slice(r0, r0 + 1), slice(c0, c0 + 1))
    del lab
    m = _CROP_MARGIN
    ra, rb = max(sl[0].start - m, 0), min(sl[0].stop + m, acf.shape[0])
    ca, cb = max(sl[1].start - m, 0), min(sl[1].stop + m, acf.shape[1])
    return ra, rb, ca, cb


def decay_lengths(
    acf: np.ndarray, dx: float, dy: float, s: float = 0.2, n_angles: int = 720, ray_step: float = 0.25
) -> tuple[np.ndarray, np.ndarray]:
    """Decay length (mm, NaN if no crossing within the lag domain of ``acf``, zero lag at its centre) to
    threshold ``s`` along ``n_angles`` directions in [0, 180) deg (angle from +x towards +y)."""
    r0 = (acf.shape[0] - 1) // 2
    c0 = (acf.shape[1] - 1) // 2
    ra, rb, ca, cb = _central_crop(acf, r0, c0, s)
    return _decay_lengths_in_crop(acf[ra:rb, ca:cb], ra, ca, r0, c0, dx, dy, s, n_angles, ray_step)


def _decay_lengths_in_crop(crop, ra, ca, r0, c0, dx, dy, s, n_angles, ray_step):
    """:func:`decay_lengths` from ``crop = acf[ra:rb, ca:cb]`` (:func:`_central_crop`) of an ACF whose zero lag
    is at ``(r0, c0)`` and whose lag domain is ``r0`` rows and ``c0`` columns either side of it."""
    max_ly = r0 * dy  # mm
    max_lx = c0 * dx
    theta = np.arange(n_angles) * (np.pi / n_angles)
    ux, uy = np.cos(theta), np.sin(theta)
    # longest distance (mm) inside the lag ellipse-free rectangle along each ray
    with np.errstate(divide="ignore"):
        tx = np.where(np.abs(ux) > 1e-12, max_lx / np.abs(ux), np.inf)
        ty = np.where(np.abs(uy) > 1e-12, max_ly / np.abs(uy), np.inf)
    tmax = np.minimum(tx, ty)
    h = ray_step * min(dx, dy)
    n_steps = int(np.ceil(tmax.max() / h)) + 1
    out = np.full(n_angles, np.nan)
    # cubic interpolation on a crop around the central region above s (bounding box + margin): the crossing of
    # every ray lies inside it, and the spline prefilter stays cheap
    coef = ndimage.spline_filter(crop, order=3, mode="nearest")
    # march rays in chunks of distance so that short decays do not pay for the whole domain
    chunk = 256
    alive = np.ones(n_angles, dtype=bool)
    prev_val = np.ones(n_angles)
    prev_d = np.zeros(n_angles)
    for start in range(1, n_steps, chunk):
        idx = np.flatnonzero(alive)
        if idx.size == 0:
            break
        d = np.arange(start, min(start + chunk, n_steps)) * h  # mm
        rows = r0 + (uy[idx, None] * d[None, :]) / dy
        cols = c0 + (ux[idx, None] * d[None, :]) / dx
        vals = ndimage.map_coordinates(
            coef, [rows.ravel() - ra, cols.ravel() - ca], order=3, mode="nearest", prefilter=False
        )
        vals = vals.reshape(idx.size, d.size)
        inside = d[None, :] <= tmax[idx, None]
        below = (vals < s) & inside
        hit = below.any(axis=1)
        first = np.argmax(below, axis=1)
        for k in np.flatnonzero(hit):
            j = first[k]
            v1, d1 = vals[k, j], d[j]
            v0, d0 = (vals[k, j - 1], d[j - 1]) if j > 0 else (prev_val[idx[k]], prev_d[idx[k]])
            out[idx[k]] = d0 + (v0 - s) / (v0 - v1) * (d1 - d0) if v0 != v1 else d1
        done = hit | ~inside[:, -1]
        prev_val[idx] = vals[:, -1]
        prev_d[idx] = d[-1]
        alive[idx[done]] = False
    return np.degrees(theta), out


@lru_cache(maxsize=2)
def _angular_bins(shape: tuple[int, int], dx: float, dy: float, step_deg: float) -> np.ndarray:
    """Angular bin + 1 (intp, 0 for the zero frequency) of every rfft2 coefficient, flat, as ``np.bincount``
    takes it; read-only, memoised."""
    fy = sfft.fftfreq(shape[0], d=dy).astype(np.float32)
    fx = sfft.rfftfreq(shape[1], d=dx).astype(np.float32)
    ang = np.degrees(np.arctan2(fy[:, None], fx[None, :]))
    ang %= 180.0
    nb = int(round(180.0 / step_deg))
    b = (ang / np.float32(step_deg)).astype(np.int32)
    b %= nb
    b[0, 0] = -1
    b = (b.ravel() + 1).astype(np.intp)
    b.setflags(write=False)
    return b


def texture_direction(amp: np.ndarray, shape: tuple[int, int], dx: float, dy: float, step_deg: float = 0.5) -> float:
    """Std (deg in [0, 180)): direction of the maximum angular amplitude density of the rfft2 amplitude
    ``amp`` of a zero-padded grid ``shape``."""
    nb = int(round(180.0 / step_deg))
    b = _angular_bins(tuple(shape), float(dx), float(dy), float(step_deg))
    dens = np.bincount(b, weights=amp.ravel(), minlength=nb + 1)[1:]
    return float((np.argmax(dens) + 0.5) * step_deg)


def _decays_in_window(z, dx, dy, s, n_angles, workers, max_lag_fraction):
    """The decay lengths of :func:`spatial_parameters` from a zero padding of only ``_FIRST_WINDOW_LAGS`` lags
    per axis (rounded up to a fast FFT length): ``(angles, lengths)``, or None where the region above ``s`` (with
    the crop's margin) reaches the border of the lags that padding keeps free of wrap-around (and that border is
    not the lag domain's). Every lag it computes is the same sum of products as with the domain's padding (the
    linear ACF is exact for lags up to the padding), so the crop and the decay lengths are the same up to the
    FFT's rounding (other transform lengths): relative differences of order 1e-15."""
    rows, cols = z.shape
    pad = (_FIRST_WINDOW_LAGS, _FIRST_WINDOW_LAGS)
    _, cpower, shape, ky, kx = _padded_power(z, workers, max_lag_fraction, keep_power=False, pad=pad)
    ly, lx = _lag_domain(z.shape, max_lag_fraction)
    win = _AcfRows(cpower, shape, rows, cols, ky, kx, workers)(ky)
    del cpower
    ra, rb, ca, cb = _central_crop(win, ky, kx, s)
    inside_y = ky == ly or (ra > 0 and rb < win.shape[0])
    inside_x = kx == lx or (ca > 0 and cb < win.shape[1])
    if not (inside_y and inside_x):
        return None
    return _decay_lengths_in_crop(win[ra:rb, ca:cb], ra + ly - ky, ca + lx - kx, ly, lx, dx, dy, s, n_angles, 0.25)


def spatial_parameters(
    z: np.ndarray,
    dx: float,
    dy: float,
    s: float = 0.2,
    n_angles: int = 720,
    on_border: str = "nan",
    std_step_deg: float = 0.5,
    workers: int = 1,
    max_lag_fraction: float = 0.5,
    direction: bool = True,
) -> SpatialResult:
    """Sal (mm), Str, Std (deg) of a complete height array (mm); see the module docstring. ``direction=False``:
    Sal and Str alone (Std NaN), without the angular power spectrum and, where the region of the ACF above ``s``
    lies well inside the first ``_FIRST_WINDOW_LAGS`` lags, from a zero padding of only those lags
    (:func:`_decays_in_window`): the same Sal and Str up to the FFT's rounding (relative 1e-15)."""
    if on_border not in ("nan", "bound"):
        raise ValueError(f"on_border must be 'nan' or 'bound', got {on_border!r}")
    found = None if direction else _decays_in_window(z, dx, dy, s, n_angles, workers, max_lag_fraction)
    std = np.nan
    if found is None:
        rows, cols = z.shape
        power, cpower, shape, ly, lx = _padded_power(z, workers, max_lag_fraction, keep_power=direction)
        std = texture_direction(power, shape, dx, dy, std_step_deg) if direction else np.nan
        del power
        acf_rows = _AcfRows(cpower, shape, rows, cols, ly, lx, workers)
        del cpower
        # Only the rows of the ACF around the region above s are needed (decay_lengths' crop). Rows |ky| <= k are
        # computed for a growing k until that region (with the crop's margin) ends inside them; then the region,
        # the crop and every decay length are those of the whole ACF (a 4-connected region that does not reach
        # the first or last row of the window cannot continue outside it).
        k = min(ly, _FIRST_WINDOW_LAGS)
        while True:
            win = acf_rows(k)
            ra, rb, ca, cb = _central_crop(win, k, lx, s)
            if k == ly or (ra > 0 and rb < win.shape[0]):
                break
            k = min(ly, 4 * k)
        crop = win[ra:rb, ca:cb]
        del win, acf_rows
        found = _decay_lengths_in_crop(crop, ra + ly - k, ca, ly, lx, dx, dy, s, n_angles, 0.25)
    ang, lengths = found
    within = bool(np.isfinite(lengths).all())
    if not np.isfinite(lengths).any():
        return SpatialResult(np.nan, np.nan, std, False, ang, lengths)
    sal = float(np.nanmin(lengths))
    if within or on_border == "bound":
        stri = sal / float(np.nanmax(lengths))
    else:
        stri = np.nan
    return SpatialResult(sal, stri, std, within, ang, lengths)
