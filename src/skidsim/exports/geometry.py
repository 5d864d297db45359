"""The pavement solid of a heightfield (m): its triangulated top surface and its hexahedral meshes, and their
volumes. The heightfield's nodes sit on top of a flat bottom at ``Heightfield.z_bottom_m``; the triangulated top
splits each cell along the (i, j)-(i+1, j+1) diagonal, the hexahedral meshes have bilinear top faces through the
same nodes (docs/reconstruction.md)."""

from __future__ import annotations

import numpy as np

from skidsim.errors import InputError
from skidsim.reconstruct import Heightfield


def pavement_surface_mesh(hf: Heightfield) -> tuple[np.ndarray, np.ndarray]:
    """Closed triangle mesh of the pavement solid: ``(vertices (N, 3) m, faces (M, 3) int)``.

    Top: the node grid, two triangles per cell. Sides: each boundary segment of the top joined to the
    bottom by two triangles. Bottom: a fan from the bottom centre over the bottom boundary vertices.
    Faces are oriented outwards (counter-clockwise seen from outside).
    """
    ny, nx = hf.shape
    X, Y = np.meshgrid(hf.x_m(), hf.y_m())
    top = np.column_stack([X.ravel(), Y.ravel(), hf.z_m.ravel()])
    tid = np.arange(ny * nx).reshape(ny, nx)
    a = tid[:-1, :-1].ravel()
    b = tid[:-1, 1:].ravel()
    c = tid[1:, 1:].ravel()
    d = tid[1:, :-1].ravel()
    faces = [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    # Boundary loop of the top grid, counter-clockwise seen from +z.
    loop = np.concatenate([tid[0, :-1], tid[:-1, -1], tid[-1, :0:-1], tid[:0:-1, 0]])
    nb = len(loop)
    bot = top[loop].copy()
    bot[:, 2] = hf.z_bottom_m
    boff = len(top)
    bid = boff + np.arange(nb)
    centre = np.array([[0.5 * (hf.extent[0] + hf.extent[1]), 0.5 * (hf.extent[2] + hf.extent[3]), hf.z_bottom_m]])
    cid = boff + nb
    nxt = np.roll(np.arange(nb), -1)
    # Side quads (top k -> top k+1 -> bottom k+1 -> bottom k) oriented outwards.
    faces.append(np.column_stack([loop, bid, bid[nxt]]))
    faces.append(np.column_stack([loop, bid[nxt], loop[nxt]]))
    # Bottom fan, clockwise seen from +z (outward normal -z).
    faces.append(np.column_stack([np.full(nb, cid), bid[nxt], bid]))
    verts = np.vstack([top, bot, centre])
    return verts, np.vstack(faces).astype(np.int64)


def triangulated_volume_m3(hf: Heightfield) -> float:
    """Exact volume (m^3) of :func:`pavement_surface_mesh` (piecewise-linear top, same diagonals)."""
    h = hf.z_m - hf.z_bottom_m
    a, b, c, d = h[:-1, :-1], h[:-1, 1:], h[1:, 1:], h[1:, :-1]
    return float((hf.dx_m * hf.dy_m / 6.0) * np.sum(2 * a + b + 2 * c + d))


def pavement_hex_mesh(hf: Heightfield, layers: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Hexahedral mesh of the pavement solid: ``(points (N, 3) m, hexes (M, 8))`` in C3D8/VTK order.

    ``layers`` elements through the thickness, nodes equally spaced between ``z_bottom_m`` and the surface
    at each (x, y). Node id ``(k * ny + i) * nx + j`` (layer k, row i = y, column j = x); element ids in C
    order of ``(layer, row, column)``; the top layer's elements are the last ``(ny-1)(nx-1)``, whose face
    S2 (local nodes 5-8) lies on the surface.
    """
    if int(layers) < 1:
        raise InputError(None, "at least one element layer", column="layers", got=layers)
    layers = int(layers)
    ny, nx = hf.shape
    X, Y = np.meshgrid(hf.x_m(), hf.y_m())
    frac = np.arange(layers + 1) / layers
    Z = hf.z_bottom_m + frac[:, None, None] * (hf.z_m - hf.z_bottom_m)[None]
    pts = np.column_stack([np.broadcast_to(X, Z.shape).ravel(), np.broadcast_to(Y, Z.shape).ravel(), Z.ravel()])
    nid = np.arange(pts.shape[0]).reshape(layers + 1, ny, nx)
    k, i, j = np.meshgrid(np.arange(layers), np.arange(ny - 1), np.arange(nx - 1), indexing="ij")
    k, i, j = k.ravel(), i.ravel(), j.ravel()
    hexes = np.column_stack(
        [
            nid[k, i, j],
            nid[k, i, j + 1],
            nid[k, i + 1, j + 1],
            nid[k, i + 1, j],
            nid[k + 1, i, j],
            nid[k + 1, i, j + 1],
            nid[k + 1, i + 1, j + 1],
            nid[k + 1, i + 1, j],
        ]
    )
    return pts, hexes


def hex_volumes(points: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Volumes of trilinear hexahedra (C3D8 order) by 2x2x2 Gauss quadrature of det J (exact)."""
    g = 1.0 / np.sqrt(3.0)
    corners = np.array(
        [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)],
        dtype=float,
    )
    P = points[hexes]  # (M, 8, 3)
    vol = np.zeros(len(hexes))
    for xi in (-g, g):
        for eta in (-g, g):
            for ze in (-g, g):
                q = np.array([xi, eta, ze])
                # dN/dxi_k for the 8 nodes: N = prod (1 + c q)/8
                f = 1.0 + corners * q  # (8, 3)
                dN = np.empty((8, 3))
                dN[:, 0] = corners[:, 0] * f[:, 1] * f[:, 2] / 8
                dN[:, 1] = corners[:, 1] * f[:, 0] * f[:, 2] / 8
                dN[:, 2] = corners[:, 2] * f[:, 0] * f[:, 1] / 8
                J = np.einsum("mna,nb->mab", P, dN)  # (M, 3 coords, 3 params)
                vol += np.linalg.det(J)
    return vol
