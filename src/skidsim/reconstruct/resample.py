"""The scan-grid operations of the pavement strip: ISO 16610-61 Gaussian smoothing, exact area averaging from
pixels onto node boxes, and the removal of the least-squares mean plane (steps 2-4 of :mod:`.strip`).

A scan sample is a pixel: sample ``k`` covers ``[(k - 1/2) d, (k + 1/2) d]`` along its axis.
"""

from __future__ import annotations

import math

import numpy as np

#: ISO 16610-61 Gaussian constant alpha = sqrt(ln 2 / pi): 50 % transmission at the cutoff wavelength.
ISO_GAUSS_ALPHA = math.sqrt(math.log(2.0) / math.pi)


def gaussian_sigma_mm(cutoff_mm: float) -> float:
    """Standard deviation (mm) of the ISO 16610-61 Gaussian weighting function of cutoff ``cutoff_mm``.

    ``s(x) = exp(-pi (x / (alpha lc))^2) / (alpha lc)`` is a normal density with
    ``sigma = alpha lc / sqrt(2 pi) = 0.1874 lc``; its amplitude transmission at wavelength ``lambda`` is
    ``exp(-pi (alpha lc / lambda)^2)``, 50 % at ``lambda = lc``.
    """
    return ISO_GAUSS_ALPHA * float(cutoff_mm) / math.sqrt(2.0 * math.pi)


def _gaussian_reflect(a: np.ndarray, sigmas, truncate: float = 4.0) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(a, sigmas, mode="reflect", truncate=truncate)`` of a 2-D float64 array,
    the same bits, without importing SciPy (about 0.25 s of the start-up of each reconstruct job).

    SciPy's kernel (``_gaussian_kernel1d``, reversed for the correlation) and its symmetric C loop
    (``NI_Correlate1D``: ``x[i] * w[0]``, then ``+= (x[i - k] + x[i + k]) * w[-k]`` for k = r, r - 1, ..., 1),
    axis 0 then axis 1, on lines extended by reflection (NumPy's ``"symmetric"`` padding). Any other case (not
    float64, a kernel longer than the axis, a kernel not symmetric to DBL_EPSILON) is left to SciPy itself."""
    out = np.asarray(a)
    sigmas = [float(sd) for sd in sigmas]
    radii = [int(truncate * sd + 0.5) for sd in sigmas]
    plain = out.dtype == np.float64 and out.ndim == 2 and all(sd > 0 for sd in sigmas)
    weights = []
    for sd, r in zip(sigmas, radii):
        x = np.arange(-r, r + 1)
        phi = np.exp(-0.5 / (sd * sd) * x**2)
        w = (phi / phi.sum())[::-1]
        weights.append(w)
        plain = plain and np.all(np.abs(w[r + 1 :] - w[:r][::-1]) <= np.finfo(np.float64).eps)
    if not plain or any(r >= n for r, n in zip(radii, out.shape)):
        from scipy import ndimage

        return ndimage.gaussian_filter(a, sigma=sigmas, mode="reflect", truncate=truncate)
    for axis, (r, w) in enumerate(zip(radii, weights)):
        n = out.shape[axis]
        pad = [(0, 0), (0, 0)]
        pad[axis] = (r, r)
        p = np.pad(out, pad, mode="symmetric")

        def line(k, p=p, n=n, r=r, axis=axis):
            return p[r + k : r + k + n] if axis == 0 else p[:, r + k : r + k + n]

        acc = line(0) * w[r]
        tmp = np.empty_like(acc)
        for k in range(r, 0, -1):
            np.add(line(-k), line(k), out=tmp)
            tmp *= w[r - k]
            acc += tmp
        out = acc
    return out


def area_weights(n_src: int, d_src: float, centres, box: float) -> np.ndarray:
    """Area-averaging weights ``(len(centres), n_src)`` from pixels to boxes along one axis.

    Source sample ``k`` is a pixel covering ``[(k - 1/2) d_src, (k + 1/2) d_src]``; target ``m`` averages
    over ``[centres[m] - box/2, centres[m] + box/2]`` clipped to the pixels' span. Rows sum to 1.
    Units: any, as long as ``d_src``, ``centres`` and ``box`` share them.
    """
    c = np.asarray(centres, dtype=float)
    k = np.arange(n_src)
    p0 = (k - 0.5) * d_src
    p1 = (k + 0.5) * d_src
    b0 = c[:, None] - 0.5 * box
    b1 = c[:, None] + 0.5 * box
    w = np.minimum(b1, p1[None, :]) - np.maximum(b0, p0[None, :])
    np.maximum(w, 0.0, out=w)
    tot = w.sum(axis=1, keepdims=True)
    if np.any(tot <= 0):
        raise ValueError("a resampling box lies outside the source grid")
    return w / tot


def resample_area(heights: np.ndarray, dx: float, dy: float, x_nodes, y_nodes, hx: float, hy: float) -> np.ndarray:
    """Area-average ``heights`` (rows y, cols x, spacing ``dx``/``dy``) onto node boxes ``hx x hy``.

    ``x_nodes``/``y_nodes`` are the node centres in the source's coordinates (``x = j dx``). Exact for a
    piecewise-constant-per-pixel source; equal to the block mean when boxes are aligned whole pixels.
    """
    wx = area_weights(heights.shape[1], dx, x_nodes, hx)
    wy = area_weights(heights.shape[0], dy, y_nodes, hy)
    cx = np.nonzero(wx.any(axis=0))[0]
    cy = np.nonzero(wy.any(axis=0))[0]
    sx = slice(cx[0], cx[-1] + 1)
    sy = slice(cy[0], cy[-1] + 1)
    return wy[:, sy] @ heights[sy, sx] @ wx[:, sx].T


def remove_mean_plane(z: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Subtract the least-squares plane ``a + b x + c y`` from ``z (ny, nx)``; returns ``(z - plane, (a, b, c))``."""
    X, Y = np.meshgrid(x, y)
    A = np.column_stack([np.ones(X.size), X.ravel(), Y.ravel()])
    coef, *_ = np.linalg.lstsq(A, z.ravel(), rcond=None)
    return z - (A @ coef).reshape(z.shape), coef
