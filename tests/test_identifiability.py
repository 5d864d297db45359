"""Tests of skidsim.calibration.identifiability: the per-site quality flags and what a trace determines of the law.

Surrogate FE: SN = 1.05 mu(v + 5 km/h) (a geometric factor and a slip-speed excess, the physics of our
calibration's surrogate), so the mapping the calibration learns is exercised; no FE solver.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from skidsim.calibration import (
    DEFAULT_BOUNDS,
    CalibrationResult,
    FEOutcome,
    JointOptions,
    calibrate_fast,
    simulate_speeds,
)
from skidsim.calibration.identifiability import (
    FLAGS,
    IdentifiabilityOptions,
    SurrogateMap,
    assess,
    curve_combinations,
    table_row,
    trace_noise,
)
from skidsim.errors import ConfigError
from skidsim.friction import ExponentialDecay
from skidsim.generators.friction_models import mu_piarc, mu_rado
from skidsim.runlog import write_json

G, D_KMH = 1.05, 5.0
CAL, VAL = (20.0, 40.0, 60.0), (30.0, 50.0, 70.0)
SPEEDS = np.arange(84.0, 5.0, -0.5)  # a spin-down trace, km/h


def smooth_fe(speed_kmh, law):
    return FEOutcome(sn=G * float(law.mu_kmh(speed_kmh + D_KMH)), n_steps=1000, wall_s=0.0)


def trace_of(mu_fn, noise_sd, seed):
    rng = np.random.default_rng(seed)
    return pd.DataFrame({"speed_kmh": SPEEDS, "mu": mu_fn(SPEEDS) + rng.normal(0.0, noise_sd, SPEEDS.size)})


def law_trace(law, noise_sd, seed):
    """The trace the smooth FE would give for ``law`` (the DFT the law explains exactly) plus white noise."""
    return trace_of(lambda v: G * law.mu_kmh(v + D_KMH), noise_sd, seed)


def calibrate_and_assess(trace, simulate=smooth_fe, joint=None, **opts):
    res = calibrate_fast(simulate, trace, JointOptions(max_fe_runs=12, **(joint or {})))
    val = simulate_speeds(simulate, res.params, CAL + VAL).assign(method="ours")
    rec = assess(
        res,
        trace,
        val,
        options=IdentifiabilityOptions(**opts),
        calibration_speeds_kmh=CAL,
        validation_speeds_kmh=VAL,
        site="S1",
    )
    return res, rec


def test_trace_noise_recovers_white_noise_on_a_curved_law():
    law = ExponentialDecay(0.85, 0.2, 0.4)
    sig = [
        trace_noise(
            SPEEDS, law.mu_kmh(SPEEDS) + np.random.default_rng(s).normal(0, 0.01, SPEEDS.size), range_kmh=(20, 70)
        )["sigma"]
        for s in range(8)
    ]
    assert 0.0085 < np.median(sig) < 0.0115
    few = trace_noise(np.array([20.0, 40.0, 60.0]), np.array([0.5, 0.4, 0.35]))
    assert np.isnan(few["sigma"])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_known_law_no_flags_and_intervals_cover_truth(seed):
    truth = ExponentialDecay(mu_s=0.75, mu_k=0.30, alpha=0.15)
    res, rec = calibrate_and_assess(law_trace(truth, 0.005, seed))
    assert res.converged
    assert rec["flags"] == [], rec["reasons"]
    assert rec["within_noise"]
    assert 0.004 < rec["noise"]["sigma"] < 0.0065
    unc = rec["uncertainty"]
    for p in ("mu_s", "mu_k", "alpha"):
        pr = unc["params"][p]
        assert pr["profile_lower"] <= getattr(truth, p) <= pr["profile_upper"], (p, pr)
        assert not (pr["lower_open"] or pr["upper_open"]), (p, pr)
        assert pr["se"] > 0
    # the profile and the Gauss-Newton picture agree roughly where the problem is nearly linear (level)
    assert unc["combinations"]["level"]["identified"] and unc["combinations"]["slope"]["identified"]
    level = unc["combinations"]["level"]
    assert abs(level["value"] - truth.mu_kmh(40.0)) < 4 * level["se"] + 1e-3


def test_rado_hump_is_outside_the_law():
    # Rado's log-normal curve peaking at 32 km/h: rises then falls over 20-60 km/h; no exponential decay follows it
    trace = trace_of(lambda v: mu_rado(v, 0.70, 32.0, 0.9), 0.004, 5)
    _, rec = calibrate_and_assess(trace)
    assert "outside_law" in rec["flags"]
    assert "sigma" in rec["reasons"]["outside_law"]
    assert rec["fit"]["rmse_best_law_wide"] > 1.5 * rec["noise"]["sigma"]
    assert not rec["within_noise"]


def test_parameter_at_bound_is_flagged_with_the_bound_and_its_cost():
    # PIARC curve mu20 0.75, Sp 40 km/h: mu at 0 km/h is 1.24, beyond the mu_s bound 0.85
    trace = trace_of(lambda v: G * mu_piarc(v + D_KMH, 0.75, 40.0), 0.005, 7)
    res, rec = calibrate_and_assess(trace)  # the study's bounds (the default)
    assert res.params.mu_s == pytest.approx(0.85, abs=1e-9)
    assert "at_bound" in rec["flags"]
    assert {"param": "mu_s", "bound": "upper"}.items() <= rec["at_bound"][0].items()
    assert "mu_s = 0.85 at its upper bound 0.85" in rec["reasons"]["at_bound"]
    assert rec["uncertainty"]["params"]["mu_s"]["upper_open"]
    assert rec["fit"]["bound_cost_rmse"] >= 0.0
    # with the reach (reach_mu_s_max 1.5) the site is fitted with mu_s up to 1.5: near the curve's 1.24, judged against
    # the bounds it used (mu_k stays at its 0, as PIARC has no offset), and better at the calibration speeds
    wide, rec_wide = calibrate_and_assess(trace, joint={"reach_mu_s_max": 1.5})
    assert wide.settings["reach"]["used"] and wide.settings["bounds"]["mu_s"] == [0.0, 1.5]
    assert 1.1 < wide.params.mu_s < 1.4 and all(a["param"] != "mu_s" for a in rec_wide["at_bound"])  # mu_k at 0
    assert rec_wide["fit"]["rmse_fe_calibration"] < rec["fit"]["rmse_fe_calibration"]


def test_straight_window_non_identified_direction_is_mu_k_alpha_tradeoff():
    # a default-campaign-like law (its fits: alpha 0.02-0.13 s/m): over 20-60 km/h the curve is nearly straight
    truth = ExponentialDecay(mu_s=0.68, mu_k=0.20, alpha=0.05)
    res, rec = calibrate_and_assess(law_trace(truth, 0.01, 11))
    unc = rec["uncertainty"]
    weakest = unc["directions"][0]
    vec = weakest["vector_range_units"]
    assert not weakest["identified"]
    assert abs(vec["mu_k"]) == max(abs(x) for x in vec.values())  # mu_k carries the weak direction
    assert vec["alpha"] * vec["mu_k"] > 0  # higher mu_k goes with faster decay (the two branches)
    assert unc["directions"][-1]["identified"]
    assert not unc["params"]["mu_k"]["identified"]
    assert unc["combinations"]["level"]["identified"] and unc["combinations"]["slope"]["identified"]
    assert "not identified: the direction" in rec["statement"]
    # moving along the weak direction by its half-width changes the fitted curve by less than the noise
    w = np.array([b[1] - b[0] for b in (DEFAULT_BOUNDS[p] for p in ("mu_s", "mu_k", "alpha"))])
    step = weakest["halfwidth_range_fraction"] * np.array([vec[p] for p in ("mu_s", "mu_k", "alpha")]) * w * 0.5
    p0 = np.array([res.params.mu_s, res.params.mu_k, res.params.alpha])
    moved = ExponentialDecay(*(p0 + step))
    v = np.arange(20.0, 60.5, 1.0)
    assert np.sqrt(np.mean((moved.mu_kmh(v) - res.params.mu_kmh(v)) ** 2)) < rec["noise"]["sigma"]


def test_rough_fe_response_is_flagged_not_smooth():
    def rough(speed_kmh, law):  # a smooth law mapped through an FE response with +-0.05 jumps between nearby laws
        jump = 0.05 * np.sign(np.sin(4000.0 * law.mu_s + 7000.0 * law.alpha + 3.0 * speed_kmh))
        return FEOutcome(sn=G * float(law.mu_kmh(speed_kmh + D_KMH)) + float(jump), n_steps=1000, wall_s=0.0)

    truth = ExponentialDecay(mu_s=0.75, mu_k=0.30, alpha=0.15)
    res, rec = calibrate_and_assess(law_trace(truth, 0.005, 3), simulate=rough)
    assert "fe_not_smooth" in rec["flags"]
    assert not res.converged and "not_converged" in rec["flags"]
    assert rec["fe_misses"]["verify_corrected_max"] > 0.03 or rec["fe_misses"]["validation_max"] > 0.03


def test_fe_smoothness_miss_is_measured_after_small_steps_against_the_whole_step_surrogate():
    """``verify_corrected_max`` compares the FE with the whole-step prediction ``sn_pred_whole`` where the history
    has it (histories stored without it use ``sn_pred``); ``verify_all_max`` stays the miss of the surrogate used.
    The ``fe_not_smooth`` miss ``small_step_max`` counts only batches whose law moved by at most ``small_step_mu``
    from the batch before (alpha 0: mu = mu_s at every speed, so the step is |d mu_s|)."""
    from types import SimpleNamespace

    from skidsim.calibration.identifiability.smoothness import fe_misses

    mu_s = [0.50, 0.60, 0.62, 0.63]  # steps: -, 0.10, 0.02, 0.01
    h = pd.DataFrame(
        {
            "stage": "verify",
            "iteration": np.repeat([1, 2, 3, 4], 2),
            "speed_kmh": [20.0, 60.0] * 4,
            "mu_s": np.repeat(mu_s, 2),
            "mu_k": 0.2,
            "alpha": 0.0,
            "sn_sim": [0.50, 0.40, 0.66, 0.55, 0.53, 0.42, 0.60, 0.50],
            "sn_pred": [0.45, 0.40, 0.60, 0.55, 0.49, 0.42, 0.60, 0.50],  # relaxed: 0.04 at iteration 3
            "sn_pred_whole": [0.45, 0.40, 0.60, 0.55, 0.525, 0.42, 0.59, 0.50],  # whole: 0.06 (large step), 0.005, 0.01
        }
    )
    m = fe_misses(SimpleNamespace(history=h, method="ours"), None, None, (20.0, 60.0), small_step_mu=0.03)
    assert m["verify_all_max"] == pytest.approx(0.06)
    assert m["verify_corrected_max"] == pytest.approx(0.06)  # the large step's miss
    assert m["small_step_max"] == pytest.approx(0.01) and m["n_small_step"] == 2  # iterations 3 and 4
    assert m["miss_per_step_median"] == pytest.approx(np.median([0.06 / 0.1, 0.005 / 0.02, 0.01 / 0.01]))
    tight = fe_misses(SimpleNamespace(history=h, method="ours"), None, None, (20.0, 60.0), small_step_mu=0.015)
    assert tight["small_step_max"] == pytest.approx(0.01) and tight["n_small_step"] == 1
    old = h.drop(columns="sn_pred_whole")  # stored before the column: the surrogate used
    m_old = fe_misses(SimpleNamespace(history=old, method="ours"), None, None, (20.0, 60.0), small_step_mu=0.03)
    assert m_old["small_step_max"] == pytest.approx(0.04)


def test_jacobian_and_combination_gradients_match_finite_differences():
    law = ExponentialDecay(0.7, 0.3, 0.12)
    m = SurrogateMap((20.0, 40.0, 60.0), (0.0, 0.01, 0.0), (1.02, 1.05, 1.08), (6.0, 4.0, 2.0))
    v = np.array([20.0, 33.0, 47.0, 60.0])
    J = m.jacobian(law, v)
    vals, grads = curve_combinations(law, 40.0, 20.0)
    h = 1e-6
    for k, p in enumerate(("mu_s", "mu_k", "alpha")):
        d = dict(law.as_dict())
        d[p] += h
        lp = ExponentialDecay(**d)
        np.testing.assert_allclose(J[:, k], (m.predict(lp, v) - m.predict(law, v)) / h, rtol=1e-4, atol=1e-7)
        np.testing.assert_allclose(
            grads[:, k], (curve_combinations(lp, 40.0, 20.0)[0] - vals) / h, rtol=1e-4, atol=1e-7
        )
    # the combinations are the law's quadratic expansion: level, slope * h, curvature * h^2 / 2
    x = np.array([-0.01, 0.0, 0.01])
    mu = law.mu_kmh(40.0 + 20.0 * x)
    assert vals[0] == pytest.approx(mu[1], abs=1e-12)
    assert vals[1] == pytest.approx((mu[2] - mu[0]) / 0.02, rel=1e-4)
    assert vals[2] == pytest.approx((mu[2] - 2 * mu[1] + mu[0]) / 0.01**2 / 2, rel=1e-3)


def test_study_result_uses_identity_mapping_and_its_intervals():
    truth = ExponentialDecay(0.75, 0.30, 0.15)
    trace = trace_of(truth.mu_kmh, 0.005, 2)
    res = CalibrationResult(
        method="study",
        params=ExponentialDecay(0.4, 0.35, 0.6),
        history=pd.DataFrame(),
        converged=False,
        message="mu_s search ran to max_iter",
        measured_kmh={20.0: 0.6},
        settings={"intervals": {k: list(v) for k, v in DEFAULT_BOUNDS.items()}},
    )
    rec = assess(res, trace, None, calibration_speeds_kmh=CAL, validation_speeds_kmh=VAL, site="S2")
    assert rec["surrogate"]["b"] == [1.0] and rec["surrogate"]["slip_offsets_kmh"] == [0.0]
    assert "not_converged" in rec["flags"] and "max_iter" in rec["reasons"]["not_converged"]
    assert not rec["uncertainty"]["law_in_joint_region"]  # the study's start values do not explain this trace


def test_options_validation():
    assert IdentifiabilityOptions.from_config(None) == IdentifiabilityOptions()
    assert IdentifiabilityOptions.from_config({"fe_miss_max": 0.05}).fe_miss_max == 0.05
    with pytest.raises(ConfigError, match="unknown key"):
        IdentifiabilityOptions.from_config({"fe_mis_max": 0.05})
    with pytest.raises(ConfigError, match="positive"):
        IdentifiabilityOptions(outside_law_factor=0.0)
    with pytest.raises(ConfigError, match="confidence"):
        IdentifiabilityOptions(confidence=1.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        IdentifiabilityOptions().fe_miss_max = 1.0  # frozen


def test_record_round_trips_to_json_and_table_row(tmp_path):
    truth = ExponentialDecay(0.75, 0.30, 0.15)
    _, rec = calibrate_and_assess(law_trace(truth, 0.005, 4))
    path = tmp_path / "identifiability_ours.json"
    write_json(path, rec)
    back = json.loads(path.read_text())
    row = table_row(back)
    assert row["site"] == "S1" and row["method"] == "ours" and row["n_flags"] == 0
    for f in FLAGS:
        assert row[f] is False
    assert row["mu_s_lower"] <= row["mu_s"] <= row["mu_s_upper"]
    from skidsim.plotting.identifiability import plot_identifiability

    png = tmp_path / "identifiability.png"
    plot_identifiability(
        pd.DataFrame([row, dict(row, site="S2", flags="at_bound", mu_k_open="lower")]), png, bounds=back["bounds"]
    )
    assert png.stat().st_size > 1000


def test_rule_scripts_write_records_table_figure_and_warnings(tmp_path):
    """The records as validate_speeds.py makes them (``site_record`` with the job's logger), then
    calibration_summary.py: identifiability.csv with one row per site, a WARNING per flagged site in both logs and
    the flag count in the summary log."""
    import runpy
    from pathlib import Path
    from types import SimpleNamespace

    from skidsim.calibration import site_record, validation_table
    from skidsim.runlog import setup_logging

    root = Path(__file__).resolve().parents[1]

    def run(name, **ns):
        runpy.run_path(str(root / "workflow" / "scripts" / name), init_globals={"snakemake": SimpleNamespace(**ns)})

    curves = {
        "A": lambda v: G * ExponentialDecay(0.75, 0.30, 0.15).mu_kmh(v + D_KMH),
        "B": lambda v: mu_rado(v, 0.70, 32.0, 0.9),
    }  # B: outside the law
    traces, cal, val, ident = [], [], [], []
    for i, (site, fn) in enumerate(curves.items()):
        tr = trace_of(fn, 0.004, 20 + i)
        traces.append(tr.assign(site=site))
        res = calibrate_fast(smooth_fe, tr, JointOptions(max_fe_runs=12))
        d = tmp_path / "sites" / site
        res.to_json(d / "calibration_ours.json")
        vt = validation_table({site: {"ours": simulate_speeds(smooth_fe, res.params, CAL + VAL)}}, {site: tr})
        vt.to_parquet(d / "validation.parquet")
        cal.append(str(d / "calibration_ours.json"))
        val.append(str(d / "validation.parquet"))
    pd.concat(traces).to_parquet(tmp_path / "traces.parquet")
    all_traces = pd.read_parquet(tmp_path / "traces.parquet")
    for site in curves:
        # what the rule validate_speeds does after its FE runs: the record of each method, its log lines
        d = tmp_path / "sites" / site
        rec = site_record(
            CalibrationResult.from_json(d / "calibration_ours.json"),
            all_traces,
            pd.read_parquet(d / "validation.parquet"),
            site=site,
            method="ours",
            options=IdentifiabilityOptions.from_config({"fe_miss_max": 0.03}),
            calibration_speeds_kmh=list(CAL),
            validation_speeds_kmh=list(VAL),
            source=str(tmp_path / "traces.parquet"),
            log=setup_logging(str(tmp_path / "logs" / f"{site}.log")),
        )
        write_json(d / "identifiability_ours.json", rec)
        ident.append(str(d / "identifiability_ours.json"))
    assert "WARNING" not in (tmp_path / "logs" / "A.log").read_text()
    assert "outside_law" in (tmp_path / "logs" / "B.log").read_text()
    out = {
        k: str(tmp_path / "cal" / f"{k}.{e}")
        for k, e in [
            ("table2", "csv"),
            ("comparison", "csv"),
            ("stats", "csv"),
            ("validation", "parquet"),
            ("params", "parquet"),
            ("figure10", "png"),
            ("curves", "png"),
            ("identifiability", "csv"),
            ("identifiability_figure", "png"),
        ]
    }
    run(
        "calibration_summary.py",
        input=SimpleNamespace(
            ingest="", calibrations=cal, validations=val, traces=str(tmp_path / "traces.parquet"), identifiability=ident
        ),
        output=SimpleNamespace(**out),
        params=SimpleNamespace(methods=["ours"]),
        log=[str(tmp_path / "summary.log")],
    )
    table = pd.read_csv(out["identifiability"])
    assert list(table["site"]) == ["A", "B"]
    assert table.set_index("site").loc["B", "outside_law"] and not table.set_index("site").loc["A", "outside_law"]
    log = (tmp_path / "summary.log").read_text()
    assert "B ours flagged: " in log and "A ours flagged" not in log
    assert "identifiability (ours): 1 of 2 sites flagged" in log
    assert Path(out["identifiability_figure"]).stat().st_size > 1000
