"""Penalty friction (``friction_model="penalty"``) and Rayleigh slide damping: analytic checks.

* the return mapping: elastic stick ``f = k_t u`` below ``mu N``, slip at ``mu N`` above, elastic unloading;
* a one-node explicit model with the solver's law: a tangential load below ``mu N`` settles at ``F / k_t``,
  above it the node slides with friction ``mu N`` and acceleration ``(F - mu N) / m``;
* flat plane: SN = mu(v) at 2, 1 and 0.5 mm (the traction law does not depend on the element size);
* a block pushed up the steepest flank of a long sinusoidal corrugation (quasi-static, line contact of the
  front edge): SN = (mu + tan theta) / (1 - mu tan theta), the onset-of-sliding force ratio of a rigid block on
  a slope theta (analytic; no CalculiX frictional deck);
* Rayleigh damping: the fitted loss factor at the band ends, the damped step factor, and the energy balance.
"""

import math

import numpy as np
import pytest
from conftest import corrugation_flank

from skidsim.errors import ConfigError
from skidsim.friction import ConstantFriction, ExponentialDecay
from skidsim.solver import FlatPlane, SinusoidalSurface, SolverConfig, simulate
from skidsim.solver.contact_friction import (
    damped_step_factor,
    loss_factor_at,
    penalty_friction,
    rayleigh_coefficients,
    return_map,
)

UP = (np.array([0.0]), np.array([0.0]), np.array([1.0]))


def test_return_map_stick_then_slip_then_elastic_unloading():
    k_t, limit = 2.0e4, np.array([0.25])  # N/m, N (mu N)
    f = np.zeros((3, 1))
    forces = []
    for du in [5e-6] * 4 + [-5e-6]:  # loading 5 um per step, then one step back
        f, stick = penalty_friction(f, np.array([[du], [0.0], [0.0]]), np.array([k_t]), limit, UP)
        forces.append((float(f[0, 0]), bool(stick[0])))
    assert forces[0] == pytest.approx((-0.1, True))  # elastic stick: -k_t u, 0.1 N after 5 um
    assert forces[1] == pytest.approx((-0.2, True))
    assert forces[2] == pytest.approx((-0.25, False))  # trial 0.3 N > mu N: slip, held at mu N
    assert forces[3] == pytest.approx((-0.25, False))
    assert forces[4] == pytest.approx((-0.15, True))  # unloading is elastic from the slip state
    # a normal displacement does not load the tangential spring; a rotated old force is projected
    f2, _ = penalty_friction(
        np.array([[0.0], [0.1], [0.05]]), np.array([[0.0], [0.0], [1e-3]]), np.array([k_t]), limit, UP
    )
    assert f2[:, 0] == pytest.approx([0.0, 0.1, 0.0])
    # the return mapping keeps the direction of the trial force
    g, stick = return_map(np.array([[3.0], [4.0], [0.0]]), np.array([1.0]))
    assert not stick[0] and g[:, 0] == pytest.approx([0.6, 0.8, 0.0])


def _one_node(force_n, *, mass_kg=1e-4, k_t=5e4, normal_n=1.0, mu=0.4, t_end_s=4e-3, damping_per_s=2e4):
    """Explicit central difference of one contact node under a tangential load (the solver's step order)."""
    dt = 0.2 * 2.0 / math.sqrt(k_t / mass_kg)
    f = np.zeros((3, 1))
    u = v = 0.0
    fric_hist = []
    for _ in range(int(t_end_s / dt)):
        f, _ = penalty_friction(f, np.array([[v * dt], [0.0], [0.0]]), np.array([k_t]), np.array([mu * normal_n]), UP)
        fric_hist.append(float(f[0, 0]))
        v += dt * (force_n + f[0, 0] - damping_per_s * mass_kg * v) / mass_kg
        u += dt * v
    return u, v, np.array(fric_hist), dt


