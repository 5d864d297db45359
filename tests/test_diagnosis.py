"""Tests of skidsim.diagnosis: residual tables, permutation/FDR machinery, hidden-effect campaigns, outputs.

The campaigns come from tests/diagnosis_campaigns.py; the analysis receives only the campaign-level tables
(sites, measured, simulated, predicted, texture); the truth returned beside them is used only to assert.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from diagnosis_campaigns import make_campaign, read_campaign, write_campaign  # noqa: E402

from skidsim import diagnosis as dg  # noqa: E402
from skidsim.errors import InputError  # noqa: E402


# ---------------------------------------------------------------------------------------------------------------
# residual table
# ---------------------------------------------------------------------------------------------------------------

def _tiny():
    sites = pd.DataFrame({"site": ["a", "b"], "section": ["S1", "S1"], "temperature_c": [10.0, 20.0]})
    measured = pd.DataFrame({"site": ["a", "a", "a", "b", "b"], "speed_kmh": [20.0, 25.0, 95.0, 20.0, 40.0],
                             "mu": [0.60, 0.55, 0.30, 0.50, 0.45],
                             "kind": ["calibration", "trace", "trace", "calibration", "validation"]})
    simulated = pd.DataFrame({"site": ["a", "a", "b", "b"], "speed_kmh": [20.0, 40.0, 20.0, 40.0],
                              "sn": [0.58, 0.48, 0.50, 0.40]})
    predicted = pd.DataFrame({"site": ["b", "b"], "speed_kmh": [20.0, 60.0], "sn_pred": [0.52, 0.40]})
    return sites, measured, simulated, predicted


def test_build_residuals_interpolates_and_drops_out_of_range():
    sites, measured, simulated, predicted = _tiny()
    r = dg.build_residuals(sites, measured, simulated, predicted)
    w = r[r["level"] == "within-site"].set_index(["site", "speed_kmh"])
    assert len(w) == 4  # a@95 km/h lies outside the simulated 20-40 km/h: dropped, not extrapolated
    assert w.loc[("a", 25.0), "model"] == pytest.approx(0.58 - 0.10 * 5 / 20)
    assert w.loc[("a", 25.0), "residual"] == pytest.approx(0.55 - 0.555)
    assert w.loc[("b", 40.0), "residual"] == pytest.approx(0.05)
    b = r[r["level"] == "between-site"].set_index(["site", "speed_kmh"])
    assert set(b.index.get_level_values("site")) == {"b"}
    assert b.loc[("b", 40.0), "model"] == pytest.approx(0.46)
    assert (r["section"] == "S1").all()


def test_texture_model_shape_is_sim_minus_pred():
    """The between-site functional form's profile: between residual - within residual = sn_sim - sn_pred."""
    sites, measured, simulated, predicted = _tiny()
    r = dg.build_residuals(sites, measured, simulated, predicted)
    d = dg._texture_model_shape(r, 10.0)
    assert list(d.index) == ["b"] and list(d.columns) == [20.0, 40.0]
    assert d.loc["b", 20.0] == pytest.approx(0.50 - 0.52)
    assert d.loc["b", 40.0] == pytest.approx(0.40 - 0.46)
    # a between-site point without a within-site residual: None (the test falls back to the between residual)
    drop = (r["level"] == "within-site") & (r["site"] == "b") & (r["speed_kmh"] == 40.0)
    assert dg._texture_model_shape(r[~drop], 10.0) is None


@pytest.mark.parametrize("mutate, column", [
    (lambda m: m.assign(kind=["calibration", "bogus", "trace", "calibration", "validation"]), "kind"),
    (lambda m: m.drop(columns="mu"), "mu"),
    (lambda m: m.assign(speed_kmh=["20", "x", "95", "20", "40"]), "speed_kmh"),
])
def test_build_residuals_bad_input_names_the_field(mutate, column):
    sites, measured, simulated, predicted = _tiny()
    with pytest.raises(InputError) as e:
        dg.build_residuals(sites, mutate(measured), simulated, predicted)
    assert e.value.column == column
    assert "measured table" in str(e.value)


