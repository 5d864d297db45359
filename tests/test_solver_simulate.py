"""Whole-simulation verification: flat-plane SN = mu, exponential law, preload, energy balance, time-step
convergence, outputs and input errors."""

import numpy as np
import pandas as pd
import pytest

from skidsim.errors import ConfigError
from skidsim.friction import ConstantFriction, ExponentialDecay
from skidsim.solver import FlatPlane, SinusoidalSurface, SolverConfig, TiltedPlane, simulate

FAST = SolverConfig(element_mm=2.0, slide_length_mm=10.0, window_start_mm=4.0)
TEX = SinusoidalSurface(amplitude_m=0.1e-3, wavelength_x_m=4e-3, wavelength_y_m=5e-3)
TEX_CFG = SolverConfig(element_mm=1.0, slide_length_mm=8.0, window_start_mm=2.0)


@pytest.mark.parametrize("speed_kmh", [20, 40, 60, 80])
def test_flat_plane_constant_mu(speed_kmh):
    r = simulate(FlatPlane(), speed_kmh, ConstantFriction(0.45), FAST)
    assert r.sn == pytest.approx(0.45, rel=0.005)
    assert r.normal_n == pytest.approx(FAST.load_n, rel=0.02)  # short window: start-up transient in the mean


def test_flat_plane_exponential_law_every_speed():
    """A steep law (mu falls 0.05 per m/s at 10 km/h) needs a longer settling slide than a constant mu: the
    Rayleigh damping is light at the slider's bounce frequency (measured at 10 km/h: +1.1 % with a 10 mm slide,
    +0.3 % with 30 mm)."""
    law = ExponentialDecay(mu_s=0.8, mu_k=0.3, alpha=0.15)
    cfg = FAST.replace(slide_length_mm=30.0, window_start_mm=10.0)
    for v in (10, 30, 50, 70):
        r = simulate(FlatPlane(z0_m=1e-3), v, law, cfg)
        assert r.sn == pytest.approx(float(law.mu_kmh(v)), rel=0.01), v


def test_static_preload_contact_force_equals_load():
    for surf in (FlatPlane(), TEX):
        r = simulate(surf, 20, ConstantFriction(0.4), TEX_CFG.replace(slide_length_mm=2.0, window_start_mm=0.5))
        assert r.preload_contact_force_n == pytest.approx(TEX_CFG.load_n, rel=0.005)
    # on the texture the slider rests on the crests: much less than the full face is in contact
    assert r.preload_contact_area_mm2 < 0.5 * 20 * 16


def test_energy_balance_textured_run():
    r = simulate(TEX, 20, ExponentialDecay(0.6, 0.35, 0.3), TEX_CFG)
    e = r.energies
    assert e["external"] > 0 and e["friction"] > 0 and e["damping"] >= 0
    assert e["hourglass"] == 0.0
    assert abs(e["residual"]) < 0.01 * e["external"]
    # friction dissipation ~ SN-independent estimate: mean friction force x distance within a factor
    assert 0.2 < e["friction"] / (r.normal_n * 0.35 * r.slide_length_mm * 1e-3) < 3


def test_energy_balance_viscoelastic_run():
    cfg = TEX_CFG.replace(prony_g=(0.5,), prony_tau_s=(5e-5,), slide_length_mm=4.0)
    r = simulate(TEX, 20, ConstantFriction(0.4), cfg)
    assert r.energies["viscous"] > 0
    assert abs(r.energies["residual"]) < 0.01 * r.energies["external"]


def test_halving_time_step_changes_sn_less_than_one_percent():
    # a texture the slider can follow at 20 km/h (a k^2 < load / mass): no flight phases, so the response is
    # not chaotic and the comparison measures the time-discretisation error
    gentle = SinusoidalSurface(amplitude_m=0.05e-3, wavelength_x_m=5e-3, wavelength_y_m=6e-3)
    law = ExponentialDecay(0.6, 0.35, 0.3)
    a = simulate(gentle, 20, law, TEX_CFG)
    b = simulate(gentle, 20, law, TEX_CFG.replace(dt_safety=TEX_CFG.dt_safety / 2))
    assert b.dt_s == pytest.approx(a.dt_s / 2, rel=1e-9)
    assert b.sn == pytest.approx(a.sn, rel=0.01)
    # the texture is felt: partial contact and a fluctuating normal force (flat: constant to 1e-4)
    assert a.mean_contact_area_mm2 < 0.8 * 20 * 16
    assert a.trace["normal_n"].std() > 0.01 * TEX_CFG.load_n


