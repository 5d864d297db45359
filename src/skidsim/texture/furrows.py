"""Furrow parameters Fdmax, Fdmean (mm) and Fden (cm/cm^2): our definition (MountainsMap's is not public).

Definition (docs/texture.md):

* A *furrow point* is a strict local minimum of a profile along x (each row) or along y (each column) whose
  *depth* ``min(max z over the w points before, max z over the w points after) - z`` is at least
  ``min_depth_pct`` % of Sz (``w = window_mm / spacing`` points). Points closer than ``w + 1`` to the ends of
  the profile are not tested.
* Fdmax and Fdmean are the maximum and mean furrow depth over all furrow points (both directions).
* Fden is the furrow length per unit area by Cauchy-Crofton: a furrow line crossing a profile makes a furrow
  point, and for isotropically oriented lines the length per area is ``L_A = (pi/2) P_L`` with ``P_L`` the
  crossings per unit profile length averaged over directions; we average x and y:
  ``L_A = (pi/4) (P_x + P_y)`` in 1/mm, reported in cm/cm^2 (x 10). Unbiased for isotropic furrows; for furrows
  all along one grid axis it reads ``pi/4`` of the true length.
"""

from __future__ import annotations

import numpy as np

#: points of one block of profiles in :func:`_furrow_depths` (a few arrays of it stay in cache)
_BLOCK_POINTS = 1 << 15
#: points of one block of columns in :func:`_column_furrow_depths`
_COLUMN_BLOCK_POINTS = 1 << 16


def _sliding_max(f: np.ndarray, size: int, stride: int = 1) -> np.ndarray:
    """``W[j] = max(f[j : j + size * stride : stride])`` for ``j`` in ``0 .. len(f) - (size - 1) stride - 1``,
    exact: maxima over windows of 1, 2, 4, ... ``p`` points by doubling (``p`` the largest power of two up to
    ``size``), then the two windows of ``p`` that cover the ``size`` points (they overlap; a maximum does not
    mind). ``stride``: the step between the points of a window (the columns of a row-major block laid flat)."""
    p = 1 << (size.bit_length() - 1)
    cur, w = f, 1
    while w < p:
        cur = np.maximum(cur[: -w * stride], cur[w * stride :])
        w *= 2
    n_out = f.size - (size - 1) * stride
    if p == size:
        return cur
    shift = (size - p) * stride
    return np.maximum(cur[:n_out], cur[shift : shift + n_out])


def _candidates(
    f: np.ndarray, size: int, stride: int, lo: int, hi: int, min_depth: float
) -> tuple[np.ndarray, np.ndarray]:
    """Depths (mm) of the points ``f[lo:hi]`` of a flat buffer of extended profiles whose consecutive points are
    ``stride`` apart, and the mask of the furrow candidates among them: a strict local minimum at least
    ``min_depth`` deep. The depth is the lower of the maxima of the ``size`` points up to the point (the window
    starting ``size`` points before it) and of the ``size`` points after it, minus the point."""
    win = _sliding_max(f, size, stride)  # win[j]: max of f[j], f[j + stride], ... (size points)
    zc = f[lo:hi]
    depth = np.minimum(win[lo - size * stride : hi - size * stride], win[lo + stride : hi + stride])
    depth -= zc
    keep = zc < f[lo - stride : hi - stride]  # strict local minimum
    keep &= zc < f[lo + stride : hi + stride]
    keep &= depth >= min_depth
    return depth, keep


