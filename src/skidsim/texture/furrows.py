"""Furrow parameters Fdmax, Fdmean (mm) and Fden (cm/cm^2): our definition (MountainsMap's is not public).

Definition (docs/texture.md):

* A *furrow point* is a strict local minimum of a profile along x (each row) or along y (each column) whose
  *depth* ``min(max z over the w points before, max z over the w points after) - z`` is at least
  ``min_depth_pct`` % of Sz (``w = window_mm / spacing`` points). Points closer than ``w + 1`` to the ends of
  the profile are not tested.
* Fdmax and Fdmean are the maximum and mean furrow depth over all furrow points (both directions).
* Fden is the furrow length per unit area by Cauchy-Crofton: a furrow line crossing a profile makes a furrow
  point, and for isotropically oriented lines the length per area is ``L_A = (pi/2) P_L`` with ``P_L`` the
  crossings per unit profile length averaged over directions; we average x and y:
  ``L_A = (pi/4) (P_x + P_y)`` in 1/mm, reported in cm/cm^2 (x 10). Unbiased for isotropic furrows; for furrows
  all along one grid axis it reads ``pi/4`` of the true length.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def _furrow_depths(z: np.ndarray, w: int, axis: int) -> tuple[np.ndarray, int]:
    """Depths (mm) of the furrow candidates along ``axis`` and the number of tested points."""
    if axis == 0:
        z = z.T
    n = z.shape[1]
    size = 2 * (w // 2) + 1  # odd window of ~w points
    half = (size + 1) // 2
    if n <= 2 * half + 2:
        return np.empty(0), 0
    m = ndimage.maximum_filter1d(z, size=size, axis=1, mode="nearest")
    j = slice(half, n - half)
    zc = z[:, j]
    left = m[:, 0 : n - 2 * half]  # center j - half
    right = m[:, 2 * half : n]  # center j + half
    prev = z[:, half - 1 : n - half - 1]
    nxt = z[:, half + 1 : n - half + 1]
    is_min = (zc < prev) & (zc < nxt)
    depth = np.minimum(left, right)[is_min] - zc[is_min]
    return depth, zc.size


def furrow_parameters(
    zc: np.ndarray, dx: float, dy: float, *, window_mm: float = 2.0, min_depth_pct: float = 5.0
) -> dict[str, float]:
    """Fdmax, Fdmean (mm), Fden (cm/cm^2) of heights ``zc`` (mm); see the module docstring."""
    sz = float(zc.max() - zc.min())
    tmin = min_depth_pct / 100.0 * sz
    total_depths = []
    p = []
    for axis, step in ((1, dx), (0, dy)):
        w = max(1, int(round(window_mm / step)))
        depth, tested = _furrow_depths(zc, w, axis)
        depth = depth[depth >= tmin] if depth.size else depth
        total_depths.append(depth)
        p.append(depth.size / (tested * step) if tested else 0.0)  # crossings per mm of profile
    d = np.concatenate(total_depths)
    la = np.pi / 4.0 * (p[0] + p[1])  # 1/mm
    return {"Fdmax": float(d.max()) if d.size else 0.0, "Fdmean": float(d.mean()) if d.size else 0.0, "Fden": 10.0 * la}
