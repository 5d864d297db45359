"""The MPD procedure's profile filters without importing ``scipy.signal`` (about 0.5 s of the start-up of each
per-site MPD job: scipy.signal imports scipy.stats, scipy.interpolate and scipy.optimize).

:func:`butter2_sos` is ``scipy.signal.butter(2, wn, btype, output="sos")`` and :func:`sosfiltfilt` is
``scipy.signal.sosfiltfilt(sos, x, axis=-1)`` (odd padding of 3 * ntaps points), the same bits: each follows
SciPy's own steps (``buttap``, ``lp2lp_zpk`` / ``lp2hp_zpk``, ``bilinear_zpk``, ``zpk2sos`` with its
``_cplxreal`` and ``zpk2tf``; ``odd_ext``, ``sosfilt_zi`` with ``lfilter_zi``'s ``numpy.linalg.solve``, and the
transposed direct form II recursion of ``_sosfilt``, in its order of operations) with the same NumPy calls,
for the one case the MPD uses: a 2nd-order digital low- or high-pass, float64 profiles as rows of a 2-D array
(rows longer than :data:`MAX_SAMPLES` are left to SciPy's compiled loop).
``tests/test_texture_iir.py`` compares both with SciPy bit for bit.
"""

from __future__ import annotations

import numpy as np


def butter2_sos(wn: float, btype: str) -> np.ndarray:
    """``scipy.signal.butter(2, wn, btype=btype, output="sos")`` for ``btype`` "low" or "high", 0 < wn < 1."""
    if btype not in ("low", "high"):
        raise ValueError(f"butter2_sos: btype 'low' or 'high', got {btype!r}")
    Wn = np.asarray(wn, dtype=np.float64)
    if not (0 < Wn < 1):
        raise ValueError("Digital filter critical frequencies must be 0 < Wn < 1")
    # buttap(2): analog prototype
    z = np.asarray([], dtype=np.float64)
    m = np.arange(-2 + 1, 2, 2, dtype=np.float64)
    p = -np.exp(1j * np.pi * m / (2 * 2))
    k = 1.0
    # iirfilter: pre-warp, then lp2lp_zpk / lp2hp_zpk (degree 2: two poles, no zeros)
    fs = 2.0
    wo = float(2 * fs * np.tan(np.pi * Wn / fs))
    if btype == "low":
        z, p, k = wo * z, wo * p, k * wo**2
    else:
        z, p, k = np.concatenate((wo / z, np.zeros(2))), wo / p, k * np.real(np.prod(-z) / np.prod(-p))
    # bilinear_zpk
    degree = p.shape[0] - z.shape[0]
    fs2 = 2.0 * fs
    z_z = np.concatenate(((fs2 + z) / (fs2 - z), -np.ones(degree)))
    p_z = (fs2 + p) / (fs2 - p)
    k_z = k * np.real(np.prod(fs2 - z) / np.prod(fs2 - p))
    return _zpk2sos_conjugate_pair(z_z, p_z, k_z)


def _cplxreal_pair(z: np.ndarray) -> np.ndarray:
    """``concatenate(_cplxreal(z))`` of two real zeros (sorted) or of one conjugate pair (its mean member)."""
    z = np.atleast_1d(z)
    tol = 100 * np.finfo((1.0 * z).dtype).eps
    z = z[np.lexsort((abs(z.imag), z.real))]
    real_indices = abs(z.imag) <= tol * abs(z)
    zr = z[real_indices].real
    if len(zr) == len(z):
        return np.concatenate((np.array([]), zr))
    if real_indices.any():
        raise ValueError("_cplxreal_pair: a conjugate pair or two real values expected")
    zp = z[z.imag > 0]
    zn = z[z.imag < 0]
    if len(zp) != 1 or len(zn) != 1 or any(abs(zp - zn.conj()) > tol * abs(zn)):
        raise ValueError("Array contains complex value with no matching conjugate.")
    zc = (zp + zn.conj()) / 2
    return np.concatenate((zc, zr))


def _poly(seq_of_zeros: np.ndarray) -> np.ndarray:
    """``scipy.signal._polyutils.poly`` (NumPy's ``poly`` by ``convolve``) of a 1-D array."""
    dt = seq_of_zeros.dtype
    a = np.ones((1,), dtype=dt)
    one = np.ones_like(seq_of_zeros[0])
    for zero in seq_of_zeros:
        a = np.convolve(a, np.stack((one, -zero)), mode="full")
    if np.iscomplexobj(a):
        roots = np.asarray(seq_of_zeros, dtype=np.complex128)
        if np.all(np.sort(np.imag(roots)) == np.sort(np.imag(np.conj(roots)))):
            a = np.array(np.real(a), copy=True)
    return a


def _zpk2sos_conjugate_pair(z: np.ndarray, p: np.ndarray, k) -> np.ndarray:
    """``zpk2sos(z, p, k)`` (pairing "nearest") of two real zeros and one conjugate pair of poles: one section."""
    z = np.asarray(z)
    p = np.asarray(p)
    k = np.asarray(k)
    z = _cplxreal_pair(z)
    p = _cplxreal_pair(p)
    if len(z) != 2 or len(p) != 1 or np.isreal(p[0]):
        raise ValueError("_zpk2sos_conjugate_pair: two real zeros and one conjugate pair of poles expected")
    k = k.real
    p1 = p[0]
    p2 = p1.conj()
    z1_idx = np.argsort(np.abs(z - p1))[0]  # _nearest_real_complex_idx(z, p1, "any")
    z1 = z[z1_idx]
    z = np.delete(z, z1_idx)
    z2 = z[0]
    # _single_zpksos([z1, z2], [p1, p2], 1) by zpk2tf
    zz = np.asarray([z1, z2])
    pp = np.asarray([p1, p2])
    kk = np.atleast_1d(np.asarray(1, dtype=np.result_type(np.real(zz), np.real(pp), 1)))
    b = np.multiply(kk, _poly(zz))
    a = np.atleast_1d(np.asarray(_poly(pp)))
    sos = np.zeros((1, 6))
    row = np.zeros(6)
    row[3 - len(b) : 3] = b
    row[6 - len(a) : 6] = a
    sos[0] = row
    sos[0][:3] *= k
    return sos


