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
