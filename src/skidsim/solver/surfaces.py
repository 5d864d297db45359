"""Analytic rigid pavement surfaces implementing the solver's pavement protocol.

The solver accepts any object with

* ``evaluate(x_m, y_m) -> (z_m, dzdx, dzdy)``: vectorised height (m) and slopes (dimensionless) of the rigid
  surface at plan positions in m (C1: heights and slopes continuous), and
* ``extent_m`` (or ``extent``, as :class:`skidsim.reconstruct.Heightfield` names it): ``(x_min, x_max, y_min,
  y_max)`` in m, the region where ``evaluate`` is valid.

:class:`skidsim.reconstruct.Heightfield` implements it for scanned pavements; the classes here are exact analytic
surfaces for verification runs (flat, tilted and sinusoidal), usable in the workflow as well.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Default extent (m) of the analytic surfaces: a 200 mm x 60 mm strip centred on y = 0 starting at x = 0.
DEFAULT_EXTENT_M = (0.0, 0.2, -0.03, 0.03)


@dataclass(frozen=True)
class FlatPlane:
    """The plane ``z = z0_m`` (m)."""

    z0_m: float = 0.0
    extent_m: tuple[float, float, float, float] = DEFAULT_EXTENT_M

    def evaluate(self, x_m, y_m):
        x = np.asarray(x_m, dtype=float)
        shape = np.broadcast(x, np.asarray(y_m)).shape
        return np.full(shape, self.z0_m), np.zeros(shape), np.zeros(shape)


@dataclass(frozen=True)
class TiltedPlane:
    """The plane ``z = z0_m + slope_x * x + slope_y * y`` (m; slopes dimensionless)."""

    slope_x: float = 0.0
    slope_y: float = 0.0
    z0_m: float = 0.0
    extent_m: tuple[float, float, float, float] = DEFAULT_EXTENT_M

    def evaluate(self, x_m, y_m):
        x = np.asarray(x_m, dtype=float)
        y = np.asarray(y_m, dtype=float)
        shape = np.broadcast(x, y).shape
        z = self.z0_m + self.slope_x * x + self.slope_y * y
        return np.broadcast_to(z, shape).copy(), np.full(shape, self.slope_x), np.full(shape, self.slope_y)


@dataclass(frozen=True)
class SinusoidalSurface:
    """Egg-box texture ``z = a cos(2 pi x / lx + phase) cos(2 pi y / ly)`` (a, lx, ly in m).

    ``wavelength_y_m = inf`` gives ridges across the sliding direction (a 2-d corrugation).
    """

    amplitude_m: float = 0.2e-3
    wavelength_x_m: float = 4e-3
    wavelength_y_m: float = 4e-3
    phase: float = 0.0
    extent_m: tuple[float, float, float, float] = DEFAULT_EXTENT_M

    def evaluate(self, x_m, y_m):
        x = np.asarray(x_m, dtype=float)
        y = np.asarray(y_m, dtype=float)
        kx = 2 * np.pi / self.wavelength_x_m
        ky = 0.0 if np.isinf(self.wavelength_y_m) else 2 * np.pi / self.wavelength_y_m
        cx, sx = np.cos(kx * x + self.phase), np.sin(kx * x + self.phase)
        cy, sy = np.cos(ky * y), np.sin(ky * y)
        a = self.amplitude_m
        return a * cx * cy, -a * kx * sx * cy, -a * ky * cx * sy


def pavement_extent_m(pavement) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` in m of a pavement object (attribute ``extent_m``)."""
    ext = getattr(pavement, "extent_m", None)
    if ext is None:
        ext = getattr(pavement, "extent", None)  # skidsim.reconstruct.Heightfield: extent in m
    if ext is None:
        raise TypeError(
            f"pavement {type(pavement).__name__} has no 'extent_m' or 'extent' (x_min, x_max, y_min, y_max) in m"
        )
    ext = tuple(float(e) for e in ext)
    if len(ext) != 4 or not (ext[1] > ext[0] and ext[3] > ext[2]):
        raise ValueError(f"pavement extent_m: expected (x_min, x_max, y_min, y_max) with max > min in m, got {ext}")
    return ext


@dataclass(frozen=True)
class RandomTexture:
    """Seeded random isotropic texture: a sum of ``n_modes`` plane cosine waves (C-infinity, exact slopes).

    Wavelengths are log-uniform in ``[min_wavelength_m, max_wavelength_m]`` with amplitudes ~ wavelength^hurst
    (self-affine-like), random directions and phases from ``numpy.random.default_rng(seed)``; the heights are
    scaled to the RMS height ``rms_m`` (m, the expected value over the plane). A stand-in for a scanned pavement
    in benchmarks and tests (macro-texture scale; the 0.05 mm micro-texture is below the slider mesh anyway).
    """

    rms_m: float = 0.3e-3
    min_wavelength_m: float = 1.5e-3
    max_wavelength_m: float = 20e-3
    n_modes: int = 48
    hurst: float = 0.8
    seed: int = 0
    extent_m: tuple[float, float, float, float] = DEFAULT_EXTENT_M

    def __post_init__(self):
        object.__setattr__(self, "_cache", self._draw())

    def _modes(self):
        return self._cache

    def _draw(self):
        rng = np.random.default_rng(self.seed)
        lam = np.exp(rng.uniform(np.log(self.min_wavelength_m), np.log(self.max_wavelength_m), self.n_modes))
        theta = rng.uniform(0, np.pi, self.n_modes)
        phase = rng.uniform(0, 2 * np.pi, self.n_modes)
        amp = lam**self.hurst
        amp *= self.rms_m / np.sqrt(0.5 * np.sum(amp**2))
        k = 2 * np.pi / lam
        return amp, k * np.cos(theta), k * np.sin(theta), phase

    def evaluate(self, x_m, y_m):
        x = np.asarray(x_m, dtype=float)
        y = np.asarray(y_m, dtype=float)
        amp, kx, ky, ph = self._modes()
        arg = np.multiply.outer(x, kx) + np.multiply.outer(y, ky) + ph
        c, s = np.cos(arg), np.sin(arg)
        return c @ amp, -(s @ (amp * kx)), -(s @ (amp * ky))


