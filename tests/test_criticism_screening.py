"""Tests of the screening machinery of skidsim.criticism: FDR adjustment, permutations, texture adjustment,
the MPD amplitude test, texture clusters and families, the ranking by refinement."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from diagnosis_campaigns import make_campaign

from skidsim import criticism as cr
from skidsim.criticism import DiagnosisOptions
from skidsim.criticism.adjustment import (
    adjusted_basis,
    basis,
    leverage_corrected,
    residualise,
    texture_adjustment,
)
from skidsim.criticism.permutations import nested_permutations, perm_stats, permutation_p
from skidsim.criticism.residuals import residual_matrix


@pytest.mark.parametrize("method, sm", [("bh", "fdr_bh"), ("by", "fdr_by")])
def test_adjust_pvalues_matches_statsmodels(method, sm):
    from statsmodels.stats.multitest import multipletests

    p = np.random.default_rng(0).uniform(0, 0.2, 40) ** 2
    assert cr.adjust_pvalues(p, method) == pytest.approx(multipletests(p, method=sm)[1], rel=1e-12)


def test_nested_permutations_keep_sections_whole():
    sec = np.repeat(np.array(["A", "B", "C", "D", "E"]), [3, 3, 3, 2, 2])
    perms = nested_permutations(sec, 200, np.random.default_rng(1))
    for p in perms:
        assert sorted(p) == list(range(len(sec)))
        # the sites now at the positions of each section all come from one section of the same size
        for s in np.unique(sec):
            src = sec[p[sec == s]]
            assert len(set(src)) == 1 and (sec == src[0]).sum() == (sec == s).sum()
    # sections do move and sites are shuffled within sections
    assert (sec[perms[:, 0]] != "A").any()
    assert len({tuple(p[:3]) for p in perms if sec[p[0]] == "A"}) > 1


def test_permutation_statistics_match_direct_projection():
    rng = np.random.default_rng(2)
    n, S = 12, 4
    Y = rng.normal(size=(n, S))
    x1 = rng.normal(size=n)
    lab = pd.Series(np.array(list("aabbccaabbcc")))
    Q = np.concatenate([basis(pd.Series(x1), "numeric"), basis(lab, "categorical")], axis=1)
    owner = np.array([0, 1, 1])
    perms = rng.permuted(np.tile(np.arange(n), (5, 1)), axis=1)
    T = perm_stats(Y, Q, owner, 2, perms)
    for k, p in enumerate(perms):
        Yp = Y[p] - Y[p].mean(axis=0)
        xc = x1 - x1.mean()
        assert T[k, 0] == pytest.approx(((xc @ Yp) ** 2).sum() / (xc @ xc))
        # categorical: between-group sum of squares
        ss = sum(((Yp[lab == g].sum(axis=0)) ** 2).sum() / (lab == g).sum() for g in "abc")
        assert T[k, 1] == pytest.approx(ss)


def test_texture_adjustment_picks_the_texture_dimension():
    """M linear in the first two texture PCs (plus small noise): leave-one-section-out CV picks k = 2, and the
    nuisance design spans the intercept and exactly those scores."""
    rng = np.random.default_rng(5)
    n = 36
    sec = np.repeat([f"S{k}" for k in range(12)], 3)
    scores = rng.normal(size=(n, 8)) * np.linspace(3, 0.5, 8)
    M = 0.5 + 0.04 * scores[:, [0]] - 0.03 * scores[:, [1]] + rng.normal(0, 0.002, size=(n, 5))
    k, N, k_cv = texture_adjustment(M, scores, sec, variance_share=0.5)
    assert k == k_cv == 2
    assert np.allclose(N, np.c_[np.ones(n), scores[:, :2]])
    # pure noise: nothing to adjust for beyond the mean (k small), never more than the cap
    k0, _, k0_cv = texture_adjustment(rng.normal(size=(n, 5)), scores, sec, variance_share=0.5)
    assert k0_cv <= 1 and texture_adjustment(M, scores, sec, k_max=1)[0] == 1
    # the texture-variance floor: 90 % of this texture's variance needs more than 2 PCs, so the test conditions
    # on them although CV would stop at 2; never beyond the cap
    var = scores.var(axis=0)
    k90 = int(np.searchsorted(np.cumsum(var) / var.sum(), 0.9) + 1)
    assert texture_adjustment(M[:6], scores[:6], sec[:6])[0] == 0  # 2 sections: no PC can be held out
    k_t, N_t, k_cv = texture_adjustment(M, scores, sec)
    assert k90 > 2 and k_t == min(k90, 10) and k_cv == 2 and N_t.shape == (n, 1 + k_t)


def test_texture_adjusted_statistic_is_the_partial_sum_of_squares():
    """Frisch-Waugh: the adjusted statistic |Q~' (I - H) y|^2 equals SSE([1, PCs]) - SSE([1, PCs, z]) of two
    direct least-squares fits (an independent computation), and a covariate inside the texture span has no basis."""
    rng = np.random.default_rng(6)
    n = 30
    S = rng.normal(size=(n, 3))
    z = 0.8 * S[:, 0] + rng.normal(size=n)
    y = 1 + S @ [0.3, -0.2, 0.1] + 0.25 * z + rng.normal(0, 0.1, size=n)
    N = np.c_[np.ones(n), S]
    Q = adjusted_basis(basis(pd.Series(z), "numeric"), N)
    T = float(((Q.T @ residualise(y[:, None], N)) ** 2).sum())

    def sse(X):
        return float(((y - X @ np.linalg.lstsq(X, y, rcond=None)[0]) ** 2).sum())

    assert T == pytest.approx(sse(N) - sse(np.c_[N, z]), rel=1e-10)
    assert adjusted_basis(basis(pd.Series(S[:, 1] * 2 + 1), "numeric"), N).shape[1] == 0


WITHIN_SPEEDS_KMH = np.arange(20.0, 71.0, 5.0)


def _within_rows(amp, rng, speeds=WITHIN_SPEEDS_KMH, noise=0.002):
    """Within-site residual rows: site i's residual is amp_i * shape(v) plus white noise (mu)."""
    shape = 0.01 * (1.0 - ((speeds - 45.0) / 25.0) ** 2) - 0.01 * (speeds > 60) * (speeds - 60.0) / 10.0
    rows = [
        (f"s{i}", "trace", v, a * h + noise * rng.normal()) for i, a in enumerate(amp) for v, h in zip(speeds, shape)
    ]
    r = pd.DataFrame(rows, columns=["site", "kind", "speed_kmh", "residual"])
    return r.assign(level="within-site", measured=0.5 + r["residual"], model=0.5)


