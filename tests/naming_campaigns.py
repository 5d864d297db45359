"""Campaigns and helpers of the tests of issue 33's naming (test_criticism_naming.py, test_criticism_extensions.py,
test_criticism_section_columns.py, test_criticism_beyond_texture.py): naming the right cause when the texture model
is what is wrong.

Campaigns: the sites and texture of tests/diagnosis_campaigns.py (36 sites, 12 sections), friction from the
exponential-decay law with the texture dependence of that harness, plus one hidden effect written here (the truth
stays in this file); calibration and texture predictions by the harness's cheap path (derive_tables: scipy
curve_fit, principal-component regression of each site's level on all texture columns times the training mean
shape). ``cause`` builds a screened cause by hand for the tests of the naming rule alone; ``rate_screen`` screens a
rate campaign of tests/diagnosis_rate_campaigns.py as the diagnosis does. Units: speeds km/h, friction mu, MPD mm,
temperatures deg C.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
import diagnosis_campaigns as dc
from diagnosis_rate_campaigns import screen_rate_campaign

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisInputs, DiagnosisOptions
from skidsim.criticism.causes import Cause

#: sizes of the hidden effects of this file's campaigns
NONLINEAR_MPD = 0.06  # friction x (1 - 0.06 (z^2 - 1)), z = standardised MPD: a curvature the linear model misses
AADT_LOSS = 0.08  # friction x (1 - 0.08 (aadt - 16000) / 14000): polishing by traffic, a section-level number
AGGREGATE_LOSS = 0.10  # polished aggregate: friction x (1 - 0.10 max(0, min(1, (60 - v) / 40)))
SLOPE_HYSTERESIS = 0.04  # friction x (1 - 0.04 z(micro_Sdq) (v - 20) / 50): hysteresis growing with speed and slope


def campaign(seed: int, effect: str | None, trace_step_kmh: float = 4.0, noise_mu: float = 0.005) -> dict:
    """The diagnosis tables of a campaign with one hidden effect: None, "nonlinear_mpd", "aadt" (traffic per
    section, vehicles per day), "aggregate_speed" (a categorical section column whose 'polished' level loses
    low-speed friction), "slope_speed" (hysteresis growing with speed and the micro rms slope micro_Sdq). Every
    campaign has the section-level columns aadt and aggregate (with or without an effect)."""
    sites, _, tex, _ = dc.generate_campaign(seed, None)
    rng = np.random.default_rng(seed + 1000)
    n = len(sites)
    sec = pd.factorize(sites["section"])[0]
    n_sec = int(sec.max()) + 1
    aadt = np.round(rng.uniform(2000, 30000, n_sec))[sec]
    kinds = np.array(["polished", "granite", "limestone"])
    aggregate = kinds[rng.permutation(n_sec) % 3][sec]
    sites = sites.assign(aadt=aadt, aggregate=aggregate)
    micro = (tex["micro_Sq_mm"].to_numpy() - 0.03) / 0.005
    mpd = tex["mpd_mm"].to_numpy()
    mu_k = 0.30 + 0.04 * micro + 0.012 * rng.normal(size=n)
    mu_s = mu_k + 0.30 + 0.04 * micro + 0.015 * rng.normal(size=n)
    alpha = 0.10 * np.exp(0.10 * rng.normal(size=n))
    zm = (mpd - mpd.mean()) / mpd.std()

    def mu(i, v):
        m = dc._law(v, mu_s[i], mu_k[i], alpha[i])
        if effect == "nonlinear_mpd":
            m = m * (1 - NONLINEAR_MPD * (zm[i] ** 2 - 1))
        elif effect == "aadt":
            m = m * (1 - AADT_LOSS * (aadt[i] - 16000) / 14000)
        elif effect == "slope_speed":
            sdq = (tex["micro_Sdq"].to_numpy()[i] - 0.40) / 0.06
            m = m * (1 - SLOPE_HYSTERESIS * sdq * (v - 20.0) / 50.0)
        elif effect == "aggregate_speed":
            m = m * (1 - AGGREGATE_LOSS * (aggregate[i] == "polished") * np.clip((60.0 - v) / 40.0, 0, 1))
        return m

    rows = []
    tv = np.arange(20.0, 80.0 + 1e-9, trace_step_kmh)
    for i in range(n):
        for kind, vs, sd in (
            ("calibration", (20.0, 40.0, 60.0), noise_mu),
            ("validation", (30.0, 50.0, 70.0), noise_mu),
            ("trace", tv, 1.5 * noise_mu),
        ):
            vs = np.asarray(vs, float)
            y = mu(i, vs) + sd * rng.normal(size=len(vs))
            rows += [(sites["site"][i], float(v), float(m), kind) for v, m in zip(vs, y)]
    measured = pd.DataFrame(rows, columns=["site", "speed_kmh", "mu", "kind"])
    return dc.derive_tables(sites, measured, tex)


def screen(tables, seed):
    """The screening of a campaign's tables (:func:`campaign`) with the default options and ``seed``."""
    res = cr.build_residuals(tables["sites"], tables["measured"], tables["simulated"], tables["predicted"])
    return cr.screen_candidates(res, tables["sites"], tables["texture"], DiagnosisOptions(seed=seed))


