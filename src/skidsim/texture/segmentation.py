"""Watershed segmentation into motifs (dales of z, or hills = dales of -z) with Wolf pruning.

Algorithm (docs/texture.md, "Feature parameters"):

1. **Catchment basins** by steepest descent (8-connectivity): every point drains to its lowest strictly lower
   neighbour; points without one are sinks; 8-connected groups of sinks seed one basin each; every point gets
   the basin of the sink its descent path ends in (pointer doubling, vectorised).
2. **Saddles**: for every pair of 8-adjacent basins, the pour height is the minimum over their shared boundary
   of the higher of the two adjoining heights.
3. **Wolf pruning** (threshold ``t`` in mm): a motif whose local depth (its lowest bounding saddle minus its
   minimum) is below ``t`` is merged into the neighbour across that saddle. We apply it in vectorised rounds:
   every motif whose lowest saddle leads to a motif with a *deeper* minimum (ties: lower index) and whose local
   depth is below ``t`` is merged into that neighbour, all at once; chains resolve by pointer doubling. Such a
   motif dies at that saddle in every processing order (before it, it touches no other motif; at it, it meets
   a deeper one), so the rounds are exact. They stop when no motif qualifies; then every motif has local depth
   >= ``t``, hence persistence (dynamic) >= ``t``: the result is the set of significant motifs that iterative
   Wolf pruning (surfalize's heap implementation, checked in the tests) and persistence simplification keep.
4. **Edge motifs**: optionally, motifs with a point on the border of the evaluation area are dropped.

Each significant motif records its critical point (deepest point), its base (the lowest saddle to another
significant motif; for a lone motif, its highest point), its area and its volume below the base.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skidsim._lazy import lazy_module

from .basins import _EIGHT, _catchment_basins, _sink_plateaus, catchment_basins
from .pruning import _contract_leaves
from .saddles import _saddles, basin_adjacency, boundary_pairs, dedupe_edges

ndimage = lazy_module("scipy.ndimage")  # imported on first use (skidsim._lazy)

_GATHER_BLOCK = 1 << 16  # points per block of the motifs' areas and volumes (the indices stay in cache)

__all__ = [
    "Segmentation",
    "basin_adjacency",
    "boundary_pairs",
    "catchment_basins",
    "dedupe_edges",
    "deepest_motifs",
    "segment",
]


@dataclass
class Segmentation:
    """Significant motifs of one segmentation, in the coordinates of the segmented array ``d`` (hills: ``-z``).

    Attributes (one entry per significant motif, sorted by critical value ascending):
    critical_index: flat index of the critical point; critical: its value in ``d`` (mm);
    base: base height in ``d`` (mm); area_mm2; volume_mm3 (``sum(max(base - d, 0)) dx dy`` over the motif);
    touches_edge: motif has a border point; threshold_mm: the pruning height used.
    motif_of_basin: basin label -> motif id (0..m-1), for plotting; labels: basin labels; peaks (with
    ``keep_peaks``): the points of ``d`` without a strictly higher neighbour, i.e. the sinks of ``-d``, else None.
    """

    critical_index: np.ndarray
    critical: np.ndarray
    base: np.ndarray
    area_mm2: np.ndarray
    volume_mm3: np.ndarray
    touches_edge: np.ndarray
    threshold_mm: float
    motif_of_basin: np.ndarray
    labels: np.ndarray
    peaks: np.ndarray | None = None

    def select(self, exclude_edge: bool) -> np.ndarray:
        """Boolean mask of the motifs kept (all, or those not touching the border)."""
        return ~self.touches_edge if exclude_edge else np.ones(self.critical.size, dtype=bool)


def segment(
    d: np.ndarray,
    threshold_mm: float,
    dx: float,
    dy: float,
    keep_labels: bool = False,
    keep_peaks: bool = False,
    measure: bool = True,
    bases: bool = True,
) -> Segmentation:
    """Wolf-pruned watershed segmentation of ``d`` (mm) into dales; see the module docstring. ``keep_peaks``: also
    the sinks of ``-d`` (from the same pass over the neighbours; :func:`deepest_motifs` of ``-d`` reads them).
    ``measure=False``: no pass over the points for the motifs' areas and volumes (NaN) nor for the highest point
    of a lone motif (its base is then NaN); critical points, the other bases and edge flags are the same.
    ``bases=False`` (with ``measure=False``): no bases either (NaN): only the saddles at which the pruning can
    merge are computed (:func:`skidsim.texture.saddles._saddles`, ``merging``); the motifs, their critical
    points and edge flags are the same."""
    if measure and not bases:
        raise ValueError("segment: bases=False needs measure=False (the volumes are measured below the bases)")
    labels, n, sink, peaks = _catchment_basins(d, keep_peaks)
    flat = d.ravel()
    crit_val = flat[sink]  # basin k (0-based) -> its minimum
    t = float(threshold_mm)
    a, b, sad = _saddles(labels, d, n, None if bases else (crit_val, t))
    motif_root, a, b, sad = _contract_leaves(a, b, sad, crit_val, t)
    roots, motif_of_basin = _roots_and_ranks(motif_root)
    m = roots.size
    crit = crit_val[roots]
    lf = labels.ravel()
    if not bases:
        base = count = vol = np.full(m, np.nan)
    else:
        base, count, vol = _bases_and_measures(a, b, sad, motif_of_basin, lf, flat, m, measure)
    area = count * dx * dy
    vol = vol * dx * dy
    border = np.unique(np.concatenate([labels[0, :], labels[-1, :], labels[:, 0], labels[:, -1]]))
    edge = np.zeros(m, dtype=bool)
    edge[motif_of_basin[border - 1]] = True
    srt = np.argsort(crit, kind="stable")
    inv = np.empty(m, dtype=np.int64)
    inv[srt] = np.arange(m)
    return Segmentation(
        critical_index=sink[roots][srt],
        critical=crit[srt],
        base=base[srt],
        area_mm2=area[srt],
        volume_mm3=vol[srt],
        touches_edge=edge[srt],
        threshold_mm=t,
        motif_of_basin=inv[motif_of_basin],
        labels=labels if keep_labels else np.empty(0, np.int32),
        peaks=peaks,
    )


def _roots_and_ranks(unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(unit, return_inverse=True)`` of the pruning's unit of every basin (each value a basin that is
    its own unit), without a sort: the roots ascending and each basin's rank among them."""
    is_root = unit == np.arange(unit.size)
    roots = np.flatnonzero(is_root)
    rank = np.cumsum(is_root, dtype=np.intp)
    rank -= 1
    return roots, rank.take(unit)


