"""Pavement reconstruction: a scan strip turned into the rigid FE heightfield of the DFT model.

The study (Section 3, Fig. 7) cut a 114.3 x 40 mm strip of the LS-40 scan, smoothed it "before meshing" and
meshed it at 0.5 mm as a rigid 114.3 x 40 x 8 mm body. :func:`pavement_strip` does the same, with every
choice explicit (see ``docs/reconstruction.md``):

1. **Position** (scan coordinates, mm; point ``(i, j)`` of the scan at ``x = j dx, y = i dy``): the strip's
   nodes span ``[x0, x0 + length] x [y0, y0 + width]``. Default: centred on the scan.
2. **Smoothing**: ISO 16610-61 Gaussian low-pass applied on the scan grid, cutoff wavelength ``smoothing``
   (mm; default ``"nyquist"`` = 2 x resolution, the shortest wavelength the FE grid can carry). It plays the
   role of the study's unspecified surface smoothing: it removes the sub-grid content that would alias into
   the 0.5 mm grid and the sharp angles that make contact normals jump.
3. **Resampling** by exact area averaging: each FE node gets the mean of the scan over the
   ``hx x hy`` box centred on it, the scan being piecewise constant on its pixels (pixel ``j`` covers
   ``[(j - 1/2) dx, (j + 1/2) dx]``). When the box is an integer number of pixels aligned with pixel edges
   this is exactly the block mean. Boxes of edge nodes are clipped to the scanned area.
   The node spacing is ``length / round(length / resolution)`` (0.49913 mm for 114.3 mm at 0.5 mm) so that
   the strip is exactly ``length`` long.
4. **Levelling** (default on): the least-squares mean plane of the resampled strip is removed, so ``z = 0``
   is the strip's mean plane and the surface has no tilt along the sliding direction. The solver places
   the slider relative to :attr:`Heightfield.max_height_m`.
5. **Units**: the :class:`Heightfield` is SI (metres), in the FE frame: node ``(i, j)`` at
   ``x = origin_x + j dx_m``, ``y = origin_y + i dy_m``, origin ``(0, 0)`` at the strip's first node
   (x = sliding direction). The scan position is kept in ``meta``.
6. **Solid**: the heightfield on top of a flat bottom at ``z_bottom_m = min(z) - base_depth`` (8 mm by
   default), so the solid is at least ``base_depth`` thick under the deepest valley.

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

from .atomic import atomic_path
from .errors import ConfigError, InputError
from .options import section_items
from .surface import Surface

#: ISO 16610-61 Gaussian constant alpha = sqrt(ln 2 / pi): 50 % transmission at the cutoff wavelength.
ISO_GAUSS_ALPHA = math.sqrt(math.log(2.0) / math.pi)

# Hermite-to-monomial matrix: p(t) = [1 t t^2 t^3] . M . [p0, p1, p0', p1'].
_HERMITE = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-3.0, 3.0, -2.0, -1.0], [2.0, -2.0, 1.0, 1.0]])


def gaussian_sigma_mm(cutoff_mm: float) -> float:
    """Standard deviation (mm) of the ISO 16610-61 Gaussian weighting function of cutoff ``cutoff_mm``.

    ``s(x) = exp(-pi (x / (alpha lc))^2) / (alpha lc)`` is a normal density with
    ``sigma = alpha lc / sqrt(2 pi) = 0.1874 lc``; its amplitude transmission at wavelength ``lambda`` is
    ``exp(-pi (alpha lc / lambda)^2)``, 50 % at ``lambda = lc``.
    """
    return ISO_GAUSS_ALPHA * float(cutoff_mm) / math.sqrt(2.0 * math.pi)


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


# ---------------------------------------------------------------------- resampling
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


#: the study's strip length (mm): the DFT slider's path, ``mesh.length_mm`` by default
STUDY_STRIP_LENGTH_MM = 114.3


@dataclass(frozen=True)
class MeshOptions:
    """The FE pavement strip and its exports (config keys under ``mesh:``).

    length_mm, width_mm: strip size in mm along x (the sliding direction) and y (the study's 114.3 x 40;
    ``length_mm="auto"``: see :func:`strip_length_mm`); x0_mm, y0_mm: strip origin on the scan in mm (None:
    centred); resolution_mm: node spacing of the rigid pavement in mm (area-averaged); smoothing: Gaussian cutoff
    in mm applied before resampling, ``"nyquist"`` (2 x resolution_mm) or None; base_depth_mm: solid below the
    lowest point in mm; gmsh_layers: hexahedral layers through the pavement of the gmsh .msh; inp_speed_kmh:
    sliding speed in km/h written into the dynamic CalculiX/ABAQUS decks.
    """

    length_mm: float | str = STUDY_STRIP_LENGTH_MM
    width_mm: float = 40.0
    x0_mm: float | None = None
    y0_mm: float | None = None
    resolution_mm: float = 0.5
    smoothing: float | str | None = "nyquist"
    base_depth_mm: float = 8.0
    gmsh_layers: int = 4
    inp_speed_kmh: float = 20.0

    def __post_init__(self) -> None:
        def bad(key, expected):
            raise ConfigError(f"mesh.{key}: expected {expected}, got {getattr(self, key)!r}")

        def positive(v):
            return isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0

        if not (self.length_mm == "auto" or positive(self.length_mm)):
            bad("length_mm", "a length > 0 mm or 'auto'")
        for key in ("width_mm", "resolution_mm", "base_depth_mm", "inp_speed_kmh"):
            if not positive(getattr(self, key)):
                bad(key, "a number > 0")
        for key in ("x0_mm", "y0_mm"):
            v = getattr(self, key)
            if v is not None and not (isinstance(v, (int, float)) and v >= 0):
                bad(key, "null (centred) or a coordinate >= 0 mm")
        if not (self.smoothing in ("nyquist", None) or positive(self.smoothing)):
            bad("smoothing", "'nyquist', null or a cutoff > 0 mm")
        if not (isinstance(self.gmsh_layers, int) and self.gmsh_layers >= 1):
            bad("gmsh_layers", "an integer >= 1")

    @classmethod
    def from_dict(cls, d: dict | None) -> MeshOptions:
        """From the ``mesh:`` config block; an unknown key raises :class:`ConfigError`."""
        d = section_items(cls, d, "mesh")
        return cls(**d)

    def strip_kwargs(self) -> dict:
        """Keyword arguments of :func:`pavement_strip` (the strip geometry, resolution and smoothing)."""
        return dict(
            length_mm=self.length_mm,
            width_mm=self.width_mm,
            x0_mm=self.x0_mm,
            y0_mm=self.y0_mm,
            resolution_mm=self.resolution_mm,
            smoothing=self.smoothing,
            base_depth_mm=self.base_depth_mm,
        )


def strip_length_mm(surface: Surface, length_mm: float | str, x0_mm: float | None = None) -> float:
    """The strip length in mm: ``length_mm`` itself, or for ``"auto"`` the scan's length along x from ``x0_mm``
    (the whole scan when None) up to the study's 114.3 mm."""
    if isinstance(length_mm, str):
        if length_mm != "auto":
            raise InputError(
                surface.name or "<surface>", "a strip length in mm or 'auto'", column="length_mm", got=length_mm
            )
        return min(STUDY_STRIP_LENGTH_MM, surface.width_mm - (x0_mm or 0.0))
    return float(length_mm)


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


