"""FE extension (viscoelastic slider): held-out-speed gain, the g = 0 identity, the workflow decision and wiring."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from conftest import run_snakemake

from skidsim.criticism.fe_extension import (
    DEFAULT_PRONY,
    campaign_speed_gain,
    fe_extension_decision,
    fe_gain_record,
    prony_moduli,
    site_fe_gain,
    site_speed_gain,
    viscoelastic_solver_cfg,
)
from skidsim.errors import ConfigError
from skidsim.friction import ExponentialDecay
from skidsim.solver import SinusoidalSurface, SolverConfig, simulate

VAL = [30.0, 50.0, 70.0]
MEAS = {20.0: 0.6, 30.0: 0.5, 40.0: 0.45, 50.0: 0.4, 60.0: 0.35, 70.0: 0.3}


def test_site_gain_known_answer():
    before = {30.0: 0.52, 50.0: 0.43, 70.0: 0.34, 20.0: 9.0}  # 20 km/h is a calibration speed: ignored
    after = {30.0: 0.51, 50.0: 0.39, 70.0: 0.30}
    g = site_speed_gain(MEAS, before, after, VAL)
    assert g["n"] == 3 and g["speeds_kmh"] == VAL
    assert g["rmse_before"] == pytest.approx(0.01 * math.sqrt(29 / 3), abs=1e-12)  # residuals 0.02, 0.03, 0.04
    assert g["rmse_after"] == pytest.approx(0.01 * math.sqrt(2 / 3), abs=1e-12)  # 0.01, -0.01, 0
    assert g["rmse_gain"] == pytest.approx(0.01 * (math.sqrt(29 / 3) - math.sqrt(2 / 3)), abs=1e-12)
    # a validation speed missing from one simulation is left out
    g2 = site_speed_gain(MEAS, before, {30.0: 0.51, 50.0: 0.39}, VAL)
    assert g2["n"] == 2 and g2["rmse_before"] == pytest.approx(0.01 * math.sqrt(13 / 2), abs=1e-12)
    with pytest.raises(ValueError, match="no validation speed"):
        site_speed_gain(MEAS, {20.0: 0.6}, {20.0: 0.6}, VAL)


def test_campaign_gain_pooled_and_bootstrap():
    a = site_speed_gain(MEAS, {30.0: 0.52, 50.0: 0.43, 70.0: 0.34}, {30.0: 0.51, 50.0: 0.39, 70.0: 0.30}, VAL)
    b = site_speed_gain(MEAS, {30.0: 0.46, 50.0: 0.40, 70.0: 0.30}, {30.0: 0.55, 50.0: 0.40, 70.0: 0.30}, VAL)
    agg = campaign_speed_gain({"A": a, "B": b}, n_boot=500, seed=3)
    # pooled: before residuals 0.02 0.03 0.04 -0.04 0 0 -> SSE 45e-4; after 0.01 -0.01 0 0.05 0 0 -> 27e-4
    assert agg["rmse_before"] == pytest.approx(math.sqrt(45e-4 / 6), abs=1e-12)
    assert agg["rmse_after"] == pytest.approx(math.sqrt(27e-4 / 6), abs=1e-12)
    assert agg["n_sites"] == 2 and agg["n_points"] == 6
    lo, hi = agg["rmse_gain_ci"]
    # resamples {A, A}, {A, B}, {B, B}: the extremes are site A's and site B's own gains (n equal per site)
    ga = a["rmse_gain"]
    gb = math.sqrt(16e-4 / 3) - math.sqrt(25e-4 / 3)  # site B got worse: -0.0058 SN
    assert b["rmse_gain"] == pytest.approx(gb, abs=1e-12)
    assert lo == pytest.approx(min(ga, gb), abs=1e-12) and hi == pytest.approx(max(ga, gb), abs=1e-12)
    assert agg["gain_excludes_zero"] is False  # site B got worse
    assert campaign_speed_gain({"A": a, "B": b}, n_boot=500, seed=3) == agg  # seeded
    # identical sites: every resample gives the same gain, the interval is a point and excludes zero
    same = campaign_speed_gain({"A": a, "C": a}, n_boot=200, seed=0)
    assert same["rmse_gain_ci"] == pytest.approx([a["rmse_gain"]] * 2, abs=1e-12)
    assert same["gain_excludes_zero"] is True


def test_fe_gain_record_applied_and_not():
    """fe_gain.json: the decision and named cause always; where applied, the per-site entries (with the
    recalibrated law), the pooled campaign gain with the given bootstrap settings, the Prony series and speeds."""
    from types import SimpleNamespace

    from skidsim.criticism import DiagnosisOptions

    law = SimpleNamespace(params=SimpleNamespace(mu_s=0.8, mu_k=0.3, alpha=0.05), converged=True, n_fe_runs=7)
    a = site_fe_gain(MEAS, {30.0: 0.52, 50.0: 0.43, 70.0: 0.34}, {30.0: 0.51, 50.0: 0.39, 70.0: 0.30}, VAL, law)
    b = site_fe_gain(MEAS, {30.0: 0.46, 50.0: 0.40, 70.0: 0.30}, {30.0: 0.55, 50.0: 0.40, 70.0: 0.30}, VAL, law)
    assert a["params_viscoelastic"] == {"mu_s": 0.8, "mu_k": 0.3, "alpha": 0.05} and a["n_fe_runs_viscoelastic"] == 7
    opts = DiagnosisOptions(n_boot=500, seed=3)
    rec = fe_gain_record(
        "always", [CAUSE_T], {"A": a, "B": b}, prony=DEFAULT_PRONY, validation_speeds_kmh=VAL, options=opts
    )
    assert rec["applied"] and rec["named_cause"]["variable"] == "temperature_c"
    assert rec["held_out_speeds"] == campaign_speed_gain({"A": a, "B": b}, n_boot=500, seed=3)
    assert rec["held_out_speeds"]["rmse_before"] == pytest.approx(math.sqrt(45e-4 / 6), abs=1e-12)
    assert rec["prony"]["prony_tau_s"] == DEFAULT_PRONY["prony_tau_s"] and rec["validation_speeds_kmh"] == VAL
    off = fe_gain_record("auto", [CAUSE_T])
    assert not off["applied"] and "held_out_speeds" not in off and "not a within-site shape" in off["reason"]
    with pytest.raises(ValueError, match="not inputs"):
        fe_gain_record("always", [], None)


CAUSE_T = {"variable": "temperature_c", "level": "between-site", "kind": "main", "significant": True}
CAUSE_FF = {"variable": "functional_form", "level": "within-site", "kind": "functional_form", "significant": True}
CAUSE_MPD = {
    "variable": "macro_Sa",
    "level": "within-site",
    "kind": "x_speed",
    "group": ["macro_Sa", "profile_MPD"],
    "significant": True,
}


@pytest.mark.parametrize(
    "mode, causes, applied",
    [
        ("auto", [CAUSE_T, CAUSE_FF], False),  # first entry names the cause: temperature
        ("auto", [CAUSE_FF, CAUSE_T], True),
        ("auto", [CAUSE_MPD], True),
        ("auto", [dict(CAUSE_MPD, level="between-site")], False),
        ("auto", [dict(CAUSE_FF, level="between-site")], False),
        ("auto", [dict(CAUSE_FF, significant=False)], False),
        ("auto", [], False),
        ("always", [CAUSE_T], True),
        ("always", [], True),
        ("never", [CAUSE_FF], False),
    ],
)
def test_decision(mode, causes, applied):
    ok, reason = fe_extension_decision(mode, causes)
    assert ok is applied
    assert mode in reason


def test_decision_and_cfg_errors():
    with pytest.raises(ConfigError, match="fe_extension"):
        fe_extension_decision("sometimes", [])
    with pytest.raises(ConfigError, match="equal"):
        viscoelastic_solver_cfg({"preset": "quick"}, {"prony_g": [0.5], "prony_tau_s": []})
    cfg = viscoelastic_solver_cfg({"preset": "quick", "overrides": {"element_mm": 3.0}})
    assert cfg["overrides"] == {"element_mm": 3.0, "prony_g": [0.5, 0.5, 0.5], "prony_tau_s": [1e-5, 1e-4, 1e-3]}


def test_default_prony_loss_factor_in_band():
    """The default series dissipates in the DFT's excitation band: tan(delta) 0.15-0.25 from 160 Hz to 10 kHz."""
    f = np.array([160.0, 1e3, 1e4])
    storage, loss = prony_moduli(f, **DEFAULT_PRONY)
    assert np.all((loss / storage > 0.14) & (loss / storage < 0.25)), loss / storage
    assert storage[0] < storage[1] < storage[2] < 1 + sum(DEFAULT_PRONY["prony_g"])