def diagnose(tables, **kw):
    """The whole diagnosis of a campaign's tables; ``kw``: DiagnosisOptions fields."""
    t = tables
    inputs = DiagnosisInputs(t["sites"], t["measured"], t["simulated"], t["predicted"], t["texture"])
    return cr.diagnose(inputs, DiagnosisOptions(**kw))


def cause(variable, share, *, sig=True, kind="main", section_level=True, section_id=False, source="sites", cv=0.5):
    """A screened cause between sites for the tests of the naming rule alone: ``share`` of the section effect
    (of its kind and of the site means), p 0.001, p_adjusted 0.01, effect 0.01 mu, cv_gain ``cv``."""
    return Cause(
        variable=variable,
        level="between-site",
        kind=kind,
        effect=0.01,
        cv_gain=cv,
        p_value=0.001,
        p_adjusted=0.01,
        significant=sig,
        dtype="categorical" if section_id else "numeric",
        section_level=section_level,
        source=source,
        section_share=share,
        section_share_main=share,
        section_id=section_id,
    )


def rate_screen(t, seed, **options):
    """The screening of a rate campaign's tables as the diagnosis runs it
    (``diagnosis_rate_campaigns.screen_rate_campaign``; ``options``: DiagnosisOptions fields other than the seed,
    e.g. ``fdr``)."""
    return screen_rate_campaign(t, DiagnosisOptions(seed=seed, **options))


def section_column_level(seed: int, effect: str, texture: str | None = None):
    """One between-site level of 36 sites in 12 sections of 3 with a 4-level section column `aggregate` (3 sections
    per level) and a 2-level decoy `binder`; residual speed profiles (6 bins) hold `effect`: "aggregate" (its
    'limestone' sections lose 0.03 mu at low speed), or "latent" (a random speed slope per section, no column).
    ``texture``: the texture model's member of the leading texture PCs is passed to the test, a design drawn per
    section (plus a little per site); "misfit" adds a speed slope along it to the residual (the texture model's
    misfit, clustered by section as the texture designs are), "unrelated" adds nothing."""
    from skidsim.criticism.covariates import CandidateRoles, candidate_set
    from skidsim.criticism.levels import LevelData, level_context
    from skidsim.criticism.screening import covariate_tests
    from skidsim.criticism.section_tests import section_rest_tests
    from skidsim.criticism.texture_candidate import PCS_MEMBER, TextureMember

    rng = np.random.default_rng(seed)
    sec = np.repeat(np.arange(12), 3)
    tex_rng = np.random.default_rng(1000 + seed)
    design = tex_rng.normal(size=(12, 3))[sec] + 0.2 * tex_rng.normal(size=(36, 3))
    design = (design - design.mean(axis=0)) / design.std(axis=0)
    agg = np.array(["limestone", "granite", "basalt", "gritstone"])[rng.permutation(12) % 4][sec]
    binder = np.array(["PG64-22", "PG76-22"])[rng.permutation(12) % 2][sec]
    sites = pd.DataFrame({"site": [f"s{i:02d}" for i in range(36)], "section": [f"S{g:02d}" for g in sec]})
    sites = sites.assign(aggregate=agg, binder=binder)
    bins = np.arange(20.0, 80.0, 10.0)
    R = 0.004 * rng.normal(size=(36, len(bins)))
    if effect == "aggregate":
        R -= 0.03 * (agg == "limestone")[:, None] * np.clip((60 - bins) / 40, 0, 1)[None, :]
    else:
        R += 0.01 * rng.normal(size=12)[sec][:, None] * (bins - bins.mean())[None, :] / 25
    if texture == "misfit":
        R += 0.01 * (design @ [1.0, 0.5, -0.5])[:, None] * (bins - bins.mean())[None, :] / 25
    cands = candidate_set(sites, None, CandidateRoles(), 0.8)
    data = LevelData("between-site", list(sites["site"]), bins, R)
    ctx = level_context(data, cands, 1999, np.random.default_rng(seed + 1))
    tests = [t for t in covariate_tests(ctx, None) if t.kind == "x_speed"]
    members = [TextureMember(PCS_MEMBER, "the leading texture PCs", design)] if texture else []
    section_rest_tests(ctx, tests, members=members)
    return ctx, {t.variable: t for t in tests}
