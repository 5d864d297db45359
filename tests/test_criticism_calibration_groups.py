"""Which calibrated sites carry a within-site shape (skidsim.criticism.calibration_groups): the sites whose
calibration did not settle, those whose mu_s sits at its upper bound, and the others. Residual tables built here
with known profiles, so each group's profile and share are known exactly. Units: speeds km/h, friction mu.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skidsim.criticism.calibration_groups import GROUPS, calibration_groups, site_groups

SPEEDS = np.r_[np.arange(20.0, 70.0, 2.5), 70.0]  # a trace every 2.5 km/h up to 70 km/h


def residual_table(profiles: dict) -> pd.DataFrame:
    """Within-site rows of sites (each its own section) whose residual at speed v is ``profiles[site](v)``, and
    between-site rows that must be ignored."""
    rows = []
    for site, f in profiles.items():
        for v in SPEEDS:
            rows.append({"site": site, "section": site, "level": "within-site", "speed_kmh": v, "residual": f(v)})
            rows.append({"site": site, "section": site, "level": "between-site", "speed_kmh": v, "residual": 1.0})
    return pd.DataFrame(rows)


def falling(v):
    """The tilt of a law pinned at its upper bound: +0.0125 mu at 20 km/h, falling 0.0005 mu per km/h."""
    return 0.0125 - 0.0005 * (v - 20.0)


def flat(v):
    return 0.0


BOUND = ["a1", "a2", "a3", "a4"]
UNSETTLED = ["u1", "u2"]
INSIDE = ["b1", "b2", "b3", "b4", "b5", "b6"]


def record() -> pd.DataFrame:
    """The calibration's record: 4 sites at the upper bound of mu_s (one also at mu_k's lower bound), 2 not settled
    (one of them also at the bound: not settled comes first), 6 inside the bounds (one at mu_k's lower bound)."""
    return pd.DataFrame(
        {
            "site": BOUND + UNSETTLED + INSIDE,
            "flags": ["at_bound"] * 4
            + ["at_bound;not_converged", "outside_law;fit_beyond_noise"]
            + [np.nan] * 5
            + ["at_bound"],
            "at_bound_params": ["mu_s:upper", "mu_s:upper;mu_k:lower", "mu_s:upper", "mu_s:upper", "mu_s:upper", np.nan]
            + [np.nan] * 5
            + ["mu_k:lower"],
        }
    )


def test_each_site_goes_to_the_first_group_that_applies():
    g = site_groups(record())
    assert g[BOUND].eq("at the upper bound of mu_s").all()
    assert g[UNSETTLED].eq("not settled").all()
    assert g[INSIDE].eq("inside the bounds").all()


def test_the_shares_split_the_mean_profile_among_the_groups():
    """The sites at the bound fall with speed, the others are flat: the bound group's profile is the line's value at
    each bin's mean speed (bins centred on multiples of 10 km/h, a speed halfway rounded to the even multiple:
    25 km/h to 20, 35 to 40) less its mean over the bins (centred, as the functional form's test), and it
    carries the whole shared shape (share 1, the others 0). Its own permutation p is the chance that random
    signs of its 4 sections' profiles all agree, 2 / 2^4; a flat group's p is 1. With the unsettled sites
    falling 1.5 times as steeply, the shares follow the sites' weights in the mean profile (4 x 1 against 2 x
    1.5), and with every group falling the largest share below a half is "the largest part"; the shares always
    add up to 1."""
    res = residual_table({**dict.fromkeys(BOUND, falling), **dict.fromkeys(UNSETTLED + INSIDE, flat)})
    rec = calibration_groups(res, record(), n_perm=999, seed=3)
    assert rec["speeds_kmh"] == [20.0, 30.0, 40.0, 50.0, 60.0, 70.0]
    assert rec["speed_range_kmh"][0] == [20.0, 25.0] and rec["speed_range_kmh"][1] == [27.5, 32.5]
    assert rec["speed_range_kmh"][-1] == [67.5, 70.0]
    centres = np.array([np.mean(SPEEDS[(SPEEDS >= lo) & (SPEEDS <= hi)]) for lo, hi in rec["speed_range_kmh"]])
    line = falling(centres) - falling(centres).mean()
    by = {g["group"]: g for g in rec["groups"]}
    assert np.allclose(by["at the upper bound of mu_s"]["profile_mu"], line, atol=1e-15)
    assert np.allclose(rec["shared_profile_mu"], 4 / 12 * line, atol=1e-15)
    assert by["at the upper bound of mu_s"]["share"] == pytest.approx(1.0, abs=1e-12)
    assert by["not settled"]["share"] == 0.0 and by["inside the bounds"]["share"] == 0.0
    assert by["at the upper bound of mu_s"]["p_alone"] == pytest.approx(2 / 16, abs=0.04)
    assert by["not settled"]["p_alone"] == 1.0 and by["inside the bounds"]["p_alone"] == 1.0
    assert by["not settled"]["sites"] == UNSETTLED
    assert "most of it is carried by the sites at the upper bound of mu_s: the law's upper bound" in rec["reading"]
    assert "4 at the upper bound of mu_s (+0.011 to -0.012)" in rec["reading"]  # the profile's ends, 3 decimals
    assert "share 1.00, alone p 0.1" in rec["reading"]

    steep = residual_table(
        {
            **dict.fromkeys(BOUND, falling),
            **{s: (lambda v: 1.5 * falling(v)) for s in UNSETTLED},
            **dict.fromkeys(INSIDE, flat),
        }
    )
    shares = {g["group"]: g["share"] for g in calibration_groups(steep, record())["groups"]}
    assert shares["at the upper bound of mu_s"] == pytest.approx(4 / 7, abs=1e-12)
    assert shares["not settled"] == pytest.approx(3 / 7, abs=1e-12)
    assert sum(shares.values()) == pytest.approx(1.0, abs=1e-12)
    spread = residual_table(
        {
            **dict.fromkeys(BOUND + UNSETTLED, falling),
            **{s: (lambda v: 0.5 * falling(v)) for s in INSIDE},
        }
    )
    rec = calibration_groups(spread, record())
    shares = {g["group"]: g["share"] for g in rec["groups"]}
    assert [shares[k] for k in GROUPS] == pytest.approx([2 / 9, 4 / 9, 3 / 9], abs=1e-12)
    assert "the largest part is carried by the sites at the upper bound of mu_s" in rec["reading"]


def test_a_shape_of_the_well_calibrated_sites_is_the_fe_response():
    """The fall at the sites inside the bounds only: they carry it, and the reading says it is the FE's response to
    the law; a group running against the shared shape has a negative share."""
    res = residual_table(
        {
            **{s: (lambda v: -0.5 * falling(v)) for s in BOUND},
            **dict.fromkeys(UNSETTLED, flat),
            **dict.fromkeys(INSIDE, falling),
        }
    )
    rec = calibration_groups(res, record())
    shares = {g["group"]: g["share"] for g in rec["groups"]}
    assert shares["at the upper bound of mu_s"] < 0 < shares["inside the bounds"]
    assert sum(shares.values()) == pytest.approx(1.0, abs=1e-12)
    assert rec["reading"].endswith(
        "the FE's response to the law between the calibration speeds, at sites the calibration fitted inside its bounds"
    )


def test_no_reading_without_within_site_rows_of_recorded_sites_or_a_shape():
    res = residual_table(dict.fromkeys(BOUND, falling))
    assert calibration_groups(res[res["level"] == "between-site"], record()) is None
    assert calibration_groups(res, record().iloc[4:]) is None  # none of the residual's sites in the record
    assert calibration_groups(residual_table(dict.fromkeys(BOUND, flat)), record()) is None  # no shape to share


def test_the_profiles_are_the_functional_form_matrix():
    """The groups' profiles are the functional form's centred site profiles: per site the mean residual in each
    bin centred on a multiple of 10 km/h, the bins observed at every site, minus the site's mean over them; computed
    here by hand on random residuals (one site lacks the 70 km/h bin, which is then dropped for all)."""
    rng = np.random.default_rng(5)
    sites = BOUND + UNSETTLED + INSIDE
    coef = rng.normal(size=(len(sites), 2))
    res = residual_table({s: (lambda v, c=c: 0.01 * c[0] + 0.0003 * c[1] * v) for s, c in zip(sites, coef)})
    res.loc[res["level"] == "within-site", "residual"] += rng.normal(0, 0.002, (res["level"] == "within-site").sum())
    res = res[~((res["site"] == "b6") & (res["speed_kmh"] >= 67.5))]
    rec = calibration_groups(res, record())
    w = res[res["level"] == "within-site"]
    tab = w.assign(b=[10.0 * round(v / 10.0) for v in w["speed_kmh"]]).pivot_table("residual", "site", "b", "mean")
    tab = tab.loc[:, tab.notna().all()]
    D = tab.sub(tab.mean(axis=1), axis=0)
    assert rec["speeds_kmh"] == [20.0, 30.0, 40.0, 50.0, 60.0]
    assert np.allclose(rec["shared_profile_mu"], D.mean().to_numpy(), atol=1e-15)
    by = {g["group"]: g for g in rec["groups"]}
    for name in GROUPS:
        assert np.allclose(by[name]["profile_mu"], D.loc[by[name]["sites"]].mean().to_numpy(), atol=1e-15)


def pinned_campaign(seed: int = 5):
    """36 sites in 12 sections whose measured curves are exponential decays of speed; the calibrated simulation
    follows them at 18 sites and is tilted against them at the other 18, whose calibrated mu_s sits at its upper
    bound (too low at 20 km/h, too high at 70: +0.02 to -0.02 mu). Texture columns of noise; the texture-based
    predictions equal the truth. Returns the diagnosis inputs with the calibration's record."""
    from skidsim.criticism import DiagnosisInputs

    rng = np.random.default_rng(seed)
    n = 36
    site = [f"s{i:02d}" for i in range(n)]
    sites = pd.DataFrame({"site": site, "section": np.repeat([f"S{k:02d}" for k in range(12)], 3)})
    pinned = np.zeros(n, dtype=bool)
    pinned[rng.permutation(n)[:18]] = True
    v = np.arange(20.0, 70.1, 2.5)
    rows_m, rows_s, rows_p = [], [], []
    for i, s in enumerate(site):
        truth = 0.35 + 0.45 * np.exp(-rng.uniform(0.010, 0.025) * v)
        sim = truth - (0.02 - 0.0008 * (v - 20.0)) * pinned[i]
        kind = np.where(
            np.isin(v, [20.0, 40.0, 60.0]),
            "calibration",
            np.where(np.isin(v, [30.0, 50.0, 70.0]), "validation", "trace"),
        )
        mu = truth + rng.normal(0.0, 0.004, v.size)
        rows_m += [dict(site=s, speed_kmh=a, mu=b, kind=k) for a, b, k in zip(v, mu, kind)]
        rows_s += [dict(site=s, speed_kmh=a, sn=b) for a, b in zip(v, sim)]
        rows_p += [dict(site=s, speed_kmh=a, sn_pred=b) for a, b in zip(v, sim)]
    wide = pd.DataFrame({"site": site, **{f"macro_P{j}": rng.normal(size=n) for j in range(3)}})
    record = pd.DataFrame(
        {
            "site": site,
            "flags": np.where(pinned, "at_bound", ""),
            "at_bound_params": np.where(pinned, "mu_s:upper", ""),
        }
    )
    inputs = DiagnosisInputs(
        sites, pd.DataFrame(rows_m), pd.DataFrame(rows_s), pd.DataFrame(rows_p), wide, calibration=record
    )
    return inputs, sorted(np.array(site)[pinned])


def test_the_within_site_level_of_the_settled_sites_leaves_out_the_pinned_laws():
    """With every site, the tilt of the pinned laws is named as the within-site functional form, and gain.json's
    ``by_calibration`` gives the sites at the bound the whole shape. With ``within_site_sites: settled`` their
    within-site rows are left out (gain.json ``within_site_left_out`` and report.md say which), the between-site
    rows all stay, and the settled sites share no shape: no within-site cause is named."""
    from skidsim import criticism as cr
    from skidsim.criticism import DiagnosisOptions
    from skidsim.criticism.calibration_groups import settled_residuals
    from skidsim.criticism.report import report_markdown

    inputs, pinned = pinned_campaign()
    every = cr.diagnose(inputs, DiagnosisOptions(seed=2, n_boot=100, within_site_sites="all"))
    assert every.named is not None and every.named.variable == "functional_form"
    assert every.named.level == "within-site"
    groups = {g["group"]: g for g in every.gain["curve_form"]["by_calibration"]["groups"]}
    assert groups["at the upper bound of mu_s"]["sites"] == pinned
    assert groups["at the upper bound of mu_s"]["share"] > 0.9 and "within_site_left_out" not in every.gain

    settled = cr.diagnose(inputs, DiagnosisOptions(seed=2, n_boot=100, within_site_sites="settled"))
    assert settled.gain["within_site_left_out"] == {"at the upper bound of mu_s": pinned}
    within = settled.residuals[settled.residuals["level"] == "within-site"]
    assert set(within["site"]) == set(inputs.sites["site"]) - set(pinned)
    assert (settled.residuals["level"] == "between-site").sum() == (every.residuals["level"] == "between-site").sum()
    assert not any(c.significant and c.level == "within-site" for c in settled.causes), settled.causes[:3]
    report = report_markdown([], settled.gain, None, ".")
    assert settled.gain["within_site_sites_tested"] == 18
    assert (
        "Within-site tests on the 18 sites the calibration settled inside its bounds; left out: 18 where the " in report
    )
    assert "not screened" not in report
    kept, left = settled_residuals(every.residuals, inputs.calibration)
    assert left == {"at the upper bound of mu_s": pinned} and len(kept) == len(settled.residuals)


def test_too_few_settled_sites_leave_the_within_site_level_unscreened_and_the_report_says_so():
    """With 3 settled sites (fewer than the 4 a level needs) the within-site level is not screened: no within-site
    cause, gain.json counts the 3 sites and report.md says that no cause within sites could be named."""
    from skidsim import criticism as cr
    from skidsim.criticism import DiagnosisInputs, DiagnosisOptions
    from skidsim.criticism.report import report_markdown

    inputs, _ = pinned_campaign()
    rec = inputs.calibration.assign(flags="at_bound", at_bound_params="mu_s:upper")
    rec.loc[:2, ["flags", "at_bound_params"]] = ""
    few = DiagnosisInputs(
        inputs.sites, inputs.measured, inputs.simulated, inputs.predicted, inputs.texture, calibration=rec
    )
    r = cr.diagnose(few, DiagnosisOptions(seed=2, n_boot=50, within_site_sites="settled"))
    assert r.gain["within_site_sites_tested"] == 3
    assert len(r.gain["within_site_left_out"]["at the upper bound of mu_s"]) == 33
    assert not any(c.level == "within-site" for c in r.causes)
    report = report_markdown([], r.gain, None, ".")
    assert "Within-site tests on the 3 sites" in report
    assert "**The within-site level was not screened**: it needs at least 4 sites" in report
