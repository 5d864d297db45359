"""The texture model as the explanation of a section x speed effect between sites (issue 33; docs/model-criticism.md,
section 2, "The texture model as a candidate cause"): the members' x_speed tests, asked as a child family of a
significant section x speed effect, and the naming rule that then names the texture model, or
``section (unexplained)`` when the texture does not carry the section effect.

Campaigns built at the residual level: 36 sites in 12 sections, MPD (mm) section-structured, a few texture columns
without effect; the measured curves, the calibrated simulation (equal to the measured curve plus noise) and the
texture model's held-out prediction (the measured curve minus the residual written here). Speeds km/h, mu
dimensionless.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisOptions
from skidsim.criticism.causes import SECTION_UNEXPLAINED

SPEEDS_KMH = np.arange(20.0, 71.0, 10.0)
#: size of the residual's speed slope (mu per 25 km/h)
SLOPE_MU = 0.02


def _campaign(seed: int, slope: str) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(residuals, sites, texture): the between-site residual's slope over speed is ``SLOPE_MU (v - 45) / 25``
    times ``z^2 - 1`` (z the standardised MPD: a shape a model linear in MPD cannot carry) for ``slope="mpd"``,
    times a random number per section for ``"section"`` (the same spread; nothing in the texture carries it)."""
    rng = np.random.default_rng(seed)
    n_sec, per = 12, 3
    sec_idx = np.repeat(np.arange(n_sec), per)
    n = n_sec * per
    site = [f"S{k:02d}-{j}" for k in range(n_sec) for j in range(per)]
    section = [f"S{k:02d}" for k in sec_idx]
    sites = pd.DataFrame({"site": site, "section": section})
    mpd_mm = np.exp(np.log(0.9) + 0.35 * rng.normal(size=n_sec)[sec_idx] + 0.08 * rng.normal(size=n))
    tex = pd.DataFrame(rng.normal(size=(n, 6)), columns=[f"raw_n{j}" for j in range(6)]).assign(
        site=site, profile_MPD=mpd_mm, micro_Sq=rng.uniform(0.02, 0.05, n)
    )
    z = (mpd_mm - mpd_mm.mean()) / mpd_mm.std()
    if slope == "mpd":
        amp = z**2 - 1.0
    else:
        amp = (np.sqrt(2.0) * rng.normal(size=n_sec))[sec_idx]
    rows, sim, pred = [], [], []
    for i, s in enumerate(site):
        v = SPEEDS_KMH
        mu = 0.6 - 0.004 * (v - 20.0) + rng.normal(0, 0.003, len(v))
        resid = SLOPE_MU * amp[i] * (v - 45.0) / 25.0 + rng.normal(0, 0.004, len(v))
        rows.append(pd.DataFrame({"site": s, "speed_kmh": v, "mu": mu, "kind": "calibration"}))
        sim.append(pd.DataFrame({"site": s, "speed_kmh": v, "sn": mu + rng.normal(0, 0.002, len(v))}))
        pred.append(pd.DataFrame({"site": s, "speed_kmh": v, "sn_pred": mu - resid}))
    res = cr.build_residuals(sites, pd.concat(rows), pd.concat(sim), pd.concat(pred))
    return res, sites, tex


def _screen(seed: int, slope: str):
    res, sites, tex = _campaign(seed, slope)
    return cr.screen_candidates(res, sites, tex, DiagnosisOptions(seed=seed))


def _between(causes, variable_prefix: str, kind: str):
    return [
        c for c in causes if c.level == "between-site" and c.kind == kind and c.variable.startswith(variable_prefix)
    ]


@pytest.mark.parametrize("seed", [0, 1])
def test_a_speed_shape_nonlinear_in_mpd_names_the_texture_model(seed):
    """The residual's speed slope is a quadratic of MPD and clusters by section (MPD is section-structured): the
    section x speed effect is significant, the texture model's x_speed member ``nonlinear in profile_MPD``
    explains most of it, and the section rule names the texture model, above section identity."""
    causes = _screen(seed, "mpd")
    sec = next(c for c in causes if c.variable == "section" and c.level == "between-site" and c.kind == "x_speed")
    assert sec.significant, sec
    tm = _between(causes, "texture_model[", "x_speed")
    assert {c.family for c in tm} == {"child"} and len({c.unit for c in tm}) == 1
    member = next(c for c in tm if c.variable == "texture_model[nonlinear in profile_MPD]")
    assert member.significant and member.section_share >= 0.5 and member.p_adjusted >= sec.p_adjusted
    top = cr.named_cause(causes)
    assert top is member, causes[:3]
    assert top.label == "the texture model: the speed shape of friction is a nonlinear function of profile_MPD"
    assert causes.index(sec) > 0 and causes[causes.index(sec)].label != SECTION_UNEXPLAINED


