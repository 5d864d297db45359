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
  is noisy; the zero padding is sized to that domain) has no decay length. If no direction crosses, Sal is NaN;
  if some direction does not cross, Str is NaN (``on_border="nan"``, default) or the bound
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
from scipy import fft as sfft
from scipy import ndimage


@dataclass(frozen=True)
class SpatialResult:
    """Sal (mm), Str (1), Std (deg), whether every direction decayed inside the domain, decay lengths (mm)."""

    Sal: float
    Str: float
    Std: float
    decays_within: bool
    angles_deg: np.ndarray
    decay_mm: np.ndarray


def autocorrelation(z: np.ndarray, workers: int = 1, return_spectrum: bool = False, max_lag_fraction: float = 1.0):
    """Unbiased linear ACF (normalised, ACF(0)=1) of a complete height array for lags up to
    ``max_lag_fraction`` of the extent (``L = floor(f (n - 1))`` points per axis); the zero lag sits at index
    ``(Ly, Lx)`` of the returned ``(2 Ly + 1, 2 Lx + 1)`` array. The zero padding is ``L`` points per axis,
    enough to keep every returned lag free of wrap-around.

    With ``return_spectrum`` also returns the power |F|^2 of the zero-padded rfft2 (for Std) and the padded
    shape.
    """
    rows, cols = z.shape
    ly = int(np.floor(max_lag_fraction * (rows - 1)))
    lx = int(np.floor(max_lag_fraction * (cols - 1)))
    c = z - z.mean()
    shape = (sfft.next_fast_len(rows + ly, real=True), sfft.next_fast_len(cols + lx, real=True))
    spec = sfft.rfft2(c, s=shape, workers=workers)
    del c
    power = spec.real**2
    power += spec.imag**2
    amp = power.copy() if return_spectrum else None
    del spec
    full = sfft.irfft2(power, s=shape, workers=workers)
    del power
    ry = np.r_[shape[0] - ly : shape[0], 0 : ly + 1]
    rx = np.r_[shape[1] - lx : shape[1], 0 : lx + 1]
    acf = full[np.ix_(ry, rx)]
    del full
    ny = rows - np.abs(np.arange(-ly, ly + 1))
    nx = cols - np.abs(np.arange(-lx, lx + 1))
    acf /= ny[:, None]
    acf /= nx[None, :]
    acf /= acf[ly, lx]
    if return_spectrum:
        return acf, amp, shape
    return acf


def decay_lengths(
    acf: np.ndarray, dx: float, dy: float, s: float = 0.2, n_angles: int = 720, ray_step: float = 0.25
) -> tuple[np.ndarray, np.ndarray]:
    """Decay length (mm, NaN if no crossing within the lag domain of ``acf``, zero lag at its centre) to
    threshold ``s`` along ``n_angles`` directions in [0, 180) deg (angle from +x towards +y)."""
    r0 = (acf.shape[0] - 1) // 2
    c0 = (acf.shape[1] - 1) // 2
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
    lab, _ = ndimage.label(acf > s)
    sl = ndimage.find_objects(lab)[lab[r0, c0] - 1] if lab[r0, c0] else (slice(r0, r0 + 1), slice(c0, c0 + 1))
    del lab
    m = 4
    ra, rb = max(sl[0].start - m, 0), min(sl[0].stop + m, acf.shape[0])
    ca, cb = max(sl[1].start - m, 0), min(sl[1].stop + m, acf.shape[1])
    coef = ndimage.spline_filter(acf[ra:rb, ca:cb], order=3, mode="nearest")
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


@lru_cache(maxsize=4)
def _angular_bins(shape: tuple[int, int], dx: float, dy: float, step_deg: float) -> np.ndarray:
    """Angular bin (int32, -1 for the zero frequency) of every rfft2 coefficient; read-only, memoised."""
    fy = sfft.fftfreq(shape[0], d=dy).astype(np.float32)
    fx = sfft.rfftfreq(shape[1], d=dx).astype(np.float32)
    ang = np.degrees(np.arctan2(fy[:, None], fx[None, :]))
    ang %= 180.0
    nb = int(round(180.0 / step_deg))
    b = (ang / np.float32(step_deg)).astype(np.int32)
    b %= nb
    b[0, 0] = -1
    b.setflags(write=False)
    return b


def texture_direction(amp: np.ndarray, shape: tuple[int, int], dx: float, dy: float, step_deg: float = 0.5) -> float:
    """Std (deg in [0, 180)): direction of the maximum angular amplitude density of the rfft2 amplitude
    ``amp`` of a zero-padded grid ``shape``."""
    nb = int(round(180.0 / step_deg))
    b = _angular_bins(tuple(shape), float(dx), float(dy), float(step_deg))
    dens = np.bincount(b.ravel() + 1, weights=amp.ravel(), minlength=nb + 1)[1:]
    return float((np.argmax(dens) + 0.5) * step_deg)


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
) -> SpatialResult:
    """Sal (mm), Str, Std (deg) of a complete height array (mm); see the module docstring."""
    if on_border not in ("nan", "bound"):
        raise ValueError(f"on_border must be 'nan' or 'bound', got {on_border!r}")
    acf, amp, shape = autocorrelation(z, workers=workers, return_spectrum=True, max_lag_fraction=max_lag_fraction)
    std = texture_direction(amp, shape, dx, dy, std_step_deg)
    del amp
    ang, lengths = decay_lengths(acf, dx, dy, s=s, n_angles=n_angles)
    del acf
    within = bool(np.isfinite(lengths).all())
    if not np.isfinite(lengths).any():
        return SpatialResult(np.nan, np.nan, std, False, ang, lengths)
    sal = float(np.nanmin(lengths))
    if within or on_border == "bound":
        stri = sal / float(np.nanmax(lengths))
    else:
        stri = np.nan
    return SpatialResult(sal, stri, std, within, ang, lengths)
