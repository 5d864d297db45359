"""Tests of skidsim.criticism.options (the config ``diagnosis:`` section) and skidsim.criticism.inputs (the
diagnosis inputs from the workflow's tables: kinds of measured points, g(v), between-site predictions)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from skidsim.calibration import geometric_factors
from skidsim.criticism import DiagnosisOptions, read_workflow_inputs
from skidsim.criticism.inputs import between_site_predictions, measured_table
from skidsim.errors import ConfigError, InputError

ROOT = Path(__file__).resolve().parents[1]


def _law(v_kmh, mu_s, mu_k, alpha):
    return mu_k + (mu_s - mu_k) * np.exp(-alpha * np.asarray(v_kmh, dtype=float) / 3.6)


def test_options_are_the_config_section():
    section = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["diagnosis"]
    assert DiagnosisOptions.from_config(section) == DiagnosisOptions()
    o = DiagnosisOptions()
    assert (o.seed, o.n_boot, o.fdr, o.fdr_method, o.fe_extension) == (11, 1000, 0.04, "bh", "auto")
    assert DiagnosisOptions.from_config({"n_boot": 50}).n_boot == 50


def test_options_reject_unknown_keys_and_bad_values():
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['n_bootstrap'\]"):
        DiagnosisOptions.from_config({"n_bootstrap": 10})
    with pytest.raises(ConfigError, match="diagnosis.fdr: expected a number in"):
        DiagnosisOptions(fdr=1.5)
    with pytest.raises(ConfigError, match="fdr_method"):
        DiagnosisOptions(fdr_method="holm")
    with pytest.raises(ConfigError, match="fe_extension"):
        DiagnosisOptions(fe_extension="sometimes")
    with pytest.raises(ConfigError, match=r"diagnosis.within_site_sites: expected one of \('all', 'settled'\)"):
        DiagnosisOptions(within_site_sites="flagged")


def test_measured_table_kinds():
    pts = pd.DataFrame({"site": ["a"] * 4, "speed_kmh": [20.0, 40.0, 30.0, 45.0], "mu": [0.6, 0.5, 0.55, 0.48]})
    tr = pd.DataFrame({"site": ["a"], "speed_kmh": [25.0], "mu": [0.57], "extra": [1]})
    m = measured_table(pts, tr, [20, 40], [30])
    assert m["kind"].tolist() == ["calibration", "calibration", "validation", "trace", "trace"]
    assert list(m.columns) == ["site", "speed_kmh", "mu", "kind"]


def test_geometric_factor_and_between_site_predictions():
    """g(v) = SN_sim / mu_cal(v) of the calibrated law; the predictions are g(v) times the predicted law, the
    predicted parameters clipped at 0 (a negative alpha becomes a flat law)."""
    v = np.array([20.0, 40.0, 60.0])
    g_true = np.array([1.05, 1.02, 0.98])
    val = pd.DataFrame(
        {
            "site": ["a"] * 3 + ["b"] * 3,
            "speed_kmh": np.r_[v, v],
            "sn_sim": np.r_[g_true * _law(v, 0.8, 0.3, 0.05), g_true * _law(v, 0.7, 0.2, 0.04)],
        }
    )
    par = pd.DataFrame({"site": ["a", "b"], "mu_s": [0.8, 0.7], "mu_k": [0.3, 0.2], "alpha": [0.05, 0.04]})
    g = geometric_factors(val, par)
    assert np.allclose(g["g"], np.r_[g_true, g_true], rtol=1e-12)
    cvp = pd.DataFrame(
        {
            "site": ["a", "b", "a"],
            "model": ["m1", "m1", "m0"],
            "mu_s": [0.75, 0.6, 9.0],
            "mu_k": [0.35, 0.25, 9.0],
            "alpha": [0.06, -0.01, 9.0],
        }
    )
    p = between_site_predictions(g, cvp, "m1").set_index(["site", "speed_kmh"])["sn_pred"]
    assert p.loc["a"].to_numpy() == pytest.approx(g_true * _law(v, 0.75, 0.35, 0.06), rel=1e-12)
    assert p.loc["b"].to_numpy() == pytest.approx(g_true * 0.6, rel=1e-12)  # alpha clipped to 0: mu = mu_s
    with pytest.raises(InputError, match="calibrated law for every simulated site"):
        geometric_factors(val, par.iloc[:1])
    with pytest.raises(InputError, match="model 'nope'"):
        between_site_predictions(g, cvp, "nope")


def test_read_workflow_inputs(tmp_path):
    v = np.array([20.0, 40.0, 60.0])
    sites = pd.DataFrame({"site": ["a", "b"], "section": ["S1", "S2"]})
    val = pd.DataFrame(
        {
            "site": ["a"] * 3 + ["b"] * 3,
            "method": "ours",
            "speed_kmh": np.r_[v, v],
            "sn_sim": np.r_[_law(v, 0.8, 0.3, 0.05), _law(v, 0.7, 0.2, 0.04)],
        }
    )
    par = pd.DataFrame(
        {
            "site": ["a", "b", "a"],
            "method": ["ours", "ours", "study"],
            "mu_s": [0.8, 0.7, 0.1],
            "mu_k": [0.3, 0.2, 0.1],
            "alpha": [0.05, 0.04, 0.1],
        }
    )
    files = {
        "ingest": sites,
        "validation": val,
        "params": par,
        "wide": pd.DataFrame({"site": ["a", "b"], "x": [1, 2]}),
        "dft": pd.DataFrame({"site": ["a", "b"], "speed_kmh": [20.0, 50.0], "mu": [0.6, 0.4]}),
        "traces": pd.DataFrame({"site": ["a"], "speed_kmh": [30.0], "mu": [0.5]}),
    }
    paths = {}
    for k, df in files.items():
        paths[k] = tmp_path / f"{k}.parquet"
        df.to_parquet(paths[k])
    paths["cv_predictions"] = tmp_path / "cv.csv"
    pd.DataFrame(
        {
            "site": ["a", "b"],
            "model": "m1",
            "mu_s": [0.8, 0.7],
            "mu_k": [0.3, 0.2],
            "alpha": [0.05, 0.04],
            "features": ["log(x)+y", "log(x)+y"],
        }
    ).to_csv(paths["cv_predictions"], index=False)
    paths["best_model"] = tmp_path / "best.txt"
    paths["best_model"].write_text("m1\n")
    inp = read_workflow_inputs(paths, "ours", [20, 40, 60], [50])
    assert inp.calibration is None  # no identifiability table among the inputs
    paths["identifiability"] = tmp_path / "identifiability.csv"
    pd.DataFrame(
        {
            "site": ["a", "b", "a"],
            "method": ["ours", "ours", "study"],
            "flags": ["at_bound", np.nan, "not_converged"],
            "at_bound_params": ["mu_s:upper;mu_k:lower", np.nan, "mu_s:upper"],
        }
    ).to_csv(paths["identifiability"], index=False)
    inp = read_workflow_inputs(paths, "ours", [20, 40, 60], [50])
    assert inp.calibration["site"].tolist() == ["a", "b"]
    assert inp.calibration["at_bound_params"].iloc[0] == "mu_s:upper;mu_k:lower"
    assert inp.calibration["flags"].iloc[0] == "at_bound" and pd.isna(inp.calibration["flags"].iloc[1])
    pd.DataFrame({"site": ["a"], "method": ["ours"], "flags": ["at_bound"]}).to_csv(paths["identifiability"])
    with pytest.raises(InputError, match="at_bound_params"):
        read_workflow_inputs(paths, "ours", [20, 40, 60], [50])
    del paths["identifiability"]
    assert inp.prediction_model == "m1" and inp.prediction_features == ("log(x)", "y")
    assert inp.measured["kind"].tolist() == ["calibration", "validation", "trace"]
    # the predicted law equals the calibrated one here, so the predictions reproduce the simulation
    assert np.allclose(inp.predicted.sort_values(["site", "speed_kmh"])["sn_pred"], val["sn_sim"], rtol=1e-12)
    with pytest.raises(InputError, match="calibration method 'fast'"):
        read_workflow_inputs(paths, "fast", [20], [50])
    with pytest.raises(InputError, match="an input named 'traces'"):
        read_workflow_inputs({k: p for k, p in paths.items() if k != "traces"}, "ours", [20], [50])
