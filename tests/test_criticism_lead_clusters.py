"""Texture clusters between sites on what the tests see: the columns beyond the prediction model's terms
(skidsim.criticism.texture_tests.beyond_lead_clusters; docs/model-criticism.md, section 2, "Texture clusters")."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.stats import spearmanr

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisOptions, texture_tests
from skidsim.criticism.covariates import CandidateRoles, candidate_set
from skidsim.criticism.levels import level_data
from skidsim.criticism.residuals import build_residuals
from skidsim.errors import InputError

LEAD = ("log(profile_MPD)", "log(micro_Sq)")
SPEEDS_KMH = np.arange(20.0, 71.0, 10.0)


def _campaign(effect_mu: float, seed: int = 5):
    """36 sites in 12 sections. macro_Sq and macro_Sa follow MPD closely (one cluster of the columns), each with a
    log-normal part of its own (sd 0.12); the residual level of a site is ``effect_mu`` times the standardised own
    part of macro_Sq, plus noise (0.004 mu); the texture model predicts 0.5 everywhere."""
    rng = np.random.default_rng(seed)
    n = 36
    site = [f"s{i:02d}" for i in range(n)]
    sites = pd.DataFrame({"site": site, "section": np.repeat([f"S{k:02d}" for k in range(12)], 3)})
    mpd = rng.uniform(0.5, 1.5, n)
    a, b = rng.normal(size=n), rng.normal(size=n)
    tex = pd.DataFrame(
        {
            "site": site,
            "profile_MPD": mpd,
            "micro_Sq": rng.uniform(0.02, 0.08, n),
            "macro_Sq": 0.45 * mpd * np.exp(0.12 * a),
            "macro_Sa": 0.35 * mpd * np.exp(0.12 * b),
            "micro_Ssk": rng.normal(size=n),
        }
    )
    rows, sim, pred = [], [], []
    for i, s in enumerate(site):
        mu = 0.55 - 0.003 * (SPEEDS_KMH - 20) + effect_mu * a[i] + rng.normal(0, 0.004, len(SPEEDS_KMH))
        rows.append(pd.DataFrame({"site": s, "speed_kmh": SPEEDS_KMH, "mu": mu, "kind": "calibration"}))
        sim.append(pd.DataFrame({"site": s, "speed_kmh": SPEEDS_KMH, "sn": 0.55 - 0.003 * (SPEEDS_KMH - 20)}))
        pred.append(pd.DataFrame({"site": s, "speed_kmh": SPEEDS_KMH, "sn_pred": np.full(len(SPEEDS_KMH), 0.5)}))
    return build_residuals(sites, pd.concat(rows), pd.concat(sim), pd.concat(pred)), sites, tex


def _beyond(tex: pd.DataFrame, column: str) -> np.ndarray:
    """The part of ``column`` orthogonal to [1, log MPD, log micro Sq] (an independent least squares)."""
    F = np.c_[np.ones(len(tex)), np.log(tex["profile_MPD"]), np.log(tex["micro_Sq"])]
    x = tex[column].to_numpy(float)
    return x - F @ np.linalg.lstsq(F, x, rcond=None)[0]


def test_between_site_clusters_are_those_of_the_columns_beyond_the_lead_terms():
    res, sites, tex = _campaign(0.0)
    cands = candidate_set(sites, tex, CandidateRoles(), 0.8)
    assert ["profile_MPD", "macro_Sq", "macro_Sa"] in cands.clusters  # the columns go together (rho >= 0.8)
    data = level_data(res, DiagnosisOptions())
    between = texture_tests.beyond_lead_clusters(data["between-site"], cands, LEAD, 0.8)
    assert texture_tests.beyond_lead_clusters(data["within-site"], cands, LEAD, 0.8) is None
    assert texture_tests.beyond_lead_clusters(data["between-site"], cands, (), 0.8) is None
    assert sorted(c for cl in between for c in cl) == sorted(c for cl in cands.clusters for c in cl)
    tex_b = tex.set_index("site").loc[data["between-site"].site_ids].reset_index()
    for cl in between:  # every pair of a cluster: |Spearman rho| >= 0.8 of the parts beyond the lead terms
        for i, u in enumerate(cl):
            for v in cl[i + 1 :]:
                assert abs(spearmanr(_beyond(tex_b, u), _beyond(tex_b, v))[0]) >= 0.8
    # what the two macro columns share, MPD, is in the lead terms: their own parts are unrelated
    rho = spearmanr(_beyond(tex_b, "macro_Sq"), _beyond(tex_b, "macro_Sa"))[0]
    assert abs(rho) < 0.5
    assert not any({"macro_Sq", "macro_Sa"} <= set(cl) for cl in between)


def test_a_column_named_between_sites_for_its_part_beyond_the_lead_is_tested_as_its_own_unit(monkeypatch):
    """The residual level follows macro_Sq's own part. In the cluster of the columns, macro_Sq's unit p is the
    maximum over members (MPD, macro_Sa) whose parts beyond the lead terms are unrelated to it; in the cluster of
    those parts it is its own unit, unit p = its p. The test itself (its statistic and permutations) is the same.
    Its direction is that of the column (the QR basis of a column may carry the opposite sign)."""
    res, sites, tex = _campaign(0.0025)
    opts = DiagnosisOptions(seed=3, n_permutations=4999)

    def screen():
        causes = cr.screen_candidates(res, sites, tex, opts, texture_lead=LEAD)
        return next(c for c in causes if (c.variable, c.level, c.kind) == ("macro_Sq", "between-site", "main"))

    own = screen()
    assert own.unit == "macro_Sq" and own.unit_p == own.p_value < 0.005 and own.direction == 1
    monkeypatch.setattr(texture_tests, "beyond_lead_clusters", lambda *a: None)
    monkeypatch.setattr(cr.screening, "beyond_lead_clusters", lambda *a: None)
    joint = screen()
    assert joint.unit == "cluster:macro_Sq" and joint.group == own.group
    assert joint.p_value == own.p_value and joint.statistic == own.statistic
    assert joint.unit_p > 2 * joint.p_value and joint.p_adjusted > own.p_adjusted


def test_a_site_without_a_row_is_named_with_the_lead_terms_given():
    """The clusters between sites are built before the levels; a residual site missing from the sites table is
    still reported by the level's clear error (InputError naming the sites table and the site), not a KeyError."""
    res, sites, tex = _campaign(0.0)
    with pytest.raises(InputError, match="s35"):
        cr.screen_candidates(res, sites[sites["site"] != "s35"], tex, DiagnosisOptions(seed=3), texture_lead=LEAD)