def _lfilter_zi(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter_zi(b, a)`` of one second-order section."""
    b = np.atleast_1d(np.asarray(b))
    a = np.atleast_1d(np.asarray(a))
    while a.shape[0] > 1 and a[0] == 0.0:
        a = a[1:]
    if a[0] != 1.0:
        b = b / a[0]
        a = a / a[0]
    n = max(a.shape[0], b.shape[0])
    if a.shape[0] < n:
        a = np.concatenate((a, np.zeros(n - a.shape[0], dtype=a.dtype)))
    elif b.shape[0] < n:
        b = np.concatenate((b, np.zeros(n - b.shape[0], dtype=b.dtype)))
    dt = np.result_type(a, b)
    # scipy.linalg.companion(a)
    first_row = -a[1:] / (1.0 * a[0:1])
    c = np.zeros((n - 1, n - 1), dtype=first_row.dtype)
    c[0, :] = first_row
    c[np.arange(1, n - 1), np.arange(0, n - 2)] = 1
    IminusA = np.asarray(np.eye(n - 1) - c.T, dtype=dt)
    B = b[1:] - a[1:] * b[0]
    return np.linalg.solve(IminusA, B)


def _sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    n_sections = sos.shape[0]
    zi = np.empty((n_sections, 2), dtype=sos.dtype)
    scale = 1.0
    for section in range(n_sections):
        b = sos[section, :3]
        a = sos[section, 3:]
        zi[section, ...] = scale * _lfilter_zi(b, a)
        scale *= np.sum(b) / np.sum(a)
    return zi


def _sosfilt_rows(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> np.ndarray:
    """SciPy's ``_sosfilt`` on the rows of ``x`` (n_rows, n_samples), initial state ``zi`` (n_rows, n_sections,
    2): the recursion sample by sample, every row at once, each operation in SciPy's order."""
    x = np.array(x, dtype=np.float64, order="C")
    z0 = [np.array(zi[:, s, 0]) for s in range(sos.shape[0])]
    z1 = [np.array(zi[:, s, 1]) for s in range(sos.shape[0])]
    coef = [tuple(float(c) for c in sec) for sec in sos]
    t = np.empty(x.shape[0])
    for n in range(x.shape[1]):
        x_cur = x[:, n].copy()
        for s, (b0, b1, b2, _a0, a1, a2) in enumerate(coef):
            x_new = b0 * x_cur
            x_new += z0[s]
            # z0 = (b1 * x_cur - a1 * x_new) + z1 ; z1 = b2 * x_cur - a2 * x_new
            np.multiply(x_cur, b1, out=z0[s])
            np.multiply(x_new, a1, out=t)
            z0[s] -= t
            z0[s] += z1[s]
            np.multiply(x_cur, b2, out=z1[s])
            np.multiply(x_new, a2, out=t)
            z1[s] -= t
            x_cur = x_new
        x[:, n] = x_cur
    return x


#: rows longer than this go to scipy.signal.sosfiltfilt itself (the recursion here is one Python step per sample:
#: cheap for a scan's 100 mm profiles, about 250 samples, but not for a 1 km network run); the same bits either way
MAX_SAMPLES = 4096


def sosfiltfilt(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=-1)`` (padtype "odd", default padlen) of the rows of a 2-D float64
    array; a row of at most 3 * ntaps points raises ValueError as SciPy does. Rows longer than
    :data:`MAX_SAMPLES` are filtered by SciPy."""
    sos = np.asarray(sos, dtype=np.float64)
    x = np.asarray(x)
    if sos.ndim != 2 or sos.shape[1] != 6 or not np.all(sos[:, 3] == 1):
        raise ValueError("sos must be shape (n_sections, 6) with sos[:, 3] all ones")
    if x.ndim != 2 or x.dtype != np.float64:
        raise ValueError("sosfiltfilt: a 2-D float64 array of profiles (rows) expected")
    n_sections = sos.shape[0]
    ntaps = 2 * n_sections + 1
    ntaps -= min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum())
    edge = ntaps * 3
    if x.shape[1] <= edge:
        raise ValueError(f"The length of the input vector x must be greater than padlen, which is {edge}.")
    if x.shape[1] > MAX_SAMPLES:
        from scipy import signal

        return signal.sosfiltfilt(sos, x, axis=-1)
    # odd_ext
    ext = np.concatenate(
        (2 * x[:, 0:1] - x[:, edge:0:-1], x, 2 * x[:, -1:] - x[:, -2 : -(edge + 2) : -1]),
        axis=1,
    )
    zi = _sosfilt_zi(sos).reshape(n_sections, 1, 2)
    # sosfilt's zi layout: (n_sections, rows, 2) -> (rows, n_sections, 2)
    zi_f = np.ascontiguousarray(np.moveaxis(zi * ext[:, 0:1], 0, 1))
    y = _sosfilt_rows(sos, ext, zi_f)
    zi_b = np.ascontiguousarray(np.moveaxis(zi * y[:, -1:], 0, 1))
    y = _sosfilt_rows(sos, y[:, ::-1], zi_b)[:, ::-1]
    return y[:, edge:-edge]
