"""Saddles between 8-adjacent catchment basins, step 2 of :mod:`skidsim.texture.segmentation`: for every pair of
adjacent basins the pour height is the minimum over their shared boundary of the higher of the two adjoining
heights."""

from __future__ import annotations

import numpy as np

_SADDLE_STRIP_POINTS = 64 * 2448  # points per strip of rows in _saddles


def run_starts(v: np.ndarray) -> np.ndarray:
    """Indices where a run of equal consecutive values of ``v`` (1-d, non-empty) starts:
    ``np.flatnonzero(np.r_[True, v[1:] != v[:-1]])``, without building the concatenation."""
    m = np.empty(v.size, dtype=bool)
    m[:1] = True
    np.not_equal(v[1:], v[:-1], out=m[1:])
    return np.flatnonzero(m)


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
    starts = run_starts(key)
    return key[starts], np.minimum.reduceat(pour.take(order, mode="clip"), starts)


def _saddles(
    labels: np.ndarray, d: np.ndarray, n: int, merging: tuple[np.ndarray, float] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``dedupe_edges(*boundary_pairs(labels, d), n)``, same result, in strips of rows: the pairs of each
    direction whose first point lies in the strip are keyed as unordered pairs at once (across rows, a run of the
    same pair in raster order kept once with its minimum pour) and reduced to unique keys
    with their minimum pour per strip (in cache: most basins lie in one or two strips); the strips' keys are then
    reduced once more. The minimum is exact and does not depend on the order, so the saddles are those of the
    whole set of pairs.

    ``merging = (minimum of each basin (0-based, mm), Wolf threshold t (mm))``: only the saddles at which the
    pruning can merge (:func:`skidsim.texture.pruning._contract_leaves`): a pair of points of basins ``x`` and
    ``y`` at pour ``p`` is dropped when ``p - max(min_x, min_y) >= t``. Every unit the pruning forms around
    either basin has a minimum no higher than that basin's, so ``p`` minus it is at least ``t`` too (rounded
    subtraction is monotone): such a saddle is never the lowest of a unit below the threshold, and the units
    below the threshold keep their lowest saddle and the neighbour across it. An edge whose every pair is
    dropped is left out; the others keep their exact saddle (the minimum is over kept pairs, and a dropped pair
    is above it). The pruning's units are the same; the saddles between settled motifs (their bases) are not all
    there."""
    rows, cols = labels.shape
    lf = labels.ravel()
    df = d.ravel()
    total = lf.size
    if merging is not None:  # the minimum of each basin by 1-based label (entry 0 unused), and t
        low1 = np.concatenate(([np.inf], merging[0]))
        t = float(merging[1])
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
            if merging is not None:
                keep = np.maximum(low1.take(x), low1.take(y))
                np.subtract(p, keep, out=keep)
                kept = np.flatnonzero(keep < t)  # then gathers: faster than three boolean selections
                if kept.size == 0:
                    continue
                x, y, p = x.take(kept), y.take(kept), p.take(kept)
            key = np.minimum(x, y).astype(np.int64)
            key *= base
            key += np.maximum(x, y)
            if step != 1:  # along a boundary across rows the same pair repeats point after point: one per run
                st = run_starts(key)
                if st.size < key.size:
                    key = key.take(st)
                    p = np.minimum.reduceat(p, st)
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