@pytest.mark.parametrize("seed", [0, 1])
def test_a_random_section_effect_in_the_speed_slope_is_section_unexplained(seed):
    """The same spread of slopes, but a random number per section: the texture model's x_speed members do not
    explain it (not significant, or less than half of the section effect), and ``section (unexplained)`` is named."""
    causes = _screen(seed, "section")
    top = cr.named_cause(causes)
    assert top is not None and top.variable == "section" and top.kind == "x_speed", causes[:3]
    assert top.label == SECTION_UNEXPLAINED
    for c in _between(causes, "texture_model[", "x_speed"):
        assert not (c.significant and c.section_share >= 0.5), c


def test_without_a_section_x_speed_effect_the_texture_model_is_not_asked_about_the_speed_shape():
    """No residual beyond noise: section x speed is not significant, so no x_speed texture-model test is made
    (the child family is asked only under a significant section x speed effect)."""
    res, sites, tex = _campaign(3, "mpd")
    res = res.assign(residual=np.random.default_rng(3).normal(0, 0.004, len(res)))
    causes = cr.screen_candidates(res, sites, tex, DiagnosisOptions(seed=3))
    sec = next(c for c in causes if c.variable == "section" and c.level == "between-site" and c.kind == "x_speed")
    assert not sec.significant
    assert not _between(causes, "texture_model[", "x_speed")


def test_members_of_two_lead_terms_and_the_contact_zone():
    """With the prediction model's two texture terms the members are a cubic of each, their quadratic surface
    ``[za zb, za^2, zb^2]`` and, where the table holds raw/micro Sp and Sq (mm), the contact-zone design; without
    raw_Sp there is no contact-zone member."""
    from skidsim.criticism.texture_candidate import texture_members

    rng = np.random.default_rng(5)
    n = 36
    cov = pd.DataFrame(
        {
            "profile_MPD": np.exp(rng.normal(0, 0.3, n)),
            "micro_Sq": np.exp(rng.normal(-3.5, 0.2, n)),
            "micro_Sp": np.exp(rng.normal(-2.0, 0.2, n)),
            "raw_Sq": np.exp(rng.normal(-1.0, 0.2, n)),
            "raw_Sp": np.exp(rng.normal(0.5, 0.2, n)),
        },
        index=[f"s{i}" for i in range(n)],
    )
    lead = ("log(profile_MPD)", "log(micro_Sq)")
    members = texture_members(cov.index, cov, "profile_MPD", np.zeros((n, 2)), lead, 2)
    names = [m.name for m in members]
    assert names == [
        "nonlinear in log(profile_MPD)",
        "nonlinear in log(micro_Sq)",
        "curved in log(profile_MPD) and log(micro_Sq)",
        "contact-zone microtexture",
    ], names
    z = lambda x: (x - x.mean()) / x.std()  # noqa: E731
    za, zb = z(np.log(cov["profile_MPD"].to_numpy())), z(np.log(cov["micro_Sq"].to_numpy()))
    assert np.allclose(members[2].design[:, 1], z(za**2)) and np.allclose(members[2].design[:, 0], z(za * zb))
    peak = z(np.log(cov["raw_Sp"] / cov["raw_Sq"]).to_numpy())
    assert np.allclose(members[3].design[:, 0], peak)
    assert all(m.design.shape == (n, 3) for m in members)
    without = texture_members(cov.index, cov.drop(columns="raw_Sp"), "profile_MPD", np.zeros((n, 2)), lead, 2)
    assert "contact-zone microtexture" not in [m.name for m in without]
    assert members[0].speed_words == "the speed shape of friction is a nonlinear function of log(profile_MPD)"


