"""The texture model of the between-site tests: the regression model's own columns when they predict unseen
sections better than texture PCs (skidsim.criticism.adjustment.texture_model_scores)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skidsim.criticism.adjustment import lead_design, texture_adjustment, texture_model_scores
from skidsim.criticism.inputs import prediction_features
from skidsim.criticism.report import report_markdown
from skidsim.criticism.residuals import build_residuals

SPEEDS_KMH = np.arange(20.0, 71.0, 10.0)


def test_prediction_features_are_the_terms_most_folds_chose():
    cv = pd.DataFrame(
        {
            "site": list("abcde"),
            "model": ["p"] * 4 + ["q"],
            "features": ["log(m)+log(s)", "m+s", "log(m)+log(s)", None, "x+y"],
        }
    )
    assert prediction_features(cv, "p") == ("log(m)", "log(s)")
    assert prediction_features(cv, "q") == ("x", "y")
    assert prediction_features(cv, "r") == ()
    assert prediction_features(cv.drop(columns="features"), "p") == ()
    assert prediction_features(cv.assign(features=""), "p") == ()


def test_lead_design_standardises_logs_and_refuses_what_it_cannot_use():
    cov = pd.DataFrame({"m": [0.5, 1.0, 2.0, 4.0], "s": [1.0, 2.0, 3.0, 4.0], "z": [0.0, 1.0, 2.0, 3.0]})
    L = lead_design(cov, ("log(m)", "s"))
    lm = np.log(cov["m"].to_numpy())
    assert np.allclose(L[:, 0], (lm - lm.mean()) / lm.std())
    assert np.allclose(L.mean(axis=0), 0) and np.allclose(L.std(axis=0), 1)
    assert lead_design(cov, ("log(z)",)) is None  # a zero under a log
    assert lead_design(cov, ("w",)) is None  # not a column
    assert lead_design(cov.assign(s=1.0), ("s",)) is None  # constant


def test_texture_adjustment_always_keeps_the_lead_columns():
    """With n_lead columns first, k and k_cv never drop below n_lead, and the variance floor counts PCs on top."""
    rng = np.random.default_rng(8)
    n = 36
    sec = np.repeat([f"S{k}" for k in range(12)], 3)
    pcs = rng.normal(size=(n, 8)) * np.linspace(3, 0.5, 8)
    lead = rng.normal(size=(n, 2))  # pure noise: CV alone would never take it
    M = 0.5 + 0.04 * pcs[:, [0]] + rng.normal(0, 0.002, size=(n, 5))
    k, N, k_cv = texture_adjustment(M, np.c_[lead, pcs], sec, variance_share=0.5, n_lead=2)
    var = pcs.var(axis=0)
    k50 = int(np.searchsorted(np.cumsum(var) / var.sum(), 0.5) + 1)
    assert k_cv == 3  # the lead columns, then PC 1
    assert k == max(3, 2 + k50) and np.allclose(N, np.c_[np.ones(n), lead, pcs[:, : k - 2]])


def _campaign(lead_signal: bool, seed: int = 3):
    """36 sites in 12 sections: measured curves from log MPD (the level and the speed gradient) and log micro Sq
    (the level) when ``lead_signal``, else from a texture column outside the lead; 20 noise texture columns."""
    rng = np.random.default_rng(seed)
    n = 36
    site = [f"s{i:02d}" for i in range(n)]
    sites = pd.DataFrame({"site": site, "section": np.repeat([f"S{k:02d}" for k in range(12)], 3)})
    mpd = rng.uniform(0.4, 2.0, n)
    sq = rng.uniform(0.02, 0.08, n)
    other = rng.normal(size=n)
    tex = pd.DataFrame(rng.normal(size=(n, 20)), columns=[f"raw_n{j}" for j in range(20)]).assign(
        site=site, profile_MPD=mpd, micro_Sq=sq, raw_other=other
    )
    rows, sim, pred = [], [], []
    for i, s in enumerate(site):
        v = SPEEDS_KMH
        if lead_signal:
            mu = 0.55 + 0.12 * np.log(sq[i] / 0.04) - (0.004 - 0.0015 * np.log(mpd[i])) * (v - 20)
        else:
            mu = 0.55 + 0.05 * other[i] - 0.003 * (v - 20)
        mu = mu + rng.normal(0, 0.003, len(v))
        rows.append(pd.DataFrame({"site": s, "speed_kmh": v, "mu": mu, "kind": "calibration"}))
        sim.append(pd.DataFrame({"site": s, "speed_kmh": v, "sn": mu}))
        pred.append(pd.DataFrame({"site": s, "speed_kmh": v, "sn_pred": np.full(len(v), 0.5)}))
    res = build_residuals(sites, pd.concat(rows), pd.concat(sim), pd.concat(pred))
    return res, sites, tex


def _loso_r2_of_mean_per_bin(res: pd.DataFrame) -> float:
    """Leave-one-section-out R^2 of the measured curves predicted by the training sections' mean per speed
    (computed directly from the long table, an independent route)."""
    b = res[res["level"] == "between-site"]
    sse = 0.0
    for s in b["section"].unique():
        te, tr = b[b["section"] == s], b[b["section"] != s]
        mean = tr.groupby("speed_kmh")["measured"].mean()
        sse += float(((te["measured"] - te["speed_kmh"].map(mean)) ** 2).sum())
    return 1 - sse / float(((b["measured"] - b["measured"].mean()) ** 2).sum())


def test_texture_model_takes_the_prediction_columns_when_they_predict_better():
    res, sites, tex = _campaign(lead_signal=True)
    lead = ("log(profile_MPD)", "log(micro_Sq)")
    table, rec = texture_model_scores(res, sites, tex, lead=lead)
    assert rec["lead_chosen"] and table.attrs["n_lead"] == 2 and rec["lead"] == list(lead)
    assert rec["cv_r2_lead"] > 0.95 > rec["cv_r2_pcs"]
    assert rec["cv_r2_mean_per_bin"] == pytest.approx(_loso_r2_of_mean_per_bin(res), abs=1e-12)
    cov = tex.set_index("site").loc[table.index]
    assert np.allclose(table["_tpc1"], lead_design(cov, lead)[:, 0])
    report = report_markdown([], {"scopes": {}, "texture_model": {"prediction_model": "physics2@dft", **rec}}, {}, ".")
    assert "log(profile_MPD), log(micro_Sq) (the columns of physics2@dft)" in report


def test_texture_model_keeps_the_pcs_when_the_prediction_columns_do_not_help():
    res, sites, tex = _campaign(lead_signal=False)
    table, rec = texture_model_scores(res, sites, tex, lead=("profile_MPD", "micro_Sq"))
    assert not rec["lead_chosen"] and "n_lead" not in table.attrs
    assert rec["cv_r2_pcs"] > rec["cv_r2_lead"]
    plain, rec0 = texture_model_scores(res, sites, tex)
    assert np.array_equal(plain.to_numpy(), table.to_numpy()) and rec0["cv_r2_lead"] is None
