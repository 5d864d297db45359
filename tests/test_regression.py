"""Tests of skidsim.regression (PCA regression, Tables 5/6, CV comparison, Figure 11 tables) and its plots."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm

from skidsim import regression as R
from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay

NAMES = ["Sq", "Ssk", "Sku", "Sp", "Sv", "Sz", "Sa", "Sdr", "Sal", "Str"]


def latent_campaign(n_sections=12, per=3, k=3, p_per_band=6, noise_x=0.0, seed=0):
    """Feature table driven by ``k`` latent factors (rank k if noise_x == 0): columns of three bands plus MPD,
    each scaled and offset differently (original units differ). Returns X (index site), F (n, k), groups."""
    rng = np.random.default_rng(seed)
    n = n_sections * per
    F = rng.normal(size=(n, k))
    cols = {}
    for band in ("raw", "macro", "micro"):
        W = rng.normal(size=(k, p_per_band))
        A = F @ W + noise_x * rng.normal(size=(n, p_per_band))
        for j in range(p_per_band):
            cols[f"{band}_{NAMES[j]}"] = A[:, j] * rng.uniform(0.1, 3.0) + rng.uniform(-1.0, 5.0)
    cols["profile_MPD"] = 0.3 * (F @ rng.normal(size=k) + noise_x * rng.normal(size=n)) + 1.0
    idx = pd.Index([f"S{i:02d}" for i in range(n)], name="site")
    groups = pd.Series(np.repeat([f"E{i:02d}" for i in range(n_sections)], per), index=idx, name="section")
    return pd.DataFrame(cols, index=idx), F, groups


def independent_campaign(n_sections=12, per=3, p=30, seed=1):
    """Independent standard-normal feature columns (no latent structure), incl. profile_MPD and micro_Sq."""
    rng = np.random.default_rng(seed)
    n = n_sections * per
    names = ["profile_MPD", "micro_Sq"] + [f"macro_P{j:02d}" for j in range(p - 2)]
    idx = pd.Index([f"S{i:02d}" for i in range(n)], name="site")
    X = pd.DataFrame(rng.normal(size=(n, p)), columns=names, index=idx)
    groups = pd.Series(np.repeat([f"E{i:02d}" for i in range(n_sections)], per), index=idx, name="section")
    return X, groups, rng


# ----------------------------------------------------------------------------------------------- PCA regression


def test_all_components_table6_equals_plain_ols_with_same_standard_errors():
    rng = np.random.default_rng(3)
    n, p = 30, 7
    X = pd.DataFrame(
        rng.normal(size=(n, p)) @ rng.normal(size=(p, p)) + rng.uniform(0, 5, p),
        columns=[f"macro_{c}" for c in NAMES[:p]],
    )
    X["temperature_c"] = 15 + 3 * rng.normal(size=n)
    y = pd.Series(0.4 + X.to_numpy() @ rng.normal(scale=0.01, size=p + 1) + 0.02 * rng.normal(size=n), name="mu_s")
    fit = R.fit_pca_regression(X, y, n_components=p + 1)
    ref = sm.OLS(y.to_numpy(), sm.add_constant(X.to_numpy())).fit()  # OLS in the original units
    t6 = fit.table6()
    np.testing.assert_allclose(t6["coefficient"].to_numpy(), ref.params, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(t6["std_error"].to_numpy(), ref.bse, rtol=1e-7)
    np.testing.assert_allclose(t6["p_value"].to_numpy(), ref.pvalues, rtol=1e-6, atol=1e-300)
    np.testing.assert_allclose(fit.predict(X).to_numpy(), ref.fittedvalues, atol=1e-12)
    assert fit.statistics()["r2"] == pytest.approx(ref.rsquared, rel=1e-10)
    assert list(t6["band"]) == ["intercept"] + ["macro"] * p + ["temperature"]


def test_recovers_generating_map_in_the_kept_span():
    X, F, groups = latent_campaign(k=3, noise_x=0.0, seed=5)  # rank 3, 19 columns of different units
    rng = np.random.default_rng(6)
    beta = rng.normal(scale=0.02, size=X.shape[1])  # generating map in original units
    y = pd.Series(0.35 + X.to_numpy() @ beta, index=X.index, name="mu_k")
    for rule in ("kaiser", "cv", "variance:0.999"):
        fit = R.fit_pca_regression(X, y, rule=rule, groups=groups)
        assert fit.n_components == 3, rule
        sd = X.std(ddof=1).to_numpy()
        # independent PCA: eigenvectors of the correlation matrix
        w, v = np.linalg.eigh(np.corrcoef(X.to_numpy().T))
        V = v[:, np.argsort(w)[::-1][:3]]
        expect_per_sd = V @ V.T @ (beta * sd)  # the generating map projected onto the kept span
        np.testing.assert_allclose(fit.coefficients_per_sd.to_numpy(), expect_per_sd, atol=1e-10)
        c = fit.coefficients
        mean = X.mean().to_numpy()
        assert c["Intercept"] + mean @ c.to_numpy()[1:] == pytest.approx(0.35 + mean @ beta, abs=1e-12)
    # new sites from the same latent structure are predicted exactly
    rng2 = np.random.default_rng(99)
    Fn = rng2.normal(size=(12, 3))
    A = X.to_numpy()
    coef, *_ = np.linalg.lstsq(np.c_[np.ones(len(A)), F], A, rcond=None)  # columns are affine in the latent F
    Xnew = pd.DataFrame(np.c_[np.ones(12), Fn] @ coef, columns=X.columns)
    np.testing.assert_allclose(fit.predict(Xnew).to_numpy(), 0.35 + Xnew.to_numpy() @ beta, atol=1e-10)


def test_recovers_generating_map_with_noise_at_large_n():
    # noisy texture and noisy friction: the estimate converges to the generating map projected onto the span
    X, F, groups = latent_campaign(n_sections=100, per=3, k=3, noise_x=0.05, seed=17)
    rng = np.random.default_rng(18)
    beta = rng.normal(scale=0.02, size=X.shape[1])
    y = pd.Series(0.35 + X.to_numpy() @ beta + 0.002 * rng.normal(size=len(X)), index=X.index, name="mu_s")
    fit = R.fit_pca_regression(X, y, rule="kaiser")
    assert fit.n_components == 3
    w, v = np.linalg.eigh(np.corrcoef(X.to_numpy().T))
    V = v[:, np.argsort(w)[::-1][:3]]
    expect = V @ V.T @ (beta * X.std(ddof=1).to_numpy())
    err = fit.coefficients_per_sd.to_numpy() - expect
    assert np.max(np.abs(err)) < 0.01 * np.max(np.abs(expect)), np.abs(err).max()


def test_table5_matches_statsmodels_on_independent_pca():
    from sklearn.decomposition import PCA
    from sklearn.preprocessing import StandardScaler

    X, F, groups = latent_campaign(k=4, noise_x=0.3, seed=2, n_sections=9)
    rng = np.random.default_rng(7)
    y = pd.Series(0.45 + 0.04 * F[:, 0] - 0.02 * F[:, 2] + 0.01 * rng.normal(size=len(X)), index=X.index, name="mu_s")
    fit = R.fit_pca_regression(X, y, n_components=5)
    T = PCA(n_components=5).fit_transform(StandardScaler().fit_transform(X.to_numpy()))
    ref = sm.OLS(y.to_numpy(), sm.add_constant(T)).fit()
    t5 = fit.table5()
    np.testing.assert_allclose(t5["p_value"].to_numpy(), ref.pvalues, rtol=1e-6, atol=1e-300)
    scale = np.sqrt(len(X) / (len(X) - 1))  # sklearn standardises with ddof=0, skidsim with ddof=1
    np.testing.assert_allclose(np.abs(t5["coefficient"].to_numpy()[1:]), np.abs(ref.params[1:]) * scale, rtol=1e-7)
    st = fit.statistics()
    assert st["r2"] == pytest.approx(ref.rsquared, rel=1e-9)
    assert st["adj_r2"] == pytest.approx(ref.rsquared_adj, rel=1e-9)
    assert st["rse"] == pytest.approx(np.sqrt(ref.scale), rel=1e-9)
    assert list(t5["stars"]) == [R.significance_stars(p) for p in ref.pvalues]
    assert [R.significance_stars(p) for p in (0.0009, 0.009, 0.049, 0.05)] == ["***", "**", "*", ""]
    ev = np.linalg.eigvalsh(np.corrcoef(X.to_numpy().T))[::-1]
    np.testing.assert_allclose(t5["explained_variance"].to_numpy()[1:], ev[:5] / ev.sum(), rtol=1e-8)


def test_retention_rules_against_their_definitions():
    X, F, groups = latent_campaign(k=4, noise_x=0.4, seed=8, n_sections=9)
    rng = np.random.default_rng(9)
    y = pd.Series(0.45 + 0.03 * F @ rng.normal(size=4) + 0.01 * rng.normal(size=len(X)), index=X.index, name="mu_s")
    ev = np.linalg.eigvalsh(np.corrcoef(X.to_numpy().T))[::-1]
    assert R.fit_pca_regression(X, y, rule="kaiser").n_components == int(np.sum(ev > 1))
    cum = np.cumsum(ev) / ev.sum()
    assert R.fit_pca_regression(X, y, rule="variance:0.9").n_components == int(np.argmax(cum >= 0.9) + 1)
    study = R.fit_pca_regression(X, y, rule="study")
    k = study.n_components
    assert k >= 1 and np.all(study.table5()["p_value"].to_numpy()[1:] < 0.05)
    for kk in range(k + 1, min(X.shape[1], len(X) - 3) + 1):  # every larger model: a non-significant component
        assert np.any(R.fit_pca_regression(X, y, n_components=kk).table5()["p_value"].to_numpy()[1:] >= 0.05)
    with pytest.raises(InputError, match="retention rule"):
        R.fit_pca_regression(X, y, rule="elbow")


def test_standardiser_drops_constant_and_mostly_nan_columns_and_imputes():
    X, F, groups = latent_campaign(k=3, noise_x=0.2, seed=4, n_sections=8)
    X["micro_Spc"] = 2.5  # constant
    X["micro_Sal"] = X["micro_Sq"] * 2
    X.loc[X.index[:8], "micro_Sal"] = np.nan  # 8/24 = 33 % NaN -> dropped
    X.loc[X.index[:2], "macro_Sq"] = np.nan  # 2/24 -> imputed with the median
    y = pd.Series(0.3 + 0.02 * F[:, 0], index=X.index, name="mu_k")
    fit = R.fit_pca_regression(X, y, rule="kaiser")
    st = fit.standardiser
    assert set(st.dropped) == {"micro_Spc", "micro_Sal"}
    assert "constant" in st.dropped["micro_Spc"] and "NaN" in st.dropped["micro_Sal"]
    j = st.columns.index("macro_Sq")
    assert st.medians[j] == pytest.approx(np.nanmedian(X["macro_Sq"]))
    filled = X["macro_Sq"].fillna(np.nanmedian(X["macro_Sq"]))
    assert st.means[j] == pytest.approx(filled.mean()) and st.sds[j] == pytest.approx(filled.std(ddof=1))
    assert "micro_Spc" not in set(fit.table6()["variable"])
    assert np.all(np.isfinite(fit.predict(X)))


# ----------------------------------------------------------------------------------------------- splits


def test_split_sites_deterministic_random_and_grouped():
    sites = pd.DataFrame(
        {"site": [f"S{i:02d}" for i in range(36)], "section": np.repeat([f"C{i}" for i in range(12)], 3)}
    )
    tr, te = R.split_sites(sites, 27, seed=4)
    assert (tr, te) == R.split_sites(sites, 27, seed=4)
    assert len(tr) == 27 and len(te) == 9 and set(tr).isdisjoint(te) and set(tr) | set(te) == set(sites["site"])
    assert R.split_sites(sites, 27, seed=5) != (tr, te)
    # same split whatever the row order of the table
    assert R.split_sites(sites.iloc[::-1], 27, seed=4) == (tr, te)
    trg, teg = R.split_sites(sites, 27, seed=4, grouped_by="section")
    sec = dict(zip(sites["site"], sites["section"]))
    assert len(trg) == 27 and {sec[s] for s in trg}.isdisjoint({sec[s] for s in teg})
    assert len({sec[s] for s in teg}) == 3
    with pytest.raises(InputError, match="n_train"):
        R.split_sites(sites, 36)
    with pytest.raises(InputError) as e:
        R.split_sites(sites, 27, grouped_by="lane")
    assert e.value.column == "lane"


# ----------------------------------------------------------------------------------------------- models


def test_ridge_and_pls_paths_match_sklearn():
    from sklearn.cross_decomposition import PLSRegression
    from sklearn.linear_model import Ridge

    rng = np.random.default_rng(11)
    Z = rng.normal(size=(25, 12)) @ rng.normal(size=(12, 12))
    Z = (Z - Z.mean(0)) / Z.std(0, ddof=1)
    y = Z[:, 0] - 0.5 * Z[:, 3] + 0.3 * rng.normal(size=25)
    Zt = rng.normal(size=(6, 12))
    alphas = [0.1, 3.0, 100.0]
    P = R.ridge_path_predictions(Z, y, Zt, alphas)
    for j, a in enumerate(alphas):
        np.testing.assert_allclose(P[:, j], Ridge(alpha=a).fit(Z, y).predict(Zt), rtol=1e-9, atol=1e-12)
    P = R.pls_path_predictions(Z, y, Zt, [1, 2, 3, 4])
    for j, nc in enumerate([1, 2, 3, 4]):
        ref = PLSRegression(n_components=nc, scale=False).fit(Z, y).predict(Zt).ravel()
        np.testing.assert_allclose(P[:, j], ref, rtol=1e-7, atol=1e-10)


def test_cv_never_sees_the_held_out_section():
    X, groups, rng = independent_campaign(n_sections=6, p=10, seed=12)
    Y = pd.DataFrame(
        {"mu_s": 0.5 + 0.05 * X["micro_Sq"] + 0.01 * rng.normal(size=len(X)), "alpha": 0.4 + 0.05 * X["profile_MPD"]},
        index=X.index,
    )
    models = ("mean", "pca", "pca:study", "ridge", "lasso", "pls", "two_variable")
    base = R.cross_validated_predictions(X, Y, groups, models)
    held = groups == "E03"
    Y2 = Y.copy()
    Y2.loc[held, :] += 10.0  # wildly different friction in one section
    pert = R.cross_validated_predictions(X, Y2, groups, models, workers=2)  # processes: same numbers, same order
    in_held = base["section"] == "E03"
    cols = ["mu_s", "alpha"]
    np.testing.assert_array_equal(base.loc[in_held, cols].to_numpy(), pert.loc[in_held, cols].to_numpy())
    for m in models:  # every model's other-section predictions do react to that section's values
        other = (~in_held) & (base["model"] == m)
        assert np.all(np.abs(base.loc[other, cols].to_numpy() - pert.loc[other, cols].to_numpy()).max(0) > 1e-6), m
    # and a fold equals a fit on the other sections only
    direct = R.predict_parameters("ridge", X[~held], Y[~held], X[held], groups_train=groups[~held].to_numpy())
    row = (base["model"] == "ridge") & in_held
    np.testing.assert_allclose(base.loc[row, cols].to_numpy(), direct[cols].to_numpy(), rtol=1e-12)


def test_target_depending_only_on_section_has_no_out_of_section_skill():
    # texture identifies the section (section-level vectors + small site noise); friction is a section effect
    # unrelated to texture. Out of section there is nothing to learn; folds that mix sections leak the section.
    rng = np.random.default_rng(13)
    n_sec, per, p = 12, 3, 20
    sec = np.repeat(np.arange(n_sec), per)
    idx = pd.Index([f"S{i:02d}" for i in range(n_sec * per)], name="site")
    cols = ["profile_MPD", "micro_Sq"] + [f"macro_P{j:02d}" for j in range(p - 2)]
    X = pd.DataFrame(rng.normal(size=(n_sec, p))[sec] + 0.1 * rng.normal(size=(len(idx), p)), columns=cols, index=idx)
    groups = pd.Series([f"E{s:02d}" for s in sec], index=idx)
    Y = pd.DataFrame({"mu_s": 0.5 + 0.05 * rng.normal(size=n_sec)[sec] + 0.002 * rng.normal(size=len(idx))}, index=idx)
    models = ("pca", "ridge", "lasso")
    cv = R.cross_validate_models(X, Y, groups, models=models)
    assert len(cv) == 3 and np.all(cv["r2"] < 0.15), cv
    mixed = pd.Series([f"F{i % n_sec:02d}" for i in range(len(idx))], index=idx)  # each fold: 3 sections
    leaky = R.cross_validate_models(X, Y, mixed, models=models)
    assert np.all(leaky["r2"] > 0.8), leaky  # the same models do find the section when it leaks


def test_sparse_truth_lasso_wins_and_two_variable_truth_is_competitive():
    X, groups, rng = independent_campaign(n_sections=12, p=30, seed=14)
    Y = pd.DataFrame(
        {"mu_s": 0.5 + 0.05 * X["macro_P03"] - 0.04 * X["macro_P17"] + 0.005 * rng.normal(size=36)}, index=X.index
    )
    cv = R.cross_validate_models(X, Y, groups, models=("pca", "ridge", "lasso", "two_variable"))
    assert R.best_model(cv) == "lasso", cv
    rank = R.rank_models(cv)
    assert rank.attrs["criterion"] == "param_r2" and rank["gap"].iloc[1] > 0
    # a two-variable truth on correlated texture (latent structure)
    Xl, F, g = latent_campaign(k=3, noise_x=0.3, seed=15)
    rng = np.random.default_rng(16)
    Yl = pd.DataFrame(
        {"mu_k": 0.3 + 0.05 * Xl["profile_MPD"] + 0.02 * Xl["micro_Sq"] + 0.002 * rng.normal(size=len(Xl))},
        index=Xl.index,
    )
    cvl = R.cross_validate_models(Xl, Yl, g, models=("pca", "ridge", "two_variable"))
    rk = R.rank_models(cvl).set_index("model")
    assert rk.loc["two_variable", "score"] <= 1.1 * rk["score"].min() + 1e-3, rk
    assert cvl.set_index("model").loc["two_variable", "r2"] > 0.9


# ----------------------------------------------------------------------------------------------- DFT tables


def test_predict_dft_uses_the_law_g_and_clipping():
    params = pd.DataFrame(
        {"mu_s": [0.6, 0.5], "mu_k": [0.4, 0.3], "alpha": [0.2, -0.1]}, index=pd.Index(["A", "B"], name="site")
    )
    d = R.predict_dft(params)
    a = d[d["site"] == "A"]
    np.testing.assert_allclose(a["mu"], ExponentialDecay(0.6, 0.4, 0.2).mu_kmh(np.array(R.DEFAULT_SPEEDS_KMH)))
    np.testing.assert_allclose(d.loc[d["site"] == "B", "mu"], 0.5)  # alpha clipped to 0: mu = mu_s
    g = pd.DataFrame(
        {
            "site": ["A"] * 6 + ["B"] * 6,
            "speed_kmh": list(R.DEFAULT_SPEEDS_KMH) * 2,
            "g": np.r_[np.full(6, 1.2), np.full(6, 0.8)],
        }
    )
    d2 = R.predict_dft(params, g)
    np.testing.assert_allclose(d2["mu"], d["mu"] * d2["g"])
    np.testing.assert_allclose(d2.loc[d2["site"] == "B", "mu"], 0.4)
    with pytest.raises(InputError) as e:
        R.predict_dft(params, g.iloc[:-1])
    assert e.value.column == "g" and "70 km/h" in str(e.value)


def test_figure11_table_and_summary():
    pred = pd.DataFrame(
        {"site": ["A", "B", "A", "B"], "speed_kmh": [20.0, 20.0, 60.0, 60.0], "mu": [0.54, 0.60, 0.40, 0.30]}
    )
    meas = pd.DataFrame({"site": ["A", "B", "A", "B"], "speed_kmh": [20, 20, 60, 60], "mu": [0.5, 0.5, 0.4, 0.4]})
    t = R.figure11_table(pred, meas)
    np.testing.assert_allclose(t["relative_error"], [0.08, 0.2, 0.0, -0.25])
    assert list(t["within_10pct"]) == [True, False, True, False]
    s = R.figure11_summary(t)
    np.testing.assert_allclose(s["share_within_10pct"], [0.5, 0.5, 0.5])
    assert np.isnan(s["speed_kmh"].iloc[-1]) and s["n"].iloc[-1] == 4
    assert s["rmse"].iloc[0] == pytest.approx(np.sqrt((0.04**2 + 0.1**2) / 2))
    with pytest.raises(InputError) as e:
        R.figure11_table(pred, meas.iloc[:3])
    assert "site B at 60 km/h" in str(e.value)


def test_cv_dft_rows_against_hand_computation():
    X, groups, rng = independent_campaign(n_sections=4, p=5, seed=21)
    Y = pd.DataFrame(
        {"mu_s": rng.uniform(0.5, 0.7, 12), "mu_k": rng.uniform(0.3, 0.4, 12), "alpha": rng.uniform(0.1, 0.5, 12)},
        index=X.index,
    )
    cv = R.cross_validate_models(X, Y, groups, models=("mean",), speeds_kmh=(20.0, 60.0))
    # "mean" predicts the mean of the other three sections
    pred = pd.DataFrame({c: [Y.loc[groups != groups[s], c].mean() for s in X.index] for c in Y.columns}, index=X.index)
    v = 60.0 / 3.6  # m/s
    mu_p = pred["mu_k"] + (pred["mu_s"] - pred["mu_k"]) * np.exp(-pred["alpha"] * v)
    mu_m = Y["mu_k"] + (Y["mu_s"] - Y["mu_k"]) * np.exp(-Y["alpha"] * v)
    row = cv[(cv["quantity"] == "dft") & (cv["speed_kmh"] == 60.0)].iloc[0]
    assert row["rmse"] == pytest.approx(np.sqrt(np.mean((mu_p - mu_m) ** 2)), rel=1e-12)
    e = pred["mu_s"] - Y["mu_s"]
    r = cv[cv["quantity"] == "mu_s"].iloc[0]
    assert r["r2"] == pytest.approx(1 - np.sum(e**2) / np.sum((Y["mu_s"] - Y["mu_s"].mean()) ** 2), rel=1e-12)
    assert R.rank_models(cv).attrs["criterion"] == "dft_rmse"


# ----------------------------------------------------------------------------------------------- inputs


def test_assemble_design_and_input_errors():
    camp = pd.DataFrame(
        {
            "site": ["a", "b", "c"],
            "section": ["E1", "E1", "C1"],
            "operator": ["x", "y", "z"],
            "temperature_c": [15.0, 16.0, 14.0],
            "macro_Sq": [0.3, 0.4, 0.5],
            "profile_MPD": [1.0, np.nan, 1.2],
        }
    )
    fr = pd.DataFrame(
        {"site": ["c", "a", "b"], "mu_s": [0.5, 0.6, 0.7], "mu_k": [0.3, 0.3, 0.4], "alpha": [0.2, 0.3, 0.4]}
    )
    d = R.assemble_design(camp, fr)
    assert list(d.X.columns) == ["macro_Sq", "profile_MPD", "temperature_c"]
    assert list(d.Y.index) == ["a", "b", "c"] and d.Y.loc["c", "mu_s"] == 0.5
    assert d.groups.loc["c"] == "C1"
    with pytest.raises(InputError) as e:
        R.assemble_design(camp.drop(columns="section"), fr)
    assert e.value.column == "section"
    with pytest.raises(InputError) as e:
        R.assemble_design(camp, fr.drop(columns="alpha"), friction_file="friction.csv")
    assert e.value.column == "alpha" and "friction.csv" in str(e.value)
    bad = camp.copy()
    bad["macro_Sq"] = ["0.3", "oops", "0.5"]
    with pytest.raises(InputError) as e:
        R.assemble_design(bad, fr)
    assert e.value.column == "macro_Sq" and e.value.row == 1
    with pytest.raises(InputError) as e:
        R.assemble_design(pd.concat([camp, camp.iloc[:1]]), fr)
    assert e.value.column == "site"
    with pytest.raises(InputError) as e:
        R.assemble_design(camp, fr.iloc[:2])
    assert "every site of the campaign" in str(e.value)


# ----------------------------------------------------------------------------------------------- plots


def test_plots_write_pngs(tmp_path):
    from skidsim.plotting import regression as P

    X, F, groups = latent_campaign(k=3, noise_x=0.3, seed=31, n_sections=6)
    Y = pd.DataFrame(
        {"mu_s": 0.5 + 0.03 * F[:, 0], "mu_k": 0.35 + 0.02 * F[:, 1], "alpha": 0.4 + 0.05 * F[:, 2]}, index=X.index
    )
    fits = R.fit_pca_tables(X, Y, rule="kaiser")
    tr = X.index[:12]
    te = X.index[12:]
    pred = R.predict_parameters("pca", X.loc[tr], Y.loc[tr], X.loc[te])
    tab = R.figure11_table(R.predict_dft(pred), R.predict_dft(Y.loc[te]))
    cv = R.cross_validate_models(X, Y, groups, models=("mean", "two_variable"))
    for fn, arg, name in (
        (P.plot_figure11, tab, "f11.png"),
        (P.plot_cv_comparison, cv, "cv.png"),
        (P.plot_table6, R.table6(fits), "t6.png"),
    ):
        out = fn(arg, tmp_path / name)
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cv.png", "f11.png", "t6.png"]
    with pytest.raises(InputError):
        P.plot_figure11(tab.drop(columns="measured"), tmp_path / "x.png")


def test_run_analysis_and_write_analysis(tmp_path):
    X, F, groups = latent_campaign(k=3, noise_x=0.3, seed=41, n_sections=8)
    rng = np.random.default_rng(42)
    Y = pd.DataFrame(
        {
            "mu_s": 0.5 + 0.03 * F[:, 0] + 0.005 * rng.normal(size=24),
            "mu_k": 0.35 + 0.02 * F[:, 1] + 0.005 * rng.normal(size=24),
            "alpha": 0.4 + 0.05 * F[:, 2] + 0.01 * rng.normal(size=24),
        },
        index=X.index,
    )
    d = R.Design(X=X, Y=Y, groups=groups)
    opts = R.RegressionOptions(
        seed=3, grouped_by="section", models=("mean", "pca", "two_variable"), figure11_models=("best", "pca:study")
    )
    a = R.run_analysis(d, opts, n_train=18)
    assert len(a.train_ids) == 18 and set(a.test_ids) == set(X.index) - set(a.train_ids)
    assert set(a.table5["rule"]) == {"cv", "study"} and set(a.table6["target"]) == {"mu_s", "mu_k", "alpha"}
    assert a.best == a.ranking["model"].iloc[0] and a.best != "mean"
    assert set(a.test_parameters["model"]) == {a.best, "pca:study"}
    tp = a.test_parameters[a.test_parameters["model"] == a.best].set_index("site")
    direct = R.predict_parameters(
        a.best,
        X.loc[a.train_ids],
        Y.loc[a.train_ids],
        X.loc[a.test_ids],
        groups_train=groups.loc[a.train_ids].to_numpy(),
    )
    np.testing.assert_allclose(tp.loc[a.test_ids, ["mu_s", "mu_k", "alpha"]].to_numpy(), direct.to_numpy())
    paths = R.write_analysis(a, tmp_path / "reg")
    assert (tmp_path / "reg" / "best_model.txt").read_text().strip() == a.best
    back = pd.read_csv(paths["table6"])
    np.testing.assert_allclose(back["coefficient"], a.table6["coefficient"])
    written = {
        "split",
        "table5",
        "table5_statistics",
        "table6",
        "cv_predictions",
        "cv_table",
        "cv_ranking",
        "test_parameters",
        "prediction_skill",
    }
    assert set(paths) == written | {"best_model"}
    # atomic writes: only the final files, no temporary sibling left behind
    assert sorted(p.name for p in (tmp_path / "reg").iterdir()) == sorted(
        [f"{n}.csv" for n in written] + ["best_model.txt"]
    )


def test_cv_threads_give_identical_predictions():
    """workers=2 (process pool over model x section) returns bit-identical rows in the same order as workers=1."""
    X, groups, rng = independent_campaign(n_sections=5, p=10, seed=3)
    Y = pd.DataFrame({"mu_s": 0.5 + 0.05 * X["micro_Sq"] + 0.01 * rng.normal(size=len(X))}, index=X.index)
    models = ("pca", "ridge", "lasso", "pls")
    one = R.cross_validated_predictions(X, Y, groups, models, workers=1)
    two = R.cross_validated_predictions(X, Y, groups, models, workers=2)
    pd.testing.assert_frame_equal(one, two, check_exact=True)
    assert len(one) == len(X) * len(models)


def test_law_from_curve_inverts_curve_targets():
    """Three anchors, three unknowns: an identifiable law is recovered exactly; for any law in the bounds the
    curve at the anchors is reproduced (the parameters of a nearly straight curve need not be)."""
    laws = pd.DataFrame(
        {"mu_s": [0.70, 0.55, 0.80], "mu_k": [0.30, 0.20, 0.0], "alpha": [0.10, 0.05, 0.02]}, index=["a", "b", "c"]
    )
    C = R.curve_targets(laws)
    assert list(C.columns) == [f"mu@{v:g}" for v in R.CURVE_ANCHORS_KMH]
    assert C.loc["a", "mu@40"] == pytest.approx(0.30 + 0.40 * np.exp(-0.10 * 40 / 3.6), abs=1e-12)
    for site, row in C.iterrows():
        ms, mk, a = R.law_from_curve(row.to_numpy())
        back = ExponentialDecay(ms, mk, a).mu_kmh(np.asarray(R.CURVE_ANCHORS_KMH))
        assert np.allclose(back, row.to_numpy(), atol=1e-7), site
    assert R.law_from_curve(C.loc["a"].to_numpy()) == pytest.approx((0.70, 0.30, 0.10), abs=1e-5)


def _slow_twin(law: ExponentialDecay) -> ExponentialDecay:
    """The law with mu_k = 0 (a slow decay) closest to ``law`` at the anchors: the other parameterisation of
    a nearly straight DFT curve."""
    from skidsim.calibration import fit_exponential_decay

    v = np.asarray(R.CURVE_ANCHORS_KMH)
    twin, _ = fit_exponential_decay(v, law.mu_kmh(v), bounds={"mu_s": (0, 0.85), "mu_k": (0, 0), "alpha": (0, 1)})
    return twin


def test_curve_targets_average_curves_not_parameters():
    """Two laws with nearly the same curve over 20-60 km/h but very different parameters (mu_k 0.35 with a fast
    decay; mu_k = 0 with a slow one): the law of the mean parameters is far from both curves (the decay is convex
    in alpha), the ``mean@curve`` law is the mean curve."""
    v = np.asarray(R.CURVE_ANCHORS_KMH)
    fast = ExponentialDecay(0.62, 0.35, 0.20)
    slow = _slow_twin(fast)
    spread = np.max(np.abs(fast.mu_kmh(v) - slow.mu_kmh(v)))
    assert slow.mu_k == 0 and spread < 0.015
    Y = pd.DataFrame(
        [[fast.mu_s, fast.mu_k, fast.alpha], [slow.mu_s, slow.mu_k, slow.alpha]] * 6,
        columns=list(R.PARAMETERS),
        index=[f"S{i:02d}" for i in range(12)],
    )
    X = pd.DataFrame({"profile_MPD": np.linspace(0.5, 1.5, 12)}, index=Y.index)
    mean_curve = R.curve_targets(Y).mean().to_numpy()
    p_par = R.predict_parameters("mean", X, Y, X.iloc[:1]).iloc[0]
    p_cur = R.predict_parameters("mean@curve", X, Y, X.iloc[:1]).iloc[0]
    assert list(p_cur.index) == list(R.PARAMETERS)
    mu_par = ExponentialDecay(*p_par[list(R.PARAMETERS)]).mu_kmh(v)
    mu_cur = ExponentialDecay(*p_cur[list(R.PARAMETERS)]).mu_kmh(v)
    assert np.max(np.abs(mu_cur - mean_curve)) < 1e-6
    assert np.max(np.abs(mu_par - mean_curve)) > 5 * spread, (mu_par, mean_curve, spread)


def test_curve_model_recovers_curves_that_are_linear_in_texture():
    """Friction curves linear in one texture factor; each site's calibrated parameters are one of the two
    near-equivalent parameterisations of its curve at random: ridge@curve predicts held-out sections' curves
    far better than ridge on the parameters."""
    X, F, groups = latent_campaign(k=2, seed=3)
    v = np.asarray(R.CURVE_ANCHORS_KMH)
    rng = np.random.default_rng(4)
    rows = []
    for f in F[:, 0]:
        law = ExponentialDecay(*R.law_from_curve(0.45 + 0.1 * np.exp(-0.1 * 2.0 * v / 3.6) + 0.02 * f))
        rows.append(_slow_twin(law) if rng.random() < 0.5 else law)
    Y = pd.DataFrame([[r.mu_s, r.mu_k, r.alpha] for r in rows], columns=list(R.PARAMETERS), index=X.index)
    truth = pd.DataFrame(
        {
            "site": np.repeat(X.index, len(v)),
            "speed_kmh": np.tile(v, len(X)),
            "mu": R.curve_targets(Y).to_numpy().ravel(),
        }
    )
    cvp = R.cross_validated_predictions(X, Y, groups, ["ridge", "ridge@curve"])
    t = R.score_predictions(cvp, Y, measured_dft=truth, speeds_kmh=v)
    pooled = t[(t["quantity"] == "dft") & t["speed_kmh"].isna()].set_index("model")["rmse"]
    assert pooled["ridge@curve"] < 0.006, pooled
    assert pooled["ridge"] > 3 * pooled["ridge@curve"], pooled
