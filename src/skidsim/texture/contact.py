"""Microtexture of the contact zone: the micro band on the surface's tops, where a slider touches.

A DFT slider (or a tyre) rests on the highest parts of the texture, the aggregate tops; the microtexture of the
binder and of the valleys between stones never touches it. The whole-scan micro Sq averages over both, so on a
surface where the tops carry microtexture and the binder is flat (a flushed or bleeding surface, a chip seal) it
falls with the share of binder even where the microtexture the slider meets does not change. These parameters
measure the micro band only where the surface is high (conventions in docs/texture.md, "Contact zone"):

* **top zone**: the points whose raw height (form removed, mm) is at or above ``Smc(top_pct)``, the height at
  the areal material ratio ``top_pct`` % (ISO 25178-2; the ``1 - top_pct/100`` quantile of the heights with
  linear interpolation between order statistics, as :class:`~skidsim.texture.material_ratio.MaterialRatio`).
  Ties at that height are all in the zone, so a flat plateau of tops counts whole. Default ``top_pct`` = 10 %,
  the zone of the peak material volume ``Vmp`` (p = 10 %).
* **Sq_top** (mm): ``sqrt(mean(m^2))`` over the top zone, ``m`` the micro band referenced to its mean over the
  whole scan (the mean plane of every other areal parameter).
* **Sdq_top** (1): the root-mean-square gradient of the micro band over the top zone, with the forward
  differences of Sdq (:mod:`skidsim.texture.hybrid`): ``sqrt(mean_x (dm/dx)^2 + mean_y (dm/dy)^2)``, each
  direction averaged over the differences whose first point (the lower column, the lower row) is in the zone.

Both are reported with the micro band (``micro_Sq_top``, ``micro_Sdq_top`` in the wide table).
"""

from __future__ import annotations

import numpy as np

from .height import finite_mean


def top_zone(raw: np.ndarray, top_pct: float) -> np.ndarray:
    """Boolean mask of the points of ``raw`` (mm, complete) at or above ``Smc(top_pct)``, the height at the areal
    material ratio ``top_pct`` % (0 < top_pct <= 100)."""
    z = np.asarray(raw, dtype=float)
    if not 0 < top_pct <= 100:
        raise ValueError(f"top_zone: top_pct must lie in (0, 100], got {top_pct!r}")
    if not np.isfinite(z).all():
        raise ValueError("top_zone: the raw surface has invalid points; fill them first (fill_invalid)")
    c = np.quantile(z, 1.0 - top_pct / 100.0)  # linear interpolation between order statistics
    return z >= c


def contact_parameters(
    raw: np.ndarray, micro: np.ndarray, dx: float, dy: float, top_pct: float = 10.0
) -> dict[str, float]:
    """``{"Sq_top": mm, "Sdq_top": 1}``: the micro band ``micro`` (mm) on the top zone of ``raw`` (mm; same
    shape, complete), spacings ``dx`` (columns) and ``dy`` (rows) in mm (module docstring)."""
    r = np.asarray(raw, dtype=float)
    m = np.asarray(micro, dtype=float)
    if r.shape != m.shape:
        raise ValueError(f"contact_parameters: raw {r.shape} and micro {m.shape} differ in shape")
    if min(m.shape) < 2:
        raise ValueError(f"contact_parameters: surface is {m.shape}, need >= 2x2")
    mean = finite_mean(m)
    if mean is None:
        raise ValueError("contact_parameters: the micro band has invalid points; fill them first (fill_invalid)")
    top = top_zone(r, top_pct)
    sq = float(np.sqrt(np.mean((m[top] - mean) ** 2)))
    tx, ty = top[:, :-1], top[:-1, :]  # the differences whose first point is in the zone (only those are formed)
    gx = m[:, 1:][tx] - m[:, :-1][tx]
    gy = m[1:, :][ty] - m[:-1, :][ty]
    mx = float(np.mean(gx**2)) / dx**2 if gx.size else 0.0
    my = float(np.mean(gy**2)) / dy**2 if gy.size else 0.0
    return {"Sq_top": sq, "Sdq_top": float(np.sqrt(mx + my))}


__all__ = ["top_zone", "contact_parameters"]