def test_mpd_x_speed_goes_above_the_texture_clusters_that_hold_mpd_within_sites_only():
    """Ranking alone (``rank_causes``): a between-site cluster holding MPD whose level term has 8 times the
    predictive evidence (cv_msr) of MPD x speed stays above a between-site MPD x speed (itself a texture-model misfit:
    on the chips texture x speed rate campaigns the cluster's level term predicts held-out sites, MPD x speed does
    not), while a within-site MPD x speed (the drainage hypothesis) goes above it, also where a between-site MPD x
    speed ranks before it; MPD x speed at either level goes above a texture-model x speed member built on MPD (its
    cubic nests the linear column)."""
    from dataclasses import replace

    from skidsim.criticism.causes import Cause
    from skidsim.criticism.ranking import rank_causes

    group = ("macro_Sdq", "macro_Sdr", "profile_MPD")

    def cause(variable, kind, cv_msr, **kw):
        c = Cause(variable, "between-site", kind, 0.01, 0.5, 0.0001, 0.005, True, source="texture", group=group)
        return replace(c, cv_msr=cv_msr, **kw)

    cluster = cause("macro_Sdq", "main", 7e-4, unit="cluster:macro_Sdq")
    mpd = cause("profile_MPD", "x_speed", 9e-5, unit="profile_MPD", family="primary")
    member = cause("texture_model[nonlinear in profile_MPD]", "x_speed", 5e-4, source="texture_model", group=())
    cov = pd.DataFrame({"profile_MPD": np.linspace(0.5, 1.5, 6)}, index=[f"s{k}" for k in range(6)])
    out = rank_causes([mpd, cluster], cov, "profile_MPD")
    assert [c.variable for c in out] == ["macro_Sdq", "profile_MPD"]
    within = replace(mpd, level="within-site")
    out = rank_causes([within, cluster], cov, "profile_MPD")
    assert [(c.variable, c.level) for c in out] == [("profile_MPD", "within-site"), ("macro_Sdq", "between-site")]
    for m in (mpd, within):
        out = rank_causes([m, member, cluster], cov, "profile_MPD")
        assert out.index(m) < out.index(member), out
    out = rank_causes([mpd, member], cov, "profile_MPD")
    assert out[0] is mpd
    # both levels significant, the between-site one ranked first by cv_msr: the drainage hypothesis moves
    out = rank_causes([cluster, replace(mpd, cv_msr=3e-4), replace(within, cv_msr=1e-4)], cov, "profile_MPD")
    assert [(c.variable, c.level) for c in out][:2] == [("profile_MPD", "within-site"), ("macro_Sdq", "between-site")]


