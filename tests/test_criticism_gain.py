"""Tests of skidsim.criticism.gain: RMSE / R^2 before and after with bootstrap intervals over whole sites."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skidsim import criticism as cr


def test_measure_gain_matches_direct_formulas():
    rng = np.random.default_rng(4)
    rows = []
    for i in range(10):
        for v in (20.0, 40.0, 60.0):
            y = 0.5 + 0.02 * rng.normal()
            rows.append((f"s{i}", v, y, y + 0.03 * rng.normal(), y + 0.01 * rng.normal()))
    p = pd.DataFrame(rows, columns=["site", "speed_kmh", "measured", "before", "after"])
    g = cr.measure_gain(p, n_boot=300, seed=1)
    eb = p["measured"] - p["before"]
    ea = p["measured"] - p["after"]
    assert g["rmse_before"] == pytest.approx(np.sqrt(np.mean(eb**2)))
    assert g["rmse_after"] == pytest.approx(np.sqrt(np.mean(ea**2)))
    from sklearn.metrics import r2_score

    assert g["r2_after"] == pytest.approx(r2_score(p["measured"], p["after"]))
    shape = eb - eb.groupby(p["site"]).transform("mean")
    assert g["shape_rmse_before"] == pytest.approx(np.sqrt(np.mean(shape**2)))
    lo, hi = g["rmse_gain_ci"]
    assert lo <= g["rmse_gain"] <= hi and lo > 0 and g["gain_excludes_zero"]
    same = cr.measure_gain(p.assign(after=p["before"]), n_boot=100, seed=1)
    assert same["rmse_gain"] == 0 and same["rmse_gain_ci"] == [0.0, 0.0] and not same["gain_excludes_zero"]
    assert g == cr.measure_gain(p, n_boot=300, seed=1)  # deterministic for a seed
