"""Texture B, "spectral": a non-Gaussian random field from a power spectrum, with sand-grain microtexture.

* Macrotexture: a Gaussian field with the anisotropic spectrum ``(1 + (qx lx)^2 + (qy ly)^2)^-(1 + H)`` (q in rad/mm,
  correlation lengths ``lx``, ``ly`` mm, Hurst exponent H), wavelengths below ``macro_cut_mm`` removed, made unit
  variance and mapped point by point through a negatively skewed marginal, ``-exp(sigma G)`` (a mirrored
  log-normal: deep narrow voids between broad plateaus, as on porous asphalt and SMA), standardised and scaled to
  RMS ``macro_sq_mm``.
* Microtexture: shot noise of sand grains: a Poisson number of grains per grid point (``grain_density_per_mm2``),
  each a spherical cap of radius ``grain_radius_mm``, standardised and scaled to RMS ``micro_rms_mm``; added
  everywhere.
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft
from scipy.signal import fftconvolve

DEFAULTS = {
    "corr_mm": (2.0, 6.0),  # section's correlation length along x: U(low, high)
    "aspect": (0.6, 1.6),  # section's ly / lx: U(low, high)
    "hurst": 0.8,
    "macro_cut_mm": 2.0,
    "skew_sigma": (0.3, 0.7),  # section's log-normal sigma of the marginal: U(low, high)
    "macro_sq_mm": (0.2, 1.2),  # section's macro RMS: U(low, high)
    "micro_rms_mm": (0.005, 0.060),  # section's micro RMS: U(low, high)
    "grain_density_per_mm2": 10.0,
    "grain_radius_mm": 0.15,
}


def section_draws(rng: np.random.Generator, c: dict) -> dict:
    """The section's texture levels (see :data:`DEFAULTS`)."""
    return {k: float(rng.uniform(*c[k])) for k in ("corr_mm", "aspect", "skew_sigma", "macro_sq_mm", "micro_rms_mm")}


def gaussian_field(
    rng: np.random.Generator, shape, dx_mm: float, lx_mm: float, ly_mm: float, hurst: float, cut_mm: float
) -> np.ndarray:
    """Zero-mean unit-variance Gaussian field with the spectrum of the module docstring (periodic, by FFT)."""
    rows, cols = shape
    qx = 2 * np.pi * sfft.rfftfreq(cols, dx_mm)
    qy = 2 * np.pi * sfft.fftfreq(rows, dx_mm)
    q2 = (qx[None, :] * lx_mm) ** 2 + (qy[:, None] * ly_mm) ** 2
    amp = (1.0 + q2) ** (-(1.0 + hurst) / 2)
    qmag = np.sqrt(qx[None, :] ** 2 + qy[:, None] ** 2)
    amp[qmag > 2 * np.pi / cut_mm] = 0.0
    amp[0, 0] = 0.0
    noise = sfft.rfft2(rng.standard_normal(shape))
    g = sfft.irfft2(noise * amp, s=shape)
    return (g - g.mean()) / g.std()


def sand_grains(rng: np.random.Generator, shape, dx_mm: float, density_per_mm2: float, radius_mm: float) -> np.ndarray:
    """Zero-mean unit-RMS shot noise of spherical caps (see the module docstring)."""
    counts = rng.poisson(density_per_mm2 * dx_mm * dx_mm, size=shape).astype(float)
    k = max(int(np.ceil(radius_mm / dx_mm)), 1)
    ii, jj = np.mgrid[-k : k + 1, -k : k + 1] * dx_mm
    cap = np.sqrt(np.clip(radius_mm**2 - ii**2 - jj**2, 0.0, None))
    z = fftconvolve(counts, cap, mode="same")
    z -= z.mean()
    sd = z.std()
    return z / sd if sd > 0 else z


def render(rng: np.random.Generator, shape, dx_mm: float, sec: dict, site: dict, c: dict) -> tuple:
    """Clean height map (mm) of one site and its summary. ``site``: factors ``macro_factor``, ``micro_factor``."""
    lx = sec["corr_mm"]
    g = gaussian_field(rng, shape, dx_mm, lx, lx * sec["aspect"], c["hurst"], c["macro_cut_mm"])
    m = -np.exp(sec["skew_sigma"] * g)
    m = (m - m.mean()) / m.std()
    macro_sq = sec["macro_sq_mm"] * site["macro_factor"]
    micro_rms = sec["micro_rms_mm"] * site["micro_factor"]
    z = macro_sq * m + micro_rms * sand_grains(rng, shape, dx_mm, c["grain_density_per_mm2"], c["grain_radius_mm"])
    return z, {"macro_sq_mm": float(macro_sq), "micro_rms_mm": float(micro_rms)}
