"""Instrument artefacts of a laser texture scanner, applied to a clean height map (mm) in this order: plane tilt,
dropouts (NaN blobs), spikes, quantisation to integer height codes.

Written for the independent generators; it shares no code with :mod:`skidsim.generators.default`. Every count is exact
(``round(fraction x points)``), so tests can check them.
"""

from __future__ import annotations

import numpy as np


def tilt(h: np.ndarray, rng: np.random.Generator, dx_mm: float, max_slope: float, axis: str) -> tuple:
    """Add a plane of slope U(0, max_slope) (dimensionless, mm/mm): ``axis="y"`` tilts across rows only (each row
    keeps its height: the carriage's level across its travel), ``"any"`` in a random direction."""
    slope = float(rng.uniform(0.0, max_slope))
    angle = np.pi / 2 if axis == "y" else float(rng.uniform(0.0, 2 * np.pi))
    rows, cols = h.shape
    x = np.arange(cols) * dx_mm
    y = np.arange(rows) * dx_mm
    plane = slope * (np.cos(angle) * x[None, :] + np.sin(angle) * y[:, None])
    return h + plane, {"tilt_slope": slope, "tilt_angle_rad": angle}


def dropouts(
    h: np.ndarray,
    rng: np.random.Generator,
    dx_mm: float,
    fraction: float,
    radius_mm: tuple[float, float],
    low_quantile: float,
) -> tuple:
    """Set ``round(fraction x n)`` points to NaN in discs of radius U(radius_mm) centred on points among the lowest
    ``low_quantile`` of heights (occlusion in voids); the last disc is trimmed to the exact count."""
    out = h.copy()
    n_target = int(round(fraction * h.size))
    if n_target == 0:
        return out, {"dropout_points": 0, "dropout_blobs": 0}
    candidates = np.flatnonzero(h.ravel() <= np.quantile(h, low_quantile))
    rows, cols = h.shape
    done = 0
    blobs = 0
    while done < n_target:
        c = int(candidates[rng.integers(candidates.size)])
        ci, cj = divmod(c, cols)
        r = float(rng.uniform(*radius_mm)) / dx_mm
        k = int(np.ceil(r))
        i0, i1, j0, j1 = max(ci - k, 0), min(ci + k + 1, rows), max(cj - k, 0), min(cj + k + 1, cols)
        ii, jj = np.mgrid[i0:i1, j0:j1]
        inside = ((ii - ci) ** 2 + (jj - cj) ** 2 <= r * r) & ~np.isnan(out[i0:i1, j0:j1])
        idx = np.flatnonzero(inside)[: n_target - done]
        if idx.size:
            out[ii.ravel()[idx], jj.ravel()[idx]] = np.nan
            done += idx.size
            blobs += 1
    return out, {"dropout_points": int(done), "dropout_blobs": blobs}


def spikes(h: np.ndarray, rng: np.random.Generator, fraction: float, height_mm: tuple[float, float]) -> tuple:
    """Add +-U(height_mm) mm (sign 50/50) to exactly ``round(fraction x n)`` distinct valid points."""
    out = h.copy()
    valid = np.flatnonzero(np.isfinite(h.ravel()))
    n = int(round(fraction * h.size))
    idx = np.sort(rng.choice(valid, size=n, replace=False))
    size = rng.uniform(*height_mm, size=n) * rng.choice([-1.0, 1.0], size=n)
    out.ravel()[idx] += size
    return out, {"spike_points": n, "spike_index": idx.tolist()}


def quantise(h: np.ndarray, step_mm: float) -> np.ndarray:
    """Round to integer multiples of ``step_mm`` (the scanner's height code; NaN stays NaN)."""
    return np.round(h / step_mm) * step_mm


def scan(clean: np.ndarray, rng: np.random.Generator, dx_mm: float, c: dict) -> tuple[np.ndarray, dict]:
    """All artefacts with the settings ``c`` (keys tilt_max, tilt_axis, dropout_fraction, dropout_radius_mm,
    dropout_low_quantile, spike_fraction, spike_mm, z_step_mm). Returns (heights mm, info)."""
    h, info = tilt(clean, rng, dx_mm, c["tilt_max"], c["tilt_axis"])
    h, i2 = dropouts(h, rng, dx_mm, c["dropout_fraction"], tuple(c["dropout_radius_mm"]), c["dropout_low_quantile"])
    h, i3 = spikes(h, rng, c["spike_fraction"], tuple(c["spike_mm"]))
    info.update(i2)
    info.update({"spike_points": i3["spike_points"]})
    return quantise(h, c["z_step_mm"]), info