def test_within_site_shape_amplitude_follows_inverse_speed_constant():
    """A residual shape shared by all sites whose amplitude follows the IFI 1/Sp(MPD) (drainage): MPD x speed is
    tested on the shape's amplitude (one degree of freedom), is significant, and ranks above the functional form
    (the shared shape is its mean); with amplitudes unrelated to MPD the functional form alone is named; the
    statistic equals the squared projection computed directly."""
    rng = np.random.default_rng(3)
    n = 36
    sites = pd.DataFrame(
        {
            "site": [f"s{i}" for i in range(n)],
            "section": np.repeat([f"S{k}" for k in range(12)], 3),
            "temperature_c": rng.uniform(10, 20, n),
        }
    )
    mpd = rng.uniform(0.45, 1.45, n)
    tex = pd.DataFrame({"site": sites["site"], "profile_MPD": mpd, "other": rng.normal(size=n)})
    inv_sp = 1.0 / (14.2 + 89.7 * mpd)
    amp = inv_sp / inv_sp.mean()  # mean 1: the shared shape, modulated by drainage
    res = _within_rows(amp, rng)
    causes = cr.screen_candidates(res, sites, tex, DiagnosisOptions(seed=0))
    top = causes[0]
    assert (top.variable, top.level, top.kind, top.significant) == ("profile_MPD", "within-site", "x_speed", True)
    assert top.family == "primary" and top.direction == -1  # deeper texture, weaker shape error
    ff = next(c for c in causes if c.kind == "functional_form")
    assert ff.significant and causes.index(ff) == 1
    # the statistic: squared projection of the shapes' amplitudes (on the unit mean shape) on the centred 1/Sp
    ids, bins, R = residual_matrix(res, 10.0)
    D = R - R.mean(axis=1, keepdims=True)
    f = D.mean(axis=0)
    a = (D - f) @ (f / np.linalg.norm(f))
    z = pd.Series(inv_sp, index=sites["site"]).loc[ids].to_numpy()
    z = (z - z.mean()) / np.linalg.norm(z - z.mean())
    assert top.statistic == pytest.approx(float(z @ a) ** 2, rel=1e-9)
    # amplitudes unrelated to MPD: the shared shape is the cause
    causes0 = cr.screen_candidates(
        _within_rows(rng.permutation(amp), np.random.default_rng(4)), sites, tex, DiagnosisOptions(seed=0)
    )
    assert causes0[0].kind == "functional_form" and causes0[0].significant
    assert not next(c for c in causes0 if c.variable == "profile_MPD").significant


