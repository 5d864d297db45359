"""ISO 25178-2 height parameters on the heights referenced to their mean plane (mean subtracted).

Sq, Sa, Ssk, Sku (not excess: a Gaussian gives 3), Sp (highest point above the mean), Sv (depth of the lowest
point below the mean, positive), Sz = Sp + Sv. Every grid point has equal weight (sums divided by N).
"""

from __future__ import annotations

import numpy as np

from .pairwise import leaves, pairwise_tree, tree_sum


def finite_mean(z: np.ndarray):
    """The mean of the heights ``z`` (mm), or None when ``z`` holds a NaN or an infinity. A finite mean means
    finite heights (a NaN or an infinity makes the sum NaN or infinite), so the point-by-point check runs only
    where the mean is not finite (an overflowing sum of finite heights passes it, as the check alone would).
    An empty array gives NaN."""
    mean = z.mean() if z.size else np.nan
    if np.isfinite(mean) or np.isfinite(z).all():
        return mean
    return None


def sa_sq(z: np.ndarray) -> dict[str, float]:
    """``{"Sa": mm, "Sq": mm}`` of a complete height array (mm) alone: the same bits as :func:`height_parameters`'
    (the same block sums of ``|c|`` and ``c^2``), each block of heights about the mean formed in a buffer, without
    the whole arrays of ``c`` and ``c^2``, the third and fourth moments and the extremes."""
    flat = np.ravel(z)
    n = flat.size
    mean = flat.mean()
    tree = pairwise_tree(0, n)
    s2, s1 = {}, {}
    parts = leaves(tree)
    size = max(length for _, length in parts)
    cbuf, buf = np.empty(size), np.empty(size)
    for leaf in parts:
        start, length = leaf
        cb, b = cbuf[:length], buf[:length]
        np.subtract(flat[start : start + length], mean, out=cb)
        s1[leaf] = np.abs(cb, out=b).sum()
        s2[leaf] = np.multiply(cb, cb, out=b).sum()
    return {"Sa": float(tree_sum(tree, s1) / n), "Sq": float(np.sqrt(tree_sum(tree, s2) / n))}


def height_parameters(z: np.ndarray) -> dict[str, float]:
    """Height parameters of a complete (no NaN) height array in mm: Sq, Ssk, Sku, Sp, Sv, Sz, Sa.

    Sq, Sp, Sv, Sz, Sa in mm; Ssk, Sku dimensionless. The sums of ``c^2``, ``|c|`` and ``c^4`` (``c`` the heights
    about their mean) are those of ``np.sum`` of the whole arrays, evaluated block by block
    (:mod:`skidsim.texture.pairwise`); the third moment is ``np.dot(c^2, c)``.
    """
    flat = np.ravel(z)
    n = flat.size
    mean = flat.mean()
    c = flat - mean
    c2 = c * c
    m3 = float(np.dot(c2, c) / n)
    tree = pairwise_tree(0, n)
    s2, s1, s4 = {}, {}, {}
    parts = leaves(tree)
    buf = np.empty(max(length for _, length in parts))
    for leaf in parts:
        start, length = leaf
        cb, c2b, b = c[start : start + length], c2[start : start + length], buf[:length]
        s2[leaf] = c2b.sum()
        s1[leaf] = np.abs(cb, out=b).sum()
        s4[leaf] = np.multiply(c2b, c2b, out=b).sum()
    m2 = tree_sum(tree, s2) / n
    sq = float(np.sqrt(m2))
    sa = float(tree_sum(tree, s1) / n)
    m4 = float(tree_sum(tree, s4) / n)
    sp = float(c.max())
    sv = float(-c.min())
    return {
        "Sq": sq,
        "Ssk": m3 / sq**3 if sq > 0 else np.nan,
        "Sku": m4 / m2**2 if sq > 0 else np.nan,
        "Sp": sp,
        "Sv": sv,
        "Sz": sp + sv,
        "Sa": sa,
    }
