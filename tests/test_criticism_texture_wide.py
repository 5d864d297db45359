"""The texture model's wide member and the minP test of its members (issue 33, item 1; docs/model-criticism.md,
section 2, "The texture model as a candidate cause").

A texture measure that the table does not hold (the microtexture where the slider touches) shows in the
between-site residual as a direction that several of the table's columns share, beyond the prediction model's
terms, and not always along the leading three texture PCs: the wide member, the leading ``k`` PCs beyond those
terms, carries it. Its design is wider than the other members' (``k`` against 3 columns), so the members are tested
by single-step minP, each on its own permutation scale.

Campaigns built at the residual level: 36 sites in 12 sections, 16 texture columns from 10 section-structured
latent factors, the prediction model's terms ``log(profile_MPD)`` and ``log(micro_Sq)``; the measured curves, the
calibrated simulation (the measured curve plus noise) and the held-out prediction (the measured curve minus the
residual written here). Speeds km/h, mu dimensionless.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisOptions
from skidsim.criticism import texture_candidate as tc
from skidsim.criticism.permutations import min_p, permutation_p

SPEEDS_KMH = np.arange(20.0, 71.0, 10.0)
LEAD = ("log(profile_MPD)", "log(micro_Sq)")
#: sd over the sites of the residual's level along texture PCs 4-8 beyond the terms (mu)
EFFECT_MU = 0.012


def _texture(rng, n_sec: int = 12, per: int = 3) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(sites, texture): 16 texture columns from 10 latent factors (section part 0.8, site part 0.6), MPD (mm) and
    micro Sq (mm) from two of them."""
    sec_idx = np.repeat(np.arange(n_sec), per)
    n = n_sec * per
    site = [f"S{k:02d}-{j}" for k in range(n_sec) for j in range(per)]
    sites = pd.DataFrame({"site": site, "section": [f"S{k:02d}" for k in sec_idx]})
    latent = 0.8 * rng.normal(size=(n_sec, 10))[sec_idx] + 0.6 * rng.normal(size=(n, 10))
    cols = latent @ rng.normal(size=(10, 16)) + 0.3 * rng.normal(size=(n, 16))
    tex = pd.DataFrame(cols, columns=[f"raw_c{j}" for j in range(16)]).assign(
        site=site,
        profile_MPD=np.exp(np.log(0.9) + 0.3 * latent[:, 0]),
        micro_Sq=np.exp(np.log(0.03) + 0.15 * latent[:, 1]),
    )
    return sites, tex


def _beyond_terms_pcs(tex: pd.DataFrame) -> np.ndarray:
    """Left singular vectors of the standardised texture columns beyond ``[1, log MPD, log micro Sq]`` (an
    independent construction of what the wide member holds)."""
    cols = [c for c in tex.columns if c != "site"]
    X = tex[cols].to_numpy(float)
    X = (X - X.mean(axis=0)) / X.std(axis=0)
    z = lambda x: (x - x.mean()) / x.std()  # noqa: E731
    B = np.c_[np.ones(len(tex)), z(np.log(tex["profile_MPD"].to_numpy())), z(np.log(tex["micro_Sq"].to_numpy()))]
    Xb = X - B @ np.linalg.lstsq(B, X, rcond=None)[0]
    return np.linalg.svd(Xb, full_matrices=False)[0]


def _campaign(seed: int, effect_mu: float = EFFECT_MU):
    """(residuals, sites, texture): the between-site residual's level is a random combination of texture PCs 4-8
    beyond the prediction model's terms with sd ``effect_mu`` over the sites, plus site noise (sd 0.004) and point
    noise (sd 0.003)."""
    rng = np.random.default_rng(seed)
    sites, tex = _texture(rng)
    U = _beyond_terms_pcs(tex)
    level = U[:, 3:8] @ rng.normal(size=5)
    level = effect_mu * (level - level.mean()) / level.std()
    rows, sim, pred = [], [], []
    for i, s in enumerate(sites["site"]):
        v = SPEEDS_KMH
        mu = 0.6 - 0.004 * (v - 20.0) + rng.normal(0, 0.003, len(v))
        resid = level[i] + rng.normal(0, 0.004) + rng.normal(0, 0.003, len(v))
        rows.append(pd.DataFrame({"site": s, "speed_kmh": v, "mu": mu, "kind": "calibration"}))
        sim.append(pd.DataFrame({"site": s, "speed_kmh": v, "sn": mu + rng.normal(0, 0.002, len(v))}))
        pred.append(pd.DataFrame({"site": s, "speed_kmh": v, "sn_pred": mu - resid}))
    return cr.build_residuals(sites, pd.concat(rows), pd.concat(sim), pd.concat(pred)), sites, tex