def test_texture_clusters_and_families():
    """Correlated texture parameters form one cluster (every pair |Spearman rho| >= 0.8); the physical hypotheses
    (functional form, temperature between sites, MPD x speed) form the primary family."""
    tables, _ = make_campaign(seed=0, effect=None)
    cov, info = cr.site_covariates(tables["sites"], tables["texture"])
    cl = cr.texture_clusters(cov, info, 0.8)
    macro = next(c for c in cl if "mpd_mm" in c)
    assert {"mpd_mm", "macro_Sq_mm", "macro_Sa_mm", "macro_Sdr_pct"} <= set(macro)
    assert not any(c.startswith("micro") for c in macro)
    for c in cl:
        rho = cov[c].rank().corr().abs().to_numpy()
        assert rho.min() >= 0.8
    assert cr.find_mpd_column(cov, info) == "mpd_mm"
    assert cr.find_mpd_column(pd.DataFrame(columns=["profile_MPD_sd", "profile_MPD", "x"])) == "profile_MPD"
    res = cr.build_residuals(tables["sites"], tables["measured"], tables["simulated"], tables["predicted"])
    with pytest.warns(RuntimeWarning, match="can never be significant"):
        causes = cr.screen_candidates(
            res, tables["sites"], tables["texture"], DiagnosisOptions(seed=0, n_permutations=199)
        )
    prim = {(c.variable, c.level, c.kind) for c in causes if c.family == "primary"}
    assert prim == {
        ("functional_form", "within-site", "functional_form"),
        ("functional_form", "between-site", "functional_form"),
        ("temperature_c", "between-site", "main"),
        ("temperature_c", "between-site", "x_speed"),
        ("mpd_mm", "within-site", "x_speed"),
        ("mpd_mm", "between-site", "x_speed"),
        # the texture model as a candidate (one unit: its members share one minP test)
        ("texture_model[nonlinear in mpd_mm]", "between-site", "main"),
        ("texture_model[texture PCs 1-3]", "between-site", "main"),
        ("texture_model[texture PCs 1-8]", "between-site", "main"),
    }
    tm = [c for c in causes if c.source == "texture_model"]
    assert len({c.unit for c in tm}) == 1 and len({c.unit_p for c in tm}) == 1
    # the MPD column x speed: drainage within sites; between sites the IFI speed constant the texture model misses
    mpd = {c.level: c for c in causes if c.variable == "mpd_mm" and c.kind == "x_speed"}
    assert mpd["within-site"].label == "" and mpd["within-site"].category == "drainage"
    assert mpd["between-site"].label.startswith("the texture model misses how mpd_mm changes the speed shape")
    assert "IFI speed constant" in mpd["between-site"].label and mpd["between-site"].category == "texture model"
    # a cluster is one unit: its members share the unit, its max-statistic p-value, and p_adjusted >= unit_p
    mac = [c for c in causes if c.variable in macro and c.level == "between-site" and c.kind == "main"]
    rep = max(mac, key=lambda c: c.statistic)
    assert {c.unit for c in mac} == {f"cluster:{rep.variable}"} and len(mac) == len(macro)
    assert len({c.unit_p for c in mac}) == 1 and rep.unit_p >= rep.p_value  # the max over members costs power
    assert all(c.p_adjusted >= c.unit_p for c in mac)


