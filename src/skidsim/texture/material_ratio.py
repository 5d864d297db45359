"""Material-ratio (Abbott-Firestone) functional parameters: volumes (Vm, Vv, Vmp, Vmc, Vvc, Vvv) and the Sk
family (Sk, Spk, Svk, Smr1, Smr2, Sa1, Sa2), ISO 25178-2 / ISO 13565-2.

Conventions (docs/texture.md):

* Areal material ratio ``Smr(c)`` = share of points with height >= c; its inverse ``Smc(mr)`` is the
  ``1 - mr`` quantile of the heights (linear interpolation between order statistics).
* Volumes are exact on the point set: ``Vm(p) = mean(max(z - Smc(p), 0))`` and
  ``Vv(p) = mean(max(Smc(p) - z, 0))`` in mm^3/mm^2 (= mm). ``Vmp = Vm(p)``, ``Vmc = Vm(q) - Vm(p)``,
  ``Vvc = Vv(p) - Vv(q)``, ``Vvv = Vv(q)`` with p = 10 %, q = 80 %; ``Vm`` and ``Vv`` without argument are
  reported at p = 10 % (as Table 4 of the study implies: Vm = Vmp, Vv = Vvc + Vvv).
* Sk (ISO 25178-2:2021 B.1): the material ratio curve is sampled at ``n_classes`` equally spaced material ratios
  0..100 %; the 40 % window whose secant has the smallest gradient (first one on ties) locates the central
  region; the equivalent straight line is the least-squares fit (heights on material ratio) of the curve
  samples in that window. Sk = line(0 %) - line(100 %).
* Smr1, Smr2 (%): material ratios at the line's 0 % and 100 % heights. Sa1 = ``mean(max(z - line(0), 0))``
  and Sa2 = ``mean(max(line(100) - z, 0))`` in mm^3/mm^2: the areas A1, A2 of the peak and dale triangles'
  regions of the curve divided by 100 %. Spk = 2 A1 / Smr1, Svk = 2 A2 / (100 - Smr2) in mm.
"""

from __future__ import annotations

import numpy as np

EQUIVALENCE_WIDTH_PCT = 40.0


class MaterialRatio:
    """The empirical material ratio curve of a complete height array (mm)."""

    def __init__(self, z: np.ndarray, n_classes: int = 10001, sorted_desc: np.ndarray | None = None):
        if sorted_desc is None:
            s = np.sort(np.ravel(z))[::-1]  # descending heights: index i <-> material ratio i/(N-1)
        else:
            s = sorted_desc
        self.sorted = s
        self._asc = s[::-1]  # ascending: the searchsorted key of smr and the volumes (a view)
        self.n = s.size
        # cumulative sums for exact volumes: csum[i] = sum of the i highest heights (one sequential sum)
        self._csum = np.empty(s.size + 1)
        self._csum[0] = 0.0
        np.cumsum(s, out=self._csum[1:])
        self.n_classes = int(n_classes)

    def smc(self, mr_pct):
        """Height (mm) at material ratio ``mr_pct`` (%)."""
        pos = np.asarray(mr_pct, dtype=float) / 100.0 * (self.n - 1)
        i0 = np.clip(np.floor(pos).astype(int), 0, self.n - 1)
        i1 = np.clip(i0 + 1, 0, self.n - 1)
        w = pos - i0
        return self.sorted[i0] * (1 - w) + self.sorted[i1] * w

    def smr(self, c: float) -> float:
        """Material ratio (%) at height ``c`` (mm): share of points with z >= c."""
        count = self.n - np.searchsorted(self._asc, c, side="left")  # points with z >= c
        return 100.0 * count / self.n

    def volume_above(self, c: float) -> float:
        """``mean(max(z - c, 0))`` in mm^3/mm^2."""
        k = self.n - np.searchsorted(self._asc, c, side="right")  # number of points with z > c
        return float((self._csum[k] - k * c) / self.n)

    def volume_below(self, c: float) -> float:
        """``mean(max(c - z, 0))`` in mm^3/mm^2."""
        k = self.n - np.searchsorted(self._asc, c, side="left")  # points with z >= c
        m = self.n - k
        return float((m * c - (self._csum[-1] - self._csum[k])) / self.n)

    def equivalence_line(self) -> tuple[float, float]:
        """``(slope mm/%, intercept mm)`` of the ISO 25178-2 B.1 equivalent straight line."""
        mr = np.linspace(0.0, 100.0, self.n_classes)
        h = self.smc(mr)
        step = mr[1] - mr[0]
        w = int(round(EQUIVALENCE_WIDTH_PCT / step))
        secant = (h[w:] - h[:-w]) / EQUIVALENCE_WIDTH_PCT  # all <= 0
        i0 = int(np.argmax(secant))  # smallest gradient magnitude, first occurrence
        xs, ys = mr[i0 : i0 + w + 1], h[i0 : i0 + w + 1]
        slope, intercept = np.polyfit(xs, ys, 1)
        return float(slope), float(intercept)


def material_ratio_parameters(
    z: np.ndarray | None = None,
    *,
    curve: MaterialRatio | None = None,
    p_pct: float = 10.0,
    q_pct: float = 80.0,
    n_classes: int = 10001,
) -> dict[str, float]:
    """Vm Vv Vmp Vmc Vvc Vvv (mm^3/mm^2), Sk Spk Svk (mm), Smr1 Smr2 (%), Sa1 Sa2 (mm^3/mm^2).

    Heights are taken as given (the caller subtracts the mean plane; these parameters do not depend on it).
    """
    mrc = curve if curve is not None else MaterialRatio(z, n_classes)
    cp, cq = mrc.smc([p_pct, q_pct])
    vm_p, vm_q = mrc.volume_above(cp), mrc.volume_above(cq)
    vv_p, vv_q = mrc.volume_below(cp), mrc.volume_below(cq)
    slope, intercept = mrc.equivalence_line()
    upper = intercept
    lower = intercept + slope * 100.0
    smr1 = mrc.smr(upper)
    smr2 = mrc.smr(lower)
    sa1 = mrc.volume_above(upper)
    sa2 = mrc.volume_below(lower)
    spk = 2.0 * sa1 * 100.0 / smr1 if smr1 > 0 else 0.0
    svk = 2.0 * sa2 * 100.0 / (100.0 - smr2) if smr2 < 100 else 0.0
    return {
        "Vm": vm_p,
        "Vv": vv_p,
        "Vmp": vm_p,
        "Vmc": vm_q - vm_p,
        "Vvc": vv_p - vv_q,
        "Vvv": vv_q,
        "Sk": upper - lower,
        "Spk": spk,
        "Svk": svk,
        "Smr1": smr1,
        "Smr2": smr2,
        "Sa1": sa1,
        "Sa2": sa2,
    }