def to_heightfield(surface, spacing_m: float = 0.1e-3, name: str = ""):
    """Sample an analytic surface on a regular grid (spacing in m) over its extent as a
    :class:`skidsim.reconstruct.Heightfield` (C1 interpolation, the path scanned pavements take; also far cheaper
    to evaluate than :class:`RandomTexture`'s sum of cosines)."""
    from skidsim.reconstruct import Heightfield

    x0, x1, y0, y1 = pavement_extent_m(surface)
    nx = int(round((x1 - x0) / spacing_m)) + 1
    ny = int(round((y1 - y0) / spacing_m)) + 1
    x = x0 + spacing_m * np.arange(nx)
    y = y0 + spacing_m * np.arange(ny)
    X, Y = np.meshgrid(x, y)
    z, _, _ = surface.evaluate(X.ravel(), Y.ravel())
    return Heightfield(
        np.asarray(z).reshape(X.shape), spacing_m, spacing_m, origin_m=(x0, y0), name=name or type(surface).__name__
    )


#: Monomial -> Bernstein coefficients of a cubic on [0, 1]: ``b_i = sum_{j <= i} C(i, j) / C(3, j) a_j``.
_MONO_TO_BERNSTEIN = np.array(
    [[1.0, 0.0, 0.0, 0.0], [1.0, 1.0 / 3.0, 0.0, 0.0], [1.0, 2.0 / 3.0, 1.0 / 3.0, 0.0], [1.0, 1.0, 1.0, 1.0]]
)


class SurfaceBound:
    """Per-cell upper bound of a :class:`skidsim.reconstruct.Heightfield`'s C1 (bicubic) surface: contact candidates.

    The bicubic of each cell is converted to the Bernstein basis; by the convex-hull property its largest Bernstein
    coefficient bounds the surface over the cell from above. A bottom node whose height is not below the bound of
    its cell (plus ``margin_m``, 1 nm against rounding) cannot penetrate, so the solver evaluates the surface and
    the contact/friction forces only on the remaining candidates: the same result as evaluating every node (the
    others get zero force), at a fraction of the cost (typically 1-20 % of the bottom nodes are candidates).
    """

    def __init__(self, heightfield, margin_m: float = 1e-9):
        coef_t, lo, inv, hi, nxc = heightfield._cells
        c = coef_t.reshape(4, 4, -1)  # [u power, t power, cell]
        b = np.einsum("ib,ja,bac->ijc", _MONO_TO_BERNSTEIN, _MONO_TO_BERNSTEIN, c, optimize=True)
        self.zmax_m = b.reshape(16, -1).max(axis=0) + margin_m
        self._lo, self._inv, self._hi, self._nxc = lo[:, 0], inv[:, 0], hi[:, 0], nxc
        self._hf = heightfield

    @classmethod
    def of(cls, pavement):
        """The bound of a Heightfield-like pavement (with the bicubic ``_cells``), else ``None`` (no pruning)."""
        return cls(pavement) if all(hasattr(pavement, a) for a in ("_cells", "z_m", "surface_at")) else None

    def cells(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Padded cell index of points (m), computed exactly as ``Heightfield.evaluate`` does."""
        sx = (x_m - self._lo[0]) * self._inv[0]
        sy = (y_m - self._lo[1]) * self._inv[1]
        # np.clip(s, 0, hi) as its two ufuncs (the same values up to the sign of a zero; the cells are equal),
        # without np.clip's Python wrappers
        np.minimum(np.maximum(sx, 0.0, out=sx), self._hi[0], out=sx)
        np.minimum(np.maximum(sy, 0.0, out=sy), self._hi[1], out=sy)
        cell = sy.astype(np.intp)
        cell *= self._nxc
        cell += sx.astype(np.intp)
        return cell

    def candidates(self, x_m: np.ndarray, y_m: np.ndarray, z_m: np.ndarray) -> np.ndarray:
        """Indices of the points ``(x_m, y_m, z_m)`` (m, 1-D) below the surface bound of their cell."""
        return np.flatnonzero(z_m < self.zmax_m.take(self.cells(x_m, y_m)))

    def surface_at_candidates(self, xyz_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The candidates among the points ``xyz_m`` ``(3, n)`` (m) and the surface there: ``(cand, zg)`` with
        ``cand`` their indices (increasing) and ``zg`` ``(3, cand.size)`` the heights (m) and slopes
        ``[z, dz/dx, dz/dy]``, bit for bit ``Heightfield.evaluate`` (one cell lookup serves the bound and the
        evaluation)."""
        cell, s, k = self._hf.locate(xyz_m[:2])
        cand = (xyz_m[2] < self.zmax_m.take(cell)).nonzero()[0]
        tu3 = np.empty((4, cand.size))
        np.subtract(s.take(cand, axis=1), k.take(cand, axis=1), out=tu3[:2])
        np.multiply(tu3[:2], 3.0, out=tu3[2:])
        return cand, self._hf.surface_at(cell.take(cand), tu3)
