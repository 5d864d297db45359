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

ndimage = lazy_module("scipy.ndimage")  # imported on first use (skidsim._lazy)

_OFFSETS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
_EIGHT = np.ones((3, 3), dtype=bool)
_BLOCK_POINTS = 8 * 2448  # points per block of rows in catchment_basins (a few arrays of it stay in L1/L2 cache)
_WHOLE_ROUNDS_ABOVE = 16  # catchment_basins: whole-array doubling rounds while > 1/16 of the points move
_GATHER_BLOCK = 1 << 16  # entries per gather of a whole doubling round (the indices stay in cache)
_SADDLE_STRIP_POINTS = 16 * 2448  # points per strip of rows in _saddles
_PARALLEL_EDGES_SHARE = 0.7  # _contract_leaves drops dominated parallel edges after a round keeping more edges


def _descent(d: np.ndarray, peaks: bool = False):
    """Steepest descent of every point of ``d``: ``(ptr, sink)``, ``ptr`` (int32, flat) the 8-neighbour that is
    strictly lowest (the first of ``_OFFSETS`` on ties), the point itself where no neighbour is strictly lower;
    ``sink`` (bool) True there. With ``peaks`` also ``peak`` (bool): no neighbour strictly higher (the sinks of
    ``-d``).

    Blocks of rows, each with its own padded copy (NaN outside the grid: never lower, ignored by ``fmin`` and
    ``fmax``), so that the eight passes over a block stay in cache. Every pass runs on the flat padded block: the
    points of its rows, and the two padding points between consecutive rows (their results are dropped), are one
    contiguous run, and each neighbour is the same run shifted by its flat offset (one-dimensional loops, about
    twice as fast as the strided two-dimensional views). Per offset a strict ``<`` against the lowest height so
    far, the running minimum, and a running maximum of ``(k + 1) * lowered``: the last offset that lowered the
    minimum is the first that reaches it. The first offset starts the minimum from the point itself and the code
    from its comparison."""
    rows, cols = d.shape
    ptr = np.empty(d.size, dtype=np.int32)
    sink = np.empty(d.shape, dtype=bool)
    peak = np.empty(d.shape, dtype=bool) if peaks else None
    delta = np.array([0] + [oy * cols + ox for oy, ox in _OFFSETS], dtype=np.int32)  # code 0: no lower point
    block = max(1, min(rows, _BLOCK_POINTS // max(cols, 1)))
    width = cols + 2  # a padded row
    pad = np.full((block + 2, width), np.nan)
    flat_pad = pad.ravel()
    run = block * width  # flat positions (1, 1) .. (h, cols) of the padded block, and the padding between rows
    low = np.empty(run)
    high = np.empty(run)
    better = np.empty(run, dtype=bool)
    code = np.empty(run, dtype=np.int8)
    tmp = np.empty(run, dtype=np.int8)
    shifts = [width + 1 + oy * width + ox for oy, ox in _OFFSETS]  # flat start of each neighbour's run
    for r0 in range(0, rows, block):
        r1 = min(r0 + block, rows)
        h = r1 - r0
        n = h * width - 2  # from the first point of the block to its last
        lo, hi, be, co, tm = low[:n], high[:n], better[:n], code[:n], tmp[:n]
        # rows r0 - 1 .. r1 of d in rows 0 .. h + 1 of the padded block, NaN outside the grid
        pad[0, 1:-1] = d[r0 - 1] if r0 > 0 else np.nan
        pad[1 : h + 1, 1:-1] = d[r0:r1]
        pad[h + 1, 1:-1] = d[r1] if r1 < rows else np.nan
        centre = flat_pad[width + 1 : width + 1 + n]
        for k, s in enumerate(shifts):
            nb = flat_pad[s : s + n]
            if k == 0:
                np.less(nb, centre, out=be)
                np.fmin(centre, nb, out=lo)
                np.copyto(co, be.view(np.int8))
                if peaks:
                    np.fmax(nb, -np.inf, out=hi)  # -inf where no neighbour (the highest so far)
                continue
            np.less(nb, lo, out=be)  # strictly lower than the lowest so far: first offset wins ties
            np.fmin(lo, nb, out=lo)
            np.multiply(be.view(np.int8), np.int8(k + 1), out=tm)
            np.maximum(co, tm, out=co)
            if peaks:
                np.fmax(hi, nb, out=hi)
        co2 = code[: h * width].reshape(h, width)[:, :cols]  # the points of the block (padding dropped)
        np.equal(co2, 0, out=sink[r0:r1])
        if peaks:
            np.less_equal(high[: h * width].reshape(h, width)[:, :cols], d[r0:r1], out=peak[r0:r1])
        out = ptr[r0 * cols : r1 * cols].reshape(h, cols)
        delta.take(co2, out=out, mode="clip")
        out += np.arange(r0 * cols, r1 * cols, dtype=np.int32).reshape(h, cols)
    return (ptr, sink, peak) if peaks else (ptr, sink)


def _jump_to_roots(ptr: np.ndarray) -> np.ndarray:
    """Pointer doubling on ``ptr`` (int32 flat indices, a forest whose roots point to themselves) until every
    entry is its root; returns the array (``ptr`` is overwritten). Any order of jumps ends at the root, so the
    result is that of plain doubling. Whole-array rounds (gathers in blocks that stay in cache, each block compared
    with its old pointers while it is there) while more than 1/16 of the entries still move, then only the entries
    not yet at a root."""
    n = ptr.size
    nxt = np.empty_like(ptr)
    moving = np.empty(n, dtype=bool)
    step = _GATHER_BLOCK

    def whole_round(src, dst, moving) -> int:
        moved = 0
        for s0 in range(0, n, step):
            old, new, mv = src[s0 : s0 + step], dst[s0 : s0 + step], moving[s0 : s0 + step]
            np.take(src, old, out=new, mode="clip")
            np.not_equal(new, old, out=mv)
            moved += int(np.count_nonzero(mv))
        return moved

    moved = whole_round(ptr, nxt, moving)
    while moved * _WHOLE_ROUNDS_ABOVE > n:
        ptr, nxt = nxt, ptr
        moved = whole_round(ptr, nxt, moving)
    del nxt
    active = np.flatnonzero(moving)
    del moving
    while active.size:
        nx = ptr.take(ptr.take(active, mode="clip"), mode="clip")
        ptr[active] = nx
        active = active[ptr.take(nx, mode="clip") != nx]
    return ptr


def _first_sinks(sink_idx: np.ndarray, lab: np.ndarray, n: int) -> np.ndarray:
    """Flat index of the first (in raster order) point of each plateau label 1..n, from the ascending flat
    indices ``sink_idx`` of the sink points and their labels ``lab``."""
    first = np.full(n + 1, sink_idx.size, dtype=np.intp)
    np.minimum.at(first, lab, np.arange(sink_idx.size, dtype=np.intp))
    return sink_idx[first[1:]]


def _sink_labels(sink: np.ndarray) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
    """``ndimage.label(sink, structure=_EIGHT)`` of a boolean mask of sinks and more: ``(markers (int32), n,
    ascending flat indices of the sink points, flat index of the first point of each label 1..n)``.

    On continuous heights no two sinks touch (every plateau is one point), which four gathers at the sink points
    tell (the sinks right, below, below right and below left of each): then the components are the points
    themselves, labelled 1..n in raster order as ``ndimage.label`` numbers them, and each is its own first point;
    otherwise ``ndimage.label``."""
    rows, cols = sink.shape
    flat = sink.ravel()
    idx = np.flatnonzero(flat)
    col = idx % cols if idx.size else idx
    touching = False
    for off, col_ok in ((1, col < cols - 1), (cols, None), (cols + 1, col < cols - 1), (cols - 1, col > 0)):
        j = idx + off
        ok = j < flat.size
        if col_ok is not None:
            ok &= col_ok
        if flat.take(j[ok]).any():
            touching = True
            break
    if touching:
        markers, n = ndimage.label(sink, structure=_EIGHT)
        return markers, n, idx, _first_sinks(idx, markers.ravel().take(idx), n)
    markers = np.zeros(sink.shape, dtype=np.int32)
    markers.ravel()[idx] = np.arange(1, idx.size + 1, dtype=np.int32)
    return markers, int(idx.size), idx, idx


def catchment_basins(d: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """Steepest-descent basins of ``d`` (8-connected). Returns ``(labels 1..n (int32), n, sink flat index of
    each basin (n,))``; the sink of basin k is ``sink[k-1]``."""
    return _catchment_basins(d)[:3]


def _catchment_basins(d: np.ndarray, peaks: bool = False):
    """:func:`catchment_basins` and, with ``peaks``, the points without a strictly higher neighbour (else None)."""
    ptr, sink, *peak = _descent(d, peaks)
    markers, n, _, first = _sink_labels(sink)
    del sink
    flat_markers = markers.ravel()
    # every point points to its steepest-descent neighbour, a sink to itself; doubling ends at the sinks
    ptr = _jump_to_roots(ptr)
    labels = flat_markers.take(ptr, mode="clip").reshape(d.shape)
    del ptr
    if labels.dtype != np.int32:
        labels = labels.astype(np.int32)
    return labels, n, first, (peak[0] if peaks else None)


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
    return key[starts], np.minimum.reduceat(pour.take(order, mode="clip"), starts)


def _saddles(labels: np.ndarray, d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``dedupe_edges(*boundary_pairs(labels, d), n)``, same result, in strips of rows: the pairs of each
    direction whose first point lies in the strip are keyed as unordered pairs at once and reduced to unique keys
    with their minimum pour per strip (in cache: most basins lie in one or two strips); the strips' keys are then
    reduced once more. The minimum is exact and does not depend on the order, so the saddles are those of the
    whole set of pairs."""
    rows, cols = labels.shape
    lf = labels.ravel()
    df = d.ravel()
    total = lf.size
    base = n + 1  # key = lo * base + hi on 1-based labels: ascending like the 0-based keys of dedupe_edges
    bound = base * base
    block = max(1, _SADDLE_STRIP_POINTS // max(cols, 1))
    # (flat offset to the second point, column of the first point whose pair would wrap to another row)
    steps = ((1, cols - 1), (cols, None), (cols + 1, cols - 1), (cols - 1, 0))
    strip_keys, strip_pours = [], []
    for r0 in range(0, rows, block):
        a0, a1 = r0 * cols, min(r0 + block, rows) * cols
        keys, pours = [], []
        for step, wrap in steps:
            e = min(a1, total - step)  # first points whose partner exists
            if step == 0 or e <= a0:  # one column: no diagonal pairs; one row: no pairs across rows
                continue
            la, lb = lf[a0:e], lf[a0 + step : e + step]
            m = la != lb
            if wrap is not None:
                m[wrap::cols] = False  # a0 starts a row
            ia = np.flatnonzero(m)
            del m
            if ia.size == 0:
                continue
            x, y = la.take(ia), lb.take(ia)
            p = np.maximum(df[a0:e].take(ia), df[a0 + step : e + step].take(ia))
            key = np.minimum(x, y).astype(np.int64)
            key *= base
            key += np.maximum(x, y)
            keys.append(key)
            pours.append(p)
        if keys:
            k, p = _unique_min(np.concatenate(keys), np.concatenate(pours), bound)
            strip_keys.append(k)
            strip_pours.append(p)
    if not strip_keys:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty.copy(), np.empty(0)
    key = np.concatenate(strip_keys)
    pour = np.concatenate(strip_pours)
    del strip_keys, strip_pours
    uniq, saddle = _unique_min(key, pour, bound)
    return uniq // base - 1, uniq % base - 1, saddle


def basin_adjacency(labels: np.ndarray, d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique adjacent basin pairs ``(a < b)`` (1-based labels, 8-connectivity) and their saddle heights."""
    a, b, p = boundary_pairs(labels, d)
    lo, hi, s = dedupe_edges(a, b, p, n)
    return lo + 1, hi + 1, s


def _drop_dominated_edges(a, b, pour, n):
    """The edges of :func:`_contract_leaves` in their order without those above the lowest saddle between the same
    two units: as long as both units live, that lower edge joins them too, and a unit's lowest saddle is at most
    it, so no round chooses the higher one (and the unit pairs' lowest saddles stay). Merging leaves many parallel
    edges between the surviving units; dropping them keeps the later rounds proportional to the distinct pairs."""
    key = np.minimum(a, b) * n + np.maximum(a, b)  # the unordered pair
    idx_bits = max(int(key.size - 1).bit_length(), 1)
    if idx_bits + int(n * n).bit_length() > 63:
        return a, b, pour
    key <<= idx_bits
    key |= np.arange(key.size, dtype=np.int64)
    key.sort()
    order = key & ((1 << idx_bits) - 1)
    key >>= idx_bits
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    p = pour.take(order)
    low = np.minimum.reduceat(p, starts)
    keep = np.empty(a.size, dtype=bool)
    keep[order] = p == np.repeat(low, np.diff(np.r_[starts, key.size]))
    return a[keep], b[keep], pour[keep]


def _contract_leaves(a, b, pour, minv, threshold, max_rounds=10000):
    """Vectorised pre-pruning (exact, see docs): a unit whose lowest incident saddle leads to a unit with a
    deeper minimum, at a local depth below ``threshold``, dies there in any order of processing; it is merged
    into that neighbour. At convergence every remaining unit has local depth >= threshold, hence persistence
    >= threshold: the units are exactly the significant motifs. Returns ``(unit of each basin, edges between
    remaining units)``.

    A unit's local depth never decreases (it keeps its minimum; what it absorbs has no saddle below its lowest
    one), so a unit at local depth >= threshold stays so and is never a candidate again. Edges between two such
    settled units change no later round: they are set aside and returned before the others; every candidate sees
    all of its incident edges in their original order, so the rounds choose the same neighbours as on the whole
    edge list. Every round works on the remaining edges only (the per-unit arrays are reset where they were
    written): on plateaus of equal heights the rounds merge few units each, and there are many. A merged unit
    keeps the unit it merged into (``parent``); the unit of every basin is the end of that chain."""
    n = minv.size
    parent = np.arange(n)  # a live unit: itself; a merged one: where it went
    lowest = np.full(n, np.inf)
    nb = np.full(n, -1, dtype=np.int64)
    mark = np.zeros(n, dtype=bool)
    done_a, done_b, done_p = [], [], []
    for _ in range(max_rounds):
        if a.size == 0:
            break
        np.minimum.at(lowest, a, pour)
        np.minimum.at(lowest, b, pour)
        low_a, low_b = lowest.take(a), lowest.take(b)
        m = pour == low_a
        nb[a[m]] = b[m]
        m = pour == low_b
        nb[b[m]] = a[m]
        # local depth below the threshold, per end of every edge (settled units are no candidates)
        open_a = low_a - minv.take(a) < threshold
        open_b = low_b - minv.take(b) < threshold
        mark[a[open_a]] = True
        mark[b[open_b]] = True
        cand = np.flatnonzero(mark)
        mark[cand] = False
        nbc = nb.take(cand)
        lowest[a] = np.inf  # reset what this round wrote
        lowest[b] = np.inf
        nb[a] = -1
        nb[b] = -1
        mc, mn = minv.take(cand), minv.take(nbc)
        deeper = (mn < mc) | ((mn == mc) & (nbc < cand))
        cand, nbc = cand[deeper], nbc[deeper]
        if cand.size == 0:
            break
        settled_pair = ~(open_a | open_b)  # never relabelled: settled units are not merged
        if settled_pair.any():
            done_a.append(a[settled_pair])
            done_b.append(b[settled_pair])
            done_p.append(pour[settled_pair])
        parent[cand] = nbc
        # chains of this round strictly descend in (minv, index): jump the candidates to the end of theirs
        act = cand
        while act.size:
            to = parent.take(act)
            nxt = parent.take(to)
            moved = nxt != to
            act = act[moved]
            parent[act] = nxt[moved]
        a, b = parent.take(a), parent.take(b)
        keep = a != b
        keep &= ~settled_pair
        before = a.size
        a, b, pour = a[keep], b[keep], pour[keep]
        if a.size > _PARALLEL_EDGES_SHARE * before:  # the edges shrink slowly: drop the dominated parallel ones
            a, b, pour = _drop_dominated_edges(a, b, pour, n)
    if done_a:
        a = np.concatenate(done_a + [a])
        b = np.concatenate(done_b + [b])
        pour = np.concatenate(done_p + [pour])
    # a basin merged in an earlier round points to the unit of that round, which may have merged since
    unit = parent
    nxt = unit.take(unit)
    while not np.array_equal(nxt, unit):
        unit = nxt
        nxt = unit.take(unit)
    return unit, a, b, pour


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
    d: np.ndarray, threshold_mm: float, dx: float, dy: float, keep_labels: bool = False, keep_peaks: bool = False
) -> Segmentation:
    """Wolf-pruned watershed segmentation of ``d`` (mm) into dales; see the module docstring. ``keep_peaks``: also
    the sinks of ``-d`` (from the same pass over the neighbours; :func:`deepest_motifs` of ``-d`` reads them)."""
    labels, n, sink, peaks = _catchment_basins(d, keep_peaks)
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
    # motif of every point (label k -> motif_of_basin[k - 1]), in blocks of points that stay in cache; points per
    # motif are exact integer counts, and each motif's volume is summed in raster order (``np.add.at`` adds in
    # index order from 0.0, as ``np.bincount`` with weights does)
    motif_of_label = np.concatenate((motif_of_basin[:1], motif_of_basin))
    lf = labels.ravel()
    step = _GATHER_BLOCK
    lone = ~np.isfinite(base)
    if lone.any():
        mx = np.full(m, -np.inf)
        for s0 in range(0, lf.size, step):
            np.maximum.at(mx, motif_of_label.take(lf[s0 : s0 + step], mode="clip"), flat[s0 : s0 + step])
        base[lone] = mx[lone]
    count = np.zeros(m, dtype=np.intp)
    vol = np.zeros(m)
    for s0 in range(0, lf.size, step):
        pm = motif_of_label.take(lf[s0 : s0 + step], mode="clip")
        np.add.at(count, pm, 1)
        w = base.take(pm, mode="clip")
        w -= flat[s0 : s0 + step]
        np.maximum(w, 0.0, out=w)
        np.add.at(vol, pm, w)
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


def _sink_plateaus(d: np.ndarray, sink: np.ndarray | None = None) -> tuple[np.ndarray, int, np.ndarray]:
    """The sinks of :func:`catchment_basins` without the basins: ``(plateau labels 1..n (0 elsewhere), n, flat
    index of the first point of each plateau)``; plateau k is the sink of basin k (same labels). A sink is a point
    without a strictly lower 8-neighbour: the minimum of its neighbours is not below it. ``sink``: that mask when
    it is known (the peaks of ``-d`` from :func:`segment`)."""
    if sink is not None:
        markers, n, _, first = _sink_labels(sink)
        return markers, n, first
    rows, cols = d.shape
    sink = np.empty(d.shape, dtype=bool)
    block = max(1, min(rows, _BLOCK_POINTS // max(cols, 1)))
    pad = np.full((block + 2, cols + 2), np.inf)
    low = np.empty((block, cols))
    for r0 in range(0, rows, block):
        r1 = min(r0 + block, rows)
        h = r1 - r0
        pb, lo = pad[: h + 2], low[:h]
        pb[0, 1:-1] = d[r0 - 1] if r0 > 0 else np.inf
        pb[1 : h + 1, 1:-1] = d[r0:r1]
        pb[h + 1, 1:-1] = d[r1] if r1 < rows else np.inf
        lo.fill(np.inf)
        for oy, ox in _OFFSETS:
            np.minimum(lo, pb[1 + oy : 1 + oy + h, 1 + ox : 1 + ox + cols], out=lo)
        np.greater_equal(lo, d[r0:r1], out=sink[r0:r1])
    markers, n, _, first = _sink_labels(sink)
    return markers, n, first


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
                return segment(d, t, 1.0, 1.0).critical[:count]
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