def test_zero_prony_equals_elastic():
    """A Prony series with g = 0 is the elastic solver to round-off (tiny mesh, short slide)."""
    tex = SinusoidalSurface(amplitude_m=0.1e-3, wavelength_x_m=4e-3, wavelength_y_m=5e-3)
    cfg = SolverConfig(element_mm=2.0, slide_length_mm=8.0, window_start_mm=3.0)
    law = ExponentialDecay(0.5, 0.3, 0.1)
    e = simulate(tex, 40.0, law, cfg)
    v = simulate(tex, 40.0, law, cfg.replace(prony_g=(0.0,), prony_tau_s=(1e-4,)))
    w = simulate(tex, 40.0, law, cfg.replace(prony_g=(1.0,), prony_tau_s=(1e-4,)))
    assert e.n_steps == v.n_steps
    assert v.sn == pytest.approx(e.sn, rel=1e-10, abs=1e-12)
    assert abs(w.sn - e.sn) > 1e-6  # a real branch does change SN: the comparison can fail


def _dry(tmp_path, mode):
    (tmp_path / "tiny.yaml").write_text(
        "synthetic:\n  seed: 5\n  sections: [E1, E6, C2]\n  sites_per_section: 1\n  shape: [300, 600]\n"
        "  spacing_mm: 0.2\nsolver:\n  preset: quick\ncalibration:\n  methods: [ours]\nmesh_study:\n  sizes_mm: []\n"
        f"diagnosis:\n  fe_extension: {mode}\n"
    )
    r = run_snakemake(
        "-n", "results/diagnosis/fe_gain.json", workdir=tmp_path, configfiles=[tmp_path / "tiny.yaml"], timeout=300
    )
    out = r.stdout + r.stderr
    return {
        m.group(1): int(m.group(2))
        for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", out, flags=re.M)
        if m.group(1) != "total"
    }


@pytest.mark.parametrize("mode, n_recal, checkpoint", [("always", 3, 0), ("never", 0, 0), ("auto", 0, 1)])
def test_workflow_wiring(tmp_path, mode, n_recal, checkpoint):
    """always: one viscoelastic recalibration per site; never: none and no diagnosis; auto: none before the
    diagnosis checkpoint has named the cause (the checkpoint is scheduled instead)."""
    counts = _dry(tmp_path, mode)
    assert counts.get("fe_gain") == 1, counts
    assert counts.get("fe_recalibrate", 0) == n_recal, counts
    assert counts.get("diagnosis", 0) == checkpoint, counts