def test_mpd_x_speed_within_sites_goes_only_above_the_clusters_mpd_describes():
    """Drainage's footprint between sites is a function of MPD: a within-site MPD x speed goes above a cluster
    holding MPD only where MPD's own between-site term of the cluster's kind carries at least half its cv_msr
    (``DRAINAGE_FOOTPRINT_SHARE``; 0.81-1.06 on the residual-level drainage campaigns, -0.20 to 0.41 on the chips
    texture x speed campaigns with Rado's curves at seeds 0 and 1), and not past a cluster it does not describe; a
    texture-model x speed member in MPD above such a cluster goes right below the MPD column that it nests."""
    from dataclasses import replace

    from skidsim.criticism.causes import Cause
    from skidsim.criticism.ranking import DRAINAGE_FOOTPRINT_SHARE, _mpd_above_its_clusters, rank_causes

    group = ("macro_Sdq", "macro_Sdr", "profile_MPD")

    def cause(variable, kind, cv_msr, level="between-site", **kw):
        c = Cause(variable, level, kind, 0.01, 0.5, 0.0001, 0.005, True, source="texture", group=group)
        return replace(c, cv_msr=cv_msr, **kw)

    cov = pd.DataFrame({"profile_MPD": np.linspace(0.5, 1.5, 6)}, index=[f"s{k}" for k in range(6)])
    within = cause("profile_MPD", "x_speed", 7.7e-5, level="within-site", unit="profile_MPD", family="primary")
    level = cause("macro_Sdq", "main", 7.1e-4, unit="cluster:macro_Sdq")
    slope = cause("macro_Sdr", "x_speed", 2.1e-4, unit="cluster:macro_Sdr")
    # chips + Rado, seed 0: MPD's own between-site level term carries 0.13 of the cluster's, its slope term 0.41
    mpd_level = cause("profile_MPD", "main", 0.13 * 7.1e-4, significant=False, p_adjusted=0.065)
    mpd_slope = cause("profile_MPD", "x_speed", 0.41 * 2.1e-4, significant=False, p_adjusted=0.06)
    out = rank_causes([within, level, slope, mpd_level, mpd_slope], cov, "profile_MPD")
    assert [c.variable for c in out[:3]] == ["macro_Sdq", "macro_Sdr", "profile_MPD"], out
    assert out[2].level == "within-site"
    # MPD describes both clusters (drainage: 0.81-1.06): the drainage hypothesis goes first
    share = DRAINAGE_FOOTPRINT_SHARE
    described = [replace(mpd_level, cv_msr=0.9 * 7.1e-4), replace(mpd_slope, cv_msr=1.01 * 2.1e-4)]
    out = rank_causes([within, level, slope, *described], cov, "profile_MPD")
    assert out[0] is within, out
    # at the threshold it still moves; just under it, not
    at = [replace(mpd_level, cv_msr=share * 7.1e-4), replace(mpd_slope, cv_msr=share * 2.1e-4)]
    assert rank_causes([within, level, slope, *at], cov, "profile_MPD")[0] is within
    under = [replace(mpd_level, cv_msr=0.99 * share * 7.1e-4), described[1]]
    out = rank_causes([within, level, slope, *under], cov, "profile_MPD")
    # it passes the slope cluster MPD describes, but not the level cluster above it that MPD does not
    assert [(c.variable, c.level) for c in out[:3]] == [
        ("macro_Sdq", "between-site"),
        ("profile_MPD", "within-site"),
        ("macro_Sdr", "between-site"),
    ], out
    # a texture-model member nonlinear in MPD ranked above that level cluster goes right below the MPD column (the
    # rule alone, on a list in rank order)
    member = cause("texture_model[nonlinear in profile_MPD]", "x_speed", 9e-4, source="texture_model", group=())
    ranked = [member, level, slope, within, *under]
    _mpd_above_its_clusters(ranked, "profile_MPD")
    assert [c.variable for c in ranked[:4]] == ["macro_Sdq", "profile_MPD", member.variable, "macro_Sdr"], ranked


def test_mpd_x_speed_within_sites_goes_above_the_mpd_column_between_sites():
    """The MPD column itself between sites (its level or its speed slope) is drainage's footprint, which MPD
    describes: a significant within-site MPD x speed (the drainage hypothesis, whose extension recovers the squeeze
    form's kappa within sites) goes above it, past nothing that MPD does not describe (the drainage rate campaigns,
    default seed 3 and chips seed 5, 2026-12-07); without a within-site MPD x speed the column keeps its place."""
    from dataclasses import replace

    from skidsim.criticism.causes import Cause
    from skidsim.criticism.ranking import rank_causes

    def cause(variable, kind, cv_msr, level="between-site", **kw):
        c = Cause(variable, level, kind, 0.01, 0.5, 0.0001, 0.005, True, source="texture", group=(variable,))
        return replace(c, cv_msr=cv_msr, **kw)

    cov = pd.DataFrame({"profile_MPD": np.linspace(0.5, 1.5, 6)}, index=[f"s{k}" for k in range(6)])
    within = cause("profile_MPD", "x_speed", 1.0e-4, level="within-site", unit="profile_MPD", family="primary")
    between = cause("profile_MPD", "main", 2.0e-4, unit="profile_MPD")
    slope = cause("profile_MPD", "x_speed", 1.5e-4, unit="profile_MPD")
    for column in (between, slope):
        out = rank_causes([within, column], cov, "profile_MPD")
        assert out[0] is within and out[1] is column, out
        assert rank_causes([column], cov, "profile_MPD")[0] is column
    # a cluster that MPD does not describe above the column stays above both
    other = cause("macro_Sdq", "main", 7e-4, unit="cluster:macro_Sdq", group=("macro_Sdq", "profile_MPD"))
    mpd_low = replace(between, cv_msr=0.1 * 7e-4)
    out = rank_causes([within, other, mpd_low], cov, "profile_MPD")
    assert [(c.variable, c.level) for c in out] == [
        ("macro_Sdq", "between-site"),
        ("profile_MPD", "within-site"),
        ("profile_MPD", "between-site"),
    ], out
