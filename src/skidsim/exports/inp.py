"""The ABAQUS/CalculiX .inp deck of the DFT model: the rubber slider on the rigid pavement, a static indentation,
a dynamic slide or a CalculiX push, in **SI** (m, N, Pa, kg/m^3, s; so the ABAQUS decay coefficient ``d_c`` equals
the project's ``alpha`` in s/m). Written atomically (:mod:`skidsim.atomic`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from skidsim.atomic import write_text
from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay, kmh_to_ms
from skidsim.reconstruct import Heightfield
from skidsim.slidermesh import SliderMesh

from .geometry import pavement_hex_mesh

#: Material of the rubber slider (study, Section 3): E in Pa, nu, rho in kg/m^3.
RUBBER = {"E_pa": 100e6, "nu": 0.45, "rho_kg_m3": 1200.0}
#: Nominal DFT load on one slider, N.
DFT_LOAD_N = 11.8


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
            from skidsim.solver.config import SolverConfig

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
