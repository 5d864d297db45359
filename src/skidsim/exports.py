"""Exports of the DFT FE model: STL, gmsh .msh, VTU (ParaView) and ABAQUS/CalculiX .inp; CalculiX runner.

Units (they change numbers; see ``docs/reconstruction.md``):

* Geometry files for viewers and meshers (STL, .msh, VTU) are written in **mm** by default
  (``unit="m"`` writes metres).
* The .inp deck is **SI**: m, N, Pa, kg/m^3, s; so the ABAQUS decay coefficient ``d_c`` equals the
  project's ``alpha`` in s/m.

Pavement solid: the heightfield's nodes on top of a flat bottom at ``Heightfield.z_bottom_m``. The STL top
is the node grid split into two triangles per cell along the (i, j)-(i+1, j+1) diagonal; the hexahedral
meshes (msh, VTU, inp) have bilinear top faces through the same nodes.

Every writer goes through :mod:`skidsim.atomic` (a temporary sibling renamed to the final name at the end).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import atomic_path, write_bytes, write_text
from .errors import InputError, SkidsimError
from .friction import ExponentialDecay, kmh_to_ms
from .reconstruct import Heightfield, MeshOptions
from .slidermesh import SliderMesh

_UNIT_SCALE = {"mm": 1e3, "m": 1.0}

#: Material of the rubber slider (study, Section 3): E in Pa, nu, rho in kg/m^3.
RUBBER = {"E_pa": 100e6, "nu": 0.45, "rho_kg_m3": 1200.0}
#: Nominal DFT load on one slider, N.
DFT_LOAD_N = 11.8


class CalculixError(SkidsimError):
    """CalculiX failed, did not converge, or wrote output that cannot be parsed."""


# ---------------------------------------------------------------------- helpers
def _scale(unit: str) -> float:
    if unit not in _UNIT_SCALE:
        raise InputError(None, "unit 'mm' or 'm'", column="unit", got=unit)
    return _UNIT_SCALE[unit]


# ---------------------------------------------------------------------- pavement geometry
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


# ---------------------------------------------------------------------- STL / VTU / gmsh
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


# ---------------------------------------------------------------------- ABAQUS / CalculiX deck
@dataclass(frozen=True)
class InpDeck:
    """What :func:`write_inp` wrote, for mapping CalculiX results back onto the slider.

    Node ids are 1-based as in the deck. ``slider_node_ids[n]`` is the deck id of ``SliderMesh`` flat node
    ``n``; the deck's slider coordinates are ``slider.points + slider_offset_m`` (m).
    """

    path: Path
    step: str
    dialect: str
    holder: str
    slider_node_ids: np.ndarray
    pavement_node_ids: np.ndarray
    ref_node: int
    slider_offset_m: tuple[float, float, float]
    bottom_node_ids: np.ndarray  # deck ids of the slider's contact-face nodes, SliderMesh.bottom_nodes() order
    bottom_tributary_area_m2: np.ndarray  # per bottom node, same order
    load_n: float
    penalty_pa_per_m: float
    mu_equivalent: float | None = None
    speed_ms: float | None = None
    slide_distance_m: float | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)


def _fmt_rows(ids: np.ndarray, arr: np.ndarray, fmt: str = "%.10e") -> str:
    """``id, v1, v2, ...`` lines, every value in the %-format ``fmt``; one format per row on Python scalars (the
    decks of a 0.5 mm pavement have ~100k node lines)."""
    ids = np.asarray(ids)
    a = np.asarray(arr).reshape(len(ids), -1)
    rowfmt = "%d, " + ", ".join([fmt] * a.shape[1])
    return "\n".join(rowfmt % (i, *row) for i, row in zip(ids.astype(np.int64).tolist(), a.tolist())) + "\n"


def _id_lines(ids, per_line: int = 12) -> str:
    ids = [str(int(i)) for i in ids]
    return "\n".join(", ".join(ids[k : k + per_line]) for k in range(0, len(ids), per_line)) + "\n"


def slider_placement(slider: SliderMesh, hf: Heightfield, center_xy_m=None, overclosure_m: float = 1e-6):
    """Translation (m) that puts the slider's bottom face centre at ``center_xy_m`` (default: the
    heightfield centre) and lowers it until its highest-reaching bottom node is ``overclosure_m`` below
    the faceted (bilinear) pavement surface, i.e. exactly one node just in contact.
    """
    x0, x1, y0, y1 = hf.extent
    if center_xy_m is None:
        center_xy_m = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
    L, W, _ = slider.size_m
    ox = center_xy_m[0] - (slider.origin[0] + 0.5 * L)
    oy = center_xy_m[1] - (slider.origin[1] + 0.5 * W)
    if (
        center_xy_m[0] - 0.5 * L < x0 - 1e-12
        or center_xy_m[0] + 0.5 * L > x1 + 1e-12
        or center_xy_m[1] - 0.5 * W < y0 - 1e-12
        or center_xy_m[1] + 0.5 * W > y1 + 1e-12
    ):
        raise InputError(
            hf.name or None,
            "a slider footprint inside the pavement extent",
            column="center_xy_m",
            got=tuple(center_xy_m),
        )
    b = slider.points[slider.bottom_nodes()]
    zs = hf.bilinear(b[:, 0] + ox, b[:, 1] + oy)
    oz = float(zs.max()) - overclosure_m - slider.origin[2]
    return (float(ox), float(oy), oz)


def write_inp(
    path: str | Path,
    slider: SliderMesh,
    heightfield: Heightfield,
    law: ExponentialDecay,
    load_n: float = DFT_LOAD_N,
    speed_kmh: float = 20.0,
    step: str = "static",
    *,
    dialect: str = "calculix",
    holder: str = "rigid",
    center_xy_m=None,
    slide_distance_m: float | None = None,
    penalty_pa_per_m: float | None = None,
    overclosure_m: float = 1e-6,
    contact: str = "node to surface",
    material: dict | None = None,
    element_type: str = "C3D8R",
    title: str | None = None,
    push_increments: int = 40,
    stick_slope_pa_per_m: float | None = None,
    _shared: dict | None = None,
) -> InpDeck:
    """Write an ABAQUS/CalculiX input deck of the DFT slider on the pavement (SI: m, N, Pa, kg/m^3, s).

    Model: the slider (``SliderMesh``, ``element_type`` C3D8R (study) or C3D8, linear elastic rubber E 100 MPa,
    nu 0.45, rho 1200 kg/m^3) placed by :func:`slider_placement`; the pavement as one layer of C3D8 elements
    between ``z_bottom_m`` and the heightfield nodes, every node fixed (a rigid body without rigid-body machinery);
    a penalty contact pair (slave: slider bottom face S1, master: pavement top face S2,
    ``*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR`` with slope ``penalty_pa_per_m``, default
    ``10 E / h_z`` of the slider).

    ``holder``: ``"rigid"`` (default) ties the vertical displacement of all top-face nodes to one reference
    top node by ``*EQUATION`` (a stiff, non-tilting holder) and puts ``load_n`` on it; ``"distributed"``
    spreads the load over the top nodes by tributary area and leaves them free to tilt. In both, the top
    nodes are held in y, and in x (static) or driven in x (dynamic).

    ``step="static"``: frictionless indentation (``*STATIC``), no ``*FRICTION``.
    ``step="dynamic"``: ``*DYNAMIC, EXPLICIT`` over ``slide_distance_m`` (default: pavement length minus
    slider length, starting at the x-start) at ``speed_kmh``: initial velocity of all slider nodes and a
    linear displacement ramp of the top nodes in x (constant speed). Friction: ``dialect="abaqus"`` writes
    ``*FRICTION, EXPONENTIAL DECAY`` (mu_s, mu_k, d_c = alpha in s/m); CalculiX has no exponential decay,
    so ``dialect="calculix"`` writes a constant ``mu = law.mu(v)`` at the sliding speed (slip speed = v),
    with stick slope ``penalty / 10``.
    ``step="push"`` (CalculiX only): a quasi-static frictional push, two ``*STATIC`` steps. Step 1 is the
    static step above (load ``load_n`` on the holder, top nodes held in x) with friction active; step 2
    prescribes the x displacement ``slide_distance_m`` (m, default 1 mm) of every top (holder) node, ramped
    linearly over at most ``1 / push_increments`` of the step per increment (``push_increments`` >= 1; CalculiX
    may cut an increment back, never make it longer), with the load held. Friction: ``*FRICTION`` with the
    constant ``mu = law.mu(v)`` at ``speed_kmh`` (pass :class:`skidsim.friction.ConstantFriction` for a given
    mu) and the stick slope ``stick_slope_pa_per_m`` (Pa/m; default the solver's
    ``SolverConfig.friction_stiffness_pa_per_m``, 5e10 Pa/m). Matching the stick slope: for node-to-surface
    contact CalculiX's tangential spring of a slave node is the stick slope times the node's slave area
    (``springforc_n2f``: ``xk = lambda * springarea``), the elastic-stick/return-mapping law of
    ``friction_model="penalty"`` (``k_t = friction_stiffness_pa_per_m * tributary area``); the slave areas of
    the slider's uniform bottom grid equal our tributary areas, so ``stick_slope_pa_per_m =
    friction_stiffness_pa_per_m`` is the same law node by node (for surface-to-surface contact it is the same
    traction-slip slope, integrated over the faces). Practical notes (CalculiX 2.20, 2 mm slider mesh): use
    ``contact="node to surface"`` (the nodal law of our solver; surface to surface integrates over the slave
    faces cut by every pavement facet, about 6x slower on a 0.2 mm pavement grid) and ``element_type="C3D8"``
    (C3D8R hourglasses under the point-like contact forces); with a stick slope 4x the normal penalty (2e11
    against E / h_z = 5e10 Pa/m) step 1 on an egg-box texture did not converge (contact elements flip between
    iterations), with a normal penalty of 10 E / h_z it does. Every increment of step 2 prints the total
    reaction of the pavement nodes (``*NODE PRINT, NSET=PAVE_ALL, TOTALS=ONLY``: RF), the slider displacements
    (U, with the holder's in it) and the contact stresses (``*CONTACT PRINT``: CSTR); read them with
    :func:`parse_push_history`.

    ``_shared`` (private, speed only): a dict that the decks of one pavement share (:func:`write_model_bundle`);
    the pavement's node and element lines, the same in every deck, are formatted once into it.
    """
    slide_distance_m, stick_slope_pa_per_m = _checked_inp_options(
        step, dialect, holder, contact, load_n, element_type, push_increments, slide_distance_m, stick_slope_pa_per_m
    )
    mat = dict(RUBBER, **(material or {}))
    hf = heightfield
    v_ms = float(kmh_to_ms(speed_kmh))
    if step == "dynamic":
        L = slider.size_m[0]
        slide_distance_m, center_xy_m = _dynamic_slide(hf, L, v_ms, speed_kmh, slide_distance_m, center_xy_m)
    off = slider_placement(slider, hf, center_xy_m, overclosure_m)
    kpen = float(penalty_pa_per_m) if penalty_pa_per_m else 10.0 * mat["E_pa"] / slider.hz
    m = _inp_numbering(slider, hf, off)
    interaction, mu_eq, notes = _inp_interaction(step, dialect, contact, law, v_ms, kpen, stick_slope_pa_per_m)
    text = (
        _inp_model(m, slider, hf, off, step, dialect, element_type, title, mat, _shared)
        + interaction
        + _inp_steps(m, step, dialect, holder, load_n, slide_distance_m, v_ms, push_increments)
    )
    path = Path(path)
    write_text(path, text)
    return InpDeck(
        path,
        step,
        dialect,
        holder,
        m["s_ids"],
        m["p_ids"],
        m["ref"],
        off,
        slider.bottom_nodes() + 1,
        m["trib"],
        float(load_n),
        kpen,
        mu_eq,
        v_ms if step == "dynamic" else None,
        slide_distance_m,
        notes,
    )


def _checked_inp_options(
    step, dialect, holder, contact, load_n, element_type, push_increments, slide_distance_m, stick_slope_pa_per_m
):
    """:func:`write_inp`'s choices checked; for ``step="push"`` the push distance (m) and the stick slope (Pa/m)
    with their defaults. Returns ``(slide_distance_m, stick_slope_pa_per_m)``."""
    if step not in ("static", "dynamic", "push"):
        raise InputError(None, "step 'static', 'dynamic' or 'push'", column="step", got=step)
    if dialect not in ("calculix", "abaqus"):
        raise InputError(None, "dialect 'calculix' or 'abaqus'", column="dialect", got=dialect)
    if holder not in ("rigid", "distributed"):
        raise InputError(None, "holder 'rigid' or 'distributed'", column="holder", got=holder)
    if contact not in ("node to surface", "surface to surface"):
        raise InputError(None, "contact 'node to surface' or 'surface to surface'", column="contact", got=contact)
    if not (np.isfinite(load_n) and load_n > 0):
        raise InputError(None, "a positive load in N", column="load_n", got=load_n)
    if element_type not in ("C3D8R", "C3D8"):
        raise InputError(None, "element_type 'C3D8R' or 'C3D8'", column="element_type", got=element_type)
    if step == "push":
        if dialect != "calculix":
            raise InputError(None, "dialect 'calculix' for step 'push'", column="dialect", got=dialect)
        if int(push_increments) < 1:
            raise InputError(None, "at least one increment", column="push_increments", got=push_increments)
        if slide_distance_m is None:
            slide_distance_m = 1e-3
        if not (np.isfinite(slide_distance_m) and slide_distance_m > 0):
            raise InputError(None, "a positive push distance in m", column="slide_distance_m", got=slide_distance_m)
        if stick_slope_pa_per_m is None:
            from .solver.config import SolverConfig

            stick_slope_pa_per_m = SolverConfig().friction_stiffness_pa_per_m
        if not (np.isfinite(stick_slope_pa_per_m) and stick_slope_pa_per_m > 0):
            raise InputError(
                None, "a positive stick slope in Pa/m", column="stick_slope_pa_per_m", got=stick_slope_pa_per_m
            )
    return slide_distance_m, stick_slope_pa_per_m


def _dynamic_slide(hf: Heightfield, L: float, v_ms: float, speed_kmh: float, slide_distance_m, center_xy_m):
    """The slide of a dynamic deck: its distance (m; default the pavement length minus the slider length ``L``)
    and the slider's start centre (m; default at the x-start), checked to stay on the pavement."""
    x0, x1, y0, y1 = hf.extent
    if slide_distance_m is None:
        slide_distance_m = (x1 - x0) - L
    if center_xy_m is None:
        center_xy_m = (x0 + 0.5 * L, 0.5 * (y0 + y1))
    if center_xy_m[0] + 0.5 * L + slide_distance_m > x1 + 1e-9:
        raise InputError(
            hf.name or None,
            "a slide that keeps the slider on the pavement",
            column="slide_distance_m",
            got=slide_distance_m,
        )
    if not v_ms > 0:
        raise InputError(None, "a positive sliding speed in km/h", column="speed_kmh", got=speed_kmh)
    return slide_distance_m, center_xy_m


def _inp_numbering(slider: SliderMesh, hf: Heightfield, off) -> dict:
    """Node and element numbers of the deck (slider first, then the pavement, 1-based), the node sets and the
    tributary areas of the top nodes."""
    sp = slider.points + np.array(off)
    ns = slider.n_nodes
    s_ids = np.arange(1, ns + 1)
    ppts, phex = pavement_hex_mesh(hf, 1)
    p_ids = ns + 1 + np.arange(len(ppts))
    es = slider.n_elements
    e_slider = np.arange(1, es + 1)
    e_pave = es + 1 + np.arange(len(phex))
    conn_s = slider.connectivity + 1
    conn_p = phex + ns + 1
    bottom_elems = e_slider[np.arange(es) % slider.nz == 0]
    top_ids = slider.top_nodes() + 1
    ref = int(top_ids[0])
    wx = np.full(slider.nx + 1, slider.hx)
    wx[[0, -1]] *= 0.5
    wy = np.full(slider.ny + 1, slider.hy)
    wy[[0, -1]] *= 0.5
    trib = np.outer(wx, wy).ravel()  # same C order as top_nodes()/bottom_nodes()

    return {
        "sp": sp,
        "ns": ns,
        "s_ids": s_ids,
        "ppts": ppts,
        "phex": phex,
        "p_ids": p_ids,
        "es": es,
        "e_slider": e_slider,
        "e_pave": e_pave,
        "conn_s": conn_s,
        "conn_p": conn_p,
        "bottom_elems": bottom_elems,
        "top_ids": top_ids,
        "ref": ref,
        "wx": wx,
        "wy": wy,
        "trib": trib,
    }


def _inp_model(
    m: dict, slider: SliderMesh, hf: Heightfield, off, step, dialect, element_type, title, mat, shared=None
) -> str:
    """The heading, nodes, elements, sets, surfaces, materials and sections of the deck; ``shared``: see
    :func:`write_inp` (the pavement blocks depend only on the heightfield and the slider's node count)."""
    sp, s_ids, ppts, p_ids, e_slider, conn_s, e_pave, conn_p, bottom_elems, top_ids, ref = (
        m["sp"],
        m["s_ids"],
        m["ppts"],
        m["p_ids"],
        m["e_slider"],
        m["conn_s"],
        m["e_pave"],
        m["conn_p"],
        m["bottom_elems"],
        m["top_ids"],
        m["ref"],
    )
    out = []
    w = out.append
    w("*HEADING\n")
    w((title or f"skidsim DFT model: {hf.name or 'pavement'}, {step} step, {dialect} dialect") + "\n")
    w("** Units: m, N, Pa, kg/m^3, s. Written by skidsim.exports.write_inp.\n")
    w(
        f"** Slider {slider.nx}x{slider.ny}x{slider.nz} {element_type}, "
        f"offset (m) {off[0]:.6e} {off[1]:.6e} {off[2]:.6e}\n"
    )
    w("*NODE, NSET=SLIDER_ALL\n")
    w(_fmt_rows(s_ids, sp))
    w("*NODE, NSET=PAVE_ALL\n")
    key = (id(hf), slider.n_nodes)
    if shared is None or shared.get("key") != key:
        blocks = {"nodes": _fmt_rows(p_ids, ppts), "elements": _fmt_rows(e_pave, conn_p, "%d")}
        if shared is not None:
            shared.update(blocks, key=key)
    else:
        blocks = shared
    w(blocks["nodes"])
    w(f"*ELEMENT, TYPE={element_type}, ELSET=SLIDER\n")
    w(_fmt_rows(e_slider, conn_s, "%d"))
    w("*ELEMENT, TYPE=C3D8, ELSET=PAVEMENT\n")
    w(blocks["elements"])
    w("*ELSET, ELSET=SLIDER_BOTTOM_EL\n")
    w(_id_lines(bottom_elems))
    w("*NSET, NSET=SLIDER_TOP\n")
    w(_id_lines(top_ids))
    w("*NSET, NSET=SLIDER_BOTTOM\n")
    w(_id_lines(slider.bottom_nodes() + 1))
    w(f"*NSET, NSET=REF\n{ref}\n")
    w("*SURFACE, NAME=SLIDER_FACE, TYPE=ELEMENT\nSLIDER_BOTTOM_EL, S1\n")
    w("*SURFACE, NAME=PAVE_FACE, TYPE=ELEMENT\nPAVEMENT, S2\n")
    w(
        "*MATERIAL, NAME=RUBBER\n*ELASTIC\n{:.6e}, {:.6g}\n*DENSITY\n{:.6g}\n".format(
            mat["E_pa"], mat["nu"], mat["rho_kg_m3"]
        )
    )
    w("** Pavement material: irrelevant (all pavement nodes are fixed).\n")
    w("*MATERIAL, NAME=PAVE\n*ELASTIC\n2.0e10, 0.3\n*DENSITY\n2400.\n")
    w("*SOLID SECTION, ELSET=SLIDER, MATERIAL=RUBBER\n")
    w("*SOLID SECTION, ELSET=PAVEMENT, MATERIAL=PAVE\n")
    return "".join(out)


def _inp_interaction(step, dialect, contact, law: ExponentialDecay, v_ms, kpen, stick_slope_pa_per_m):
    """The surface interaction, friction and contact pair: ``(cards, mu_eq or None, notes)``."""
    notes = []
    out = []
    w = out.append
    w("*SURFACE INTERACTION, NAME=SLIDER_ROAD\n")
    if dialect == "abaqus" and step == "dynamic":
        w("*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=HARD\n")
    else:
        # CalculiX: slope K (Pa/m) and, for node-to-surface, the tension at large clearance sigma_inf (Pa).
        w(
            f"*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n{kpen:.6e}, 1.0\n"
            if dialect == "calculix"
            else f"*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n{kpen:.6e}\n"
        )
    mu_eq = None
    if step == "dynamic":
        if dialect == "abaqus":
            w(f"*FRICTION, EXPONENTIAL DECAY\n{law.mu_s:.8g}, {law.mu_k:.8g}, {law.alpha:.8g}\n")
        else:
            mu_eq = float(law.mu(v_ms))
            w("** CalculiX has no EXPONENTIAL DECAY friction: constant mu = mu(v) at the sliding speed.\n")
            w(f"** law: mu_s={law.mu_s:.8g}, mu_k={law.mu_k:.8g}, alpha={law.alpha:.8g} s/m; v={v_ms:.6g} m/s\n")
            w(f"*FRICTION\n{mu_eq:.8g}, {kpen / 10.0:.6e}\n")
            notes.append("calculix dynamic deck: constant mu = law.mu(speed) instead of exponential decay")
    elif step == "push":
        mu_eq = float(law.mu(v_ms))
        w(f"** Quasi-static push: constant mu = law.mu(v) at v={v_ms:.6g} m/s; stick slope in Pa/m.\n")
        w(f"*FRICTION\n{mu_eq:.8g}, {stick_slope_pa_per_m:.6e}\n")
    ctype = contact.upper()
    if dialect == "abaqus" and step == "dynamic":
        w("*CONTACT PAIR, INTERACTION=SLIDER_ROAD, MECHANICAL CONSTRAINT=PENALTY\nSLIDER_FACE, PAVE_FACE\n")
    else:
        w(f"*CONTACT PAIR, INTERACTION=SLIDER_ROAD, TYPE={ctype}\nSLIDER_FACE, PAVE_FACE\n")
    return "".join(out), mu_eq, tuple(notes)


def _inp_steps(m: dict, step, dialect, holder, load_n, slide_distance_m, v_ms, push_increments) -> str:
    """The boundary conditions, the holder, the load and the step(s) with their output requests."""
    ns, s_ids, top_ids, ref, trib = (m["ns"], m["s_ids"], m["top_ids"], m["ref"], m["trib"])
    out = []
    w = out.append
    w("*BOUNDARY\nPAVE_ALL, 1, 3\nSLIDER_TOP, 2, 2\n")
    if step in ("static", "push"):
        w("SLIDER_TOP, 1, 1\n")
    if holder == "rigid":
        w("*EQUATION\n")
        for n in top_ids[1:]:
            w(f"2\n{int(n)}, 3, 1.0, {ref}, 3, -1.0\n")
    if step == "dynamic":
        T = slide_distance_m / v_ms
        w(f"*AMPLITUDE, NAME=SLIDE\n0.0, 0.0, {T:.10e}, 1.0\n")
        w("*INITIAL CONDITIONS, TYPE=VELOCITY\n")
        w(_fmt_rows(s_ids, np.column_stack([np.ones(ns), np.full(ns, v_ms)]), "%.10g"))
    if holder == "rigid":
        cload = f"{ref}, 3, {-load_n:.10e}\n"
    else:
        cload = _fmt_rows(top_ids, np.column_stack([np.full(len(top_ids), 3), -load_n * trib / trib.sum()]), "%.10g")
    if step == "push":
        # step 1: the normal load on the holder (held in x), friction active; step 2 (below): the push
        w("** Step 1: normal load. Step 2: x displacement of the holder (top) nodes, load held.\n")
        w("*STEP, INC=1000\n*STATIC\n0.25, 1.0, 1e-6, 1.0\n*CLOAD\n" + cload)
        w("*NODE PRINT, NSET=PAVE_ALL, TOTALS=ONLY\nRF\n*END STEP\n")
    w("*STEP, INC=1000\n" if step in ("static", "push") else "*STEP, INC=100000000\n")
    if step == "push":
        dinc = 1.0 / int(push_increments)
        w(f"*STATIC\n{dinc:.10g}, 1.0, {1e-4 * dinc:.6g}, {dinc:.10g}\n")
        w(f"*BOUNDARY\nSLIDER_TOP, 1, 1, {slide_distance_m:.10e}\n")
    elif step == "static":
        w("*STATIC\n0.25, 1.0, 1e-6, 1.0\n")
    else:
        w(f"*DYNAMIC, EXPLICIT\n{1e-7:.6e}, {slide_distance_m / v_ms:.10e}\n")
        w(f"*BOUNDARY, AMPLITUDE=SLIDE\nSLIDER_TOP, 1, 1, {slide_distance_m:.10e}\n")
    w("*CLOAD\n" + cload)
    if dialect == "calculix" or step == "static":
        w("*NODE PRINT, NSET=PAVE_ALL, TOTALS=ONLY\nRF\n")
        w("*NODE PRINT, NSET=SLIDER_ALL\nU\n")
        w("*CONTACT PRINT\nCSTR\n" if dialect == "calculix" else "*CONTACT PRINT\nCSTRESS\n")
        w("*NODE FILE\nU\n")
    else:
        w(
            f"*OUTPUT, HISTORY, TIME INTERVAL={slide_distance_m / v_ms / 200:.6e}\n"
            "*NODE OUTPUT, NSET=SLIDER_TOP\nRF1, RF3, U1, U3\n"
        )
    w("*END STEP\n")
    return "".join(out)


# ---------------------------------------------------------------------- CalculiX runner
@dataclass(frozen=True)
class CalculixResult:
    """Results of the last increment of a CalculiX run of a :func:`write_inp` deck (SI units).

    ``total_force_n``: sum of the reaction forces (N) at the fixed pavement nodes ``(fx, fy, fz)``: what the
    support exerts on the pavement, equal and opposite to the slider's total contact force on it.
    ``normal_force_n = fz`` (positive when the slider presses down; equals the load in equilibrium).
    ``contact_nodes``/``contact_pressure_pa``: slave node ids with a contact element and their pressure.
    ``contact_area_mm2``: summed tributary area (mm^2) of slave nodes with positive pressure (needs the
    deck; ``None`` otherwise). ``node_ids``/``displacements_m``: the slider nodes printed in the .dat, and
    ``slider_displacements_m`` the same in ``SliderMesh`` flat order when the deck is given.
    """

    time: float
    total_force_n: tuple[float, float, float]
    normal_force_n: float
    contact_nodes: np.ndarray
    contact_pressure_pa: np.ndarray
    contact_area_mm2: float | None
    node_ids: np.ndarray
    displacements_m: np.ndarray
    slider_displacements_m: np.ndarray | None
    workdir: Path
    log: str


_FLOAT = r"[-+]?\d+\.\d*(?:[EeDd][-+]?\d+)?"


def parse_dat(path: str | Path) -> dict:
    """Parse the last time block of each table in a CalculiX ``.dat`` file (:func:`parse_dat_history`'s blocks).

    Returns ``{"time": float, "total_force": (fx, fy, fz) | None, "displacements": (ids, (n, 3)) | None,
    "contact": (ids, (n, 3) press/tang1/tang2) | None}``; raises :class:`CalculixError` on a bad file.
    """
    blocks = parse_dat_history(path)
    last = {b["kind"]: b for b in blocks}  # file order: the last block of each kind wins
    out: dict = {"time": max(b["time"] for b in blocks), "total_force": None, "displacements": None, "contact": None}
    if "total force" in last and len(last["total force"]["rows"]):
        out["total_force"] = tuple(float(x) for x in last["total force"]["rows"][0][:3])
    for key, name in (("displacements", "displacements"), ("contact stress", "contact")):
        if key in last and len(last[key]["rows"]):
            a = last[key]["rows"]
            out[name] = (a[:, 0].astype(np.int64), a[:, 1:4])
    return out


def parse_dat_history(path: str | Path) -> list[dict]:
    """Every table block of a CalculiX ``.dat`` file, in file order (one per output increment and set).

    Each block is ``{"kind": "total force" | "displacements" | "contact stress", "set": str | None, "time":
    float, "rows": (n, k) array}``; ``time`` is CalculiX's total time (step 1 ends at 1.0, step 2 at 2.0, ...);
    the rows are as printed (``fx, fy, fz`` in N for totals; node id then values, SI, otherwise). Raises
    :class:`CalculixError` when the file cannot be read or has no table.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise CalculixError(f"{path}: cannot read CalculiX output ({exc})") from None
    head = re.compile(
        r"^\s*(total force|displacements|contact stress)\b(?:.*?for set (\S+) )?.*time\s+(" + _FLOAT + r")\s*$",
        re.IGNORECASE,
    )
    blocks: list[dict] = []
    rows = None
    for line in text.splitlines():
        m = head.match(line)
        if m:
            rows = []
            blocks.append({"kind": m.group(1).lower(), "set": m.group(2), "time": float(m.group(3)), "rows": rows})
            continue
        if rows is None or not line.split():
            continue
        try:
            rows.append([float(p.replace("D", "E")) for p in line.split()])
        except ValueError:
            rows = None
    if not blocks:
        raise CalculixError(f"{path}: no result tables (total force, displacements, contact stress) found")
    for b in blocks:  # a header followed by no number row gives a (0, 0) table
        b["rows"] = np.array(b["rows"], dtype=float) if b["rows"] else np.empty((0, 0))
    return blocks


@dataclass(frozen=True)
class PushHistory:
    """Per-increment results of step 2 of a ``step="push"`` deck (:func:`write_inp`), SI units.

    ``time``: CalculiX total time (1 < t <= 2 in the push step); ``holder_x_m``: x displacement of the holder
    (reference top node, m); ``force_n``: ``(n, 3)`` sum of the reaction forces (N) at the fixed pavement nodes,
    as :attr:`CalculixResult.total_force_n` (``force_n[:, 2]`` the normal load, positive; ``force_n[:, 0]``
    negative when the slider is pushed in +x); ``ratio = -force_n[:, 0] / force_n[:, 2]``: the resisting
    tangential over the normal force (the SN of :func:`skidsim.solver.simulate`); ``contact_nodes``:
    slave nodes with positive pressure; ``slip_nodes``: those whose shear stress is at the Coulomb limit
    (``|tau| >= (1 - slip_tolerance) mu p``).
    """

    time: np.ndarray
    holder_x_m: np.ndarray
    force_n: np.ndarray
    ratio: np.ndarray
    contact_nodes: np.ndarray
    slip_nodes: np.ndarray

    def onset_index(self) -> int | None:
        """Index of the first increment in which every contact node slips (gross sliding), or ``None``."""
        full = np.flatnonzero((self.contact_nodes > 0) & (self.slip_nodes == self.contact_nodes))
        return int(full[0]) if full.size else None


def parse_push_history(path: str | Path, deck: InpDeck, slip_tolerance: float = 1e-3) -> PushHistory:
    """Read the push step's increments from the ``.dat`` of a :func:`write_inp` ``step="push"`` deck.

    Per increment of time > 1: the total reaction force of the ``PAVE_ALL`` set, the holder displacement (the
    deck's reference node) and the contact state (pressure and shear stresses of ``*CONTACT PRINT``, Pa).
    Raises :class:`CalculixError` when a table is missing.
    """
    if deck.step != "push" or deck.mu_equivalent is None:
        raise InputError(None, "a deck written with step='push'", column="deck", got=deck.step)
    blocks = parse_dat_history(path)
    by_time: dict[float, dict] = {}
    for b in blocks:
        if b["time"] > 1.0 + 1e-9:
            by_time.setdefault(b["time"], {})[b["kind"]] = b
    times = sorted(by_time)
    if not times:
        raise CalculixError(f"{path}: no increment of the push step (time > 1) found")
    mu = deck.mu_equivalent
    hx, force, n_c, n_s = [], [], [], []
    for t in times:
        rec = by_time[t]
        if "total force" not in rec or "displacements" not in rec:
            raise CalculixError(f"{path}: time {t}: missing total force or displacements table")
        force.append(rec["total force"]["rows"][0, :3])
        d = rec["displacements"]["rows"]
        hit = np.flatnonzero(d[:, 0].astype(np.int64) == deck.ref_node)
        if not hit.size:
            raise CalculixError(f"{path}: time {t}: no displacement of the holder node {deck.ref_node}")
        hx.append(d[hit[0], 1])
        c = rec.get("contact stress")
        if c is None or not len(c["rows"]):
            n_c.append(0)
            n_s.append(0)
            continue
        p, tau = c["rows"][:, 1], np.hypot(c["rows"][:, 2], c["rows"][:, 3])
        on = p > 0
        n_c.append(int(on.sum()))
        n_s.append(int((on & (tau >= (1.0 - slip_tolerance) * mu * p)).sum()))
    force = np.array(force)
    return PushHistory(np.array(times), np.array(hx), force, -force[:, 0] / force[:, 2], np.array(n_c), np.array(n_s))


def run_calculix(
    inp_path: str | Path,
    workdir: str | Path | None = None,
    deck: InpDeck | None = None,
    ccx: str = "ccx",
    timeout_s: float = 600.0,
    threads: int = 1,
) -> CalculixResult:
    """Run CalculiX on ``inp_path`` in ``workdir`` (default: the deck's directory) and parse its ``.dat``.

    Raises :class:`CalculixError` when ``ccx`` is missing, fails, reports an ``*ERROR`` or does not finish.
    ``threads`` sets ``OMP_NUM_THREADS``/``CCX_NPROC_EQUATION_SOLVER`` (default 1: shared machines).
    """
    inp_path = Path(inp_path)
    exe = shutil.which(ccx)
    if exe is None:
        raise CalculixError(f"{ccx!r} not found on PATH: install CalculiX (Debian package calculix-ccx)")
    if not inp_path.is_file():
        raise InputError(inp_path, "an existing .inp file", got="missing")
    workdir = Path(workdir) if workdir is not None else inp_path.parent
    workdir.mkdir(parents=True, exist_ok=True)
    job = inp_path.stem
    target = workdir / inp_path.name
    if target.resolve() != inp_path.resolve():
        shutil.copyfile(inp_path, target)
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_EQUATION_SOLVER=str(threads))
    try:
        proc = subprocess.run([exe, "-i", job], cwd=workdir, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise CalculixError(f"{inp_path}: CalculiX did not finish within {timeout_s} s") from None
    log = proc.stdout + proc.stderr
    write_text(workdir / (job + ".log"), log)
    errors = [ln.strip() for ln in log.splitlines() if "*ERROR" in ln]
    if proc.returncode != 0 or errors or "Job finished" not in log:
        raise CalculixError(
            f"{inp_path}: CalculiX failed (exit {proc.returncode}): " + ("; ".join(errors[:3]) or log[-500:])
        )
    res = parse_dat(workdir / (job + ".dat"))
    if res["total_force"] is None:
        raise CalculixError(f"{workdir / (job + '.dat')}: no 'total force' table (NODE PRINT TOTALS=ONLY RF)")
    f = tuple(float(v) for v in res["total_force"])
    ids, u = res["displacements"] if res["displacements"] is not None else (np.zeros(0, np.int64), np.zeros((0, 3)))
    cn, cs = res["contact"] if res["contact"] is not None else (np.zeros(0, np.int64), np.zeros((0, 3)))
    area = None
    su = None
    if deck is not None:
        amap = dict(zip(deck.bottom_node_ids.tolist(), deck.bottom_tributary_area_m2.tolist()))
        area = 1e6 * float(sum(amap.get(int(n), 0.0) for n, p in zip(cn, cs[:, 0]) if p > 0))
        if len(ids):
            pos = {int(n): k for k, n in enumerate(ids)}
            sel = [pos.get(int(n), -1) for n in deck.slider_node_ids]
            if min(sel) >= 0:
                su = u[sel]
    return CalculixResult(res["time"], f, f[2], cn, cs[:, 0].copy(), area, ids, u, su, workdir, log)


def write_model_bundle(
    hf: Heightfield,
    slider: SliderMesh,
    law: ExponentialDecay,
    outdir: str | Path,
    *,
    load_n: float = DFT_LOAD_N,
    speed_kmh: float = MeshOptions.inp_speed_kmh,
    gmsh_layers: int = MeshOptions.gmsh_layers,
    unit: str = "mm",
) -> dict[str, Path]:
    """Write every export of one site's FE model into ``outdir``; returns ``{kind: path}``.

    Files: ``pavement.npz`` (the heightfield, SI), ``pavement.stl``, ``pavement.msh``, ``pavement.vtu``,
    ``slider.vtu`` (geometry in ``unit``), ``dft_static_calculix.inp`` (frictionless indentation),
    ``dft_dynamic_calculix.inp`` (constant mu at ``speed_kmh``) and ``dft_dynamic_abaqus.inp``
    (``*FRICTION, EXPONENTIAL DECAY``), decks in SI.
    """
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "npz": hf.to_npz(out / "pavement.npz"),
        "stl": write_stl(hf, out / "pavement.stl", unit=unit),
        "msh": write_gmsh(hf, out / "pavement.msh", layers=gmsh_layers, unit=unit),
        "vtu_pavement": write_vtu_pavement(hf, out / "pavement.vtu", unit=unit),
        "vtu_slider": write_vtu_slider(slider, out / "slider.vtu", unit=unit),
    }
    shared: dict = {}  # the pavement's node and element lines, formatted for the first deck only
    for key, step, dialect in (
        ("inp_static", "static", "calculix"),
        ("inp_dynamic_calculix", "dynamic", "calculix"),
        ("inp_dynamic_abaqus", "dynamic", "abaqus"),
    ):
        name = f"dft_{step}_{dialect}.inp"
        deck = write_inp(out / name, slider, hf, law, load_n, speed_kmh, step, dialect=dialect, _shared=shared)
        paths[key] = deck.path
    return paths
