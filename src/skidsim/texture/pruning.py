"""Wolf pruning in exact vectorised rounds, step 3 of :mod:`skidsim.texture.segmentation`: a motif whose local
depth (its lowest bounding saddle minus its minimum) is below the threshold is merged into the neighbour across
that saddle."""

from __future__ import annotations

import numpy as np

from .saddles import run_starts

_PARALLEL_EDGES_SHARE = 0.7  # _contract_leaves drops dominated parallel edges after a round keeping more edges


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
    starts = run_starts(key)
    p = pour.take(order)
    low = np.minimum.reduceat(p, starts)
    keep = np.empty(a.size, dtype=bool)
    keep[order] = p == np.repeat(low, np.diff(np.r_[starts, key.size]))
    return _select(keep, a, b, pour)


def _select(mask: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """``tuple(x[mask] for x in arrays)``, the same arrays, by one ``np.flatnonzero`` and gathers: a boolean
    selection scans its mask once per array and is several times slower where the mask is irregular."""
    idx = np.flatnonzero(mask)
    return tuple(x.take(idx) for x in arrays)


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
        am, bm = _select(pour == low_a, a, b)
        nb[am] = bm
        bm, am = _select(pour == low_b, b, a)
        nb[bm] = am
        # local depth below the threshold, per end of every edge (settled units are no candidates)
        open_a = low_a - minv.take(a) < threshold
        open_b = low_b - minv.take(b) < threshold
        mark[_select(open_a, a)[0]] = True
        mark[_select(open_b, b)[0]] = True
        cand = np.flatnonzero(mark)
        mark[cand] = False
        nbc = nb.take(cand)
        lowest[a] = np.inf  # reset what this round wrote
        lowest[b] = np.inf
        nb[a] = -1
        nb[b] = -1
        mc, mn = minv.take(cand), minv.take(nbc)
        deeper = (mn < mc) | ((mn == mc) & (nbc < cand))
        cand, nbc = _select(deeper, cand, nbc)
        if cand.size == 0:
            break
        settled_pair = ~(open_a | open_b)  # never relabelled: settled units are not merged
        if settled_pair.any():
            sa, sb, sp = _select(settled_pair, a, b, pour)
            done_a.append(sa)
            done_b.append(sb)
            done_p.append(sp)
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
        a, b, pour = _select(keep, a, b, pour)
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