def test_build_residuals_unknown_site():
    sites, measured, simulated, predicted = _tiny()
    with pytest.raises(InputError, match="sites listed in the sites table"):
        dg.build_residuals(sites.iloc[:1], measured, simulated, predicted)


# ---------------------------------------------------------------------------------------------------------------
# machinery
# ---------------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method, sm", [("bh", "fdr_bh"), ("by", "fdr_by")])
def test_adjust_pvalues_matches_statsmodels(method, sm):
    from statsmodels.stats.multitest import multipletests
    p = np.random.default_rng(0).uniform(0, 0.2, 40) ** 2
    assert dg.adjust_pvalues(p, method) == pytest.approx(multipletests(p, method=sm)[1], rel=1e-12)


def test_nested_permutations_keep_sections_whole():
    sec = np.repeat(np.array(["A", "B", "C", "D", "E"]), [3, 3, 3, 2, 2])
    perms = dg._nested_permutations(sec, 200, np.random.default_rng(1))
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
    Q = np.concatenate([dg._basis(pd.Series(x1), "numeric"), dg._basis(lab, "categorical")], axis=1)
    owner = np.array([0, 1, 1])
    perms = rng.permuted(np.tile(np.arange(n), (5, 1)), axis=1)
    T = dg._perm_stats(Y, Q, owner, 2, perms)
    for k, p in enumerate(perms):
        Yp = Y[p] - Y[p].mean(axis=0)
        xc = x1 - x1.mean()
        assert T[k, 0] == pytest.approx(((xc @ Yp) ** 2).sum() / (xc @ xc))
        # categorical: between-group sum of squares
        ss = sum(((Yp[lab == g].sum(axis=0)) ** 2).sum() / (lab == g).sum() for g in "abc")
        assert T[k, 1] == pytest.approx(ss)


def test_measure_gain_matches_direct_formulas():
    rng = np.random.default_rng(4)
    rows = []
    for i in range(10):
        for v in (20.0, 40.0, 60.0):
            y = 0.5 + 0.02 * rng.normal()
            rows.append((f"s{i}", v, y, y + 0.03 * rng.normal(), y + 0.01 * rng.normal()))
    p = pd.DataFrame(rows, columns=["site", "speed_kmh", "measured", "before", "after"])
    g = dg.measure_gain(p, n_boot=300, seed=1)
    eb = p["measured"] - p["before"]
    ea = p["measured"] - p["after"]
    assert g["rmse_before"] == pytest.approx(np.sqrt(np.mean(eb ** 2)))
    assert g["rmse_after"] == pytest.approx(np.sqrt(np.mean(ea ** 2)))
    from sklearn.metrics import r2_score
    assert g["r2_after"] == pytest.approx(r2_score(p["measured"], p["after"]))
    shape = eb - eb.groupby(p["site"]).transform("mean")
    assert g["shape_rmse_before"] == pytest.approx(np.sqrt(np.mean(shape ** 2)))
    lo, hi = g["rmse_gain_ci"]
    assert lo <= g["rmse_gain"] <= hi and lo > 0 and g["gain_excludes_zero"]
    same = dg.measure_gain(p.assign(after=p["before"]), n_boot=100, seed=1)
    assert same["rmse_gain"] == 0 and same["rmse_gain_ci"] == [0.0, 0.0] and not same["gain_excludes_zero"]
    assert g == dg.measure_gain(p, n_boot=300, seed=1)  # deterministic for a seed


# ---------------------------------------------------------------------------------------------------------------
# hidden effects: the analysis sees only the campaign tables
# ---------------------------------------------------------------------------------------------------------------

def _diagnose(tables, **kw):
    t = tables
    return dg.diagnose(t["sites"], t["measured"], t["simulated"], t["predicted"], t["texture"], **kw)


def _campaign_dir(tmp_path, seed, effect, **kw):
    """Write the campaign to disk and return the tables derived from that directory alone, and the truth."""
    d = tmp_path / f"campaign_{effect}_{seed}"
    truth = write_campaign(d, seed=seed, effect=effect, **kw)
    # what a user provides (sites.csv, DFT traces) and the derived texture table; no truth on disk
    files = sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file())
    assert files[-2:] == ["sites.csv", "texture.csv"] and all(f.startswith("dft/") for f in files[:-2])
    assert not any("truth" in f for f in files)
    return read_campaign(d), truth


