"""Geometry files for viewers and meshers: binary STL, gmsh .msh (format 2.2) and VTU (ParaView) of the pavement,
VTU of the slider; in **mm** by default (``unit="m"`` writes metres), each written atomically
(:mod:`skidsim.atomic`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from skidsim.atomic import atomic_path, write_bytes
from skidsim.errors import InputError, SkidsimError
from skidsim.reconstruct import Heightfield
from skidsim.slidermesh import SliderMesh

from .geometry import pavement_hex_mesh, pavement_surface_mesh

#: lengths of the geometry files per metre, by ``unit``
_UNIT_SCALE = {"mm": 1e3, "m": 1.0}


def _scale(unit: str) -> float:
    if unit not in _UNIT_SCALE:
        raise InputError(None, "unit 'mm' or 'm'", column="unit", got=unit)
    return _UNIT_SCALE[unit]


#: one binary STL record: unit normal, three corners (float32), attribute byte count
_STL_RECORD = np.dtype([("normals", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")])


def stl_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary STL of a triangle mesh: an 80-byte zero header, the face count, per face its unit normal and its
    corners as float32. The bytes trimesh (4, 5) writes for ``Trimesh(vertices, faces, process=False)``: the same
    normals (cross product of the first two edges, unitised as ``trimesh.util.unitize``, zero for a degenerate
    face; tests/test_exports.py compares the files), without importing trimesh (0.4 s per reconstruct job)."""
    v = np.asarray(vertices, dtype=np.float64, order="C")
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    edges = tri[:, 1:, :] - tri[:, :2, :]
    cross = np.cross(edges[:, 0], edges[:, 1])
    norm = np.sqrt(np.dot(cross * cross, [1.0] * 3))
    valid = norm > float(np.finfo(np.float64).resolution * 100)
    norm[valid] **= -1
    normals = cross * norm.reshape((-1, 1))
    normals[~valid] = 0.0
    header = np.zeros(1, dtype=np.dtype([("header", np.void, 80), ("face_count", "<u4")]))
    header["face_count"] = len(f)
    packed = np.zeros(len(f), dtype=_STL_RECORD)
    packed["normals"] = normals
    packed["vertices"] = tri
    return header.tobytes() + packed.tobytes()


def is_watertight(faces: np.ndarray) -> bool:
    """Whether every edge of a triangle mesh is shared by exactly two faces (trimesh's ``is_watertight``)."""
    f = np.asarray(faces, dtype=np.int64)
    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(len(f) > 0 and (counts == 2).all())


def write_stl(hf: Heightfield, path: str | Path, unit: str = "mm") -> Path:
    """Write the pavement solid as a watertight binary STL (:func:`stl_bytes`), lengths in ``unit``; returns the
    path."""
    s = _scale(unit)
    v, f = pavement_surface_mesh(hf)
    if not is_watertight(f):
        raise SkidsimError(f"{hf.name or 'heightfield'}: pavement surface mesh is not watertight")
    return write_bytes(path, stl_bytes(v * s, f))


def write_vtu_pavement(hf: Heightfield, path: str | Path, layers: int = 1, unit: str = "mm") -> Path:
    """Write the pavement solid as hexahedra to a VTU file (meshio), with point data ``height_mm``."""
    import meshio

    s = _scale(unit)
    pts, hexes = pavement_hex_mesh(hf, layers)
    mesh = meshio.Mesh(pts * s, [("hexahedron", hexes)], point_data={"height_mm": pts[:, 2] * 1e3})
    path = Path(path)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return path


def write_vtu_slider(
    mesh: SliderMesh,
    path: str | Path,
    point_data: dict | None = None,
    displacement_m: np.ndarray | None = None,
    unit: str = "mm",
) -> Path:
    """Write the slider hex mesh to VTU (meshio); ``point_data`` arrays have ``n_nodes`` rows.

    ``displacement_m`` (``(n_nodes, 3)`` m, optional) moves the points to the deformed configuration and
    is also stored as point data ``displacement_m``.
    """
    import meshio

    s = _scale(unit)
    pts = mesh.points.copy()
    data = {}
    for name, arr in (point_data or {}).items():
        arr = np.asarray(arr)
        if arr.shape[0] != mesh.n_nodes:
            raise InputError(
                None, f"{mesh.n_nodes} rows (one per slider node)", column=f"point_data[{name!r}]", got=arr.shape
            )
        data[name] = arr
    if displacement_m is not None:
        u = np.asarray(displacement_m, dtype=float)
        if u.shape != pts.shape:
            raise InputError(None, f"shape {pts.shape}", column="displacement_m", got=u.shape)
        pts = pts + u
        data["displacement_m"] = u
    m = meshio.Mesh(pts * s, [("hexahedron", mesh.connectivity)], point_data=data)
    path = Path(path)
    with atomic_path(path) as tmp:
        meshio.write(tmp, m, file_format="vtu")
    return path


def write_gmsh(hf: Heightfield, path: str | Path, layers: int = 4, unit: str = "mm", stride: int = 1) -> Path:
    """Write a hexahedral volume mesh of the pavement solid to a gmsh .msh (format 4.1) via the gmsh API.

    The structured mesh of :func:`pavement_hex_mesh` (``layers`` through the thickness; ``stride`` > 1 keeps
    every ``stride``-th node of the heightfield for a coarser mesh) becomes a discrete gmsh volume with a
    discrete top surface (quads). Physical groups: volume ``pavement`` (tag 1), surface ``top`` (tag 2).
    """
    import gmsh

    s = _scale(unit)
    if int(stride) < 1:
        raise InputError(None, "a positive integer", column="stride", got=stride)
    sub = hf
    if stride > 1:
        z = hf.z_m[::stride, ::stride]
        sub = Heightfield(z, hf.dx_m * stride, hf.dy_m * stride, hf.origin_m, hf.z_bottom_m, hf.name, hf.meta)
    pts, hexes = pavement_hex_mesh(sub, layers)
    ny, nx = sub.shape
    ntop = (ny - 1) * (nx - 1)
    top_quads = hexes[-ntop:, 4:8]
    path = Path(path)
    with atomic_path(path, suffix=".msh") as tmp:
        gmsh.initialize(interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.model.add(hf.name or "pavement")
            vol = gmsh.model.addDiscreteEntity(3)
            srf = gmsh.model.addDiscreteEntity(2)
            gmsh.model.mesh.addNodes(3, vol, np.arange(1, len(pts) + 1), (pts * s).ravel())
            gmsh.model.mesh.addElementsByType(vol, 5, np.arange(1, len(hexes) + 1), (hexes + 1).ravel())
            gmsh.model.mesh.addElementsByType(
                srf, 3, np.arange(len(hexes) + 1, len(hexes) + ntop + 1), (top_quads + 1).ravel()
            )
            gmsh.model.addPhysicalGroup(3, [vol], 1, name="pavement")
            gmsh.model.addPhysicalGroup(2, [srf], 2, name="top")
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.option.setNumber("Mesh.Binary", 0)
            gmsh.write(str(tmp))
        finally:
            gmsh.finalize()
    return path