def test_one_node_stick_below_mu_n_and_slip_above():
    k_t, mu_n = 5e4, 0.4
    u, v, fr, _ = _one_node(0.4 * mu_n, k_t=k_t)  # peak dynamic load 0.8 mu N: stays elastic
    assert u == pytest.approx(0.4 * mu_n / k_t, rel=1e-4)  # elastic stick: F / k_t
    assert np.abs(fr).max() < mu_n
    # above mu N (no damping): after the elastic ramp the friction is mu N and the node accelerates uniformly
    force, m = 2.0 * mu_n, 1e-4
    u, v, fr, dt = _one_node(force, k_t=k_t, mass_kg=m, damping_per_s=0.0, t_end_s=2e-3)
    assert fr[-1] == pytest.approx(-mu_n, rel=1e-12)
    a = (force - mu_n) / m
    assert v == pytest.approx(a * 2e-3, rel=0.02)


@pytest.mark.parametrize("element_mm", [2.0, 1.0, 0.5])
def test_flat_plane_sn_equals_law_at_every_element_size(element_mm):
    law = ExponentialDecay(0.45, 0.3, 0.5)
    cfg = SolverConfig(element_mm=element_mm, slide_length_mm=3.0, window_start_mm=1.0, friction_model="penalty")
    r = simulate(FlatPlane(), 40.0, law, cfg)
    assert r.sn == pytest.approx(float(law.mu_kmh(40.0)), rel=0.005)
    # on a flat plane the law is sampled at the sliding speed
    assert r.mean_slip_speed_ms == pytest.approx(40.0 / 3.6, rel=0.01)


@pytest.mark.parametrize("friction_model", ["penalty", "stick_limit"])
def test_push_up_the_flank_of_a_sinusoid_gives_the_onset_force_ratio(friction_model):
    """Front-edge line contact on the steepest rising flank of a 200 mm corrugation (slope 0.2): the pavement
    force ratio F_x / F_z of a block pushed quasi-statically up a slope tan theta is
    (mu + tan theta) / (1 - mu tan theta); curvature over the 2 mm slide changes the slope by 0.1 %."""
    mu, slope, lam = 0.3, 0.2, 0.2
    cfg = SolverConfig(
        element_mm=2.0, slide_length_mm=2.0, window_start_mm=0.5, friction_model=friction_model, edge_margin_mm=0.5
    )
    x_front_mid = 0.5e-3 + 20e-3 + 1.0e-3  # front edge at mid-slide, m
    surf = corrugation_flank(slope, lam, x_front_mid)
    assert surf.evaluate(np.array([x_front_mid]), np.array([0.0]))[1][0] == pytest.approx(slope)
    r = simulate(surf, 1.0, ConstantFriction(mu), cfg)  # 1 km/h: quasi-static
    assert r.sn == pytest.approx((mu + slope) / (1 - mu * slope), rel=0.001)  # measured -0.006 %
    # only the front row of nodes touches (the face is flat, the flank rises under it)
    tr = r.trace[r.trace["position_mm"] >= cfg.window_start_mm]
    assert tr["contact_nodes"].max() <= 2 * (cfg.slider_width_mm / cfg.element_mm + 1)


def test_rayleigh_fit_and_step_factor():
    eta, band = 0.2, (300.0, 6000.0)
    a, b = rayleigh_coefficients(eta, band)
    assert loss_factor_at(band[0], a, b) == pytest.approx(eta, rel=1e-12)
    assert loss_factor_at(band[1], a, b) == pytest.approx(eta, rel=1e-12)
    assert loss_factor_at(math.sqrt(band[0] * band[1]), a, b) < eta  # lower inside the band
    assert damped_step_factor(1e6, 0.0, 0.0) == 1.0
    xi = 0.5 * b * 1e6
    assert damped_step_factor(1e6, 0.0, b) == pytest.approx(math.sqrt(1 + xi * xi) - xi)