def pavement_strip(
    surface: Surface,
    length_mm: float | str = MeshOptions.length_mm,
    width_mm: float = MeshOptions.width_mm,
    x0_mm: float | None = MeshOptions.x0_mm,
    y0_mm: float | None = MeshOptions.y0_mm,
    resolution_mm: float = MeshOptions.resolution_mm,
    smoothing: float | str | None = MeshOptions.smoothing,
    base_depth_mm: float = MeshOptions.base_depth_mm,
    level: bool = True,
) -> Heightfield:
    """Cut, smooth, resample and level a strip of ``surface`` into the FE :class:`Heightfield` (SI).

    Parameters
    ----------
    surface:
        Despeckled, gap-filled scan (heights mm, no NaN inside the strip and its smoothing margin).
    length_mm, width_mm:
        Strip size along x (sliding direction) and y, mm (study: 114.3 x 40). ``length_mm="auto"``: the scan's
        length (from ``x0_mm``, or all of it) up to 114.3 mm, so a scan a little shorter than the study's strip
        still gives a pavement (:func:`strip_length_mm`); the solver then shortens the slide to fit.
    x0_mm, y0_mm:
        Scan coordinates (mm, ``x = j dx``) of the strip's first node; ``None`` centres the strip.
    resolution_mm:
        Target node spacing (mm); the actual spacing is ``length / round(length / resolution)``.
    smoothing:
        ISO 16610-61 Gaussian cutoff wavelength in mm applied to the scan before resampling;
        ``"nyquist"`` (default) = ``2 * resolution_mm``; ``None`` or 0 = no smoothing.
    base_depth_mm:
        Thickness (mm) of solid under the lowest point: ``z_bottom = min(z) - base_depth``.
    level:
        Remove the least-squares mean plane of the strip (z = 0 is its mean plane). If False, heights keep
        the scan's datum.
    """
    where = surface.name or "<surface>"
    length_mm = strip_length_mm(surface, length_mm, x0_mm)
    for nm, v in (
        ("length_mm", length_mm),
        ("width_mm", width_mm),
        ("resolution_mm", resolution_mm),
        ("base_depth_mm", base_depth_mm),
    ):
        if not (np.isfinite(v) and v > 0):
            raise InputError(where, "a positive length in mm", column=nm, got=v)
    nx_cells = max(1, int(round(length_mm / resolution_mm)))
    ny_cells = max(1, int(round(width_mm / resolution_mm)))
    hx = length_mm / nx_cells
    hy = width_mm / ny_cells
    W, H = surface.width_mm, surface.height_mm
    if x0_mm is None:
        x0_mm = 0.5 * (W - length_mm)
    if y0_mm is None:
        y0_mm = 0.5 * (H - width_mm)
    tol = 1e-9 * max(W, H, 1.0)
    if x0_mm < -tol or x0_mm + length_mm > W + tol:
        hint = (
            f"the scan is {length_mm - W:.4g} mm shorter than the {length_mm:g} mm strip: give a longer scan, "
            "or length_mm='auto' for a strip of the scan's length"
            if length_mm > W + tol
            else None
        )
        raise InputError(
            where,
            f"a strip x range inside the scan's [0, {W:.4g}] mm",
            column="x0_mm",
            got=(round(x0_mm, 6), round(x0_mm + length_mm, 6)),
            hint=hint,
        )
    if y0_mm < -tol or y0_mm + width_mm > H + tol:
        raise InputError(
            where, f"a strip y range inside the scan's [0, {H:.4g}] mm", column="y0_mm", got=(y0_mm, y0_mm + width_mm)
        )
    if isinstance(smoothing, str):
        if smoothing != "nyquist":
            raise InputError(where, "smoothing 'nyquist', a cutoff in mm, or None", column="smoothing", got=smoothing)
        cutoff_mm = 2.0 * resolution_mm
    else:
        cutoff_mm = float(smoothing) if smoothing else 0.0
        if cutoff_mm < 0 or not np.isfinite(cutoff_mm):
            raise InputError(where, "a non-negative smoothing cutoff in mm", column="smoothing", got=smoothing)
    xn = x0_mm + hx * np.arange(nx_cells + 1)
    yn = y0_mm + hy * np.arange(ny_cells + 1)
    dx, dy = surface.dx, surface.dy
    sig = gaussian_sigma_mm(cutoff_mm) if cutoff_mm > 0 else 0.0
    # Source window: node boxes plus the Gaussian's 4-sigma support, within the scan.
    mx, my = 0.5 * hx + 4.0 * sig + dx, 0.5 * hy + 4.0 * sig + dy
    j0 = max(0, int(math.floor((xn[0] - mx) / dx)))
    j1 = min(surface.shape[1], int(math.ceil((xn[-1] + mx) / dx)) + 1)
    i0 = max(0, int(math.floor((yn[0] - my) / dy)))
    i1 = min(surface.shape[0], int(math.ceil((yn[-1] + my) / dy)) + 1)
    win = surface.heights[i0:i1, j0:j1]
    bad = ~np.isfinite(win)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(
            where,
            "finite heights in the strip (gap-fill the scan first)",
            column="heights",
            got=f"{int(bad.sum())} NaN, first at row {i0 + r}, col {j0 + c}",
        )
    if sig > 0:
        win = _gaussian_reflect(win, (sig / dy, sig / dx), truncate=4.0)
    z_mm = resample_area(win, dx, dy, xn - j0 * dx, yn - i0 * dy, hx, hy)
    xl = hx * np.arange(nx_cells + 1)
    yl = hy * np.arange(ny_cells + 1)
    plane = np.zeros(3)
    if level:
        z_mm, plane = remove_mean_plane(z_mm, xl, yl)
    z_m = z_mm * 1e-3
    meta = {
        "source": surface.name,
        "x0_mm": float(x0_mm),
        "y0_mm": float(y0_mm),
        "length_mm": float(length_mm),
        "width_mm": float(width_mm),
        "resolution_mm": float(resolution_mm),
        "dx_mm": hx,
        "dy_mm": hy,
        "smoothing_cutoff_mm": cutoff_mm,
        "smoothing_sigma_mm": sig,
        "smoothing_kernel": "ISO 16610-61 Gaussian",
        "resampling": "area average",
        "levelled": bool(level),
        "removed_plane_mm": {"a_mm": float(plane[0]), "b_mm_per_mm": float(plane[1]), "c_mm_per_mm": float(plane[2])},
        "base_depth_mm": float(base_depth_mm),
    }
    return Heightfield(
        z_m, hx * 1e-3, hy * 1e-3, (0.0, 0.0), float(z_m.min()) - base_depth_mm * 1e-3, surface.name, meta
    )