def _texture_model_main(causes):
    return [c for c in causes if c.source == "texture_model" and c.level == "between-site" and c.kind == "main"]


# ---------------------------------------------------------------------------------------------------------------
# minP
# ---------------------------------------------------------------------------------------------------------------


def test_min_p_against_a_direct_count():
    """Unit p and adjusted p of :func:`min_p` against the definition counted permutation by permutation (each
    permutation's p on each statistic's own null of P + 1 arrangements, the observation among them; the minimum
    over the statistics), on chi-square nulls of 1, 3 and 8 degrees of freedom."""
    rng = np.random.default_rng(3)
    P = 499
    Tp = rng.chisquare([1, 3, 8], size=(P, 3))
    Tobs = np.array([6.0, 9.0, 21.0])
    unit, adj, top = min_p(Tobs, Tp)
    p_perm = np.array(
        [[(np.sum(Tp[:, j] >= Tp[b, j]) + (Tobs[j] >= Tp[b, j])) / (P + 1) for j in range(3)] for b in range(P)]
    ).min(axis=1)
    p_obs = [permutation_p(Tobs[j], Tp[:, j]) for j in range(3)]
    expect = [(1 + np.sum(p_perm <= p)) / (P + 1) for p in p_obs]
    assert np.allclose(adj, expect, rtol=0, atol=1e-15)
    assert top == int(np.argmin(p_obs)) and unit == expect[top]
    assert unit < min(expect[j] for j in range(3) if j != top)


def test_min_p_is_blind_to_a_statistics_scale_and_equals_the_plain_p_for_one():
    """Scaling one statistic (observed and permuted) changes nothing, where the max-statistic would let it decide;
    a unit of one statistic gets its plain permutation p."""
    rng = np.random.default_rng(4)
    Tp = rng.chisquare([3, 3], size=(999, 2))
    Tobs = np.array([12.0, 5.0])
    base = min_p(Tobs, Tp)
    scaled = min_p(Tobs * [1.0, 100.0], Tp * [1.0, 100.0])
    assert base[0] == scaled[0] and np.array_equal(base[1], scaled[1]) and base[2] == scaled[2] == 0
    maxT = permutation_p(max(Tobs * [1, 100]), (Tp * [1, 100]).max(axis=1))
    assert maxT > 0.1 and base[0] < 0.05  # the scaled, weaker statistic decides the max-statistic
    one = min_p(Tobs[:1], Tp[:, :1])
    assert one[0] == permutation_p(Tobs[0], Tp[:, 0])


# ---------------------------------------------------------------------------------------------------------------
# the wide member
# ---------------------------------------------------------------------------------------------------------------


def test_the_wide_member_is_the_leading_pcs_beyond_the_terms():
    """With 12 sections the wide member holds ``min(8, 12 - 4)`` = 8 columns spanning the 8 leading singular
    vectors of the texture columns beyond ``[1, lead]`` (built independently here), each standardised; with 7
    sections (k = 3, no wider than the PCs member) there is none, and none without texture columns."""
    sites, tex = _texture(np.random.default_rng(1))
    cov = tex.set_index("site")
    cols = tuple(c for c in cov.columns)
    members = tc.texture_members(cov.index, cov, None, None, LEAD, 0, texture_columns=cols, n_sections=12)
    wide = next(m for m in members if m.name == "texture PCs 1-8")
    assert wide.design.shape == (36, 8)
    assert np.allclose(wide.design.mean(axis=0), 0, atol=1e-12) and np.allclose(wide.design.std(axis=0), 1)
    U = _beyond_terms_pcs(tex)[:, :8]
    D = wide.design / np.linalg.norm(wide.design, axis=0)
    assert np.allclose(np.abs(np.sum(D * U, axis=0)), 1.0, atol=1e-10)  # the same directions, one by one
    few = tc.texture_members(cov.index, cov, None, None, LEAD, 0, texture_columns=cols, n_sections=7)
    assert not [m for m in few if m.name.startswith("texture PCs 1-") and m.design.shape[1] > 3]
    none = tc.texture_members(cov.index, cov, None, None, LEAD, 0, texture_columns=(), n_sections=12)
    assert not [m for m in none if m.design.shape[1] > 3]