def test_order_by_refinement_puts_the_coarser_grouping_first():
    """A finer grouping ranked first by cv (comment: mixes split by RAS) moves right below the coarser one it refines
    (mix); section identity also goes below mix; a column that does not nest in mix (binder cuts across it), a
    numeric column and a cause of another kind keep their places."""
    secs = [f"S{k}" for k in range(6)]
    cov = pd.DataFrame(
        {
            "section": secs,
            "mix": ["HMA", "HMA", "WMA", "WMA", "WMA", "SMA"],
            "comment": ["HMA+RAS", "HMA", "WMA+RAS", "WMA", "WMA", "SMA"],
            "binder": ["A", "B", "A", "B", "A", "B"],
            "station_ft": np.arange(6.0),
        },
        index=[f"{s}-1" for s in secs],
    )

    def cause(v, kind="main", dtype="categorical", sig=True):
        return cr.Cause(
            variable=v,
            level="between-site",
            kind=kind,
            effect=0.01,
            cv_gain=0.5,
            p_value=0.01,
            p_adjusted=0.02,
            significant=sig,
            dtype=dtype,
            section_level=True,
        )

    order = [
        cause("comment"),
        cause("section"),
        cause("station_ft", dtype="numeric"),
        cause("binder"),
        cause("mix"),
        cause("comment", kind="x_speed"),
    ]
    out = [(c.variable, c.kind) for c in cr.order_by_refinement(order, cov)]
    assert out == [
        ("station_ft", "main"),
        ("binder", "main"),
        ("mix", "main"),
        ("comment", "main"),
        ("section", "main"),
        ("comment", "x_speed"),
    ], out
    assert cr.refines(order[0], order[4], cov) and not cr.refines(order[4], order[0], cov)
    assert not cr.refines(order[3], order[4], cov)  # binder does not nest in mix
    # section identity goes below a section-level number too (station_ft: one value per section)
    assert [
        c.variable for c in cr.order_by_refinement([cause("section"), cause("station_ft", dtype="numeric")], cov)
    ] == ["station_ft", "section"]
    # an insignificant coarser grouping moves nothing
    assert [c.variable for c in cr.order_by_refinement([cause("comment"), cause("mix", sig=False)], cov)] == [
        "comment",
        "mix",
    ]


def test_leverage_correction_restores_the_error_covariance_of_each_section():
    """Analytic: residuals of a fit on N have covariance (I - H) for unit errors; after the correction
    ``(I - H_gg)^(-1/2)`` per section, the covariance of each section's block is the identity (eigenvalues above the
    floor), and residuals of a fit on the intercept alone come back unchanged when the whole campaign is one block."""
    rng = np.random.default_rng(11)
    n = 36
    sec = np.repeat(np.arange(12), 3)
    N = np.c_[np.ones(n), rng.normal(size=(12, 6))[sec] + 0.1 * rng.normal(size=(n, 6))]
    R = np.eye(n) - N @ np.linalg.pinv(N)  # residuals of the unit vectors: covariance R R' = I - H
    T = leverage_corrected(R, N, sec, floor=1e-9)
    C = T @ T.T
    for g in range(12):
        idx = np.flatnonzero(sec == g)
        assert np.allclose(C[np.ix_(idx, idx)], np.eye(3), atol=1e-8)
    # before the correction the blocks are shrunk by the leverage (trace below 3)
    assert max(np.trace(R[np.ix_(idx, idx)]) for g in range(12) for idx in [np.flatnonzero(sec == g)]) < 2.9
    one = np.ones((n, 1))
    y = rng.normal(size=(n, 2))
    r1 = residualise(y, one)
    assert np.allclose(leverage_corrected(r1, one, np.zeros(n)), r1)


def _null_rejection_rate(correct: bool, n_null: int = 300, P: int = 199) -> float:
    """Share of covariates without effect that a texture-adjusted between-site test rejects at 0.05 on a
    12-section campaign: section effects in the measured means, 8 nuisance columns that vary mainly between
    sections, the covariate a section value plus a small site scatter (like a temperature logged per site)."""
    rng = np.random.default_rng(12)
    n, n_sec = 36, 12
    sec = np.repeat(np.arange(n_sec), 3)
    N = np.c_[np.ones(n), rng.normal(size=(n_sec, 8))[sec] + 0.2 * rng.normal(size=(n, 8))]
    perms = nested_permutations(sec, P, rng)
    rej = 0
    for _ in range(n_null):
        y = (rng.normal(0, 0.02, n_sec)[sec] + rng.normal(0, 0.01, n))[:, None]
        z = rng.uniform(8, 28, n_sec)[sec] + rng.normal(0, 0.5, n)
        Q = adjusted_basis(basis(pd.Series(z), "numeric"), N)
        Y = residualise(y, N)
        Yp = leverage_corrected(Y, N, sec) if correct else Y
        T = float(((Q.T @ Y) ** 2).sum())
        Tp = perm_stats(Yp, Q, np.zeros(Q.shape[1], int), 1, perms)[:, 0]
        rej += permutation_p(T, Tp) <= 0.05
    return rej / n_null