def test_campaign_directory_round_trip(tmp_path):
    """The directory path reproduces the raw campaign: sites.csv columns and DFT points at the test speeds."""
    from diagnosis_campaigns import generate_campaign
    tables, _ = _campaign_dir(tmp_path, 3, "wear")
    sites, measured, tex, _ = generate_campaign(3, "wear")
    assert list(tables["sites"].columns[:5]) == ["site", "section", "scan", "dft", "temperature_c"]
    assert tables["sites"]["test_order"].tolist() == sites["test_order"].tolist()
    cal = tables["measured"].query("kind == 'calibration'").set_index(["site", "speed_kmh"])["mu"]
    # the file holds the mean of the calibration and trace samples at 20/40/60 km/h
    exp = measured[measured["speed_kmh"].isin([20.0, 40.0, 60.0])].groupby(["site", "speed_kmh"])["mu"].mean()
    assert np.allclose(cal.sort_index().to_numpy(), exp.sort_index().to_numpy(), atol=1e-9)
    assert np.allclose(tables["texture"]["mpd_mm"], tex["mpd_mm"])


def test_texture_adjustment_picks_the_texture_dimension():
    """M linear in the first two texture PCs (plus small noise): leave-one-section-out CV picks k = 2, and the
    nuisance design spans the intercept and exactly those scores."""
    rng = np.random.default_rng(5)
    n = 36
    sec = np.repeat([f"S{k}" for k in range(12)], 3)
    scores = rng.normal(size=(n, 8)) * np.linspace(3, 0.5, 8)
    M = 0.5 + 0.04 * scores[:, [0]] - 0.03 * scores[:, [1]] + rng.normal(0, 0.002, size=(n, 5))
    k, N, k_cv = dg.texture_adjustment(M, scores, sec, variance_share=0.5)
    assert k == k_cv == 2
    assert np.allclose(N, np.c_[np.ones(n), scores[:, :2]])
    # pure noise: nothing to adjust for beyond the mean (k small), never more than the cap
    k0, _, k0_cv = dg.texture_adjustment(rng.normal(size=(n, 5)), scores, sec, variance_share=0.5)
    assert k0_cv <= 1 and dg.texture_adjustment(M, scores, sec, k_max=1)[0] == 1
    # the texture-variance floor: 90 % of this texture's variance needs more than 2 PCs, so the test conditions
    # on them although CV would stop at 2; never beyond the cap
    var = scores.var(axis=0)
    k90 = int(np.searchsorted(np.cumsum(var) / var.sum(), 0.9) + 1)
    assert dg.texture_adjustment(M[:6], scores[:6], sec[:6])[0] == 0  # 2 sections: no PC can be held out
    k_t, N_t, k_cv = dg.texture_adjustment(M, scores, sec)
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
    Q = dg._adjusted_basis(dg._basis(pd.Series(z), "numeric"), N)
    T = float(((Q.T @ dg._residualise(y[:, None], N)) ** 2).sum())

    def sse(X):
        return float(((y - X @ np.linalg.lstsq(X, y, rcond=None)[0]) ** 2).sum())

    assert T == pytest.approx(sse(N) - sse(np.c_[N, z]), rel=1e-10)
    assert dg._adjusted_basis(dg._basis(pd.Series(S[:, 1] * 2 + 1), "numeric"), N).shape[1] == 0


def _within_rows(amp, rng, speeds=np.arange(20.0, 71.0, 5.0), noise=0.002):
    """Within-site residual rows: site i's residual is amp_i * shape(v) plus white noise (mu)."""
    shape = 0.01 * (1.0 - ((speeds - 45.0) / 25.0) ** 2) - 0.01 * (speeds > 60) * (speeds - 60.0) / 10.0
    rows = [(f"s{i}", "trace", v, a * h + noise * rng.normal()) for i, a in enumerate(amp)
            for v, h in zip(speeds, shape)]
    r = pd.DataFrame(rows, columns=["site", "kind", "speed_kmh", "residual"])
    return r.assign(level="within-site", measured=0.5 + r["residual"], model=0.5)


