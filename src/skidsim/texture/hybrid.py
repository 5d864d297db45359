"""ISO 25178-2 hybrid parameters Sdq and Sdr (discretisation documented in docs/texture.md).

* **Sdq** (dimensionless): ``sqrt(mean(dz/dx)^2 + mean(dz/dy)^2)`` with forward differences; each direction is
  averaged over its own differences (``rows*(cols-1)`` along x, ``(rows-1)*cols`` along y).
* **Sdr** (%): ISO 25178-2:2021 eq. D.15: every grid cell is split into two triangles along each diagonal, the
  two triangulations are averaged (equivalently: half the sum of the four corner triangles), and the developed
  area is divided by the projected area of the cells ``(cols-1) dx * (rows-1) dy``; ``Sdr = (A/A0 - 1) * 100``.
"""

from __future__ import annotations

import numpy as np


def sdq(z: np.ndarray, dx: float, dy: float) -> float:
    """Root-mean-square gradient (dimensionless) of a complete height array (mm) on spacings dx, dy (mm)."""
    gx = np.diff(z, axis=1)
    gy = np.diff(z, axis=0)
    mx = float(np.einsum("ij,ij->", gx, gx)) / gx.size / dx**2
    my = float(np.einsum("ij,ij->", gy, gy)) / gy.size / dy**2
    return float(np.sqrt(mx + my))


def developed_area(z: np.ndarray, dx: float, dy: float) -> float:
    """Developed (true) area in mm^2 by ISO 25178-2 eq. D.15 (both diagonal triangulations averaged)."""
    gx = np.diff(z, axis=1)  # (R, C-1)
    gx *= dy
    np.square(gx, out=gx)  # (dy dz_x)^2
    gy = np.diff(z, axis=0)  # (R-1, C)
    gy *= dx
    np.square(gy, out=gy)  # (dx dz_y)^2
    cz = (dx * dy) ** 2
    total = 0.0
    for xs in (gx[:-1, :], gx[1:, :]):  # bottom, top x edges of each cell
        for ys in (gy[:, :-1], gy[:, 1:]):  # left, right y edges
            t = xs + ys
            t += cz
            np.sqrt(t, out=t)
            total += float(t.sum())
    return 0.25 * total


def sdr(z: np.ndarray, dx: float, dy: float) -> float:
    """Developed interfacial area ratio in % (ISO 25178-2 eq. D.15; see module docstring)."""
    rows, cols = z.shape
    a0 = (cols - 1) * dx * (rows - 1) * dy
    return (developed_area(z, dx, dy) / a0 - 1.0) * 100.0
