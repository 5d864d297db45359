"""Against CalculiX: static frictionless indentation of the slider on a textured surface.

The deck is written by :func:`skidsim.exports.write_inp` (static step, rigid holder, penalty 10 E / h_z, node to
surface); CalculiX (``ccx``) solves it via :func:`skidsim.exports.run_calculix`; our explicit solver's
quasi-static preload on the same Heightfield with the same penalty stiffness (``penalty_scale`` 10) and no
friction must give the same total contact force and the same real contact area (tributary area of the bottom
nodes in contact) within 5 %.
"""

import shutil

import numpy as np
import pytest
from conftest import simulate_centre_m

from skidsim.friction import ConstantFriction, ExponentialDecay
from skidsim.slidermesh import SliderMesh
from skidsim.solver import SinusoidalSurface, SolverConfig, simulate
from skidsim.solver.surfaces import to_heightfield

CCX = shutil.which("ccx")
pytestmark = pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) not installed")


def test_static_indentation_matches_calculix(tmp_path):
    from skidsim.exports import run_calculix, write_inp

    surf = SinusoidalSurface(
        amplitude_m=30e-6, wavelength_x_m=10e-3, wavelength_y_m=12e-3, phase=0.3, extent_m=(0.0, 0.024, -0.01, 0.01)
    )
    hf = to_heightfield(surf, 0.25e-3)
    cfg = SolverConfig(
        element_mm=1.0,
        slide_length_mm=0.6,
        window_start_mm=0.1,
        penalty_scale=10.0,
        edge_margin_mm=0.5,
        preload_time_s=2e-3,
    )
    slider = SliderMesh.box(cfg.slider_length_mm, cfg.slider_width_mm, cfg.slider_thickness_mm, cfg.element_mm)
    centre = simulate_centre_m(hf, cfg, slider)
    deck = write_inp(
        tmp_path / "static.inp",
        slider,
        hf,
        ExponentialDecay(0.5, 0.4, 0.3),
        load_n=cfg.load_n,
        step="static",
        center_xy_m=centre,
    )
    assert deck.penalty_pa_per_m == pytest.approx(10 * cfg.youngs_modulus_pa / slider.hz)
    res = run_calculix(deck.path, tmp_path, deck=deck, ccx=CCX)
    fz_ccx = abs(res.normal_force_n)
    area_ccx = res.contact_area_mm2 * 1e-6
    # independent check of the parsed area: our own reading of the contact pressures and tributary areas
    own = float(
        deck.bottom_tributary_area_m2[
            np.isin(deck.bottom_node_ids, res.contact_nodes[res.contact_pressure_pa > 0])
        ].sum()
    )
    assert own == pytest.approx(area_ccx, rel=1e-9)

    r = simulate(hf, 20, ConstantFriction(0.0), cfg)
    assert r.preload_contact_force_n == pytest.approx(fz_ccx, rel=0.05)
    assert r.preload_contact_force_n == pytest.approx(cfg.load_n, rel=0.005)
    assert r.preload_contact_area_mm2 * 1e-6 == pytest.approx(area_ccx, rel=0.05)
    # partial contact: the comparison is not the trivial full-face case
    assert 0.05 * 320e-6 < area_ccx < 0.8 * 320e-6
