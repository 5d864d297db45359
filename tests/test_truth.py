"""Tests of the truth friction model (skidsim.generators.truth): descriptors, base curve, each effect, DFT trace."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from skidsim.errors import ConfigError
from skidsim.friction import ExponentialDecay
from skidsim.generators import truth as T

DESC = {"mpd_mm": 0.8, "micro_sq_mm": 0.025, "micro_sdq": 0.33, "ssk": -1.4}
ROW = {"site": "E1-1", "section": "E1", "mix": "HMA", "temperature_c": 15.8, "test_order": 1}


def cfg_with(**effects):
    """Truth config with every effect disabled except the ones given (name -> dict of overrides)."""
    cfg = T.default_truth_config()
    for name in T.EFFECT_ORDER:
        cfg["effects"][name]["enabled"] = False
    for name, over in effects.items():
        cfg["effects"][name].update({"enabled": True, **over})
    return cfg


# ------------------------------------------------------------------------------------------------ descriptors


def test_mpd_of_a_sine_profile():
    """MSD of a sine of amplitude A is A; the 0.5 mm bin mean scales it by sinc(w / lambda)."""
    dx, lam, amp = 0.05, 10.0, 0.7
    x = np.arange(2448) * dx
    # a cosine even about the centre of the (centred, 100 mm) segment, plus a slope that the per-segment fit
    # removes exactly
    h = np.tile(amp * np.cos(2 * np.pi * (x - 61.0) / lam) + 0.004 * x, (16, 1))
    expected = amp * math.sin(math.pi * 0.5 / lam) / (math.pi * 0.5 / lam)
    assert T.mpd_mm(h, dx, row_step=4) == pytest.approx(expected, rel=0.01)
    # dropouts are interpolated
    h2 = h.copy()
    h2[:, 300:310] = np.nan
    assert T.mpd_mm(h2, dx, row_step=4) == pytest.approx(expected, rel=0.01)


def test_micro_descriptors_of_a_sine():
    """Micro band = 1 - Gaussian transmission exp(-pi (a lc / lam)^2), a = sqrt(ln2 / pi)."""
    dx, lam, amp, lc = 0.05, 0.4, 0.02, 0.5
    x = np.arange(800) * dx
    h = np.tile(amp * np.sin(2 * np.pi * x / lam), (64, 1))
    keep = 1 - math.exp(-math.pi * (math.sqrt(math.log(2) / math.pi) * lc / lam) ** 2)
    d = T.micro_descriptors(h, dx, dx, lc)
    assert d["micro_sq_mm"] == pytest.approx(keep * amp / math.sqrt(2), rel=0.03)
    # central-difference gradient of a sampled sine: amplitude * sin(k dx) / dx
    k = 2 * math.pi / lam
    assert d["micro_sdq"] == pytest.approx(keep * amp * math.sin(k * dx) / dx / math.sqrt(2), rel=0.03)


def test_skewness_of_a_two_level_surface():
    h = np.zeros((10, 100))
    h[:, :20] = -1.0  # 20 % valleys: Bernoulli skewness -(1 - 2q) / sqrt(q (1 - q)), q = 0.2
    assert T.skewness(h) == pytest.approx(-(1 - 0.4) / math.sqrt(0.16), rel=1e-9)


# ------------------------------------------------------------------------------------------------ model


def test_null_truth_is_the_exponential_decay_family():
    tr = T.site_truth(DESC, ROW, cfg_with())
    v = np.linspace(5, 85, 33)
    b = tr["base"]
    law = ExponentialDecay(b["mu_s"], b["mu_k"], b["alpha_s_per_m"])
    assert np.allclose(T.mu_true(v, tr), law.mu_kmh(v), rtol=0, atol=1e-14)
    for name, c in T.contributions(v, tr).items():
        assert np.all(c == 0.0), name
    # base terms: adhesion from micro slope, hysteresis from MPD (documented formulas)
    bc = T.default_truth_config()["base"]
    assert b["mu_k"] == pytest.approx(bc["mu_k0"] + bc["mu_k1"] * (1 - math.exp(-0.33 / bc["sdq_ref"])))
    assert b["mu_s"] - b["mu_k"] == pytest.approx(bc["h0"] + bc["h1"] * 0.8)
    assert b["alpha_s_per_m"] == pytest.approx(bc["alpha0_s_per_m"])  # MPD = mpd_ref


def test_wlf_shift_values():
    assert T.wlf_log10_shift(15.8, 15.8) == 0.0
    # Ts = Tg + 50 = 0 deg C: -8.86*11.8/113.4 + 8.86*15.8/117.4
    assert T.wlf_log10_shift(11.8, 15.8) == pytest.approx(-8.86 * 11.8 / 113.4 + 8.86 * 15.8 / 117.4, rel=1e-12)
    assert T.wlf_log10_shift(11.8, 15.8) > 0 > T.wlf_log10_shift(18.9, 15.8)


def test_temperature_effect_is_the_configured_wlf_shift():
    cfg = cfg_with(temperature={"level_per_c": -0.005})
    cold = T.site_truth(DESC, ROW | {"temperature_c": 12.0}, cfg)
    warm = T.site_truth(DESC, ROW | {"temperature_c": 18.5}, cfg)
    a_c, a_w = cold["effects"]["temperature"]["a_T"], warm["effects"]["temperature"]["a_T"]
    assert math.log10(a_c / a_w) == pytest.approx(T.wlf_log10_shift(12.0, 18.5), rel=1e-12)
    lc, lw = 1 - 0.005 * (12.0 - 15.8), 1 - 0.005 * (18.5 - 15.8)
    v = np.linspace(5, 60, 12)
    # mu_cold(v) / L_cold = base(a_c v) = mu_warm(v a_c / a_w) / L_warm
    assert np.allclose(T.mu_true(v, cold) / lc, T.mu_true(v * a_c / a_w, warm) / lw, rtol=1e-12)
    # recovered from noise-free spin-down traces by a 1-D search over the log shift
    rng = np.random.default_rng(0)
    dft = {"noise_cv": 0.0, "mu_decimals": 9}
    sc, mc, _ = T.spin_down_trace(cold, dft, rng)
    sw, mw, _ = T.spin_down_trace(warm, dft, rng)
    order = np.argsort(sw)
    shifts = np.linspace(-0.5, 0.5, 2001)
    sel = sc < 40
    err = [np.sum((mc[sel] / lc - np.interp(sc[sel] * 10**s, sw[order], mw[order] / lw)) ** 2) for s in shifts]
    assert shifts[int(np.argmin(err))] == pytest.approx(math.log10(a_c / a_w), abs=0.002)


def test_drainage_effect_follows_ifi_speed_constant():
    cfg = cfg_with(drainage={"size": 0.4})
    v = np.array([5.0, 20.0, 40.0, 60.0, 80.0])
    for mpd in (0.4, 1.5):
        d = DESC | {"mpd_mm": mpd}
        on = T.site_truth(d, ROW, cfg)
        off = T.site_truth(d, ROW, cfg_with())
        sp = 14.2 + 89.7 * mpd
        assert on["effects"]["drainage"]["sp_kmh"] == pytest.approx(sp)
        assert np.allclose(T.mu_true(v, on) / T.mu_true(v, off), np.exp(-0.4 * (v - 20.0) / sp), rtol=1e-12)
    # deeper texture drains better: the speed gradient is flatter
    lo = T.site_truth(DESC | {"mpd_mm": 0.4}, ROW, cfg)
    hi = T.site_truth(DESC | {"mpd_mm": 1.5}, ROW, cfg)
    ratio = lambda tr: T.mu_true(60.0, tr) / T.mu_true(20.0, tr)  # noqa: E731
    assert ratio(hi) > ratio(lo)


def test_squeeze_drainage_is_quadratic_in_speed_and_floored():
    """form "squeeze": 1 - size (v^2 - v_ref^2) / Sp^2, floored; an unknown form is refused."""
    cfg = cfg_with(drainage={"size": 0.3, "form": "squeeze"})
    v = np.array([5.0, 20.0, 40.0, 70.0])
    for mpd in (0.5, 1.4):
        d = DESC | {"mpd_mm": mpd}
        on = T.site_truth(d, ROW, cfg)
        off = T.site_truth(d, ROW, cfg_with())
        sp = 14.2 + 89.7 * mpd
        expected = 1.0 - 0.3 * (v**2 - 400.0) / sp**2
        assert np.allclose(T.mu_true(v, on) / T.mu_true(v, off), expected, rtol=1e-12)
    # the loss accelerates with speed (concave), unlike the exponential-decay law
    f = T.drainage_factor(
        np.array([20.0, 45.0, 70.0]), {"sp_kmh": 60.0, "size": 0.3, "v_ref_kmh": 20.0, "form": "squeeze", "floor": 0.05}
    )
    assert f[0] - f[1] < f[1] - f[2]
    low = T.drainage_factor(300.0, {"sp_kmh": 60.0, "size": 0.3, "v_ref_kmh": 20.0, "form": "squeeze", "floor": 0.05})
    assert low == pytest.approx(0.05)
    with pytest.raises(ConfigError, match="drainage.form"):
        T.check_truth_config({"effects": {"drainage": {"form": "hydro"}}})


def test_metadata_and_section_effects():
    cfg = cfg_with(metadata={"column": "test_order", "size": -0.004}, section={"offsets": {"E6": 0.05}})
    first = T.site_truth(DESC, ROW, cfg)
    late = T.site_truth(DESC, ROW | {"test_order": 31}, cfg)
    e6 = T.site_truth(DESC, ROW | {"section": "E6"}, cfg)
    v = np.array([20.0, 60.0])
    assert np.allclose(T.mu_true(v, late) / T.mu_true(v, first), 1 - 0.004 * 30, rtol=1e-12)
    assert np.allclose(T.mu_true(v, e6) - T.mu_true(v, first), 0.05, atol=1e-12)
    assert np.allclose(T.contributions(v, first)["section"], 0.0)
    with pytest.raises(ConfigError, match="no_col"):
        T.site_truth(DESC, ROW, cfg_with(metadata={"column": "no_col"}))
    with pytest.raises(ConfigError, match="bogus"):
        T.site_truth(DESC, ROW, {"effects": {"bogus": {}}})


def test_a_low_speed_section_effect_is_the_offset_times_its_speed_ramp():
    """``speed_shape: low_speed``: a polished aggregate's sections lose the offset in full up to 20 km/h, half at
    40 km/h and nothing from 60 km/h (closed form); other sections and the level shape are unchanged; bad shapes and
    speed pairs are refused naming the key."""
    sec = {"column": "mix", "offsets": {"WMA": -0.12}, "speed_shape": "low_speed"}
    cfg = cfg_with(section=sec)
    plain = T.site_truth(DESC, ROW, cfg)
    wma = T.site_truth(DESC, ROW | {"mix": "WMA"}, cfg)
    v = np.array([5.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0])
    ramp = np.array([1.0, 1.0, 0.75, 0.5, 0.25, 0.0, 0.0])
    np.testing.assert_allclose(T.mu_true(v, wma) - T.mu_true(v, plain), -0.12 * ramp, atol=1e-12)
    np.testing.assert_allclose(T.contributions(v, wma)["section"], -0.12 * ramp, atol=1e-12)
    assert wma["effects"]["section"]["speed_shape"] == "low_speed"
    level = T.site_truth(DESC, ROW | {"mix": "WMA"}, cfg_with(section={**sec, "speed_shape": "level"}))
    np.testing.assert_array_equal(T.mu_true(v, level), T.mu_true(v, plain) - 0.12)
    with pytest.raises(ConfigError, match="section.speed_shape"):
        T.check_truth_config({"effects": {"section": {"speed_shape": "high_speed"}}})
    with pytest.raises(ConfigError, match="section.low_speed_kmh"):
        T.check_truth_config({"effects": {"section": {"low_speed_kmh": [60, 20]}}})


def test_contributions_add_up_and_truth_reproducible():
    cfg = T.default_truth_config()
    cfg["effects"]["metadata"]["enabled"] = True
    cfg["effects"]["section"]["enabled"] = True
    row = ROW | {"section": "E6", "test_order": 20, "temperature_c": 13.1}
    tr = T.site_truth(DESC, row, cfg)
    v = np.linspace(5, 80, 16)
    c = T.contributions(v, tr)
    steps = T.mu_steps(v, tr)
    assert np.allclose(steps["base"] + sum(c.values()), T.mu_true(v, tr), atol=1e-14)
    assert all(np.any(np.abs(c[n]) > 1e-3) for n in T.EFFECT_ORDER)
    tr2 = T.site_truth(copy.deepcopy(DESC), dict(row), copy.deepcopy(cfg))
    assert tr == tr2
    assert json.loads(json.dumps(tr)) == tr
    assert np.allclose(tr["curve"]["total"], T.mu_true(tr["curve"]["speeds_kmh"], tr), atol=1e-6)


def test_default_truth_gives_realistic_dft_levels():
    """Over the campaign's descriptor and temperature ranges: DFT20 in 0.35-0.85, decreasing with speed."""
    for mpd in (0.4, 0.8, 1.6):
        for sdq in (0.2, 0.3, 0.45):
            for temp in (11.8, 15.8, 18.9):
                tr = T.site_truth(DESC | {"mpd_mm": mpd, "micro_sdq": sdq}, ROW | {"temperature_c": temp})
                mu = T.mu_true(np.array([20.0, 40.0, 60.0, 80.0]), tr)
                assert 0.35 <= mu[0] <= 0.85, (mpd, sdq, temp, mu)
                assert np.all(np.diff(mu) < 0)
                assert 0.5 < mu[2] / mu[0] < 0.95


