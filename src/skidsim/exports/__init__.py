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

Modules: :mod:`.geometry` (the pavement solid's meshes and volumes), :mod:`.meshfiles` (STL, .msh, VTU),
:mod:`.inp` (the ABAQUS/CalculiX deck), :mod:`.calculix` (the CalculiX runner and its output); this package re-exports
their public names and writes one site's whole bundle (:func:`write_model_bundle`).
"""

from __future__ import annotations

from pathlib import Path

from skidsim.friction import ExponentialDecay
from skidsim.reconstruct import Heightfield, MeshOptions
from skidsim.slidermesh import SliderMesh

from .calculix import (
    CalculixError,
    CalculixResult,
    PushHistory,
    parse_dat,
    parse_dat_history,
    parse_push_history,
    run_calculix,
)
from .geometry import hex_volumes, pavement_hex_mesh, pavement_surface_mesh, triangulated_volume_m3
from .inp import DFT_LOAD_N, RUBBER, InpDeck, slider_placement, write_inp
from .meshfiles import is_watertight, stl_bytes, write_gmsh, write_stl, write_vtu_pavement, write_vtu_slider

__all__ = [
    "DFT_LOAD_N",
    "RUBBER",
    "CalculixError",
    "CalculixResult",
    "InpDeck",
    "PushHistory",
    "hex_volumes",
    "is_watertight",
    "parse_dat",
    "parse_dat_history",
    "parse_push_history",
    "pavement_hex_mesh",
    "pavement_surface_mesh",
    "run_calculix",
    "slider_placement",
    "stl_bytes",
    "triangulated_volume_m3",
    "write_gmsh",
    "write_inp",
    "write_model_bundle",
    "write_stl",
    "write_vtu_pavement",
    "write_vtu_slider",
]


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
