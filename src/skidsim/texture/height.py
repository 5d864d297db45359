"""ISO 25178-2 height parameters on the heights referenced to their mean plane (mean subtracted).

Sq, Sa, Ssk, Sku (not excess: a Gaussian gives 3), Sp (highest point above the mean), Sv (depth of the lowest
point below the mean, positive), Sz = Sp + Sv. Every grid point has equal weight (sums divided by N).
"""

from __future__ import annotations

import numpy as np


def height_parameters(z: np.ndarray) -> dict[str, float]:
    """Height parameters of a complete (no NaN) height array in mm: Sq, Ssk, Sku, Sp, Sv, Sz, Sa.

    Sq, Sp, Sv, Sz, Sa in mm; Ssk, Sku dimensionless.
    """
    flat = np.ravel(z)
    n = flat.size
    mean = flat.mean()
    c = flat - mean
    c2 = c * c
    m2 = c2.sum() / n
    sq = float(np.sqrt(m2))
    sa = float(np.abs(c).sum() / n)
    m3 = float(np.dot(c2, c) / n)
    c2 *= c2
    m4 = float(c2.sum() / n)
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
