"""Structured hexahedral mesh of the DFT rubber slider (20 x 16 x 6 mm by default).

The mesh is a box of ``nx * ny * nz`` identical brick elements. Its data layout is the design of the solver
kernel (cf. LLNL LULESH): nodal arrays have shape ``(3, nx+1, ny+1, nz+1)`` (component first, C order), so
the 8 corner nodes of all elements are 8 array *slices* and the internal-force kernel needs neither a
per-element loop nor a general gather/scatter.

Units: lengths in **metres** here (the solver is SI). Node ``(i, j, k)`` is at
``(x0 + i*hx, y0 + j*hy, z0 + k*hz)``; ``k = 0`` is the bottom (contact) face. x is the sliding direction.

Local node numbering of a hexahedron (ABAQUS/CalculiX C3D8 order)::

    0:(0,0,0) 1:(1,0,0) 2:(1,1,0) 3:(0,1,0) 4:(0,0,1) 5:(1,0,1) 6:(1,1,1) 7:(0,1,1)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

# (di, dj, dk) offsets of the 8 local nodes, C3D8 order.
HEX_CORNERS = np.array(
    [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)], dtype=int
)


@dataclass(frozen=True)
class SliderMesh:
    """A structured box mesh of identical hexahedra.

    Attributes
    ----------
    nx, ny, nz: number of elements along x (sliding direction), y, z.
    hx, hy, hz: element edge lengths in m.
    origin: ``(x0, y0, z0)`` of node (0, 0, 0) in m.
    """

    nx: int
    ny: int
    nz: int
    hx: float
    hy: float
    hz: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def box(
        cls,
        length_mm: float = 20.0,
        width_mm: float = 16.0,
        thickness_mm: float = 6.0,
        element_mm: float = 0.5,
        origin_m=(0.0, 0.0, 0.0),
    ) -> SliderMesh:
        """Mesh a ``length x width x thickness`` (mm) box with elements close to ``element_mm``.

        The number of elements along each edge is ``max(1, round(edge / element_mm))``; the element edge is
        then ``edge / n`` (so elements may be slightly non-cubic when the size does not divide the edge).
        """
        if element_mm <= 0:
            raise ValueError(f"element size must be positive mm, got {element_mm}")
        n = [max(1, int(round(e / element_mm))) for e in (length_mm, width_mm, thickness_mm)]
        h = [e * 1e-3 / k for e, k in zip((length_mm, width_mm, thickness_mm), n)]
        return cls(n[0], n[1], n[2], h[0], h[1], h[2], tuple(float(o) for o in origin_m))

    @property
    def n_elements(self) -> int:
        return self.nx * self.ny * self.nz

    @property
    def node_shape(self) -> tuple[int, int, int]:
        return (self.nx + 1, self.ny + 1, self.nz + 1)

    @property
    def n_nodes(self) -> int:
        a, b, c = self.node_shape
        return a * b * c

    @property
    def size_m(self) -> tuple[float, float, float]:
        return (self.nx * self.hx, self.ny * self.hy, self.nz * self.hz)

    @cached_property
    def coordinates(self) -> np.ndarray:
        """Reference nodal coordinates, shape ``(3, nx+1, ny+1, nz+1)`` in m."""
        x = self.origin[0] + self.hx * np.arange(self.nx + 1)
        y = self.origin[1] + self.hy * np.arange(self.ny + 1)
        z = self.origin[2] + self.hz * np.arange(self.nz + 1)
        X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
        return np.stack([X, Y, Z])

    def node_id(self, i, j, k):
        """Flat (0-based) node index of grid node ``(i, j, k)`` in C order of ``node_shape``."""
        _, b, c = self.node_shape
        return (np.asarray(i) * b + np.asarray(j)) * c + np.asarray(k)

    @cached_property
    def connectivity(self) -> np.ndarray:
        """Element-to-node table ``(n_elements, 8)`` of flat 0-based node ids, C3D8 order.

        Elements are numbered in C order of ``(nx, ny, nz)``.
        """
        i, j, k = np.meshgrid(np.arange(self.nx), np.arange(self.ny), np.arange(self.nz), indexing="ij")
        i, j, k = i.ravel(), j.ravel(), k.ravel()
        return np.stack([self.node_id(i + di, j + dj, k + dk) for di, dj, dk in HEX_CORNERS], axis=1)

    @cached_property
    def points(self) -> np.ndarray:
        """Reference coordinates as ``(n_nodes, 3)`` in m, rows ordered by flat node id."""
        return self.coordinates.reshape(3, -1).T.copy()

    def bottom_nodes(self) -> np.ndarray:
        """Flat ids of the contact-face nodes (k = 0), C order of ``(nx+1, ny+1)``."""
        i, j = np.meshgrid(np.arange(self.nx + 1), np.arange(self.ny + 1), indexing="ij")
        return self.node_id(i.ravel(), j.ravel(), 0)

    def top_nodes(self) -> np.ndarray:
        """Flat ids of the loaded face nodes (k = nz)."""
        i, j = np.meshgrid(np.arange(self.nx + 1), np.arange(self.ny + 1), indexing="ij")
        return self.node_id(i.ravel(), j.ravel(), self.nz)

    def nodal_tributary_area_bottom(self) -> np.ndarray:
        """Tributary area (m^2) of each bottom node, shape ``(nx+1, ny+1)``; sums to the face area."""
        wx = np.full(self.nx + 1, self.hx)
        wx[[0, -1]] *= 0.5
        wy = np.full(self.ny + 1, self.hy)
        wy[[0, -1]] *= 0.5
        return np.outer(wx, wy)