def test_spin_down_trace_sampling_and_noise():
    tr = T.site_truth(DESC, ROW)
    s, m, true = T.spin_down_trace(tr, None, np.random.default_rng(1))
    assert 80.0 <= s[0] <= 86.0 and 5.0 <= s[-1] < 6.5
    steps = -np.diff(s)
    assert steps.min() > 0.3 and steps.max() < 1.2 and 0.5 < steps.mean() < 1.0
    # step proportional to friction (disk deceleration by the friction torque)
    assert np.allclose(steps, 0.8 * T.mu_true(s[:-1], tr) / 0.5, atol=0.011)
    assert np.allclose(true, T.mu_true(s, tr))
    # a long trace: noise CV and lag-one correlation as configured
    cfg = {"step_kmh_at_mu_0_5": 0.02, "mu_decimals": 9}
    s, m, true = T.spin_down_trace(tr, cfg, np.random.default_rng(2))
    r = m / true - 1
    assert r.size > 3000
    assert r.std() == pytest.approx(0.03, rel=0.1)
    lag1 = np.corrcoef(r[:-1], r[1:])[0, 1]
    assert lag1 == pytest.approx((1 - 0.3) * 0.7, abs=0.06)
    # same generator seed, same trace
    a = T.spin_down_trace(tr, None, np.random.default_rng(5))
    b = T.spin_down_trace(tr, None, np.random.default_rng(5))
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