def test_tilted_plane_geometry():
    """On a plane tilted in y (no slope along x) sliding in x, the pavement force is inclined: SN = mu still
    holds for the x force over the vertical force times the normal's z component."""
    s = 0.05
    r = simulate(TiltedPlane(slope_y=s), 20, ConstantFriction(0.4), FAST)
    # normal force along n = (0, -s, 1)/sqrt(1+s^2): vertical component of N is N/sqrt(1+s^2)
    assert r.sn == pytest.approx(0.4 * np.sqrt(1 + s * s), rel=0.01)


def test_outputs_trace_and_vtu(tmp_path):
    # mass-proportional slide damping: with the default Rayleigh damping a flat plane carries a friction-induced
    # limit cycle in which some bottom nodes lift for a moment (docs/solver.md, "Known limitations")
    cfg = FAST.replace(vtu_frames=3, slide_damping_model="mass")
    calls = []
    r = simulate(
        FlatPlane(),
        30,
        ConstantFriction(0.4),
        cfg.replace(progress_every_s=1e-9),
        trace_path=tmp_path / "t.parquet",
        vtu_dir=tmp_path / "vtu",
        progress=lambda *a: calls.append(a),
    )
    t = pd.read_parquet(tmp_path / "t.parquet")
    assert list(t.columns) == [
        "time_s",
        "position_mm",
        "tangential_n",
        "normal_n",
        "contact_area_mm2",
        "friction_x_n",
        "contact_nodes",
        "stick_nodes",
        "slip_speed_ms",
    ]
    # flat plane: the whole resisting force is friction, every bottom node is in contact, none held by the limit
    assert np.allclose(t["friction_x_n"], t["tangential_n"], rtol=1e-9, atol=1e-12)
    steady = t[t["position_mm"] >= cfg.window_start_mm]  # (2 of the 99 nodes lift briefly at the start)
    assert (steady["contact_nodes"] == (cfg.slider_length_mm / 2 + 1) * (cfg.slider_width_mm / 2 + 1)).all()
    assert (steady["stick_nodes"] == 0).all()
    # the law sees the sliding speed on a flat plane (normal-force-weighted slip speed, m/s)
    assert steady["slip_speed_ms"].mean() == pytest.approx(30 / 3.6, rel=0.01)
    assert r.mean_slip_speed_ms == pytest.approx(30 / 3.6, rel=0.01)
    # per-phase wall times: all six phases timed, together not more than the run
    ph = r.meta["phase_s"]
    assert set(ph) == {"internal_force", "damping_load", "contact", "friction", "update", "output", "setup_and_rest"}
    assert all(v >= 0 for v in ph.values()) and sum(ph.values()) == pytest.approx(r.wall_s, rel=1e-6)
    assert t["position_mm"].iloc[-1] == pytest.approx(r.slide_length_mm, abs=0.1)
    assert len(list((tmp_path / "vtu").glob("*.vtu"))) == 3 and (tmp_path / "vtu" / "slider.pvd").exists()
    assert calls and calls[-1][0] == r.n_steps
    import meshio

    m = meshio.read(sorted((tmp_path / "vtu").glob("*.vtu"))[-1])
    assert m.points.shape[0] == (cfg.slider_length_mm / 2 + 1) * (cfg.slider_width_mm / 2 + 1) * 4
    assert m.point_data["contact_pressure_pa"].max() > 0


def test_slide_clamped_to_strip_and_errors():
    short = FlatPlane(extent_m=(0.0, 0.05, -0.01, 0.01))
    r = simulate(short, 20, ConstantFriction(0.4), FAST.replace(slide_length_mm=100.0))
    assert r.slide_clamped and r.slide_length_mm == pytest.approx(50 - 20 - 2 * FAST.edge_margin_mm)
    with pytest.raises(ConfigError, match="slide_length_mm"):
        simulate(short, 20, ConstantFriction(0.4), FAST.replace(slide_length_mm=100.0, clamp_slide=False))
    with pytest.raises(ConfigError, match="y_offset_mm"):
        simulate(short, 20, ConstantFriction(0.4), FAST, y_offset_mm=5.0)
    with pytest.raises(ConfigError, match="speed_kmh"):
        simulate(short, 0.0, ConstantFriction(0.4), FAST)
    with pytest.raises(ConfigError, match="mass_scaling"):
        SolverConfig(mass_scaling=0.5)
    with pytest.raises(ConfigError, match="unknown"):
        SolverConfig.from_dict({"element_size": 1.0})
    assert SolverConfig.from_dict({"prony_g": [0.2], "prony_tau_s": [1e-4]}).prony_g == (0.2,)