def test_within_site_shape_amplitude_follows_inverse_speed_constant():
    """A residual shape shared by all sites whose amplitude follows the IFI 1/Sp(MPD) (drainage): MPD x speed is
    tested on the shape's amplitude (one degree of freedom), is significant, and ranks above the functional form
    (the shared shape is its mean); with amplitudes unrelated to MPD the functional form alone is named; the
    statistic equals the squared projection computed directly."""
    rng = np.random.default_rng(3)
    n = 36
    sites = pd.DataFrame({"site": [f"s{i}" for i in range(n)], "section": np.repeat([f"S{k}" for k in range(12)], 3),
                          "temperature_c": rng.uniform(10, 20, n)})
    mpd = rng.uniform(0.45, 1.45, n)
    tex = pd.DataFrame({"site": sites["site"], "profile_MPD": mpd, "other": rng.normal(size=n)})
    inv_sp = 1.0 / (14.2 + 89.7 * mpd)
    amp = inv_sp / inv_sp.mean()  # mean 1: the shared shape, modulated by drainage
    res = _within_rows(amp, rng)
    causes = dg.screen_candidates(res, sites, tex, seed=0)
    top = causes[0]
    assert (top.variable, top.level, top.kind, top.significant) == ("profile_MPD", "within-site", "x_speed", True)
    assert top.family == "primary" and top.direction == -1  # deeper texture, weaker shape error
    ff = next(c for c in causes if c.kind == "functional_form")
    assert ff.significant and causes.index(ff) == 1
    # the statistic: squared projection of the shapes' amplitudes (on the unit mean shape) on the centred 1/Sp
    ids, bins, R = dg._residual_matrix(res, 10.0)
    D = R - R.mean(axis=1, keepdims=True)
    f = D.mean(axis=0)
    a = (D - f) @ (f / np.linalg.norm(f))
    z = pd.Series(inv_sp, index=sites["site"]).loc[ids].to_numpy()
    z = (z - z.mean()) / np.linalg.norm(z - z.mean())
    assert top.statistic == pytest.approx(float(z @ a) ** 2, rel=1e-9)
    # amplitudes unrelated to MPD: the shared shape is the cause
    causes0 = dg.screen_candidates(_within_rows(rng.permutation(amp), np.random.default_rng(4)), sites, tex, seed=0)
    assert causes0[0].kind == "functional_form" and causes0[0].significant
    assert not next(c for c in causes0 if c.variable == "profile_MPD").significant


