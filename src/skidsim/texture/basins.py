"""Catchment basins by steepest descent (8-connectivity), step 1 of :mod:`skidsim.texture.segmentation`: every point
drains to its lowest strictly lower neighbour; points without one are sinks; 8-connected groups of sinks seed one
basin each; every point gets the basin of the sink its descent path ends in (pointer doubling, vectorised)."""

from __future__ import annotations

import numpy as np

from skidsim._lazy import lazy_module

ndimage = lazy_module("scipy.ndimage")  # imported on first use (skidsim._lazy)

_OFFSETS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
_EIGHT = np.ones((3, 3), dtype=bool)
_BLOCK_POINTS = 8 * 2448  # points per block of rows in catchment_basins (a few arrays of it stay in L1/L2 cache)
_WHOLE_ROUNDS_ABOVE = 16  # catchment_basins: whole-array doubling rounds while > 1/16 of the points move
_GATHER_BLOCK = 1 << 18  # entries per gather of a whole doubling round and of the labels (the indices stay in cache)


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
        active = active.take(np.flatnonzero(ptr.take(nx, mode="clip") != nx))  # gathers: faster than a mask
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
    labels = np.empty(ptr.size, dtype=np.int32)
    for s0 in range(0, ptr.size, _GATHER_BLOCK):  # blocks: the indices' conversion to intp stays in cache
        np.take(flat_markers, ptr[s0 : s0 + _GATHER_BLOCK], out=labels[s0 : s0 + _GATHER_BLOCK], mode="clip")
    labels = labels.reshape(d.shape)
    del ptr
    return labels, n, first, (peak[0] if peaks else None)


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