@pytest.mark.parametrize("seed", [0, 1])
def test_an_effect_beyond_the_leading_pcs_names_the_wide_member(seed, monkeypatch):
    """The residual's level follows texture PCs 4-8 beyond the prediction model's terms: the texture model is named
    by its wide member. Without the wide member (``WIDE_PCS`` 3) the other members do not reach significance."""
    res, sites, tex = _campaign(seed)
    opts = DiagnosisOptions(seed=seed)
    causes = cr.screen_candidates(res, sites, tex, opts, texture_lead=LEAD)
    top = cr.named_cause(causes)
    assert top is not None and top.variable == "texture_model[texture PCs 1-8]", causes[:3]
    assert top.category == "texture model" and top.p_adjusted <= opts.fdr
    monkeypatch.setattr(tc, "WIDE_PCS", 3)
    narrow = cr.screen_candidates(res, sites, tex, opts, texture_lead=LEAD)
    tm = _texture_model_main(narrow)
    assert tm and "texture_model[texture PCs 1-8]" not in {c.variable for c in tm}
    assert not any(c.significant for c in tm), tm[:2]


def test_without_an_effect_the_wide_member_is_not_named():
    """The same texture, no effect (site and point noise only): no texture-model member is significant."""
    res, sites, tex = _campaign(5, effect_mu=0.0)
    causes = cr.screen_candidates(res, sites, tex, DiagnosisOptions(seed=5), texture_lead=LEAD)
    assert not any(c.significant for c in _texture_model_main(causes))


def _core_table(rng, n: int = 36) -> pd.DataFrame:
    """A table holding every core column of the wide member (:func:`tc.wide_member_columns`), from 12 latent
    factors, plus the contact zone's columns and profile_MPD (mm) and micro_Sq (mm) positive."""
    latent = rng.normal(size=(n, 12))
    core = [f"{b}_{q}" for b in tc.WIDE_CORE_BANDS for q in tc.WIDE_CORE_PARAMETERS if f"{b}_{q}" != "micro_Sq"]
    X = latent @ rng.normal(size=(12, len(core) + 1)) + 0.3 * rng.normal(size=(n, len(core) + 1))
    tex = pd.DataFrame(X[:, :-1], columns=core)
    tex["micro_Sdq_top"] = X[:, -1]
    tex["micro_Sq_top"] = latent[:, 2] + 0.2 * rng.normal(size=n)
    tex["profile_MPD"] = np.exp(np.log(0.9) + 0.3 * latent[:, 0])
    tex["micro_Sq"] = np.exp(np.log(0.03) + 0.15 * latent[:, 1])
    return tex


def test_the_wide_member_of_a_table_with_the_core_columns_reads_those_alone():
    """A table holding the height and slope parameters of the three bands: the wide member is the same design
    whatever other columns the table holds beside them (here 60 near-copies of raw_Sq and macro_Sv, as the
    material-ratio volumes and the Sk family follow the heights), and differs from the PCs of the whole table;
    without one core column (micro_Sdr) the table is read whole."""
    rng = np.random.default_rng(6)
    tex = _core_table(rng)
    sites = [f"S{k:02d}-{j}" for k in range(12) for j in range(3)]
    cov = tex.set_index(pd.Index(sites, name="site"))
    copies = {f"raw_V{j}": cov["raw_Sq"] * (1 + 0.1 * j) + 0.05 * rng.normal(size=36) for j in range(30)}
    copies |= {f"macro_F{j}": cov["macro_Sv"] + 0.05 * rng.normal(size=36) for j in range(30)}
    wide = pd.concat([cov, pd.DataFrame(copies, index=cov.index)], axis=1)

    def design(table):
        m = tc.texture_members(table.index, table, None, None, LEAD, 0, tuple(table.columns), n_sections=12)
        return next(x for x in m if x.name == "texture PCs 1-8").design

    assert set(tc.wide_member_columns(wide.columns)) == set(cov.columns)
    assert np.array_equal(design(cov), design(wide))

    def pcs(table):  # the 8 leading PCs beyond [1, lead] (built independently)
        X = table.to_numpy(float)
        Xs = (X - X.mean(axis=0)) / X.std(axis=0)
        B = np.c_[np.ones(36), np.log(table["profile_MPD"]), np.log(table["micro_Sq"])]
        return np.linalg.svd(Xs - B @ np.linalg.lstsq(B, Xs, rcond=None)[0], full_matrices=False)[0][:, :8]

    D = design(wide) / np.sqrt(36)
    assert np.allclose(np.abs(np.sum(D * pcs(cov), axis=0)), 1.0, atol=1e-8)
    # the whole table's PCs differ: the copies pull the leading directions towards raw_Sq and macro_Sv
    assert np.abs(np.sum(D * pcs(wide), axis=0)).min() < 0.9
    partial = wide.drop(columns="micro_Sdr")
    assert tc.wide_member_columns(partial.columns) == list(partial.columns)
