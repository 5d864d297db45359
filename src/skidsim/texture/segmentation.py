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
from scipy import ndimage

_OFFSETS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
_EIGHT = np.ones((3, 3), dtype=bool)
_BLOCK_POINTS = 32 * 2448  # points per block of rows in catchment_basins (a few arrays of it fit in cache)
_WHOLE_ROUNDS_ABOVE = 16  # catchment_basins: whole-array doubling rounds while > 1/16 of the points move


def catchment_basins(d: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """Steepest-descent basins of ``d`` (8-connected). Returns ``(labels 1..n (int32), n, sink flat index of
    each basin (n,))``; the sink of basin k is ``sink[k-1]``."""
    rows, cols = d.shape
    pad = np.full((rows + 2, cols + 2), np.inf)
    pad[1:-1, 1:-1] = d
    code = np.full(d.shape, -1, dtype=np.int8)
    # blocks of rows, so that the eight passes over a block stay in cache (same result as whole-array passes)
    block = max(1, min(rows, _BLOCK_POINTS // max(cols, 1)))
    low = np.empty((block, cols))
    better = np.empty((block, cols), dtype=bool)
    for r0 in range(0, rows, block):
        r1 = min(r0 + block, rows)
        lo, be, co = low[: r1 - r0], better[: r1 - r0], code[r0:r1]
        lo[...] = d[r0:r1]
        for k, (oy, ox) in enumerate(_OFFSETS):
            nb = pad[1 + oy + r0 : 1 + oy + r1, 1 + ox : 1 + ox + cols]
            np.less(nb, lo, out=be)  # strictly lower than the lowest so far: first offset wins ties
            np.minimum(lo, nb, out=lo)
            np.copyto(co, np.int8(k), where=be)
    del pad, low, better
    sink = code < 0
    markers, n = ndimage.label(sink, structure=_EIGHT)
    del sink
    delta = np.array([oy * cols + ox for oy, ox in _OFFSETS] + [0], dtype=np.int32)
    ptr = np.arange(rows * cols, dtype=np.int32)
    ptr += delta[code.ravel()]  # code -1 indexes the trailing 0
    del code
    # pointer doubling: every point ends at the sink of its descent path (a sink points to itself; any order of
    # jumps ends there). Whole-array rounds while more than 1/16 of the points still move (a gather of int32 in
    # order is cheaper than the indexed updates), then only the points not yet at a sink jump
    nxt = ptr[ptr]
    moving = nxt != ptr
    while np.count_nonzero(moving) * _WHOLE_ROUNDS_ABOVE > ptr.size:
        ptr = nxt
        nxt = ptr[ptr]
        np.not_equal(nxt, ptr, out=moving)
    del nxt
    active = np.flatnonzero(moving)
    del moving
    while active.size:
        nxt = ptr[ptr[active]]
        ptr[active] = nxt
        active = active[ptr[nxt] != nxt]
    flat_markers = markers.ravel()
    labels = flat_markers[ptr].reshape(d.shape)
    del ptr
    if labels.dtype != np.int32:
        labels = labels.astype(np.int32)
    sink_idx = np.flatnonzero(flat_markers)
    lab = flat_markers[sink_idx]
    _, first = np.unique(lab, return_index=True)
    return labels, n, sink_idx[first]


def boundary_pairs(labels: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """8-adjacent point pairs in different basins: ``(basin a, basin b, pour height max(d_a, d_b))``
    (0-based basin ids). Consecutive repeats of a pair along a boundary are reduced to their minimum pour;
    the result is not fully deduplicated. Pairs are listed per direction (right, down, down-right, down-left),
    each in raster order of its first point."""
    rows, cols = labels.shape
    lf = labels.ravel()
    df = d.ravel()
    las, lbs, pours = [], [], []
    # (flat offset to the second point, column of the first point whose pair would wrap to another row)
    for step, wrap in ((1, cols - 1), (cols, None), (cols + 1, cols - 1), (cols - 1, 0)):
        if step == 0 or step >= lf.size:  # one column: no diagonal pairs; one row: no pairs across rows
            las.append(lf[:0])
            lbs.append(lf[:0])
            pours.append(df[:0])
            continue
        m = lf[:-step] != lf[step:]
        if wrap is not None:
            m[wrap::cols] = False
        ia = np.flatnonzero(m)
        del m
        ib = ia + step
        x, y = lf[ia], lf[ib]
        p = np.maximum(df[ia], df[ib])
        del ia, ib
        if x.size:
            starts = np.flatnonzero(np.r_[True, (x[1:] != x[:-1]) | (y[1:] != y[:-1])])
            x, y, p = x[starts], y[starts], np.minimum.reduceat(p, starts)
        las.append(x)
        lbs.append(y)
        pours.append(p)
    return (np.concatenate(las).astype(np.int64) - 1, np.concatenate(lbs).astype(np.int64) - 1, np.concatenate(pours))


def dedupe_edges(a: np.ndarray, b: np.ndarray, pour: np.ndarray, n: int):
    """Unique unordered pairs ``(lo < hi)``, ascending by ``lo * (n + 1) + hi``, with their minimum pour height
    (the saddle)."""
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    if lo.size == 0:
        return lo, hi, pour
    key = lo * (n + 1) + hi
    del lo, hi
    uniq, saddle = _unique_min(key, pour, n * (n + 2))
    return uniq // (n + 1), uniq % (n + 1), saddle


def _unique_min(key: np.ndarray, pour: np.ndarray, key_bound: int) -> tuple[np.ndarray, np.ndarray]:
    """Ascending unique values of ``key`` (int64, ``0 <= key < key_bound``; overwritten) and the minimum of
    ``pour`` over each."""
    idx_bits = max(int(key.size - 1).bit_length(), 1)
    if idx_bits + int(key_bound).bit_length() <= 63:
        # the position rides in the low bits of the key: one sort of int64 values instead of an argsort
        key <<= idx_bits
        key |= np.arange(key.size, dtype=np.int64)
        key.sort()
        order = key & ((1 << idx_bits) - 1)
        key >>= idx_bits
    else:
        order = np.argsort(key)
        key = key[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    return key[starts], np.minimum.reduceat(pour[order], starts)


def _saddles(labels: np.ndarray, d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``dedupe_edges(*boundary_pairs(labels, d), n)`` in one pass, same result: the pairs of each direction
    are keyed as unordered pairs at once (runs of one key along a boundary reduced to their minimum pour), and
    the keys of all directions sorted together."""
    rows, cols = labels.shape
    lf = labels.ravel()
    df = d.ravel()
    base = n + 1  # key = lo * base + hi on 1-based labels: ascending like the 0-based keys of dedupe_edges
    keys, pours = [], []
    for step, wrap in ((1, cols - 1), (cols, None), (cols + 1, cols - 1), (cols - 1, 0)):
        if step == 0 or step >= lf.size:
            continue
        m = lf[:-step] != lf[step:]
        if wrap is not None:
            m[wrap::cols] = False
        ia = np.flatnonzero(m)
        del m
        if ia.size == 0:
            continue
        ib = ia + step
        x, y = lf[ia], lf[ib]
        p = np.maximum(df[ia], df[ib])
        del ia, ib
        key = np.minimum(x, y).astype(np.int64)
        key *= base
        key += np.maximum(x, y)
        del x, y
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        keys.append(key[starts])
        pours.append(np.minimum.reduceat(p, starts))
    if not keys:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty.copy(), np.empty(0)
    key = np.concatenate(keys)
    pour = np.concatenate(pours)
    del keys, pours
    uniq, saddle = _unique_min(key, pour, base * base)
    return uniq // base - 1, uniq % base - 1, saddle


def basin_adjacency(labels: np.ndarray, d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique adjacent basin pairs ``(a < b)`` (1-based labels, 8-connectivity) and their saddle heights."""
    a, b, p = boundary_pairs(labels, d)
    lo, hi, s = dedupe_edges(a, b, p, n)
    return lo + 1, hi + 1, s


def _contract_leaves(a, b, pour, minv, threshold, max_rounds=10000):
    """Vectorised pre-pruning (exact, see docs): a unit whose lowest incident saddle leads to a unit with a
    deeper minimum, at a local depth below ``threshold``, dies there in any order of processing; it is merged
    into that neighbour. At convergence every remaining unit has local depth >= threshold, hence persistence
    >= threshold: the units are exactly the significant motifs. Returns ``(unit of each basin, edges between
    remaining units)``."""
    n = minv.size
    unit = np.arange(n)
    for _ in range(max_rounds):
        if a.size == 0:
            break
        lowest = np.full(n, np.inf)
        np.minimum.at(lowest, a, pour)
        np.minimum.at(lowest, b, pour)
        nb = np.full(n, -1, dtype=np.int64)
        m = pour == lowest[a]
        nb[a[m]] = b[m]
        m = pour == lowest[b]
        nb[b[m]] = a[m]
        cand = np.flatnonzero((nb >= 0) & (lowest - minv < threshold))
        deeper = (minv[nb[cand]] < minv[cand]) | ((minv[nb[cand]] == minv[cand]) & (nb[cand] < cand))
        cand = cand[deeper]
        if cand.size == 0:
            break
        parent = np.arange(n)
        parent[cand] = nb[cand]
        for _ in range(64):  # chains strictly descend in (minv, index): pointer doubling terminates
            nxt = parent[parent]
            if np.array_equal(nxt, parent):
                break
            parent = nxt
        unit = parent[unit]
        a, b = parent[a], parent[b]
        keep = a != b
        a, b, pour = a[keep], b[keep], pour[keep]
    return unit, a, b, pour


@dataclass
class Segmentation:
    """Significant motifs of one segmentation, in the coordinates of the segmented array ``d`` (hills: ``-z``).

    Attributes (one entry per significant motif, sorted by critical value ascending):
    critical_index: flat index of the critical point; critical: its value in ``d`` (mm);
    base: base height in ``d`` (mm); area_mm2; volume_mm3 (``sum(max(base - d, 0)) dx dy`` over the motif);
    touches_edge: motif has a border point; threshold_mm: the pruning height used.
    motif_of_basin: basin label -> motif id (0..m-1), for plotting; labels: basin labels.
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

    def select(self, exclude_edge: bool) -> np.ndarray:
        """Boolean mask of the motifs kept (all, or those not touching the border)."""
        return ~self.touches_edge if exclude_edge else np.ones(self.critical.size, dtype=bool)


def segment(d: np.ndarray, threshold_mm: float, dx: float, dy: float, keep_labels: bool = False) -> Segmentation:
    """Wolf-pruned watershed segmentation of ``d`` (mm) into dales; see the module docstring."""
    labels, n, sink = catchment_basins(d)
    flat = d.ravel()
    crit_val = flat[sink]  # basin k (0-based) -> its minimum
    t = float(threshold_mm)
    a, b, sad = _saddles(labels, d, n)
    motif_root, a, b, sad = _contract_leaves(a, b, sad, crit_val, t)
    roots, motif_of_basin = np.unique(motif_root, return_inverse=True)
    m = roots.size
    crit = crit_val[roots]
    # base: lowest saddle to a different motif
    ma, mb = motif_of_basin[a], motif_of_basin[b]
    diff = ma != mb
    base = np.full(m, np.inf)
    np.minimum.at(base, ma[diff], sad[diff])
    np.minimum.at(base, mb[diff], sad[diff])
    labf = labels.ravel()
    # points per motif from the points per basin (exact integer counts, as counting the points directly)
    area = np.bincount(motif_of_basin, weights=np.bincount(labf, minlength=n + 1)[1:], minlength=m) * dx * dy
    pix_motif = np.concatenate((motif_of_basin[:1], motif_of_basin))[labf]  # label k -> motif_of_basin[k - 1]
    del labf
    lone = ~np.isfinite(base)
    if lone.any():
        mx = np.full(m, -np.inf)
        np.maximum.at(mx, pix_motif, flat)
        base[lone] = mx[lone]
    w = base[pix_motif] - flat
    np.maximum(w, 0.0, out=w)
    vol = np.bincount(pix_motif, weights=w, minlength=m) * dx * dy
    del w
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
    )
