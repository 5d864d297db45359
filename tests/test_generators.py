"""The independent campaign generators (skidsim.generators): determinism, the data contract, the friction models'
recovery from generated traces, the instrument features of the scans and the texture-to-friction relations.

Small campaigns (6 sites in 3 sections, 300 x 600 points at 0.2 mm) built once per module. Fits here use
scipy.optimize.curve_fit / numpy least squares written in the test, not the generators' own formulas.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import curve_fit

from skidsim import generators
from skidsim.campaign import load_campaign
from skidsim.errors import ConfigError
from skidsim.generators import friction_models
from skidsim.surface import Surface
from skidsim.texture import mean_profile_depth
from skidsim.x3p import read_x3p

ROOT = Path(__file__).resolve().parents[1]
SMALL = {"n_sites": 6, "shape": [300, 600], "spacing_mm": 0.2}


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    out = {}
    for gen in ("chips", "spectral"):
        d = tmp_path_factory.mktemp(gen)
        design = generators.write_campaign(d / "campaign", gen, SMALL)
        cfg = generators.generator_config(gen, SMALL)
        sites = {row["site"]: generators.generate_site(row, cfg) for _, row in design.iterrows()}
        out[gen] = {"dir": d / "campaign", "truth": d / "campaign-truth", "design": design, "cfg": cfg, "sites": sites}
    return out


# --- determinism and the data contract -------------------------------------------------------------------------


@pytest.mark.parametrize("gen", ["chips", "spectral"])
def test_same_seed_same_bytes_and_site_alone_equals_site_in_campaign(campaigns, gen, tmp_path):
    c = campaigns[gen]
    row = c["design"].iloc[3]
    data = generators.generate_site(row, c["cfg"])  # generated alone, again
    site = row["site"]
    generators.write_site(data, tmp_path / "a.x3p", tmp_path / "a.csv", tmp_path / "a.json")
    assert (tmp_path / "a.x3p").read_bytes() == (c["dir"] / "scans" / f"{site}.x3p").read_bytes()
    assert (tmp_path / "a.csv").read_bytes() == (c["dir"] / "dft" / f"{site}.csv").read_bytes()
    assert (tmp_path / "a.json").read_bytes() == (c["truth"] / f"{site}.json").read_bytes()
    other = generators.generate_site(row, generators.generator_config(gen, {**SMALL, "seed": 7}))
    assert not np.array_equal(np.nan_to_num(other.surface.heights), np.nan_to_num(data.surface.heights))


@pytest.mark.parametrize("gen", ["chips", "spectral"])
def test_campaign_passes_validation_and_reads_back(campaigns, gen):
    c = campaigns[gen]
    camp = load_campaign(c["dir"], check_scans="full")
    assert len(camp.sites) == 6
    assert sorted(camp.sites["section"].unique()) == ["S01", "S02", "S03"]
    assert (c["dir"].parent / "campaign-truth").is_dir() and not (c["dir"] / "truth").exists()
    site = "S02-1"
    back = read_x3p(c["dir"] / "scans" / f"{site}.x3p")
    h = c["sites"][site].surface.heights
    assert back.dx == pytest.approx(0.2) and back.heights.shape == (300, 600)
    np.testing.assert_array_equal(np.isnan(back.heights), np.isnan(h))
    np.testing.assert_allclose(back.heights, h, atol=1e-9, equal_nan=True)
    pts = camp.dft_points()
    assert set(pts["speed_kmh"]) == {20.0, 30.0, 40.0, 50.0, 60.0, 70.0}


def test_generators_do_not_use_our_own_generator_or_truth_model():
    code = (
        "import sys\nfrom skidsim import generators\n"
        "cfg = generators.generator_config('chips', {'n_sites': 3, 'shape': [20, 600], 'spacing_mm': 0.2})\n"
        "generators.generate_site(generators.design_campaign(cfg).iloc[0], cfg)\n"
        "print(sorted(m for m in sys.modules if m in ('skidsim.generators.default', 'skidsim.generators.truth')))\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env=dict(os.environ, PYTHONPATH=str(ROOT / "src")),
    )
    assert r.stdout.strip() == "[]"


def test_bad_settings_raise_one_clear_error():
    with pytest.raises(ConfigError, match="unknown key 'n_site'"):
        generators.generator_config("chips", {"n_site": 3})
    with pytest.raises(ConfigError, match="expected one of chips, spectral, got 'gravel'"):
        generators.generator_config("gravel")
    with pytest.raises(ConfigError, match="friction.model: expected one of piarc, rado, penn_state, got 'linear'"):
        generators.generator_config("spectral", {"friction": {"model": "linear"}})


def test_cli_writes_a_valid_campaign(tmp_path):
    from skidsim.cli import main

    out = tmp_path / "camp"
    assert (
        main(
            [
                "synth",
                str(out),
                "--generator",
                "spectral",
                "--sites",
                "3",
                "--shape",
                "60",
                "600",
                "--spacing-mm",
                "0.2",
                "--seed",
                "5",
            ]
        )
        == 0
    )
    camp = load_campaign(out)
    assert list(camp.sites["site"]) == ["S01-1", "S02-1", "S03-1"]
    truth = json.loads((tmp_path / "camp-truth" / "S02-1.json").read_text())
    assert truth["friction_model"] == "rado" and truth["seed"] == 5


# --- friction models recovered from the generated traces -------------------------------------------------------


def _noise_free(gen: str, model: str | None = None):
    over = {**SMALL, "n_sites": 3, "dft": {"noise_mu": 0.0}}
    if model:
        over["friction"] = {"model": model}
    cfg = generators.generator_config(gen, over)
    return [generators.generate_site(r, cfg) for _, r in generators.design_campaign(cfg).iterrows()]


def test_piarc_sp_recovered_from_a_noise_free_trace():
    for s in _noise_free("chips"):
        v, mu = s.dft["speed_kmh"].to_numpy(), s.dft["mu"].to_numpy()
        (a, sp), _ = curve_fit(lambda v, a, sp: a * np.exp(-v / sp), v, mu, p0=(0.8, 80.0))
        t = s.truth["parameters"]
        assert sp == pytest.approx(t["sp_kmh"], rel=0.01)
        assert a * np.exp(-20.0 / sp) == pytest.approx(t["mu20"], abs=0.002)
        # Sp from the published relation on the MPD of the clean surface, times the section and site factors
        mpd = s.truth["texture_measures"]["mpd_mm"]
        f = s.truth["section_sp_factor"] * s.truth["site_sp_factor"]
        assert t["sp_kmh"] == pytest.approx((14.2 + 89.7 * mpd) * f, rel=1e-12)


def test_rado_parameters_recovered_from_a_noise_free_trace():
    for s in _noise_free("spectral"):
        v, mu = s.dft["speed_kmh"].to_numpy(), s.dft["mu"].to_numpy()
        t = s.truth["parameters"]
        model = friction_models.evaluate("rado", t, v)
        below = model <= friction_models.MU_SATURATION_START  # above it the low-speed end is saturated (next test)
        np.testing.assert_allclose(mu, friction_models.saturate(model), atol=6e-4)
        L = np.log(v[below])
        c2, c1, c0 = np.polyfit(L, np.log(mu[below]), 2)  # ln mu = ln mu_p - (L - ln v_p)^2 / C^2
        C = np.sqrt(-1.0 / c2)
        v_peak = np.exp(c1 * C**2 / 2)
        assert C == pytest.approx(t["c"], rel=0.01)
        assert v_peak == pytest.approx(t["v_peak_kmh"], rel=0.05)
        assert 1.0 <= t["v_peak_kmh"] <= 4.0 < v.min()  # the peak lies below the trace: mu falls over it
        # the log-slope at 40 km/h is the IFI's -1/Sp
        slope = np.log(friction_models.mu_rado(40.5, t["mu_peak"], t["v_peak_kmh"], t["c"])) - np.log(
            friction_models.mu_rado(39.5, t["mu_peak"], t["v_peak_kmh"], t["c"])
        )
        assert slope == pytest.approx(-1.0 / t["sp_kmh"], rel=1e-3)


def test_saturation_keeps_plausible_friction_and_bends_the_rest_below_the_ceiling():
    """``saturate``: the same floats up to mu 1.0, then continuous with slope 1, increasing and below 1.3 (checked
    against the closed form and by finite differences); a Rado site of high level on shallow texture, whose model
    reaches mu 1.75 at the end of a spin-down, gives a true curve within the DFT reader's range (0, 1.5) that equals
    the model wherever the model is at most 1.0."""
    m0, top = friction_models.MU_SATURATION_START, friction_models.MU_CEILING
    mu = np.linspace(0.05, 3.0, 2951)
    out = friction_models.saturate(mu)
    low = mu <= m0
    np.testing.assert_array_equal(out[low], mu[low])
    assert np.all(out[~low] < top) and np.all(out[~low] > m0) and np.all(np.diff(out) > 0)
    w = top - m0
    np.testing.assert_allclose(out[~low], m0 + w * np.tanh((mu[~low] - m0) / w), rtol=1e-15)
    eps = 1e-7  # slope 1 on both sides of m0
    assert (friction_models.saturate(m0 + eps) - m0) / eps == pytest.approx(1.0, abs=1e-6)
    assert friction_models.saturate(10.0) == pytest.approx(top, abs=1e-12)
    params = friction_models.model_parameters("rado", 0.85, 0.3, v_peak_kmh=2.0)  # Sp 41 km/h, C 2.48
    v = np.linspace(85.0, 5.0, 161)
    model = friction_models.evaluate("rado", params, v)
    assert model.max() > 1.7  # the unsaturated model at 5 km/h (mu_peak 2.0 at v_peak 2 km/h)
    fr = {"friction_model": "rado", "parameters": params, "hidden": {"effect": None}}
    true = generators.site_mu(fr, v)
    assert 1.2 < true.max() < top < 1.5
    np.testing.assert_array_equal(true[model <= m0], model[model <= m0])


def test_penn_state_png_recovered_from_a_noise_free_trace():
    for s in _noise_free("chips", "penn_state"):
        v, mu = s.dft["speed_kmh"].to_numpy(), s.dft["mu"].to_numpy()
        slope, _ = np.polyfit(v, np.log(mu), 1)
        t = s.truth["parameters"]
        assert -100.0 * slope == pytest.approx(t["png_pct_per_kmh"], rel=0.01)
        mpd = s.truth["texture_measures"]["mpd_mm"]
        f = s.truth["section_sp_factor"] * s.truth["site_sp_factor"]
        assert t["png_pct_per_kmh"] == pytest.approx(0.94 * mpd**-0.84 / f, rel=1e-12)


def test_hidden_squeeze_effect_multiplies_the_model_by_its_factor():
    """A hidden texture-and-speed effect: the noise-free trace is the model times ``1 - kappa (v^2 - 400) / Sp^2``
    with Sp = (14.2 + 89.7 MPD) x the site's factors (checked against the published relation, not the factor
    function); the scan is unchanged (friction draws no texture random numbers)."""
    kappa = 0.3
    base = {**SMALL, "n_sites": 2, "dft": {"noise_mu": 0.0}}
    for gen in ("chips", "spectral"):
        plain = generators.generator_config(gen, base)
        hidden = generators.generator_config(
            gen, {**base, "friction": {"hidden_effect": "squeeze", "hidden_kappa": kappa}}
        )
        for (_, r0), (_, r1) in zip(
            generators.design_campaign(plain).iterrows(), generators.design_campaign(hidden).iterrows()
        ):
            s0, s1 = generators.generate_site(r0, plain), generators.generate_site(r1, hidden)
            np.testing.assert_array_equal(s0.surface.heights, s1.surface.heights)
            assert s0.truth["hidden"]["effect"] is None and s1.truth["hidden"]["effect"] == "squeeze"
            v = s1.dft["speed_kmh"].to_numpy()
            t = s1.truth
            sp = (14.2 + 89.7 * t["texture_measures"]["mpd_mm"]) * t["section_sp_factor"] * t["site_sp_factor"]
            model = friction_models.evaluate(t["friction_model"], t["parameters"], v)
            # the trace: mu rounded to 0.001, speeds to 0.01 km/h
            np.testing.assert_allclose(s1.dft["mu"].to_numpy(), model * (1 - kappa * (v * v - 400) / sp**2), atol=1e-3)
            np.testing.assert_allclose(s0.dft["mu"].to_numpy(), model, atol=1e-3)
            at = np.array(t["curve"]["speed_kmh"]) == 20.0
            assert np.array(t["curve"]["mu"])[at][0] == pytest.approx(t["mu20"], rel=1e-12)
            assert s1.dft["mu"].iloc[0] < s0.dft["mu"].iloc[0] - 0.01  # a visible loss at 80 km/h


def test_bad_hidden_effect_settings_raise_naming_the_key():
    with pytest.raises(ConfigError, match="friction.hidden_effect"):
        generators.generator_config("chips", {"friction": {"hidden_effect": "aquaplane"}})
    with pytest.raises(ConfigError, match="friction.hidden_kappa"):
        generators.generator_config("spectral", {"friction": {"hidden_effect": "drainage", "hidden_kappa": -1}})


def test_trace_is_a_spin_down_with_the_configured_noise(campaigns):
    resid = []
    for s in campaigns["chips"]["sites"].values():
        v = s.dft["speed_kmh"].to_numpy()
        assert np.all(np.diff(v) < 0) and 80.0 <= v[0] <= 85.0 and 5.0 <= v[-1] < 5.7
        assert np.median(-np.diff(v)) == pytest.approx(0.5, abs=0.02)
        t = s.truth
        resid.append(s.dft["mu"].to_numpy() - friction_models.evaluate(t["friction_model"], t["parameters"], v))
    sd = np.std(np.concatenate(resid))
    assert sd == pytest.approx(0.01, rel=0.15)


# --- texture: the instrument's features and the two structures -------------------------------------------------


@pytest.mark.parametrize("gen", ["chips", "spectral"])
def test_scanner_features_quantisation_spikes_dropouts(campaigns, gen):
    for s in campaigns[gen]["sites"].values():
        h = read_x3p(campaigns[gen]["dir"] / "scans" / f"{s.truth['site']}.x3p").heights
        fin = np.isfinite(h)
        codes = h[fin] / 0.01
        assert np.max(np.abs(codes - np.round(codes))) < 1e-6  # integer codes of 0.01 mm
        assert (~fin).sum() == round(0.005 * h.size)  # dropouts: exactly 0.5 % of the points
        spikes = np.abs(h[fin] - s.clean[fin]) > 2.0  # tilt < 0.25 mm, spikes 3-5 mm
        assert spikes.sum() == round(0.0005 * h.size)
        d = (h - s.clean)[fin][spikes]
        assert (d > 0).any() and (d < 0).any() and np.abs(d).max() < 5.3


def _modal_share(row: np.ndarray) -> float:
    _, counts = np.unique(np.round(row[np.isfinite(row)] / 0.01), return_counts=True)
    return counts.max() / row.size


def test_chips_binder_is_flat_spectral_field_is_not(campaigns):
    chips = [_modal_share(r) for s in campaigns["chips"]["sites"].values() for r in s.surface.heights[::10]]
    spec = [_modal_share(r) for s in campaigns["spectral"]["sites"].values() for r in s.surface.heights[::10]]
    assert np.mean(np.array(chips) > 0.5) > 0.8  # most rows: over half the points on one height code
    assert max(spec) < 0.1
    for s in campaigns["chips"]["sites"].values():  # positive skew: chips standing on a plane
        z = s.clean - s.clean.mean()
        assert np.mean(z**3) / np.std(z) ** 3 > 0.3
        assert 0.2 < s.truth["layout"]["chip_share"] < 0.5
    for s in campaigns["spectral"]["sites"].values():  # negative skew: plateaus and deep voids
        z = s.clean - s.clean.mean()
        assert np.mean(z**3) / np.std(z) ** 3 < -0.5


def test_texture_measures_are_skidsim_texture_on_the_clean_surface(campaigns):
    s = campaigns["spectral"]["sites"]["S01-2"]
    m = s.truth["texture_measures"]
    ref = mean_profile_depth(Surface(s.clean, 0.2, 0.2), segment_mm=m["mpd_segment_mm"]).mpd_mm
    assert m["mpd_mm"] == pytest.approx(ref, rel=1e-12)
    assert m["mpd_segment_mm"] == 100.0 and m["micro_cut_mm"] == pytest.approx(1.0)


# --- texture drives friction as the published relations say ---------------------------------------------------


@pytest.fixture(scope="module")
def larger():
    """36 sites in 12 sections of narrow scans at each generator's own spacing (0.05 / 0.1 mm; 8 mm wide, 122 mm
    long: MPD profiles of one 100 mm segment)."""
    rows = []
    for gen, shape in (("chips", [160, 2448]), ("spectral", [80, 1224])):
        cfg = generators.generator_config(gen, {"n_sites": 36, "shape": shape})
        for _, r in generators.design_campaign(cfg).iterrows():
            t = generators.generate_site(r, cfg).truth
            rows.append(
                {
                    "gen": gen,
                    "mpd": t["texture_measures"]["mpd_mm"],
                    "sp": t["parameters"]["sp_kmh"],
                    "micro": t["texture_measures"]["micro_sq_mm"],
                    "mu20": t["mu20"],
                    "micro_rms": t["layout"]["micro_rms_mm"],
                }
            )
    return pd.DataFrame(rows)


@pytest.mark.parametrize("gen", ["chips", "spectral"])
def test_sp_follows_the_ifi_relation_with_mpd(larger, gen):
    d = larger[larger["gen"] == gen]
    assert d["mpd"].max() - d["mpd"].min() > 0.6  # a range of macrotexture to fit over
    slope, intercept = np.polyfit(d["mpd"], d["sp"], 1)
    assert slope == pytest.approx(89.7, rel=0.2)
    assert np.corrcoef(d["mpd"], d["sp"])[0, 1] > 0.9


@pytest.mark.parametrize("gen", ["chips", "spectral"])
def test_level_rises_with_microtexture(larger, gen):
    d = larger[larger["gen"] == gen]
    assert d["mu20"].between(0.3, 0.9).all()
    rank = d[["micro", "mu20"]].rank()
    assert np.corrcoef(rank["micro"], rank["mu20"])[0, 1] > 0.6
    # the micro measure follows the generated microtexture amplitude
    rank = d[["micro", "micro_rms"]].rank()
    assert np.corrcoef(rank["micro"], rank["micro_rms"])[0, 1] > 0.6


# --- the benchmark's baseline (OLS on at most two texture parameters) ------------------------------------------


def _bench():
    path = ROOT / "benchmarks" / "independent_campaigns.py"
    spec = importlib.util.spec_from_file_location("independent_campaigns", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_baseline_finds_a_planted_pair():
    b = _bench()
    rng = np.random.default_rng(2)
    X = pd.DataFrame(
        rng.normal(size=(24, 8)),
        columns=[f"raw_p{k}" for k in range(8)],
        index=[f"S{k // 3}-{k % 3 + 1}" for k in range(24)],
    )
    speeds = np.array([20, 30, 40, 50, 60, 70.0])
    Y = 0.6 + 0.05 * X["raw_p2"].to_numpy()[:, None] - 0.03 * X["raw_p5"].to_numpy()[:, None] * speeds / 40
    Y = Y + rng.normal(0, 0.003, Y.shape)
    groups = np.repeat([f"S{k}" for k in range(8)], 3)
    res = b.baseline_cv(X, Y, groups)
    assert res["r2"] > 0.95
    assert set(res["chosen"]) == {"raw_p2+raw_p5"}


@pytest.mark.parametrize("form", ["identity", "log"])
def test_physics_prior_finds_the_form_of_a_planted_relation(form):
    """The benchmark's physics prior (OLS of the DFT on profile_MPD and micro_Sq, as they are or as logs by inner
    section CV) picks the planted form in every fold and predicts held-out sections."""
    b = _bench()
    rng = np.random.default_rng(3)
    n = 30
    X = pd.DataFrame(
        {
            "profile_MPD": rng.uniform(0.3, 2.0, n),
            "micro_Sq": rng.uniform(0.003, 0.06, n),
            "raw_noise": rng.normal(size=n),
        },
        index=[f"S{k // 3}-{k % 3 + 1}" for k in range(n)],
    )
    tx = np.log if form == "log" else (lambda z: z / z.std())
    speeds = np.array([20, 30, 40, 50, 60, 70.0])
    Y = (
        0.6
        + 0.05 * tx(X["micro_Sq"].to_numpy())[:, None]
        + 0.04 * tx(X["profile_MPD"].to_numpy())[:, None] * (speeds / 40.0)[None, :]
    )
    Y = Y + rng.normal(0, 0.002, Y.shape)
    res = b.physics_prior_cv(X, Y, np.repeat([f"S{k}" for k in range(n // 3)], 3))
    assert res["chosen"] == [form] * (n // 3)
    assert res["r2"] > 0.95
    assert b.physics_prior_cv(X.drop(columns="micro_Sq"), Y, np.repeat(np.arange(n // 3), 3)) is None
