"""Material-ratio (Abbott-Firestone) functional parameters: volumes (Vm, Vv, Vmp, Vmc, Vvc, Vvv) and the Sk
family (Sk, Spk, Svk, Smr1, Smr2, Sa1, Sa2), ISO 25178-2 / ISO 13565-2.

Conventions (docs/texture.md):

* Areal material ratio ``Smr(c)`` = share of points with height >= c; its inverse ``Smc(mr)`` is the
  ``1 - mr`` quantile of the heights (linear interpolation between order statistics). The order statistics are
  selected exactly without a whole sort (:class:`_Binning`: value bins of 5 points, only the bins holding the
  ranks read are sorted; one whole sort where those bins hold more than 25 % of the points).
* Volumes are exact on the point set (sums over the points, pairwise summation):
  ``Vm(p) = mean(max(z - Smc(p), 0))`` and ``Vv(p) = mean(max(Smc(p) - z, 0))`` in mm^3/mm^2 (= mm).
  ``Vmp = Vm(p)``, ``Vmc = Vm(q) - Vm(p)``, ``Vvc = Vv(p) - Vv(q)``, ``Vvv = Vv(q)`` with p = 10 %, q = 80 %;
  ``Vm`` and ``Vv`` without argument are reported at p = 10 % (as Table 4 of the study implies: Vm = Vmp,
  Vv = Vvc + Vvv).
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


_SELECT_POINTS_PER_BIN = 5  # value bins of the order-statistic selection: one per 5 points (1 M on an LS-40 scan)
_SELECT_MIN_POINTS = 1 << 16  # fewer heights: one sort
_SELECT_SHARE_MAX = 0.25  # above this share of the points in the bins to sort, sort them all


class _Binning:
    """The heights binned by value once, for :meth:`select`."""

    def __init__(self, z: np.ndarray):
        self.z = z
        lo, hi = float(np.min(z)), float(np.max(z))  # NaN if any height is NaN
        self.sorted_all = None
        if not (np.isfinite(lo) and np.isfinite(hi)) or hi == lo or z.size < _SELECT_MIN_POINTS:
            self.sorted_all = np.sort(z)
            return
        self.bins = z.size // _SELECT_POINTS_PER_BIN
        t = np.subtract(z, lo)
        t *= self.bins / (hi - lo)
        # truncation: monotone, so a higher bin never holds a lower height; bin ``bins`` (the maximum, or heights
        # within a rounding of it) is counted with bin ``bins - 1``, as a clamp of the indices would put them
        idx = t.astype(np.intp)
        del t
        self.idx = idx
        counts = np.bincount(idx, minlength=self.bins + 1)
        counts[self.bins - 1] += counts[self.bins]
        self.counts = counts[: self.bins]
        self.cum = np.cumsum(self.counts)  # points in bins <= b

    def select(self, ranks: np.ndarray) -> np.ndarray:
        """``np.sort(z)[ranks]`` (ascending order statistics; ``ranks`` unique int), the same bits."""
        if self.sorted_all is not None:
            return self.sorted_all[ranks]
        b = np.searchsorted(self.cum, ranks, side="right")  # the bin holding each rank
        need = np.zeros(self.bins + 1, dtype=bool)  # entry ``bins``: the points counted with bin ``bins - 1``
        need[b] = True
        need[self.bins] = need[self.bins - 1]
        ub = np.flatnonzero(need[: self.bins])
        if self.counts[ub].sum() > _SELECT_SHARE_MAX * self.z.size:  # ties or few distinct heights: sort them all
            self.sorted_all = np.sort(self.z)
            del self.idx, self.counts, self.cum
            return self.sorted_all[ranks]
        vals = self.z[need.take(self.idx)]  # the points of the needed bins, in bin order once sorted
        vals.sort()
        offset = np.zeros(self.bins, dtype=np.intp)  # where each needed bin starts in vals
        offset[ub] = np.cumsum(self.counts[ub]) - self.counts[ub]
        return vals[offset[b] + (ranks - (self.cum[b] - self.counts[b]))]


class MaterialRatio:
    """The empirical material ratio curve of a complete height array (mm).

    No sort of the heights: the order statistics the curve is read at are selected exactly (:meth:`_Binning.select`)
    and the volumes and material ratios are sums and counts over the points."""

    def __init__(self, z: np.ndarray, n_classes: int = 10001):
        self.z = np.ravel(z)
        self.n = self.z.size
        self.n_classes = int(n_classes)
        self._binning: _Binning | None = None
        self._buf: np.ndarray | None = None

    def smc(self, mr_pct):
        """Height (mm) at material ratio ``mr_pct`` (%): linear between the order statistics of descending index
        ``floor(pos)`` and ``floor(pos) + 1``, ``pos = mr_pct / 100 (N - 1)``."""
        pos = np.asarray(mr_pct, dtype=float) / 100.0 * (self.n - 1)
        i0 = np.clip(np.floor(pos).astype(np.intp), 0, self.n - 1)
        i1 = np.clip(i0 + 1, 0, self.n - 1)
        w = pos - i0
        need, where = np.unique(np.concatenate((np.ravel(i0), np.ravel(i1))), return_inverse=True)
        if self._binning is None:
            self._binning = _Binning(self.z)
        v = self._binning.select(self.n - 1 - need).take(where)  # descending index i <-> ascending n - 1 - i
        h0, h1 = v[: i0.size].reshape(i0.shape), v[i0.size :].reshape(i0.shape)
        return h0 * (1 - w) + h1 * w

    def smr(self, c: float) -> float:
        """Material ratio (%) at height ``c`` (mm): share of points with z >= c."""
        return 100.0 * np.count_nonzero(self.z >= c) / self.n

    def _positive_sum(self, a, b) -> float:
        """``sum(max(a - b, 0))`` (one of ``a``, ``b`` the heights) in one buffer of the heights' size."""
        if self._buf is None:
            self._buf = np.empty(self.n)
        d = np.subtract(a, b, out=self._buf)
        np.maximum(d, 0.0, out=d)
        return float(d.sum())

    def volume_above(self, c: float) -> float:
        """``mean(max(z - c, 0))`` in mm^3/mm^2."""
        return self._positive_sum(self.z, c) / self.n

    def volume_below(self, c: float) -> float:
        """``mean(max(c - z, 0))`` in mm^3/mm^2."""
        return self._positive_sum(c, self.z) / self.n

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


def _core_limits(mrc: MaterialRatio) -> tuple[float, float]:
    """Heights (mm) of the equivalent straight line at 0 % and at 100 % material ratio (Sk's upper and lower
    limits)."""
    slope, intercept = mrc.equivalence_line()
    return intercept, intercept + slope * 100.0


def core_height(z: np.ndarray | None = None, *, curve: MaterialRatio | None = None, n_classes: int = 10001) -> float:
    """Sk (mm) alone: the equivalence line of the material ratio curve, without the volumes and material ratios
    of :func:`material_ratio_parameters` (the same bits as its ``Sk``)."""
    upper, lower = _core_limits(curve if curve is not None else MaterialRatio(z, n_classes))
    return upper - lower


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
    upper, lower = _core_limits(mrc)
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