def _bases_and_measures(a, b, sad, motif_of_basin, lf, flat, m, measure):
    """Each motif's base (its lowest saddle to a different motif; a lone motif: its highest point, NaN without
    ``measure``), its number of points and its ``sum(max(base - d, 0))`` (NaN without ``measure``)."""
    ma, mb = motif_of_basin[a], motif_of_basin[b]
    diff = ma != mb
    base = np.full(m, np.inf)
    np.minimum.at(base, ma[diff], sad[diff])
    np.minimum.at(base, mb[diff], sad[diff])
    lone = ~np.isfinite(base)
    if not measure:
        base[lone] = np.nan
        return base, np.full(m, np.nan), np.full(m, np.nan)
    # motif of every point: label k -> motif_of_basin[k - 1], read in blocks of points that stay in cache
    motif_of_label = np.concatenate((motif_of_basin[:1], motif_of_basin))
    if lone.any():
        mx = np.full(m, -np.inf)
        for s0 in range(0, lf.size, _GATHER_BLOCK):
            pm = motif_of_label.take(lf[s0 : s0 + _GATHER_BLOCK], mode="clip")
            np.maximum.at(mx, pm, flat[s0 : s0 + _GATHER_BLOCK])
        base[lone] = mx[lone]
    count, vol = _motif_measures(lf, flat, motif_of_label, base, m)
    return base, count, vol


