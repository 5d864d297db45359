"""Texture A, "chips": polygonal aggregate chips standing in a smooth, flat binder.

Geometry (all lengths mm):

* Chip seeds are a Poisson point process of intensity ``1 / size_mm^2``; each seed owns its Voronoi cell. A chip is
  the part of its cell farther than ``gap_mm / 2`` from the cell's edges and within ``radius_i`` of the seed
  (a rounded polygon); ``radius_i = size_mm x sqrt(cover / pi) x U(0.8, 1.2)`` aims at the area share ``cover``.
* A chip's top is a flat facet ``p_i + g_x (x - x_i) + g_y (y - y_i)`` with protrusion ``p_i = protrusion_mm x
  U(0.5, 1.0)`` and a random inclination of at most ``facet_slope`` (mm/mm); its flanks are bevelled at
  ``flank_slope`` (height rises ``flank_slope`` mm per mm from the chip's outline); the chip shapes are rounded by
  a Gaussian of sigma ``edge_round_mm`` (so that their edges do not put macrotexture into the micro band).
* The binder is the plane at height 0: every binder point of a row sits on one height code.
* Microtexture on the chip tops only: a Weierstrass-Mandelbrot sum of cosines (wavelengths ``micro_lmax_mm x
  gamma^-n``, n = 0..``micro_levels``-1, none shorter than 2.5 grid steps, amplitude ~ wavelength^``micro_hurst``,
  ``micro_directions`` random directions and phases per level), scaled to RMS ``micro_rms_mm``, faded in over
  0.3 mm from the chip outline.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

DEFAULTS = {
    "size_mm": (6.0, 14.0),  # section's nominal chip size: U(low, high)
    "cover": (0.25, 0.45),  # section's chip area share: U(low, high)
    "protrusion_mm": (0.7, 2.6),  # section's protrusion scale: U(low, high)
    "gap_mm": 0.6,
    "facet_slope": 0.12,
    "flank_slope": 1.5,
    "edge_round_mm": 0.25,  # Gaussian rounding of the chip shapes (sigma, mm)
    "micro_rms_mm": (0.005, 0.060),  # section's microtexture RMS on chip tops: U(low, high)
    "micro_hurst": 0.8,
    "micro_lmax_mm": 0.5,
    "micro_gamma": 1.5,
    "micro_levels": 8,
    "micro_directions": 6,
}


def section_draws(rng: np.random.Generator, c: dict) -> dict:
    """The section's texture levels (mm or dimensionless, see :data:`DEFAULTS`)."""
    return {k: float(rng.uniform(*c[k])) for k in ("size_mm", "cover", "protrusion_mm", "micro_rms_mm")}


def weierstrass_mandelbrot(rng: np.random.Generator, shape, dx_mm: float, c: dict) -> np.ndarray:
    """Zero-mean, unit-RMS Weierstrass-Mandelbrot field on the grid (see the module docstring)."""
    rows, cols = shape
    x = np.arange(cols) * dx_mm
    y = np.arange(rows) * dx_mm
    z = np.zeros(shape)
    for n in range(c["micro_levels"]):
        lam = c["micro_lmax_mm"] * c["micro_gamma"] ** -n
        if lam < 2.5 * dx_mm:  # below the grid's resolution
            break
        amp = lam ** c["micro_hurst"]
        for _ in range(c["micro_directions"]):
            th = rng.uniform(0.0, np.pi)
            ph = rng.uniform(0.0, 2 * np.pi)
            k = 2 * np.pi / lam
            # cos(a + b) = cos a cos b - sin a sin b keeps it separable (rows x cols outer products)
            ax = k * np.cos(th) * x
            by = k * np.sin(th) * y + ph
            z += amp * (np.cos(by)[:, None] * np.cos(ax)[None, :] - np.sin(by)[:, None] * np.sin(ax)[None, :])
    z -= z.mean()
    sd = z.std()
    return z / sd if sd > 0 else z


def render(rng: np.random.Generator, shape, dx_mm: float, sec: dict, site: dict, c: dict) -> tuple:
    """Clean height map (mm) of one site and its layout summary. ``sec``: :func:`section_draws`; ``site``:
    per-site factors ``protrusion_factor``, ``micro_factor``."""
    rows, cols = shape
    w, hgt = cols * dx_mm, rows * dx_mm
    size = sec["size_mm"]
    margin = 2 * size
    n_seeds = int(rng.poisson((w + 2 * margin) * (hgt + 2 * margin) / size**2))
    seeds = np.column_stack([rng.uniform(-margin, w + margin, n_seeds), rng.uniform(-margin, hgt + margin, n_seeds)])
    radius = size * np.sqrt(sec["cover"] / np.pi) * rng.uniform(0.8, 1.2, n_seeds)
    prot = sec["protrusion_mm"] * site["protrusion_factor"] * rng.uniform(0.5, 1.0, n_seeds)
    slope_mag = rng.uniform(0.0, c["facet_slope"], n_seeds)
    slope_dir = rng.uniform(0.0, 2 * np.pi, n_seeds)
    gx, gy = slope_mag * np.cos(slope_dir), slope_mag * np.sin(slope_dir)

    yy, xx = np.mgrid[0:rows, 0:cols]
    pts = np.column_stack([xx.ravel() * dx_mm, yy.ravel() * dx_mm])
    del xx, yy
    d, idx = cKDTree(seeds).query(pts, k=2)
    s1, s2 = seeds[idx[:, 0]], seeds[idx[:, 1]]
    sep = np.linalg.norm(s2 - s1, axis=1)
    to_edge = (d[:, 1] ** 2 - d[:, 0] ** 2) / (2 * sep)  # distance to the Voronoi bisector
    i = idx[:, 0]
    inside = np.minimum(to_edge - c["gap_mm"] / 2, radius[i] - d[:, 0])  # > 0 on the chip
    rel = pts - seeds[i]
    top = prot[i] + gx[i] * rel[:, 0] + gy[i] * rel[:, 1]
    z = np.where(inside > 0, np.minimum(top, c["flank_slope"] * inside), 0.0)
    z = np.maximum(z, 0.0).reshape(shape)
    z = ndimage.gaussian_filter(z, c["edge_round_mm"] / dx_mm, mode="nearest")  # rounded chip edges
    fade = np.clip(inside / 0.3, 0.0, 1.0).reshape(shape)
    micro_rms = sec["micro_rms_mm"] * site["micro_factor"]
    z = z + micro_rms * fade * weierstrass_mandelbrot(rng, shape, dx_mm, c)
    chip = (inside > 0).reshape(shape)
    z[~chip] = 0.0  # the binder stays exactly flat
    np.maximum(z, 0.0, out=z)  # no chip point below the binder
    info = {
        "chips": int(np.unique(i[inside > 0]).size),
        "chip_share": float(chip.mean()),
        "micro_rms_mm": float(micro_rms),
    }
    return z, info