def test_texture_adjusted_test_recovers_an_effect_the_texture_model_absorbed():
    """Temperature correlates with texture; the texture model (fitted on curves that carry the temperature effect)
    absorbs most of it, so the residual test is weak. Conditioning on texture names temperature, and its
    texture-refit extension gains on held-out sites where the plain residual term cannot."""
    rng = np.random.default_rng(8)
    n, secs = 36, np.repeat([f"S{k:02d}" for k in range(12)], 3)
    tex = rng.normal(size=(n, 4))
    temp = 20 + 4 * tex[:, 0] + rng.normal(0, 3, n)
    level = 0.45 + 0.05 * tex[:, 0] + 0.03 * tex[:, 1] - 0.006 * (temp - 20)
    leak = np.polyfit(tex[:, 0], temp, 1)  # the texture model learns temperature through texture column 0
    pred_level = 0.45 + 0.05 * tex[:, 0] + 0.03 * tex[:, 1] - 0.006 * (np.polyval(leak, tex[:, 0]) - 20) \
        + rng.normal(0, 0.01, n)
    v = np.arange(20.0, 71.0, 10.0)
    shape = -0.002 * (v - 45)
    sites = pd.DataFrame({"site": [f"s{i}" for i in range(n)], "section": secs, "temperature_c": temp})
    wide = pd.DataFrame({"site": sites["site"], **{f"macro_P{j}": tex[:, j] for j in range(4)}})
    rows_m, rows_s, rows_p = [], [], []
    for i, s in enumerate(sites["site"]):
        mu = level[i] + shape + rng.normal(0, 0.004, len(v))
        rows_m += [dict(site=s, speed_kmh=vv, mu=m, kind="validation") for vv, m in zip(v, mu)]
        rows_s += [dict(site=s, speed_kmh=vv, sn=level[i] + sh) for vv, sh in zip(v, shape)]
        rows_p += [dict(site=s, speed_kmh=vv, sn_pred=pred_level[i] + sh) for vv, sh in zip(v, shape)]
    r = dg.diagnose(sites, pd.DataFrame(rows_m), pd.DataFrame(rows_s), pd.DataFrame(rows_p), wide, seed=1,
                    n_boot=300)
    top = r.named
    assert top is not None and top.variable == "temperature_c" and top.level == "between-site", r.causes[:3]
    assert top.kind == "main" and top.texture_pcs >= 1 and top.direction == -1
    own = r.gain["scopes"]["held_out_sites"]
    assert own["gain_excludes_zero"] and own["rmse_after"] < own["rmse_before"], own
    generic = own if r.gain["extension"] == "CovariateTerm" else \
        next(a["scopes"]["held_out_sites"] for a in r.gain["alternatives"] if a["extension"] == "CovariateTerm")
    assert generic["extension"]["settings"]["texture_pcs"] == top.texture_pcs_cv
    assert generic["gain_excludes_zero"] and generic["over_texture_refit"]["rmse_gain_ci"][0] > 0
    # the added-variable data recover the true partial effect, -0.006 mu per K (Frisch-Waugh slope)
    av = r.added_variable
    assert len(av) == n and np.polyfit(av["covariate_adj"], av["measured_adj"], 1)[0] == pytest.approx(-0.006,
                                                                                                      abs=0.0015)
    # two sections leave no texture PC to condition on: the residual test is kept
    few = sites["site"].iloc[:6]
    small = dg.screen_candidates(r.residuals[r.residuals["site"].isin(few)], sites.iloc[:6], wide.iloc[:6],
                                 seed=1)
    assert all(c.texture_pcs == -1 for c in small)
    plain = dg.screen_candidates(r.residuals, sites, wide, seed=1, adjust_texture=False)
    t_plain = next(c for c in plain if c.variable == "temperature_c" and c.kind == "main")
    assert t_plain.texture_pcs == -1 and t_plain.p_value > top.p_value


@pytest.mark.parametrize("effect", ["temperature", "drainage", "squeeze", "wear", "mix"])
def test_hidden_effect_is_named_and_extension_gains(tmp_path, effect):
    tables, truth = _campaign_dir(tmp_path, 0, effect)
    r = _diagnose(tables, seed=0, n_boot=400)
    top = r.named
    assert top is not None and top.significant and top is r.causes[0]
    hidden = truth["variable"]
    assert top.variable == hidden or hidden in top.group, (top, hidden)
    assert top.level == "between-site"
    # the extension's gain on held-out data (held-out sites for a between-site cause) excludes zero
    own = r.gain["scopes"][r.gain["scope"]]
    assert r.gain["scope"] == "held_out_sites"
    assert own["rmse_gain_ci"][0] > 0 and own["rmse_after"] < own["rmse_before"]
    assert own["r2_after"] > own["r2_before"]
    assert r.gain["gain_excludes_zero"]
    # and beyond a campaign-wide level offset of the texture model: the named variable itself carries the gain
    assert own["over_shared_level"]["rmse_gain_ci"][0] > 0
    # the physical extension is used where one exists
    expected = {"temperature": "TemperatureShift", "drainage": "DrainageIFI", "squeeze": "DrainageIFI"}.get(effect)
    if expected is not None:
        assert expected in [r.gain["extension"]] + [a["extension"] for a in r.gain["alternatives"]]
    if r.gain["extension"] == "DrainageIFI":  # form "auto": the chosen curve form per fold is recorded and reported
        folds = own["extension"]["params_per_fold"]
        assert all(f["form"] in ("ifi", "squeeze") and f["train_sse"] >= 0 for f in folds)
        report = Path(dg.write_outputs(tmp_path / "out", r.residuals, r.causes, r.gain)["report"]).read_text()
        assert "Drainage curve form chosen on the training data, per fold:" in report