def _furrow_depths(z: np.ndarray, w: int, axis: int, min_depth: float = -np.inf) -> tuple[np.ndarray, int]:
    """Depths (mm) of the furrow candidates along ``axis`` at least ``min_depth`` (mm) deep, profile by profile
    in the order of the profiles (rows of ``z`` for axis 1, columns for axis 0), and the number of tested points.

    The maxima before and after a point are those of ``scipy.ndimage.maximum_filter1d(z, 2 (w // 2) + 1,
    mode="nearest")`` centred ``half`` points away (the same values: the nearest extension repeats the end value,
    which the window holds anyway). Blocks of profiles, each extended by ``size`` points at both ends, in one
    buffer that stays in cache; every step runs on that flat buffer. Rows (axis 1) are laid end to end (the windows
    of the tested points do not reach the next profile); columns (axis 0) stay in row-major order, a block of
    columns extended by ``size`` rows at the top and the bottom (no transposed copy), every window and neighbour a
    shift by whole rows, and the depths are read out column by column."""
    size = 2 * (w // 2) + 1  # odd window of ~w points
    half = (size + 1) // 2
    n = z.shape[axis]
    if n <= 2 * half + 2:
        return np.empty(0), 0
    count = z.shape[1 - axis]  # profiles
    length = n + 2 * size  # extended profile
    k0, k1 = size + half, size + n - half  # tested points of an extended profile
    if axis == 0:
        return _column_furrow_depths(z, size, min_depth, k0, k1), count * (n - 2 * half)
    per = max(1, min(count, _BLOCK_POINTS // length))
    tested = np.zeros((per, length), dtype=bool)
    tested[:, k0:k1] = True
    tested = tested.ravel()
    buf = np.empty((per, length))
    out = []
    for b0 in range(0, count, per):
        b1 = min(b0 + per, count)
        prof = z[b0:b1]
        bb = buf[: b1 - b0]
        bb[:, size : size + n] = prof
        bb[:, :size] = prof[:, :1]
        bb[:, size + n :] = prof[:, -1:]
        lo, hi = k0, (b1 - b0 - 1) * length + k1
        depth, keep = _candidates(bb.ravel(), size, 1, lo, hi, min_depth)
        keep &= tested[lo:hi]
        out.append(depth[keep])
    return np.concatenate(out), count * (n - 2 * half)


def _column_furrow_depths(z: np.ndarray, size: int, min_depth: float, k0: int, k1: int) -> np.ndarray:
    """The depths of :func:`_furrow_depths` along axis 0 (the columns' profiles), column by column: blocks of
    ``_COLUMN_BLOCK_POINTS`` points of columns, extended rows ``0 .. n + 2 size`` (the first and last row
    repeated), row-major; the same values and tests as the rows' path, a shift by ``k`` rows being one by ``k``
    times the block's width."""
    n, count = z.shape
    length = n + 2 * size
    per = max(1, min(count, _COLUMN_BLOCK_POINTS // length))
    buf = np.empty(length * per)
    out = []
    for c0 in range(0, count, per):
        c1 = min(c0 + per, count)
        cb = c1 - c0
        f = buf[: length * cb]
        e = f.reshape(length, cb)
        e[size : size + n] = z[:, c0:c1]
        e[:size] = z[0, c0:c1]
        e[size + n :] = z[-1, c0:c1]
        depth, keep = _candidates(f, size, cb, k0 * cb, k1 * cb, min_depth)  # a row is a shift by cb points
        out.append(depth.reshape(-1, cb).T[keep.reshape(-1, cb).T])  # column by column
    return np.concatenate(out)


def furrow_parameters(
    zc: np.ndarray,
    dx: float,
    dy: float,
    *,
    window_mm: float = 2.0,
    min_depth_pct: float = 5.0,
    sz: float | None = None,
) -> dict[str, float]:
    """Fdmax, Fdmean (mm), Fden (cm/cm^2) of heights ``zc`` (mm); see the module docstring. ``sz``:
    ``zc.max() - zc.min()`` when the caller has it."""
    sz = float(zc.max() - zc.min()) if sz is None else sz
    tmin = min_depth_pct / 100.0 * sz
    total_depths = []
    p = []
    for axis, step in ((1, dx), (0, dy)):
        w = max(1, int(round(window_mm / step)))
        depth, tested = _furrow_depths(zc, w, axis, tmin)
        total_depths.append(depth)
        p.append(depth.size / (tested * step) if tested else 0.0)  # crossings per mm of profile
    d = np.concatenate(total_depths)
    la = np.pi / 4.0 * (p[0] + p[1])  # 1/mm
    return {"Fdmax": float(d.max()) if d.size else 0.0, "Fdmean": float(d.mean()) if d.size else 0.0, "Fden": 10.0 * la}