def test_mesh_study_script_and_plots(tmp_path):
    import runpy

    from skidsim.plotting.solver import plot_trace

    mod = runpy.run_path("benchmarks/mesh_study.py", run_name="mesh_study")
    rc = mod["main"](
        [
            str(tmp_path / "m.csv"),
            str(tmp_path / "m.png"),
            "--sizes",
            "2",
            "1.5",
            "--speeds",
            "60",
            "--slide-mm",
            "8",
            "--window-mm",
            "3",
            "--pavement",
            "sinusoid",
        ]
    )
    assert rc == 0
    t = pd.read_csv(tmp_path / "m.csv")
    assert len(t) == 2 and t.loc[t["element_mm"] == 1.5, "error_pct"].item() == 0.0
    assert (tmp_path / "m.png").stat().st_size > 1000
    r = simulate(FlatPlane(), 40, ConstantFriction(0.4), FAST)
    plot_trace(r.trace, tmp_path / "t.png", window_mm=r.window_mm)
    assert (tmp_path / "t.png").exists()


class _NoBound:
    """The same Heightfield without its bicubic cells: the solver then evaluates every bottom node."""

    def __init__(self, hf):
        self.hf = hf
        self.extent = hf.extent

    def evaluate(self, x, y):
        return self.hf.evaluate(x, y)


def test_contact_candidate_pruning_is_exact():
    """The per-cell Bernstein bound (SurfaceBound) only skips nodes that cannot touch: same run to round-off."""
    from skidsim.solver.surfaces import SurfaceBound, to_heightfield

    hf = to_heightfield(
        SinusoidalSurface(
            amplitude_m=0.2e-3, wavelength_x_m=3e-3, wavelength_y_m=4e-3, extent_m=(0.0, 0.04, -0.01, 0.01)
        ),
        0.25e-3,
    )
    b = SurfaceBound(hf)
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-1e-3, 0.041, 200_000), rng.uniform(-0.011, 0.011, 200_000)
    z, _, _ = hf.evaluate(x, y)
    slack = b.zmax_m.take(b.cells(x.copy(), y.copy())) - z
    assert slack.min() >= 0.0  # an upper bound everywhere (also outside the grid)
    assert np.median(slack) < 0.2 * 0.2e-3 * 2  # and a useful one (well below the peak-to-valley height)
    cfg = TEX_CFG.replace(slide_length_mm=3.0, window_start_mm=1.0)
    law = ExponentialDecay(0.6, 0.35, 0.3)
    a = simulate(hf, 40, law, cfg)
    c = simulate(_NoBound(hf), 40, law, cfg)
    assert a.n_steps == c.n_steps and a.mean_contact_area_mm2 < 0.5 * 20 * 16
    assert a.sn == pytest.approx(c.sn, rel=1e-10)
    assert np.allclose(a.trace["tangential_n"], c.trace["tangential_n"], rtol=1e-9, atol=1e-12)
    assert (a.trace["contact_nodes"] == c.trace["contact_nodes"]).all()


def test_contact_gap_and_penalty_length_options():
    """contact_gap 'normal': normal stiffness k on any slope, so the slope leaves the time-step bound; the
    statics are unchanged (SN = mu sqrt(1+s^2) on a plane tilted across the slide). penalty_length_mm equal to
    the element height is the default penalty; a longer one is softer (deeper penetration, longer dt)."""
    s = 0.5
    law = ConstantFriction(0.4)
    vert = simulate(TiltedPlane(slope_y=s), 20, law, FAST)
    norm = simulate(TiltedPlane(slope_y=s), 20, law, FAST.replace(contact_gap="normal"))
    assert norm.dt_s > vert.dt_s
    assert norm.meta["slope_bound"] == pytest.approx(s * s, rel=1e-6)
    assert norm.sn == pytest.approx(0.4 * np.sqrt(1 + s * s), rel=0.01)
    # same contact force, (1 + s^2) times softer along the normal: deeper vertical penetration
    assert norm.max_penetration_um == pytest.approx(vert.max_penetration_um * (1 + s * s), rel=0.05)
    # a tangential penalty softer than both normal ones, so that the normal penalty sets the step bound
    cfg = FAST.replace(friction_stiffness_pa_per_m=1e10)
    same = simulate(FlatPlane(), 20, law, cfg.replace(penalty_length_mm=FAST.element_mm))
    base = simulate(FlatPlane(), 20, law, cfg)
    assert same.sn == pytest.approx(base.sn, rel=1e-12) and same.dt_s == pytest.approx(base.dt_s, rel=1e-12)
    soft = simulate(FlatPlane(), 20, law, cfg.replace(penalty_length_mm=4 * FAST.element_mm))
    # 4x softer: deeper (the largest penetration is a dynamic peak: measured 1.9x with the default Rayleigh
    # damping, 2.9x with the mass-proportional slide damping), a longer stable step, SN still mu
    assert soft.max_penetration_um > 1.5 * base.max_penetration_um and soft.dt_s > base.dt_s
    assert soft.sn == pytest.approx(0.4, rel=0.005)
    for bad in (dict(contact_gap="sideways"), dict(penalty_length_mm=0.0)):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            SolverConfig(**bad)
