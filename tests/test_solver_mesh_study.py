"""The mesh-study table: one run per (speed, size), error against the finest mesh of the same speed."""

import numpy as np
import pandas as pd
import pytest

from skidsim.friction import ExponentialDecay
from skidsim.solver import SinusoidalSurface, SolverConfig
from skidsim.solver.mesh_study import mesh_study


def test_mesh_study_table_and_error_definition():
    pav = SinusoidalSurface(amplitude_m=0.1e-3, wavelength_x_m=4e-3, wavelength_y_m=5e-3)
    base = SolverConfig(slide_length_mm=12.0, window_start_mm=3.0)
    law = ExponentialDecay(0.4, 0.35, 0.6)
    t = mesh_study(pav, [2.0, 4.0], [60.0], law=law, base=base)
    assert list(t["element_mm"]) == [4.0, 2.0]  # coarse to fine
    fine = t[t["element_mm"] == 2.0].iloc[0]
    coarse = t[t["element_mm"] == 4.0].iloc[0]
    assert fine["error_pct"] == 0.0
    assert np.isclose(coarse["error_pct"], 100 * abs(coarse["sn"] - fine["sn"]) / fine["sn"])
    # on the gentle texture the fine mesh gives SN close to mu(60 km/h) = 0.35, and the coarse mesh rests on
    # fewer, stiffer-loaded nodes and reads higher (docs/solver.md: SN falls with refinement)
    assert np.isclose(fine["sn"], law.mu_kmh(60.0), rtol=0.1)
    assert coarse["sn"] > fine["sn"]
    assert (t["n_elements"].to_numpy() == [5 * 4 * 2, 10 * 8 * 3]).all()
    # the SN split: friction part + contact-normal (geometric) part = SN; on this gentle texture the friction
    # part is mu(60 km/h) within 2 % and nothing sticks
    assert np.allclose(t["sn_friction"] + t["sn_geometric"], t["sn"], rtol=1e-9)
    assert np.allclose(t["sn_friction"], law.mu_kmh(60.0), rtol=0.02)
    assert (t["mean_contact_nodes"] > 0).all() and (t["stick_fraction"] < 0.05).all()
    assert (t["friction_model"] == base.friction_model).all()
    assert (t["slide_damping_model"] == base.slide_damping_model).all()
    # the law sees about the sliding speed on the gentle texture (m/s)
    assert np.allclose(t["mean_slip_speed_ms"], 60 / 3.6, rtol=0.1)


def test_the_speeds_of_a_mesh_run_as_one_batch_with_the_single_runs_numbers():
    """``batch=True`` runs the speeds of each mesh as one ``simulate_batch``: every column of the
    table but the wall times and the energy residual (to rounding) equals the single runs' bit for bit, in the
    same row order (speed-major)."""
    pav = SinusoidalSurface(amplitude_m=0.1e-3, wavelength_x_m=4e-3, wavelength_y_m=5e-3)
    base = SolverConfig(slide_length_mm=8.0, window_start_mm=3.0)
    law = ExponentialDecay(0.4, 0.35, 0.6)
    batched = mesh_study(pav, [2.0, 4.0], [30.0, 60.0], law=law, base=base, batch=True)
    single = mesh_study(pav, [2.0, 4.0], [30.0, 60.0], law=law, base=base)
    assert list(zip(batched["speed_kmh"], batched["element_mm"])) == [
        (30.0, 4.0),
        (30.0, 2.0),
        (60.0, 4.0),
        (60.0, 2.0),
    ]
    other = ["wall_s", "element_steps_per_s", "energy_residual_frac"]
    pd.testing.assert_frame_equal(batched.drop(columns=other), single.drop(columns=other), check_exact=True)
    # energies: per-member dot products round differently in a batch (docs/solver.md: to 1e-12 of the work)
    np.testing.assert_allclose(batched["energy_residual_frac"], single["energy_residual_frac"], rtol=0, atol=1e-10)
    assert batched["n_steps"].iloc[0] > batched["n_steps"].iloc[2]  # the members finish at different steps


def test_richardson_recovers_the_limit_and_order_of_a_power_law():
    from skidsim.solver.mesh_study import richardson

    h = [0.5, 0.35, 0.25]  # mm, non-uniform refinement ratios (1.43, 1.4)
    est = richardson(h, [0.35 - 0.04 * x**1.5 for x in h])
    assert est["monotone"]
    assert est["value"] == pytest.approx(0.35, rel=1e-10) and est["order"] == pytest.approx(1.5, rel=1e-8)
    assert est["error_pct"][0] == pytest.approx(100 * (-0.04 * 0.5**1.5) / 0.35, rel=1e-8)
    # oscillating differences: no order, no extrapolation
    osc = richardson(h, [0.35, 0.34, 0.345])
    assert not osc["monotone"] and np.isnan(osc["value"])
    with pytest.raises(ValueError, match="three"):
        richardson([0.5, 0.5, 0.25], [1.0, 1.0, 1.0])
