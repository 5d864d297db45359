"""ISO 25178-2 hybrid parameters Sdq and Sdr (discretisation documented in docs/texture.md).

* **Sdq** (dimensionless): ``sqrt(mean(dz/dx)^2 + mean(dz/dy)^2)`` with forward differences; each direction is
  averaged over its own differences (``rows*(cols-1)`` along x, ``(rows-1)*cols`` along y).
* **Sdr** (%): ISO 25178-2:2021 eq. D.15: every grid cell is split into two triangles along each diagonal, the
  two triangulations are averaged (equivalently: half the sum of the four corner triangles), and the developed
  area is divided by the projected area of the cells ``(cols-1) dx * (rows-1) dy``; ``Sdr = (A/A0 - 1) * 100``.
"""

from __future__ import annotations

import numpy as np

from .pairwise import leaves, pairwise_tree, tree_sum


def sdq(z: np.ndarray, dx: float, dy: float) -> float:
    """Root-mean-square gradient (dimensionless) of a complete height array (mm) on spacings dx, dy (mm)."""
    return hybrid_parameters(z, dx, dy, area=False)["Sdq"]


def _sdq_of(gx: np.ndarray, gy: np.ndarray, dx: float, dy: float) -> float:
    mx = float(np.einsum("ij,ij->", gx, gx)) / gx.size / dx**2
    my = float(np.einsum("ij,ij->", gy, gy)) / gy.size / dy**2
    return float(np.sqrt(mx + my))


def _developed_area_of(gx: np.ndarray, gy: np.ndarray, dx: float, dy: float) -> float:
    """Eq. D.15 (mm^2) from the forward differences ``gx = diff(z, axis=1)``, ``gy = diff(z, axis=0)`` (mm).

    Per cell and corner triangle ``sqrt((dy dz_x)^2 + (dx dz_y)^2 + (dx dy)^2)``; each of the four corner
    choices is summed over the cells as ``np.sum`` of the whole ``(rows - 1, cols - 1)`` array does (pairwise),
    but evaluated in blocks of rows that stay in cache (:mod:`skidsim.texture.pairwise`): the same bits."""
    r1, c1 = gx.shape[0] - 1, gy.shape[1] - 1  # cells
    if r1 <= 0 or c1 <= 0:
        return 0.0
    cz = (dx * dy) ** 2
    tree = pairwise_tree(0, r1 * c1)
    sums: list[dict] = [{}, {}, {}, {}]
    for leaf in leaves(tree):
        s, length = leaf
        ra, rb = s // c1, (s + length - 1) // c1 + 1  # rows of cells holding the leaf
        sx = np.multiply(gx[ra : rb + 1], dy)
        np.square(sx, out=sx)  # (dy dz_x)^2 on the bottom and top edges of the cells
        sy = np.multiply(gy[ra:rb], dx)
        np.square(sy, out=sy)  # (dx dz_y)^2 on the left and right edges
        t = np.empty((rb - ra, c1))
        flat = t.ravel()[s - ra * c1 : s - ra * c1 + length]
        k = 0
        for xs in (sx[:-1], sx[1:]):  # bottom, top x edges of each cell
            for ys in (sy[:, :-1], sy[:, 1:]):  # left, right y edges
                np.add(xs, ys, out=t)
                t += cz
                np.sqrt(t, out=t)
                sums[k][leaf] = flat.sum()
                k += 1
    total = 0.0
    for part in sums:
        total += float(tree_sum(tree, part))
    return 0.25 * total


def developed_area(z: np.ndarray, dx: float, dy: float) -> float:
    """Developed (true) area in mm^2 by ISO 25178-2 eq. D.15 (both diagonal triangulations averaged)."""
    return _developed_area_of(np.diff(z, axis=1), np.diff(z, axis=0), dx, dy)


def sdr(z: np.ndarray, dx: float, dy: float) -> float:
    """Developed interfacial area ratio in % (ISO 25178-2 eq. D.15; see module docstring); the same bits as
    :func:`hybrid_parameters`' ``Sdr``, without Sdq."""
    return _sdr_of(np.diff(z, axis=1), np.diff(z, axis=0), z.shape, dx, dy)


def _sdr_of(gx: np.ndarray, gy: np.ndarray, shape: tuple[int, int], dx: float, dy: float) -> float:
    rows, cols = shape
    a0 = (cols - 1) * dx * (rows - 1) * dy
    return (_developed_area_of(gx, gy, dx, dy) / a0 - 1.0) * 100.0


def hybrid_parameters(z: np.ndarray, dx: float, dy: float, area: bool = True) -> dict[str, float]:
    """``{"Sdq": .., "Sdr": ..}`` (Sdr only with ``area``) from one pair of forward differences."""
    gx = np.diff(z, axis=1)  # (R, C-1)
    gy = np.diff(z, axis=0)  # (R-1, C)
    out = {"Sdq": _sdq_of(gx, gy, dx, dy)}
    if area:
        out["Sdr"] = _sdr_of(gx, gy, z.shape, dx, dy)
    return out