def test_texture_clusters_and_families():
    """Correlated texture parameters form one cluster (every pair |Spearman rho| >= 0.8); the physical hypotheses
    (functional form, temperature between sites, MPD x speed) form the primary family."""
    tables, _ = make_campaign(seed=0, effect=None)
    cov, info = dg.site_covariates(tables["sites"], tables["texture"])
    cl = dg.texture_clusters(cov, info, 0.8)
    macro = next(c for c in cl if "mpd_mm" in c)
    assert {"mpd_mm", "macro_Sq_mm", "macro_Sa_mm", "macro_Sdr_pct"} <= set(macro)
    assert not any(c.startswith("micro") for c in macro)
    for c in cl:
        rho = cov[c].rank().corr().abs().to_numpy()
        assert rho.min() >= 0.8
    assert dg.find_mpd_column(cov, info) == "mpd_mm"
    assert dg.find_mpd_column(pd.DataFrame(columns=["profile_MPD_sd", "profile_MPD", "x"])) == "profile_MPD"
    res = dg.build_residuals(tables["sites"], tables["measured"], tables["simulated"], tables["predicted"])
    with pytest.warns(RuntimeWarning, match="can never be significant"):
        causes = dg.screen_candidates(res, tables["sites"], tables["texture"], seed=0, n_permutations=199)
    prim = {(c.variable, c.level, c.kind) for c in causes if c.family == "primary"}
    assert prim == {("functional_form", "within-site", "functional_form"),
                    ("functional_form", "between-site", "functional_form"),
                    ("temperature_c", "between-site", "main"), ("temperature_c", "between-site", "x_speed"),
                    ("mpd_mm", "within-site", "x_speed"), ("mpd_mm", "between-site", "x_speed")}
    # a cluster is one unit: its members share the unit, its max-statistic p-value, and p_adjusted >= unit_p
    mac = [c for c in causes if c.variable in macro and c.level == "between-site" and c.kind == "main"]
    rep = max(mac, key=lambda c: c.statistic)
    assert {c.unit for c in mac} == {f"cluster:{rep.variable}"} and len(mac) == len(macro)
    assert len({c.unit_p for c in mac}) == 1 and rep.unit_p >= rep.p_value  # the max over members costs power
    assert all(c.p_adjusted >= c.unit_p for c in mac)


@pytest.mark.slow
def test_null_campaigns_name_nothing(tmp_path):
    """Null campaigns with DFT traces every 4 km/h (as real campaigns have): many dependent points per site."""
    named = []
    for seed in range(20):
        tables, _ = _campaign_dir(tmp_path, 100 + seed, None, trace_step_kmh=4.0)
        # per site the trace file holds 20-80 km/h every 4 km/h plus the validation samples at 30/50/70 km/h
        assert (tables["measured"]["kind"] == "trace").sum() == 36 * (16 + 3)
        res = dg.build_residuals(tables["sites"], tables["measured"], tables["simulated"], tables["predicted"])
        causes = dg.screen_candidates(res, tables["sites"], tables["texture"], seed=seed)
        # enough permutations for the smallest p-value to pass BH in the larger family at its share of fdr
        n_units = len({(c.family, c.unit, c.level, c.kind) for c in causes if c.family == "secondary"})
        assert causes[0].n_permutations + 1 >= 4 * n_units / (0.5 * 0.05)
        named.append(dg.named_cause(causes) is not None)
    assert sum(named) <= 1, named  # >= 95 % of null seeds name nothing