def _motif_measures(lf, flat, motif_of_label, base, m):
    """Points per motif (exact integer counts) and each motif's ``sum(max(base - d, 0))`` summed in raster order
    (``np.add.at`` adds in index order from 0.0, as ``np.bincount`` with weights does), in blocks of points that
    stay in cache."""
    count = np.zeros(m, dtype=np.intp)
    vol = np.zeros(m)
    step = _GATHER_BLOCK
    for s0 in range(0, lf.size, step):
        pm = motif_of_label.take(lf[s0 : s0 + step], mode="clip")
        np.add.at(count, pm, 1)
        w = base.take(pm, mode="clip")
        w -= flat[s0 : s0 + step]
        np.maximum(w, 0.0, out=w)
        np.add.at(vol, pm, w)
    return count, vol


def deepest_motifs(
    d: np.ndarray, threshold_mm: float, count: int, flood_budget: float = 2.0, sinks: np.ndarray | None = None
) -> np.ndarray:
    """``segment(d, threshold_mm, ...).critical[:count]`` (mm, ascending): the minima of the ``count`` deepest
    significant motifs, without segmenting the whole array (S5v reads only these).

    The motifs :func:`segment` keeps are those of persistence >= ``t`` (module docstring, step 3): a basin with
    minimum ``v`` is merged iff a path of 8-adjacent points, each with ``d - v < t`` (the contraction's test on
    the saddle it crosses, the highest point of the path), joins it to a deeper basin (lower minimum; on equal
    minima a lower basin index, the index of :func:`catchment_basins`). The basins are visited in that order from
    the deepest. For each, the 8-connected region of ``d - v < t`` around its sink is labelled in a window around
    it; the basin is merged as soon as the part of the region in the window holds a lower point, a sink of an
    equally deep basin of lower index, or a point of the region of a basin visited before (its region, at a level
    no lower, then holds that whole region and that deeper sink); it is kept when the region ends inside the
    window without any; otherwise the window grows. When the windows together exceed ``flood_budget`` times the
    array, the whole segmentation is done instead (same result). ``sinks``: the points of ``d`` without a strictly
    lower neighbour when known (``segment(-d, ..., keep_peaks=True).peaks``)."""
    t = float(threshold_mm)
    rows, cols = d.shape
    markers, n, first = _sink_plateaus(d, sinks)
    crit = d.ravel().take(first)
    pending = np.argsort(crit, kind="stable")  # ascending minimum, then basin index
    if not t > 0:  # d - v < t never holds on a saddle (saddles are not below the basin's minimum): nothing merges
        return crit[pending[:count]]
    out: list[float] = []
    flooded = 0
    seen = np.zeros(d.shape, dtype=bool)  # the (parts of) regions labelled so far
    seen_flat = seen.ravel()
    for b in pending:
        if len(out) >= count:
            break
        if seen_flat[first[b]]:
            continue  # inside the region of a deeper basin
        v = crit[b]
        if not out:  # the deepest basin: nothing deeper to merge into (its region, often most of it, unlabelled)
            out.append(v)
            continue
        r, c = divmod(int(first[b]), cols)
        h = 16
        while True:
            r0, r1, c0, c1 = max(r - h, 0), min(r + h + 1, rows), max(c - h, 0), min(c + h + 1, cols)
            win = d[r0:r1, c0:c1]
            lab, _ = ndimage.label((win - v) < t, structure=_EIGHT)
            region = lab == lab[r - r0, c - c0]
            del lab
            flooded += region.size
            if flooded > flood_budget * d.size:
                return segment(d, t, 1.0, 1.0, measure=False, bases=False).critical[:count]
            tied = markers[r0:r1, c0:c1][region & (win == v)]
            merged = (
                (win[region] < v).any()  # a lower point: its descent ends in a deeper basin of the region
                or ((tied > 0) & (tied - 1 < b)).any()  # an equally deep basin of lower index
                or (region & seen[r0:r1, c0:c1]).any()  # the region of a deeper basin
            )
            if merged or not (
                (r0 > 0 and region[0].any())
                or (r1 < rows and region[-1].any())
                or (c0 > 0 and region[:, 0].any())
                or (c1 < cols and region[:, -1].any())
            ):
                break  # decided, or the region ends inside the window (or the window is the whole array)
            h *= 4
        seen[r0:r1, c0:c1] |= region
        if not merged:
            out.append(v)
    return np.asarray(out, dtype=d.dtype)
