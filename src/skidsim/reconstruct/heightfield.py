"""The rigid pavement surface of the FE model: a heightfield in SI units on a regular grid.

Node ``(i, j)`` of a :class:`Heightfield` is at ``x = origin_x + j dx_m``, ``y = origin_y + i dy_m`` (m; x = the
sliding direction), heights in m above the flat bottom ``z_bottom_m`` of the solid; it is written to and read from
an ``.npz`` file (:meth:`Heightfield.to_npz`, :meth:`Heightfield.from_npz`).

:meth:`Heightfield.evaluate` is a C1 piecewise bicubic Hermite interpolant (slopes by second-order finite
differences: central inside, one-sided at the edges), exact for polynomials of degree <= 2, evaluated from
precomputed per-cell coefficients.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import InputError

# Hermite-to-monomial matrix: p(t) = [1 t t^2 t^3] . M . [p0, p1, p0', p1'].
_HERMITE = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-3.0, 3.0, -2.0, -1.0], [2.0, -2.0, 1.0, 1.0]])


@dataclass(frozen=True, eq=False)
class Heightfield:
    """A rigid pavement surface ``z(x, y)`` on a regular grid, SI units.

    Attributes
    ----------
    z_m:
        ``(ny, nx)`` float64 heights in m; rows run along y, columns along x (sliding direction).
    dx_m, dy_m:
        Node spacings in m along x (columns) and y (rows).
    origin_m:
        ``(x, y)`` in m of node ``(0, 0)``; node ``(i, j)`` is at ``(x0 + j dx_m, y0 + i dy_m)``.
    z_bottom_m:
        Height (m) of the flat bottom of the pavement solid; ``None`` means ``min(z) - 8 mm``.
    name:
        Identifier for messages (site, scan).
    meta:
        Provenance (scan position in mm, smoothing, resolution, removed plane); JSON-serialisable.
    """

    z_m: np.ndarray
    dx_m: float
    dy_m: float
    origin_m: tuple[float, float] = (0.0, 0.0)
    z_bottom_m: float | None = None
    name: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        z = np.ascontiguousarray(self.z_m, dtype=np.float64)
        where = self.name or "<heightfield>"
        if z.ndim != 2 or z.shape[0] < 2 or z.shape[1] < 2:
            raise InputError(where, "a 2-D height array with at least 2 x 2 nodes", column="z_m", got=z.shape)
        if not np.all(np.isfinite(z)):
            raise InputError(
                where,
                "finite heights (no NaN: gap-fill the scan first)",
                column="z_m",
                got=f"{int(np.sum(~np.isfinite(z)))} non-finite values",
            )
        for nm in ("dx_m", "dy_m"):
            v = getattr(self, nm)
            if not (np.isfinite(v) and v > 0):
                raise InputError(where, "a positive spacing in m", column=nm, got=v)
        object.__setattr__(self, "z_m", z)
        object.__setattr__(self, "dx_m", float(self.dx_m))
        object.__setattr__(self, "dy_m", float(self.dy_m))
        object.__setattr__(self, "origin_m", (float(self.origin_m[0]), float(self.origin_m[1])))
        zb = float(z.min()) - 8e-3 if self.z_bottom_m is None else float(self.z_bottom_m)
        if not zb < float(z.min()):
            raise InputError(where, "z_bottom_m below the lowest height", column="z_bottom_m", got=zb)
        object.__setattr__(self, "z_bottom_m", zb)

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int]:
        """``(ny, nx)`` number of nodes along y and x."""
        return self.z_m.shape  # type: ignore[return-value]

    @property
    def length_m(self) -> float:
        """Extent along x (sliding direction) in m."""
        return (self.shape[1] - 1) * self.dx_m

    @property
    def width_m(self) -> float:
        """Extent along y in m."""
        return (self.shape[0] - 1) * self.dy_m

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the node grid in m."""
        x0, y0 = self.origin_m
        return (x0, x0 + self.length_m, y0, y0 + self.width_m)

    @property
    def max_height_m(self) -> float:
        """Highest node height in m (the interpolant never exceeds it by more than the cubic overshoot)."""
        return float(self.z_m.max())

    @property
    def min_height_m(self) -> float:
        """Lowest node height in m."""
        return float(self.z_m.min())

    def x_m(self) -> np.ndarray:
        """Node x coordinates in m."""
        return self.origin_m[0] + self.dx_m * np.arange(self.shape[1])

    def y_m(self) -> np.ndarray:
        """Node y coordinates in m."""
        return self.origin_m[1] + self.dy_m * np.arange(self.shape[0])

    def volume_m3(self) -> float:
        """Volume (m^3) of the solid between ``z_bottom_m`` and the bilinear surface (trapezoid rule)."""
        h = self.z_m - self.z_bottom_m
        wy = np.full(self.shape[0], self.dy_m)
        wy[[0, -1]] *= 0.5
        wx = np.full(self.shape[1], self.dx_m)
        wx[[0, -1]] *= 0.5
        return float(wy @ h @ wx)

    def bilinear(self, x_m, y_m) -> np.ndarray:
        """Heights (m) of the piecewise *bilinear* surface through the nodes (what a quad-faceted mesh sees).

        Points outside the grid are clamped onto it.
        """
        x = np.asarray(x_m, dtype=float)
        y = np.asarray(y_m, dtype=float)
        ny, nx = self.shape
        s = np.clip((x - self.origin_m[0]) / self.dx_m, 0.0, nx - 1.0)
        r = np.clip((y - self.origin_m[1]) / self.dy_m, 0.0, ny - 1.0)
        j = np.minimum(s.astype(np.intp), nx - 2)
        i = np.minimum(r.astype(np.intp), ny - 2)
        t = s - j
        u = r - i
        z = self.z_m
        return (
            (1 - t) * (1 - u) * z[i, j]
            + t * (1 - u) * z[i, j + 1]
            + (1 - t) * u * z[i + 1, j]
            + t * u * z[i + 1, j + 1]
        )

    def crop(self, x_range_m: tuple[float, float], y_range_m: tuple[float, float]) -> Heightfield:
        """The sub-grid of nodes inside ``x_range_m x y_range_m`` (m, inclusive), same bottom and meta."""
        x = self.x_m()
        y = self.y_m()
        eps = 1e-9 * max(self.dx_m, self.dy_m)
        jj = np.nonzero((x >= x_range_m[0] - eps) & (x <= x_range_m[1] + eps))[0]
        ii = np.nonzero((y >= y_range_m[0] - eps) & (y <= y_range_m[1] + eps))[0]
        if len(jj) < 2 or len(ii) < 2:
            raise InputError(
                self.name or "<heightfield>",
                "a crop window holding at least 2 x 2 nodes",
                column="x_range_m/y_range_m",
                got=(x_range_m, y_range_m),
            )
        return Heightfield(
            self.z_m[ii[0] : ii[-1] + 1, jj[0] : jj[-1] + 1].copy(),
            self.dx_m,
            self.dy_m,
            (float(x[jj[0]]), float(y[ii[0]])),
            self.z_bottom_m,
            self.name,
            dict(self.meta),
        )

    # ------------------------------------------------------------------ C1 interpolation
    @cached_property
    def _cells(self):
        """Per-cell bicubic coefficients and constants for :meth:`evaluate`.

        Returns ``(coef_t, lo, inv, hi, nxc)``. ``coef_t`` is ``(16, cells)``: per cell the 16 monomial
        coefficients ``c[b, a]`` (row ``4 b + a``) of ``t^a u^b`` (``t``, ``u`` in [0, 1] the local cell coordinates
        along x and y). The grid of cells is padded by one ring of *extension cells* that are constant
        across the edge (the edge's 1-D Hermite curve, or the corner value), so that clamping a point into
        ``[-1, n]`` cells implements the documented outside behaviour without masks or branches.
        """
        z = self.z_m
        ny, nx = z.shape
        # Slopes w.r.t. the local coordinates (per node spacing): 2nd-order FD, one-sided at edges.
        eox = 2 if nx >= 3 else 1
        eoy = 2 if ny >= 3 else 1
        ft = np.gradient(z, axis=1, edge_order=eox)
        fu = np.gradient(z, axis=0, edge_order=eoy)
        ftu = np.gradient(ft, axis=0, edge_order=eoy)
        # F[a, b] per cell: a over (t=0, t=1, d/dt at 0, d/dt at 1), b likewise for u.
        F = np.empty((ny - 1, nx - 1, 4, 4))
        for a, (dj, src_t) in enumerate([(0, 0), (1, 0), (0, 1), (1, 1)]):
            for b, (di, src_u) in enumerate([(0, 0), (1, 0), (0, 1), (1, 1)]):
                src = (z, fu, ft, ftu)[src_t * 2 + src_u]
                F[:, :, a, b] = src[di : di + ny - 1, dj : dj + nx - 1]
        # C = M F M^T per cell (C[p, q]: coefficient of t^p u^q) as one GEMM with kron(M, M); stored
        # transposed, [u power, t power].
        C = (F.reshape(-1, 16) @ np.kron(_HERMITE, _HERMITE).T).reshape(ny - 1, nx - 1, 4, 4)
        C = np.swapaxes(C, -1, -2)  # [cell row, cell col, u power, t power]
        P = np.zeros((ny + 1, nx + 1, 4, 4))
        P[1:-1, 1:-1] = C
        P[1:-1, 0, :, 0] = C[:, 0, :, 0]  # left: the curve at t = 0, constant in t
        P[1:-1, -1, :, 0] = C[:, -1].sum(axis=2)  # right: the curve at t = 1
        P[0, 1:-1, 0, :] = C[0, :, 0, :]  # bottom: the curve at u = 0, constant in u
        P[-1, 1:-1, 0, :] = C[-1].sum(axis=1)  # top: the curve at u = 1
        P[0, 0, 0, 0], P[0, -1, 0, 0], P[-1, 0, 0, 0], P[-1, -1, 0, 0] = z[0, 0], z[0, -1], z[-1, 0], z[-1, -1]
        coef_t = np.ascontiguousarray(P.reshape(-1, 16).T)  # (16, cells): a gather gives (16, points)
        # Local coordinate s = (x - x0)/dx + 1 in padded cells; clamp into [0, n + 1) (n + 1 - tiny keeps
        # the cell index in range: at most 1e-9 of a cell off on the far outside edge).
        lo = np.array([[self.origin_m[0] - self.dx_m], [self.origin_m[1] - self.dy_m]])
        inv = np.array([[1.0 / self.dx_m], [1.0 / self.dy_m]])
        hi = np.array([[nx + 1.0 - 1e-9], [ny + 1.0 - 1e-9]])
        return coef_t, lo, inv, hi, nx + 1

    @cached_property
    def _horner(self):
        """The coefficients of :attr:`_cells` as :meth:`surface_at` reads them: ``(7, 4, cells)``, rows
        ``c[3], c[3], c[2], 2 c[2], c[1], c[1], c[0]`` (``c[b][a]``: coefficient of ``t^a u^b``), so that one gather
        serves the Horner recurrences of ``q_a(u)`` and ``q_a'(u)`` at once (``2 c[2]`` is exact)."""
        c = self._cells[0].reshape(4, 4, -1)
        return np.ascontiguousarray(np.stack([c[3], c[3], c[2], 2.0 * c[2], c[1], c[1], c[0]]))

    def locate(self, xy_m: np.ndarray):
        """Padded cells and local coordinates of points ``xy_m`` ``(2, n)`` (m): ``(cell, s, k)`` with ``s`` the
        clamped padded-grid coordinates ``(2, n)`` and ``k`` their integer parts (the cell is ``k[1] nxc + k[0]``);
        ``s - k`` are the local coordinates ``(t, u)`` in [0, 1] that :meth:`surface_at` takes."""
        _, lo, inv, hi, nxc = self._cells
        s = np.subtract(xy_m, lo)
        s *= inv
        np.maximum(s, 0.0, out=s)
        np.minimum(s, hi, out=s)
        k = s.astype(np.intp)
        cell = k[1] * nxc
        cell += k[0]
        return cell, s, k

    def surface_at(self, cell: np.ndarray, tu3: np.ndarray) -> np.ndarray:
        """``[z_m, dzdx, dzdy]`` ``(3, n)`` of the C1 surface at local coordinates ``tu3 = (t, u, 3 t, 3 u)``
        ``(4, n)`` in the padded cells ``cell`` (see :meth:`locate`); the operations of :meth:`evaluate`."""
        inv = self._cells[2]
        c = self._horner.take(cell, axis=2)  # (7, 4, n)
        t, u = tu3[0], tu3[1]
        # [q_a(u), q_a'(u)] = [sum_b c[b, a] u^b, its derivative], for the 4 powers a of t at once (Horner in u)
        w = np.multiply(c[0:2], tu3[1::2, None])  # [c3 u, c3 (3 u)]
        w += c[2:4]
        w *= u
        w += c[4:6]
        q = w[0]
        q *= u
        q += c[6]
        # z (from q) and dz/du (from q') share the Horner recurrence in t: rows 0 and 2 of the result
        out = np.empty((3, t.size))
        r = np.multiply(w[:, 3], t, out=out[0::2])
        r += w[:, 2]
        r *= t
        r += w[:, 1]
        r *= t
        r += w[:, 0]
        dzt = np.multiply(q[3], tu3[2], out=out[1])
        dzt += 2.0 * q[2]
        dzt *= t
        dzt += q[1]
        out[1:] *= inv  # dz/dt / dx, dz/du / dy
        return out

    def evaluate(self, x_m, y_m):
        """Height and slopes of the C1 surface at points ``(x_m, y_m)`` (m, arrays of one shape).

        Returns ``(z_m, dzdx, dzdy)``, arrays of the input shape (slopes dimensionless, m/m).

        Outside the grid the surface is extended as a constant across the edge: the point is clamped
        onto the grid, the slope across the edge it passed is 0 and the slope along the edge is kept.
        The high edges themselves (``x = x_max``, ``y = y_max``) belong to the extension (slope across 0
        exactly there); the low edges belong to the grid.
        Cost: about 30 NumPy calls on arrays of the input size (no Python loop); :meth:`locate` and
        :meth:`surface_at` are its two halves.
        """
        x = np.asarray(x_m, dtype=np.float64)
        y = np.asarray(y_m, dtype=np.float64)
        shape = x.shape if x.shape == y.shape else np.broadcast_shapes(x.shape, y.shape)
        n = math.prod(shape)
        xy = np.empty((2, n))
        xy[0] = x.ravel() if x.shape == shape else np.broadcast_to(x, shape).ravel()
        xy[1] = y.ravel() if y.shape == shape else np.broadcast_to(y, shape).ravel()
        cell, s, k = self.locate(xy)
        tu3 = np.empty((4, n))
        np.subtract(s, k, out=tu3[:2])
        np.multiply(tu3[:2], 3.0, out=tu3[2:])
        z = self.surface_at(cell, tu3)
        return z[0].reshape(shape), z[1].reshape(shape), z[2].reshape(shape)

    def normal(self, x_m, y_m) -> np.ndarray:
        """Upward unit normals ``(..., 3)`` of the C1 surface at ``(x_m, y_m)`` (m)."""
        _, zx, zy = self.evaluate(x_m, y_m)
        n = np.stack([-zx, -zy, np.ones_like(zx)], axis=-1)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        return n

    # ------------------------------------------------------------------ persistence
    def to_npz(self, path: str | Path) -> Path:
        """Write to ``path`` (.npz, uncompressed) atomically; returns the path."""
        path = Path(path)
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez(
                fh,
                z_m=self.z_m,
                dx_m=self.dx_m,
                dy_m=self.dy_m,
                origin_m=np.array(self.origin_m),
                z_bottom_m=self.z_bottom_m,
                name=np.array(self.name),
                meta_json=np.array(json.dumps(self.meta, sort_keys=True, default=_json_default)),
                format=np.array("skidsim.heightfield/1"),
            )
        return path

    @classmethod
    def from_npz(cls, path: str | Path) -> Heightfield:
        """Read a file written by :meth:`to_npz`; bad content raises :class:`InputError` naming the field."""
        path = Path(path)
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise InputError(path, "a readable .npz heightfield", got=str(exc)) from None
        with data:
            need = ("z_m", "dx_m", "dy_m", "origin_m", "z_bottom_m")
            for key in need:
                if key not in data.files:
                    raise InputError(path, "an array named " + key, column=key, got="missing")
            origin = np.asarray(data["origin_m"], dtype=float)
            if origin.shape != (2,):
                raise InputError(path, "origin_m of shape (2,)", column="origin_m", got=origin.shape)
            meta = json.loads(str(data["meta_json"])) if "meta_json" in data.files else {}
            name = str(data["name"]) if "name" in data.files else path.stem
            z = np.asarray(data["z_m"])
            if z.ndim != 2:
                raise InputError(path, "a 2-D array z_m", column="z_m", got=z.shape)
            return cls(
                z,
                float(data["dx_m"]),
                float(data["dy_m"]),
                (float(origin[0]), float(origin[1])),
                float(data["z_bottom_m"]),
                name,
                meta,
            )


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o)}")