def test_write_outputs_and_figures(tmp_path):
    from skidsim.plotting.diagnosis import diagnosis_figures
    tables, _ = make_campaign(seed=0, effect="wear", trace_step_kmh=10.0)
    r = _diagnose(tables, seed=0, n_boot=200, n_permutations=2999)
    figs = diagnosis_figures(r, tmp_path)
    paths = dg.write_outputs(tmp_path, r.residuals, r.causes, r.gain, figs)
    res = pd.read_parquet(paths["residuals"])
    assert set(res["level"]) == {"within-site", "between-site"}
    assert np.allclose(res["residual"], res["measured"] - res["model"])
    causes = json.loads(Path(paths["causes"]).read_text())
    for key in ("variable", "level", "effect", "cv_gain", "p_value", "p_adjusted", "significant", "rank"):
        assert key in causes[0]
    assert [c["rank"] for c in causes] == list(range(1, len(causes) + 1))
    gain = json.loads(Path(paths["gain"]).read_text())
    for sc in gain["scopes"].values():
        for key in ("rmse_before", "rmse_after", "r2_before", "r2_after", "rmse_gain_ci", "r2_after_ci"):
            assert key in sc
    report = Path(paths["report"]).read_text()
    assert causes[0]["variable"] in report
    for p in figs.values():
        assert Path(p).stat().st_size > 1000 and f"]({Path(p).name})" in report
    assert not list(tmp_path.glob("*.tmp*"))


def test_a_grouping_that_refines_the_named_one_ranks_below_it(tmp_path):
    """Parsimony between section-level groupings: a free-text column that splits the mixes further (as the study's
    'comment' does) holds the evidence of mix; where both are significant, mix is named and the finer one follows.
    Without the refinement (the finer column no longer nests in mix) no such reordering applies."""
    tables, truth = _campaign_dir(tmp_path, 0, "mix")
    sites = tables["sites"].copy()
    hidden = truth["variable"]
    sec_rank = sites["section"].rank(method="dense").astype(int)
    sites["comment"] = sites[hidden].astype(str) + np.where(sec_rank % 2 == 0, " with RAP", " with RAP + RAS")
    r = _diagnose({**tables, "sites": sites}, seed=0, n_boot=50)
    sig = [c.variable for c in r.causes if c.significant and c.level == "between-site" and c.kind == "main"]
    assert "comment" in sig and hidden in sig, sig  # both carry the effect
    assert r.named.variable == hidden and sig.index(hidden) < sig.index("comment"), sig


def test_order_by_refinement_puts_the_coarser_grouping_first():
    """A finer grouping ranked first by cv (comment: mixes split by RAS) moves right below the coarser one it refines
    (mix); section identity also goes below mix; a column that does not nest in mix (binder cuts across it), a
    numeric column and a cause of another kind keep their places."""
    secs = [f"S{k}" for k in range(6)]
    cov = pd.DataFrame({"section": secs, "mix": ["HMA", "HMA", "WMA", "WMA", "WMA", "SMA"],
                        "comment": ["HMA+RAS", "HMA", "WMA+RAS", "WMA", "WMA", "SMA"],
                        "binder": ["A", "B", "A", "B", "A", "B"], "station_ft": np.arange(6.0)},
                       index=[f"{s}-1" for s in secs])

    def cause(v, kind="main", dtype="categorical", sig=True):
        return dg.Cause(variable=v, level="between-site", kind=kind, effect=0.01, cv_gain=0.5, p_value=0.01,
                        p_adjusted=0.02, significant=sig, dtype=dtype, section_level=True)

    order = [cause("comment"), cause("section"), cause("station_ft", dtype="numeric"), cause("binder"),
             cause("mix"), cause("comment", kind="x_speed")]
    out = [(c.variable, c.kind) for c in dg.order_by_refinement(order, cov)]
    assert out == [("station_ft", "main"), ("binder", "main"), ("mix", "main"), ("comment", "main"),
                   ("section", "main"), ("comment", "x_speed")], out
    assert dg.refines(order[0], order[4], cov) and not dg.refines(order[4], order[0], cov)
    assert not dg.refines(order[3], order[4], cov)  # binder does not nest in mix
    # section identity goes below a section-level number too (station_ft: one value per section)
    assert [c.variable for c in dg.order_by_refinement([cause("section"), cause("station_ft", dtype="numeric")],
                                                       cov)] == ["station_ft", "section"]
    # an insignificant coarser grouping moves nothing
    assert [c.variable for c in dg.order_by_refinement([cause("comment"), cause("mix", sig=False)], cov)] == \
        ["comment", "mix"]
