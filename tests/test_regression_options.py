"""Tests of skidsim.regression.options: RegressionOptions mirrors the config's ``regression:`` section."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import pytest
import yaml

from skidsim import regression as R
from skidsim.errors import ConfigError

CONFIG = Path(__file__).resolve().parents[1] / "config" / "config.yaml"


def test_defaults_are_the_config_section():
    section = yaml.safe_load(CONFIG.read_text())["regression"]
    assert [f.name for f in fields(R.RegressionOptions)] == list(section)
    defaults = R.RegressionOptions()
    for key, value in section.items():
        got = getattr(defaults, key)
        assert (list(got) if isinstance(got, tuple) else got) == value, key
    assert R.RegressionOptions.from_config(section) == defaults
    assert R.RegressionOptions.from_config(None) == defaults == R.RegressionOptions.from_config({})
    assert R.RegressionOptions.from_dict(section) == defaults


def test_from_config_keeps_values_and_makes_lists_tuples():
    o = R.RegressionOptions.from_config(
        {
            "models": ["mean", "ridge@dft", "pca:variance:0.9"],
            "rule": "kaiser",
            "grouped_by": "section",
            "prediction_speeds_kmh": [20, 60],
        }
    )
    assert o.models == ("mean", "ridge@dft", "pca:variance:0.9") and o.prediction_speeds_kmh == (20, 60)
    assert o.rule == "kaiser" and o.grouped_by == "section" and o.seed == 20170117


@pytest.mark.parametrize(
    "section, message",
    [
        ({"n_tests": 9}, r"regression: unknown key\(s\) \['n_tests'\]"),
        ({"rule": "elbow"}, "regression.rule: expected 'cv', 'study', 'kaiser' or 'variance:F'"),
        ({"rule": "variance:1.5"}, "regression.rule"),
        ({"models": ["mean", "forest"]}, "regression.models: expected a non-empty list of model names"),
        ({"models": ["pca:elbow@dft"]}, "regression.models"),
        ({"models": []}, "regression.models"),
        ({"models": "mean"}, "regression.models: expected a list"),
        ({"figure11_models": ["best", "ridge@foo"]}, "regression.figure11_models"),
        ({"criterion": "aic"}, r"regression.criterion: expected one of \['auto', 'dft_rmse', 'param_r2'\], got 'aic'"),
        ({"inner_folds": 1}, "regression.inner_folds: expected an integer >= 2"),
        ({"n_test": 0}, "regression.n_test"),
        ({"seed": 1.5}, "regression.seed"),
        ({"calibration_method": "theirs"}, "regression.calibration_method"),
        ({"prediction_speeds_kmh": [20, -5]}, "regression.prediction_speeds_kmh"),
    ],
)
def test_bad_sections_name_the_key(section, message):
    with pytest.raises(ConfigError, match=message):
        R.RegressionOptions.from_config(section)


def test_options_are_frozen():
    with pytest.raises(AttributeError):
        R.RegressionOptions().seed = 1