def test_penalty_friction_and_rayleigh_on_a_texture_balance_energy_and_shrink_the_step():
    tex = SinusoidalSurface(amplitude_m=0.1e-3, wavelength_x_m=4e-3, wavelength_y_m=5e-3)
    law = ExponentialDecay(0.4, 0.35, 0.6)
    # a tangential penalty 4x the normal one (E / h_z = 5e10 Pa/m at 2 mm), so that it sets the step bound below
    base = SolverConfig(
        element_mm=2.0,
        slide_length_mm=6.0,
        window_start_mm=2.0,
        friction_model="penalty",
        friction_stiffness_pa_per_m=2e11,
        slide_damping_model="mass",
    )
    r0 = simulate(tex, 40, law, base)
    cfg = base.replace(slide_damping_model="rayleigh", loss_band_hz=(1e3, 1e5))
    r1 = simulate(tex, 40, law, cfg)
    a, b = rayleigh_coefficients(cfg.loss_factor, cfg.loss_band_hz)
    assert r1.dt_s == pytest.approx(r0.dt_s * damped_step_factor(r0.omega_max_rad_s, a, b), rel=1e-12)
    for r in (r0, r1):
        assert r.energy_residual_fraction() < 0.01
        assert r.energies["friction"] > 0 and r.energies["damping"] > 0
        assert 0.3 < r.sn < 0.45
    # the tangential penalty enters the step bound: omega_max^2 >= k_t / m of an interior bottom node
    # (tributary area h^2, lumped mass rho h^3 / 2)
    h = base.element_mm * 1e-3
    k_t_over_m = base.friction_stiffness_pa_per_m * h * h / (base.density_kg_m3 * h**3 / 2)
    assert r0.omega_max_rad_s**2 >= k_t_over_m


def test_bad_options_name_the_field():
    with pytest.raises(ConfigError, match="friction_model"):
        SolverConfig(friction_model="coulomb")
    with pytest.raises(ConfigError, match="slide_damping_model"):
        SolverConfig(slide_damping_model="stiffness")
    with pytest.raises(ConfigError, match="loss_band_hz"):
        SolverConfig(loss_band_hz=(6000.0, 300.0))
    with pytest.raises(ConfigError, match="friction_stiffness_pa_per_m"):
        SolverConfig(friction_stiffness_pa_per_m=0.0)
    assert SolverConfig.from_dict({"loss_band_hz": [100, 200]}).loss_band_hz == (100.0, 200.0)


def _bits(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def test_scalar_paths_of_the_contact_laws_give_the_array_paths_bits():
    """Small contact sets take Python-float paths (``contact.SCALAR_MAX_NODES``): every output bit for bit (signs of
    zeros included) the array paths', on random nodes around a heightfield, with stick, slip and zero velocities."""
    from skidsim.solver.contact import normal_contact, penalty_step
    from skidsim.solver.surfaces import RandomTexture, SurfaceBound, to_heightfield

    hf = to_heightfield(RandomTexture(extent_m=(0.0, 0.02, -0.01, 0.01)), 0.5e-3)
    bound = SurfaceBound(hf)
    rng = np.random.default_rng(5)
    n = 40
    law = ExponentialDecay(0.5, 0.3, 0.4)
    n_stick = n_slip = 0
    for trial in range(12):
        xyz = np.stack([rng.uniform(0.0, 0.02, n), rng.uniform(-0.01, 0.01, n), np.zeros(n)])
        xyz[2] = hf.evaluate(xyz[0], xyz[1])[0] + rng.uniform(-4e-5, 1e-4, n)
        k_pen, area = rng.uniform(1e3, 1e5, n), rng.uniform(1e-7, 1e-6, n)
        ft0 = rng.standard_normal((3, n)) * rng.uniform(0.0, 0.05, n)
        for normal_gap in (True, False):
            out = []
            for scalar_max in (0, n):  # the array path, the scalar path
                c = normal_contact(hf, bound, xyz.copy(), k_pen, area, normal_gap, np.arange(n), scalar_max)
                m = c.ia.size
                vt = np.random.default_rng(trial).standard_normal((3, m)) * (np.arange(m) % 4 != 0)  # some at rest
                ft = ft0.copy()
                fric, stick, s = penalty_step(ft, vt, np.full(m, 1e-3), c, law.mu, scalar_max)
                out.append((c, fric.copy(), stick, s, ft))
            (ca, *ra), (cs, *rs) = out
            assert ca.ia.size > 0 and np.array_equal(ca.ia, cs.ia)
            for name in ("d_m", "gx", "gy", "kd_n", "force_n", "normal_n", "normal", "rows"):
                assert np.array_equal(_bits(getattr(ca, name)), _bits(getattr(cs, name))), name
            for a, b in zip(ra, rs):
                assert np.array_equal(_bits(a), _bits(b))
            n_stick, n_slip = n_stick + ra[1].sum(), n_slip + (~ra[1]).sum()
    assert n_stick > 10 and n_slip > 10