def test_texture_adjusted_permutation_holds_its_level_with_the_leverage_correction():
    """Freedman-Lane residuals of a fit on 9 section-structured columns are shrunk by their leverage, so their
    permutations understate the statistic's spread: the plain test rejects far above 5 % of null covariates; with
    the per-section leverage correction it holds its level (binomial sd of the rate at 300 draws: 1.3 %)."""
    plain = _null_rejection_rate(False)
    corrected = _null_rejection_rate(True)
    assert plain > 0.12
    assert 0.01 <= corrected <= 0.085


def test_texture_family_takes_its_share_of_fdr_from_the_secondary():
    """``texture_share`` > 0 moves every texture cluster (and lone texture column) out of the secondary family into
    a family ``texture`` of its own: each family's unit p-values are stepped up by BH (statsmodels, an independent
    implementation) and divided by the family's share, 0.3 for the texture family and 0.5 - 0.3 for the sites.csv
    columns; the primary family is untouched; shares that leave no secondary family are a ConfigError."""
    from statsmodels.stats.multitest import multipletests

    from skidsim.errors import ConfigError

    with pytest.raises(ConfigError, match="texture_share"):
        DiagnosisOptions(primary_share=0.5, texture_share=0.5)
    tables, _ = make_campaign(seed=0, effect=None)
    res = cr.build_residuals(tables["sites"], tables["measured"], tables["simulated"], tables["predicted"])
    cov, info = cr.site_covariates(tables["sites"], tables["texture"])
    texture_cols = {c for c in cov.columns if info[c][0] == "texture" and info[c][1] == "numeric"}

    def screen(share):
        opts = DiagnosisOptions(seed=0, n_permutations=999, texture_share=share)
        with warnings.catch_warnings():  # 999 permutations: too few for a significant cause, enough for the p's
            warnings.simplefilter("ignore", RuntimeWarning)
            return cr.screen_candidates(res, tables["sites"], tables["texture"], opts)

    base, split = screen(0.0), screen(0.3)
    fam = {c.family for c in split if c.variable in texture_cols and c.source == "texture"}
    assert fam == {"texture", "primary"}  # the MPD column x speed stays a physical (primary) hypothesis
    assert {c.variable for c in split if c.variable in texture_cols and c.family == "primary"} == {"mpd_mm"}
    assert {c.family for c in base if c.variable in texture_cols and c.source == "texture"} == {"secondary", "primary"}
    assert {c.family for c in split if c.source == "sites" and c.variable != "temperature_c"} == {"secondary"}
    share = {"texture": 0.3, "secondary": 0.2, "primary": 0.5}
    for family, s in share.items():
        units = {}
        for c in split:
            if c.family == family and c.source != "texture_model":
                units.setdefault((c.unit, c.level, c.kind), []).append(c)
        keys = sorted(units)
        unit_p = np.array([units[k][0].unit_p for k in keys])
        bh = np.minimum(multipletests(unit_p, method="fdr_bh")[1] / s, 1.0)
        if family == "primary":  # the texture model's members are one more primary unit
            tm = [c for c in split if c.source == "texture_model"]
            unit_p = np.r_[unit_p, tm[0].unit_p]
            bh = np.minimum(multipletests(unit_p, method="fdr_bh")[1] / s, 1.0)[:-1]
        for k, expected in zip(keys, bh):
            got = min(c.p_adjusted for c in units[k])  # the unit's top member carries the unit's adjusted p
            if family == "secondary" and any(c.section_level for c in units[k]):
                assert got <= expected + 1e-12  # the gatekeeper may lower a section-level column's
            else:
                assert got == pytest.approx(expected, rel=1e-12), k
